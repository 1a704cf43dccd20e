#include "fibres/decompose.h"

#include "fibres/azimuth_cast.h"
#include "fibres/fibre_grid.h"
#include "fibres/strip_cast.h"
#include "geometry/cross_section.h"
#include "geometry/errors.h"
#include "geometry/mesh_stats.h"
#include "morph/sphere_locator.h"
#include "morph/surface_query.h"
#include "repair/simplify_mesh.h"
#include "springs/compute_backend.h"

#include <Eigen/SVD>
#include <tbb/parallel_invoke.h>
#include <algorithm>
#include <array>
#include <chrono>
#include <memory>
#include <optional>
#include <unordered_map>
#include <tuple>
#include <cmath>


namespace fascicle {

namespace {

using Clock = std::chrono::steady_clock;
double since(Clock::time_point start) { return std::chrono::duration<double>(Clock::now() - start).count(); }

nlohmann::json settle_json(const springs::SettleReport& r) {
  return {{"solver", r.solver},       {"backend", r.backend},   {"iterations", r.iterations},
          {"converged", r.converged}, {"residual", r.residual}, {"setup_seconds", r.setup_seconds},
          {"seconds", r.seconds}};
}

// Rest lengths from the template, stretched by the symmetric part of the linear map that best
// fits the template's spring vectors onto those of `fitted` (least squares).
void stretch_rest_lengths(springs::SpringSystem& system, const std::vector<Vec3>& template_positions,
                          const std::vector<Vec3>& fitted, bool tension, nlohmann::json& report) {
  Eigen::Matrix3d cross = Eigen::Matrix3d::Zero(), gram = Eigen::Matrix3d::Zero();
  for (const springs::Spring& s : system.springs) {
    const Vec3 t =
        template_positions[static_cast<std::size_t>(s.b)] - template_positions[static_cast<std::size_t>(s.a)];
    const Vec3 h = fitted[static_cast<std::size_t>(s.b)] - fitted[static_cast<std::size_t>(s.a)];
    cross += h * t.transpose();
    gram += t * t.transpose();
  }
  const Eigen::Matrix3d linear = cross * gram.inverse();
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(linear, Eigen::ComputeFullU | Eigen::ComputeFullV);
  const Eigen::Matrix3d stretch = svd.matrixV() * svd.singularValues().asDiagonal() * svd.matrixV().transpose();
  double shortest = 1e300;
  for (springs::Spring& s : system.springs) {
    const Vec3 t =
        template_positions[static_cast<std::size_t>(s.b)] - template_positions[static_cast<std::size_t>(s.a)];
    s.rest = (stretch * t).norm();
    shortest = std::min(shortest, s.rest);
    if (!(s.rest > 0.0)) throw SolverError("decompose: the template stretch gives a spring of rest length 0");
    s.stiffness = 1.0 / s.rest;
  }
  double scale = 1.0;
  if (tension) {
    // Every spring starts stretched: rest <= 0.9 of its length in the fitted configuration.
    for (const springs::Spring& s : system.springs) {
      const double l = (fitted[static_cast<std::size_t>(s.b)] - fitted[static_cast<std::size_t>(s.a)]).norm();
      scale = std::min(scale, 0.9 * l / s.rest);
    }
    if (!(scale > 0.0)) throw SolverError("decompose: a spring has length 0 in the harmonic map; use --rest zero");
    for (springs::Spring& s : system.springs) {
      s.rest *= scale;
      s.stiffness = 1.0 / s.rest;
    }
    shortest *= scale;
  }
  report["tension_scale"] = scale;
  const Vec3 sv = svd.singularValues();
  report["stretch"] = {sv.x(), sv.y(), sv.z()};
  report["shortest_rest"] = shortest;
}

// Whether the inner points of layer k, seen along `axis`, form an unfolded grid: every quad
// (diagonals crossed) turns the same way as the whole layer.
bool layer_unfolded(const springs::SpringSystem& system, const springs::Lattice& lattice, int k, const Vec3& axis) {
  auto at = [&](int i, int j) { return system.positions[static_cast<std::size_t>(lattice.index(i, j, k))]; };
  std::vector<double> areas;
  double total = 0.0;
  for (int j = 1; j + 2 < lattice.ny; ++j)
    for (int i = 1; i + 2 < lattice.nx; ++i) {
      const double a = (at(i + 1, j + 1) - at(i, j)).cross(at(i, j + 1) - at(i + 1, j)).dot(axis);
      areas.push_back(a);
      total += a;
    }
  for (double a : areas)
    if (!(a * total > 0.0)) return false;
  return true;
}

// Affine fit c + A (g - g_mean) of the inner points of layer k over the index grid g = (i, j):
// A (3 x 2; its columns are the layer's r and s directions), c the layer's centroid.
struct LayerFit {
  Vec3 centre = Vec3::Zero();
  Eigen::Matrix<double, 3, 2> map = Eigen::Matrix<double, 3, 2>::Zero();
  Vec3 normal() const { return map.col(0).cross(map.col(1)); }
};
// Position of line (i, j) in the (r, s) grid, in inner spacings (the index when the edge cells
// are as wide as the others).
Eigen::Vector2d grid_position(const springs::Lattice& lattice, int i, int j) {
  return {springs::lattice_line_position(i, lattice.nx, lattice.edge_cell),
          springs::lattice_line_position(j, lattice.ny, lattice.edge_cell)};
}

LayerFit layer_fit(const springs::SpringSystem& system, const springs::Lattice& lattice, int k) {
  auto at = [&](int i, int j) { return system.positions[static_cast<std::size_t>(lattice.index(i, j, k))]; };
  LayerFit fit;
  int count = 0;
  for (int j = 1; j + 1 < lattice.ny; ++j)
    for (int i = 1; i + 1 < lattice.nx; ++i) fit.centre += at(i, j), ++count;
  fit.centre /= std::max(count, 1);
  const Eigen::Vector2d g_mean = 0.5 * grid_position(lattice, lattice.nx - 1, lattice.ny - 1);
  Eigen::Matrix<double, 3, 2> cross = Eigen::Matrix<double, 3, 2>::Zero();
  Eigen::Matrix2d gram = Eigen::Matrix2d::Zero();
  for (int j = 1; j + 1 < lattice.ny; ++j)
    for (int i = 1; i + 1 < lattice.nx; ++i) {
      const Eigen::Vector2d g = grid_position(lattice, i, j) - g_mean;
      cross += (at(i, j) - fit.centre) * g.transpose();
      gram += g * g.transpose();
    }
  if (gram.determinant() > 0.0) fit.map = cross * gram.inverse();
  return fit;
}

}  // namespace

int lattice_handedness(const springs::SpringSystem& system, const springs::Lattice& lattice) {
  if (lattice.nz < 3) return 0;
  std::vector<LayerFit> fits;
  for (int k = 0; k < lattice.nz; ++k) fits.push_back(layer_fit(system, lattice, k));
  double total = 0.0;
  for (int k = 1; k + 1 < lattice.nz; ++k)
    total += fits[static_cast<std::size_t>(k)].normal().dot(fits[static_cast<std::size_t>(k + 1)].centre -
                                                            fits[static_cast<std::size_t>(k - 1)].centre);
  return total > 0.0 ? 1 : total < 0.0 ? -1 : 0;
}

namespace {

// The fibre ends of each attachment face, rebuilt under the layer of points next to it: that
// layer (its inner points) is shrunk towards its centroid by a factor lambda and cast onto the
// surface along the end axis (from the second layer's centroid through the first's). Seen along
// the axis the face is then a scaled copy of the layer above it, so the end layer of cells are
// frustums of that layer's cells and do not fold, whatever the sphere map did near the region
// centre. Where that layer is itself folded seen along the axis (a narrow, bent tendon end), a
// copy would carry the fold into the fibre ends, which the untangling must keep near their cast
// places and so could never open: the face is then cast from the layer's best affine fit over the
// template's index grid instead (a regular grid of parallelograms, unfolded by construction).
// A face must also turn the lattice's way (lattice_handedness()): a layer, or fit, that is
// mirrored seen along the cast axis (a layer turned over as a whole next to a narrow end) would
// give a mirrored face and turn every cell of the end layer over, which no untangling with the
// ends held can open; the fit of the nearest layer further in that turns the right way is cast
// instead.
// The face's rim (its surface-ring points) is cast with the ends, from the same layer or fit one
// index step beyond them (cast_rim): the placement's depth rule can shrink a face to a few percent
// of its region, and a rim left there lies inside the cast ends, so that the cells between fold.
// lambda starts at 1 and shrinks by 0.8 until every end lies within `radius` of an attachment-area
// point (at most 20 times). When no lambda fits along the end axis (an end that bends away from
// it), the axis from the layer's centroid to the area's centre is tried, then the axis to the
// area point nearest to that centroid; the ends stay where they were when none fits.
// With `strip` (landmark areas joined into strips) the factor is split into one along the strip
// and one across it (fibres/strip_cast.h).
nlohmann::json cast_faces(springs::SpringSystem& system, const springs::Lattice& lattice, const TriangleMesh& muscle,
                          const Attachments& areas, double radius, const SurfaceQuery& query, bool cast_rim,
                          bool strip, bool by_azimuth) {
  nlohmann::json out = nlohmann::json::array();
  const double reach = 4.0 * (bounding_box(muscle.positions).diagonal() + 1e-300);
  const int hand = lattice_handedness(system, lattice);
  for (const auto& [k_end, k1, k2, area] : {std::tuple<int, int, int, const AttachmentArea*>{0, 1, 2, &areas.origin},
                                            std::tuple<int, int, int, const AttachmentArea*>{
                                                lattice.nz - 1, lattice.nz - 2, lattice.nz - 3, &areas.insertion}}) {
    if (k2 < 0 || k2 >= lattice.nz || k1 == k_end) continue;
    auto at = [&](int i, int j, int k) -> Vec3& {
      return system.positions[static_cast<std::size_t>(lattice.index(i, j, k))];
    };
    Vec3 c1 = Vec3::Zero(), c2 = Vec3::Zero();
    int count = 0;
    for (int j = 1; j + 1 < lattice.ny; ++j)
      for (int i = 1; i + 1 < lattice.nx; ++i) c1 += at(i, j, k1), c2 += at(i, j, k2), ++count;
    c1 /= count;
    c2 /= count;
    const Vec3 layer_axis = (c1 - c2).normalized();
    if (!layer_axis.allFinite()) continue;
    // Offsets of the cast's starting points from c1 at lambda = 1: the layer's own, or its
    // affine fit c1 + A (g - g_mean) over the index grid g = (i, j) when the layer is folded.
    std::vector<Vec3> offsets;
    for (int j = 1; j + 1 < lattice.ny; ++j)
      for (int i = 1; i + 1 < lattice.nx; ++i) offsets.push_back(at(i, j, k1) - c1);
    // The face's rim (its surface-ring points), in the same order: the rim of layer k1, or the
    // fit extrapolated to the rim's index.
    std::vector<std::array<int, 2>> rim;
    for (int j = 0; j < lattice.ny; ++j)
      for (int i = 0; i < lattice.nx; ++i)
        if (i == 0 || j == 0 || i + 1 == lattice.nx || j + 1 == lattice.ny) rim.push_back({i, j});
    std::vector<Vec3> rim_offsets;
    for (const auto& [i, j] : rim) rim_offsets.push_back(at(i, j, k1) - c1);
    // Direction of growing k at this face: a face turns the lattice's way when its (r, s)
    // normal points along it times the handedness.
    const Vec3 k_direction = k_end == 0 ? Vec3(-layer_axis) : layer_axis;
    const auto turns_right = [&](const Eigen::Matrix<double, 3, 2>& map) {
      const Vec3 normal = map.col(0).cross(map.col(1));
      return hand == 0 || normal.dot(k_direction) * hand > 1e-6 * map.squaredNorm();
    };
    const LayerFit own = layer_fit(system, lattice, k1);
    const bool folded = !layer_unfolded(system, lattice, k1, layer_axis) || !turns_right(own.map);
    int fit_layer = -1;
    if (folded) {
      const int step = k_end == 0 ? 1 : -1;
      for (int k = k1; k > 0 && k + 1 < lattice.nz && fit_layer < 0; k += step) {
        const LayerFit fit = k == k1 ? own : layer_fit(system, lattice, k);
        // A degenerate fit (the layer collapsed onto a line) is no better than the layer.
        if (!(fit.normal().norm() > 1e-6 * fit.map.squaredNorm()) || !turns_right(fit.map)) continue;
        fit_layer = k;
        const Eigen::Vector2d g_mean = 0.5 * grid_position(lattice, lattice.nx - 1, lattice.ny - 1);
        std::size_t n = 0;
        for (int j = 1; j + 1 < lattice.ny; ++j)
          for (int i = 1; i + 1 < lattice.nx; ++i) offsets[n++] = fit.map * (grid_position(lattice, i, j) - g_mean);
        for (std::size_t r = 0; r < rim.size(); ++r)
          rim_offsets[r] = fit.map * (grid_position(lattice, rim[r][0], rim[r][1]) - g_mean);
      }
    }
    const Vec3 area_centre = area->centroid();
    std::vector<Vec3> axes{layer_axis};
    const Vec3 to_area = (area_centre - c1).normalized();
    if (!area->points.empty() && to_area.allFinite()) axes.push_back(to_area);
    // The centroid of a broad or curved area (a strip of landmarks along a bone crest) can lie
    // off the muscle, so that neither ray meets the area: last, the axis towards the area point
    // nearest to the layer's centroid, whose ray from the centroid ends on that point when the
    // segment between them stays inside the muscle.
    if (!area->points.empty()) {
      const SurfacePoint* nearest = &area->points.front();
      for (const SurfacePoint& p : area->points)
        if ((p.position - c1).squaredNorm() < (nearest->position - c1).squaredNorm()) nearest = &p;
      const Vec3 to_nearest = (nearest->position - c1).normalized();
      if (to_nearest.allFinite()) axes.push_back(to_nearest);
    }
    double lambda = 1.0;
    bool placed = false;
    std::vector<Vec3> ends;
    std::size_t used_axis = 0;
    nlohmann::json strip_factors;
    const auto hit = [&](const Vec3& start, const Vec3& axis, Vec3& end) {
      return query.first_hit(start, axis, reach, end);
    };
    const auto near = [&](const Vec3& end) { return area->near(end, radius); };
    if (strip) {
      std::vector<Vec3> area_points;
      for (const SurfacePoint& p : area->points) area_points.push_back(p.position);
      for (std::size_t a = 0; a < axes.size() && !placed; ++a) {
        const StripCast cast = cast_strip_face(c1, offsets, axes[a], area_points, hit, near);
        placed = cast.placed;
        used_axis = a;
        if (placed) {
          ends = cast.ends;
          // Reported as one shrink, the geometric mean of the two (the code below divides the
          // single-factor search's last factor tried by 0.8, hence the 0.8 here).
          lambda = std::sqrt(cast.lambda_long * cast.lambda_cross) * 0.8;
          strip_factors = {cast.lambda_long, cast.lambda_cross};
        }
      }
    }
    // Every end cast from the layer scaled by factor about c1 along axis, or false when one
    // misses the surface or lands off the area.
    const auto cast_all = [&](double factor, const Vec3& axis, std::vector<Vec3>& hits) {
      hits.clear();
      for (const Vec3& offset : offsets) {
        Vec3 end;
        if (!hit(c1 + factor * offset, axis, end) || !near(end)) return false;
        hits.push_back(end);
      }
      return true;
    };
    std::optional<AzimuthCast> azimuth;
    for (std::size_t a = 0; a < axes.size() && !placed && !strip && by_azimuth; ++a) {
      azimuth = cast_azimuth_face(c1, offsets, axes[a], hit, near, [&](const Vec3& p) { return query.inside(p); });
      placed = azimuth->placed;
      used_axis = a;
      if (placed) {
        ends = azimuth->ends;
        lambda = azimuth->smallest() * 0.8;  // divided by 0.8 below, as the single factor's last step
      }
    }
    for (std::size_t a = 0; a < axes.size() && !placed && !strip && !by_azimuth; ++a) {
      lambda = 1.0;
      for (int attempt = 0; attempt < 20 && !placed; ++attempt, lambda *= 0.8) placed = cast_all(lambda, axes[a], ends);
      used_axis = a;
    }
    bool rim_cast = false;
    if (placed) {
      lambda /= 0.8;
      std::size_t n = 0;
      for (int j = 1; j + 1 < lattice.ny; ++j)
        for (int i = 1; i + 1 < lattice.nx; ++i) at(i, j, k_end) = ends[n++];
      // The rim follows the face: left where the sphere maps put it (a face shrunk by the
      // placement's depth rule to a few percent of its region), it can lie inside the cast ends,
      // and the cells between them fold. Cast from the same starting grid, one index step beyond
      // the ends, along the same axis (a rim point need not lie in the area); all or nothing.
      // At lambda = 1 the layer's own rim lies on the surface: start a little inside.
      if (cast_rim) {
        std::vector<Vec3> rim_hits;
        for (const Vec3& offset : rim_offsets) {
          // A start the fit puts outside the muscle (a fit wider than a bent end) can miss: its
          // closest surface point instead.
          const double rim_lambda = std::min(azimuth && azimuth->placed ? azimuth->factor(offset) : lambda, 0.95);
          const Vec3 start = c1 + rim_lambda * offset;
          Vec3 end;
          if (!hit(start, axes[used_axis], end)) end = query.closest_point(start).position;
          if (!end.allFinite()) break;
          rim_hits.push_back(end);
        }
        if (rim_hits.size() == rim.size()) {
          for (std::size_t r = 0; r < rim.size(); ++r) at(rim[r][0], rim[r][1], k_end) = rim_hits[r];
          rim_cast = true;
        }
      }
    }
    out.push_back({{"face", k_end == 0 ? "origin" : "insertion"},
                   {"cast", placed},
                   {"shrink", placed ? lambda : 0.0},
                   {"shrink_largest", azimuth && azimuth->placed ? azimuth->largest() : placed ? lambda : 0.0},
                   {"from", folded ? (fit_layer == k1 ? "affine_fit"
                                      : fit_layer < 0 ? "layer_folded"
                                                      : "affine_fit_deeper")
                                   : "layer"},
                   {"fit_layer", fit_layer},
                   {"rim", rim_cast},
                   {"axis", used_axis == 0   ? "layer"
                            : used_axis == 1 ? "area"
                                             : "nearest_area_point"}});
    if (strip) out.back()["strip_factors"] = strip_factors;
  }
  return out;
}

}  // namespace

const char* rest_shape_name(RestShape shape) {
  switch (shape) {
    case RestShape::zero: return "zero";
    case RestShape::tension: return "tension";
    case RestShape::template_: return "template";
  }
  return "?";
}

RestShape parse_rest_shape(const std::string& name) {
  if (name == "zero") return RestShape::zero;
  if (name == "tension") return RestShape::tension;
  if (name == "template") return RestShape::template_;
  throw OptionError("--rest: unknown rest shape '" + name + "' (valid: zero, tension, template)");
}

springs::SettleOptions DecomposeOptions::default_settle() {
  springs::SettleOptions s;
  s.solver = springs::SolverKind::static_equilibrium;
  s.tolerance = 1e-6;
  s.max_iterations = 20000;
  // The portable loop, the same bit for bit on every processor: the untangling turns last-bit
  // differences of the settled lattice into different folds, and a lattice of a few thousand
  // points settles in milliseconds with either loop.
  s.portable_loop = true;
  // Coarse starts unperturbed: a decomposition's lattice is under tension, not the compressed
  // lattice whose buckling the perturbation is for.
  s.coarse_start_perturbation = 0.0;
  return s;
}

const char* quality_name(Quality quality) {
  switch (quality) {
    case Quality::draft: return "draft";
    case Quality::standard: return "standard";
    case Quality::fine: return "fine";
  }
  return "?";
}

Quality parse_quality(const std::string& name) {
  if (name == "draft") return Quality::draft;
  if (name == "standard") return Quality::standard;
  if (name == "fine") return Quality::fine;
  throw OptionError("--quality: unknown level '" + name + "' (valid: draft, standard, fine)");
}

DecomposeOptions with_quality(DecomposeOptions options, Quality quality) {
  struct Level {
    int fibres, resolution;
    double tolerance;
    int samples;
  };
  const Level level = quality == Quality::draft  ? Level{36, 9, 1e-4, 5000}
                      : quality == Quality::fine ? Level{144, 19, 1e-7, 40000}
                                                 : Level{100, 15, 1e-6, 20000};
  options.fibres = level.fibres;
  options.resolution = level.resolution;
  options.settle.tolerance = level.tolerance;
  options.check.coverage_samples = level.samples;
  return options;
}

CheckOptions DecomposeOptions::default_check() {
  CheckOptions c;
  c.max_crossing_segments = -1;
  c.max_turning_angle_deg = 180.0;
  c.min_end_coverage = 0.0;
  return c;
}

void DecomposeOptions::validate() const {
  architecture.validate();
  pennate.validate();
  sphere.validate();
  attachments.validate();
  strip.validate();
  placement.validate();
  settle.validate();
  untangle.validate();
  segments.validate();
  smoothing.validate();
  // Decompose's own cap on the fibre count (below the lattice's), then the lattice's checks of
  // fibres, resolution and their product.
  if (fibres > 1'000'000) throw OptionError("fibres: at most 1000000, got " + std::to_string(fibres));
  springs::LatticeOptions lattice;
  lattice.kind = kind;
  lattice.fibres = fibres;
  lattice.resolution = resolution;
  lattice.model = model;
  lattice.edge_cell = edge_cell;
  lattice.validate();
  if (backend != "cpu" && backend != "gl" && backend != "auto")
    throw OptionError("backend: unknown backend '" + backend + "' (valid: cpu, gl, auto)");
  if (cast_rounds < 0 || cast_rounds > 100)
    throw OptionError("cast_rounds: must be in 0..100, got " + std::to_string(cast_rounds));
  if (soft_contact_rounds < 0 || soft_contact_rounds > 100)
    throw OptionError("soft_contact_rounds: must be in 0..100, got " + std::to_string(soft_contact_rounds));
  if (contact_rounds < 0 || contact_rounds > 100)
    throw OptionError("contact_rounds: must be in 0..100, got " + std::to_string(contact_rounds));
  if (!(contact_depth > 0.0 && contact_depth < 1.0))
    throw OptionError("contact_depth: must be in (0, 1), got " + std::to_string(contact_depth));
  if (!(placement_end_share > 0.0 && placement_end_share <= 1.0))
    throw OptionError("placement_end_share: must be in (0, 1], got " + std::to_string(placement_end_share));
  tries.validate();
  if (harmonic_direct_points < 0)
    throw OptionError("harmonic_direct_points: must be >= 0, got " + std::to_string(harmonic_direct_points));
  if (map_faces < 1000) throw OptionError("map_faces: must be >= 1000, got " + std::to_string(map_faces));
}

nlohmann::json DecomposeReport::to_json() const {
  nlohmann::json j;
  j["status"] = status;
  if (!failure.empty()) j["failure"] = failure;
  j["repair"] = repair;
  j["sphere"] = sphere;
  j["attachments"] = attachments;
  j["cross_section"] = cross_section;
  j["placement"] = placement;
  j["lattice"] = lattice;
  j["settle"] = settle;
  j["containment"] = containment;
  j["untangle"] = untangle;
  j["pennate"] = pennate;
  j["quality"] = quality.to_json();
  j["architecture"] = architecture.to_json();
  j["attempts"] = attempts;
  j["kept_attempt"] = kept_attempt;
  j["renderer"] = renderer;
  j["seconds"] = {{"repair", repair_seconds}, {"surface_query", query_seconds},
                  {"sphere", sphere_seconds}, {"placement", placement_seconds},
                  {"settle", settle_seconds}, {"check", check_seconds},
                  {"total", seconds}};
  return j;
}

namespace {

// Whether the fibres are the lattice's lines between automatic areas (no landmark files, and a
// template whose fibres do not cross the lattice): the case PlacementOptions::twist_for() tells apart.
bool lines_between_automatic_areas(bool automatic_areas, springs::TemplateKind kind) {
  return automatic_areas && !springs::crosses_lattice(kind);
}

// The muscle's sphere map and its point locator, made once for both tries (the second does not
// change the sphere options).
struct MuscleSphere {
  std::optional<TriangleMesh> simplified;  // the surface mapped when the muscle is finer than map_faces
  SimplifyReport simplify;
  SphereMap map;
  std::optional<SphereLocator> locator;  // empty when the map is not a bijection
  double seconds = 0.0;
};

// The template lattice of the options (a ring of surface lines round the fibres) and the factor
// of its zero-rest-length (harmonic) settle's matrix: neither depends on the muscle, so they are
// made beside the sphere map for the first try (a second try with other edge cells prepares its
// own; decompose_attempt checks it).
struct PreparedLattice {
  springs::LatticeOptions options;
  springs::Lattice lattice;
  std::shared_ptr<const springs::SpringMatrixFactor> harmonic;
  double factor_seconds = 0.0;
};

springs::LatticeOptions lattice_options_of(const DecomposeOptions& options) {
  const auto split = springs::near_square_split(options.fibres);
  springs::LatticeOptions lattice_options;
  lattice_options.kind = options.kind;
  lattice_options.nr = split[0] + 2;
  lattice_options.ns = split[1] + 2;
  lattice_options.resolution = options.resolution;
  lattice_options.model = options.model;
  lattice_options.edge_cell = options.edge_cell;
  return lattice_options;
}

// Whether two lattice options build the same lattice.
bool same_lattice(const springs::LatticeOptions& a, const springs::LatticeOptions& b) {
  return a.kind == b.kind && a.nr == b.nr && a.ns == b.ns && a.resolution == b.resolution && a.model == b.model &&
         a.edge_cell == b.edge_cell;
}

PreparedLattice prepare_lattice(const DecomposeOptions& options) {
  PreparedLattice out;
  out.options = lattice_options_of(options);
  out.lattice = springs::build_lattice(out.options);
  if (static_cast<long>(out.lattice.point_count()) > options.harmonic_direct_points) return out;  // multigrid
  const auto start = Clock::now();
  out.harmonic = springs::factor_spring_matrix(out.lattice.system);  // the rest lengths play no part
  out.factor_seconds = since(start);
  return out;
}

// The compute backend of a decomposition's settles (springs/compute_backend.h): the CPU, or for
// backend "gl" the GPU, made by the first settle and kept for the others, the attempts'
// included, instead of an OpenGL context (EGL display, driver, GLEW) for every settle.
class ComputeCache {
 public:
  explicit ComputeCache(const std::string& backend) { request_.name = backend == "gl" ? "gl" : "cpu"; }
  springs::ComputeBackend& get() {
    if (!backend_) backend_ = springs::make_compute_backend(request_);
    return *backend_;
  }

