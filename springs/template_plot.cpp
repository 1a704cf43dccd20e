// SVG pictures of the fibre templates (oblique projection; no rendering library needed).

#include "springs/template_plot.h"

#include "geometry/errors.h"

#include <cmath>
#include <cstdio>
#include <sstream>

namespace fascicle::springs {
namespace {

// Cabinet projection: x right, z up, y receding at 30 degrees with half length.
struct Projection {
  double pixels;
  void operator()(const Vec3& p, double& u, double& v) const {
    const double depth_x = 0.5 * std::cos(0.5236), depth_y = 0.5 * std::sin(0.5236);
    const double scale = pixels / 1.7, margin = 0.1 * pixels;
    u = margin + scale * (p.x() + depth_x * p.y());
    v = pixels - margin - scale * (p.z() + depth_y * p.y());
  }
};

std::string point_list(const Projection& project, const std::vector<Vec3>& points) {
  std::ostringstream out;
  out.precision(5);
  for (const Vec3& p : points) {
    double u, v;
    project(p, u, v);
    out << u << ',' << v << ' ';
  }
  return out.str();
}

void area(std::ostringstream& svg, const Projection& project, const TemplateArea& a, const char* colour) {
  for (const auto& rect : a.parts) {
    // The rectangle is flat in one axis; walk its four corners in the other two.
    int flat = 0;
    for (int axis = 0; axis < 3; ++axis)
      if (rect.lo[axis] == rect.hi[axis]) flat = axis;
    const int a1 = (flat + 1) % 3, a2 = (flat + 2) % 3;
    std::vector<Vec3> corners(4, rect.lo);
    corners[1][a1] = rect.hi[a1];
    corners[2][a1] = rect.hi[a1];
    corners[2][a2] = rect.hi[a2];
    corners[3][a2] = rect.hi[a2];
    svg << "<polygon points=\"" << point_list(project, corners) << "\" fill=\"" << colour
        << "\" fill-opacity=\"0.25\" stroke=\"" << colour << "\" stroke-width=\"1.5\"/>\n";
  }
}

}  // namespace

std::string template_svg(TemplateKind kind, int fibres_r, int fibres_s, int samples, int pixels) {
  if (fibres_r < 1 || fibres_s < 1 || samples < 2 || pixels < 32)
    throw OptionError("template plot: need fibres >= 1, samples >= 2 and pixels >= 32");
  const Projection project{static_cast<double>(pixels)};
  std::ostringstream svg;
  svg << "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" << pixels << "\" height=\"" << pixels
      << "\" viewBox=\"0 0 " << pixels << ' ' << pixels << "\">\n"
      << "<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n";
  // Cube edges.
  for (int e = 0; e < 12; ++e) {
    const int axis = e / 4, a1 = (axis + 1) % 3, a2 = (axis + 2) % 3;
    Vec3 p0 = Vec3::Zero();
    p0[a1] = (e & 1) ? 1.0 : 0.0;
    p0[a2] = (e & 2) ? 1.0 : 0.0;
    Vec3 p1 = p0;
    p1[axis] = 1.0;
    svg << "<polyline points=\"" << point_list(project, {p0, p1})
        << "\" fill=\"none\" stroke=\"#999\" stroke-width=\"1\"/>\n";
  }
  area(svg, project, origin_area(kind), "#d62728");
  area(svg, project, insertion_area(kind), "#2ca02c");
  for (int j = 0; j < fibres_s; ++j)
    for (int i = 0; i < fibres_r; ++i) {
      const double r = fibres_r == 1 ? 0.5 : static_cast<double>(i) / (fibres_r - 1);
      const double s = fibres_s == 1 ? 0.5 : static_cast<double>(j) / (fibres_s - 1);
      std::vector<Vec3> line;
      for (int k = 0; k < samples; ++k)
        line.push_back(template_point(kind, r, s, static_cast<double>(k) / (samples - 1)));
      svg << "<polyline points=\"" << point_list(project, line)
          << "\" fill=\"none\" stroke=\"#1f77b4\" stroke-width=\"1.6\"/>\n";
    }
  svg << "<text x=\"8\" y=\"20\" font-family=\"sans-serif\" font-size=\"16\">" << template_name(kind)
      << "</text>\n</svg>\n";
  return svg.str();
}

}  // namespace fascicle::springs
