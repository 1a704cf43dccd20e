// Pictures of `fascicle render` (shaders/render_*): the colour map, the cameras and the PNG
// round trip on the CPU; then real renders on the software renderer ([gpu]): a capsule with
// fibres along it, read back from the PNG: picture size, background pixels, the mesh over the
// centre, the colour ramp from origin to insertion; and the command's exit codes.

#ifdef FASCICLE_HAVE_SHADERS

#include "geometry/errors.h"
#include "geometry/mesh_io.h"
#include "geometry/primitives.h"
#include "shaders/gl_context.h"
#include "shaders/render_png.h"
#include "shaders/render_scene.h"
#include "shaders/render_view.h"
#include "test_common.h"

#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <memory>

using namespace fascicle;
using namespace fascicle::shaders;

namespace {

// One context for the whole executable (llvmpipe start-up costs).
GlContext& context() {
  static std::unique_ptr<GlContext> instance = std::make_unique<GlContext>();
  instance->make_current();
  return *instance;
}

constexpr double kLength = 80.0, kRadius = 12.0, kFibreHalf = 30.0;

// A capsule along x (80 long, radius 12) and five straight fibres inside it, x from -30
// (origin) to +30 (insertion): one on the axis, four 5 off it.
PolygonSoup capsule() { return to_soup(make_capsule(kLength, kRadius, 32)); }

Polylines fibres() {
  Polylines lines;
  const double offsets[5][2] = {{0, 0}, {5, 0}, {-5, 0}, {0, 5}, {0, -5}};
  for (const auto& o : offsets) {
    std::vector<Vec3> line;
    for (int k = 0; k <= 20; ++k) line.emplace_back(-kFibreHalf + 2.0 * kFibreHalf * k / 20.0, o[0], o[1]);
    lines.lines.push_back(line);
  }
  return lines;
}

// Pixel of scene point p in view v of a tiled picture.
std::array<int, 2> project(const Camera& c, const RenderOptions& options, int v, const Vec3& p) {
  const auto grid = tile_grid(options.views);
  const int col = v % grid[0], row = v / grid[0];
  const double x = 0.5 + 0.5 * c.right.dot(p - c.centre) / c.half_width;
  const double y = 0.5 - 0.5 * c.up.dot(p - c.centre) / c.half_height;
  return {col * options.width + static_cast<int>(std::floor(x * options.width)),
          row * options.height + static_cast<int>(std::floor(y * options.height))};
}

bool equals(const std::array<std::uint8_t, 3>& p, int r, int g, int b) { return p[0] == r && p[1] == g && p[2] == b; }

double hue_of(const std::array<std::uint8_t, 3>& p) { return hue_degrees(p[0], p[1], p[2]); }

double hue_distance(double a, double b) {
  const double d = std::abs(a - b);
  return std::min(d, 360.0 - d);
}

}  // namespace

TEST_CASE("fibre colour map runs from viridis purple to yellow with distinct hues", "[render]") {
  const Rgba a = fibre_colour(0.0), b = fibre_colour(1.0), mid = fibre_colour(0.5);
  CHECK(std::lround(a.r * 255) == 68);
  CHECK(std::lround(a.g * 255) == 1);
  CHECK(std::lround(a.b * 255) == 84);
  CHECK(std::lround(b.r * 255) == 253);
  CHECK(std::lround(b.g * 255) == 231);
  CHECK(std::lround(b.b * 255) == 37);
  CHECK(fibre_colour(-3.0).r == a.r);
  CHECK(fibre_colour(7.0).g == b.g);
  // Lightness (Rec. 709 luma) rises monotonically along the map: perceptual ordering.
  double previous = -1.0;
  for (int i = 0; i <= 50; ++i) {
    const Rgba c = fibre_colour(i / 50.0);
    const double luma = 0.2126 * c.r + 0.7152 * c.g + 0.0722 * c.b;
    CHECK(luma > previous);
    previous = luma;
  }
  CHECK(hue_distance(hue_degrees(68, 1, 84), hue_degrees(253, 231, 37)) > 90.0);
  CHECK(mid.g > mid.r);  // teal-green in the middle
  CHECK(hue_degrees(255, 0, 0) == Approx(0.0));
  CHECK(hue_degrees(0, 255, 0) == Approx(120.0));
  CHECK(hue_degrees(0, 0, 255) == Approx(240.0));
  CHECK(hue_degrees(9, 9, 9) == 0.0);
}

