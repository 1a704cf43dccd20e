// The repair pipeline (repair.h). Local repair on a CGAL Surface_mesh with Polygon Mesh
// Processing; the alpha-wrap fallback lives in alpha_wrap.cpp, the checks in mesh_checks.cpp.

#include "repair/repair.h"

#include "geometry/errors.h"
#include "geometry/mesh_stats.h"
#include "repair/clean_soup.h"
#include "repair/detail/alpha_wrap.h"
#include "repair/detail/checks.h"
#include "repair/weld_vertices.h"

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Polygon_mesh_processing/border.h>
#include <CGAL/Polygon_mesh_processing/connected_components.h>
#include <CGAL/Polygon_mesh_processing/manifoldness.h>
#include <CGAL/Polygon_mesh_processing/merge_border_vertices.h>
#include <CGAL/Polygon_mesh_processing/measure.h>
#include <CGAL/Polygon_mesh_processing/orient_polygon_soup.h>
#include <CGAL/Polygon_mesh_processing/polygon_soup_to_polygon_mesh.h>
#include <CGAL/Polygon_mesh_processing/repair_degeneracies.h>
#include <CGAL/Polygon_mesh_processing/repair_self_intersections.h>
#include <CGAL/Polygon_mesh_processing/self_intersections.h>
#include <CGAL/Polygon_mesh_processing/stitch_borders.h>
#include <CGAL/Polygon_mesh_processing/triangulate_hole.h>
#include <CGAL/Surface_mesh.h>

#include <spdlog/spdlog.h>

#include <chrono>
#include <cstring>
#include <cmath>
#include <functional>
#include <future>
#include <unordered_set>

namespace fascicle {

namespace {

using K = CGAL::Exact_predicates_inexact_constructions_kernel;
using Point = K::Point_3;
using Mesh = CGAL::Surface_mesh<Point>;
namespace PMP = CGAL::Polygon_mesh_processing;
using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

TriangleMesh from_cgal(Mesh& mesh) {
  mesh.collect_garbage();
  TriangleMesh out;
  out.positions.reserve(mesh.number_of_vertices());
  for (auto v : mesh.vertices()) {
    const Point& p = mesh.point(v);
    out.positions.emplace_back(p.x(), p.y(), p.z());
  }
  out.triangles.reserve(mesh.number_of_faces());
  for (auto f : mesh.faces()) {
    Triangle t{};
    int k = 0;
    for (auto v : CGAL::vertices_around_face(mesh.halfedge(f), mesh)) {
      if (k < 3) t[k] = static_cast<int>(v.idx());
      ++k;
    }
    FASCICLE_CHECK(k == 3, "repair produced a non-triangular face");
    out.triangles.push_back(t);
  }
  return out;
}

// Why local repair stopped short of a valid genus-0 mesh; carried to the wrap fallback.
struct NeedsWrap {
  std::string reason;
};

class RepairPipeline {
 public:
  RepairPipeline(const RepairOptions& options, RepairReport& report, double diagonal)
      : options_(options), report_(report), diagonal_(diagonal) {}

  // Runs `body` as a named step; it returns how many elements it changed.
  void step(const std::string& name, const std::function<long()>& body, const std::string& note = {}) {
    const auto t0 = Clock::now();
    const long changed = body();
    report_.steps.push_back({name, changed, seconds_since(t0), note});
    spdlog::debug("repair step {}: {} changed ({:.3f} s)", name, changed, report_.steps.back().seconds);
  }

