// GPU Verlet solvers (gpu_settle.h): `gl` (compute shaders, structured lattice or compressed
// rows) and `gl-gs` (the thesis's geometry-shader scatter), and the settle loop around them.

#include "shaders/gpu_settle.h"

#include "geometry/errors.h"
#include "geometry/mesh_stats.h"
#include "springs/solvers_internal.h"

#include <GL/glew.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstring>
#include <limits>
#include <optional>

namespace fascicle::shaders {

using springs::LatticeShape;
using springs::SettleOptions;
using springs::Spring;
using springs::SpringSystem;

GpuBackend parse_gpu_backend(const std::string& name) {
  if (name == "gl") return GpuBackend::gl;
  if (name == "gl-gs") return GpuBackend::gl_gs;
  throw OptionError("backend: unknown GPU backend '" + name + "' (valid: gl, gl-gs)");
}

const char* gpu_backend_name(GpuBackend backend) { return backend == GpuBackend::gl ? "gl" : "gl-gs"; }

void GpuSettleOptions::validate() const {
  if (check_interval < 1) throw OptionError("check_interval: must be >= 1, got " + std::to_string(check_interval));
  if (stall_checks < 1) throw OptionError("stall_checks: must be >= 1, got " + std::to_string(stall_checks));
  if (!(stall_motion >= 0.0) || !std::isfinite(stall_motion))
    throw OptionError("stall_motion: must be a finite number >= 0, got " + std::to_string(stall_motion));
  if (texture_width < 1 || texture_width > 16384)
    throw OptionError("texture_width: must be in 1..16384, got " + std::to_string(texture_width));
}

namespace {

using clock_type = std::chrono::steady_clock;
constexpr int kGroupSize = 256;  // local_size_x of every compute shader

// RAII names of GL objects.
struct Buffer {
  GLuint id = 0;
  Buffer() { glGenBuffers(1, &id); }
  ~Buffer() { glDeleteBuffers(1, &id); }
  Buffer(const Buffer&) = delete;
  Buffer& operator=(const Buffer&) = delete;
};
struct Texture {
  GLuint id = 0;
  Texture() { glGenTextures(1, &id); }
  ~Texture() { glDeleteTextures(1, &id); }
  Texture(const Texture&) = delete;
  Texture& operator=(const Texture&) = delete;
};
struct Framebuffer {
  GLuint id = 0;
  Framebuffer() { glGenFramebuffers(1, &id); }
  ~Framebuffer() { glDeleteFramebuffers(1, &id); }
  Framebuffer(const Framebuffer&) = delete;
  Framebuffer& operator=(const Framebuffer&) = delete;
};
struct VertexArray {
  GLuint id = 0;
  VertexArray() { glGenVertexArrays(1, &id); }
  ~VertexArray() { glDeleteVertexArrays(1, &id); }
  VertexArray(const VertexArray&) = delete;
  VertexArray& operator=(const VertexArray&) = delete;
};
struct Program {
  GLuint id = 0;
  Program() = default;
  explicit Program(GLuint name) : id(name) {}
  ~Program() {
    if (id) glDeleteProgram(id);
  }
  Program(const Program&) = delete;
  Program& operator=(const Program&) = delete;
  GLint uniform(const char* name) const { return glGetUniformLocation(id, name); }
};

// Work groups for n invocations as a 2D grid (gx x gy <= 65535^2); shaders flatten it.
struct Grid {
  GLuint x = 1, y = 1;
  std::size_t groups() const { return static_cast<std::size_t>(x) * y; }
};
Grid grid_for(long n) {
  const long groups = std::max<long>(1, (n + kGroupSize - 1) / kGroupSize);
  Grid g;
  g.x = static_cast<GLuint>(std::min<long>(groups, 32768));
  g.y = static_cast<GLuint>((groups + g.x - 1) / g.x);
  return g;
}

// Uploads `bytes` into a shader storage buffer; checks the device's block size limit.
void storage(const Buffer& buffer, std::size_t bytes, const void* data, const char* what, std::size_t& total) {
  GLint64 limit = 0;
  glGetInteger64v(GL_MAX_SHADER_STORAGE_BLOCK_SIZE, &limit);
  if (limit > 0 && bytes > static_cast<std::size_t>(limit))
    throw GpuError(std::string("OpenGL: ") + what + " needs " + std::to_string(bytes) +
                   " bytes, above the device's largest storage block (" + std::to_string(limit) + " bytes)");
  allocate_storage_buffer(buffer.id, bytes, data, what);
  total += bytes;
}

// The GPU holds positions relative to the centre of their bounding box, in float32: rounding is
// then relative to the lattice's extent, not to its distance from the origin (CT coordinates are
// often hundreds of millimetres from it while springs are about one millimetre long).
Vec3 bounding_box_centre(const SpringSystem& system) {
  return system.positions.empty() ? Vec3::Zero() : bounding_box(system.positions).center();
}

// Host copies of the shared per-point data, float32, relative to `centre`; w = 1 marks fixed.
std::vector<float> positions_vec4(const SpringSystem& system, const Vec3& centre) {
  std::vector<float> out(4 * system.positions.size());
  for (std::size_t i = 0; i < system.positions.size(); ++i) {
    for (int c = 0; c < 3; ++c) out[4 * i + c] = static_cast<float>(system.positions[i][c] - centre[c]);
    out[4 * i + 3] = system.fixed[i] ? 1.0f : 0.0f;
  }
  return out;
}

std::vector<Vec3> vec4_to_positions(const std::vector<float>& data, std::size_t n, const Vec3& centre) {
  std::vector<Vec3> out(n);
  for (std::size_t i = 0; i < n; ++i) out[i] = Vec3(data[4 * i], data[4 * i + 1], data[4 * i + 2]) + centre;
  return out;
}

bool uniform_coefficients(const springs::detail::VerletCoefficients& c) {
  for (std::size_t i = 1; i < c.a.size(); ++i)
    if (c.a[i] != c.a[0] || c.b[i] != c.b[0]) return false;
  return !c.a.empty();
}

double largest_partial(const Buffer& partial, std::size_t groups) {
  std::vector<float> values(groups);
  glMemoryBarrier(GL_BUFFER_UPDATE_BARRIER_BIT);
  glBindBuffer(GL_SHADER_STORAGE_BUFFER, partial.id);
  glGetBufferSubData(GL_SHADER_STORAGE_BUFFER, 0, static_cast<GLsizeiptr>(groups * sizeof(float)), values.data());
  check_gl("residual readback");
  double largest = 0.0;
  for (float v : values) {
    if (std::isnan(v)) return std::numeric_limits<double>::infinity();
    largest = std::max(largest, static_cast<double>(v));
  }
  return largest;
}

// Sum of the per-group energies in double; NaN when any is NaN or Inf (divergence).
double sum_partials(const Buffer& partial, std::size_t groups) {
  std::vector<float> values(groups);
  glMemoryBarrier(GL_BUFFER_UPDATE_BARRIER_BIT);
  glBindBuffer(GL_SHADER_STORAGE_BUFFER, partial.id);
  glGetBufferSubData(GL_SHADER_STORAGE_BUFFER, 0, static_cast<GLsizeiptr>(groups * sizeof(float)), values.data());
  check_gl("energy readback");
  double sum = 0.0;
  for (float v : values) {
    if (!std::isfinite(v)) return std::numeric_limits<double>::quiet_NaN();
    sum += static_cast<double>(v);
  }
  return sum;
}

// The structured kernel's per-direction stiffness, or nothing when `system` is not exactly the
// lattice `shape` (the CPU structured path's test: every spring a half-offset neighbour pair,
// each once, stiffness 1 / rest, every in-lattice neighbour pair joined).
std::optional<std::vector<std::vector<double>>> lattice_stiffness(const SpringSystem& system,
                                                                  const LatticeShape& shape) {
  const long n = static_cast<long>(shape.nx) * shape.ny * shape.nz;
  if (shape.nx < 1 || shape.ny < 1 || shape.nz < 1 || n != static_cast<long>(system.positions.size()))
    return std::nullopt;
  const auto& dirs = springs::half_offsets(shape.model);
  std::vector<std::vector<double>> stiffness(dirs.size(), std::vector<double>(n, 0.0));
  for (const Spring& s : system.springs) {
    const int ia = s.a % shape.nx, ja = (s.a / shape.nx) % shape.ny, ka = s.a / (shape.nx * shape.ny);
    const int ib = s.b % shape.nx, jb = (s.b / shape.nx) % shape.ny, kb = s.b / (shape.nx * shape.ny);
    const std::array<int, 3> delta = {ib - ia, jb - ja, kb - ka};
    int found = -1;
    for (std::size_t d = 0; d < dirs.size(); ++d)
      if (dirs[d] == delta) found = static_cast<int>(d);
    if (found < 0 || stiffness[found][s.a] != 0.0) return std::nullopt;
    if (!(std::abs(s.stiffness * s.rest - 1.0) <= 1e-12)) return std::nullopt;
    stiffness[found][s.a] = s.stiffness;
  }
  for (int k = 0; k < shape.nz; ++k)
    for (int j = 0; j < shape.ny; ++j)
      for (int i = 0; i < shape.nx; ++i)
        for (std::size_t d = 0; d < dirs.size(); ++d) {
          const int i2 = i + dirs[d][0], j2 = j + dirs[d][1], k2 = k + dirs[d][2];
          if (i2 < 0 || j2 < 0 || k2 < 0 || i2 >= shape.nx || j2 >= shape.ny || k2 >= shape.nz) continue;
          if (stiffness[d][i + static_cast<long>(shape.nx) * (j + static_cast<long>(shape.ny) * k)] == 0.0)
            return std::nullopt;
        }
  return stiffness;
}

// ---------------------------------------------------------------------------------------------
// gl: compute shaders over storage buffers.
class ComputeVerlet final : public GpuSpringSolver {
 public:
  ComputeVerlet(const SpringSystem& system, const SettleOptions& options,
                std::optional<std::vector<std::vector<double>>> lattice, const LatticeShape* shape, bool momentum)
      : coefficients_(momentum ? springs::detail::momentum_coefficients(system)
                               : springs::detail::verlet_coefficients(system, options)),
        momentum_(momentum) {
    n_ = static_cast<long>(system.positions.size());
    if (n_ > std::numeric_limits<int>::max() / 16) throw GpuError("OpenGL: too many points for 32-bit indices");
    grid_ = grid_for(n_);
    scale_ = springs::residual_force_scale(system);
    centre_ = bounding_box_centre(system);
    const std::vector<float> x = positions_vec4(system, centre_);
    storage(x_[0], x.size() * sizeof(float), x.data(), "positions", bytes_);
    storage(x_[1], x.size() * sizeof(float), x.data(), "previous positions", bytes_);
    storage(partial_, grid_.groups() * sizeof(float), nullptr, "residual partials", bytes_);
    storage(power_, grid_.groups() * sizeof(float), nullptr, "power partials", bytes_);
    const bool uniform_ab = uniform_coefficients(coefficients_);
    std::vector<float> ab(2 * n_);
    for (long i = 0; i < n_; ++i) {
      ab[2 * i] = static_cast<float>(coefficients_.a[i]);
      ab[2 * i + 1] = static_cast<float>(coefficients_.b[i]);
    }
    if (lattice) {
      structured_ = true;
      shape_ = *shape;
      program_ = std::make_unique<Program>(compile_program({"verlet_lattice.comp"}));
      const auto& dirs = springs::half_offsets(shape_.model);
      directions_ = static_cast<int>(dirs.size());
      // Uniform: every direction's springs share one stiffness to 1e-12 (regular lattices) and
      // every point one (a, b): the kernel then reads scalars (as the CPU structured path).
      uniform_ = uniform_ab;
      for (int d = 0; d < directions_ && uniform_; ++d) {
        double lo = std::numeric_limits<double>::infinity(), hi = 0.0, sum = 0.0;
        long count = 0;
        for (double k : (*lattice)[d]) {
          if (k == 0.0) continue;
          lo = std::min(lo, k);
          hi = std::max(hi, k);
          sum += k;
          ++count;
        }
        if (count == 0 || hi - lo > 1e-12 * hi)
          uniform_ = false;
        else
          k_uniform_[d] = static_cast<float>(sum / count);
      }
      if (!uniform_) {
        std::vector<float> k(static_cast<std::size_t>(directions_) * n_);
        for (int d = 0; d < directions_; ++d)
          for (long i = 0; i < n_; ++i) k[d * n_ + i] = static_cast<float>((*lattice)[d][i]);
        storage(stiffness_, k.size() * sizeof(float), k.data(), "lattice stiffness", bytes_);
        storage(coef_, ab.size() * sizeof(float), ab.data(), "Verlet coefficients", bytes_);
      } else {
        storage(stiffness_, 0, nullptr, "lattice stiffness", bytes_);
        storage(coef_, 0, nullptr, "Verlet coefficients", bytes_);
      }
      const GLuint id = program_->id;
      glUseProgram(id);
      glUniform3i(program_->uniform("u_size"), shape_.nx, shape_.ny, shape_.nz);
      glUniform1i(program_->uniform("u_n"), static_cast<GLint>(n_));
      glUniform1i(program_->uniform("u_directions"), directions_);
      std::vector<GLint> dir(3 * directions_), offset(directions_);
      for (int d = 0; d < directions_; ++d) {
        for (int c = 0; c < 3; ++c) dir[3 * d + c] = dirs[d][c];
        offset[d] = dirs[d][0] + shape_.nx * (dirs[d][1] + shape_.ny * dirs[d][2]);
      }
      glUniform3iv(program_->uniform("u_dir"), directions_, dir.data());
      glUniform1iv(program_->uniform("u_offset"), directions_, offset.data());
      glUniform1i(program_->uniform("u_uniform"), uniform_ ? 1 : 0);
      glUniform1fv(program_->uniform("u_k"), directions_, k_uniform_.data());
      glUniform2f(program_->uniform("u_ab"), static_cast<float>(coefficients_.a[0]),
                  static_cast<float>(coefficients_.b[0]));
      energy_program_ = std::make_unique<Program>(compile_program({"verlet_energy.comp"}, "#define LATTICE 1\n"));
      const Program& e = *energy_program_;
      glUseProgram(e.id);
      glUniform3i(e.uniform("u_size"), shape_.nx, shape_.ny, shape_.nz);
      glUniform1i(e.uniform("u_n"), static_cast<GLint>(n_));
      glUniform1i(e.uniform("u_directions"), directions_);
      glUniform3iv(e.uniform("u_dir"), directions_, dir.data());
      glUniform1iv(e.uniform("u_offset"), directions_, offset.data());
      glUniform1i(e.uniform("u_uniform"), uniform_ ? 1 : 0);
      glUniform1fv(e.uniform("u_k"), directions_, k_uniform_.data());
      glUniform2f(e.uniform("u_ab"), static_cast<float>(coefficients_.a[0]), static_cast<float>(coefficients_.b[0]));
    } else {
      program_ = std::make_unique<Program>(compile_program({"verlet_csr.comp"}));
      const springs::detail::SpringRows csr = springs::detail::spring_rows(system);
      static_assert(sizeof(GLint) == sizeof(int), "GLint rows");
      const std::vector<int>& row = csr.row;
      struct Slot {
        GLint q;
        float k, rest, pad;
      };
      static_assert(sizeof(Slot) == 16, "std430 layout of Slot");
      std::vector<Slot> slots(csr.neighbour.size());
      for (std::size_t i = 0; i < slots.size(); ++i)
        slots[i] = Slot{csr.neighbour[i], static_cast<float>(csr.stiffness[i]), static_cast<float>(csr.rest[i]), 0.0f};
      storage(rows_, row.size() * sizeof(GLint), row.data(), "spring rows", bytes_);
      storage(stiffness_, slots.size() * sizeof(Slot), slots.data(), "springs", bytes_);
      storage(coef_, ab.size() * sizeof(float), ab.data(), "Verlet coefficients", bytes_);
      glUseProgram(program_->id);
      glUniform1i(program_->uniform("u_n"), static_cast<GLint>(n_));
      energy_program_ = std::make_unique<Program>(compile_program({"verlet_energy.comp"}, "#define CSR 1\n"));
      glUseProgram(energy_program_->id);
      glUniform1i(energy_program_->uniform("u_n"), static_cast<GLint>(n_));
    }
    glUseProgram(program_->id);
    glUniform1i(program_->uniform("u_uniform_ab"), uniform_ab ? 1 : 0);
    glUniform2f(program_->uniform("u_ab"), static_cast<float>(coefficients_.a[0]),
                static_cast<float>(coefficients_.b[0]));
    u_write_ = program_->uniform("u_write");
    u_measure_ = program_->uniform("u_measure");
    u_power_ = program_->uniform("u_power");
    u_ab_ = program_->uniform("u_ab");
    glUniform1i(u_power_, 0);
    check_gl("gl solver setup");
  }

