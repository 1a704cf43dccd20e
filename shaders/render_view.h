#pragma once
/// \file render_view.h
/// Offscreen OpenGL pictures of a RenderScene (render_scene.h): N views around the scene's
/// principal axis tiled into one picture, drawn into a multisampled framebuffer of a headless
/// context (gl_context.h; Mesa's llvmpipe is enough). Lines are opaque screen-space ribbons
/// (geometry shader render_line.geom), drawn first with depth writes; the translucent surfaces
/// follow, their triangles sorted back to front for each view on the CPU (painter's order by
/// centroid depth) and blended over what is behind them without depth writes, both faces, lit by
/// a headlight (Lambert + Blinn-Phong) with opacity rising towards silhouettes so the outline
/// reads while the fibres inside stay visible.

#include "shaders/gl_context.h"
#include "shaders/render_scene.h"

#include <array>

namespace fascicle::shaders {

/// Options of one rendered picture.
struct RenderOptions {
  int views = 4;                  ///< views around the axis, tiled (default 4, in [1, 64])
  int width = 800, height = 600;  ///< pixels of one view (default 800 x 600, each in [16, 8192])
  Rgba background{1, 1, 1, 1};    ///< clear colour (default white)
  double elevation_deg = 0;       ///< views tilted towards the axis (default 0; templates use 25)
  double azimuth_deg = 0;         ///< turn of the first view around the axis (default 0)
  bool axis_up = false;           ///< axis vertical on screen (default false: horizontal)
  int samples = 8;                ///< multisampling, clamped to GL_MAX_SAMPLES (default 8, in [1, 32])
  float line_scale = 1.0f;        ///< multiplies every line width (default 1; widths also scale
                                  ///< with the view height / 600)
  /// Throws OptionError naming the field.
  void validate() const;
};

/// The camera layout of a render: views, aspect width / height, elevation, azimuth, axis_up.
ViewLayout view_layout(const RenderOptions& options);

/// Columns and rows of the tiling of `views` pictures: cols = ceil(sqrt(views)),
/// rows = ceil(views / cols) (4 -> 2 x 2, 3 -> 2 x 2, 2 -> 2 x 1). View v is at column v % cols,
/// row v / cols, rows from the top; unused tiles stay background.
std::array<int, 2> tile_grid(int views);

/// Draws scenes. Build once per context (compiles the programs), render many times; use on the
/// thread that holds `context`. Non-copyable.
class Renderer {
 public:
  /// Compiles the render programs on `context` (made current). Throws GpuError with the
  /// driver's log when a shader does not compile.
  explicit Renderer(const GlContext& context);
  ~Renderer();
  Renderer(const Renderer&) = delete;
  Renderer& operator=(const Renderer&) = delete;

  /// Draws `scene` from options.views cameras (view_cameras with the options' layout) into one
  /// picture of (cols * width) x (rows * height) pixels (tile_grid). Throws OptionError for bad
  /// options or a picture above the device's framebuffer limits, Error(internal) for an empty
  /// scene or lines whose colours do not match their points, GpuError for GL failures.
  Image render(const RenderScene& scene, const RenderOptions& options);

  /// Multisample count used by the last render (after clamping to the device).
  int samples_used() const { return samples_used_; }

 private:
  const GlContext& context_;
  unsigned surface_program_ = 0, line_program_ = 0;
  int samples_used_ = 0;
};

}  // namespace fascicle::shaders