  // Local repair of a cleaned triangle soup. Throws NeedsWrap when it cannot reach genus 0.
  TriangleMesh local_repair(const TriangleMesh& cleaned) {
    // Orient the soup; points at non-manifold spots are duplicated so it becomes a mesh.
    std::vector<Point> points;
    points.reserve(cleaned.positions.size());
    for (const Vec3& p : cleaned.positions) points.emplace_back(p.x(), p.y(), p.z());
    std::vector<std::vector<std::size_t>> polygons;
    polygons.reserve(cleaned.triangles.size());
    for (const Triangle& t : cleaned.triangles)
      polygons.push_back(
          {static_cast<std::size_t>(t[0]), static_cast<std::size_t>(t[1]), static_cast<std::size_t>(t[2])});
    bool already_oriented = false;
    step(
        "orient_soup",
        [&] {
          // A soup that already is an oriented 2-manifold (every clean export) is left as it is:
          // the orienter would change nothing, so neither it nor CGAL's soup test need run.
          already_oriented = detail::is_oriented_manifold_soup(cleaned);
          if (already_oriented) return 0L;
          const std::size_t before = points.size();
          PMP::orient_polygon_soup(points, polygons);
          return static_cast<long>(points.size() - before);
        },
        "points duplicated to split non-manifold vertices and edges");
    if (!already_oriented && !PMP::is_polygon_soup_a_polygon_mesh(polygons))
      throw NeedsWrap{"the oriented soup is not a polygon mesh"};

    Mesh mesh;
    PMP::polygon_soup_to_polygon_mesh(points, polygons, mesh);
    if (!CGAL::is_valid_polygon_mesh(mesh)) throw NeedsWrap{"the soup did not build a valid halfedge mesh"};

    step(
        "stitch_borders", [&] { return static_cast<long>(PMP::stitch_borders(mesh)); }, "pairs of border edges joined");
    step("merge_boundary_cycle_vertices", [&] {
      const long before = static_cast<long>(mesh.number_of_vertices());
      PMP::merge_duplicated_vertices_in_boundary_cycles(mesh);
      mesh.collect_garbage();
      return before - static_cast<long>(mesh.number_of_vertices());
    });
    step("split_non_manifold_vertices", [&] { return static_cast<long>(PMP::duplicate_non_manifold_vertices(mesh)); });
    if (!CGAL::is_valid_polygon_mesh(mesh)) throw NeedsWrap{"stitching left an invalid mesh"};

    keep_largest_component(mesh);

    step("remove_degenerate_faces", [&] {
      const long before = static_cast<long>(mesh.number_of_faces());
      PMP::remove_degenerate_faces(mesh);
      mesh.collect_garbage();
      return before - static_cast<long>(mesh.number_of_faces());
    });
    if (!CGAL::is_valid_polygon_mesh(mesh) || mesh.is_empty())
      throw NeedsWrap{"removing degenerate faces left an invalid mesh"};

    fill_holes(mesh);
    if (!CGAL::is_closed(mesh)) throw NeedsWrap{"some holes could not be filled"};

    remove_self_intersections(mesh);
    // Cutting out intersecting regions can split off pieces (a pinched fold, a touching shell).
    keep_largest_component(mesh);

    TriangleMesh out = from_cgal(mesh);
    step(
        "orient_outward",
        [&] {
          if (signed_volume(out) >= 0.0) return 0L;
          for (Triangle& t : out.triangles) std::swap(t[1], t[2]);
          return static_cast<long>(out.triangles.size());
        },
        "faces reversed so that normals point outward");
    return out;
  }