  void run(int iterations) override {
    glUseProgram(program_->id);
    glUniform1i(u_write_, 1);
    glUniform1i(u_measure_, 0);
    for (int it = 0; it < iterations; ++it) {
      if (momentum_) momentum_schedule();
      dispatch();
      glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT);
      if (momentum_) power_sum_ = sum_partials(power_, grid_.groups());  // a few bytes back, every step
      current_ ^= 1;  // the step wrote the new positions over the previous ones
    }
    glUniform1i(u_power_, 0);
    check_gl("gl Verlet step");
  }

  double residual() override {
    glUseProgram(program_->id);
    glUniform1i(u_write_, 0);
    glUniform1i(u_measure_, 1);
    dispatch();
    const double largest = largest_partial(partial_, grid_.groups());
    return std::isfinite(largest) ? std::sqrt(largest) / scale_ : std::numeric_limits<double>::infinity();
  }

  double energy() override {
    glUseProgram(energy_program_->id);
    dispatch();
    return sum_partials(partial_, grid_.groups());
  }

  std::vector<Vec3> positions() override {
    std::vector<float> data(4 * n_);
    glMemoryBarrier(GL_BUFFER_UPDATE_BARRIER_BIT);
    glBindBuffer(GL_SHADER_STORAGE_BUFFER, x_[current_].id);
    glGetBufferSubData(GL_SHADER_STORAGE_BUFFER, 0, static_cast<GLsizeiptr>(data.size() * sizeof(float)), data.data());
    check_gl("position readback");
    return vec4_to_positions(data, n_, centre_);
  }

