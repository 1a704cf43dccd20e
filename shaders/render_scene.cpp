// The scenes and cameras of `fascicle render` (see render_scene.h). No OpenGL here.

#include "shaders/render_scene.h"

#include "geometry/errors.h"

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>

namespace fascicle::shaders {

namespace {

constexpr double kPi = 3.14159265358979323846;

// viridis at t = 0, 1/9, ..., 1 (matplotlib's published samples, #440154 ... #fde725).
constexpr std::uint8_t kViridis[10][3] = {
    {68, 1, 84},    {72, 40, 120},  {62, 73, 137},  {49, 104, 142}, {38, 130, 142},
    {31, 158, 137}, {53, 183, 121}, {110, 206, 88}, {181, 222, 43}, {253, 231, 37},
};

void require_points(const RenderScene& scene) {
  bool any = !scene.surface_triangles.empty();
  for (const SceneLine& l : scene.lines) any = any || !l.points.empty();
  FASCICLE_CHECK(any, "render scene has no triangle and no line point");
}

template <typename F>
void for_each_point(const RenderScene& scene, F&& f) {
  if (!scene.surface_triangles.empty())
    for (const Vec3& p : scene.surface_points) f(p);
  for (const SceneLine& l : scene.lines)
    for (const Vec3& p : l.points) f(p);
}

// The coordinate axis least aligned with `a`, made perpendicular to it (unit).
Vec3 perpendicular(const Vec3& a) {
  int k = 0;
  for (int i = 1; i < 3; ++i)
    if (std::abs(a[i]) < std::abs(a[k])) k = i;
  Vec3 e = Vec3::Zero();
  e[k] = 1.0;
  return (e - e.dot(a) * a).normalized();
}

// Covariance eigenvectors of the scene, columns sorted by decreasing eigenvalue.
Eigen::Matrix3d principal_frame(const RenderScene& scene) {
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  Vec3 mean = Vec3::Zero();
  double total = 0.0;
  for (const Triangle& t : scene.surface_triangles) {
    const Vec3& a = scene.surface_points[t[0]];
    const Vec3& b = scene.surface_points[t[1]];
    const Vec3& c = scene.surface_points[t[2]];
    const double w = 0.5 * (b - a).cross(c - a).norm();
    mean += w * (a + b + c) / 3.0;
    total += w;
  }
  if (total > 0.0) {
    mean /= total;
    for (const Triangle& t : scene.surface_triangles) {
      const Vec3& a = scene.surface_points[t[0]];
      const Vec3& b = scene.surface_points[t[1]];
      const Vec3& c = scene.surface_points[t[2]];
      const double w = 0.5 * (b - a).cross(c - a).norm();
      // Second moment of a triangle about the mean: its vertices and centroid, equal weights
      // (exact for the uniform area density up to the 1/12 term, enough for an axis).
      for (const Vec3& p : {a, b, c, Vec3((a + b + c) / 3.0)}) {
        const Vec3 d = p - mean;
        cov += (w / 4.0) * d * d.transpose();
      }
    }
  } else {
    std::size_t n = 0;
    for (const SceneLine& l : scene.lines)
      for (const Vec3& p : l.points) {
        mean += p;
        ++n;
      }
    FASCICLE_CHECK(n > 0, "render scene has no surface area and no line point");
    mean /= static_cast<double>(n);
    for (const SceneLine& l : scene.lines)
      for (const Vec3& p : l.points) cov += (p - mean) * (p - mean).transpose();
  }
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(cov);
  Eigen::Matrix3d frame;
  for (int i = 0; i < 3; ++i) frame.col(i) = solver.eigenvectors().col(2 - i);  // ascending -> descending
  return frame;
}

}  // namespace

Rgba fibre_colour(double t) {
  if (!(t > 0.0)) t = 0.0;  // NaN too
  if (t > 1.0) t = 1.0;
  const double x = t * 9.0;
  const int i = std::min(8, static_cast<int>(x));
  const double f = x - i;
  Rgba c;
  c.r = static_cast<float>(((1.0 - f) * kViridis[i][0] + f * kViridis[i + 1][0]) / 255.0);
  c.g = static_cast<float>(((1.0 - f) * kViridis[i][1] + f * kViridis[i + 1][1]) / 255.0);
  c.b = static_cast<float>(((1.0 - f) * kViridis[i][2] + f * kViridis[i + 1][2]) / 255.0);
  c.a = 1.0f;
  return c;
}

double hue_degrees(std::uint8_t r, std::uint8_t g, std::uint8_t b) {
  const int hi = std::max({r, g, b}), lo = std::min({r, g, b});
  if (hi == lo) return 0.0;
  const double d = hi - lo;
  double h;
  if (hi == r)
    h = (g - b) / d;
  else if (hi == g)
    h = 2.0 + (b - r) / d;
  else
    h = 4.0 + (r - g) / d;
  h *= 60.0;
  return h < 0.0 ? h + 360.0 : h;
}

Rgba muscle_colour() { return Rgba{0.86f, 0.40f, 0.36f, 0.26f}; }

Rgba origin_colour() { return Rgba{0.90f, 0.12f, 0.10f, 1.0f}; }

Rgba insertion_colour() { return Rgba{0.10f, 0.72f, 0.18f, 1.0f}; }

void add_markers(RenderScene& scene, const std::vector<Vec3>& points, const Rgba& colour, double size,
                 float width_px) {
  for (const Vec3& p : points)
    for (int axis = 0; axis < 3; ++axis) {
      const Vec3 d = size * Vec3::Unit(axis);
      scene.lines.push_back(SceneLine{{p - d, p + d}, {colour, colour}, width_px});
    }
}

void add_fibres(RenderScene& scene, const Polylines& lines, float width_px) {
  Vec3 first = Vec3::Zero(), last = Vec3::Zero();
  std::size_t count = 0;
  for (const std::vector<Vec3>& line : lines.lines) {
    if (line.size() < 2) continue;
    SceneLine out;
    out.points = line;
    out.width_px = width_px;
    std::vector<double> s(line.size(), 0.0);
    for (std::size_t i = 1; i < line.size(); ++i) s[i] = s[i - 1] + (line[i] - line[i - 1]).norm();
    const double length = s.back();
    for (std::size_t i = 0; i < line.size(); ++i)
      out.colours.push_back(fibre_colour(length > 0.0 ? s[i] / length : static_cast<double>(i) / (line.size() - 1)));
    first += line.front();
    last += line.back();
    ++count;
    scene.lines.push_back(std::move(out));
  }
  if (count > 0) {
    scene.axis_origin = first / static_cast<double>(count);
    scene.axis_insertion = last / static_cast<double>(count);
    scene.has_axis_ends = (scene.axis_insertion - scene.axis_origin).norm() > 0.0;
  }
}

RenderScene muscle_scene(const PolygonSoup& soup, const Polylines* fibres, const std::string& name) {
  RenderScene scene;
  scene.surface_points = soup.points;
  for (const std::vector<int>& polygon : soup.polygons)
    for (std::size_t i = 2; i < polygon.size(); ++i)
      scene.surface_triangles.push_back({polygon[0], polygon[i - 1], polygon[i]});
  if (scene.surface_triangles.empty())
    throw InputError(ErrorCode::file_empty, name + ": no polygon with 3 or more corners to draw");
  scene.triangle_colours.assign(scene.surface_triangles.size(), muscle_colour());
  if (fibres) add_fibres(scene, *fibres);
  return scene;
}

RenderScene template_scene(springs::TemplateKind kind, int nr, int ns, int points) {
  if (nr < 2 || ns < 2)
    throw OptionError("template fibres: need at least 2 x 2, got " + std::to_string(nr) + " x " + std::to_string(ns));
  if (points < 2) throw OptionError("template points: need at least 2 per fibre, got " + std::to_string(points));
  RenderScene scene;
  // The cube's 12 edges.
  const Rgba edge{0.30f, 0.30f, 0.33f, 1.0f};
  for (int axis = 0; axis < 3; ++axis)
    for (int a = 0; a < 2; ++a)
      for (int b = 0; b < 2; ++b) {
        Vec3 p = Vec3::Zero(), q = Vec3::Zero();
        p[(axis + 1) % 3] = q[(axis + 1) % 3] = a;
        p[(axis + 2) % 3] = q[(axis + 2) % 3] = b;
        q[axis] = 1.0;
        scene.lines.push_back(SceneLine{{p, q}, {edge, edge}, 1.5f});
      }
  // Attachment areas as translucent rectangles (two triangles each).
  auto add_area = [&](const springs::TemplateArea& area, const Rgba& colour) {
    for (const springs::TemplateArea::Rect& rect : area.parts) {
      int flat = 0;
      for (int i = 0; i < 3; ++i)
        if (rect.hi[i] - rect.lo[i] < rect.hi[flat] - rect.lo[flat]) flat = i;
      const int u = (flat + 1) % 3, v = (flat + 2) % 3;
      const int base = static_cast<int>(scene.surface_points.size());
      for (int corner = 0; corner < 4; ++corner) {
        Vec3 p = rect.lo;
        if (corner == 1 || corner == 2) p[u] = rect.hi[u];
        if (corner >= 2) p[v] = rect.hi[v];
        scene.surface_points.push_back(p);
      }
      scene.surface_triangles.push_back({base, base + 1, base + 2});
      scene.surface_triangles.push_back({base, base + 2, base + 3});
      scene.triangle_colours.push_back(colour);
      scene.triangle_colours.push_back(colour);
    }
  };
  auto translucent = [](Rgba c) {
    c.a = 0.45f;
    return c;
  };
  add_area(springs::origin_area(kind), translucent(origin_colour()));
  add_area(springs::insertion_area(kind), translucent(insertion_colour()));
  // Fibres.
  Polylines fibres;
  for (int j = 0; j < ns; ++j)
    for (int i = 0; i < nr; ++i) {
      std::vector<Vec3> line;
      for (int k = 0; k < points; ++k)
        line.push_back(springs::template_point(kind, static_cast<double>(i) / (nr - 1),
                                               static_cast<double>(j) / (ns - 1),
                                               static_cast<double>(k) / (points - 1)));
      fibres.lines.push_back(std::move(line));
    }
  add_fibres(scene, fibres, 3.0f);
  scene.axis = Vec3::UnitZ();
  scene.has_axis_ends = false;  // the views keep z up whatever the fibres do
  return scene;
}

Vec3 principal_axis(const RenderScene& scene) {
  require_points(scene);
  return principal_frame(scene).col(0).normalized();
}

SceneBounds scene_bounds(const RenderScene& scene) {
  require_points(scene);
  SceneBounds b;
  bool first = true;
  for_each_point(scene, [&](const Vec3& p) {
    if (first) {
      b.lo = b.hi = p;
      first = false;
    }
    b.lo = b.lo.cwiseMin(p);
    b.hi = b.hi.cwiseMax(p);
  });
  return b;
}

void ViewLayout::validate() const {
  if (views < 1 || views > 64) throw OptionError("views: must be in [1, 64], got " + std::to_string(views));
  if (!(aspect > 0.0) || !std::isfinite(aspect))
    throw OptionError("aspect: must be a positive number, got " + std::to_string(aspect));
  if (!(std::abs(elevation_deg) < 90.0))
    throw OptionError("elevation: must be in (-90, 90) degrees, got " + std::to_string(elevation_deg));
  if (!std::isfinite(azimuth_deg)) throw OptionError("azimuth: must be a finite number of degrees");
  if (!(margin >= 0.0 && margin < 1.0)) throw OptionError("margin: must be in [0, 1), got " + std::to_string(margin));
}

std::vector<Camera> view_cameras(const RenderScene& scene, const ViewLayout& layout) {
  layout.validate();
  require_points(scene);
  Vec3 axis, side;
  if (scene.axis.norm() > 0.0) {
    axis = scene.axis.normalized();
    side = perpendicular(axis);
  } else {
    const Eigen::Matrix3d frame = principal_frame(scene);
    axis = frame.col(0).normalized();
    side = frame.col(2).normalized();  // the first view looks across the thinnest direction
  }
  if (scene.has_axis_ends) {
    if (axis.dot(scene.axis_insertion - scene.axis_origin) < 0.0) axis = -axis;
  } else if (scene.axis.norm() == 0.0) {
    int k = 0;
    for (int i = 1; i < 3; ++i)
      if (std::abs(axis[i]) > std::abs(axis[k])) k = i;
    if (axis[k] < 0.0) axis = -axis;
  }
  const Vec3 other = axis.cross(side);
  const double elevation = layout.elevation_deg * kPi / 180.0;

  std::vector<Camera> cameras;
  double half_width = 0.0;
  for (int v = 0; v < layout.views; ++v) {
    const double phi = layout.azimuth_deg * kPi / 180.0 + 2.0 * kPi * v / layout.views;
    const Vec3 around = std::cos(phi) * side + std::sin(phi) * other;  // from the scene to the viewer
    const Vec3 eye = std::cos(elevation) * around + std::sin(elevation) * axis;
    Camera c;
    c.forward = -eye.normalized();
    if (layout.axis_up) {
      c.up = (axis - axis.dot(c.forward) * c.forward).normalized();
      c.right = c.forward.cross(c.up);
    } else {
      c.right = (axis - axis.dot(c.forward) * c.forward).normalized();
      c.up = c.right.cross(c.forward);
    }
    // Extent of the projected points.
    double x0 = 1e300, x1 = -1e300, y0 = 1e300, y1 = -1e300, z0 = 1e300, z1 = -1e300;
    for_each_point(scene, [&](const Vec3& p) {
      const double x = c.right.dot(p), y = c.up.dot(p), z = c.forward.dot(p);
      x0 = std::min(x0, x), x1 = std::max(x1, x);
      y0 = std::min(y0, y), y1 = std::max(y1, y);
      z0 = std::min(z0, z), z1 = std::max(z1, z);
    });
    c.centre = 0.5 * (x0 + x1) * c.right + 0.5 * (y0 + y1) * c.up + 0.5 * (z0 + z1) * c.forward;
    const double hw = 0.5 * (x1 - x0), hh = 0.5 * (y1 - y0), hd = 0.5 * (z1 - z0);
    half_width = std::max({half_width, hw, hh * layout.aspect});
    const double depth = std::max(hd, 1e-9 * std::max({hw, hh, 1.0}));
    c.near = -1.01 * depth;
    c.far = 1.01 * depth;
    cameras.push_back(c);
  }
  if (!(half_width > 0.0)) half_width = 1.0;  // a single point: any scale frames it
  half_width *= 1.0 + layout.margin;
  for (Camera& c : cameras) {
    c.half_width = half_width;
    c.half_height = half_width / layout.aspect;
  }
  return cameras;
}

}  // namespace fascicle::shaders
