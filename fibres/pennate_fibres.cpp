// Pennate fibres through a settled lattice: the cube's map, the cross-section's lens map, the
// pennation solved per sheet, the ends on the surface and the areas they span.

#include "fibres/pennate_fibres.h"

#include "fibres/fibre_check.h"
#include "geometry/errors.h"
#include "geometry/mesh_stats.h"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace fascicle {
namespace {

constexpr double kPi = 3.14159265358979323846;
// Bounds of a sheet's advance: from fibres straight across (pennation near the cross-section's
// angle to the line of action) to fibres along the lattice lines (near the parallel template).
constexpr double kAdvanceLo = 1e-3, kAdvanceHi = 1e3;
constexpr int kBisections = 60;

/// The lattice's map of the cube: trilinear over its index cells at the lattice coordinates.
class LatticeMap {
 public:
  LatticeMap(const springs::Lattice& lattice, const std::vector<Vec3>& positions)
      : lattice_(lattice), positions_(positions) {
    for (int i = 0; i < lattice.nx; ++i)
      xs_.push_back(springs::lattice_coordinates(lattice, lattice.index(i, 0, 0)).x());
    for (int j = 0; j < lattice.ny; ++j)
      ys_.push_back(springs::lattice_coordinates(lattice, lattice.index(0, j, 0)).y());
    for (int k = 0; k < lattice.nz; ++k)
      zs_.push_back(springs::lattice_coordinates(lattice, lattice.index(0, 0, k)).z());
  }

  Vec3 at(const Vec3& c) const {
    double u = 0, v = 0, w = 0;
    const int i = locate(xs_, c.x(), u), j = locate(ys_, c.y(), v), k = locate(zs_, c.z(), w);
    auto p = [&](int di, int dj, int dk) {
      return positions_[static_cast<std::size_t>(lattice_.index(i + di, j + dj, k + dk))];
    };
    const Vec3 x00 = (1 - u) * p(0, 0, 0) + u * p(1, 0, 0), x10 = (1 - u) * p(0, 1, 0) + u * p(1, 1, 0);
    const Vec3 x01 = (1 - u) * p(0, 0, 1) + u * p(1, 0, 1), x11 = (1 - u) * p(0, 1, 1) + u * p(1, 1, 1);
    return (1 - w) * ((1 - v) * x00 + v * x10) + w * ((1 - v) * x01 + v * x11);
  }

  /// at(), fitted to the surface: in the cells next to the lattice's side faces (its surface
  /// ring lies on the surface at its points, and between them on bilinear patches a little
  /// inside or outside a curved surface), the point moves by the offset that takes its foot on
  /// the face onto the closest surface point, weighted from 1 on the face to 0 one cell in; next
  /// to two faces (a corner line) by the mean of both offsets weighted by their weights, so the
  /// correction is continuous across the corner. The end faces (the cast layers t = 0, 1) are not
  /// fitted: the fibres do not enter their cells (pennate_fibres()).
  Vec3 fitted(const Vec3& c, const SurfaceQuery& query) const {
    const Vec3 p = at(c);
    Vec3 offset = Vec3::Zero();
    double weights = 0.0;
    const std::vector<double>* lines[2] = {&xs_, &ys_};
    for (int axis = 0; axis < 2; ++axis) {
      const std::vector<double>& l = *lines[axis];
      const std::size_t n = l.size();
      double weight = 0.0, face = 0.0;
      if (c[axis] < l[1]) {
        weight = (l[1] - c[axis]) / (l[1] - l[0]);
        face = l[0];
      } else if (c[axis] > l[n - 2]) {
        weight = (c[axis] - l[n - 2]) / (l[n - 1] - l[n - 2]);
        face = l[n - 1];
      }
      weight = std::min(1.0, weight);
      if (!(weight > 0.0)) continue;
      Vec3 foot = c;
      foot[axis] = face;
      const Vec3 on_face = at(foot);
      offset += weight * weight * (query.closest_point(on_face).position - on_face);
      weights += weight;
    }
    return weights > 0.0 ? Vec3(p + offset / weights) : p;
  }