  void finish() override { glFinish(); }
  std::string backend() const override {
    return std::string(momentum_ ? "momentum-" : "") +
           (structured_ ? (uniform_ ? "gl-structured-uniform" : "gl-structured") : "gl-general");
  }
  double time_step() const override { return coefficients_.dt; }
  double mean_damping() const override { return coefficients_.mean_damping; }
  std::size_t gpu_bytes() const override { return bytes_; }

 private:
  void dispatch() {
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 0, x_[current_].id);
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 1, x_[current_ ^ 1].id);
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 4, partial_.id);
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 6, power_.id);
    if (structured_) {
      glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 2, stiffness_.id);
      glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 3, coef_.id);
    } else {
      glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 2, rows_.id);
      glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 3, stiffness_.id);
      glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 5, coef_.id);
    }
    glDispatchCompute(grid_.x, grid_.y, 1);
  }

  // The momentum static solver's step (as the CPU's, springs/verlet_structured.cpp): Nesterov's
  // momentum b = k / (k + 3) with the gradient restart of O'Donoghue and Candes 2015: when the
  // last step moved against the force (sum F . v < 0, measured by that step's dispatch), the
  // velocity is dropped (previous positions := current ones, a copy on the GPU).
  void momentum_schedule() {
    if (schedule_.restart(power_sum_ < 0.0)) {
      glBindBuffer(GL_COPY_READ_BUFFER, x_[current_].id);
      glBindBuffer(GL_COPY_WRITE_BUFFER, x_[current_ ^ 1].id);
      glCopyBufferSubData(GL_COPY_READ_BUFFER, GL_COPY_WRITE_BUFFER, 0, 0,
                          static_cast<GLsizeiptr>(4 * n_ * sizeof(float)));
      glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT);
    }
    const double b = schedule_.next();
    glUniform2f(u_ab_, static_cast<float>(coefficients_.a[0]), static_cast<float>(b));
    glUniform1i(u_power_, 1);
  }

  springs::detail::VerletCoefficients coefficients_;
  bool momentum_ = false;
  springs::detail::MomentumSchedule schedule_;
  double power_sum_ = 0.0;
  Buffer power_;
  GLint u_power_ = -1, u_ab_ = -1;
  long n_ = 0;
  Grid grid_;
  double scale_ = 1.0;
  bool structured_ = false, uniform_ = false;
  LatticeShape shape_;
  int directions_ = 0;
  std::array<float, 13> k_uniform_{};
  Buffer x_[2], partial_, stiffness_, coef_, rows_;
  int current_ = 0;
  std::unique_ptr<Program> program_, energy_program_;
  GLint u_write_ = -1, u_measure_ = -1;
  Vec3 centre_ = Vec3::Zero();  // positions on the GPU are relative to it
  std::size_t bytes_ = 0;
};

