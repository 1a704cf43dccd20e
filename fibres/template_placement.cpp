#include "fibres/template_placement.h"

#include "fibres/pole_frame.h"
#include "geometry/errors.h"
#include "geometry/detail/for_each_index.h"
#include "geometry/mesh_stats.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <nlohmann/json.hpp>
#include <numeric>
#include <optional>
#include <unordered_map>

namespace fascicle {

namespace {

constexpr double kPi = 3.14159265358979323846;

// Vertices within `radius` of any of `points` (hash grid of cell `radius`), plus for each point
// the nearest corner of its face, so that a region is never empty.
std::vector<char> region_of(const TriangleMesh& mesh, const AttachmentArea& area, double radius) {
  std::vector<char> in(mesh.positions.size(), 0);
  const Vec3 lo = bounding_box(mesh.positions).min;
  auto key = [&](const Vec3& p) {
    const Vec3 c = (p - lo) / radius;
    const auto ix = static_cast<long long>(std::floor(c.x()));
    const auto iy = static_cast<long long>(std::floor(c.y()));
    const auto iz = static_cast<long long>(std::floor(c.z()));
    return std::array<long long, 3>{ix, iy, iz};
  };
  auto hash = [](long long x, long long y, long long z) {
    return static_cast<unsigned long long>(x) * 73856093ULL ^ static_cast<unsigned long long>(y) * 19349663ULL ^
           static_cast<unsigned long long>(z) * 83492791ULL;
  };
  std::unordered_map<unsigned long long, std::vector<int>> grid;
  for (std::size_t i = 0; i < area.points.size(); ++i) {
    const auto k = key(area.points[i].position);
    grid[hash(k[0], k[1], k[2])].push_back(static_cast<int>(i));
  }
  const double r2 = radius * radius;
  // Vertices outside the points' box grown by twice the radius are farther than the radius
  // from every point: no grid lookups for them.
  Vec3 box_lo = Vec3::Constant(std::numeric_limits<double>::infinity()), box_hi = -box_lo;
  for (const SurfacePoint& sp : area.points) {
    box_lo = box_lo.cwiseMin(sp.position);
    box_hi = box_hi.cwiseMax(sp.position);
  }
  box_lo.array() -= 2.0 * radius;
  box_hi.array() += 2.0 * radius;
  for (std::size_t v = 0; v < mesh.positions.size(); ++v) {
    const Vec3& p = mesh.positions[v];
    if ((p.array() < box_lo.array()).any() || (p.array() > box_hi.array()).any()) continue;
    const auto k = key(p);
    bool found = false;
    for (long long dx = -1; dx <= 1 && !found; ++dx)
      for (long long dy = -1; dy <= 1 && !found; ++dy)
        for (long long dz = -1; dz <= 1 && !found; ++dz) {
          const auto it = grid.find(hash(k[0] + dx, k[1] + dy, k[2] + dz));
          if (it == grid.end()) continue;
          for (int i : it->second)
            if ((area.points[static_cast<std::size_t>(i)].position - p).squaredNorm() <= r2) {
              found = true;
              break;
            }
        }
    in[v] = found ? 1 : 0;
  }
  for (const SurfacePoint& sp : area.points) {
    if (sp.face < 0 || sp.face >= static_cast<int>(mesh.triangles.size())) continue;
    const Triangle& t = mesh.triangles[static_cast<std::size_t>(sp.face)];
    int best = t[0];
    for (int c = 1; c < 3; ++c)
      if ((mesh.positions[t[c]] - sp.position).squaredNorm() < (mesh.positions[best] - sp.position).squaredNorm())
        best = t[c];
    in[best] = 1;
  }
  return in;
}

// The region vertex farthest (angle on the sphere) from the region's border (non-region
// vertices next to it): a centre inside the region even when it is not convex. With `away` and
// `keep` < 1, the vertex farthest from the point `away` among those at least `keep` times that
// largest distance from the border.
int region_centre(const TriangleMesh& mesh, const std::vector<Vec3>& sphere, const std::vector<char>& in,
                  const std::string& name, const Vec3* away = nullptr, double keep = 1.0) {
  std::vector<char> border(mesh.positions.size(), 0);
  for (const Triangle& t : mesh.triangles)
    for (int c = 0; c < 3; ++c) {
      const int a = t[c], b = t[(c + 1) % 3];
      if (in[a] && !in[b]) border[b] = 1;
      if (in[b] && !in[a]) border[a] = 1;
    }
  std::vector<Vec3> border_points;
  for (std::size_t v = 0; v < border.size(); ++v)
    if (border[v]) border_points.push_back(sphere[v]);
  if (border_points.empty()) throw InputError(ErrorCode::landmarks, name + " area covers the whole muscle");
  int best = -1;
  double best_cos = 2.0;  // smallest max-cosine = farthest from the border
  for (std::size_t v = 0; v < in.size(); ++v) {
    if (!in[v]) continue;
    double max_cos = -1.0;
    for (const Vec3& b : border_points) {
      max_cos = std::max(max_cos, sphere[v].dot(b));
      if (max_cos >= best_cos) break;  // cannot beat the best any more
    }
    if (max_cos < best_cos) {
      best_cos = max_cos;
      best = static_cast<int>(v);
    }
  }
  if (best < 0) throw InputError(ErrorCode::landmarks, name + " area has no vertex on the muscle");
  if (keep >= 1.0 || away == nullptr) return best;
  // Towards the far end of the region: among the vertices at least `keep` of the largest
  // border distance from the border, the one farthest (in space) from `away`.
  const double deepest = std::acos(std::clamp(best_cos, -1.0, 1.0));
  int chosen = best;
  double chosen_distance = (mesh.positions[static_cast<std::size_t>(best)] - *away).norm();
  for (std::size_t v = 0; v < in.size(); ++v) {
    if (!in[v]) continue;
    double max_cos = -1.0;
    for (const Vec3& b : border_points) max_cos = std::max(max_cos, sphere[v].dot(b));
    if (std::acos(std::clamp(max_cos, -1.0, 1.0)) < keep * deepest) continue;
    const double d = (mesh.positions[v] - *away).norm();
    if (d > chosen_distance) {
      chosen_distance = d;
      chosen = static_cast<int>(v);
    }
  }
  return chosen;
}

// Star radius R(phi) of a region around the north pole of a frame, sampled in `bins` azimuths.
class StarRadius {
 public:
  StarRadius() = default;
  // From each vertex's polar angle and azimuth in the pole frame.
  StarRadius(const std::vector<double>& polar, const std::vector<double>& azimuths, const std::vector<char>& in,
             bool south, int bins)
      : radius_(static_cast<std::size_t>(bins), kPi) {
    for (std::size_t v = 0; v < polar.size(); ++v) {
      if (in[v]) continue;
      const double theta = south ? kPi - polar[v] : polar[v];
      const std::size_t b = bin(azimuths[v]);
      radius_[b] = std::min(radius_[b], theta);
    }
    // A border vertex bounds the edges around it, which reach into the neighbouring azimuths:
    // take the minimum over two bins either side.
    std::vector<double> widened(radius_.size());
    const int n = bins;
    for (int b = 0; b < n; ++b) {
      double m = kPi;
      for (int d = -2; d <= 2; ++d) m = std::min(m, radius_[static_cast<std::size_t>(((b + d) % n + n) % n)]);
      widened[static_cast<std::size_t>(b)] = m;
    }
    radius_ = std::move(widened);
  }
  double operator()(double phi) const {
    const double n = static_cast<double>(radius_.size());
    double x = (phi + kPi) / (2.0 * kPi) * n - 0.5;  // bin centres at integer x
    x -= n * std::floor(x / n);
    const auto b0 = static_cast<std::size_t>(std::floor(x)) % radius_.size();
    const std::size_t b1 = (b0 + 1) % radius_.size();
    const double f = x - std::floor(x);
    return (1.0 - f) * radius_[b0] + f * radius_[b1];
  }
  std::vector<double>& values() { return radius_; }
  const std::vector<double>& values() const { return radius_; }

