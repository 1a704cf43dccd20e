#include "fibres/decompose.h"

#include "fibres/fibre_grid.h"
#include "geometry/errors.h"
#include "geometry/mesh_stats.h"
#include "morph/sphere_locator.h"
#include "morph/surface_query.h"

#include <Eigen/SVD>
#include <algorithm>
#include <chrono>
#include <unordered_map>
#include <tuple>
#include <cmath>

#ifdef FASCICLE_HAVE_SHADERS
#include "shaders/gl_context.h"
#include "shaders/gpu_settle.h"
#endif

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
    const Vec3 t = template_positions[static_cast<std::size_t>(s.b)] - template_positions[static_cast<std::size_t>(s.a)];
    const Vec3 h = fitted[static_cast<std::size_t>(s.b)] - fitted[static_cast<std::size_t>(s.a)];
    cross += h * t.transpose();
    gram += t * t.transpose();
  }
  const Eigen::Matrix3d linear = cross * gram.inverse();
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(linear, Eigen::ComputeFullU | Eigen::ComputeFullV);
  const Eigen::Matrix3d stretch = svd.matrixV() * svd.singularValues().asDiagonal() * svd.matrixV().transpose();
  double shortest = 1e300;
  for (springs::Spring& s : system.springs) {
    const Vec3 t = template_positions[static_cast<std::size_t>(s.b)] - template_positions[static_cast<std::size_t>(s.a)];
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

// Mean length of the springs at each point (its local lattice spacing).
std::vector<double> local_spacing(const springs::SpringSystem& system) {
  std::vector<double> sum(system.positions.size(), 0.0), count(system.positions.size(), 0.0);
  for (const springs::Spring& s : system.springs) {
    const double l = (system.positions[static_cast<std::size_t>(s.a)] - system.positions[static_cast<std::size_t>(s.b)]).norm();
    sum[static_cast<std::size_t>(s.a)] += l;
    sum[static_cast<std::size_t>(s.b)] += l;
    count[static_cast<std::size_t>(s.a)] += 1.0;
    count[static_cast<std::size_t>(s.b)] += 1.0;
  }
  for (std::size_t i = 0; i < sum.size(); ++i) sum[i] = count[i] > 0.0 ? sum[i] / count[i] : 0.0;
  return sum;
}

std::vector<int> outside_free_points(const springs::SpringSystem& system, const SurfaceQuery& query) {
  std::vector<int> out;
  for (std::size_t q = 0; q < system.positions.size(); ++q)
    if (!system.fixed[q] && query.side(system.positions[q]) != Side::inside) out.push_back(static_cast<int>(q));
  return out;
}

// The tetrahedra of all lattice cells, split as the quality check splits them (fibres/fibre_check.h:
// six Kuhn tetrahedra a cell around its diagonal (i,j,k)-(i+1,j+1,k+1)), oriented like the total
// volume of the output fibres' cells at `x`. Counted: the cells between output fibres (interior
// lattice lines), which the check counts; the cells against the surface ring are in the energy
// only (keeping them positive keeps the interior inside the ring). Reference shape of a cell in
// layer k: a box with the mean edge lengths along r, s and t of that layer's interior cells.
std::vector<UntangleTet> lattice_cell_tets(const springs::Lattice& lattice, const std::vector<Vec3>& x) {
  static const int perms[6][3] = {{0, 1, 2}, {1, 2, 0}, {2, 0, 1}, {0, 2, 1}, {2, 1, 0}, {1, 0, 2}};
  static const bool odd[6] = {false, false, false, true, true, true};
  auto at = [&](int i, int j, int k) { return lattice.index(i, j, k); };
  auto len = [&](int a, int b) { return (x[static_cast<std::size_t>(a)] - x[static_cast<std::size_t>(b)]).norm(); };
  std::vector<UntangleTet> tets;
  double total = 0.0;
  for (int k = 0; k + 1 < lattice.nz; ++k) {
    double hr = 0.0, hs = 0.0, ht = 0.0;
    int nr = 0, ns = 0, nt = 0;
    for (int c = 0; c < 2; ++c)
      for (int j = 1; j + 1 < lattice.ny; ++j)
        for (int i = 1; i + 1 < lattice.nx; ++i) {
          if (i + 2 < lattice.nx) hr += len(at(i, j, k + c), at(i + 1, j, k + c)), ++nr;
          if (j + 2 < lattice.ny) hs += len(at(i, j, k + c), at(i, j + 1, k + c)), ++ns;
          if (c == 0) ht += len(at(i, j, k), at(i, j, k + 1)), ++nt;
        }
    const Vec3 h(nr ? hr / nr : 1.0, ns ? hs / ns : 1.0, nt ? ht / nt : 1.0);
    if (!(h.minCoeff() > 0.0)) continue;
    for (int j = 0; j + 1 < lattice.ny; ++j)
      for (int i = 0; i + 1 < lattice.nx; ++i) {
        const bool counted = i >= 1 && j >= 1 && i + 2 < lattice.nx && j + 2 < lattice.ny;
        int corner_index[8];
        Vec3 corner_box[8];
        for (int q = 0; q < 8; ++q) {
          const int a = q & 1, b = (q >> 1) & 1, c = (q >> 2) & 1;
          corner_index[q] = at(i + a, j + b, k + c);
          corner_box[q] = Vec3(a * h.x(), b * h.y(), c * h.z());
        }
        for (int t = 0; t < 6; ++t) {
          UntangleTet tet;
          tet.counted = counted;
          tet.eps_floor = counted ? 0.0 : 0.5;
          int corner = 0;
          std::array<int, 4> local{0, 0, 0, 0};
          for (int step = 0; step < 3; ++step) {
            corner |= 1 << perms[t][step];
            local[static_cast<std::size_t>(step) + 1] = corner;
          }
          if (odd[t]) std::swap(local[2], local[3]);
          Eigen::Matrix3d s, d;
          for (int col = 0; col < 3; ++col) {
            s.col(col) = corner_box[local[static_cast<std::size_t>(col) + 1]] - corner_box[local[0]];
            d.col(col) = x[static_cast<std::size_t>(corner_index[local[static_cast<std::size_t>(col) + 1]])] -
                         x[static_cast<std::size_t>(corner_index[local[0]])];
          }
          for (int v = 0; v < 4; ++v) tet.v[static_cast<std::size_t>(v)] = corner_index[local[static_cast<std::size_t>(v)]];
          tet.reference_inverse = s.inverse();
          if (counted) total += d.determinant();
          tets.push_back(tet);
        }
      }
  }
  if (total < 0.0) {
    // The lattice lies mirrored in the muscle: orient every tetrahedron (and its reference) the
    // other way.
    const Eigen::Matrix3d mirror = Eigen::Vector3d(-1.0, 1.0, 1.0).asDiagonal();
    for (UntangleTet& tet : tets) tet.reference_inverse = tet.reference_inverse * mirror;
  }
  // A tetrahedron in good shape keeps its own settled shape as the reference, so that the
  // untangling energy is least where the settle left the lattice and changes it only around
  // the folds: good = det J > 0.2 and shape distortion tr(J^T J) / (3 det^(2/3)) < 2 against the
  // layer's box (the same orientation, so an inverted tetrahedron never becomes a reference).
  for (UntangleTet& tet : tets) {
    Eigen::Matrix3d d;
    for (int col = 0; col < 3; ++col)
      d.col(col) = x[static_cast<std::size_t>(tet.v[static_cast<std::size_t>(col) + 1])] - x[static_cast<std::size_t>(tet.v[0])];
    const Eigen::Matrix3d j = d * tet.reference_inverse;
    const double det = j.determinant();
    if (!(det > 0.2)) continue;
    if (j.squaredNorm() / (3.0 * std::cbrt(det * det)) < 2.0) tet.reference_inverse = d.inverse();
  }
  return tets;
}

// First hit of the ray p + t d (t > 0) with the muscle surface (Moeller-Trumbore on every
// triangle whose box meets the box of the ray's first `reach` length units); false when none.
bool ray_hit(const TriangleMesh& mesh, const Vec3& p, const Vec3& d, double reach, Vec3& hit) {
  double best = reach;
  bool found = false;
  const Vec3 q = p + reach * d;
  const Vec3 lo = p.cwiseMin(q), hi = p.cwiseMax(q);
  for (const Triangle& t : mesh.triangles) {
    const Vec3& a = mesh.positions[t[0]];
    const Vec3& b = mesh.positions[t[1]];
    const Vec3& c = mesh.positions[t[2]];
    if ((a.cwiseMax(b).cwiseMax(c) - lo).minCoeff() < 0.0 || (hi - a.cwiseMin(b).cwiseMin(c)).minCoeff() < 0.0) continue;
    const Vec3 e1 = b - a, e2 = c - a, h = d.cross(e2);
    const double det = e1.dot(h);
    if (std::abs(det) < 1e-300) continue;
    const Vec3 s = p - a;
    const double u = s.dot(h) / det;
    if (u < 0.0 || u > 1.0) continue;
    const Vec3 qv = s.cross(e1);
    const double v = d.dot(qv) / det;
    if (v < 0.0 || u + v > 1.0) continue;
    const double t_hit = e2.dot(qv) / det;
    if (t_hit > 0.0 && t_hit < best) {
      best = t_hit;
      found = true;
    }
  }
  if (found) hit = p + best * d;
  return found;
}

// The fibre ends of each attachment face, rebuilt under the layer of points next to it: that
// layer (its inner points) is shrunk towards its centroid by a factor lambda and cast onto the
// surface along the end axis (from the second layer's centroid through the first's). Seen along
// the axis the face is then a scaled copy of the layer above it, so the end layer of cells are
// frustums of that layer's cells and do not fold, whatever the sphere map did near the region
// centre. lambda starts at 1 and shrinks by 0.8 until every end lies within `radius` of an
// attachment-area point (at most 20 times; the ends stay where they were when no lambda fits).
nlohmann::json cast_faces(springs::SpringSystem& system, const springs::Lattice& lattice, const TriangleMesh& muscle,
                          const Attachments& areas, double radius) {
  nlohmann::json out = nlohmann::json::array();
  const double reach = 4.0 * (bounding_box(muscle.positions).diagonal() + 1e-300);
  for (const auto& [k_end, k1, k2, area] :
       {std::tuple<int, int, int, const AttachmentArea*>{0, 1, 2, &areas.origin},
        std::tuple<int, int, int, const AttachmentArea*>{lattice.nz - 1, lattice.nz - 2, lattice.nz - 3, &areas.insertion}}) {
    if (k2 < 0 || k2 >= lattice.nz || k1 == k_end) continue;
    auto at = [&](int i, int j, int k) -> Vec3& { return system.positions[static_cast<std::size_t>(lattice.index(i, j, k))]; };
    Vec3 c1 = Vec3::Zero(), c2 = Vec3::Zero();
    int count = 0;
    for (int j = 1; j + 1 < lattice.ny; ++j)
      for (int i = 1; i + 1 < lattice.nx; ++i) c1 += at(i, j, k1), c2 += at(i, j, k2), ++count;
    c1 /= count;
    c2 /= count;
    const Vec3 axis = (c1 - c2).normalized();
    if (!axis.allFinite()) continue;
    double lambda = 1.0;
    bool placed = false;
    std::vector<Vec3> ends;
    for (int attempt = 0; attempt < 20 && !placed; ++attempt, lambda *= 0.8) {
      ends.clear();
      placed = true;
      for (int j = 1; j + 1 < lattice.ny && placed; ++j)
        for (int i = 1; i + 1 < lattice.nx && placed; ++i) {
          const Vec3 start = c1 + lambda * (at(i, j, k1) - c1);
          Vec3 hit;
          if (!ray_hit(muscle, start, axis, reach, hit)) {
            placed = false;
            break;
          }
          double nearest = 1e300;
          for (const SurfacePoint& p : area->points) nearest = std::min(nearest, (p.position - hit).squaredNorm());
          if (nearest > radius * radius) placed = false;
          ends.push_back(hit);
        }
    }
    if (placed) {
      lambda /= 0.8;
      std::size_t n = 0;
      for (int j = 1; j + 1 < lattice.ny; ++j)
        for (int i = 1; i + 1 < lattice.nx; ++i) at(i, j, k_end) = ends[n++];
    }
    out.push_back({{"face", k_end == 0 ? "origin" : "insertion"}, {"cast", placed}, {"shrink", placed ? lambda : 0.0}});
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
  return s;
}

void DecomposeOptions::validate() const {
  repair.validate();
  sphere.validate();
  attachments.validate();
  placement.validate();
  settle.validate();
  untangle.validate();
  if (!(end_shift >= 0.0 && end_shift < 1.0))
    throw OptionError("end_shift: must be in [0, 1), got " + std::to_string(end_shift));
  if (!(end_anchor_weight > 0.0 && end_anchor_weight < 1e12))
    throw OptionError("end_anchor_weight: must be in (0, 1e12), got " + std::to_string(end_anchor_weight));
  if (untangle_iterations < 0 || untangle_iterations > 10'000'000)
    throw OptionError("untangle_iterations: must be in 0..10000000, got " + std::to_string(untangle_iterations));
  // Decompose's own cap on the fibre count (below the lattice's), then the lattice's checks of
  // fibres, resolution and their product.
  if (fibres > 1'000'000) throw OptionError("fibres: at most 1000000, got " + std::to_string(fibres));
  springs::LatticeOptions lattice;
  lattice.kind = kind;
  lattice.fibres = fibres;
  lattice.resolution = resolution;
  lattice.model = model;
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
  if (smooth_steps < 0 || smooth_steps > 100'000)
    throw OptionError("smooth: must be in 0..100000 steps, got " + std::to_string(smooth_steps));
  if (!(smooth_weight > 0.0 && smooth_weight <= 1.0))
    throw OptionError("smooth-weight: must be in (0, 1], got " + std::to_string(smooth_weight));
}

nlohmann::json DecomposeReport::to_json() const {
  nlohmann::json j;
  j["status"] = status;
  if (!failure.empty()) j["failure"] = failure;
  j["repair"] = repair;
  j["sphere"] = sphere;
  j["attachments"] = attachments;
  j["placement"] = placement;
  j["lattice"] = lattice;
  j["settle"] = settle;
  j["containment"] = containment;
  j["untangle"] = untangle;
  j["smoothing"] = smoothing;
  j["quality"] = quality.to_json();
  j["renderer"] = renderer;
  j["seconds"] = {{"repair", repair_seconds},   {"sphere", sphere_seconds}, {"placement", placement_seconds},
                  {"settle", settle_seconds},   {"check", check_seconds},   {"total", seconds}};
  return j;
}

Decomposition decompose(const PolygonSoup& soup, const Landmarks& landmarks, const DecomposeOptions& options) {
  options.validate();
  const auto start = Clock::now();
  RepairResult repaired = repair_mesh(soup, options.repair);
  const double repair_seconds = since(start);
  Decomposition out = decompose_repaired(repaired.mesh, landmarks, options);
  out.report.repair = repaired.report.to_json();
  out.report.repair_seconds = repair_seconds;
  out.report.seconds += repair_seconds;
  return out;
}

Decomposition decompose_repaired(const TriangleMesh& muscle, const Landmarks& landmarks,
                                 const DecomposeOptions& options) {
  options.validate();
  const auto start = Clock::now();
  Decomposition out;
  out.muscle = muscle;
  DecomposeReport& report = out.report;

  // Attachment areas.
  Attachments areas;
  if (landmarks.given()) {
    if (landmarks.origin.empty() || landmarks.insertion.empty())
      throw OptionError("landmarks: give both an origin and an insertion file, or neither (automatic areas)");
    areas = landmark_attachments(muscle, landmarks.origin, landmarks.origin_source, landmarks.insertion,
                                 landmarks.insertion_source, options.attachments);
  } else {
    areas = automatic_attachments(muscle, options.attachments);
  }
  report.attachments = {{"automatic", areas.automatic},
                        {"origin", {{"source", areas.origin.source},
                                    {"points", areas.origin.points.size()},
                                    {"max_distance", areas.origin.max_distance}}},
                        {"insertion", {{"source", areas.insertion.source},
                                       {"points", areas.insertion.points.size()},
                                       {"max_distance", areas.insertion.max_distance}}}};

  // Sphere map of the muscle.
  auto stage = Clock::now();
  const SphereMap map = map_to_sphere(muscle, options.sphere);
  report.sphere = map.report.to_json();
  if (!map.report.quality.bijective())
    throw SolverError("sphere map: not a bijection (" + map.report.failure + "); try --sphere-method " +
                      std::string(map.report.method == "tutte" ? "relax" : "tutte"));
  const SphereLocator locator(map.positions, muscle.triangles);
  report.sphere_seconds = since(stage);

  // Template lattice with a ring of surface lines, placed on the muscle.
  stage = Clock::now();
  const auto split = springs::near_square_split(options.fibres);
  springs::LatticeOptions lattice_options;
  lattice_options.kind = options.kind;
  lattice_options.nr = split[0] + 2;
  lattice_options.ns = split[1] + 2;
  lattice_options.resolution = options.resolution;
  lattice_options.model = options.model;
  const springs::Lattice lattice = springs::build_lattice(lattice_options);
  const Placement placement = place_template(muscle, map.positions, locator, areas, lattice, options.placement);
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
  stage = Clock::now();
  springs::SpringSystem system = lattice.system;
  const std::vector<Vec3> template_positions = system.positions;
  for (std::size_t q = 0; q < system.positions.size(); ++q)
    if (system.fixed[q]) system.positions[q] = placement.points[q].position;
  const springs::LatticeShape shape = springs::shape_of(lattice);
  const SurfaceQuery query(muscle);
  {
    springs::SpringSystem harmonic = system;
    for (springs::Spring& s : harmonic.springs) s.rest = 0.0;
    springs::SettleOptions linear;
    linear.solver = springs::SolverKind::static_equilibrium;
    linear.static_method = springs::StaticMethod::local_global;
    linear.acceleration = springs::Acceleration::none;
    linear.tolerance = 1e-12;
    linear.max_iterations = 4;
    const springs::SettleReport first = springs::settle(harmonic, linear);
    report.settle["harmonic"] = settle_json(first);
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
    const Vec3 p = system.positions[static_cast<std::size_t>(q)];
    const SurfacePoint c = query.closest_point(p);
    Vec3 inward = c.position - p;
    if (inward.norm() == 0.0) {
      // On the surface: go towards the muscle's centre of mass of the lattice neighbours.
      inward = Vec3::Zero();
      for (const springs::Spring& s : system.springs) {
        if (s.a == q) inward += system.positions[static_cast<std::size_t>(s.b)] - p;
        if (s.b == q) inward += system.positions[static_cast<std::size_t>(s.a)] - p;
      }
    }
    inward.normalize();
    double depth = options.contact_depth * spacing[static_cast<std::size_t>(q)];
    Vec3 moved = c.position + depth * inward;
    for (int attempt = 0; attempt < 6 && query.side(moved) != Side::inside; ++attempt) {
      depth *= 0.5;
      moved = c.position + depth * inward;
    }
    if (query.side(moved) == Side::inside) return moved;
    // Thin places, where the inward normal leaves through the other side: on the way from the
    // closest surface point to a lattice neighbour that is inside (nearest first).
    std::vector<std::pair<double, Vec3>> inside_neighbours;
    for (const springs::Spring& s : system.springs) {
      const int other = s.a == q ? s.b : s.b == q ? s.a : -1;
      if (other < 0 || other >= lattice.point_count()) continue;
      const Vec3& o = system.positions[static_cast<std::size_t>(other)];
      if (query.side(o) == Side::inside) inside_neighbours.emplace_back((o - p).norm(), o);
    }
    std::sort(inside_neighbours.begin(), inside_neighbours.end(),
              [](const auto& a, const auto& b) { return a.first < b.first; });
    for (const auto& [distance, o] : inside_neighbours)
      for (double t = 0.5; t > 1e-2; t *= 0.5) {
        const Vec3 candidate = o + t * (c.position - o);
        if (query.side(candidate) == Side::inside) return candidate;
      }
    return moved;
  };
  auto settle_with_contact = [&](const springs::SettleOptions& settle_options) {
    int soft = 0, local_rounds = 0;
    for (;;) {
      springs::SettleReport settled;
      if (options.backend == "gl") {
  #ifdef FASCICLE_HAVE_SHADERS
        const shaders::GlContext context;
        shaders::GpuSettleOptions gpu;
        const shaders::GpuSettleReport gpu_report = shaders::settle_gpu(context, system, settle_options, gpu,
                                                                               anchor_spring.empty() ? &shape : nullptr);
        report.renderer = gpu_report.renderer;
        settled = gpu_report;
  #else
        throw Error(ErrorCode::gpu, "backend: gl is not in this build (OpenGL, EGL or GLEW was not found when it "
                                    "was built); use --backend cpu");
  #endif
      } else {
        settled = springs::settle(system, settle_options, anchor_spring.empty() ? &shape : nullptr);
      }
      solves.push_back(settle_json(settled));
      outside = outside_free_points(system, query);
      if (outside.empty() || local_rounds == options.contact_rounds) break;
      ++local_rounds;
      ++rounds;
      const std::vector<double> spacing = local_spacing(system);
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
    casts.push_back(cast_faces(system, lattice, muscle, areas, end_radius));
    settle_with_contact(round + 1 < options.cast_rounds ? rough : options.settle);
  }
  // Untangling: the cells the settle left inverted are unfolded with the fixed points held; a
  // point that this moves outside is pinned just inside (as in the containment) and the
  // untangling repeated.
  if (options.untangle_cells) {
    const std::vector<UntangleTet> tets = lattice_cell_tets(lattice, system.positions);
    nlohmann::json runs = nlohmann::json::array();
    auto inverted_count = [&] {
      long n = 0;
      const std::vector<double> dets = tet_jacobian_dets(system.positions, tets);
      for (std::size_t t = 0; t < tets.size(); ++t) n += tets[t].counted && !(dets[t] > 0.0) ? 1 : 0;
      return n;
    };
    // One attempt: rounds of (local, then wider) untangling and soft containment. With
    // `free_ends` the fibre ends may give way too (into the muscle, or along the surface), held
    // by soft pins at the places the cast gave them: a cell against an end face can need that.
    int budget = options.untangle_iterations;
    const double length = muscle_length(muscle);
    auto attempt = [&](bool free_ends) {
      std::vector<UntangleAnchor> anchors;
      std::unordered_map<int, std::size_t> anchor_of;  // lattice point -> its anchor
      std::unordered_map<int, Vec3> cast_place;         // fibre end -> where the cast put it
      if (free_ends) {
        const std::vector<double> spacing = local_spacing(system);
        for (int k : {0, lattice.nz - 1})
          for (int j = 1; j + 1 < lattice.ny; ++j)
            for (int i = 1; i + 1 < lattice.nx; ++i) {
              const int q = lattice.index(i, j, k);
              const double h = spacing[static_cast<std::size_t>(q)];
              system.fixed[static_cast<std::size_t>(q)] = 0;
              anchor_of[q] = anchors.size();
              cast_place[q] = system.positions[static_cast<std::size_t>(q)];
              anchors.push_back({q, system.positions[static_cast<std::size_t>(q)], options.end_anchor_weight / (h * h)});
            }
      }
      for (int round = 0;; ++round) {
        const std::size_t runs_before = runs.size();
        // Local first: only the points within `radius` lattice steps (Chebyshev) of an inverted
        // cell or an anchored point move, the rest of the settled lattice stays as it is; the
        // region grows while cells stay inverted, up to the whole lattice.
        for (int radius : {2, 6, 1 << 20}) {
          if (budget <= 0) break;
          const std::vector<double> dets = tet_jacobian_dets(system.positions, tets);
          std::vector<char> near(static_cast<std::size_t>(lattice.point_count()), 0);
          bool inverted = false;
          for (std::size_t t = 0; t < tets.size(); ++t) {
            if (!tets[t].counted || dets[t] > options.untangle.min_det) continue;
            inverted = true;
            for (int v : tets[t].v) near[static_cast<std::size_t>(v)] = 1;
          }
          if (!inverted && (radius > 2 || anchors.empty())) break;
          for (const UntangleAnchor& a : anchors) near[static_cast<std::size_t>(a.point)] = 1;
          const bool whole = radius >= std::max({lattice.nx, lattice.ny, lattice.nz});
          std::vector<char> local_fixed = system.fixed;
          if (!whole) {
            std::vector<char> region(near.size(), 0);
            for (int k = 0; k < lattice.nz; ++k)
              for (int j = 0; j < lattice.ny; ++j)
                for (int i = 0; i < lattice.nx; ++i) {
                  if (!near[static_cast<std::size_t>(lattice.index(i, j, k))]) continue;
                  for (int c = std::max(0, k - radius); c <= std::min(lattice.nz - 1, k + radius); ++c)
                    for (int b = std::max(0, j - radius); b <= std::min(lattice.ny - 1, j + radius); ++b)
                      for (int a = std::max(0, i - radius); a <= std::min(lattice.nx - 1, i + radius); ++a)
                        region[static_cast<std::size_t>(lattice.index(a, b, c))] = 1;
                }
            for (std::size_t q = 0; q < region.size(); ++q)
              if (!region[q]) local_fixed[q] = 1;
          }
          const UntangleReport untangled = untangle(system.positions, local_fixed, tets, options.untangle, anchors);
          nlohmann::json run = untangled.to_json();
          run["radius"] = whole ? -1 : radius;
          run["round"] = round;
          run["anchors"] = anchors.size();
          runs.push_back(run);
          budget -= untangled.iterations;
          if (untangled.untangled()) break;
        }
        outside = outside_free_points(system, query);
        if (runs.size() > runs_before) {
          runs.back()["outside"] = outside.size();
          runs.back()["free_ends"] = free_ends;
        }
        if (outside.empty() || round == options.contact_rounds || budget <= 0) break;
        // Containment: an outside point gets a soft pin just inside, 4x stronger each round.
        const std::vector<double> spacing = local_spacing(system);
        for (int q : outside) {
          const Vec3 target = contact_target(q, spacing);
          const auto it = anchor_of.find(q);
          if (it == anchor_of.end()) {
            const double h = spacing[static_cast<std::size_t>(q)];
            anchor_of[q] = anchors.size();
            anchors.push_back({q, target, 30.0 / (h * h)});
          } else {
            anchors[it->second].target = target;
            anchors[it->second].weight *= 4.0;
          }
        }
      }
      // The ends are fixed again, at most `end_shift` (a share of the muscle length) from their
      // cast places so that they stay on their attachment areas; one the untangling left outside
      // goes to the closest surface point.
      if (free_ends)
        for (int k : {0, lattice.nz - 1})
          for (int j = 1; j + 1 < lattice.ny; ++j)
            for (int i = 1; i + 1 < lattice.nx; ++i) {
              const int q = lattice.index(i, j, k);
              Vec3& x = system.positions[static_cast<std::size_t>(q)];
              const Vec3 cast = cast_place.at(q);
              const double limit = options.end_shift * length;
              if ((x - cast).norm() > limit) x = cast + limit * (x - cast).normalized();
              if (query.side(x) == Side::outside) x = query.closest_point(x).position;
              system.fixed[static_cast<std::size_t>(q)] = 1;
            }
      return inverted_count();
    };
    // The ends free first; then, while cells stay inverted, on from there with the ends held,
    // and last from the settled lattice with the ends held (some lattices unfold only so); the
    // result with the fewest inverted cells stays. Each attempt has the whole iteration budget.
    const std::vector<Vec3> settled = system.positions;
    const std::vector<char> settled_fixed = system.fixed;
    long inverted_left = attempt(true);
    std::string kept = "free_ends";
    auto try_held = [&](const std::vector<Vec3>& from, const std::string& name) {
      if (inverted_left == 0) return;
      const std::vector<Vec3> best = system.positions;
      const long best_inverted = inverted_left;
      system.positions = from;
      system.fixed = settled_fixed;
      budget = options.untangle_iterations;
      inverted_left = attempt(false);
      if (inverted_left >= best_inverted) {
        system.positions = best;
        system.fixed = settled_fixed;
        inverted_left = best_inverted;
      } else {
        kept = name;
      }
    };
    try_held(system.positions, "free_then_held_ends");
    try_held(settled, "held_ends");
    runs.push_back({{"kept", kept}});
    outside = outside_free_points(system, query);
    // Last resort: points still outside are fixed just inside (also fibre points the settle's
    // containment fixed at a place that was not inside: the fallback of contact_target).
    for (int k = 1; k + 1 < lattice.nz; ++k)
      for (int j = 1; j + 1 < lattice.ny; ++j)
        for (int i = 1; i + 1 < lattice.nx; ++i) {
          const int q = lattice.index(i, j, k);
          if (system.fixed[static_cast<std::size_t>(q)] && query.side(system.positions[static_cast<std::size_t>(q)]) != Side::inside)
            outside.push_back(q);
        }
    const std::vector<double> spacing = local_spacing(system);
    for (int q : outside) {
      system.positions[static_cast<std::size_t>(q)] = contact_target(q, spacing);
      system.fixed[static_cast<std::size_t>(q)] = 1;
      ++pinned;
    }
    outside = outside_free_points(system, query);
    report.untangle = {{"runs", runs}, {"inverted_left", inverted_left}, {"budget_left", budget}};
  }
  report.settle["cast_faces"] = casts;
  report.settle["solves"] = solves;
  report.containment = {{"rounds", rounds}, {"anchored_points", anchored}, {"pinned_points", pinned}, {"outside_after", outside.size()}};
  report.settle_seconds = since(stage);

  // Smoothing along fibres, free points only; a point the smoothing would move out stays.
  long reverted = 0;
  if (options.smooth_steps > 0) {
    const std::vector<Vec3> before = system.positions;
    const int plane = lattice.nx * lattice.ny;
    for (int step = 0; step < options.smooth_steps; ++step) {
      std::vector<Vec3> next = system.positions;
      for (int q = 0; q < lattice.point_count(); ++q) {
        const int k = q / plane;
        if (system.fixed[static_cast<std::size_t>(q)] || k == 0 || k == lattice.nz - 1) continue;
        const Vec3 mid = 0.5 * (system.positions[static_cast<std::size_t>(q - plane)] +
                                system.positions[static_cast<std::size_t>(q + plane)]);
        next[static_cast<std::size_t>(q)] =
            (1.0 - options.smooth_weight) * system.positions[static_cast<std::size_t>(q)] + options.smooth_weight * mid;
      }
      system.positions.swap(next);
    }
    for (int q : outside_free_points(system, query)) {
      system.positions[static_cast<std::size_t>(q)] = before[static_cast<std::size_t>(q)];
      ++reverted;
    }
  }
  report.smoothing = {{"steps", options.smooth_steps}, {"weight", options.smooth_weight}, {"reverted", reverted}};

  // Fibres: the interior lattice lines, origin (t = 0) to insertion.
  std::vector<std::vector<Vec3>> lines;
  std::vector<int> rs, ss;
  for (int j = 1; j + 1 < lattice.ny; ++j)
    for (int i = 1; i + 1 < lattice.nx; ++i) {
      std::vector<Vec3> line(static_cast<std::size_t>(lattice.nz));
      for (int k = 0; k < lattice.nz; ++k) line[static_cast<std::size_t>(k)] = system.positions[static_cast<std::size_t>(lattice.index(i, j, k))];
      lines.push_back(std::move(line));
      rs.push_back(i - 1);
      ss.push_back(j - 1);
    }
  out.fibres = lattice_fibres(std::move(lines), rs, ss);
  for (const auto& line : out.fibres.lines)
    for (const Vec3& p : line)
      if (!p.allFinite()) throw SolverError("decompose: a fibre point is not finite; check the settle options");

  // Check.
  stage = Clock::now();
  report.quality = check_fibres(out.fibres, muscle, query, areas, options.check);
  report.check_seconds = since(stage);
  report.status = report.quality.pass ? "ok" : "failed";
  if (!report.quality.pass) report.failure = "the fibres fail the quality check";
  report.seconds = since(start);
  return out;
}

}  // namespace fascicle