// ---------------------------------------------------------------------------------------------
// gl-gs: the thesis's geometry-shader scatter into a float texture with additive blending.
class GeometryShaderVerlet final : public GpuSpringSolver {
 public:
  GeometryShaderVerlet(const SpringSystem& system, const SettleOptions& options, const GpuSettleOptions& gpu)
      : coefficients_(springs::detail::verlet_coefficients(system, options)) {
    n_ = static_cast<long>(system.positions.size());
    springs_ = static_cast<long>(system.springs.size());
    scale_ = springs::residual_force_scale(system);
    GLint max_size = 0;
    glGetIntegerv(GL_MAX_TEXTURE_SIZE, &max_size);
    width_ = static_cast<int>(std::min<long>(std::min(gpu.texture_width, max_size), std::max<long>(n_, 1)));
    height_ = static_cast<int>((n_ + width_ - 1) / width_);
    if (height_ > max_size)
      throw GpuError("OpenGL: " + std::to_string(n_) + " points need a " + std::to_string(width_) + " x " +
                     std::to_string(height_) + " texture, above the device's largest (" + std::to_string(max_size) +
                     ")");
    height_ = std::max(height_, 1);
    const std::size_t texels = static_cast<std::size_t>(width_) * height_;
    std::vector<float> x(4 * texels, 0.0f);
    centre_ = bounding_box_centre(system);
    const std::vector<float> given = positions_vec4(system, centre_);
    std::copy(given.begin(), given.end(), x.begin());
    for (int t = 0; t < 3; ++t) make_texture(positions_[t], x.data(), "position texture");
    make_texture(force_, nullptr, "force texture");
    uniform_ = uniform_coefficients(coefficients_);
    if (!uniform_) {
      std::vector<float> ab(4 * texels, 0.0f);
      for (long i = 0; i < n_; ++i) {
        ab[4 * i] = static_cast<float>(coefficients_.a[i]);
        ab[4 * i + 1] = static_cast<float>(coefficients_.b[i]);
      }
      make_texture(coef_, ab.data(), "coefficient texture");
    } else {
      make_texture(coef_, nullptr, "coefficient texture", 1, 1);
    }
    for (int t = 0; t < 3; ++t) attach(position_fbo_[t], positions_[t]);
    attach(force_fbo_, force_);

    // One vertex per spring: (a, b) as integers, (D, |l0|) as floats.
    std::vector<GLint> ends(2 * springs_);
    std::vector<float> params(2 * springs_);
    for (long s = 0; s < springs_; ++s) {
      const Spring& spring = system.springs[s];
      ends[2 * s] = spring.a;
      ends[2 * s + 1] = spring.b;
      params[2 * s] = static_cast<float>(spring.stiffness);
      params[2 * s + 1] = static_cast<float>(spring.rest);
    }
    glBindVertexArray(springs_vao_.id);
    glBindBuffer(GL_ARRAY_BUFFER, ends_.id);
    glBufferData(GL_ARRAY_BUFFER, static_cast<GLsizeiptr>(ends.size() * sizeof(GLint)), ends.data(), GL_STATIC_DRAW);
    glEnableVertexAttribArray(0);
    glVertexAttribIPointer(0, 2, GL_INT, 0, nullptr);
    glBindBuffer(GL_ARRAY_BUFFER, params_.id);
    glBufferData(GL_ARRAY_BUFFER, static_cast<GLsizeiptr>(params.size() * sizeof(float)), params.data(),
                 GL_STATIC_DRAW);
    glEnableVertexAttribArray(1);
    glVertexAttribPointer(1, 2, GL_FLOAT, GL_FALSE, 0, nullptr);
    glBindVertexArray(0);
    check_gl("gl-gs spring buffers");
    bytes_ += ends.size() * sizeof(GLint) + params.size() * sizeof(float);

    force_program_ =
        std::make_unique<Program>(compile_program({"spring_force.vert", "spring_force.geom", "spring_force.frag"}));
    integrate_program_ = std::make_unique<Program>(compile_program({"fullscreen.vert", "verlet_integrate.frag"}));
    residual_program_ = std::make_unique<Program>(compile_program({"force_residual.comp"}));
    energy_program_ = std::make_unique<Program>(compile_program({"verlet_energy.comp"}, "#define TEXTURES 1\n"));
    glUseProgram(force_program_->id);
    glUniform1i(force_program_->uniform("u_positions"), 0);
    glUniform1i(force_program_->uniform("u_width"), width_);
    glUniform2i(force_program_->uniform("u_size"), width_, height_);
    glUseProgram(integrate_program_->id);
    glUniform1i(integrate_program_->uniform("u_current"), 0);
    glUniform1i(integrate_program_->uniform("u_previous"), 1);
    glUniform1i(integrate_program_->uniform("u_force"), 2);
    glUniform1i(integrate_program_->uniform("u_coefficients"), 3);
    glUniform1i(integrate_program_->uniform("u_uniform"), uniform_ ? 1 : 0);
    glUniform2f(integrate_program_->uniform("u_ab"), static_cast<float>(coefficients_.a[0]),
                static_cast<float>(coefficients_.b[0]));
    glUseProgram(residual_program_->id);
    glUniform1i(residual_program_->uniform("u_force"), 2);
    glUniform1i(residual_program_->uniform("u_positions"), 0);
    glUniform1i(residual_program_->uniform("u_width"), width_);
    glUniform1i(residual_program_->uniform("u_n"), static_cast<GLint>(n_));
    glUseProgram(energy_program_->id);
    glUniform1i(energy_program_->uniform("u_current"), 0);
    glUniform1i(energy_program_->uniform("u_previous"), 1);
    glUniform1i(energy_program_->uniform("u_coefficients"), 3);
    glUniform1i(energy_program_->uniform("u_uniform"), uniform_ ? 1 : 0);
    glUniform2f(energy_program_->uniform("u_ab"), static_cast<float>(coefficients_.a[0]),
                static_cast<float>(coefficients_.b[0]));
    glUniform1i(energy_program_->uniform("u_width"), width_);
    glUniform1i(energy_program_->uniform("u_n"), static_cast<GLint>(n_));
    glUniform1i(energy_program_->uniform("u_springs"), static_cast<GLint>(springs_));
    energy_grid_ = grid_for(std::max(n_, springs_));
    grid_ = grid_for(n_);
    storage(partial_, std::max(grid_.groups(), energy_grid_.groups()) * sizeof(float), nullptr, "residual partials",
            bytes_);
    glBindBuffer(GL_PIXEL_PACK_BUFFER, pbo_.id);
    glBufferData(GL_PIXEL_PACK_BUFFER, static_cast<GLsizeiptr>(texels * 4 * sizeof(float)), nullptr, GL_STREAM_READ);
    glBindBuffer(GL_PIXEL_PACK_BUFFER, 0);
    bytes_ += texels * 4 * sizeof(float);
    glDisable(GL_DEPTH_TEST);
    check_gl("gl-gs setup");
  }