 private:
  std::size_t bin(double phi) const {
    const double n = static_cast<double>(radius_.size());
    auto b = static_cast<long long>(std::floor((phi + kPi) / (2.0 * kPi) * n));
    return static_cast<std::size_t>(std::clamp<long long>(b, 0, static_cast<long long>(radius_.size()) - 1));
  }
  std::vector<double> radius_;
};

// Cumulative share of a measure over [0, 1], as a monotone piecewise-linear function with its
// inverse.
class Cumulative {
 public:
  explicit Cumulative(int bins) : mass_(static_cast<std::size_t>(bins), 0.0) {}
  void add(double u, double weight) {
    if (!(u >= 0.0 && u <= 1.0) || !(weight > 0.0)) return;
    const auto b = std::min(mass_.size() - 1, static_cast<std::size_t>(u * static_cast<double>(mass_.size())));
    mass_[b] += weight;
  }
  void finish() {
    double total = std::accumulate(mass_.begin(), mass_.end(), 0.0);
    // A small uniform floor keeps the function strictly increasing (invertible) over empty bins.
    const double floor = (total > 0.0 ? total : 1.0) * 1e-3 / static_cast<double>(mass_.size());
    cdf_.assign(mass_.size() + 1, 0.0);
    for (std::size_t b = 0; b < mass_.size(); ++b) cdf_[b + 1] = cdf_[b] + mass_[b] + floor;
    for (double& c : cdf_) c /= cdf_.back();
  }
  /// Measure added to bins [first, last).
  double mass(int first, int last) const {
    return std::accumulate(mass_.begin() + first, mass_.begin() + last, 0.0);
  }
  double share(double u) const {
    const double x = std::clamp(u, 0.0, 1.0) * static_cast<double>(mass_.size());
    const auto b = std::min(mass_.size() - 1, static_cast<std::size_t>(x));
    return cdf_[b] + (x - static_cast<double>(b)) * (cdf_[b + 1] - cdf_[b]);
  }
  double inverse(double share_value) const {
    const double s = std::clamp(share_value, 0.0, 1.0);
    const auto it = std::upper_bound(cdf_.begin(), cdf_.end(), s);
    std::size_t b = it == cdf_.begin() ? 0 : static_cast<std::size_t>(it - cdf_.begin()) - 1;
    b = std::min(b, mass_.size() - 1);
    const double width = cdf_[b + 1] - cdf_[b];
    const double f = width > 0.0 ? (s - cdf_[b]) / width : 0.0;
    return (static_cast<double>(b) + std::clamp(f, 0.0, 1.0)) / static_cast<double>(mass_.size());
  }