TEST_CASE("views turn around the long axis, origin to the left, all framed at one scale", "[render]") {
  RenderScene scene = muscle_scene(capsule(), nullptr, "capsule");
  const Vec3 axis = principal_axis(scene);
  CHECK(std::abs(axis.x()) == Approx(1.0).margin(1e-6));
  // Fibres reversed (origin at +x): the axis turns so the origin is on the left of every view.
  Polylines reversed = fibres();
  for (auto& line : reversed.lines) std::reverse(line.begin(), line.end());
  add_fibres(scene, reversed);
  REQUIRE(scene.has_axis_ends);
  ViewLayout layout;
  layout.views = 5;
  const std::vector<Camera> cameras = view_cameras(scene, layout);
  REQUIRE(cameras.size() == 5);
  for (const Camera& c : cameras) {
    CHECK(c.right.x() == Approx(-1.0).margin(1e-9));  // right = -x: origin (x = +30) on the left
    CHECK(c.right.dot(c.up) == Approx(0.0).margin(1e-12));
    CHECK(c.right.cross(c.up).dot(-c.forward) == Approx(1.0));  // right-handed
    CHECK(c.half_width == cameras[0].half_width);
    CHECK(c.half_width / c.half_height == Approx(layout.aspect));
    // Every point inside the frame, the widest extent filling it up to the margin.
    for (const Vec3& p : scene.surface_points) {
      CHECK(std::abs(c.right.dot(p - c.centre)) <= c.half_width);
      CHECK(std::abs(c.up.dot(p - c.centre)) <= c.half_height);
      CHECK(std::abs(c.forward.dot(p - c.centre)) <= c.far);
    }
    CHECK(c.half_width == Approx(0.5 * kLength * (1.0 + layout.margin)).epsilon(1e-3));
  }
  // Views are evenly spaced: consecutive viewing directions 72 degrees apart.
  CHECK(cameras[0].forward.dot(cameras[1].forward) == Approx(std::cos(2.0 * 3.14159265358979 / 5)).margin(1e-9));
  layout.views = 0;
  CHECK_THROWS_AS(view_cameras(scene, layout), OptionError);
  CHECK_THROWS_AS(view_cameras(RenderScene{}, ViewLayout{}), Error);
}

TEST_CASE("tile grid, template scenes and PNG round trip", "[render]") {
  CHECK(tile_grid(1) == std::array<int, 2>{1, 1});
  CHECK(tile_grid(2) == std::array<int, 2>{2, 1});
  CHECK(tile_grid(3) == std::array<int, 2>{2, 2});
  CHECK(tile_grid(4) == std::array<int, 2>{2, 2});
  CHECK(tile_grid(5) == std::array<int, 2>{3, 2});
  CHECK(tile_grid(9) == std::array<int, 2>{3, 3});
  for (springs::TemplateKind kind : springs::all_template_kinds()) {
    const RenderScene t = template_scene(kind, 4, 3, 10);
    CHECK(t.lines.size() == 12 + 12);  // cube edges + 4 x 3 fibres
    CHECK(t.surface_triangles.size() == t.triangle_colours.size());
    CHECK(!t.surface_triangles.empty());
    for (const Vec3& p : t.surface_points) CHECK(((p.array() >= -1e-12) && (p.array() <= 1 + 1e-12)).all());
  }
  CHECK_THROWS_AS(template_scene(springs::TemplateKind::parallel, 1, 3, 10), OptionError);

  Image image;
  image.width = 7;
  image.height = 3;
  for (int i = 0; i < 7 * 3 * 3; ++i) image.rgb.push_back(static_cast<std::uint8_t>(i * 11));
  const std::string bytes = encode_png(image);
  REQUIRE(bytes.size() > 8);
  CHECK(bytes.substr(1, 3) == "PNG");
  const Image back = decode_png(bytes, "memory");
  CHECK(back.width == 7);
  CHECK(back.height == 3);
  CHECK(back.rgb == image.rgb);
  try {
    decode_png("not a png at all", "junk.png");
    FAIL("decode_png accepted junk");
  } catch (const InputError& e) {
    CHECK(e.code() == ErrorCode::malformed);
    CHECK(std::string(e.what()).find("junk.png") != std::string::npos);
  }
  CHECK_THROWS_AS(read_png("/nonexistent/picture.png"), InputError);
}