  void run(int iterations) override {
    for (int it = 0; it < iterations; ++it) {
      accumulate_forces();
      // Pass 2: integrate into the third texture.
      const int next = (current_ + 2) % 3, previous = (current_ + 1) % 3;
      glBindFramebuffer(GL_FRAMEBUFFER, position_fbo_[next].id);
      glViewport(0, 0, width_, height_);
      glDisable(GL_BLEND);
      glUseProgram(integrate_program_->id);
      bind_texture(0, positions_[current_]);
      bind_texture(1, positions_[previous]);
      bind_texture(2, force_);
      bind_texture(3, coef_);
      glBindVertexArray(empty_vao_.id);
      glDrawArrays(GL_TRIANGLES, 0, 3);
      // Rotate: the current positions become the previous ones, the new ones current.
      current_ = next;
    }
    glBindVertexArray(0);
    check_gl("gl-gs Verlet step");
  }

  double residual() override {
    accumulate_forces();
    glUseProgram(residual_program_->id);
    bind_texture(0, positions_[current_]);
    bind_texture(2, force_);
    glMemoryBarrier(GL_TEXTURE_FETCH_BARRIER_BIT | GL_FRAMEBUFFER_BARRIER_BIT);
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 4, partial_.id);
    glDispatchCompute(grid_.x, grid_.y, 1);
    const double largest = largest_partial(partial_, grid_.groups());
    return std::isfinite(largest) ? std::sqrt(largest) / scale_ : std::numeric_limits<double>::infinity();
  }

  double energy() override {
    glUseProgram(energy_program_->id);
    bind_texture(0, positions_[current_]);
    bind_texture(1, positions_[(current_ + 1) % 3]);
    bind_texture(3, coef_);
    glMemoryBarrier(GL_TEXTURE_FETCH_BARRIER_BIT | GL_FRAMEBUFFER_BARRIER_BIT);
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 0, ends_.id);
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 1, params_.id);
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 4, partial_.id);
    glDispatchCompute(energy_grid_.x, energy_grid_.y, 1);
    return sum_partials(partial_, energy_grid_.groups());
  }

  std::vector<Vec3> positions() override { return read(true); }

  // glReadPixels of the current position texture, into client memory or through the PBO.
  std::vector<Vec3> read(bool pbo) {
    const std::size_t texels = static_cast<std::size_t>(width_) * height_;
    std::vector<float> data(4 * texels);
    glBindFramebuffer(GL_READ_FRAMEBUFFER, position_fbo_[current_].id);
    glReadBuffer(GL_COLOR_ATTACHMENT0);
    glPixelStorei(GL_PACK_ALIGNMENT, 4);
    if (pbo) {
      glBindBuffer(GL_PIXEL_PACK_BUFFER, pbo_.id);
      glReadPixels(0, 0, width_, height_, GL_RGBA, GL_FLOAT, nullptr);  // returns at once
      GLsync fence = glFenceSync(GL_SYNC_GPU_COMMANDS_COMPLETE, 0);
      glClientWaitSync(fence, GL_SYNC_FLUSH_COMMANDS_BIT, std::numeric_limits<GLuint64>::max());
      glDeleteSync(fence);
      const void* mapped = glMapBufferRange(GL_PIXEL_PACK_BUFFER, 0,
                                            static_cast<GLsizeiptr>(data.size() * sizeof(float)), GL_MAP_READ_BIT);
      if (!mapped) {
        glBindBuffer(GL_PIXEL_PACK_BUFFER, 0);
        check_gl("pixel buffer map");
        throw GpuError("OpenGL: the pixel buffer object could not be mapped");
      }
      std::memcpy(data.data(), mapped, data.size() * sizeof(float));
      glUnmapBuffer(GL_PIXEL_PACK_BUFFER);
      glBindBuffer(GL_PIXEL_PACK_BUFFER, 0);
    } else {
      glReadPixels(0, 0, width_, height_, GL_RGBA, GL_FLOAT, data.data());
    }
    glBindFramebuffer(GL_READ_FRAMEBUFFER, 0);
    check_gl("position readback");
    return vec4_to_positions(data, n_, centre_);
  }

  void finish() override { glFinish(); }
  std::string backend() const override { return "gl-gs"; }
  double time_step() const override { return coefficients_.dt; }
  double mean_damping() const override { return coefficients_.mean_damping; }
  std::size_t gpu_bytes() const override { return bytes_; }

 private:
  void make_texture(const Texture& texture, const float* data, const char* what, int w = 0, int h = 0) {
    if (!w) w = width_;
    if (!h) h = height_;
    glBindTexture(GL_TEXTURE_2D, texture.id);
    glTexImage2D(GL_TEXTURE_2D, 0, GL_RGBA32F, w, h, 0, GL_RGBA, GL_FLOAT, data);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAX_LEVEL, 0);
    glBindTexture(GL_TEXTURE_2D, 0);
    check_gl(what);
    bytes_ += static_cast<std::size_t>(w) * h * 4 * sizeof(float);
  }
  void attach(const Framebuffer& fbo, const Texture& texture) {
    glBindFramebuffer(GL_FRAMEBUFFER, fbo.id);
    glFramebufferTexture2D(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_TEXTURE_2D, texture.id, 0);
    const GLenum status = glCheckFramebufferStatus(GL_FRAMEBUFFER);
    glBindFramebuffer(GL_FRAMEBUFFER, 0);
    if (status != GL_FRAMEBUFFER_COMPLETE)
      throw GpuError("OpenGL: an RGBA32F framebuffer is not complete on this device (status " + std::to_string(status) +
                     ")");
  }
  static void bind_texture(int unit, const Texture& texture) {
    glActiveTexture(GL_TEXTURE0 + unit);
    glBindTexture(GL_TEXTURE_2D, texture.id);
  }
  // Pass 1: force texture = sum over springs, scattered by the geometry shader, blended (ONE, ONE).
  void accumulate_forces() {
    glBindFramebuffer(GL_FRAMEBUFFER, force_fbo_.id);
    glViewport(0, 0, width_, height_);
    const float zero[4] = {0.0f, 0.0f, 0.0f, 0.0f};
    glClearBufferfv(GL_COLOR, 0, zero);
    glEnable(GL_BLEND);
    glBlendEquation(GL_FUNC_ADD);
    glBlendFunc(GL_ONE, GL_ONE);
    glUseProgram(force_program_->id);
    bind_texture(0, positions_[current_]);
    glBindVertexArray(springs_vao_.id);
    glDrawArrays(GL_POINTS, 0, static_cast<GLsizei>(springs_));
    glDisable(GL_BLEND);
  }

  springs::detail::VerletCoefficients coefficients_;
  long n_ = 0, springs_ = 0;
  int width_ = 1, height_ = 1;
  double scale_ = 1.0;
  bool uniform_ = false;
  Texture positions_[3], force_, coef_;
  Framebuffer position_fbo_[3], force_fbo_;
  VertexArray springs_vao_, empty_vao_;
  Buffer ends_, params_, partial_, pbo_;
  Grid grid_;
  int current_ = 0;  // previous = current + 1, next = current + 2 (mod 3)
  std::unique_ptr<Program> force_program_, integrate_program_, residual_program_, energy_program_;
  Grid energy_grid_;
  Vec3 centre_ = Vec3::Zero();  // positions on the GPU are relative to it
  std::size_t bytes_ = 0;
};

}  // namespace