 private:
  std::vector<double> mass_, cdf_;
};

// Template frame: index-box direction from the centre, rotated so that the origin face (t = 0)
// is at the north pole: (r, s, t) -> (r, -s, -t), a rotation.
Vec3 template_pole_vector(const Vec3& index_coords) {
  const Vec3 d = index_coords - Vec3(0.5, 0.5, 0.5);
  return Vec3(d.x(), -d.y(), -d.z()).normalized();
}

// Polar angle of the edge of the origin face (t = 0) of the unit index box at azimuth phi.
double face_edge(double phi) { return std::atan(1.0 / std::max(std::abs(std::cos(phi)), std::abs(std::sin(phi)))); }

// Share of the perimeter of the square [-1, 1]^2, counted anticlockwise from its corner
// (-1, -1), at the point where the ray from its centre at azimuth phi meets it.
double square_perimeter_share(double phi) {
  const double c = std::cos(phi), s = std::sin(phi);
  const double m = std::max(std::abs(c), std::abs(s));
  const double x = c / m, y = s / m;
  double share;
  if (std::abs(s) >= std::abs(c))
    share = s < 0.0 ? 0.125 * (x + 1.0) : 0.5 + 0.125 * (1.0 - x);
  else
    share = c > 0.0 ? 0.25 + 0.125 * (y + 1.0) : 0.75 + 0.125 * (1.0 - y);
  return std::clamp(share, 0.0, 1.0);
}

}  // namespace

void PlacementOptions::validate() const {
  if (!(region_radius > 0.0 && region_radius <= 0.5))
    throw OptionError("region_radius: must be in (0, 0.5], got " + std::to_string(region_radius));
  if (!(region_margin > 0.0 && region_margin <= 1.0))
    throw OptionError("region_margin: must be in (0, 1], got " + std::to_string(region_margin));
  if (azimuth_bins < 8 || azimuth_bins > 4096)
    throw OptionError("azimuth_bins: must be in 8..4096, got " + std::to_string(azimuth_bins));
  if (!(max_face_depth > 0.0)) throw OptionError("max_face_depth: must be > 0, got " + std::to_string(max_face_depth));
  if (face_shrink_rounds < 0 || face_shrink_rounds > 100)
    throw OptionError("face_shrink_rounds: must be in 0..100, got " + std::to_string(face_shrink_rounds));
  if (!(min_band > 0.0 && min_band < 3.0))
    throw OptionError("min_band: must be in (0, 3), got " + std::to_string(min_band));
  if (!(landmark_centre_keep > 0.0 && landmark_centre_keep <= 1.0))
    throw OptionError("landmark_centre_keep: must be in (0, 1], got " + std::to_string(landmark_centre_keep));
  if (!(bend_step_deg >= 0.0 && bend_step_deg <= 180.0))
    throw OptionError("bend_step_deg: must be in [0, 180], got " + std::to_string(bend_step_deg));
  if (!(corner_twist_deg >= -180.0 && corner_twist_deg <= 180.0))
    throw OptionError("corner_twist_deg: must be in [-180, 180], got " + std::to_string(corner_twist_deg));
  if (!(edge_corner_twist_deg >= -180.0 && edge_corner_twist_deg <= 180.0))
    throw OptionError("edge_corner_twist_deg: must be in [-180, 180], got " + std::to_string(edge_corner_twist_deg));
  if (!(flat_section_aspect == 0.0 || flat_section_aspect >= 1.0))
    throw OptionError("flat_section_aspect: must be 0 or >= 1, got " + std::to_string(flat_section_aspect));
}

nlohmann::json PlacementReport::to_json() const {
  return {{"origin_region_vertices", origin_region_vertices},
          {"insertion_region_vertices", insertion_region_vertices},
          {"centre_angle_deg", centre_angle_deg},
          {"origin_centre", {origin_centre.x(), origin_centre.y(), origin_centre.z()}},
          {"insertion_centre", {insertion_centre.x(), insertion_centre.y(), insertion_centre.z()}},
          {"moebius_scale", moebius_scale},
          {"twist_deg", {twist_deg, twist_end_deg}},
          {"origin_radius_deg", {origin_radius_min_deg, origin_radius_max_deg}},
          {"insertion_radius_deg", {insertion_radius_min_deg, insertion_radius_max_deg}},
          {"face_scale", {origin_face_scale, insertion_face_scale}},
          {"centre_turn_deg", centre_turn_deg},
          {"bend_share", bend_share},
          {"located", located},
          {"seconds", seconds}};
}

Placement place_template(const TriangleMesh& muscle, const std::vector<Vec3>& sphere, const SphereLocator& locator,
                         const Attachments& areas, const springs::Lattice& lattice, const PlacementOptions& options) {
  options.validate();
  const auto start = std::chrono::steady_clock::now();
  FASCICLE_CHECK(sphere.size() == muscle.positions.size(), "sphere map size");
  Placement out;
  PlacementReport& report = out.report;

  // Regions and their centres on the muscle sphere.
  const double length = muscle_length(muscle);
  const double radius = std::max(options.region_radius * length, 1e-300);
  const std::vector<char> origin_in = region_of(muscle, areas.origin, radius);
  const std::vector<char> insertion_in = region_of(muscle, areas.insertion, radius);
  report.origin_region_vertices = static_cast<int>(std::count(origin_in.begin(), origin_in.end(), 1));
  report.insertion_region_vertices = static_cast<int>(std::count(insertion_in.begin(), insertion_in.end(), 1));
  // Landmark areas: each centre towards the end of its region away from the other area.
  const Vec3 origin_centroid = areas.origin.centroid(), insertion_centroid = areas.insertion.centroid();
  const bool toward_end = !areas.automatic && options.landmark_centre_keep < 1.0;
  const int origin_vertex = region_centre(muscle, sphere, origin_in, "origin (" + areas.origin.source + ")",
                                          toward_end ? &insertion_centroid : nullptr, options.landmark_centre_keep);
  const int insertion_vertex = region_centre(muscle, sphere, insertion_in, "insertion (" + areas.insertion.source + ")",
                                             toward_end ? &origin_centroid : nullptr, options.landmark_centre_keep);
  const Vec3 origin_centre = sphere[static_cast<std::size_t>(origin_vertex)];
  const Vec3 insertion_centre = sphere[static_cast<std::size_t>(insertion_vertex)];
  report.origin_centre = muscle.positions[static_cast<std::size_t>(origin_vertex)];
  report.insertion_centre = muscle.positions[static_cast<std::size_t>(insertion_vertex)];
  report.centre_angle_deg =
      std::atan2(origin_centre.cross(insertion_centre).norm(), origin_centre.dot(insertion_centre)) * 180.0 / kPi;
  if (report.centre_angle_deg < 1e-6)
    throw InputError(ErrorCode::landmarks, areas.origin.source + " and " + areas.insertion.source +
                                               ": origin and insertion areas have the same centre");

  // Muscle pole frame, scaled so that half the surface area lies on each side of the equator.
  PoleFrame frame(origin_centre, insertion_centre);
  const std::size_t nv = muscle.positions.size();
  std::vector<double> vertex_area(nv, 0.0);
  for (const Triangle& t : muscle.triangles) {
    const double a =
        0.5 *
        (muscle.positions[t[1]] - muscle.positions[t[0]]).cross(muscle.positions[t[2]] - muscle.positions[t[0]]).norm();
    for (int c = 0; c < 3; ++c) vertex_area[t[c]] += a / 3.0;
  }
  {
    std::vector<std::pair<double, double>> modulus(nv);
    for_each_index(nv, [&](std::size_t v) {
      modulus[v] = {std::abs(PoleFrame::stereographic(frame.to_pole(sphere[v]))), vertex_area[v]};
    });
    double total = 0.0;
    for (std::size_t v = 0; v < nv; ++v) total += vertex_area[v];
    std::sort(modulus.begin(), modulus.end());
    double acc = 0.0, median = 1.0;
    for (const auto& [m, a] : modulus) {
      acc += a;
      if (acc >= 0.5 * total) {
        median = m;
        break;
      }
    }
    if (median > 1e-12 && std::isfinite(median)) frame.set_scale(1.0 / median);
  }
  report.moebius_scale = frame.scale();
  // Per vertex: its pole-frame direction, polar angle and azimuth.
  std::vector<Vec3> pole(nv);
  std::vector<double> vertex_theta(nv), vertex_phi(nv);
  for_each_index(nv, [&](std::size_t v) {
    pole[v] = frame.to_pole(sphere[v]);
    vertex_theta[v] = polar_angle(pole[v]);
    vertex_phi[v] = azimuth(pole[v]);
  });

  // Star radii of both regions, kept apart by the lateral band.
  StarRadius origin_radius(vertex_theta, vertex_phi, origin_in, false, options.azimuth_bins);
  StarRadius insertion_radius(vertex_theta, vertex_phi, insertion_in, true, options.azimuth_bins);
  for (std::size_t b = 0; b < origin_radius.values().size(); ++b) {
    double& ro = origin_radius.values()[b];
    double& ri = insertion_radius.values()[b];
    ro *= options.region_margin;
    ri *= options.region_margin;
    const double room = kPi - options.min_band;
    if (ro + ri > room) {
      const double f = room / (ro + ri);
      ro *= f;
      ri *= f;
    }
  }
  const auto [omin, omax] = std::minmax_element(origin_radius.values().begin(), origin_radius.values().end());
  const auto [imin, imax] = std::minmax_element(insertion_radius.values().begin(), insertion_radius.values().end());
  report.origin_radius_min_deg = *omin * 180.0 / kPi;
  report.origin_radius_max_deg = *omax * 180.0 / kPi;
  report.insertion_radius_min_deg = *imin * 180.0 / kPi;
  report.insertion_radius_max_deg = *imax * 180.0 / kPi;

  // Twist: the template's r axis (azimuth 0 in its frame) towards the muscle's second axis.
  const PrincipalAxes axes = principal_axes(muscle.positions);
  const Vec3 second = axes.axes.col(1);
  // Per vertex and per face, what place() below needs and does not depend on the face scales:
  // pole-frame angles, star radii, cos and sin of the azimuth, face areas (place() runs up to
  // 1 + face_shrink_rounds times).
  std::vector<double> vertex_cos(nv), vertex_sin(nv), vertex_ro(nv), vertex_ri(nv);
  for_each_index(nv, [&](std::size_t v) {
    vertex_cos[v] = std::cos(vertex_phi[v]);
    vertex_sin[v] = std::sin(vertex_phi[v]);
    vertex_ro[v] = origin_radius(vertex_phi[v]);
    vertex_ri[v] = insertion_radius(vertex_phi[v]);
  });
  const std::size_t n_faces = muscle.triangles.size();
  std::vector<double> face_theta(n_faces), face_phi(n_faces), face_ro(n_faces), face_ri(n_faces), face_area(n_faces);
  for_each_index(n_faces, [&](std::size_t f) {
    const Triangle& t = muscle.triangles[f];
    const Vec3 c = (pole[t[0]] + pole[t[1]] + pole[t[2]]).normalized();
    face_phi[f] = azimuth(c);
    face_theta[f] = polar_angle(c);
    face_ro[f] = origin_radius(face_phi[f]);
    face_ri[f] = insertion_radius(face_phi[f]);
    face_area[f] =
        0.5 *
        (muscle.positions[t[1]] - muscle.positions[t[0]]).cross(muscle.positions[t[2]] - muscle.positions[t[0]]).norm();
  });
  // Meridian rings: each face's centre and azimuth sector (neither depends on the face scales).
  constexpr int kMeridians = 24;
  std::vector<Vec3> triangle_centre;
  std::vector<int> triangle_sector;
  if (options.band_by_length && options.meridian_rings) {
    triangle_centre.resize(n_faces);
    triangle_sector.resize(n_faces);
    for (std::size_t f = 0; f < n_faces; ++f) {
      const Triangle& t = muscle.triangles[f];
      triangle_centre[f] = (muscle.positions[t[0]] + muscle.positions[t[1]] + muscle.positions[t[2]]) / 3.0;
      const double x = face_phi[f] / (2.0 * kPi);
      triangle_sector[f] = static_cast<int>(std::floor((x - std::floor(x)) * kMeridians)) % kMeridians;
    }
  }
  double sx = 0.0, sy = 0.0;
  for (std::size_t v = 0; v < nv; ++v) {
    const double theta = vertex_theta[v];
    if (theta < kPi / 4.0 || theta > 3.0 * kPi / 4.0) continue;
    const double w = (muscle.positions[v] - axes.mean).dot(second) * vertex_area[v];
    sx += w * vertex_cos[v];
    sy += w * vertex_sin[v];
  }
  const double twist = (sx == 0.0 && sy == 0.0) ? 0.0 : std::atan2(sy, sx);

  // Area shares along the lateral band, muscle and template; then every surface point of the
  // lattice: template sphere -> muscle pole frame -> muscle sphere. `so` and `si` scale the two
  // star radii (the part of each region the attachment face covers).
  std::vector<int> surface_points;
  constexpr int kBandBins = 512;
  Cumulative template_band(kBandBins);
  for (const Triangle& t : lattice.surface) {
    const Vec3 c = (template_pole_vector(springs::lattice_coordinates(lattice, t[0])) +
                    template_pole_vector(springs::lattice_coordinates(lattice, t[1])) +
                    template_pole_vector(springs::lattice_coordinates(lattice, t[2])))
                       .normalized();
    const double edge = face_edge(azimuth(c));
    const double u = (polar_angle(c) - edge) / (kPi - 2.0 * edge);
    const auto& p = lattice.system.positions;
    const double a = 0.5 * (p[t[1]] - p[t[0]]).cross(p[t[2]] - p[t[0]]).norm();
    template_band.add(u, a);
  }
  template_band.finish();
  auto place = [&](double so, double si) {
    Cumulative muscle_band(kBandBins);

    // Twist along the band: at each level u the template's r axis turns towards the muscle's
    // second principal axis as seen from that level's centroid, so that the lattice follows the
    // muscle's cross-sections instead of the sphere map's azimuths (which rotate along a long
    // muscle); unwrapped and smoothed along u.
    constexpr int kLevels = 32;
    std::vector<Vec3> level_centre(kLevels, Vec3::Zero());
    std::vector<double> level_area(kLevels, 0.0), level_x(kLevels, 0.0), level_y(kLevels, 0.0);
    std::vector<int> level_of(nv, -1);
    for (std::size_t v = 0; v < nv; ++v) {
      const double ro = so * vertex_ro[v], ri = si * vertex_ri[v];
      const double u = (vertex_theta[v] - ro) / (kPi - ri - ro);
      if (!(u >= 0.0 && u <= 1.0)) continue;
      const int b = std::min(kLevels - 1, static_cast<int>(u * kLevels));
      level_of[v] = b;
      level_centre[static_cast<std::size_t>(b)] += vertex_area[v] * muscle.positions[v];
      level_area[static_cast<std::size_t>(b)] += vertex_area[v];
    }
    for (int b = 0; b < kLevels; ++b)
      if (level_area[static_cast<std::size_t>(b)] > 0.0)
        level_centre[static_cast<std::size_t>(b)] /= level_area[static_cast<std::size_t>(b)];
    for (std::size_t v = 0; v < nv; ++v) {
      if (level_of[v] < 0) continue;
      const auto b = static_cast<std::size_t>(level_of[v]);
      const double w = (muscle.positions[v] - level_centre[b]).dot(second) * vertex_area[v];
      level_x[b] += w * vertex_cos[v];
      level_y[b] += w * vertex_sin[v];
    }
    // The muscle's band measure: surface area, or area per level circumference (length along
    // the muscle: rings then sit at even steps along it, which keeps the lattice's layers flat
    // where a muscle narrows to a tendon).
    std::vector<double> level_radius(kLevels, 0.0);
    for (std::size_t v = 0; v < nv; ++v)
      if (level_of[v] >= 0)
        level_radius[static_cast<std::size_t>(level_of[v])] +=
            vertex_area[v] * (muscle.positions[v] - level_centre[static_cast<std::size_t>(level_of[v])]).norm();
    for (int b = 0; b < kLevels; ++b)
      if (level_area[static_cast<std::size_t>(b)] > 0.0)
        level_radius[static_cast<std::size_t>(b)] /= level_area[static_cast<std::size_t>(b)];
    for (std::size_t f = 0; f < n_faces; ++f) {
      const double ro = so * face_ro[f], ri = si * face_ri[f];
      const double u = (face_theta[f] - ro) / (kPi - ri - ro);
      double a = face_area[f];
      if (options.band_by_length && u >= 0.0 && u <= 1.0) {
        const double r = level_radius[static_cast<std::size_t>(std::min(kLevels - 1, static_cast<int>(u * kLevels)))];
        a = r > 0.0 ? a / r : 0.0;
      }
      muscle_band.add(u, a);
    }
    muscle_band.finish();

    // Rings closer where the muscle turns: a fibre of straight segments between rings cuts the
    // inner side of a bend and turns at its joints by the turn between two rings. The centre line
    // (the level centres, which jitter by a good part of a level's step because a level of the
    // sphere map is not a plane cross-section, smoothed by a Gaussian of two levels) may turn by
    // at most bend_step between two rings: each level gets at least the measure its turn needs at
    // that rate, M turn / ((nz - 1) bend_step), M the band's measure after the additions (a fixed
    // point; relaxed where the muscle turns more than nz - 1 steps allow). Only the rings between
    // the first and the last lateral ring move: those two stay, so the faces' depth rule and the
    // casts of the ends see the rings they see without it.
    std::optional<Cumulative> bend_band;
    if (options.band_by_length && options.bend_step_deg > 0.0) {
      std::vector<int> filled;
      for (int b = 0; b < kLevels; ++b)
        if (level_area[static_cast<std::size_t>(b)] > 0.0) filled.push_back(b);
      constexpr double kSigma = 2.0;
      std::vector<Vec3> line(filled.size(), Vec3::Zero());
      for (std::size_t j = 0; j < filled.size(); ++j) {
        double weight = 0.0;
        for (std::size_t i = 0; i < filled.size(); ++i) {
          const double d = (filled[i] - filled[j]) / kSigma;
          const double w = std::exp(-0.5 * d * d);
          line[j] += w * level_centre[static_cast<std::size_t>(filled[i])];
          weight += w;
        }
        line[j] /= weight;
      }
      std::vector<double> turn(kLevels, 0.0);
      for (std::size_t j = 1; j + 1 < filled.size(); ++j) {
        const Vec3 a = line[j] - line[j - 1], c = line[j + 1] - line[j];
        if (a.norm() > 0.0 && c.norm() > 0.0)
          turn[static_cast<std::size_t>(filled[j])] = std::atan2(a.cross(c).norm(), a.dot(c));
      }
      // A level's measure: its kBandBins / kLevels bins of the band (both counts powers of two,
      // so a level's bins are exactly the faces whose u falls in it).
      constexpr int kPerLevel = kBandBins / kLevels;
      std::vector<double> level_mass(kLevels);
      for (int b = 0; b < kLevels; ++b)
        level_mass[static_cast<std::size_t>(b)] = muscle_band.mass(b * kPerLevel, (b + 1) * kPerLevel);
      const double all_turn = std::accumulate(turn.begin(), turn.end(), 0.0);
      const double steps = static_cast<double>(std::max(1, lattice.nz - 1));
      const double rate =
          std::min(1.0 / (steps * options.bend_step_deg * kPi / 180.0), 0.9 / std::max(all_turn, 1e-12));
      double total = std::accumulate(level_mass.begin(), level_mass.end(), 0.0);
      const double length_mass = total;
      for (int round = 0; round < 100; ++round) {
        double next = 0.0;
        for (int b = 0; b < kLevels; ++b)
          next += std::max(level_mass[static_cast<std::size_t>(b)], rate * turn[static_cast<std::size_t>(b)] * total);
        const bool settled = next - total <= 1e-9 * next;
        total = next;
        if (settled) break;
      }
      bend_band.emplace(muscle_band);
      for (int b = 0; b < kLevels; ++b) {
        const double extra = rate * turn[static_cast<std::size_t>(b)] * total - level_mass[static_cast<std::size_t>(b)];
        if (!(extra > 0.0)) continue;
        for (int j = 0; j < kPerLevel; ++j) bend_band->add((b * kPerLevel + j + 0.5) / kBandBins, extra / kPerLevel);
      }
      bend_band->finish();
      out.report.centre_turn_deg = all_turn * 180.0 / kPi;
      out.report.bend_share = total > 0.0 ? (total - length_mass) / total : 0.0;
    }

    // Rings by meridian length: along each meridian (muscle azimuth phi in the pole frame, u from
    // the origin region to the insertion region) the lateral rings go to even shares of the
    // meridian's length on the muscle (through the area-weighted face centres of meridian_steps
    // levels, over a window of three of kMeridians azimuth sectors), instead of one share per
    // level for all azimuths. Where the sphere map's levels run obliquely along a thin tendon (a
    // narrow level can span much of it), a ring at one level for all azimuths skips most of the
    // tendon: one very long layer followed by a very short one.
    // Levels along each meridian: at most 48, fewer on a coarse mesh (about 6 faces a sector
    // and level, 18 in its window), at least 12.
    const int meridian_steps = std::clamp(static_cast<int>(n_faces / (6 * kMeridians)), 12, 48);
    std::vector<std::vector<double>> meridian_u, meridian_share;
    if (!triangle_centre.empty()) {
      struct Cell {
        Vec3 sum = Vec3::Zero();
        double area = 0.0, u = 0.0;
      };
      std::vector<Cell> cells(static_cast<std::size_t>(kMeridians * meridian_steps));
      for (std::size_t f = 0; f < n_faces; ++f) {
        const double ro = so * face_ro[f], ri = si * face_ri[f];
        const double u = (face_theta[f] - ro) / (kPi - ri - ro);
        if (!(u >= 0.0 && u <= 1.0)) continue;
        const int m = triangle_sector[f];
        const int j = std::min(meridian_steps - 1, static_cast<int>(u * meridian_steps));
        for (int dm = -1; dm <= 1; ++dm) {
          Cell& cell = cells[static_cast<std::size_t>(((m + dm + kMeridians) % kMeridians) * meridian_steps + j)];
          cell.sum += face_area[f] * triangle_centre[f];
          cell.area += face_area[f];
          cell.u += face_area[f] * u;
        }
      }
      meridian_u.resize(kMeridians);
      meridian_share.resize(kMeridians);
      for (int m = 0; m < kMeridians; ++m) {
        std::vector<double> us;
        std::vector<Vec3> centres;
        for (int j = 0; j < meridian_steps; ++j) {
          const Cell& cell = cells[static_cast<std::size_t>(m * meridian_steps + j)];
          if (cell.area <= 0.0) continue;
          us.push_back(cell.u / cell.area);
          centres.push_back(cell.sum / cell.area);
        }
        if (us.size() < 2) {
          meridian_u.clear();
          meridian_share.clear();
          break;
        }
        // Two passes of a (1, 2, 1) filter along the meridian (ends kept): the centres of a few
        // faces each zigzag, which would add length where a meridian's cells are sparse.
        for (int pass = 0; pass < 2 && centres.size() > 2; ++pass) {
          std::vector<Vec3> smoothed = centres;
          for (std::size_t i = 1; i + 1 < centres.size(); ++i)
            smoothed[i] = 0.25 * (centres[i - 1] + 2.0 * centres[i] + centres[i + 1]);
          centres.swap(smoothed);
        }
        // Length from u = 0 to the first centre and from the last to u = 1: the neighbouring
        // piece's length per unit of u.
        std::vector<double> nodes_u{0.0}, arc{0.0};
        const double first = (centres[1] - centres[0]).norm() / std::max(us[1] - us[0], 1e-12);
        nodes_u.push_back(us[0]);
        arc.push_back(first * us[0]);
        for (std::size_t i = 1; i < us.size(); ++i) {
          nodes_u.push_back(us[i]);
          arc.push_back(arc.back() + (centres[i] - centres[i - 1]).norm());
        }
        const std::size_t n = us.size();
        const double last = (centres[n - 1] - centres[n - 2]).norm() / std::max(us[n - 1] - us[n - 2], 1e-12);
        nodes_u.push_back(1.0);
        arc.push_back(arc.back() + last * (1.0 - us[n - 1]));
        // Strictly increasing (a small floor per node, as Cumulative does over empty bins).
        const double floor = arc.back() * 1e-4 / static_cast<double>(arc.size());
        for (std::size_t i = 1; i < arc.size(); ++i) arc[i] += floor * static_cast<double>(i);
        for (double& l : arc) l /= arc.back();
        meridian_u[static_cast<std::size_t>(m)] = std::move(nodes_u);
        meridian_share[static_cast<std::size_t>(m)] = std::move(arc);
      }
    }
    // Band level u (in [0, 1]) of the lateral ring at share `share` of the length at muscle
    // azimuth phi (blend of the two neighbouring meridians: monotone in the share).
    const auto meridian_level = [&](double phi, double share) {
      const auto inverse = [&](int m, double v) {
        const auto& sh = meridian_share[static_cast<std::size_t>(m)];
        const auto& us = meridian_u[static_cast<std::size_t>(m)];
        const auto it = std::upper_bound(sh.begin(), sh.end(), v);
        std::size_t i = it == sh.begin() ? 0 : static_cast<std::size_t>(it - sh.begin()) - 1;
        i = std::min(i, sh.size() - 2);
        const double w = sh[i + 1] - sh[i];
        const double f = w > 0.0 ? std::clamp((v - sh[i]) / w, 0.0, 1.0) : 0.0;
        return us[i] + f * (us[i + 1] - us[i]);
      };
      const double x = phi / (2.0 * kPi);
      const double y = (x - std::floor(x)) * kMeridians - 0.5;
      const double yf = std::floor(y);
      const int m0 = (static_cast<int>(yf) + kMeridians) % kMeridians, m1 = (m0 + 1) % kMeridians;
      const double f = y - yf;
      return (1.0 - f) * inverse(m0, share) + f * inverse(m1, share);
    };

    std::vector<double> level_twist(kLevels, twist);
    double previous = twist;
    for (int b = 0; b < kLevels; ++b) {
      const auto i = static_cast<std::size_t>(b);
      double t = previous;
      if (std::hypot(level_x[i], level_y[i]) > 0.0) {
        t = std::atan2(level_y[i], level_x[i]);
        t = previous + std::remainder(t - previous, 2.0 * kPi);
      }
      level_twist[i] = previous = t;
    }
    for (int pass = 0; pass < 2; ++pass) {
      std::vector<double> smoothed(kLevels);
      for (int b = 0; b < kLevels; ++b) {
        double sum = 0.0;
        int count = 0;
        for (int d = -2; d <= 2; ++d) {
          const int c = b + d;
          if (c < 0 || c >= kLevels) continue;
          sum += level_twist[static_cast<std::size_t>(c)];
          ++count;
        }
        smoothed[static_cast<std::size_t>(b)] = sum / count;
      }
      level_twist.swap(smoothed);
    }
    const double corner_twist = options.corner_twist_deg * kPi / 180.0;
    const auto twist_at = [&](double u) {
      const double x = std::clamp(u * kLevels - 0.5, 0.0, static_cast<double>(kLevels - 1));
      const auto b = std::min(static_cast<std::size_t>(x), static_cast<std::size_t>(kLevels - 2));
      const double f = x - static_cast<double>(b);
      return corner_twist + (1.0 - f) * level_twist[b] + f * level_twist[b + 1];
    };
    report.twist_deg = twist_at(0.0) * 180.0 / kPi;
    report.twist_end_deg = twist_at(1.0) * 180.0 / kPi;

    // Even perimeter: around each cross-section the template's surface points go to the muscle's
    // azimuths at the same share of the perimeter (surface area by azimuth, in kRingLevels
    // levels along the band), counted from a corner of the template's square cross-section
    // (azimuth -135 degrees from its r axis, turned by the twist; on the template, the share of
    // the square's perimeter where the ray from its centre at that azimuth meets it, which
    // spaces its surface points evenly, the lattice being regular). Azimuth alone crowds the
    // lattice's corners (where the square's sides subtend the least angle) into the thin edges of
    // a flat muscle, which the sphere map compresses: the corner cells fold. The map of each
    // level is monotone and fixes the corner, so is every blend of two levels: the
    // correspondence stays a homeomorphism.
    constexpr int kRingLevels = 8, kRingBins = 48;
    const double ring_start = -0.75 * kPi;
    const auto ring_share = [&](double phi, double turn) {
      const double x = (phi - turn - ring_start) / (2.0 * kPi);
      return x - std::floor(x);
    };
    std::vector<Cumulative> muscle_ring(kRingLevels, Cumulative(kRingBins));
    if (options.even_perimeter) {
      // Muscle area by level and azimuth bin, smoothed over neighbouring bins and levels (a
      // level of a coarse mesh has few triangles).
      std::vector<std::vector<double>> mass(kRingLevels, std::vector<double>(kRingBins, 0.0));
      for (std::size_t f = 0; f < n_faces; ++f) {
        const double phi = face_phi[f];
        const double ro = so * face_ro[f], ri = si * face_ri[f];
        const double u = (face_theta[f] - ro) / (kPi - ri - ro);
        if (!(u >= 0.0 && u <= 1.0)) continue;
        const int level = std::min(kRingLevels - 1, static_cast<int>(u * kRingLevels));
        const int b = std::min(kRingBins - 1, static_cast<int>(ring_share(phi, twist_at(u)) * kRingBins));
        mass[static_cast<std::size_t>(level)][static_cast<std::size_t>(b)] += face_area[f];
      }
      for (int level = 0; level < kRingLevels; ++level) {
        for (int b = 0; b < kRingBins; ++b) {
          double m = 0.0;
          for (int dl = -1; dl <= 1; ++dl) {
            const int l = level + dl;
            if (l < 0 || l >= kRingLevels) continue;
            const auto& row = mass[static_cast<std::size_t>(l)];
            const double w = dl == 0 ? 1.0 : 0.5;
            m += w *
                 (0.25 * row[static_cast<std::size_t>((b + kRingBins - 1) % kRingBins)] +
                  0.5 * row[static_cast<std::size_t>(b)] + 0.25 * row[static_cast<std::size_t>((b + 1) % kRingBins)]);
          }
          muscle_ring[static_cast<std::size_t>(level)].add((b + 0.5) / kRingBins, m);
        }
        muscle_ring[static_cast<std::size_t>(level)].finish();
      }
    }
    // Muscle azimuth of the template azimuth phi_t at band level u.
    const auto muscle_azimuth = [&](double phi_t, double u) {
      const double turn = twist_at(u);
      if (!options.even_perimeter) return phi_t + turn;
      const double share = square_perimeter_share(phi_t);
      const double y = std::clamp(u * kRingLevels - 0.5, 0.0, static_cast<double>(kRingLevels - 1));
      const auto l = std::min(static_cast<std::size_t>(y), static_cast<std::size_t>(kRingLevels - 2));
      const double f = y - static_cast<double>(l);
      const double x = (1.0 - f) * muscle_ring[l].inverse(share) + f * muscle_ring[l + 1].inverse(share);
      return turn + ring_start + 2.0 * kPi * x;
    };

    // Every surface point of the lattice: template sphere -> muscle pole frame -> muscle sphere.
    const int n = lattice.point_count();
    surface_points.clear();
    for (int q = 0; q < n; ++q)
      if (lattice.system.fixed[static_cast<std::size_t>(q)]) surface_points.push_back(q);
    // Template band level in [0, 1] of a lateral point with template pole vector tq: its polar
    // angle between the two faces' edges at its azimuth.
    const auto template_azimuth = [](const Vec3& tq) {
      return (std::abs(tq.x()) + std::abs(tq.y()) == 0.0) ? 0.0 : azimuth(tq);
    };
    const auto lateral_level = [&](const Vec3& tq) {
      const double edge = face_edge(template_azimuth(tq));
      return std::clamp((polar_angle(tq) - edge) / (kPi - 2.0 * edge), 0.0, 1.0);
    };
    // Band level of a lateral point at template share `share`: with bend_band, the shares between
    // the first and the last lateral ring (s_first, s_last) go through it, the rest unchanged.
    double s_first = 1.0, s_last = 0.0;
    if (bend_band && lattice.nz >= 4) {
      s_first = 0.0;
      s_last = 1.0;
      for (int q : surface_points) {
        const int k = q / (lattice.nx * lattice.ny);
        if (k != 1 && k != lattice.nz - 2) continue;
        const double sh = template_band.share(lateral_level(template_pole_vector(springs::lattice_coordinates(lattice, q))));
        if (k == 1) s_first = std::max(s_first, sh);
        else s_last = std::min(s_last, sh);
      }
    }
    const bool bend = bend_band && s_first < s_last;
    const double c_first = bend ? bend_band->share(muscle_band.inverse(s_first)) : 0.0;
    const double c_last = bend ? bend_band->share(muscle_band.inverse(s_last)) : 1.0;
    const auto band_level = [&](double share) {
      if (!bend || share <= s_first || share >= s_last) return muscle_band.inverse(share);
      return bend_band->inverse(c_first + (share - s_first) / (s_last - s_first) * (c_last - c_first));
    };
    std::vector<Vec3> directions(surface_points.size());
    for_each_index(surface_points.size(), [&](std::size_t i) {
      const int q = surface_points[i];
      const Vec3 c = springs::lattice_coordinates(lattice, q);
      const Vec3 tq = template_pole_vector(c);
      const double theta_t = polar_angle(tq);
      const double phi_t = template_azimuth(tq);
      const double edge = face_edge(phi_t);
      const int k = q / (lattice.nx * lattice.ny);
      double theta, phi;
      if (k == 0) {
        phi = muscle_azimuth(phi_t, 0.0);
        const double rho = std::min(1.0, std::tan(theta_t) / std::tan(edge));
        theta = rho * so * origin_radius(phi);
      } else if (k == lattice.nz - 1) {
        phi = muscle_azimuth(phi_t, 1.0);
        const double rho = std::min(1.0, std::tan(kPi - theta_t) / std::tan(edge));
        theta = kPi - rho * si * insertion_radius(phi);
      } else {
        const double share = template_band.share(lateral_level(tq));
        // Meridian rings keep the levels by length for their azimuths, as their own spacing.
        double um = meridian_u.empty() ? band_level(share) : muscle_band.inverse(share);
        phi = muscle_azimuth(phi_t, um);
        if (!meridian_u.empty()) um = meridian_level(phi, share);
        const double ro = so * origin_radius(phi), ri = si * insertion_radius(phi);
        theta = ro + um * (kPi - ri - ro);
      }
      directions[i] = frame.from_pole(from_polar(theta, phi));
    });
    const std::vector<SurfacePoint> located = locator.locate_all(directions);
    out.points.assign(static_cast<std::size_t>(n), SurfacePoint{});
    for (std::size_t i = 0; i < surface_points.size(); ++i) {
      SurfacePoint sp = located[i];
      sp.position = point_on_mesh(muscle, sp);
      sp.distance = 0.0;
      out.points[static_cast<std::size_t>(surface_points[i])] = sp;
    }
  };

  // An attachment face must not be deeper (along the muscle, from its first fibre points to its
  // rim) than max_face_depth of the way to the first lateral ring: a face that wraps round a
  // rounded end folds the first layer of cells. Shrink the face towards its centre until it fits.
  const int plane = lattice.nx * lattice.ny;
  auto face_depth_ratio = [&](int k_face, int k_ring) {
    Vec3 face_centre = Vec3::Zero(), ring_centre = Vec3::Zero();
    int nf = 0, nr = 0;
    for (int q : surface_points) {
      const int k = q / plane;
      if (k == k_face) face_centre += out.points[static_cast<std::size_t>(q)].position, ++nf;
      if (k == k_ring) ring_centre += out.points[static_cast<std::size_t>(q)].position, ++nr;
    }
    if (nf == 0 || nr == 0) return 0.0;
    face_centre /= nf;
    ring_centre /= nr;
    const Vec3 axis = (ring_centre - face_centre).normalized();
    double lo = 1e300, hi = -1e300, ring = 0.0;
    for (int q : surface_points) {
      const int k = q / plane;
      const double d = (out.points[static_cast<std::size_t>(q)].position - face_centre).dot(axis);
      if (k == k_face) lo = std::min(lo, d), hi = std::max(hi, d);
      if (k == k_ring) ring += d / nr;
    }
    const double gap = ring - lo;
    return gap > 0.0 ? (hi - lo) / gap : 1e300;
  };
  double so = 1.0, si = 1.0;
  place(so, si);
  for (int round = 0; round < options.face_shrink_rounds && lattice.nz > 2; ++round) {
    // A face's depth grows about with the square of its radius on a rounded end: aim at 0.6 of
    // the allowed depth from the measured ratio, shrinking by at least 0.8 and at most 0.3 a round.
    const double origin_ratio = face_depth_ratio(0, 1);
    const double insertion_ratio = face_depth_ratio(lattice.nz - 1, lattice.nz - 2);
    const auto factor = [&](double ratio) {
      return std::clamp(std::sqrt(0.6 * options.max_face_depth / ratio), 0.3, 0.8);
    };
    const bool origin_deep = origin_ratio > options.max_face_depth;
    const bool insertion_deep = insertion_ratio > options.max_face_depth;
    if (!origin_deep && !insertion_deep) break;
    if (origin_deep) so *= factor(origin_ratio);
    if (insertion_deep) si *= factor(insertion_ratio);
    place(so, si);
  }
  report.origin_face_scale = so;
  report.insertion_face_scale = si;
  report.located = static_cast<long>(surface_points.size());
  report.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return out;
}

}  // namespace fascicle
