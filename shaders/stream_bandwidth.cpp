// GPU stream bandwidth probe (stream_bandwidth.h).

#include "shaders/stream_bandwidth.h"

#include "geometry/errors.h"

#include <GL/glew.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <string>
#include <vector>

namespace fascicle::shaders {

void StreamBandwidthOptions::validate() const {
  if (bytes < 16 || bytes % 16 != 0)
    throw OptionError("bytes: must be a positive multiple of 16, got " + std::to_string(bytes));
  if (bytes / 16 > 0xffffffffull) throw OptionError("bytes: at most 64 GiB (vec4 count in 32 bits)");
  if (repetitions < 1) throw OptionError("repetitions: must be >= 1, got " + std::to_string(repetitions));
  if (!(min_seconds > 0.0)) throw OptionError("min_seconds: must be > 0");
}

namespace {

// Buffers and program released on every path out.
struct StreamObjects {
  GLuint buffers[2] = {0, 0};
  GLuint program = 0;
  StreamObjects() { glGenBuffers(2, buffers); }
  ~StreamObjects() {
    glDeleteBuffers(2, buffers);
    if (program) glDeleteProgram(program);
  }
  StreamObjects(const StreamObjects&) = delete;
  StreamObjects& operator=(const StreamObjects&) = delete;
};

}  // namespace

StreamBandwidth measure_stream_bandwidth(const GlContext& context, const StreamBandwidthOptions& options) {
  options.validate();
  context.make_current();
  const std::size_t count = options.bytes / 16;
  // One invocation per vec4: groups of 256 on a grid of at most 32768 columns.
  const std::size_t groups = (count + 255) / 256;
  const GLuint columns = static_cast<GLuint>(std::min<std::size_t>(groups, 32768));
  const GLuint rows = static_cast<GLuint>((groups + columns - 1) / columns);
  StreamObjects objects;
  objects.program = compile_program({"stream_copy.comp"});

  // Source: float k at vec4 component k (a pattern that a stale or partial copy cannot match);
  // destination cleared to -1.
  std::vector<float> pattern(4 * std::min<std::size_t>(count, std::size_t(1) << 20));
  for (std::size_t k = 0; k < pattern.size(); ++k) pattern[k] = static_cast<float>(k % 16777216);
  allocate_storage_buffer(objects.buffers[0], options.bytes, nullptr, "stream bandwidth: source buffer");
  for (std::size_t at = 0; at < count; at += pattern.size() / 4) {
    const std::size_t n = std::min(pattern.size() / 4, count - at);
    glBufferSubData(GL_SHADER_STORAGE_BUFFER, static_cast<GLintptr>(16 * at), static_cast<GLsizeiptr>(16 * n),
                    pattern.data());
  }
  allocate_storage_buffer(objects.buffers[1], options.bytes, nullptr, "stream bandwidth: destination buffer");
  const float minus_one = -1.0f;
  glClearBufferData(GL_SHADER_STORAGE_BUFFER, GL_R32F, GL_RED, GL_FLOAT, &minus_one);
  check_gl("stream bandwidth: destination buffer");

  glUseProgram(objects.program);
  glUniform1ui(glGetUniformLocation(objects.program, "u_count"), static_cast<GLuint>(count));
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 0, objects.buffers[0]);
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 1, objects.buffers[1]);
  auto copies = [&](int k) {
    for (int i = 0; i < k; ++i) {
      glDispatchCompute(columns, rows, 1);
      glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT);
    }
    glFinish();
  };
  copies(1);  // warm-up: first touch of the pages, program upload
  check_gl("stream bandwidth: copy");

  StreamBandwidth result;
  result.bytes = options.bytes;
  using clock = std::chrono::steady_clock;
  for (int rep = 0; rep < options.repetitions; ++rep) {
    int k = 1;
    for (;;) {
      const auto t0 = clock::now();
      copies(k);
      const double s = std::chrono::duration<double>(clock::now() - t0).count();
      if (s >= options.min_seconds || k >= (1 << 16)) {
        const double rate = 2.0 * static_cast<double>(options.bytes) * k / s / 1e9;
        if (rate > result.gb_per_second) result = {rate, options.bytes, k, s};
        break;
      }
      k *= 2;
    }
  }

  // The copy must be exact: the destination's first and last vec4s equal the source's.
  const std::size_t check = std::min<std::size_t>(count, 4096);
  std::vector<float> head(4 * check), tail(4 * check);
  glMemoryBarrier(GL_BUFFER_UPDATE_BARRIER_BIT);
  glBindBuffer(GL_SHADER_STORAGE_BUFFER, objects.buffers[1]);
  glGetBufferSubData(GL_SHADER_STORAGE_BUFFER, 0, static_cast<GLsizeiptr>(16 * check), head.data());
  glGetBufferSubData(GL_SHADER_STORAGE_BUFFER, static_cast<GLintptr>(16 * (count - check)),
                     static_cast<GLsizeiptr>(16 * check), tail.data());
  check_gl("stream bandwidth: read back");
  const std::size_t period = pattern.size() / 4;
  for (std::size_t v = 0; v < check; ++v)
    for (int c = 0; c < 4; ++c) {
      const std::size_t last = count - check + v;
      if (head[4 * v + c] != pattern[4 * (v % period) + c] || tail[4 * v + c] != pattern[4 * (last % period) + c])
        throw GpuError("stream bandwidth: the copy kernel did not copy the buffer (vec4 " + std::to_string(v) +
                       " differs); the device's compute shaders are not working");
    }
  if (!(result.gb_per_second > 0.0) || !std::isfinite(result.gb_per_second))
    throw GpuError("stream bandwidth: no timing could be taken");
  return result;
}

}  // namespace fascicle::shaders