  const Vec3& corner(int i, int j, int k) const {
    return positions_[static_cast<std::size_t>(lattice_.index(i, j, k))];
  }

 private:
  // The cell [i, i + 1] of `lines` holding `value`, and the fraction along it.
  static int locate(const std::vector<double>& lines, double value, double& fraction) {
    const int n = static_cast<int>(lines.size());
    int i = static_cast<int>(std::upper_bound(lines.begin(), lines.end(), value) - lines.begin()) - 1;
    i = std::clamp(i, 0, n - 2);
    fraction = std::clamp((value - lines[i]) / (lines[i + 1] - lines[i]), 0.0, 1.0);
    return i;
  }

  const springs::Lattice& lattice_;
  const std::vector<Vec3>& positions_;
  std::vector<double> xs_, ys_, zs_;
};

/// Template coordinates (x across the thickness, y across the width, z along) to lattice
/// coordinates: y picks the chord X + Y = 2y of the lattice's square, x runs along it from the
/// side Y = 0 or X = 1 to the side X = 0 or Y = 1; mirrored: X replaced by 1 - X.
Vec3 lens(const Vec3& c, bool mirrored) {
  const double u = 2.0 * c.y();
  const Eigen::Vector2d from = u <= 1.0 ? Eigen::Vector2d(u, 0.0) : Eigen::Vector2d(1.0, u - 1.0);
  const Eigen::Vector2d to = u <= 1.0 ? Eigen::Vector2d(0.0, u) : Eigen::Vector2d(u - 1.0, 1.0);
  Eigen::Vector2d p = from + c.x() * (to - from);
  if (mirrored) p.x() = 1.0 - p.x();
  return Vec3(p.x(), p.y(), c.z());
}

double angle_deg(const Vec3& chord, const Vec3& line) {
  const double n = chord.norm();
  if (!(n > 0.0)) return 0.0;
  return std::acos(std::min(1.0, std::abs(chord.dot(line)) / n)) * 180.0 / kPi;
}

// Whether a template point of a crossing family lies on the cube's surface (its faces x = 0, 1
// and z = 0, 1; the bipennate sheet x = 1/2 is inside).
bool on_cube_surface(const Vec3& c) {
  constexpr double eps = 1e-12;
  return c.x() <= eps || c.x() >= 1.0 - eps || c.z() <= eps || c.z() >= 1.0 - eps;
}

}  // namespace

void PennateOptions::validate() const {
  if (!(pennation_deg > 0.0 && pennation_deg < 90.0)) {
    char buffer[64];
    std::snprintf(buffer, sizeof(buffer), "%g", pennation_deg);
    throw OptionError(std::string("PennateOptions::pennation_deg must be in (0, 90) (got ") + buffer + ")");
  }
  if (area_density < 1)
    throw OptionError("PennateOptions::area_density must be >= 1 (got " + std::to_string(area_density) + ")");
  if (smoothing_steps < 0 || smoothing_steps > 10000)
    throw OptionError("PennateOptions::smoothing_steps must be in 0..10000 (got " + std::to_string(smoothing_steps) +
                      ")");
  if (!(smoothing_weight > 0.0 && smoothing_weight <= 1.0))
    throw OptionError("PennateOptions::smoothing_weight must be in (0, 1] (got " + std::to_string(smoothing_weight) +
                      ")");
}

nlohmann::json PennateReport::to_json() const {
  return {{"target_deg", target_deg},
          {"mean_deg", mean_deg},
          {"advance", advance},
          {"unreached_sheets", unreached},
          {"mirrored", mirrored},
          {"diagonal_ratio", diagonal_ratio},
          {"fibres", fibres},
          {"projected_ends", projected_ends},
          {"reflected_points", reflected_points},
          {"smoothing_refused", smoothing_refused},
          {"smoothing_reduced", smoothing_reduced},
          {"origin_points", origin_points},
          {"insertion_points", insertion_points}};
}