std::unique_ptr<GpuSpringSolver> make_gpu_solver(const GlContext& context, const SpringSystem& system,
                                                 const SettleOptions& options, const GpuSettleOptions& gpu_options,
                                                 const LatticeShape* shape) {
  options.validate();
  gpu_options.validate();
  springs::validate(system);
  const bool momentum = options.solver == springs::SolverKind::static_equilibrium;
  if (momentum && (options.static_method != springs::StaticMethod::momentum || gpu_options.backend != GpuBackend::gl))
    throw OptionError(
        "solver: on the GPU the static solver runs only as --static-method momentum on --backend gl; "
        "use --backend cpu for the others");
  context.make_current();
  if (gpu_options.backend == GpuBackend::gl_gs) {
    if (system.positions.empty()) throw OptionError("system: no point to settle");
    return std::make_unique<GeometryShaderVerlet>(system, options, gpu_options);
  }
  std::optional<std::vector<std::vector<double>>> lattice;
  if (shape && options.backend != springs::Backend::general) lattice = lattice_stiffness(system, *shape);
  if (options.backend == springs::Backend::structured && !lattice)
    throw OptionError(
        "backend: structured needs a lattice whose springs are exactly its model-6/26 neighbours with "
        "stiffness 1 / rest length; use the general or auto path");
  return std::make_unique<ComputeVerlet>(system, options, std::move(lattice), shape, momentum);
}