 private:
  springs::ComputeRequest request_;
  std::unique_ptr<springs::ComputeBackend> backend_;
};

// One whole decomposition of a repaired muscle (steps 2-9) with the options as given.
// `query`, `sphere`, `prepared` and `compute` are made once for all attempts.
Decomposition decompose_attempt(const TriangleMesh& muscle, const SurfaceQuery& query, const MuscleSphere& sphere,
                                const PreparedLattice& prepared, const Landmarks& landmarks,
                                const DecomposeOptions& options, ComputeCache& compute) {
  const auto start = Clock::now();
  Decomposition out;
  out.muscle = muscle;
  DecomposeReport& report = out.report;

  const auto stage_started = [&](const char* what) {
    if (options.progress) options.progress(std::string(what));
  };
  stage_started("place the template");
  // Attachment areas.
  Attachments areas;
  nlohmann::json strip;  // landmark areas only: how they were joined
  if (landmarks.given()) {
    if (landmarks.origin.empty() || landmarks.insertion.empty())
      throw OptionError("landmarks: give both an origin and an insertion file, or neither (automatic areas)");
    areas = landmark_attachments(muscle, landmarks.origin, landmarks.origin_source, landmarks.insertion,
                                 landmarks.insertion_source, options.attachments);
    strip = join_landmark_strips(areas, query, muscle_length(muscle), options.strip);
  } else {
    AttachmentOptions placed = options.attachments;
    placed.end_fraction *= options.placement_end_share;
    areas = automatic_attachments(muscle, placed);
  }
  // The check's areas: the full automatic areas where the placement used a share of them.
  const bool shared = !landmarks.given() && options.placement_end_share != 1.0;
  const Attachments whole_areas = shared ? automatic_attachments(muscle, options.attachments) : Attachments{};
  const Attachments& checked_against = shared ? whole_areas : areas;
  report.attachments = {{"automatic", areas.automatic},
                        {"placement_end_share", landmarks.given() ? 1.0 : options.placement_end_share},
                        {"origin", areas.origin.to_json()},
                        {"insertion", areas.insertion.to_json()}};
  if (!strip.is_null()) report.attachments["strip"] = strip;

  // Sphere map of the muscle (made before the attempts).
  const SphereMap& map = sphere.map;
  report.sphere = map.report.to_json();
  if (sphere.simplified) report.sphere["simplified"] = sphere.simplify.to_json();
  if (!sphere.locator)
    throw SolverError("sphere map: not a bijection (" + map.report.failure + "); try --sphere-method " +
                      std::string(map.report.method == "tutte" ? "relax" : "tutte"));
  const SphereLocator& locator = *sphere.locator;

  // Template lattice with a ring of surface lines, placed on the muscle.
  auto stage = Clock::now();
  const auto split = springs::near_square_split(options.fibres);
  FASCICLE_CHECK(same_lattice(lattice_options_of(options), prepared.options),
                 "the attempt's lattice options are the prepared lattice's");
  const springs::Lattice& lattice = prepared.lattice;
  // The corner twist of these areas and this template (PlacementOptions::twist_for()).
  PlacementOptions placing = options.placement;
  placing.corner_twist_deg =
      options.placement.twist_for(lines_between_automatic_areas(areas.automatic, options.kind));
  Placement placement = place_template(sphere.simplified ? *sphere.simplified : muscle, map.positions, locator, areas,
                                       lattice, placing);
  // On a simplified surface the placed points move to the muscle's closest points (the
  // simplification's error, a small part of a lattice cell).
  if (sphere.simplified)
    for (SurfacePoint& p : placement.points)
      if (p.face >= 0) p = query.closest_point(p.position);
  report.placement = placement.report.to_json();
  report.lattice = {{"template", springs::template_name(options.kind)},
                    {"model", static_cast<int>(options.model)},
                    {"nx", lattice.nx},
                    {"ny", lattice.ny},
                    {"nz", lattice.nz},
                    {"points", lattice.point_count()},
                    {"springs", lattice.system.springs.size()},
                    {"fibres", split[0] * split[1]}};
  report.placement_seconds = since(stage);

  // Settle: zero-rest-length equilibrium first, then the template's stretched rest lengths.
  stage_started("settle");
  stage = Clock::now();
  springs::SpringSystem system = lattice.system;
  const std::vector<Vec3> template_positions = system.positions;
  for (std::size_t q = 0; q < system.positions.size(); ++q)
    if (system.fixed[q]) system.positions[q] = placement.points[q].position;
  const springs::LatticeShape shape = springs::shape_of(lattice);
  {
    springs::SpringSystem harmonic = system;
    for (springs::Spring& s : harmonic.springs) s.rest = 0.0;
    springs::SettleOptions linear;
    linear.solver = springs::SolverKind::static_equilibrium;
    linear.portable_loop = options.settle.portable_loop;
    linear.tolerance = 1e-12;
    if (prepared.harmonic) {
      // One solve with the matrix factorized beside the sphere map, before the attempt.
      linear.static_method = springs::StaticMethod::local_global;
      linear.acceleration = springs::Acceleration::none;
      linear.max_iterations = 4;
    } else {
      // V-cycles to the harmonic start, then V-cycle-preconditioned steps: the energy is
      // quadratic with the multigrid's own Laplacian as its Hessian.
      linear.static_method = springs::StaticMethod::multigrid;
      linear.multigrid_harmonic_start = true;
      linear.max_iterations = 200;
    }
    const springs::SettleReport first =
        springs::settle(harmonic, linear, prepared.harmonic ? nullptr : &shape, prepared.harmonic);
    report.settle["harmonic"] = settle_json(first);
    report.settle["harmonic"]["factor_seconds"] = prepared.factor_seconds;
    system.positions = harmonic.positions;
  }
  if (options.rest != RestShape::zero)
    stretch_rest_lengths(system, template_positions, system.positions, options.rest == RestShape::tension,
                         report.settle);
  else
    for (springs::Spring& s : system.springs) s.rest = 0.0;
  report.settle["rest"] = rest_shape_name(options.rest);

  int pinned = 0, rounds = 0;
  nlohmann::json solves = nlohmann::json::array();
  std::vector<int> outside;
  // The settles before the last round of fibre ends only need to be close: the ends move after
  // them anyway.
  springs::SettleOptions rough = options.settle;
  if (rough.tolerance > 0.0) rough.tolerance = std::max(rough.tolerance, 1e-4);
  // Soft contact: an outside point first gets a zero-length spring to a fixed anchor just inside
  // the surface (stiffer each round), so that the correction spreads over its neighbours; only
  // points still outside after the soft rounds are pinned.
  const std::size_t lattice_points = system.positions.size();
  // Distance within which a fibre end's segment may touch the surface (the check's).
  const double diagonal = bounding_box(muscle.positions).diagonal();
  const double end_tolerance = options.check.end_tolerance * diagonal;
  const SegmentContact segment_contact{end_tolerance, options.check.segment_tolerance * diagonal,
                                       options.check.excursion_samples, options.segments};
  std::vector<double> point_stiffness(lattice_points, 0.0), point_springs(lattice_points, 0.0);
  for (const springs::Spring& s : system.springs) {
    point_stiffness[static_cast<std::size_t>(s.a)] += s.stiffness;
    point_stiffness[static_cast<std::size_t>(s.b)] += s.stiffness;
  }
  std::unordered_map<int, std::size_t> anchor_spring;  // lattice point -> index of its anchor spring
  int anchored = 0;
  // A point just inside the surface for the outside point q: the closest surface point moved
  // `contact_depth` local spacings inwards (halved until it is inside).
  auto contact_target = [&](int q, const std::vector<double>& spacing) -> Vec3 {
    return lattice_contact_point(system, lattice.point_count(), query, q, options.contact_depth, spacing);
  };
  auto settle_with_contact = [&](const springs::SettleOptions& settle_options) {
    int soft = 0, local_rounds = 0;
    for (;;) {
      springs::SettleReport settled;
      nlohmann::json gpu_fields = nlohmann::json::object();  // the GPU's stop and the CPU's polish
      springs::ComputeBackend& backend = compute.get();
      springs::GpuSettleFigures figures;
      settled = backend.settle(system, settle_options, anchor_spring.empty() ? &shape : nullptr, &figures);
      if (backend.name() != "cpu") {
        report.renderer = backend.device().renderer;
        gpu_fields = {{"gpu_residual", figures.gpu_residual},
                      {"stalled", figures.stalled},
                      {"polished", figures.polished},
                      {"polish_iterations", figures.polish_iterations},
                      {"polish_seconds", figures.polish_seconds}};
      }
      solves.push_back(settle_json(settled));
      solves.back().update(gpu_fields);
      outside = outside_free_points(system, query);
      if (outside.empty() || local_rounds == options.contact_rounds) break;
      ++local_rounds;
      ++rounds;
      const std::vector<double> spacing = lattice_local_spacing(system);
      for (int q : outside) {
        const Vec3 moved = contact_target(q, spacing);
        if (soft < options.soft_contact_rounds) {
          const auto it = anchor_spring.find(q);
          if (it == anchor_spring.end()) {
            system.positions.push_back(moved);
            system.fixed.push_back(1);
            system.mass.push_back(system.mass[static_cast<std::size_t>(q)]);
            springs::Spring spring;
            spring.a = q;
            spring.b = static_cast<int>(system.positions.size()) - 1;
            spring.rest = 0.0;
            spring.stiffness = 4.0 * point_stiffness[static_cast<std::size_t>(q)];
            anchor_spring[q] = system.springs.size();
            system.springs.push_back(spring);
            ++anchored;
          } else {
            springs::Spring& spring = system.springs[it->second];
            system.positions[static_cast<std::size_t>(spring.b)] = moved;
            spring.stiffness *= 4.0;
          }
          continue;
        }
        system.positions[static_cast<std::size_t>(q)] = moved;
        system.fixed[static_cast<std::size_t>(q)] = 1;
        ++pinned;
      }
      ++soft;
    }
  };
  settle_with_contact(options.cast_rounds > 0 ? rough : options.settle);
  nlohmann::json casts = nlohmann::json::array();
  const double end_radius = options.placement.region_radius * muscle_length(muscle);
  for (int round = 0; round < options.cast_rounds; ++round) {
    casts.push_back(cast_faces(system, lattice, muscle, areas, end_radius, query, options.cast_rim,
                               landmarks.given() && options.strip.join, options.cast_by_azimuth));
    settle_with_contact(round + 1 < options.cast_rounds ? rough : options.settle);
  }
  const bool crossing_kind = springs::crosses_lattice(options.kind);
  // Fibres: the interior lattice lines, origin (t = 0) to insertion.
  auto fibres_of = [&](const std::vector<Vec3>& positions) { return lattice_interior_fibres(lattice, positions); };

  // Steps 8-10 on a settled, untangled lattice: the ends aligned, the segments that leave moved
  // back inside, the sharp joints smoothed; their reports into `into`. Returns the fallbacks of
  // the check below, in order: the moved positions smoothed only at the whole check's turning
  // limit, then the positions without the segment moves smoothed (at the goal, then at the
  // limit), then without the moves or the smoothing (each where it differs). Smoothing every
  // joint over the goal (30 degrees) straightens the muscle's own bends and can draw the fibres
  // off a bend's outer side (coverage); only the joints over the limit cost less of it.
  // A smoothed fallback is smoothed only when it is tried: most results pass and try none.
  struct Fallback {
    std::vector<Vec3> positions;
    bool unmoved = false, unsmoothed = false, unheld = false;
    const FibreSmoothingOptions* smooth = nullptr;  // smooth `positions` with these when tried
    bool only_if_moved = false;                     // and leave it out when that moves nothing
  };
  FibreSmoothingOptions at_limit = options.smoothing;
  at_limit.max_turning_deg = std::max(at_limit.max_turning_deg, CheckOptions{}.max_turning_angle_deg);
  const bool limit_differs = at_limit.max_turning_deg != options.smoothing.max_turning_deg;
  auto finish_lines = [&](springs::SpringSystem& lines, nlohmann::json& into) {
    into["end_alignment"] =
        options.align_ends ? align_ends(lattice, lines, query, areas, end_radius).to_json() : nlohmann::json(nullptr);
    const std::vector<Vec3> aligned = lines.positions;
    long moved = 0, smoothed = 0;
    if (options.contain_segments) {
      const SegmentContainmentReport contained =
          contain_segments(lattice, lines, query, end_tolerance, options.segments);
      moved = contained.moved;
      into["segments"] = contained.to_json();
      into["segments"]["reverted"] = false;
    }
    std::vector<Fallback> fallbacks;
    // A crossing template smooths the fibres it draws instead.
    const bool smooth = options.smoothing.steps > 0 && !crossing_kind;
    if (smooth) {
      // The positions `from` smoothed only at the limit, as a fallback (where that differs).
      const auto limit_fallback = [&](const std::vector<Vec3>& from, bool unmoved) {
        if (limit_differs) fallbacks.push_back({from, unmoved, false, false, &at_limit, true});
      };
      const std::vector<Vec3> contained = lines.positions;
      const FibreSmoothingReport smoothing = smooth_fibres(lattice, lines, query, end_tolerance, options.smoothing);
      smoothed = smoothing.moved;
      into["smoothing"] = smoothing.to_json();
      into["smoothing"]["reverted"] = false;
      if (smoothed > 0) limit_fallback(contained, false);
      if (moved > 0) {
        fallbacks.push_back({aligned, true, false, false, &options.smoothing});
        limit_fallback(aligned, true);
      }
    }
    if (moved > 0 || smoothed > 0) fallbacks.push_back({aligned, moved > 0, smoothed > 0});
    return fallbacks;
  };
  // The whole check's segments and smoothness criteria a finished lattice fails, its joints over
  // 45 degrees and its segments out (compared in that order).
  auto segment_figures = [&](const springs::SpringSystem& lines) {
    const double max_turning = CheckOptions{}.max_turning_angle_deg;
    const long crossing = crossing_segment_count(lattice, lines, query, segment_contact),
               sharp = sharp_joints(lattice, lines.positions, max_turning);
    return std::array<long, 3>{(crossing > 0 ? 1 : 0) + (sharp > 0 ? 1 : 0), sharp, crossing};
  };

  // Untangling (fibres/untangle_lattice.h): the cells the settle left inverted are unfolded, with
  // containment.
  // The untangled lattice before its segment attempt, when that was kept (the fallback below). A
  // crossing template's fibres are drawn through the lattice, not along its lines: no attempt.
  // The attempt runs only where the lattice finished without it fails a segments or smoothness
  // criterion: on a tie the result without it is kept below, so it could not change the choice.
  // That finished lattice is kept (`asked`) and serves below instead of finishing it again.
  springs::SpringSystem unheld;
  bool has_unheld = false;
  struct Finished {
    springs::SpringSystem before, lines;  // the lattice asked about, and finished
    std::vector<Fallback> fallbacks;
    nlohmann::json report = nlohmann::json::object();
    std::array<long, 3> figures{};
  };
  std::optional<Finished> asked;
  auto segments_needed = [&](const springs::SpringSystem& untangled) {
    asked.emplace();
    asked->before = asked->lines = untangled;
    asked->fallbacks = finish_lines(asked->lines, asked->report);
    asked->figures = segment_figures(asked->lines);
    return asked->figures != std::array<long, 3>{0, 0, 0};
  };
  if (options.untangle_cells) {
    stage_started("untangle");
    const LatticeUntangleReport untangled = untangle_lattice(
        lattice, system, query, muscle_length(muscle), options.untangle, &areas,
        options.contact_segments && !crossing_kind ? &segment_contact : nullptr, &unheld, segments_needed);
    has_unheld = untangled.segments_kept;
    pinned += static_cast<int>(untangled.pinned);
    outside = outside_free_points(system, query);
    report.untangle = untangled.to_json();
  }
  report.settle["cast_faces"] = casts;
  report.settle["solves"] = solves;
  report.containment = {
      {"rounds", rounds}, {"anchored_points", anchored}, {"pinned_points", pinned}, {"outside_after", outside.size()}};
  report.settle_seconds = since(stage);

  // The finished lattice the untangling asked about, where it is the one to finish here.
  // Its segment figures go to `figures` where asked for.
  auto take_asked = [&](springs::SpringSystem& lines, nlohmann::json& into, std::vector<Fallback>& fallbacks,
                        std::array<long, 3>* figures = nullptr) {
    if (!asked || asked->before.positions != lines.positions || asked->before.fixed != lines.fixed) return false;
    lines = std::move(asked->lines);
    fallbacks = std::move(asked->fallbacks);
    for (auto& [key, value] : asked->report.items()) into[key] = std::move(value);
    if (figures != nullptr) *figures = asked->figures;
    asked.reset();
    return true;
  };
  std::vector<Fallback> fallbacks;
  if (!take_asked(system, report.containment, fallbacks)) fallbacks = finish_lines(system, report.containment);
  // With the untangling's segment attempt kept, the lattice before it is finished too, and the
  // one whose fibres fail fewer of the whole check's segments and smoothness criteria is kept,
  // then the one with fewer joints over its 45 degrees (a hook shows at any scale, a segment just
  // past 0.5 % of the diagonal does not), then fewer segments out, on a tie the one without the
  // attempt; the other is the fallback below.
  nlohmann::json unheld_report = nlohmann::json::object();
  std::vector<Fallback> unheld_fallbacks;
  auto swap_finish_reports = [&] {
    for (const char* key : {"end_alignment", "segments", "smoothing"}) {
      nlohmann::json held = report.containment.value(key, nlohmann::json(nullptr));
      report.containment[key] = unheld_report.value(key, nlohmann::json(nullptr));
      unheld_report[key] = std::move(held);
    }
  };
  if (has_unheld) {
    std::array<long, 3> unheld_figures{};
    if (!take_asked(unheld, unheld_report, unheld_fallbacks, &unheld_figures)) {
      unheld_fallbacks = finish_lines(unheld, unheld_report);
      unheld_figures = segment_figures(unheld);
    }
    const auto held_figures = segment_figures(system);
    report.untangle["segments_figures"] = {{"held", held_figures}, {"unheld", unheld_figures}};
    if (!(held_figures < unheld_figures)) {
      std::swap(system, unheld);
      std::swap(fallbacks, unheld_fallbacks);
      swap_finish_reports();
      report.untangle["segments_kept"] = false;
    }
  }
  out.fibres = fibres_of(system.positions);
  for (const auto& line : out.fibres.lines)
    for (const Vec3& p : line)
      if (!p.allFinite()) throw SolverError("decompose: a fibre point is not finite; check the settle options");

  // Check.
  stage_started("check");
  stage = Clock::now();
  if (springs::crosses_lattice(options.kind)) {
    // A crossing template's fibres are drawn through the lattice once it is settled: the lattice
    // must be a map (no folded cell, every point inside), and the fibres pass the check against
    // the areas they span. The architecture's line of action stays that of the end areas.
    CheckOptions map_check = options.check;  // only its cells and points matter here
    map_check.coverage_samples = 100;
    map_check.end_samples = 100;
    const CheckReport map_quality = check_fibres(out.fibres, muscle, query, checked_against, map_check);
    const Vec3 line = checked_against.insertion.centroid() - checked_against.origin.centroid();
    PennateFibres drawn = pennate_fibres(options.kind, lattice, system.positions, options.fibres, options.resolution,
                                         line, query, options.pennate);
    report.pennate = drawn.report.to_json();
    report.pennate["map"] = {{"inverted_cells", map_quality.inverted_cells},
                             {"inside_fraction", map_quality.inside_fraction}};
    out.fibres = std::move(drawn.fibres);
    report.quality = check_fibres(out.fibres, muscle, query, drawn.areas, options.check);
    if (map_quality.inverted_cells > 0 || map_quality.inside_fraction < options.check.min_inside_fraction) {
      report.quality.pass = false;
      report.quality.failed.push_back("map");
    }
  } else {
    report.quality = check_fibres(out.fibres, muscle, query, checked_against, options.check);
    // The segment moves (step 9) and the untangling's segment attempt guard the points, the
    // segments and the cells, not the coverage (a global figure): when the result fails, the
    // fibres before the moves, then those finished from the lattice before the segment attempt
    // (with and without its moves) are checked in turn, and the first that passes is kept (an
    // earlier one keeps more of the finishing steps). The report lists those checked and what
    // each failed, of decompose's check and of the whole check.
    if (!report.quality.pass) {
      if (has_unheld) {
        fallbacks.push_back({unheld.positions, false, false, true});
        for (Fallback& f : unheld_fallbacks) {
          f.unheld = true;
          fallbacks.push_back(std::move(f));
        }
      }
      nlohmann::json fallbacks_report = {{"failed", report.quality.failed},
                                         {"coverage_p95", report.quality.coverage.p95},
                                         {"tried", nlohmann::json::array()}};
      for (Fallback& fallback : fallbacks) {
        nlohmann::json smoothing = nullptr;  // the smoothing report of the positions tried, when smoothed
        if (fallback.smooth) {
          springs::SpringSystem smoothed = system;
          smoothed.positions = std::move(fallback.positions);
          const FibreSmoothingReport r = smooth_fibres(lattice, smoothed, query, end_tolerance, *fallback.smooth);
          if (fallback.only_if_moved && r.moved == 0) continue;
          fallback.positions = std::move(smoothed.positions);
          smoothing = r.to_json();
        }
        Polylines fibres = fibres_of(fallback.positions);
        CheckReport quality = check_fibres(fibres, muscle, query, checked_against, options.check);
        fallbacks_report["tried"].push_back({{"unmoved", fallback.unmoved},
                                             {"unsmoothed", fallback.unsmoothed},
                                             {"smoothed_above_deg",
                                              smoothing.is_null() ? nlohmann::json(nullptr) : smoothing["above_deg"]},
                                             {"unheld", fallback.unheld},
                                             {"failed", quality.failed},
                                             {"coverage_p95", quality.coverage.p95},
                                             {"whole_check_failed", failed_criteria(quality, CheckOptions{})}});
        if (!quality.pass) continue;
        out.fibres = std::move(fibres);
        report.quality = std::move(quality);
        if (fallback.unheld) {
          swap_finish_reports();
          report.untangle["segments_kept"] = !report.untangle["segments_kept"].get<bool>();
          report.untangle["segments_reverted"] = true;
        }
        if (fallback.unsmoothed) report.containment["smoothing"]["reverted"] = true;
        if (!smoothing.is_null()) {
          report.containment["smoothing"] = smoothing;
          report.containment["smoothing"]["reverted"] = false;
        }
        if (fallback.unmoved) {
          report.containment["segments"]["reverted"] = true;
          report.containment["segments"]["crossing_after"] = report.quality.touching_segments;
        }
        break;
      }
      report.containment["fallbacks"] = std::move(fallbacks_report);
    }
  }
  report.architecture = measure_architecture(out.fibres, muscle, checked_against, options.architecture);
  report.check_seconds = since(stage);
  report.status = report.quality.pass ? "ok" : "failed";
  if (!report.quality.pass) report.failure = "the fibres fail the quality check";
  report.seconds = since(start);
  return out;
}

// Whether the attempt's untangling ran its attempts with the surface ring free (those with it
// held left folds).
bool free_ring_tried(const DecomposeReport& r) {
  return r.untangle.is_object() && r.untangle.value("free_ring_tried", false);
}

// The start of an entry of the report's `attempts`: what the try changed and why.
nlohmann::json attempt_header(const std::string& change, const std::vector<std::string>& modes,
                              const DecomposeOptions& options, bool landmarks) {
  return {{"change", change},
          {"failure_modes", modes},
          {"corner_twist_deg", options.placement.twist_for(lines_between_automatic_areas(!landmarks, options.kind))},
          {"landmark_strip", options.strip.join},
          {"meridian_rings", options.placement.meridian_rings},
          {"edge_cell", options.edge_cell},
          {"max_face_depth", options.placement.max_face_depth}};
}

// One entry of the report's `attempts`: what the try changed and how its check came out.
nlohmann::json attempt_json(const std::string& change, const std::vector<std::string>& modes,
                            const DecomposeOptions& options, const DecomposeReport& r, bool landmarks) {
  const CheckReport& q = r.quality;
  nlohmann::json j = attempt_header(change, modes, options, landmarks);
  j["status"] = r.status;
  j["failed"] = q.failed;
  j["inside_fraction"] = q.inside_fraction;
  j["inverted_cells"] = q.inverted_cells;
  j["coverage_p95"] = q.coverage.p95;
  j["attachment_max"] = std::max(q.attachment.origin_max, q.attachment.insertion_max);
  j["layer_ratio"] = q.steps.layer_ratio;
  j["whole_check_failed"] = failed_criteria(q, CheckOptions{});
  j["free_ring_tried"] = free_ring_tried(r);
  j["seconds"] = r.seconds;
  return j;
}

}  // namespace

SecondTry second_try(const DecomposeOptions& first, const std::vector<std::string>& modes, bool landmarks) {
  const bool landmark_strips = landmarks && first.strip.join;
  const auto shows = [&](const char* mode) { return std::find(modes.begin(), modes.end(), mode) != modes.end(); };
  SecondTry out{"", first};
  const auto add = [&](const char* change) { out.change += (out.change.empty() ? "" : "+") + std::string(change); };
  if ((shows("folds") || shows("uneven_layers")) && first.placement.band_by_length && !first.placement.meridian_rings) {
    out.options.placement.meridian_rings = true;
    add("meridian_rings");
  }
  // A coverage gap is first the lattice's sides on a flat muscle's thin edges, whose middles the
  // settled interior cannot follow into an acute edge: corners on the edges; with the corners
  // there already, narrower edge cells.
  const bool lines = lines_between_automatic_areas(!landmarks, first.kind);
  const bool corners_on_edges = std::abs(std::remainder(first.placement.twist_for(lines), 90.0)) == 45.0;
  if (shows("coverage") && !corners_on_edges) {
    (lines ? out.options.placement.corner_twist_deg : out.options.placement.edge_corner_twist_deg) = 45.0;
    add("corners_on_edges");
  } else if (shows("coverage") && first.edge_cell > 0.5) {
    out.options.edge_cell = 0.5;
    add("narrow_edge_cells");
  }
  // A first try that passes decompose's check with ends gathered in the shadow of the layer next
  // to them, hooked end joints or segments out (the whole check): faces as deep as the first ring,
  // so that the end layers of cells curve round the muscle's ends and the ends cast from them
  // spread over their areas.
  // On a landmark strip along the muscle's side gathered ends are not that shadow: the layer next
  // to the face is a whole cross-section and its cast reaches the strip only near its centre,
  // however deep the face (fibres/strip_cast.h), so they alone call no second try.
  constexpr double kDeepFace = 1.0;  // deeper than the first ring, the end layer would turn over
  const bool ends_call = shows("gathered_ends") && !landmark_strips;
  // A joint inside the fibres (sharp_joints) is a bend of the muscle the end layers do not reach.
  if ((ends_call || shows("hooked_ends") || shows("segments_out")) && first.placement.max_face_depth < kDeepFace) {
    out.options.placement.max_face_depth = kDeepFace;
    add("deep_faces");
  }
  return out;
}

bool better_result(const CheckReport& a, const CheckReport& b) {
  if (a.pass != b.pass) return a.pass;
  if (a.failed.size() != b.failed.size()) return a.failed.size() < b.failed.size();
  if (a.inverted_cells != b.inverted_cells) return a.inverted_cells < b.inverted_cells;
  if (a.inside_fraction != b.inside_fraction) return a.inside_fraction > b.inside_fraction;
  return a.coverage.p95 < b.coverage.p95;
}

Decomposition decompose_repaired(const TriangleMesh& muscle, const Landmarks& landmarks,
                                 const DecomposeOptions& options) {
  options.validate();
  const auto start = Clock::now();
  // The surface's query trees (with the inside grid) and the muscle's sphere map side by side:
  // each is mostly one thread's work.
  std::optional<SurfaceQuery> built_query;
  MuscleSphere sphere;
  PreparedLattice prepared;
  double query_seconds = 0.0;
  if (options.progress) options.progress("map onto the sphere");
  tbb::parallel_invoke(
      [&] {
        const auto t = Clock::now();
        built_query.emplace(muscle);
        built_query->inside_grid();
        query_seconds = since(t);
        prepared = prepare_lattice(options);  // the sphere map takes longer than the query
      },
      [&] {
        const auto t = Clock::now();
        if (static_cast<long>(muscle.triangles.size()) > options.map_faces)
          sphere.simplified = simplify_mesh(muscle, options.map_faces, &sphere.simplify);
        const TriangleMesh& mapped = sphere.simplified ? *sphere.simplified : muscle;
        sphere.map = map_to_sphere(mapped, options.sphere);
        if (sphere.map.report.quality.bijective()) sphere.locator.emplace(sphere.map.positions, mapped.triangles);
        sphere.seconds = since(t);
      });
  const SurfaceQuery& query = *built_query;
  const double setup_seconds = since(start);
  ComputeCache compute(options.backend);

  // The tries (fibres/try_policy.h): the options as given, then at most one more, made from the
  // first's failure modes. An error of the first try is the decomposition's; of the second, it is
  // reported and the first result kept.
  struct Try {
    std::string change;
    std::vector<std::string> modes;  // the first try's failure modes that called this one
    DecomposeOptions options;
  };
  // A flat muscle's first try has the corners on its thin edges (PlacementOptions::flat_section_aspect):
  // the sides' middles there leave a coverage gap that only a second try would close.
  const CrossSectionShape section = cross_section_shape(muscle);
  DecomposeOptions first = options;
  const bool flat = lines_between_automatic_areas(!landmarks.given(), options.kind) &&
                    options.placement.flat_section_aspect > 0.0 &&
                    section.median_aspect >= options.placement.flat_section_aspect;
  if (flat) first.placement.corner_twist_deg = options.placement.edge_corner_twist_deg;
  std::vector<Try> tries{{"none", {}, first}};
  nlohmann::json attempts = nlohmann::json::array();
  Decomposition best;
  int kept = 0;
  double seconds = 0.0;
  for (std::size_t i = 0; i < tries.size(); ++i) {
    const Try& t = tries[i];
    if (i > 0 && options.progress) options.progress("try " + std::to_string(i + 1) + " (" + t.change + ")");
    std::optional<Decomposition> d;
    try {
      if (same_lattice(lattice_options_of(t.options), prepared.options)) {
        d = decompose_attempt(muscle, query, sphere, prepared, landmarks, t.options, compute);
      } else {
        const PreparedLattice own = prepare_lattice(t.options);
        d = decompose_attempt(muscle, query, sphere, own, landmarks, t.options, compute);
      }
    } catch (const Error& e) {
      if (i == 0) throw;
      nlohmann::json failed = attempt_header(t.change, t.modes, t.options, landmarks.given());
      failed["status"] = "error";
      failed["error"] = e.what();
      attempts.push_back(std::move(failed));
      continue;
    }
    attempts.push_back(attempt_json(t.change, t.modes, t.options, d->report, landmarks.given()));
    seconds += d->report.seconds;
    if (i == 0) {
      best = std::move(*d);
      std::vector<std::string> modes = failure_modes(best.report.quality, options.tries);
      if (modes.empty() && best.report.quality.pass) modes = whole_check_modes(best.report.quality);
      if (options.tries.second_try && !modes.empty()) {
        SecondTry second = second_try(first, modes, landmarks.given());
        if (second.change.empty())
          attempts.back()["second_try"] = "none: no change addresses " + nlohmann::json(modes).dump();
        else
          tries.push_back({second.change, modes, std::move(second.options)});
      }
      continue;
    }
    // Uneven layers alone (a first try that passes): the evener of two that pass, unless its
    // segments leave the muscle farther.
    const CheckReport& a = d->report.quality;
    const CheckReport& b = best.report.quality;
    const bool evener = a.pass && b.pass && a.steps.layer_ratio < b.steps.layer_ratio &&
                        a.max_segment_excursion_relative <= b.max_segment_excursion_relative;
    // After a first try that passed decompose's check, the second only where it passes that check
    // too: where it fails fewer of the whole check's criteria, or as many and is evener.
    const std::size_t whole_a = failed_criteria(a, CheckOptions{}).size();
    const std::size_t whole_b = failed_criteria(b, CheckOptions{}).size();
    const bool keep = !b.pass  ? better_result(a, b)
                      : !a.pass ? false
                                : whole_a < whole_b || (whole_a == whole_b && evener);
    if (keep) {
      best = std::move(*d);
      kept = static_cast<int>(i);
    }
  }
  best.report.attempts = std::move(attempts);
  best.report.kept_attempt = kept;
  best.report.cross_section = {{"median_aspect", section.median_aspect},
                               {"aspects", section.aspects},
                               {"flat_section_aspect", options.placement.flat_section_aspect},
                               {"flat", flat}};
  best.report.query_seconds = query_seconds;
  best.report.sphere_seconds = sphere.seconds;
  best.report.seconds = setup_seconds + seconds;
  return best;
}

}  // namespace fascicle