PennateFibres pennate_fibres(springs::TemplateKind kind, const springs::Lattice& lattice,
                             const std::vector<Vec3>& positions, int fibre_count, int resolution,
                             const Vec3& line_of_action, const SurfaceQuery& query, const PennateOptions& options) {
  options.validate();
  if (!springs::crosses_lattice(kind))
    throw OptionError(std::string("pennate fibres: the template '") + springs::template_name(kind) +
                      "' does not cross the lattice (use unipennate or bipennate)");
  if (resolution < 2) throw OptionError("pennate fibres: resolution must be >= 2");
  if (static_cast<long>(positions.size()) < lattice.point_count())
    throw OptionError("pennate fibres: one position per lattice point is needed");
  const LatticeMap map(lattice, positions);
  const Vec3 line = line_of_action.normalized();
  PennateFibres out;
  PennateReport& report = out.report;
  report.target_deg = options.pennation_deg;

  // The long diagonal of the cross-sections, summed over the layers.
  double d_same = 0.0, d_other = 0.0;
  for (int k = 0; k < lattice.nz; ++k) {
    d_same += (map.corner(0, 0, k) - map.corner(lattice.nx - 1, lattice.ny - 1, k)).norm();
    d_other += (map.corner(lattice.nx - 1, 0, k) - map.corner(0, lattice.ny - 1, k)).norm();
  }
  report.mirrored = d_other > d_same;
  report.diagonal_ratio = std::min(d_same, d_other) / std::max(d_same, d_other);
  const bool mirrored = report.mirrored;
  // The template's z runs over the lattice's inner layers 1 .. nz - 2: the cells next to the cast
  // end faces are sheared on a rounded end (a fibre drawn through them can turn back), so the
  // fibres cut by the end faces stop on the inner layers and are continued straight to the end.
  const double z_lo = lattice.nz >= 4 ? 1.0 / (lattice.nz - 1) : 0.0, z_hi = 1.0 - z_lo;
  auto muscle_point = [&](double advance, double r, double s, double t) {
    Vec3 c = lens(springs::pennate_point(kind, advance, r, s, t), mirrored);
    c.z() = z_lo + (z_hi - z_lo) * c.z();
    return map.fitted(c, query);
  };

  const std::array<int, 2> split = springs::near_square_split(fibre_count);
  const int nr = split[0], ns = split[1];
  // Rows along the muscle, staggered by half a row from sheet to sheet (a hexagonal packing: the
  // rows of neighbouring sheets fill each other's gaps).
  auto r_of = [&](int i, int j) { return (i + 0.25 + 0.5 * (j % 2)) / nr; };
  // The outermost sheets pass through the lattice's corner lines (its first inner line in both
  // directions): nearer the thin edges a chord runs inside the corner cells, along the surface.
  // (With nx != ny the corner line is (x1, y1), on the chord X + Y = x1 + y1.)
  const Vec3 corner_line = springs::lattice_coordinates(lattice, lattice.index(1, 1, 0));
  const double inner = 0.5 * (corner_line.x() + corner_line.y());
  auto s_of = [&](int j) { return inner + (1.0 - 2.0 * inner) * j / (ns - 1); };

  // Each sheet's advance: the mean pennation of its fibres falls as the advance grows.
  auto sheet_angle = [&](double advance, double s, int sheet) {
    double sum = 0.0;
    for (int i = 0; i < nr; ++i)
      sum += angle_deg(muscle_point(advance, r_of(i, sheet), s, 1.0) - muscle_point(advance, r_of(i, sheet), s, 0.0),
                       line);
    return sum / nr;
  };
  for (int j = 0; j < ns; ++j) {
    const double s = s_of(j);
    double lo = std::log(kAdvanceLo), hi = std::log(kAdvanceHi);
    double advance = 0.0;
    if (sheet_angle(kAdvanceLo, s, j) <= options.pennation_deg) {
      advance = kAdvanceLo;
      ++report.unreached;
    } else if (sheet_angle(kAdvanceHi, s, j) >= options.pennation_deg) {
      advance = kAdvanceHi;
      ++report.unreached;
    } else {
      for (int b = 0; b < kBisections; ++b) {
        const double mid = 0.5 * (lo + hi);
        (sheet_angle(std::exp(mid), s, j) > options.pennation_deg ? lo : hi) = mid;
      }
      advance = std::exp(0.5 * (lo + hi));
    }
    report.advance.push_back(advance);
  }

  // A fibre point: the fitted map, an inner point found outside reflected in its closest surface
  // point (the trilinear cells next to a concave stretch of surface can bulge out of it between
  // their corners).
  auto inner_point = [&](double advance, double r, double s, double t, bool count) {
    Vec3 p = muscle_point(advance, r, s, t);
    if (query.inside(p)) return p;
    if (count) ++report.reflected_points;
    // Reflected: as deep inside as it was outside, or, where the muscle is thinner than that,
    // half, a quarter, ... as deep.
    const Vec3 closest = query.closest_point(p).position;
    for (double depth = 1.0; depth > 1e-3; depth *= 0.5) {
      const Vec3 q = closest + depth * (closest - p);
      if (query.inside(q)) return q;
    }
    return p;
  };
  // A fibre end (t = 0 or 1) on the cube's faces goes where its fibre, continued straight from its
  // two inner points next to it, leaves the muscle (no hook: the cells next to a cast end face can
  // be sheared, and the template's own end point there can lie behind its neighbour); where that
  // ray meets no surface within the fibre's length, to the closest surface point of the
  // template's end. An end on the central sheet stays where the map puts it.
  const double dt = 1.0 / (resolution - 1);
  auto end_point = [&](double advance, double r, double s, int end) {
    const double t = end == 0 ? 0.0 : 1.0;
    const Vec3 cube = springs::pennate_point(kind, advance, r, s, t);
    const Vec3 p = muscle_point(advance, r, s, t);
    if (!on_cube_surface(cube)) {
      SurfacePoint point;
      point.position = p;
      return point;
    }
    if (resolution >= 4) {
      const double sign = end == 0 ? 1.0 : -1.0;
      const Vec3 neighbour = inner_point(advance, r, s, t + sign * dt, false);
      const Vec3 along = neighbour - inner_point(advance, r, s, t + 2.0 * sign * dt, false);
      Vec3 hit;
      // At most the fibre's own length on: a ray that grazes the surface would run on far.
      const double reach = (muscle_point(advance, r, s, 1.0) - muscle_point(advance, r, s, 0.0)).norm();
      if (along.norm() > 0.0 && query.first_hit(neighbour, along.normalized(), reach, hit))
        return query.closest_point(hit);
    }
    return query.closest_point(p);
  };
  // The check's default tolerances, for the smoothing's segment test (fibre ends lie on the surface).
  const CheckOptions check;
  const double diagonal = bounding_box(positions).diagonal(), end_tolerance = check.end_tolerance * diagonal;
  double angle_sum = 0.0;
  for (int j = 0; j < ns; ++j)
    for (int i = 0; i < nr; ++i) {
      const double a = report.advance[static_cast<std::size_t>(j)], r = r_of(i, j), s = s_of(j);
      std::vector<Vec3> points(static_cast<std::size_t>(resolution));
      for (int k = 1; k + 1 < resolution; ++k) points[static_cast<std::size_t>(k)] = inner_point(a, r, s, k * dt, true);
      points.front() = end_point(a, r, s, 0).position;
      points.back() = end_point(a, r, s, 1).position;
      if (on_cube_surface(springs::pennate_point(kind, a, r, s, 0.0))) ++report.projected_ends;
      if (on_cube_surface(springs::pennate_point(kind, a, r, s, 1.0))) ++report.projected_ends;
      // Smoothing keeps the points inside; where it straightens a fibre across a concave stretch
      // so that a segment leaves the muscle, the fibre takes the most smoothing (half the steps,
      // again and again) that keeps every segment inside.
      const int segments = static_cast<int>(points.size()) - 1;
      auto smoothed = [&](int steps) {
        std::vector<Vec3> line_points = points;
        for (int step = 0; step < steps; ++step)
          for (std::size_t k = 1; k + 1 < line_points.size(); ++k) {
            const Vec3 moved = line_points[k] + options.smoothing_weight *
                                                    (0.5 * (line_points[k - 1] + line_points[k + 1]) - line_points[k]);
            // A point inside stays inside; one still outside (a reflection that landed outside
            // again, in a thin fold of the surface) moves towards its neighbours in any case.
            if (query.inside(moved) || !query.inside(line_points[k])) {
              line_points[k] = moved;
            } else {
              ++report.smoothing_refused;
            }
          }
        return line_points;
      };
      // Leaves as the check judges it: the surface cuts a segment and a sample of it lies outside
      // by more than the check's segment tolerance.
      auto leaves = [&](const std::vector<Vec3>& line_points) {
        for (int k = 0; k < segments; ++k)
          if (fibre_segment_leaves(query, line_points[k], line_points[k + 1], k, segments, end_tolerance) &&
              segment_excursion(query, line_points[k], line_points[k + 1], check.excursion_samples) >
                  check.segment_tolerance * diagonal)
            return true;
        return false;
      };
      // (When the fibre leaves the muscle unsmoothed too, smoothing loses nothing: all steps.)
      const bool left_before = options.smoothing_steps > 0 && leaves(points);
      for (int steps = options.smoothing_steps; steps > 0; steps /= 2) {
        std::vector<Vec3> candidate = smoothed(steps);
        if (left_before || !leaves(candidate)) {
          points = std::move(candidate);
          break;
        }
        ++report.smoothing_reduced;
      }
      angle_sum += angle_deg(points.back() - points.front(), line);
      out.fibres.lines.push_back(std::move(points));
    }
  report.fibres = static_cast<long>(out.fibres.lines.size());
  report.mean_deg = angle_sum / static_cast<double>(report.fibres);

  // The areas: every start and every end of the family, at the sheets' advances interpolated in
  // s, placed as the fibres' ends are.
  auto advance_at = [&](double s) {
    const double x = (s - inner) / (1.0 - 2.0 * inner) * (ns - 1);  // sheet index coordinate
    if (x <= 0.0) return report.advance.front();
    if (x >= ns - 1) return report.advance.back();
    const int j = static_cast<int>(std::floor(x));
    const double f = x - j;
    return std::exp((1 - f) * std::log(report.advance[static_cast<std::size_t>(j)]) +
                    f * std::log(report.advance[static_cast<std::size_t>(j + 1)]));
  };
  const int na = options.area_density * nr, nb = options.area_density * ns;
  out.areas.automatic = false;
  out.areas.origin.source = std::string(springs::template_name(kind)) + " origin (aponeurosis)";
  out.areas.insertion.source = std::string(springs::template_name(kind)) + " insertion (aponeurosis)";
  for (int b = 0; b < nb; ++b)
    for (int c = 0; c <= na; ++c) {
      const double r = static_cast<double>(c) / na, s = inner + (1.0 - 2.0 * inner) * (b + 0.5) / nb;
      const double advance = advance_at(s);
      out.areas.origin.points.push_back(end_point(advance, r, s, 0));
      out.areas.insertion.points.push_back(end_point(advance, r, s, 1));
    }
  // Each area's own surface: its samples joined as the (r, s) grid they come from (not across the
  // bipennate family's jump at r = 1/2, where its fibres change sides).
  for (AttachmentArea* area : {&out.areas.origin, &out.areas.insertion}) {
    for (const SurfacePoint& p : area->points) area->patch.positions.push_back(p.position);
    auto at = [&](int c, int b) { return b * (na + 1) + c; };
    for (int b = 0; b + 1 < nb; ++b)
      for (int c = 0; c < na; ++c) {
        if (kind == springs::TemplateKind::bipennate && (c < na / 2.0) != (c + 1 < na / 2.0)) continue;
        area->patch.triangles.push_back({at(c, b), at(c + 1, b), at(c + 1, b + 1)});
        area->patch.triangles.push_back({at(c, b), at(c + 1, b + 1), at(c, b + 1)});
      }
  }
  report.origin_points = static_cast<long>(out.areas.origin.points.size());
  report.insertion_points = static_cast<long>(out.areas.insertion.points.size());
  return out;
}

}  // namespace fascicle