TEST_CASE("a capsule with fibres renders: background, mesh over the centre, origin-to-insertion ramp",
          "[gpu][render]") {
  Renderer renderer(context());
  RenderScene scene = muscle_scene(capsule(), nullptr, "capsule");
  add_fibres(scene, fibres());
  RenderOptions options;
  options.views = 4;
  options.width = 400;
  options.height = 300;
  options.line_scale = 2.0f;  // 4 px ribbons at 300 px
  const Image image = decode_png(encode_png(renderer.render(scene, options)), "render");
  REQUIRE(image.width == 800);
  REQUIRE(image.height == 600);
  const std::vector<Camera> cameras = view_cameras(scene, view_layout(options));
  for (int v = 0; v < 4; ++v) {
    INFO("view " << v);
    const int x0 = (v % 2) * 400, y0 = (v / 2) * 300;
    // Tile corners and a point just beyond the capsule's side are background.
    for (const auto& [x, y] :
         {std::pair<int, int>{x0 + 1, y0 + 1}, {x0 + 398, y0 + 1}, {x0 + 1, y0 + 298}, {x0 + 398, y0 + 298}})
      CHECK(equals(image.pixel(x, y), 255, 255, 255));
    const Camera& c = cameras[v];
    const auto outside = project(c, options, v, c.centre + 1.25 * kRadius * c.up);
    CHECK(equals(image.pixel(outside[0], outside[1]), 255, 255, 255));
    // Inside the silhouette but away from the fibres: the translucent flesh tone (reddish).
    const auto flesh = project(c, options, v, 9.0 * c.up);  // fibres are within 5 of the axis
    const auto m = image.pixel(flesh[0], flesh[1]);
    CHECK(!equals(m, 255, 255, 255));
    CHECK(m[0] > m[2]);
    CHECK(m[0] > m[1]);
    // The fibre on the axis: origin end (x = -30) is on the left, purple; insertion end yellow.
    const auto near_origin = project(c, options, v, Vec3(-0.85 * kFibreHalf, 0, 0));
    const auto near_insertion = project(c, options, v, Vec3(0.85 * kFibreHalf, 0, 0));
    CHECK(near_origin[0] < near_insertion[0]);
    const auto po = image.pixel(near_origin[0], near_origin[1]);
    const auto pi = image.pixel(near_insertion[0], near_insertion[1]);
    INFO("origin pixel " << int(po[0]) << "," << int(po[1]) << "," << int(po[2]) << " insertion pixel " << int(pi[0])
                         << "," << int(pi[1]) << "," << int(pi[2]));
    CHECK(hue_distance(hue_of(po), hue_of(pi)) > 90.0);
    CHECK(hue_of(po) > 240.0);  // purple
    CHECK(hue_of(pi) > 30.0);   // yellow
    CHECK(hue_of(pi) < 90.0);
    CHECK(po[2] > po[1]);  // blue over green at the origin end
    CHECK(pi[1] > pi[2]);  // green over blue at the insertion end
  }

  // Without fibres the centre of every tile is the mesh (not background), and a black
  // background is black.
  RenderScene bare = muscle_scene(capsule(), nullptr, "capsule");
  options.background = Rgba{0, 0, 0, 1};
  options.views = 2;
  const Image dark = renderer.render(bare, options);
  REQUIRE(dark.width == 800);
  REQUIRE(dark.height == 300);
  for (int v = 0; v < 2; ++v) {
    CHECK(equals(dark.pixel(v * 400 + 2, 2), 0, 0, 0));
    CHECK(equals(dark.pixel(v * 400 + 397, 297), 0, 0, 0));
    const auto centre = dark.pixel(v * 400 + 200, 150);
    CHECK(centre[0] > 40);
    CHECK(centre[0] > centre[2]);
  }
  CHECK(renderer.samples_used() >= 1);
  options.width = 10;
  CHECK_THROWS_AS(renderer.render(bare, options), OptionError);
}

