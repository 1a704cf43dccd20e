// The fibre quality check. Two spatial structures keep it fast without giving up exactness:
// - the inside grid of the muscle's SurfaceQuery (morph/inside_grid.h): points away from the
//   surface are classified by their cell, only points near it go to the exact test (CGAL
//   Side_of_triangle_mesh); its cells also seed the coverage samples.
// - SegmentTree, a bounding-volume hierarchy over the fibre segments, answers nearest-segment
//   queries by branch and bound (exact distances, no brute force).
#include "fibres/fibre_check.h"

#include "fibres/fibre_grid.h"
#include "fibres/segment_tree.h"
#include "morph/inside_grid.h"
#include "geometry/errors.h"
#include "geometry/mesh_stats.h"

#include <nlohmann/json.hpp>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <random>
#include <unordered_map>

namespace fascicle {

namespace {

constexpr double kPi = 3.14159265358979323846;

double polyline_length(const std::vector<Vec3>& line) {
  double length = 0.0;
  for (std::size_t k = 0; k + 1 < line.size(); ++k) length += (line[k + 1] - line[k]).norm();
  return length;
}

/// The far samples' breakdown (FarSamples): `distances` to the nearest fibre in mesh units.
FarSamples far_samples(const std::vector<Vec3>& samples, const std::vector<double>& distances, double spacing,
                       double threshold, bool with_depth, const TriangleMesh& muscle, const SurfaceQuery& query,
                       const Attachments& areas) {
  FarSamples far;
  far.threshold = threshold;
  far.depth_measured = with_depth;
  if (samples.empty() || !(spacing > 0.0)) return far;
  // Position along the principal axis of the vertices, oriented from the origin area's centroid
  // towards the insertion's.
  const PrincipalAxes principal = principal_axes(muscle.positions);
  Vec3 axis = principal.major();
  if ((areas.insertion.centroid() - areas.origin.centroid()).dot(axis) < 0.0) axis = -axis;
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  for (const Vec3& p : muscle.positions) {
    const double t = (p - principal.mean).dot(axis);
    lo = std::min(lo, t);
    hi = std::max(hi, t);
  }
  const double extent = hi > lo ? hi - lo : 1.0;
  // The depth of every sample is a closest-point query each, most of the check's time: it is
  // only measured where the coverage criterion fails, which is what the breakdown explains.
  const std::vector<SurfacePoint> nearest = with_depth ? query.closest_points(samples) : std::vector<SurfacePoint>{};
  long far_count = 0;
  for (std::size_t i = 0; i < samples.size(); ++i) {
    const bool is_far = distances[i] / spacing > threshold;
    far_count += is_far ? 1 : 0;
    const double t = ((samples[i] - principal.mean).dot(axis) - lo) / extent;
    const auto a = static_cast<std::size_t>(
        std::clamp(static_cast<int>(std::floor(t * FarSamples::kAlongBins)), 0, FarSamples::kAlongBins - 1));
    ++far.along_samples[a];
    far.along_far[a] += is_far ? 1 : 0;
    if (!with_depth) continue;
    std::size_t d = 0;
    const double depth = nearest[i].distance / spacing;
    while (d + 1 < static_cast<std::size_t>(FarSamples::kDepthBins) && depth >= FarSamples::depth_edges[d]) ++d;
    ++far.depth_samples[d];
    far.depth_far[d] += is_far ? 1 : 0;
  }
  far.fraction = static_cast<double>(far_count) / static_cast<double>(samples.size());
  return far;
}

/// Nearest-rank percentile of unsorted values (q in (0, 1]).
double percentile(std::vector<double> values, double q) {
  if (values.empty()) return 0.0;
  const std::size_t rank = static_cast<std::size_t>(std::ceil(q * static_cast<double>(values.size())));
  const std::size_t index = std::min(values.size() - 1, rank == 0 ? 0 : rank - 1);
  std::nth_element(values.begin(), values.begin() + static_cast<std::ptrdiff_t>(index), values.end());
  return values[index];
}

/// Inverted cells of a fibre lattice (see fibre_check.h). Each hexahedron (corners x_abc, a along
/// r, b along s, c along the fibre) is split into the six tetrahedra of the Kuhn triangulation
/// around the diagonal x_000 - x_111 (kuhn_tetrahedra(), fibres/fibre_grid.h); all six have the
/// same sign as the lattice's frame (r, s, fibre) when the cell is not folded.
void count_inverted_cells(const Polylines& fibres, const FibreGrid& grid, int listed, CheckReport& report) {
  const auto& kuhn = kuhn_tetrahedra();
  std::vector<std::array<TetVolume, 6>> volumes;
  std::vector<std::array<int, 3>> where;  // (r, s, k) of each cell
  for (int s = 0; s + 1 < grid.ns; ++s)
    for (int r = 0; r + 1 < grid.nr; ++r) {
      const int l00 = grid.at(r, s), l10 = grid.at(r + 1, s), l01 = grid.at(r, s + 1), l11 = grid.at(r + 1, s + 1);
      if (l00 < 0 || l10 < 0 || l01 < 0 || l11 < 0) continue;
      const int lines[4] = {l00, l10, l01, l11};
      for (int k = 0; k + 1 < grid.points; ++k) {
        std::array<Vec3, 8> cell;  // index a + 2b + 4c
        for (int c = 0; c < 2; ++c)
          for (int q = 0; q < 4; ++q)
            cell[static_cast<std::size_t>(q + 4 * c)] =
                fibres.lines[static_cast<std::size_t>(lines[q])][static_cast<std::size_t>(k + c)];
        std::array<TetVolume, 6> tets{};
        for (std::size_t t = 0; t < 6; ++t)
          tets[t] = tet_volume(cell[static_cast<std::size_t>(kuhn[t][0])], cell[static_cast<std::size_t>(kuhn[t][1])],
                               cell[static_cast<std::size_t>(kuhn[t][2])], cell[static_cast<std::size_t>(kuhn[t][3])]);
        volumes.push_back(tets);
        where.push_back({r, s, k});
      }
    }
  report.cells = static_cast<long>(volumes.size());
  double total = 0.0;
  for (const auto& v : volumes)
    for (const TetVolume& x : v) total += x.volume;
  const double reference = total >= 0.0 ? 1.0 : -1.0;
  long inverted = 0;
  for (std::size_t c = 0; c < volumes.size(); ++c) {
    bool bad = false;
    for (const TetVolume& t : volumes[c])
      if (!t.good(reference)) bad = true;  // folded, or flat (round-off level, zero edges)
    inverted += bad ? 1 : 0;
    if (bad && static_cast<int>(report.inverted_examples.size()) < listed) report.inverted_examples.push_back(where[c]);
  }
  report.inverted_cells = inverted;
}

/// Points bucketed in a uniform grid of cubes, for "is a point within r of p" queries.
class PointGrid {
 public:
  PointGrid(const std::vector<Vec3>& points, double cell) : points_(points), cell_(cell > 0.0 ? cell : 1.0) {
    for (std::size_t i = 0; i < points_.size(); ++i) buckets_[key(cell_of(points_[i]))].push_back(static_cast<int>(i));
  }
  bool any_within(const Vec3& p, double r) const {
    const std::array<long, 3> c = cell_of(p);
    const long reach = static_cast<long>(std::ceil(r / cell_));
    const double r2 = r * r;
    for (long dz = -reach; dz <= reach; ++dz)
      for (long dy = -reach; dy <= reach; ++dy)
        for (long dx = -reach; dx <= reach; ++dx) {
          const auto it = buckets_.find(key({c[0] + dx, c[1] + dy, c[2] + dz}));
          if (it == buckets_.end()) continue;
          for (int i : it->second)
            if ((points_[static_cast<std::size_t>(i)] - p).squaredNorm() <= r2) return true;
        }
    return false;
  }

