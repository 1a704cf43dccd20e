// fascicle render MESH [FIBRES] -o view.png [--views N] [--size WxH] [--background white|black]
//                 [--origin POINTS] [--insertion POINTS]
// fascicle render --template parallel|pennate|curved|fanned|rectus -o t.png
// Pictures through headless OpenGL (shaders/render_view.h): the muscle translucent with its
// fibres coloured from origin to insertion, from N views around its long axis, tiled into one
// PNG; or a fibre template in its unit cube with its attachment areas.

#include "app/commands.h"
#include "geometry/atomic_file.h"
#include "geometry/errors.h"
#include "geometry/mesh_io.h"
#include "geometry/mesh_stats.h"
#include "geometry/read_points.h"
#ifdef FASCICLE_HAVE_SHADERS
#include "shaders/gl_context.h"
#include "shaders/render_png.h"
#include "shaders/render_scene.h"
#include "shaders/render_view.h"
#endif

#include <spdlog/spdlog.h>

#include <chrono>
#include <cstdlib>
#include <memory>
#include <optional>
#include <string>
#include <tuple>
#include <utility>

namespace fascicle::app {

namespace {

struct RenderArgs {
  std::string mesh, fibres, output, size, background = "white", template_name, origin, insertion;
  std::optional<int> views;  // default: 4 for a muscle, 2 for a template
  int gl_device = -1;
  std::optional<double> elevation, azimuth;
  std::optional<double> line_scale;  // default: 1, 1.5 for a template
};

// "WxH" -> {W, H}. Throws OptionError naming --size.
std::pair<int, int> parse_size(const std::string& text) {
  const std::size_t x = text.find_first_of("xX");
  auto number = [&](const std::string& part) {
    if (part.empty() || part.size() > 6 || part.find_first_not_of("0123456789") != std::string::npos)
      throw OptionError("--size: expected WIDTHxHEIGHT in pixels (e.g. 800x600), got '" + text + "'");
    return std::atoi(part.c_str());
  };
  if (x == std::string::npos)
    throw OptionError("--size: expected WIDTHxHEIGHT in pixels (e.g. 800x600), got '" + text + "'");
  return {number(text.substr(0, x)), number(text.substr(x + 1))};
}

void run_render(const RenderArgs& args) {
  const bool is_template = !args.template_name.empty();
  if (is_template && !args.mesh.empty())
    throw OptionError("--template draws a template; it takes no MESH (got " + args.mesh + ")");
  if (!is_template && args.mesh.empty()) throw Error(ErrorCode::usage, "render: give a MESH file or --template NAME");
  if (lower_extension(args.output) != "png")
    throw InputError(ErrorCode::unknown_format, args.output + ": the picture must be a .png file");
  if (is_template && (!args.origin.empty() || !args.insertion.empty()))
    throw OptionError("--origin and --insertion mark a muscle's landmarks; a --template picture has none");
#ifdef FASCICLE_HAVE_SHADERS
  shaders::RenderOptions options;
  options.views = args.views ? *args.views : 4;
  if (is_template) {
    options.width = 250;  // 500 x 500 in all: docs/templates/*.png stay below 150 kB
    options.height = 250;
    options.axis_up = true;
    options.elevation_deg = 22.0;
    options.azimuth_deg = -62.0;
  }
  if (!args.size.empty()) std::tie(options.width, options.height) = parse_size(args.size);
  if (args.background == "white")
    options.background = shaders::Rgba{1, 1, 1, 1};
  else if (args.background == "black")
    options.background = shaders::Rgba{0, 0, 0, 1};
  else
    throw OptionError("--background: must be white or black, got '" + args.background + "'");
  if (args.elevation) options.elevation_deg = *args.elevation;
  if (args.azimuth) options.azimuth_deg = *args.azimuth;
  options.line_scale = static_cast<float>(args.line_scale ? *args.line_scale : (is_template ? 1.5 : 1.0));
  options.validate();

  shaders::RenderScene scene;
  std::string what;
  if (is_template) {
    const springs::TemplateKind kind = springs::parse_template_kind(args.template_name);
    scene = shaders::template_scene(kind);
    what = std::string("template ") + springs::template_name(kind);
  } else {
    check_not_same_file(args.mesh, args.output);
    const PolygonSoup soup = read_polygon_soup(args.mesh);
    std::optional<Polylines> fibres;
    if (!args.fibres.empty()) {
      check_not_same_file(args.fibres, args.output);
      fibres = read_polylines(args.fibres);
    }
    // Landmarks, read before the picture is drawn so that a bad file costs no rendering.
    std::vector<Vec3> origin, insertion;
    for (const std::string* path : {&args.origin, &args.insertion})
      if (!path->empty()) check_not_same_file(*path, args.output);
    if (!args.origin.empty()) origin = read_points(args.origin);
    if (!args.insertion.empty()) insertion = read_points(args.insertion);
    scene = shaders::muscle_scene(soup, fibres ? &*fibres : nullptr, args.mesh);
    // Markers a hundredth of the muscle's bounding-box diagonal long each way: about the radius
    // within which decompose counts a surface point as on an area.
    const double size = 0.01 * bounding_box(scene.surface_points).diagonal();
    shaders::add_markers(scene, origin, shaders::origin_colour(), size);
    shaders::add_markers(scene, insertion, shaders::insertion_colour(), size);
    what = args.mesh + " (" + std::to_string(scene.surface_triangles.size()) + " triangles" +
           (fibres ? ", " + std::to_string(fibres->lines.size()) + " fibres" : std::string()) +
           (origin.size() + insertion.size() > 0
                ? ", " + std::to_string(origin.size() + insertion.size()) + " landmarks"
                : std::string()) +
           ")";
  }

  shaders::GlContextOptions context_options;
  context_options.device = args.gl_device;
  const auto start = std::chrono::steady_clock::now();
  shaders::GlContext context(context_options);
  shaders::Renderer renderer(context);
  const shaders::Image image = renderer.render(scene, options);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  shaders::write_png(args.output, image);
  spdlog::info("wrote {}: {} x {} px, {} view(s) of {}; {} ({}x MSAA), {:.2f} s", args.output, image.width,
               image.height, options.views, what, context.renderer(), renderer.samples_used(), seconds);
#else
  throw Error(ErrorCode::gpu, "render: this build has no OpenGL (OpenGL, EGL or GLEW was not found when it was built)");
#endif
}

}  // namespace

void add_render_command(CLI::App& app) {
  auto args = std::make_shared<RenderArgs>();
  CLI::App* cmd =
      app.add_subcommand("render",
                         "Draw a muscle (translucent) with its fibres coloured from origin to insertion, from N views "
                         "around its long axis, into one PNG (headless OpenGL; software rendering works); or a fibre "
                         "template with --template");
  cmd->add_option("mesh", args->mesh, "Muscle surface (any mesh format read; need not be repaired)");
  cmd->add_option("fibres", args->fibres, "Fibres as polylines (.vtk, .obj), each from origin to insertion");
  cmd->add_option("-o,--output", args->output, "Output picture (.png)")->required();
  cmd->add_option("--views", args->views, "Views around the long axis, tiled (default 4)");
  cmd->add_option("--size", args->size, "Pixels of one view, WxH (default 800x600; 250x250 for --template)");
  cmd->add_option("--background", args->background, "white or black")->capture_default_str();
  cmd->add_option("--template", args->template_name,
                  "Draw this fibre template instead of a muscle: parallel, pennate, curved, fanned, rectus");
  cmd->add_option("--elevation", args->elevation,
                  "Tilt of the views towards the axis, degrees (default 0; 22 "
                  "for --template)");
  cmd->add_option("--azimuth", args->azimuth, "Turn of the first view around the axis, degrees (default 0)");
  cmd->add_option("--origin", args->origin,
                  "Mark these origin landmark points in red (x y z rows, CSV, 3D Slicer .fcsv / .mrk.json, as "
                  "decompose reads them)");
  cmd->add_option("--insertion", args->insertion, "Mark these insertion landmark points in green");
  cmd->add_option("--line-scale", args->line_scale, "Multiplies the line widths (default 1; 1.5 for --template)");
  cmd->add_option("--gl-device", args->gl_device, "EGL device index (-1: first hardware device, else software)")
      ->capture_default_str();
  cmd->callback([args] { run_render(*args); });
}

}  // namespace fascicle::app