TEST_CASE("translucent surfaces are blended back to front whatever their order in the scene", "[gpu][render]") {
  // Two parallel squares facing the first view (which looks along -y: the axis is x, the first
  // view's side is y): red in front (y = 1), blue behind (y = 0), listed front first, so
  // drawing in scene order would leave blue on top.
  RenderScene scene;
  auto square = [&](double y, const Rgba& colour) {
    const int base = static_cast<int>(scene.surface_points.size());
    for (const auto& [x, z] : {std::pair<double, double>{0, 0}, {2, 0}, {2, 1}, {0, 1}})
      scene.surface_points.emplace_back(x, y, z);
    scene.surface_triangles.push_back({base, base + 1, base + 2});
    scene.surface_triangles.push_back({base, base + 2, base + 3});
    scene.triangle_colours.push_back(colour);
    scene.triangle_colours.push_back(colour);
  };
  square(1.0, Rgba{1, 0, 0, 0.6f});
  square(0.0, Rgba{0, 0, 1, 0.6f});
  scene.axis = Vec3::UnitX();
  RenderOptions options;
  options.views = 2;
  options.width = 64;
  options.height = 48;
  Renderer renderer(context());
  const std::vector<Camera> cameras = view_cameras(scene, view_layout(options));
  REQUIRE(cameras[0].forward.y() == Approx(-1.0));  // view 0 sees red in front
  REQUIRE(cameras[1].forward.y() == Approx(1.0));   // view 1 sees blue in front
  const Image image = renderer.render(scene, options);
  const auto front_red = image.pixel(32, 24), front_blue = image.pixel(64 + 32, 24);
  INFO("view 0 " << int(front_red[0]) << "," << int(front_red[1]) << "," << int(front_red[2]) << "; view 1 "
                 << int(front_blue[0]) << "," << int(front_blue[1]) << "," << int(front_blue[2]));
  // Over white: front 0.6 of its colour, the back one 0.6 x 0.4 = 0.24 of its colour.
  CHECK(front_red[0] > front_red[2] + 60);
  CHECK(front_blue[2] > front_blue[0] + 60);
}

TEST_CASE("fascicle render draws raw corpus muscles as read", "[gpu][program][corpus]") {
  FASCICLE_REQUIRE_DATA();
  if (!std::filesystem::exists(test::program())) {
    WARN("skipped: " << test::program() << " is not built");
    return;
  }
  test::TempDir dir;
  // Unrepaired: the LHDL file with its blank header line, and an STL soup with hundreds of
  // non-manifold edges.
  for (const std::string name :
       {"muscles/lhdl/LHDL_R_M090_Psoas_smooth.415.vtk", "muscles/opendihu/left_biceps_brachii.stl"}) {
    INFO(name);
    const std::string out = dir.file("muscle.png");
    REQUIRE(test::run_command(test::program() + " -q render " + test::data_dir() + "/" + name + " -o " + out +
                              " --size 400x300") == 0);
    const Image image = read_png(out);
    REQUIRE(image.width == 800);
    REQUIRE(image.height == 600);
    for (int v = 0; v < 4; ++v) {
      const int x0 = (v % 2) * 400, y0 = (v / 2) * 300;
      CHECK(equals(image.pixel(x0, y0), 255, 255, 255));
      int covered = 0;
      for (int y = y0; y < y0 + 300; ++y)
        for (int x = x0; x < x0 + 400; ++x) covered += !equals(image.pixel(x, y), 255, 255, 255);
      // A long muscle, framed on its length: a few percent of the tile at least, never all.
      CHECK(covered > 400 * 300 / 50);
      CHECK(covered < 400 * 300 / 2);
    }
  }
}