  // Alpha wrapping from coarse to fine: the coarsest level is tried first (fast, most likely
  // genus 0; if it is not, coarser alphas up to half the diagonal), then each finer level while
  // the wrap stays genus 0 and time is left. The finest genus-0 wrap is kept.
  TriangleMesh wrap(const TriangleMesh& cleaned, double diagonal) {
    const double area = surface_area(cleaned);
    const double finest = options_.wrap_alpha * diagonal;
    const std::string worker = detail::find_wrap_worker("");  // throws when missing
    const auto wrap_start = Clock::now();
    std::string last_failure;
    double last_wrap_seconds = 0.0;

    auto attempt = [&](double alpha) -> std::optional<TriangleMesh> {
      const double offset = alpha * options_.wrap_offset_ratio;
      // A wrap has about 20 A / alpha^2 faces (measured over the corpus, open sheets included);
      // skip alphas whose wrap would exceed the size budget rather than run for minutes.
      if (20.0 * area / (alpha * alpha) > static_cast<double>(options_.max_wrap_faces)) {
        last_failure = "wrap at alpha " + std::to_string(alpha) + " would exceed the face budget";
        return std::nullopt;
      }
      const double left = options_.wrap_seconds - seconds_since(wrap_start);
      if (left <= 0.0) {
        last_failure = "the wrap time budget (" + std::to_string(options_.wrap_seconds) + " s) is spent";
        return std::nullopt;
      }
      std::optional<TriangleMesh> result;
      step(
          "alpha_wrap",
          [&] {
            result = detail::alpha_wrap_with_time_limit(cleaned, alpha, offset, left, worker, options_.wrap_memory_mb);
            return result ? static_cast<long>(result->triangles.size()) : 0L;
          },
          "alpha " + std::to_string(alpha) + ", offset " + std::to_string(offset));
      last_wrap_seconds = report_.steps.back().seconds;
      const std::size_t wrap_step = report_.steps.size() - 1;
      if (!result) {
        report_.steps[wrap_step].note += ": stopped at the time budget";
        last_failure = "wrap at alpha " + std::to_string(alpha) + " ran past the time budget";
        return std::nullopt;
      }
      std::string failure;
      if (options_.components == ComponentPolicy::largest) {
        double share = 1.0;
        *result = largest_shell(*result, share);
        if (share < options_.min_largest_share)
          failure = "the wrap falls into separate shells and the largest holds only " +
                    std::to_string(static_cast<int>(std::round(share * 100))) + "% of the volume";
      }
      if (failure.empty()) failure = verify_genus0(*result);
      if (!failure.empty()) {
        last_failure = "wrap at alpha " + std::to_string(alpha) + ": " + failure;
        report_.steps[wrap_step].note += ": " + failure;
        spdlog::debug("{}", last_failure);
        return std::nullopt;
      }
      // A wrap coarse enough to bridge a real hole or handle strays far from the input: that
      // is not a repair of this mesh.
      const double stray = detail::one_sided_distance(*result, cleaned, 4000) / diagonal;
      if (stray > options_.wrap_max_distance) {
        last_failure = "wrap at alpha " + std::to_string(alpha) + " lies " + std::to_string(stray * 100.0) +
                       "% of the diagonal away from the input (it bridges a hole or handle)";
        report_.steps[wrap_step].note +=
            ": strays " + std::to_string(stray * 100.0) + "% of the diagonal from the input";
        spdlog::debug("{}", last_failure);
        return std::nullopt;
      }
      report_.steps[wrap_step].note += ": genus 0";
      return result;
    };

    std::optional<TriangleMesh> best;
    double best_alpha = 0.0;
    const double coarsest = finest * std::pow(2.0, options_.wrap_levels - 1);
    for (double alpha = coarsest; alpha >= finest * (1 - 1e-9); alpha /= 2.0) {
      if (best) {
        // Halving alpha makes about four times the faces and takes at least four times as long:
        // stop refining when that would not fit in what is left of the budget.
        if (4.0 * last_wrap_seconds > options_.wrap_seconds - seconds_since(wrap_start)) {
          report_.steps.push_back(
              {"alpha_wrap_refinement_stopped", 0, 0.0, "finer levels skipped: they would not fit in the time budget"});
          break;
        }
      }
      std::optional<TriangleMesh> result = attempt(alpha);
      if (result) {
        best = std::move(result);
        best_alpha = alpha;
      } else if (best || seconds_since(wrap_start) >= options_.wrap_seconds) {
        break;  // a finer wrap opens a handle or runs out of budget: keep the last good one
      }
    }
    // Not even the coarsest level is genus 0: coarser alphas, up to half the diagonal.
    for (double alpha = 2.0 * coarsest; !best && alpha <= 0.5 * diagonal * (1 + 1e-9); alpha *= 2.0) {
      best = attempt(alpha);
      best_alpha = alpha;
      if (!best && seconds_since(wrap_start) >= options_.wrap_seconds) break;
    }
    if (!best)
      throw TopologyError("cannot bring the mesh to a closed genus-0 surface: " + last_failure,
                          ErrorCode::repair_failed);
    report_.fallback_used = true;
    report_.wrap_alpha = best_alpha;
    report_.wrap_offset = best_alpha * options_.wrap_offset_ratio;
    report_.wrap_worker = worker;
    return std::move(*best);
  }

