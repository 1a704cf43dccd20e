// Offscreen OpenGL pictures of render scenes (see render_view.h).

#include "shaders/render_view.h"

#include "geometry/errors.h"

#include <GL/glew.h>

#include <algorithm>
#include <cmath>
#include <numeric>

namespace fascicle::shaders {

namespace {

// GL objects of one render, released on every path out.
struct GlObjects {
  GLuint framebuffers[2] = {0, 0};
  GLuint renderbuffers[3] = {0, 0, 0};  // MSAA colour, MSAA depth, resolved colour
  GLuint vertex_arrays[2] = {0, 0};     // surface, lines
  GLuint buffers[3] = {0, 0, 0};        // surface vertices, surface indices, line vertices
  GlObjects() = default;
  GlObjects(const GlObjects&) = delete;
  GlObjects& operator=(const GlObjects&) = delete;
  ~GlObjects() {
    glBindFramebuffer(GL_FRAMEBUFFER, 0);
    glBindVertexArray(0);
    glDeleteFramebuffers(2, framebuffers);
    glDeleteRenderbuffers(3, renderbuffers);
    glDeleteVertexArrays(2, vertex_arrays);
    glDeleteBuffers(3, buffers);
  }
};

// Column-major 4x4 matrices for glUniformMatrix4fv.
using Mat4 = std::array<float, 16>;

// Scene (relative to `origin`) -> view space: x = right, y = up, z = -forward (towards the viewer),
// with the camera's centre at the view-space origin.
Mat4 view_matrix(const Camera& c, const Vec3& origin) {
  const Vec3 rows[3] = {c.right, c.up, -c.forward};
  const Vec3 shift = c.centre - origin;
  Mat4 m{};
  for (int r = 0; r < 3; ++r) {
    for (int col = 0; col < 3; ++col) m[col * 4 + r] = static_cast<float>(rows[r][col]);
    m[12 + r] = static_cast<float>(-rows[r].dot(shift));
  }
  m[15] = 1.0f;
  return m;
}

// Orthographic: x / half_width, y / half_height, depth d = -z in [near, far] -> [-1, 1].
Mat4 projection_matrix(const Camera& c) {
  Mat4 m{};
  m[0] = static_cast<float>(1.0 / c.half_width);
  m[5] = static_cast<float>(1.0 / c.half_height);
  const double range = c.far - c.near;
  m[10] = static_cast<float>(-2.0 / range);
  m[14] = static_cast<float>(-2.0 * c.near / range - 1.0);
  m[15] = 1.0f;
  return m;
}

struct SurfaceVertex {
  float position[3];
  float normal[3];
  float colour[4];
};

struct LineVertex {
  float position[3];
  float colour[4];
  float width;
};

}  // namespace

void RenderOptions::validate() const {
  if (views < 1 || views > 64) throw OptionError("views: must be in [1, 64], got " + std::to_string(views));
  if (width < 16 || width > 8192 || height < 16 || height > 8192)
    throw OptionError("size: each side must be in [16, 8192] pixels, got " + std::to_string(width) + "x" +
                      std::to_string(height));
  for (float v : {background.r, background.g, background.b, background.a})
    if (!(v >= 0.0f && v <= 1.0f)) throw OptionError("background: channels must be in [0, 1]");
  if (!(std::abs(elevation_deg) < 90.0))
    throw OptionError("elevation: must be in (-90, 90) degrees, got " + std::to_string(elevation_deg));
  if (!std::isfinite(azimuth_deg)) throw OptionError("azimuth: must be a finite number of degrees");
  if (samples < 1 || samples > 32) throw OptionError("samples: must be in [1, 32], got " + std::to_string(samples));
  if (!(line_scale > 0.0f && line_scale <= 100.0f))
    throw OptionError("line_scale: must be in (0, 100], got " + std::to_string(line_scale));
}

ViewLayout view_layout(const RenderOptions& options) {
  ViewLayout layout;
  layout.views = options.views;
  layout.aspect = static_cast<double>(options.width) / options.height;
  layout.elevation_deg = options.elevation_deg;
  layout.azimuth_deg = options.azimuth_deg;
  layout.axis_up = options.axis_up;
  return layout;
}

std::array<int, 2> tile_grid(int views) {
  FASCICLE_CHECK(views >= 1, "tile_grid needs at least one view");
  int cols = static_cast<int>(std::ceil(std::sqrt(static_cast<double>(views))));
  while (cols * cols < views) ++cols;
  while ((cols - 1) * (cols - 1) >= views) --cols;
  const int rows = (views + cols - 1) / cols;
  return {cols, rows};
}

Renderer::Renderer(const GlContext& context) : context_(context) {
  context_.make_current();
  surface_program_ = compile_program({"render_surface.vert", "render_surface.frag"});
  try {
    line_program_ = compile_program({"render_line.vert", "render_line.geom", "render_line.frag"});
  } catch (...) {
    glDeleteProgram(surface_program_);
    throw;
  }
}

Renderer::~Renderer() {
  glDeleteProgram(surface_program_);
  glDeleteProgram(line_program_);
}

Image Renderer::render(const RenderScene& scene, const RenderOptions& options) {
  options.validate();
  FASCICLE_CHECK(scene.triangle_colours.size() == scene.surface_triangles.size(),
                 "render scene: one colour per triangle");
  for (const Triangle& t : scene.surface_triangles)
    for (int i : t)
      FASCICLE_CHECK(i >= 0 && static_cast<std::size_t>(i) < scene.surface_points.size(),
                     "render scene: triangle index out of range");
  for (const SceneLine& l : scene.lines)
    FASCICLE_CHECK(l.colours.size() == l.points.size(), "render scene: one colour per line point");

  const std::vector<Camera> cameras = view_cameras(scene, view_layout(options));
  const SceneBounds bounds = scene_bounds(scene);
  const Vec3 origin = 0.5 * (bounds.lo + bounds.hi);  // float positions relative to the centre

  const auto [cols, rows] = tile_grid(options.views);
  const int W = cols * options.width, H = rows * options.height;

  context_.make_current();
  while (glGetError() != GL_NO_ERROR) {}
  GLint max_renderbuffer = 0, max_samples = 1, max_viewport[2] = {0, 0};
  glGetIntegerv(GL_MAX_RENDERBUFFER_SIZE, &max_renderbuffer);
  glGetIntegerv(GL_MAX_SAMPLES, &max_samples);
  glGetIntegerv(GL_MAX_VIEWPORT_DIMS, max_viewport);
  const int limit = std::min<int>(max_renderbuffer, std::min(max_viewport[0], max_viewport[1]));
  if (W > limit || H > limit)
    throw OptionError("size: the tiled picture " + std::to_string(W) + "x" + std::to_string(H) +
                      " exceeds the device's framebuffer limit of " + std::to_string(limit) + " pixels a side");
  samples_used_ = std::max(1, std::min(options.samples, static_cast<int>(max_samples)));

  GlObjects gl;
  // Framebuffers: multisampled colour + depth, and a single-sample one to resolve into.
  glGenFramebuffers(2, gl.framebuffers);
  glGenRenderbuffers(3, gl.renderbuffers);
  glBindRenderbuffer(GL_RENDERBUFFER, gl.renderbuffers[0]);
  glRenderbufferStorageMultisample(GL_RENDERBUFFER, samples_used_, GL_RGBA8, W, H);
  glBindRenderbuffer(GL_RENDERBUFFER, gl.renderbuffers[1]);
  glRenderbufferStorageMultisample(GL_RENDERBUFFER, samples_used_, GL_DEPTH_COMPONENT24, W, H);
  glBindRenderbuffer(GL_RENDERBUFFER, gl.renderbuffers[2]);
  glRenderbufferStorage(GL_RENDERBUFFER, GL_RGBA8, W, H);
  check_gl("render: framebuffer storage");
  glBindFramebuffer(GL_FRAMEBUFFER, gl.framebuffers[0]);
  glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, gl.renderbuffers[0]);
  glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, gl.renderbuffers[1]);
  if (glCheckFramebufferStatus(GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE)
    throw GpuError("OpenGL: render: the multisampled framebuffer is incomplete");
  glBindFramebuffer(GL_FRAMEBUFFER, gl.framebuffers[1]);
  glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, gl.renderbuffers[2]);
  if (glCheckFramebufferStatus(GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE)
    throw GpuError("OpenGL: render: the resolve framebuffer is incomplete");

  // Surface vertices: three per triangle (each triangle has its own colour), with the smooth
  // normal of the shared vertex (area-weighted face normals; zero where they cancel).
  std::vector<Vec3> normals(scene.surface_points.size(), Vec3::Zero());
  for (const Triangle& t : scene.surface_triangles) {
    const Vec3& a = scene.surface_points[t[0]];
    const Vec3 n = (scene.surface_points[t[1]] - a).cross(scene.surface_points[t[2]] - a);
    for (int i : t) normals[i] += n;
  }
  for (Vec3& n : normals) {
    const double length = n.norm();
    n = length > 0.0 ? Vec3(n / length) : Vec3::Zero();
  }
  std::vector<SurfaceVertex> surface;
  surface.reserve(scene.surface_triangles.size() * 3);
  for (std::size_t f = 0; f < scene.surface_triangles.size(); ++f) {
    const Rgba& c = scene.triangle_colours[f];
    for (int i : scene.surface_triangles[f]) {
      const Vec3 p = scene.surface_points[i] - origin;
      const Vec3& n = normals[i];
      surface.push_back(SurfaceVertex{{static_cast<float>(p.x()), static_cast<float>(p.y()), static_cast<float>(p.z())},
                                      {static_cast<float>(n.x()), static_cast<float>(n.y()), static_cast<float>(n.z())},
                                      {c.r, c.g, c.b, c.a}});
    }
  }
  // Line vertices: GL_LINES pairs.
  std::vector<LineVertex> lines;
  for (const SceneLine& l : scene.lines)
    for (std::size_t i = 1; i < l.points.size(); ++i)
      for (std::size_t k : {i - 1, i}) {
        const Vec3 p = l.points[k] - origin;
        const Rgba& c = l.colours[k];
        lines.push_back(LineVertex{{static_cast<float>(p.x()), static_cast<float>(p.y()), static_cast<float>(p.z())},
                                   {c.r, c.g, c.b, c.a},
                                   l.width_px});
      }

  glGenVertexArrays(2, gl.vertex_arrays);
  glGenBuffers(3, gl.buffers);
  glBindVertexArray(gl.vertex_arrays[0]);
  glBindBuffer(GL_ARRAY_BUFFER, gl.buffers[0]);
  glBufferData(GL_ARRAY_BUFFER, static_cast<GLsizeiptr>(surface.size() * sizeof(SurfaceVertex)),
               surface.empty() ? nullptr : surface.data(), GL_STATIC_DRAW);
  glEnableVertexAttribArray(0);
  glVertexAttribPointer(0, 3, GL_FLOAT, GL_FALSE, sizeof(SurfaceVertex),
                        reinterpret_cast<const void*>(offsetof(SurfaceVertex, position)));
  glEnableVertexAttribArray(1);
  glVertexAttribPointer(1, 3, GL_FLOAT, GL_FALSE, sizeof(SurfaceVertex),
                        reinterpret_cast<const void*>(offsetof(SurfaceVertex, normal)));
  glEnableVertexAttribArray(2);
  glVertexAttribPointer(2, 4, GL_FLOAT, GL_FALSE, sizeof(SurfaceVertex),
                        reinterpret_cast<const void*>(offsetof(SurfaceVertex, colour)));
  glBindBuffer(GL_ELEMENT_ARRAY_BUFFER, gl.buffers[1]);
  glBufferData(GL_ELEMENT_ARRAY_BUFFER, static_cast<GLsizeiptr>(surface.size() * sizeof(GLuint)), nullptr,
               GL_STREAM_DRAW);
  glBindVertexArray(gl.vertex_arrays[1]);
  glBindBuffer(GL_ARRAY_BUFFER, gl.buffers[2]);
  glBufferData(GL_ARRAY_BUFFER, static_cast<GLsizeiptr>(lines.size() * sizeof(LineVertex)),
               lines.empty() ? nullptr : lines.data(), GL_STATIC_DRAW);
  glEnableVertexAttribArray(0);
  glVertexAttribPointer(0, 3, GL_FLOAT, GL_FALSE, sizeof(LineVertex),
                        reinterpret_cast<const void*>(offsetof(LineVertex, position)));
  glEnableVertexAttribArray(1);
  glVertexAttribPointer(1, 4, GL_FLOAT, GL_FALSE, sizeof(LineVertex),
                        reinterpret_cast<const void*>(offsetof(LineVertex, colour)));
  glEnableVertexAttribArray(2);
  glVertexAttribPointer(2, 1, GL_FLOAT, GL_FALSE, sizeof(LineVertex),
                        reinterpret_cast<const void*>(offsetof(LineVertex, width)));
  glBindVertexArray(0);
  check_gl("render: vertex upload");

  glBindFramebuffer(GL_FRAMEBUFFER, gl.framebuffers[0]);
  glDisable(GL_SCISSOR_TEST);
  glViewport(0, 0, W, H);
  glClearColor(options.background.r, options.background.g, options.background.b, 1.0f);
  glClearDepth(1.0);
  glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
  glEnable(GL_MULTISAMPLE);
  glEnable(GL_DEPTH_TEST);
  glDepthFunc(GL_LEQUAL);
  glDisable(GL_CULL_FACE);

  const float width_scale = options.line_scale * static_cast<float>(options.height) / 600.0f;
  std::vector<GLuint> order(scene.surface_triangles.size());
  std::vector<float> depth(scene.surface_triangles.size());
  std::vector<GLuint> indices(surface.size());
  for (int v = 0; v < options.views; ++v) {
    const Camera& camera = cameras[v];
    const int col = v % cols, row = v / cols;
    glViewport(col * options.width, (rows - 1 - row) * options.height, options.width, options.height);
    const Mat4 view = view_matrix(camera, origin), projection = projection_matrix(camera);

    // Opaque lines first, writing depth.
    if (!lines.empty()) {
      glUseProgram(line_program_);
      glUniformMatrix4fv(glGetUniformLocation(line_program_, "u_view"), 1, GL_FALSE, view.data());
      glUniformMatrix4fv(glGetUniformLocation(line_program_, "u_projection"), 1, GL_FALSE, projection.data());
      glUniform2f(glGetUniformLocation(line_program_, "u_viewport"), static_cast<float>(options.width),
                  static_cast<float>(options.height));
      glUniform1f(glGetUniformLocation(line_program_, "u_width_scale"), width_scale);
      glDisable(GL_BLEND);
      glDepthMask(GL_TRUE);
      glBindVertexArray(gl.vertex_arrays[1]);
      glDrawArrays(GL_LINES, 0, static_cast<GLsizei>(lines.size()));
    }
    // Translucent surfaces, back to front, blended, without depth writes.
    if (!surface.empty()) {
      for (std::size_t f = 0; f < scene.surface_triangles.size(); ++f) {
        const Triangle& t = scene.surface_triangles[f];
        const Vec3 centroid = (scene.surface_points[t[0]] + scene.surface_points[t[1]] + scene.surface_points[t[2]]);
        depth[f] = static_cast<float>(camera.forward.dot(centroid));
      }
      std::iota(order.begin(), order.end(), 0u);
      std::stable_sort(order.begin(), order.end(), [&](GLuint a, GLuint b) { return depth[a] > depth[b]; });
      for (std::size_t k = 0; k < order.size(); ++k)
        for (GLuint c = 0; c < 3; ++c) indices[3 * k + c] = 3 * order[k] + c;
      glUseProgram(surface_program_);
      glUniformMatrix4fv(glGetUniformLocation(surface_program_, "u_view"), 1, GL_FALSE, view.data());
      glUniformMatrix4fv(glGetUniformLocation(surface_program_, "u_projection"), 1, GL_FALSE, projection.data());
      glEnable(GL_BLEND);
      glBlendFuncSeparate(GL_SRC_ALPHA, GL_ONE_MINUS_SRC_ALPHA, GL_ONE, GL_ONE_MINUS_SRC_ALPHA);
      glDepthMask(GL_FALSE);
      glBindVertexArray(gl.vertex_arrays[0]);
      glBufferSubData(GL_ELEMENT_ARRAY_BUFFER, 0, static_cast<GLsizeiptr>(indices.size() * sizeof(GLuint)),
                      indices.data());
      glDrawElements(GL_TRIANGLES, static_cast<GLsizei>(indices.size()), GL_UNSIGNED_INT, nullptr);
      glDepthMask(GL_TRUE);
      glDisable(GL_BLEND);
    }
    check_gl("render: drawing a view");
  }
  glBindVertexArray(0);
  glUseProgram(0);

  // Resolve the samples and read the picture back (GL rows run bottom to top).
  glBindFramebuffer(GL_READ_FRAMEBUFFER, gl.framebuffers[0]);
  glBindFramebuffer(GL_DRAW_FRAMEBUFFER, gl.framebuffers[1]);
  glBlitFramebuffer(0, 0, W, H, 0, 0, W, H, GL_COLOR_BUFFER_BIT, GL_NEAREST);
  glBindFramebuffer(GL_READ_FRAMEBUFFER, gl.framebuffers[1]);
  std::vector<std::uint8_t> rgba(static_cast<std::size_t>(W) * H * 4);
  glPixelStorei(GL_PACK_ALIGNMENT, 1);
  glReadPixels(0, 0, W, H, GL_RGBA, GL_UNSIGNED_BYTE, rgba.data());
  check_gl("render: reading the picture back");

  Image image;
  image.width = W;
  image.height = H;
  image.rgb.resize(static_cast<std::size_t>(W) * H * 3);
  for (int y = 0; y < H; ++y) {
    const std::uint8_t* src = &rgba[static_cast<std::size_t>(H - 1 - y) * W * 4];
    std::uint8_t* dst = &image.rgb[static_cast<std::size_t>(y) * W * 3];
    for (int x = 0; x < W; ++x)
      for (int c = 0; c < 3; ++c) dst[3 * x + c] = src[4 * x + c];
  }
  return image;
}

}  // namespace fascicle::shaders