TEST_CASE("fascicle render writes a PNG, missing input, bad options exit with their codes", "[gpu][program]") {
  if (!std::filesystem::exists(test::program())) {
    WARN("skipped: " << test::program() << " is not built");
    return;
  }
  test::TempDir dir;
  const std::string mesh = dir.file("capsule.off"), lines = dir.file("fibres.vtk"), out = dir.file("view.png");
  write_triangle_mesh(mesh, make_capsule(kLength, kRadius, 32));
  write_polylines(lines, fibres());
  const std::string fascicle = test::program() + " -q render ";

  REQUIRE(test::run_command(fascicle + mesh + " " + lines + " -o " + out + " --size 320x240") == 0);
  Image image = read_png(out);
  CHECK(image.width == 640);
  CHECK(image.height == 480);
  CHECK(equals(image.pixel(0, 0), 255, 255, 255));
  CHECK(equals(image.pixel(639, 479), 255, 255, 255));
  CHECK(!equals(image.pixel(160, 120), 255, 255, 255));

  REQUIRE(test::run_command(fascicle + mesh + " -o " + out + " --views 3 --size 200x100 --background black") == 0);
  image = read_png(out);
  CHECK(image.width == 400);
  CHECK(image.height == 200);
  CHECK(equals(image.pixel(0, 0), 0, 0, 0));
  CHECK(equals(image.pixel(399, 199), 0, 0, 0));  // the unused fourth tile
  CHECK(!equals(image.pixel(100, 50), 0, 0, 0));

  const std::string fresh = dir.file("fresh.png");
  CHECK(test::run_command(fascicle + dir.file("missing.off") + " -o " + fresh + " 2>/dev/null") == 3);
  CHECK(test::run_command(fascicle + mesh + " " + dir.file("missing.vtk") + " -o " + fresh + " 2>/dev/null") == 3);
  CHECK(test::run_command(fascicle + mesh + " -o " + fresh + " --views 0 2>/dev/null") == 18);
  CHECK(test::run_command(fascicle + mesh + " -o " + fresh + " --size 800 2>/dev/null") == 18);
  CHECK(test::run_command(fascicle + mesh + " -o " + fresh + " --size 8x6 2>/dev/null") == 18);
  CHECK(test::run_command(fascicle + mesh + " -o " + fresh + " --background pink 2>/dev/null") == 18);
  CHECK(test::run_command(fascicle + "--template feathered -o " + fresh + " 2>/dev/null") == 18);
  CHECK(test::run_command(fascicle + "-o " + fresh + " 2>/dev/null") == 2);  // neither MESH nor --template
  CHECK(test::run_command(fascicle + mesh + " --template parallel -o " + fresh + " 2>/dev/null") == 18);
  CHECK(test::run_command(fascicle + mesh + " -o " + dir.file("view.jpg") + " 2>/dev/null") == 5);
  CHECK(!std::filesystem::exists(fresh));
  CHECK(!std::filesystem::exists(dir.file("view.jpg")));

  // A template: cube, fibres, red origin and green insertion areas.
  REQUIRE(test::run_command(fascicle + "--template pennate -o " + fresh) == 0);
  image = read_png(fresh);
  CHECK(image.width == 500);
  CHECK(image.height == 500);
  int red = 0, green = 0;
  for (int y = 0; y < image.height; ++y)
    for (int x = 0; x < image.width; ++x) {
      const auto p = image.pixel(x, y);
      const int hi = std::max({p[0], p[1], p[2]}), lo = std::min({p[0], p[1], p[2]});
      if (hi - lo < 60) continue;  // greys and pale blends
      const double h = hue_of(p);
      if (h < 15.0 || h > 345.0) ++red;
      if (h > 100.0 && h < 140.0) ++green;
    }
  // Each area covers about 17000 of the 250000 pixels (measured); the fibres' own greens (viridis
  // near t = 0.75) make at most a few thousand.
  CHECK(red > 8000);
  CHECK(green > 8000);
}