 private:
  void keep_largest_component(Mesh& mesh) {
    auto fcc = mesh.add_property_map<Mesh::Face_index, std::size_t>("f:cc", 0).first;
    const std::size_t count = PMP::connected_components(mesh, fcc);
    if (count <= 1) {
      report_.steps.push_back({"keep_largest_component", 0, 0.0, "one component"});
      mesh.remove_property_map(fcc);
      return;
    }
    if (options_.components == ComponentPolicy::merge) throw NeedsWrap{std::to_string(count) + " components to merge"};
    const auto t0 = Clock::now();
    std::vector<double> area(count, 0.0);
    double total = 0.0;
    for (auto f : mesh.faces()) {
      const double a = PMP::face_area(f, mesh);
      area[fcc[f]] += a;
      total += a;
    }
    const std::size_t largest = static_cast<std::size_t>(std::max_element(area.begin(), area.end()) - area.begin());
    const double share = total > 0.0 ? area[largest] / total : 0.0;
    if (share < options_.min_largest_share)
      throw NeedsWrap{"the mesh is in " + std::to_string(count) + " pieces and the largest holds only " +
                      std::to_string(static_cast<int>(std::round(share * 100))) + "% of the area"};
    const long before = static_cast<long>(mesh.number_of_faces());
    for (auto f : mesh.faces()) {
      if (fcc[f] == largest) continue;
      std::array<Vec3, 3> corners;
      int k = 0;
      for (auto v : CGAL::vertices_around_face(mesh.halfedge(f), mesh)) {
        const Point& p = mesh.point(v);
        if (k < 3) corners[k++] = Vec3(p.x(), p.y(), p.z());
      }
      dropped_.push_back(corners);
    }
    std::vector<std::size_t> keep{largest};
    PMP::keep_connected_components(mesh, keep, fcc);
    mesh.remove_property_map(fcc);
    mesh.collect_garbage();
    report_.steps.push_back({"keep_largest_component", before - static_cast<long>(mesh.number_of_faces()),
                             seconds_since(t0),
                             std::to_string(count - 1) + " smaller components removed (faces counted)"});
  }

  void fill_holes(Mesh& mesh) {
    step(
        "fill_holes",
        [&] {
          std::vector<Mesh::Halfedge_index> cycles;
          PMP::extract_boundary_cycles(mesh, std::back_inserter(cycles));
          long added = 0;
          for (auto h : cycles) {
            std::vector<Mesh::Face_index> patch;
            std::vector<Mesh::Vertex_index> new_vertices;
            if (options_.fair_holes) {
              PMP::triangulate_refine_and_fair_hole(mesh, h, std::back_inserter(patch),
                                                    std::back_inserter(new_vertices));
            } else {
              PMP::triangulate_hole(mesh, h, std::back_inserter(patch));
            }
            added += static_cast<long>(patch.size());
          }
          return added;
        },
        "faces added to close holes");
  }