Readback read_positions(GpuSpringSolver& solver, bool pbo) {
  solver.finish();
  const auto t0 = clock_type::now();
  Readback out;
  if (auto* gs = dynamic_cast<GeometryShaderVerlet*>(&solver))
    out.positions = gs->read(pbo);
  else
    out.positions = solver.positions();
  out.seconds = std::chrono::duration<double>(clock_type::now() - t0).count();
  return out;
}

GpuSettleReport settle_gpu(const GlContext& context, SpringSystem& system, const SettleOptions& options,
                           const GpuSettleOptions& gpu_options, const LatticeShape* shape) {
  const auto t0 = clock_type::now();
  std::unique_ptr<GpuSpringSolver> solver = make_gpu_solver(context, system, options, gpu_options, shape);
  solver->finish();
  const auto t1 = clock_type::now();
  GpuSettleReport report;
  report.solver = springs::solver_name(options.solver);
  report.backend = solver->backend();
  report.dt = solver->time_step();
  report.mean_damping = solver->mean_damping();
  report.renderer = context.renderer();
  report.gl_version = context.version();
  report.hardware = context.hardware();
  report.gpu_bytes = solver->gpu_bytes();
  double residual = solver->residual();
  report.residual_history.push_back(residual);
  // Divergence as on the CPU: every energy_interval iterations the total energy comes back
  // (a reduction on the GPU, a few kilobytes); NaN/Inf, or more than energy_growth_bound times
  // the initial energy, stops the solve with the CPU's SolverError.
  // The coefficients only name the step in the error message; they are built when it is thrown.
  const springs::detail::DivergenceWatch watch(system, options, solver->energy());
  auto check_energy = [&](int iteration, double energy) {
    if (!watch.diverged(energy)) return;
    const bool momentum = options.solver == springs::SolverKind::static_equilibrium;
    watch.check(iteration, energy,
                momentum ? springs::detail::momentum_coefficients(system)
                         : springs::detail::verlet_coefficients(system, options),
                options);
  };
  check_energy(0, watch.initial_energy());
  const bool run_all = options.tolerance == 0.0;
  // The stall rule's motion floor: a share of the mean rest length, at least 64 float32
  // roundings of the half-extent (positions on the GPU are relative to the box centre).
  double motion_floor = 0.0;
  {
    double rest = 0.0;
    for (const Spring& spring : system.springs) rest += spring.rest;
    if (!system.springs.empty()) rest /= static_cast<double>(system.springs.size());
    const double half_extent = 0.5 * bounding_box(system.positions).diagonal();
    motion_floor =
        std::max(gpu_options.stall_motion * rest, 64.0 * std::numeric_limits<float>::epsilon() * half_extent);
  }
  // Largest move of a free point between two readbacks.
  auto largest_move = [&](const std::vector<Vec3>& a, const std::vector<Vec3>& b) {
    double move = 0.0;
    for (std::size_t i = 0; i < a.size(); ++i)
      if (!system.fixed[i]) move = std::max(move, (a[i] - b[i]).norm());
    return move;
  };
  std::vector<Vec3> suspected;  // positions when a stall was suspected, empty when none is
  if (run_all || residual > options.tolerance) {
    double best = residual;
    int without_progress = 0;
    int next_check = run_all ? options.max_iterations : gpu_options.check_interval;
    int next_energy = options.energy_interval;
    while (report.iterations < options.max_iterations) {
      const int until = std::min({next_check, next_energy, options.max_iterations});
      solver->run(until - report.iterations);
      report.iterations = until;
      if (watch.due(report.iterations)) {
        next_energy += options.energy_interval;
        check_energy(report.iterations, solver->energy());
      }
      if (report.iterations != next_check && report.iterations < options.max_iterations) continue;
      next_check = report.iterations + gpu_options.check_interval;
      residual = solver->residual();
      report.residual_history.push_back(residual);
      if (!std::isfinite(residual)) break;
      if (run_all) continue;
      if (residual <= options.tolerance) break;
      // No new minimum for stall_checks checks: float32 rounding may dominate the forces, or the
      // lattice is swinging. The positions are read back halfway through such a run of checks
      // and at its end; the solve stops only if no free point moved more than the floor between.
      const int half = gpu_options.stall_checks / 2;
      if (residual < 0.99 * best) {
        best = residual;
        without_progress = 0;
        suspected.clear();
      } else if (++without_progress == half) {  // never for stall_checks 1 (half 0)
        suspected = read_positions(*solver, false).positions;
      } else if (without_progress >= gpu_options.stall_checks) {
        std::vector<Vec3> now = read_positions(*solver, false).positions;
        if (!suspected.empty() && largest_move(now, suspected) <= motion_floor) {
          report.stalled = true;  // float32 rounding dominates the forces: further steps change nothing
          break;
        }
        suspected = std::move(now);  // still moving: judge again after another stall_checks - half checks
        without_progress = half;
      }
    }
  }
  if (!std::isfinite(residual)) check_energy(report.iterations, NAN);
  solver->finish();
  const auto t2 = clock_type::now();
  const Readback back = read_positions(*solver, gpu_options.pbo_readback);
  report.seconds = std::chrono::duration<double>(t2 - t1).count();
  report.setup_seconds = std::chrono::duration<double>(t1 - t0).count();
  report.readback_seconds = back.seconds;
  report.residual = residual;
  report.converged = !run_all && residual <= options.tolerance;
  for (std::size_t i = 0; i < back.positions.size(); ++i) {
    if (system.fixed[i]) continue;
    if (!back.positions[i].allFinite())
      throw SolverError("settle: point " + std::to_string(i) +
                        " is not finite after the GPU solve; use a smaller --dt or a larger --mass");
    system.positions[i] = back.positions[i];
  }
  report.gpu_residual = residual;
  if (report.stalled && gpu_options.polish && report.iterations < options.max_iterations) {
    // float32 stopped above the tolerance: the CPU finishes from here in double (the static
    // equilibrium is the Verlet solver's rest state too), within the iterations left.
    solver.reset();  // the GPU's buffers are not needed any more
    springs::SettleOptions cpu = options;
    cpu.solver = springs::SolverKind::static_equilibrium;
    cpu.static_method = springs::StaticMethod::momentum;
    cpu.coarse_start_points = 0;  // start from the GPU's positions, not from a coarse lattice
    cpu.max_iterations = options.max_iterations - report.iterations;
    const springs::SettleReport polished = springs::settle(system, cpu, shape);
    report.polished = true;
    report.polish_iterations = polished.iterations;
    report.polish_seconds = polished.setup_seconds + polished.seconds;
    report.residual = polished.residual;
    report.converged = polished.converged;
  }
  return report;
}