TEST_CASE("fascicle render marks landmark points: origin red and insertion green", "[gpu][program]") {
  if (!std::filesystem::exists(test::program())) {
    WARN("skipped: " << test::program() << " is not built");
    return;
  }
  test::TempDir dir;
  const std::string mesh = dir.file("capsule.off"), out = dir.file("view.png");
  write_triangle_mesh(mesh, make_capsule(kLength, kRadius, 32));
  // Rows of landmarks on the capsule's side near each end (x = -30 .. -20 and 20 .. 30).
  std::ofstream(dir.file("origin.xyz")) << "-30 0 12\n-25 0 12\n-20 0 12\n-30 0 -12\n-20 0 -12\n";
  std::ofstream(dir.file("insertion.xyz")) << "20 12 0\n25 12 0\n30 12 0\n20 -12 0\n30 -12 0\n";
  const std::string fascicle = test::program() + " -q render " + mesh + " --views 1 --size 400x300 ";
  // Saturated red and green pixels in each half of the picture (the translucent muscle is a pale
  // blend, left out by the saturation test).
  auto census = [](const Image& image) {
    std::array<int, 4> counts{};  // red left, red right, green left, green right
    for (int y = 0; y < image.height; ++y)
      for (int x = 0; x < image.width; ++x) {
        const auto p = image.pixel(x, y);
        const int hi = std::max({p[0], p[1], p[2]}), lo = std::min({p[0], p[1], p[2]});
        if (hi - lo < 100) continue;
        const double h = hue_of(p);
        const int side = x < image.width / 2 ? 0 : 1;
        if (h < 15.0 || h > 345.0) ++counts[static_cast<std::size_t>(side)];
        if (h > 100.0 && h < 140.0) ++counts[static_cast<std::size_t>(2 + side)];
      }
    return counts;
  };
  REQUIRE(test::run_command(fascicle + "-o " + out) == 0);
  const auto bare = census(read_png(out));
  CHECK(bare[0] + bare[1] + bare[2] + bare[3] == 0);
  REQUIRE(test::run_command(fascicle + "-o " + out + " --origin " + dir.file("origin.xyz") + " --insertion " +
                            dir.file("insertion.xyz")) == 0);
  const auto marked = census(read_png(out));
  INFO("red left " << marked[0] << " right " << marked[1] << ", green left " << marked[2] << " right " << marked[3]);
  // Without fibres nothing says which end goes left, so the test asks only for each colour on
  // one side and the two on opposite sides.
  CHECK(marked[0] + marked[1] > 20);
  CHECK(marked[2] + marked[3] > 20);
  CHECK(std::min(marked[0], marked[1]) == 0);
  CHECK(std::min(marked[2], marked[3]) == 0);
  CHECK((marked[0] > 0) != (marked[2] > 0));

  const std::string fresh = dir.file("fresh.png");
  CHECK(test::run_command(fascicle + "-o " + fresh + " --origin " + dir.file("missing.xyz") + " 2>/dev/null") == 3);
  CHECK(test::run_command(test::program() + " -q render --template parallel -o " + fresh + " --origin " +
                          dir.file("origin.xyz") + " 2>/dev/null") == 18);
  CHECK(!std::filesystem::exists(fresh));
}

#endif  // FASCICLE_HAVE_SHADERS