  void remove_self_intersections(Mesh& mesh) {
    const auto t0 = Clock::now();
    const bool intersecting = PMP::does_self_intersect<CGAL::Parallel_if_available_tag>(mesh);
    if (!intersecting) {
      report_.steps.push_back({"remove_self_intersections", 0, seconds_since(t0), "none found"});
      return;
    }
    // CT folds are mostly crumpled surface: first untangle them by smoothing the vertices of the
    // intersecting faces towards their neighbours' centroid (a small, local move), and only where
    // that fails cut the region out and refill it (PMP::experimental::remove_self_intersections).
    step(
        "untangle_self_intersections", [&] { return untangle_by_smoothing(mesh); }, "vertices smoothed to undo folds");
    if (!PMP::does_self_intersect<CGAL::Parallel_if_available_tag>(mesh)) return;
    const TriangleMesh before_cut = from_cgal(mesh);
    step(
        "remove_self_intersections",
        [&] {
          std::vector<std::pair<Mesh::Face_index, Mesh::Face_index>> pairs;
          PMP::self_intersections<CGAL::Parallel_if_available_tag>(mesh, std::back_inserter(pairs));
          const long before = static_cast<long>(pairs.size());
          PMP::experimental::remove_self_intersections(mesh, PMP::parameters::preserve_genus(false));
          mesh.collect_garbage();
          pairs.clear();
          PMP::self_intersections<CGAL::Parallel_if_available_tag>(mesh, std::back_inserter(pairs));
          return before - static_cast<long>(pairs.size());
        },
        "intersecting face pairs resolved by removing and refilling their region");
    if (!CGAL::is_valid_polygon_mesh(mesh) || !CGAL::is_closed(mesh))
      throw NeedsWrap{"removing self-intersections left an open or invalid mesh"};
    if (PMP::does_self_intersect<CGAL::Parallel_if_available_tag>(mesh))
      throw NeedsWrap{"self-intersections remain after local repair"};
    // Where faces intersect nearly everywhere (a folded surface) the cut-out regions join up and
    // the refill replaces most of the surface by a few patches: a result that the surface before
    // the cut does not lie on is no repair of it (the same limit as a wrap's), so it is wrapped.
    const double deviation = detail::one_sided_distance(before_cut, from_cgal(mesh), 4000) / diagonal_;
    if (deviation > options_.wrap_max_distance)
      throw NeedsWrap{"refilling the self-intersecting regions moved the surface " +
                      std::to_string(deviation * 100.0) + "% of the diagonal away from the input"};
  }

  // Laplacian smoothing restricted to the neighbourhood of intersecting faces; the neighbourhood
  // grows by one ring every few rounds. Returns the number of vertices moved (0 when it gave up
  // and restored the original positions).
  long untangle_by_smoothing(Mesh& mesh) {
    constexpr int kRounds = 12;
    std::vector<std::pair<Mesh::Vertex_index, Point>> original;
    std::unordered_set<std::uint32_t> moved;
    for (int round = 0; round < kRounds; ++round) {
      std::vector<std::pair<Mesh::Face_index, Mesh::Face_index>> pairs;
      PMP::self_intersections<CGAL::Parallel_if_available_tag>(mesh, std::back_inserter(pairs));
      if (pairs.empty()) break;
      std::unordered_set<std::uint32_t> region;
      for (const auto& [f, g] : pairs)
        for (auto face : {f, g})
          for (auto v : CGAL::vertices_around_face(mesh.halfedge(face), mesh)) region.insert(v.idx());
      for (int ring = 0; ring < 1 + round / 4; ++ring) {
        std::vector<std::uint32_t> grow(region.begin(), region.end());
        for (auto vi : grow)
          for (auto w : CGAL::vertices_around_target(mesh.halfedge(Mesh::Vertex_index(vi)), mesh))
            region.insert(w.idx());
      }
      std::vector<std::pair<Mesh::Vertex_index, Point>> update;
      for (auto vi : region) {
        const Mesh::Vertex_index v(vi);
        double x = 0, y = 0, z = 0;
        int n = 0;
        for (auto w : CGAL::vertices_around_target(mesh.halfedge(v), mesh)) {
          const Point& q = mesh.point(w);
          x += q.x(), y += q.y(), z += q.z(), ++n;
        }
        if (n == 0) continue;
        const Point& p = mesh.point(v);
        update.emplace_back(v, Point(0.5 * p.x() + 0.5 * x / n, 0.5 * p.y() + 0.5 * y / n, 0.5 * p.z() + 0.5 * z / n));
      }
      for (const auto& [v, p] : update) {
        if (moved.insert(v.idx()).second) original.emplace_back(v, mesh.point(v));
        mesh.point(v) = p;
      }
    }
    // Accept only an untangling that stayed local: no vertex moved farther than
    // untangle_limit of the diagonal (a deep fold is better cut out than smeared).
    double farthest = 0.0;
    for (const auto& [v, p] : original)
      farthest = std::max(farthest, std::sqrt(CGAL::squared_distance(p, mesh.point(v))));
    if (farthest <= options_.untangle_limit * diagonal_ &&
        !PMP::does_self_intersect<CGAL::Parallel_if_available_tag>(mesh))
      return static_cast<long>(moved.size());
    for (const auto& [v, p] : original) mesh.point(v) = p;  // give up: leave it to the cut-and-fill
    return 0;
  }