BackendChoice choose_backend(const std::string& requested, springs::SolverKind solver, std::size_t points,
                             bool hardware_device, std::size_t min_gpu_points) {
  const bool verlet = solver == springs::SolverKind::verlet;
  if (requested == "cpu") return {"cpu", "requested (--backend cpu)"};
  if (requested == "gl" || requested == "gl-gs") {
    if (!verlet && requested == "gl-gs")
      throw OptionError(
          "backend: gl-gs runs the Verlet solver only; use --backend gl (static method momentum), "
          "cpu or auto for --solver static");
    return {requested, "requested (--backend " + requested + ")"};
  }
  if (requested != "auto")
    throw OptionError("backend: unknown backend '" + requested + "' (valid: cpu, gl, gl-gs, auto)");
  if (!verlet) return {"cpu", "auto: the static solver runs on the CPU only"};
  if (points < min_gpu_points)
    return {"cpu", "auto: " + std::to_string(points) + " points, below the " + std::to_string(min_gpu_points) +
                       " from which a GPU is used"};
  if (!hardware_device) return {"cpu", "auto: no hardware GPU (EGL finds only a software renderer or none)"};
  return {"gl", "auto: hardware GPU and " + std::to_string(points) + " points (at least " +
                    std::to_string(min_gpu_points) + ")"};
}

}  // namespace fascicle::shaders