 private:
  std::array<long, 3> cell_of(const Vec3& p) const {
    return {static_cast<long>(std::floor(p.x() / cell_)), static_cast<long>(std::floor(p.y() / cell_)),
            static_cast<long>(std::floor(p.z() / cell_))};
  }
  static std::uint64_t key(const std::array<long, 3>& c) {
    return (static_cast<std::uint64_t>(c[0] & 0x1fffff) << 42) | (static_cast<std::uint64_t>(c[1] & 0x1fffff) << 21) |
           static_cast<std::uint64_t>(c[2] & 0x1fffff);
  }
  const std::vector<Vec3>& points_;
  double cell_;
  std::unordered_map<std::uint64_t, std::vector<int>> buckets_;
};

/// The ends criterion for one area: `samples` even samples of the muscle surface within `radius`
/// of an area point (drawn from the triangles that can reach it, area-weighted, seeded), or of
/// the area's own patch when it has one, and the
/// share of them within one ideal end spacing sqrt(area / F) of one of the F `ends`.
EndCoverage end_coverage(const TriangleMesh& muscle, const AttachmentArea& area, const std::vector<Vec3>& ends,
                         double radius, int samples, std::uint64_t seed) {
  EndCoverage out;
  if (area.points.empty() || ends.empty() || !(radius > 0.0)) return out;
  std::vector<Vec3> area_points;
  for (const SurfacePoint& p : area.points) area_points.push_back(p.position);
  const PointGrid near_area(area_points, radius);
  std::vector<int> candidates;
  std::vector<double> cumulative;
  std::vector<char> whole;
  double total = 0.0;
  // An area with its own surface (patch) is sampled there, all of it; else the muscle's surface
  // near the area's points.
  const bool own = !area.patch.triangles.empty();
  const TriangleMesh& surface = own ? area.patch : muscle;
  // The area points' box grown by the radius: a triangle whose centre lies farther than its reach
  // outside it fails the grid's test below, which this skips for most of a muscle's triangles.
  Vec3 area_lo = Vec3::Constant(std::numeric_limits<double>::infinity()), area_hi = -area_lo;
  for (const Vec3& p : area_points) {
    area_lo = area_lo.cwiseMin(p);
    area_hi = area_hi.cwiseMax(p);
  }
  area_lo -= Vec3::Constant(radius);
  area_hi += Vec3::Constant(radius);
  for (std::size_t t = 0; t < surface.triangles.size(); ++t) {
    const Triangle& tri = surface.triangles[t];
    const Vec3& a = surface.positions[static_cast<std::size_t>(tri[0])];
    const Vec3& b = surface.positions[static_cast<std::size_t>(tri[1])];
    const Vec3& c = surface.positions[static_cast<std::size_t>(tri[2])];
    const Vec3 centre = (a + b + c) / 3.0;
    const double reach = std::max({(a - centre).norm(), (b - centre).norm(), (c - centre).norm()});
    if (!own && ((centre.array() < area_lo.array() - reach).any() || (centre.array() > area_hi.array() + reach).any()))
      continue;
    if (!own && !near_area.any_within(centre, radius + reach)) continue;
    const double triangle_area = 0.5 * (b - a).cross(c - a).norm();
    if (own && !(triangle_area > 0.0)) continue;
    total += triangle_area;
    candidates.push_back(static_cast<int>(t));
    cumulative.push_back(total);
    // A triangle whose three corners are near area points is the area's as a whole (a coarse
    // mesh's automatic band: its vertices are the area's points, its triangles large).
    whole.push_back(
        own || (near_area.any_within(a, radius) && near_area.any_within(b, radius) && near_area.any_within(c, radius)));
  }
  if (candidates.empty() || !(total > 0.0)) return out;
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::vector<Vec3> kept;
  for (int i = 0; i < samples; ++i) {
    const double pick = unit(rng) * total;
    const std::size_t n =
        static_cast<std::size_t>(std::lower_bound(cumulative.begin(), cumulative.end(), pick) - cumulative.begin());
    const std::size_t pick_at = std::min(n, candidates.size() - 1);
    const Triangle& tri = surface.triangles[static_cast<std::size_t>(candidates[pick_at])];
    const double u = std::sqrt(unit(rng)), v = unit(rng);
    const Vec3 p = (1.0 - u) * surface.positions[static_cast<std::size_t>(tri[0])] +
                   u * (1.0 - v) * surface.positions[static_cast<std::size_t>(tri[1])] +
                   u * v * surface.positions[static_cast<std::size_t>(tri[2])];
    if (whole[pick_at] || near_area.any_within(p, radius)) kept.push_back(p);
  }
  out.samples = static_cast<int>(kept.size());
  if (kept.empty()) return out;
  out.area = total * static_cast<double>(kept.size()) / static_cast<double>(samples);
  out.spacing = std::sqrt(out.area / static_cast<double>(ends.size()));
  const PointGrid near_end(ends, out.spacing);
  long covered = 0;
  for (const Vec3& p : kept) covered += near_end.any_within(p, out.spacing) ? 1 : 0;
  out.share = static_cast<double>(covered) / static_cast<double>(kept.size());
  return out;
}

std::string fmt_double(double v) {
  char buffer[64];
  std::snprintf(buffer, sizeof(buffer), "%.4g", v);
  return buffer;
}

}  // namespace

void CheckOptions::validate() const {
  auto bad = [](const std::string& field, double value, const std::string& rule) {
    char buffer[64];
    std::snprintf(buffer, sizeof(buffer), "%g", value);
    throw OptionError("CheckOptions::" + field + " must be " + rule + " (got " + buffer + ")");
  };
  if (coverage_samples < 1 || coverage_samples > 100'000'000)
    bad("coverage_samples", coverage_samples, "in [1, 100000000]");
  if (!(end_tolerance >= 0.0) || !std::isfinite(end_tolerance)) bad("end_tolerance", end_tolerance, ">= 0 and finite");
  if (!(min_inside_fraction >= 0.0 && min_inside_fraction <= 1.0))
    bad("min_inside_fraction", min_inside_fraction, "in [0, 1]");
  if (max_inverted_cells < 0) bad("max_inverted_cells", static_cast<double>(max_inverted_cells), ">= 0");
  if (!(max_coverage_p95 > 0.0) || !std::isfinite(max_coverage_p95))
    bad("max_coverage_p95", max_coverage_p95, "> 0 and finite");
  if (!(max_attachment > 0.0) || !std::isfinite(max_attachment))
    bad("max_attachment", max_attachment, "> 0 and finite");
  if (max_crossing_segments < -1) bad("max_crossing_segments", static_cast<double>(max_crossing_segments), ">= -1");
  if (!(segment_tolerance >= 0.0) || !std::isfinite(segment_tolerance))
    bad("segment_tolerance", segment_tolerance, ">= 0 and finite");
  if (excursion_samples < 1 || excursion_samples > 10000) bad("excursion_samples", excursion_samples, "in [1, 10000]");
  if (!(max_turning_angle_deg > 0.0 && max_turning_angle_deg <= 180.0))
    bad("max_turning_angle_deg", max_turning_angle_deg, "in (0, 180]");
  if (!(end_region_radius > 0.0 && end_region_radius <= 1.0)) bad("end_region_radius", end_region_radius, "in (0, 1]");
  if (end_samples < 1 || end_samples > 10'000'000) bad("end_samples", end_samples, "in [1, 10000000]");
  if (!(min_end_coverage >= 0.0 && min_end_coverage <= 1.0)) bad("min_end_coverage", min_end_coverage, "in [0, 1]");
  if (outside_listed < 0) bad("outside_listed", outside_listed, ">= 0");
}

StepFigures step_figures(const Polylines& fibres) {
  StepFigures out;
  std::vector<double> ratios;
  double sum = 0.0;
  long count = 0;
  std::size_t points = fibres.lines.empty() ? 0 : fibres.lines.front().size();
  for (const auto& line : fibres.lines)
    if (line.size() != points) points = 0;
  if (points >= 2) out.layers.assign(points - 1, 0.0);
  for (std::size_t f = 0; f < fibres.lines.size(); ++f) {
    const auto& line = fibres.lines[f];
    if (line.size() < 2) continue;
    double fibre_sum = 0.0, longest = -1.0;
    int longest_at = 0;
    for (std::size_t k = 0; k + 1 < line.size(); ++k) {
      const double step = (line[k + 1] - line[k]).norm();
      fibre_sum += step;
      if (step > longest) longest = step, longest_at = static_cast<int>(k);
      if (!out.layers.empty()) out.layers[k] += step;
    }
    sum += fibre_sum;
    count += static_cast<long>(line.size()) - 1;
    const double mean = fibre_sum / static_cast<double>(line.size() - 1);
    const double ratio = mean > 0.0 ? longest / mean : 1.0;
    ratios.push_back(ratio);
    if (ratio > out.max_ratio) {
      out.max_ratio = ratio;
      out.worst_fibre = static_cast<int>(f);
      out.worst_segment = longest_at;
    }
  }
  if (count == 0) return out;
  out.mean = sum / static_cast<double>(count);
  // Median of a non-empty list, sorted in place.
  const auto median = [](std::vector<double>& v) {
    std::sort(v.begin(), v.end());
    const std::size_t n = v.size();
    return n % 2 == 1 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
  };
  out.median_ratio = median(ratios);
  if (!out.layers.empty()) {
    for (double& l : out.layers) l /= static_cast<double>(fibres.lines.size());
    std::vector<double> sorted = out.layers;
    const double middle = median(sorted);
    out.layer_ratio = middle > 0.0 ? sorted.back() / middle : 0.0;
  }
  return out;
}

double turning_angle_deg(const Vec3& u, const Vec3& v) {
  const double n = u.norm() * v.norm();
  if (!(n > 0.0)) return 0.0;
  return std::acos(std::clamp(u.dot(v) / n, -1.0, 1.0)) * 180.0 / kPi;
}

double muscle_length(const TriangleMesh& muscle) {
  if (muscle.positions.empty()) return 0.0;
  const PrincipalAxes principal = principal_axes(muscle.positions);
  const Vec3& mean = principal.mean;
  const Vec3 axis = principal.major();
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  for (const Vec3& p : muscle.positions) {
    const double t = (p - mean).dot(axis);
    lo = std::min(lo, t);
    hi = std::max(hi, t);
  }
  return hi - lo;
}

bool segment_leaves(const SurfaceQuery& query, const Vec3& a, const Vec3& b, double margin_a, double margin_b) {
  const Vec3 m = 0.5 * (a + b);
  const double half = 0.5 * (b - a).norm();
  if (!(half > 0.0)) return false;
  Vec3 hit;
  for (int side = 0; side < 2; ++side) {
    const double margin = side == 0 ? margin_a : margin_b;
    if (margin >= half) continue;
    if (query.first_hit(m, (side == 0 ? a : b) - m, 1.0 - margin / half, hit)) return true;
  }
  return false;
}

bool fibre_segment_leaves(const SurfaceQuery& query, const Vec3& a, const Vec3& b, int k, int segments,
                          double end_tolerance) {
  return segment_leaves(query, a, b, k == 0 ? end_tolerance : 0.0, k + 1 == segments ? end_tolerance : 0.0);
}

double segment_excursion(const SurfaceQuery& query, const Vec3& a, const Vec3& b, int samples, double* t,
                         Vec3* closest) {
  double deepest = 0.0;
  for (int i = 1; i <= samples; ++i) {
    const double u = static_cast<double>(i) / (samples + 1);
    const Vec3 p = a + u * (b - a);
    if (query.side(p) != Side::outside) continue;
    const SurfacePoint c = query.closest_point(p);
    if (!(c.distance > deepest)) continue;
    deepest = c.distance;
    if (t) *t = u;
    if (closest) *closest = c.position;
  }
  return deepest;
}

CheckReport check_fibres(const Polylines& fibres, const TriangleMesh& muscle, const Attachments& areas,
                         const CheckOptions& options) {
  options.validate();
  if (muscle.triangles.empty()) throw TopologyError("fibre check: the muscle mesh has no triangles");
  const SurfaceQuery query(muscle);
  return check_fibres(fibres, muscle, query, areas, options);
}

CheckReport check_fibres(const Polylines& fibres, const TriangleMesh& muscle, const SurfaceQuery& query,
                         const Attachments& areas, const CheckOptions& options) {
  const auto start = std::chrono::steady_clock::now();
  options.validate();
  if (fibres.lines.empty()) throw InputError(ErrorCode::file_empty, "fibre check: there are no fibres");
  for (std::size_t f = 0; f < fibres.lines.size(); ++f) {
    if (fibres.lines[f].size() < 2)
      throw InputError(ErrorCode::malformed, "fibre check: fibre " + std::to_string(f) + " has " +
                                                 std::to_string(fibres.lines[f].size()) +
                                                 " point(s), needs at least 2");
    for (const Vec3& p : fibres.lines[f])
      if (!p.allFinite())
        throw InputError(ErrorCode::bad_number,
                         "fibre check: fibre " + std::to_string(f) + " has a point that is not finite");
  }
  if (muscle.triangles.empty()) throw TopologyError("fibre check: the muscle mesh has no triangles");
  const double volume = signed_volume(muscle);
  if (!(volume > 0.0))
    throw TopologyError("fibre check: the muscle has volume " + fmt_double(volume) +
                        " (needs a closed, outward-oriented surface: repair it first)");
  if (areas.origin.points.empty() || areas.insertion.points.empty())
    throw InputError(
        ErrorCode::landmarks,
        "fibre check: the " + std::string(areas.origin.points.empty() ? "origin" : "insertion") + " area has no point");

  CheckReport report;
  report.thresholds = options;
  report.fibres = static_cast<long>(fibres.lines.size());
  const double diagonal = bounding_box(muscle.positions).diagonal();
  const InsideGrid& inside = query.inside_grid();  // the grid query.side() consults

  // ---- inside test of every fibre point ----
  std::vector<std::size_t> first_point(fibres.lines.size() + 1, 0);
  for (std::size_t f = 0; f < fibres.lines.size(); ++f) first_point[f + 1] = first_point[f] + fibres.lines[f].size();
  const std::size_t total_points = first_point.back();
  report.points = static_cast<long>(total_points);
  std::vector<char> point_ok(total_points, 0);
  const double end_tolerance = options.end_tolerance * diagonal;
  tbb::parallel_for(std::size_t(0), fibres.lines.size(), [&](std::size_t f) {
    const auto& line = fibres.lines[f];
    for (std::size_t k = 0; k < line.size(); ++k) {
      const Side side = query.side(line[k]);
      bool ok = side == Side::inside;
      if (!ok && (k == 0 || k + 1 == line.size())) ok = query.closest_point(line[k]).distance <= end_tolerance;
      point_ok[first_point[f] + k] = ok ? 1 : 0;
    }
  });
  for (std::size_t f = 0; f < fibres.lines.size(); ++f)
    for (std::size_t k = 0; k < fibres.lines[f].size(); ++k) {
      if (point_ok[first_point[f] + k]) {
        ++report.inside_points;
        continue;
      }
      if (static_cast<int>(report.outside_examples.size()) < options.outside_listed) {
        OutsidePoint o;
        o.fibre = static_cast<int>(f);
        o.point = static_cast<int>(k);
        o.position = fibres.lines[f][k];
        o.distance = query.closest_point(o.position).distance;
        report.outside_examples.push_back(o);
      }
    }
  report.outside = report.points - report.inside_points;
  report.inside_fraction = static_cast<double>(report.inside_points) / static_cast<double>(report.points);

  // ---- segments ----
  // A segment touches the surface when one of its points failed the inside test, or when a ray
  // from its midpoint towards either end hits the surface before that end (minus the end
  // tolerance where the end is a fibre end, which lies on the surface by design); a touching
  // segment crosses when its sampled excursion is beyond the tolerance.
  const double segment_tolerance = options.segment_tolerance * diagonal;
  {
    std::vector<std::vector<CrossingSegment>> touching(fibres.lines.size());
    tbb::parallel_for(std::size_t(0), fibres.lines.size(), [&](std::size_t f) {
      const auto& line = fibres.lines[f];
      const std::size_t last = line.size() - 1;
      for (std::size_t k = 0; k < last; ++k) {
        const Vec3& a = line[k];
        const Vec3& b = line[k + 1];
        const bool touches =
            !point_ok[first_point[f] + k] || !point_ok[first_point[f] + k + 1] ||
            fibre_segment_leaves(query, a, b, static_cast<int>(k), static_cast<int>(last), end_tolerance);
        if (!touches) continue;
        CrossingSegment c;
        c.fibre = static_cast<int>(f);
        c.segment = static_cast<int>(k);
        c.excursion = segment_excursion(query, a, b, options.excursion_samples);
        touching[f].push_back(c);
      }
    });
    report.segments = static_cast<long>(total_points - fibres.lines.size());
    for (const auto& list : touching)
      for (const CrossingSegment& c : list) {
        ++report.touching_segments;
        report.max_segment_excursion = std::max(report.max_segment_excursion, c.excursion);
        if (!(c.excursion > segment_tolerance)) continue;
        ++report.crossing_segments;
        if (static_cast<int>(report.crossing_examples.size()) < options.outside_listed)
          report.crossing_examples.push_back(c);
      }
    report.segment_inside_fraction =
        report.segments > 0 ? 1.0 - static_cast<double>(report.crossing_segments) / static_cast<double>(report.segments)
                            : 1.0;
    report.max_segment_excursion_diagonal = diagonal > 0.0 ? report.max_segment_excursion / diagonal : 0.0;
  }

  // ---- lattice cells ----
  const FibreGrid grid = fibre_grid(fibres);
  report.lattice = grid.is_lattice();
  report.lattice_nr = grid.nr;
  report.lattice_ns = grid.ns;
  if (report.lattice) count_inverted_cells(fibres, grid, options.outside_listed, report);

  // ---- lengths and turning angles ----
  std::vector<double> lengths(fibres.lines.size());
  TurningFigures& turning = report.turning;
  for (std::size_t f = 0; f < fibres.lines.size(); ++f) {
    const auto& line = fibres.lines[f];
    lengths[f] = polyline_length(line);
    Vec3 previous = Vec3::Zero();
    int first_joint = -1, last_joint = -1;
    std::vector<std::pair<int, double>> joints;  // (point index, angle) of this fibre
    for (std::size_t k = 0; k + 1 < line.size(); ++k) {
      const Vec3 d = line[k + 1] - line[k];
      if (d.norm() == 0.0) continue;  // repeated points have no direction
      if (previous.norm() > 0.0) {
        const double angle = turning_angle_deg(previous, d);
        joints.emplace_back(static_cast<int>(k), angle);
        if (first_joint < 0) first_joint = static_cast<int>(k);
        last_joint = static_cast<int>(k);
      }
      previous = d;
    }
    for (const auto& [joint, angle] : joints) {
      ++turning.joints;
      turning.over_30 += angle > 30.0 ? 1 : 0;
      if (angle > 45.0) {
        ++turning.over_45;
        turning.end_joints_over_45 += joint == first_joint || joint == last_joint ? 1 : 0;
      }
      if (angle > turning.max_deg) {
        turning.max_deg = angle;
        turning.fibre = static_cast<int>(f);
        turning.joint = joint;
        turning.max_at_end = joint == first_joint || joint == last_joint;
      }
    }
  }
  report.max_turning_angle_deg = turning.max_deg;
  report.steps = step_figures(fibres);
  double sum = 0.0, sum2 = 0.0;
  report.length.min = std::numeric_limits<double>::infinity();
  report.length.max = 0.0;
  for (double l : lengths) {
    sum += l;
    sum2 += l * l;
    report.length.min = std::min(report.length.min, l);
    report.length.max = std::max(report.length.max, l);
  }
  const double n = static_cast<double>(lengths.size());
  report.length.mean = sum / n;
  const double variance = std::max(0.0, sum2 / n - report.length.mean * report.length.mean);
  report.length.cv = report.length.mean > 0.0 ? std::sqrt(variance) / report.length.mean : 0.0;

  // ---- coverage ----
  report.coverage.volume = volume;
  report.coverage.ideal_spacing = report.length.mean > 0.0 ? std::sqrt(volume / (n * report.length.mean)) : 0.0;
  {
    // Uniform samples in the muscle by rejection from the union of the grid cells that can hold
    // inside points (all cells have the same volume: pick a cell uniformly, then a point in
    // it), which wastes far fewer candidates than the bounding box. Candidates come from one
    // seeded sequence and are accepted in order, so the result does not depend on the batching
    // or the thread count. The attempt cap only guards a degenerate muscle.
    const std::vector<long> cells = inside.candidate_cells();
    std::mt19937_64 rng(options.seed);
    std::uniform_int_distribution<std::size_t> pick(0, cells.empty() ? 0 : cells.size() - 1);
    std::uniform_real_distribution<double> unit(0.0, 1.0);
    std::vector<Vec3> samples;
    const std::size_t wanted = static_cast<std::size_t>(options.coverage_samples);
    samples.reserve(wanted);
    const std::size_t max_attempts = cells.empty() ? 0 : 1000 * wanted + 100000;
    std::size_t attempts = 0;
    while (samples.size() < wanted && attempts < max_attempts) {
      const std::size_t batch =
          std::min(max_attempts - attempts, std::max<std::size_t>(1024, 2 * (wanted - samples.size())));
      std::vector<Vec3> candidates(batch);
      for (auto& c : candidates) {
        const Vec3 corner = inside.cell_corner(cells[pick(rng)]);
        const double x = unit(rng), y = unit(rng), z = unit(rng);
        c = corner + inside.cell_size() * Vec3(x, y, z);
      }
      attempts += batch;
      std::vector<char> accepted(batch, 0);
      tbb::parallel_for(std::size_t(0), batch,
                        [&](std::size_t i) { accepted[i] = query.side(candidates[i]) == Side::inside; });
      for (std::size_t i = 0; i < batch && samples.size() < wanted; ++i)
        if (accepted[i]) samples.push_back(candidates[i]);
    }
    const SegmentTree segments(fibres);
    std::vector<double> distances(samples.size());
    tbb::parallel_for(std::size_t(0), samples.size(),
                      [&](std::size_t i) { distances[i] = segments.nearest(samples[i]); });
    report.coverage.samples = static_cast<int>(samples.size());
    if (!distances.empty() && report.coverage.ideal_spacing > 0.0) {
      double total = 0.0, largest = 0.0;
      for (double d : distances) {
        total += d;
        largest = std::max(largest, d);
      }
      const double spacing = report.coverage.ideal_spacing;
      report.coverage.mean = total / static_cast<double>(distances.size()) / spacing;
      report.coverage.max = largest / spacing;
      report.coverage.p95 = percentile(distances, 0.95) / spacing;
      report.coverage.far = far_samples(samples, distances, spacing, options.max_coverage_p95,
                                        report.coverage.p95 > options.max_coverage_p95, muscle, query, areas);
    }
  }

  // ---- attachment ----
  const double length = muscle_length(muscle);
  report.attachment.muscle_length = length;
  report.max_segment_excursion_relative = length > 0.0 ? report.max_segment_excursion / length : 0.0;
  report.attachment.origin_points = static_cast<long>(areas.origin.points.size());
  report.attachment.insertion_points = static_cast<long>(areas.insertion.points.size());
  {
    std::vector<double> to_origin(fibres.lines.size()), to_insertion(fibres.lines.size());
    auto nearest = [](const AttachmentArea& area, const Vec3& p) {
      double best = std::numeric_limits<double>::infinity();
      for (const SurfacePoint& q : area.points) best = std::min(best, (q.position - p).squaredNorm());
      return std::sqrt(best);
    };
    tbb::parallel_for(std::size_t(0), fibres.lines.size(), [&](std::size_t f) {
      to_origin[f] = nearest(areas.origin, fibres.lines[f].front()) / length;
      to_insertion[f] = nearest(areas.insertion, fibres.lines[f].back()) / length;
    });
    for (std::size_t f = 0; f < fibres.lines.size(); ++f) {
      report.attachment.origin_max = std::max(report.attachment.origin_max, to_origin[f]);
      report.attachment.insertion_max = std::max(report.attachment.insertion_max, to_insertion[f]);
      report.attachment.origin_mean += to_origin[f] / n;
      report.attachment.insertion_mean += to_insertion[f] / n;
    }
  }

  // ---- ends spread over their areas ----
  {
    std::vector<Vec3> first, last;
    for (const auto& line : fibres.lines) {
      first.push_back(line.front());
      last.push_back(line.back());
    }
    const double radius = options.end_region_radius * length;
    report.origin_ends = end_coverage(muscle, areas.origin, first, radius, options.end_samples, options.seed);
    report.insertion_ends = end_coverage(muscle, areas.insertion, last, radius, options.end_samples, options.seed + 1);
  }

  // ---- verdict ----
  report.failed = failed_criteria(report, options);
  report.pass = report.failed.empty();
  report.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return report;
}

nlohmann::json CheckReport::to_json() const {
  nlohmann::json outside_list = nlohmann::json::array();
  for (const OutsidePoint& o : outside_examples)
    outside_list.push_back({{"fibre", o.fibre},
                            {"point", o.point},
                            {"position", {o.position.x(), o.position.y(), o.position.z()}},
                            {"distance_to_surface", o.distance}});
  nlohmann::json crossing_list = nlohmann::json::array();
  for (const CrossingSegment& c : crossing_examples)
    crossing_list.push_back({{"fibre", c.fibre}, {"segment", c.segment}, {"excursion", c.excursion}});
  nlohmann::json inverted_list = nlohmann::json::array();
  for (const auto& c : inverted_examples) inverted_list.push_back({{"r", c[0]}, {"s", c[1]}, {"k", c[2]}});
  return {
      {"fibres", fibres},
      {"points", points},
      {"inside_fraction", inside_fraction},
      {"inside_points", inside_points},
      {"outside_points", outside},
      {"outside_examples", outside_list},
      {"segments", segments},
      {"crossing_segments", crossing_segments},
      {"touching_segments", touching_segments},
      {"segment_inside_fraction", segment_inside_fraction},
      {"max_segment_excursion_diagonal", max_segment_excursion_diagonal},
      {"max_segment_excursion", max_segment_excursion},
      {"max_segment_excursion_relative", max_segment_excursion_relative},
      {"crossing_examples", crossing_list},
      {"lattice", lattice},
      {"lattice_nr", lattice_nr},
      {"lattice_ns", lattice_ns},
      {"cells", cells},
      {"inverted_cells", inverted_cells},
      {"inverted_examples", inverted_list},
      {"coverage",
       {{"mean", coverage.mean},
        {"p95", coverage.p95},
        {"max", coverage.max},
        {"ideal_spacing", coverage.ideal_spacing},
        {"volume", coverage.volume},
        {"samples", coverage.samples},
        {"far",
         {{"threshold", coverage.far.threshold},
          {"fraction", coverage.far.fraction},
          {"along_samples", coverage.far.along_samples},
          {"along_far", coverage.far.along_far},
          {"depth_measured", coverage.far.depth_measured},
          {"depth_edges", {0.0, 1.0, 2.0, 4.0}},
          {"depth_samples", coverage.far.depth_samples},
          {"depth_far", coverage.far.depth_far}}}}},
      {"attachment",
       {{"origin_max", attachment.origin_max},
        {"origin_mean", attachment.origin_mean},
        {"insertion_max", attachment.insertion_max},
        {"insertion_mean", attachment.insertion_mean},
        {"muscle_length", attachment.muscle_length},
        {"origin_points", attachment.origin_points},
        {"insertion_points", attachment.insertion_points}}},
      {"length", {{"mean", length.mean}, {"min", length.min}, {"max", length.max}, {"cv", length.cv}}},
      {"steps",
       {{"mean", steps.mean},
        {"max_ratio", steps.max_ratio},
        {"median_ratio", steps.median_ratio},
        {"worst_fibre", steps.worst_fibre},
        {"worst_segment", steps.worst_segment},
        {"layers", steps.layers},
        {"layer_ratio", steps.layer_ratio}}},
      {"max_turning_angle_deg", max_turning_angle_deg},
      {"turning",
       {{"max_deg", turning.max_deg},
        {"fibre", turning.fibre},
        {"joint", turning.joint},
        {"joints", turning.joints},
        {"over_30", turning.over_30},
        {"over_45", turning.over_45},
        {"end_joints_over_45", turning.end_joints_over_45},
        {"max_at_end", turning.max_at_end}}},
      {"ends",
       {{"origin",
         {{"share", origin_ends.share},
          {"spacing", origin_ends.spacing},
          {"area", origin_ends.area},
          {"samples", origin_ends.samples}}},
        {"insertion",
         {{"share", insertion_ends.share},
          {"spacing", insertion_ends.spacing},
          {"area", insertion_ends.area},
          {"samples", insertion_ends.samples}}}}},
      {"thresholds",
       {{"min_inside_fraction", thresholds.min_inside_fraction},
        {"max_inverted_cells", thresholds.max_inverted_cells},
        {"max_coverage_p95", thresholds.max_coverage_p95},
        {"max_attachment", thresholds.max_attachment},
        {"max_crossing_segments", thresholds.max_crossing_segments},
        {"segment_tolerance", thresholds.segment_tolerance},
        {"max_turning_angle_deg", thresholds.max_turning_angle_deg},
        {"end_region_radius", thresholds.end_region_radius},
        {"end_samples", thresholds.end_samples},
        {"min_end_coverage", thresholds.min_end_coverage},
        {"excursion_samples", thresholds.excursion_samples},
        {"end_tolerance", thresholds.end_tolerance},
        {"coverage_samples", thresholds.coverage_samples},
        {"seed", thresholds.seed}}},
      {"pass", pass},
      {"failed", failed},
      {"seconds", seconds},
  };
}

std::string CheckReport::to_table() const {
  auto verdict = [this](const char* name) {
    return std::find(failed.begin(), failed.end(), name) == failed.end() ? "pass" : "FAIL";
  };
  char line[256];
  std::string out;
  std::snprintf(line, sizeof(line), "%-16s %-22s %-12s %s\n", "criterion", "value", "threshold", "verdict");
  out += line;
  std::snprintf(line, sizeof(line), "%-16s %-22s %-12s %s\n", "inside_fraction",
                (fmt_double(inside_fraction) + " (" + std::to_string(outside) + " out)").c_str(),
                (">= " + fmt_double(thresholds.min_inside_fraction)).c_str(), verdict("inside"));
  out += line;
  std::snprintf(
      line, sizeof(line), "%-16s %-22s %-12s %s\n", "inverted_cells",
      lattice ? (std::to_string(inverted_cells) + " of " + std::to_string(cells)).c_str() : "n/a (no lattice)",
      ("<= " + std::to_string(thresholds.max_inverted_cells)).c_str(), verdict("inverted_cells"));
  out += line;
  std::snprintf(line, sizeof(line), "%-16s %-22s %-12s %s\n", "coverage_p95",
                (fmt_double(coverage.p95) + " (mean " + fmt_double(coverage.mean) + ")").c_str(),
                ("<= " + fmt_double(thresholds.max_coverage_p95)).c_str(), verdict("coverage"));
  out += line;
  std::snprintf(line, sizeof(line), "%-16s %-22s %-12s %s\n", "attachment_max",
                (fmt_double(attachment.origin_max) + " / " + fmt_double(attachment.insertion_max)).c_str(),
                ("<= " + fmt_double(thresholds.max_attachment)).c_str(), verdict("attachment"));
  out += line;
  const bool judged = thresholds.max_crossing_segments >= 0;
  std::snprintf(line, sizeof(line), "%-16s %-22s %-12s %s\n", "crossing_segs",
                (std::to_string(crossing_segments) + " of " + std::to_string(segments) + ", out " +
                 fmt_double(100.0 * max_segment_excursion_diagonal) + " %")
                    .c_str(),
                judged ? ("<= " + std::to_string(thresholds.max_crossing_segments)).c_str() : "(reported)",
                judged ? verdict("segments") : "-");
  out += line;
  std::snprintf(line, sizeof(line), "%-16s %-22s %-12s %s\n", "turning_max",
                (fmt_double(turning.max_deg) + " deg (" + std::to_string(turning.over_45) + " > 45)").c_str(),
                ("<= " + fmt_double(thresholds.max_turning_angle_deg)).c_str(), verdict("smooth"));
  out += line;
  std::snprintf(line, sizeof(line), "%-16s %-22s %-12s %s\n", "end_coverage",
                (fmt_double(origin_ends.share) + " / " + fmt_double(insertion_ends.share)).c_str(),
                (">= " + fmt_double(thresholds.min_end_coverage)).c_str(), verdict("ends"));
  out += line;
  out += "segments the surface cuts at all: " + std::to_string(touching_segments) + " (the tolerance is " +
         fmt_double(100.0 * thresholds.segment_tolerance) + " % of the diagonal)\n";
  if (turning.fibre >= 0)
    out += "largest turn at fibre " + std::to_string(turning.fibre) + ", point " + std::to_string(turning.joint) +
           "; joints over 30 deg: " + std::to_string(turning.over_30) +
           ", over 45 deg: " + std::to_string(turning.over_45) + " (" + std::to_string(turning.end_joints_over_45) +
           " at a fibre's first or last joint) of " + std::to_string(turning.joints) + "\n";
  out += "fibres " + std::to_string(fibres) + ", points " + std::to_string(points) + ", ideal spacing " +
         fmt_double(coverage.ideal_spacing) + " (" + std::to_string(coverage.samples) + " samples)\n";
  if (coverage.samples > 0) {
    // Where the far samples are: share of each tenth along the muscle and of each depth band.
    auto share = [](int part, int whole) {
      char text[16];
      std::snprintf(text, sizeof(text), "%.0f", whole > 0 ? 100.0 * part / whole : 0.0);
      return std::string(text);
    };
    char total[32];
    std::snprintf(total, sizeof(total), "%.1f", 100.0 * coverage.far.fraction);
    out += "far samples (> " + fmt_double(coverage.far.threshold) + " spacings): " + total +
           " %; per tenth, origin to insertion:";
    for (int b = 0; b < FarSamples::kAlongBins; ++b)
      out += " " + share(coverage.far.along_far[static_cast<std::size_t>(b)],
                         coverage.far.along_samples[static_cast<std::size_t>(b)]);
    if (coverage.far.depth_measured) {
      out += " %; by depth 0-1, 1-2, 2-4, 4+ spacings:";
      for (int b = 0; b < FarSamples::kDepthBins; ++b)
        out += " " + share(coverage.far.depth_far[static_cast<std::size_t>(b)],
                           coverage.far.depth_samples[static_cast<std::size_t>(b)]);
    }
    out += " %\n";
  }
  out += "length mean " + fmt_double(length.mean) + ", min " + fmt_double(length.min) + ", max " +
         fmt_double(length.max) + ", cv " + fmt_double(length.cv) + "; largest turning angle " +
         fmt_double(max_turning_angle_deg) + " deg\n";
  out += "steps mean " + fmt_double(steps.mean) + "; longest / mean per fibre: median " +
         fmt_double(steps.median_ratio) + ", largest " + fmt_double(steps.max_ratio);
  if (steps.worst_fibre >= 0)
    out += " (fibre " + std::to_string(steps.worst_fibre) + " between points " + std::to_string(steps.worst_segment) +
           " and " + std::to_string(steps.worst_segment + 1) + ")";
  if (!steps.layers.empty()) out += "; longest layer / median layer " + fmt_double(steps.layer_ratio);
  out += "\n";
  for (const auto& c : inverted_examples)
    out += "inverted: cell r " + std::to_string(c[0]) + " s " + std::to_string(c[1]) + " between points " +
           std::to_string(c[2]) + " and " + std::to_string(c[2] + 1) + "\n";
  for (const CrossingSegment& c : crossing_examples)
    out += "crossing: fibre " + std::to_string(c.fibre) + " between points " + std::to_string(c.segment) + " and " +
           std::to_string(c.segment + 1) + ", " + fmt_double(c.excursion) + " outside the surface\n";
  for (const OutsidePoint& o : outside_examples)
    out += "outside: fibre " + std::to_string(o.fibre) + " point " + std::to_string(o.point) + " at (" +
           fmt_double(o.position.x()) + ", " + fmt_double(o.position.y()) + ", " + fmt_double(o.position.z()) + "), " +
           fmt_double(o.distance) + " from the surface\n";
  std::string result = pass ? "pass" : "FAIL:";
  for (const auto& f : failed) result += " " + f;
  out += "result: " + result + " (" + fmt_double(seconds) + " s)\n";
  return out;
}

std::string CheckReport::summary() const {
  const auto verdict = [this](const char* name) {
    return std::find(failed.begin(), failed.end(), name) == failed.end() ? "" : " FAIL";
  };
  std::string out = pass ? "pass:" : "FAIL:";
  out += " inside " + fmt_double(inside_fraction) + " (>= " + fmt_double(thresholds.min_inside_fraction) + ")" +
         verdict("inside");
  if (lattice)
    out += ", inverted cells " + std::to_string(inverted_cells) +
           " (<= " + std::to_string(thresholds.max_inverted_cells) + ")" + verdict("inverted_cells");
  out += ", coverage p95 " + fmt_double(coverage.p95) + " (<= " + fmt_double(thresholds.max_coverage_p95) + ")" +
         verdict("coverage");
  out += ", attachment " + fmt_double(std::max(attachment.origin_max, attachment.insertion_max)) +
         " (<= " + fmt_double(thresholds.max_attachment) + ")" + verdict("attachment");
  out +=
      ", segments out " + std::to_string(crossing_segments) + " (<= " +
      (thresholds.max_crossing_segments >= 0 ? std::to_string(thresholds.max_crossing_segments) : std::string("any")) +
      " beyond " + fmt_double(100.0 * thresholds.segment_tolerance) + " %)" + verdict("segments");
  out += ", turning " + fmt_double(turning.max_deg) + " deg (<= " + fmt_double(thresholds.max_turning_angle_deg) + ")" +
         verdict("smooth");
  out += ", ends " + fmt_double(origin_ends.share) + " / " + fmt_double(insertion_ends.share) +
         " (>= " + fmt_double(thresholds.min_end_coverage) + ")" + verdict("ends");
  return out;
}

std::vector<std::string> failed_criteria(const CheckReport& report, const CheckOptions& options) {
  std::vector<std::string> failed;
  if (report.inside_fraction < options.min_inside_fraction) failed.push_back("inside");
  if (report.inverted_cells > options.max_inverted_cells) failed.push_back("inverted_cells");
  if (!(report.coverage.p95 <= options.max_coverage_p95)) failed.push_back("coverage");
  if (!(std::max(report.attachment.origin_max, report.attachment.insertion_max) <= options.max_attachment))
    failed.push_back("attachment");
  if (options.max_crossing_segments >= 0 && report.crossing_segments > options.max_crossing_segments)
    failed.push_back("segments");
  if (!(report.turning.max_deg <= options.max_turning_angle_deg)) failed.push_back("smooth");
  if (!(std::min(report.origin_ends.share, report.insertion_ends.share) >= options.min_end_coverage))
    failed.push_back("ends");
  return failed;
}

}  // namespace fascicle