  // The largest shell of a wrap by |volume| (a wrap of scattered pieces gives several shells).
  TriangleMesh largest_shell(const TriangleMesh& wrapped, double& share) {
    share = 1.0;
    const int n = static_cast<int>(wrapped.positions.size());
    std::vector<int> parent(n);
    std::iota(parent.begin(), parent.end(), 0);
    auto find = [&](int a) {
      while (parent[a] != a) a = parent[a] = parent[parent[a]];
      return a;
    };
    for (const Triangle& t : wrapped.triangles) {
      parent[find(t[1])] = find(t[0]);
      parent[find(t[2])] = find(t[0]);
    }
    std::unordered_map<int, TriangleMesh> shells;
    for (const Triangle& t : wrapped.triangles) shells[find(t[0])].triangles.push_back(t);
    if (shells.size() <= 1) return wrapped;
    double best = -1.0, total = 0.0;
    TriangleMesh result;
    for (auto& [root, shell] : shells) {
      shell.positions = wrapped.positions;
      const double v = std::abs(signed_volume(shell));
      total += v;
      if (v > best) best = v, result = std::move(shell);
    }
    share = total > 0.0 ? best / total : 0.0;
    // Compact the points.
    std::vector<int> index(n, -1);
    TriangleMesh compact;
    for (Triangle t : result.triangles) {
      for (int& v : t) {
        if (index[v] < 0)
          index[v] = static_cast<int>(compact.positions.size()), compact.positions.push_back(wrapped.positions[v]);
        v = index[v];
      }
      compact.triangles.push_back(t);
    }
    report_.steps.push_back({"keep_largest_shell",
                             static_cast<long>(wrapped.triangles.size() - compact.triangles.size()), 0.0,
                             std::to_string(shells.size() - 1) + " smaller wrapped shells removed (faces counted)"});
    return compact;
  }

  const RepairOptions& options_;
  RepairReport& report_;
  double diagonal_;

 public:
  /// Corners of the faces dropped with smaller components (for the kept-part distance).
  std::vector<std::array<Vec3, 3>> dropped_;
};

// The input faces that the output stands for: `cleaned` minus the faces dropped with smaller
// components (matched by their corners' coordinates, which the pipeline never moves).
TriangleMesh kept_part(const TriangleMesh& cleaned, const std::vector<std::array<Vec3, 3>>& dropped) {
  if (dropped.empty()) return cleaned;
  std::unordered_set<std::string> gone;
  for (const auto& c : dropped) gone.insert(detail::face_key(c));
  TriangleMesh kept;
  kept.positions = cleaned.positions;
  for (const Triangle& t : cleaned.triangles)
    if (!gone.count(detail::face_key({cleaned.positions[t[0]], cleaned.positions[t[1]], cleaned.positions[t[2]]})))
      kept.triangles.push_back(t);
  return kept;
}

}  // namespace

RepairResult repair_mesh(const PolygonSoup& soup, const RepairOptions& options) {
  options.validate();
  const auto t0 = Clock::now();
  if (soup.polygons.empty() || soup.points.empty())
    throw InputError(ErrorCode::file_empty, "the mesh has no faces to repair");
  for (const Vec3& p : soup.points)
    if (!p.allFinite()) throw InputError(ErrorCode::bad_number, "the mesh has a non-finite coordinate");

  RepairResult result;
  RepairReport& report = result.report;
  const double diagonal = bounding_box(soup.points).diagonal();
  RepairPipeline pipeline(options, report, diagonal);
  // The input census (with its self-intersection count) runs beside the pipeline.
  std::future<MeshCensus> input_census = std::async(std::launch::async, [&soup] { return census_of(soup); });

  if (!(diagonal > 0.0)) throw TopologyError("all points coincide: nothing to repair", ErrorCode::repair_failed);

  WeldResult weld;
  pipeline.step(
      "weld_vertices",
      [&] {
        weld = weld_vertices(soup.points, options.weld_tolerance * diagonal);
        return weld.merged;
      },
      "points merged into a neighbour within the weld tolerance");
  TriangleMesh cleaned;
  CleanSoupCounts counts;
  pipeline.step("triangulate_polygons", [&] {
    cleaned = clean_soup(soup, weld.representative, &counts);
    return counts.polygons_triangulated;
  });
  report.steps.push_back({"remove_degenerate_index_faces", counts.degenerate_removed, 0.0,
                          "faces with fewer than three distinct corners"});
  report.steps.push_back({"remove_duplicate_faces", counts.duplicates_removed, 0.0, "faces repeating another face"});
  if (cleaned.triangles.empty())
    throw TopologyError("no face with three distinct corners remains: nothing to repair", ErrorCode::repair_failed);

  try {
    result.mesh = pipeline.local_repair(cleaned);
    // remove_self_intersections() left no intersecting pair, and what follows it only drops
    // whole components and flips faces: the test need not run again.
    const std::string failure = detail::verify_genus0(result.mesh, false);
    if (!failure.empty()) throw NeedsWrap{"local repair result: " + failure};
  } catch (const NeedsWrap& need) {
    report.fallback_reason = need.reason;
    spdlog::info("local repair cannot reach genus 0 ({}); falling back to alpha wrapping", need.reason);
    if (!options.allow_wrap)
      throw TopologyError("local repair cannot reach a closed genus-0 surface (" + need.reason +
                              "); alpha wrapping is disabled (--no-wrap)",
                          ErrorCode::repair_failed);
    result.mesh = pipeline.wrap(cleaned, diagonal);
  }

  const auto tv = Clock::now();
  // The output has no self-intersection (remove_self_intersections() or the wrap's own check saw
  // to it), so the census need not count again.
  report.output = detail::census_of_triangles(result.mesh, false);
  const TriangleMesh kept = report.fallback_used ? cleaned : kept_part(cleaned, pipeline.dropped_);
  // A result made of the kept input's own faces (welded, reoriented) lies at distance 0 exactly.
  auto distance_to = [&](const TriangleMesh& input) {
    return detail::same_faces(input, result.mesh)
               ? 0.0
               : detail::hausdorff_distance(input, result.mesh, options.hausdorff_samples) / diagonal;
  };
  report.hausdorff = distance_to(kept);
  report.hausdorff_whole_input =
      pipeline.dropped_.empty() || report.fallback_used ? report.hausdorff : distance_to(cleaned);
  report.input = input_census.get();
  report.kept_area_share = report.input.area > 0.0 ? report.output.area / report.input.area : 0.0;
  report.steps.push_back({"verify", 0, seconds_since(tv), "census of the output and Hausdorff distance"});
  long changed = 0;
  for (const RepairStep& s : report.steps) changed += s.changed;
  report.status = report.fallback_used ? "wrapped" : changed == 0 ? "unchanged" : "repaired";
  report.seconds = seconds_since(t0);
  return result;
}

}  // namespace fascicle
