// Repair stage: each step on small meshes built in code with each defect injected, the
// verification, options, and the refusals.

#include "geometry/errors.h"
#include "geometry/inject_defects.h"
#include "geometry/mesh_stats.h"
#include "geometry/primitives.h"
#include "geometry/sample_muscle.h"
#include "repair/clean_soup.h"
#include "repair/detail/checks.h"
#include "repair/repair.h"
#include "repair/simplify_mesh.h"
#include "repair/weld_vertices.h"

#include <catch2/catch.hpp>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <limits>

using namespace fascicle;

namespace {

// The repaired mesh must pass the verification and stay faithful to the clean shape.
void require_valid(const RepairResult& r) {
  INFO("verification: " << verify_genus0(r.mesh));
  REQUIRE(verify_genus0(r.mesh).empty());
  REQUIRE(r.report.output.components == 1);
  REQUIRE(r.report.output.boundary_edges == 0);
  REQUIRE(r.report.output.non_manifold_edges == 0);
  REQUIRE(r.report.output.genus.has_value());
  REQUIRE(*r.report.output.genus == 0);
  REQUIRE(r.report.output.self_intersections == 0);
  REQUIRE(r.report.output.volume > 0.0);
}

// Relative two-sided Hausdorff distance between the result and a reference shape.
double distance_to(const TriangleMesh& result, const TriangleMesh& reference) {
  return detail::hausdorff_distance(result, reference, 20000) / bounding_box(reference.positions).diagonal();
}

// Faithful: close to the (defective) input, or to the clean shape the defect was injected into
// (a filled hole or a dropped stray shell is far from the input but close to the clean shape).
// Defects that move geometry (a pinch glues two vertices mm apart, a fold pushes a vertex through
// the opposite side) leave intersecting faces that are cut out and refilled: `bound` 5 %.
void require_faithful(const RepairResult& r, const TriangleMesh& clean, double bound = 0.01) {
  const double to_clean = distance_to(r.mesh, clean);
  INFO("Hausdorff to input " << r.report.hausdorff << ", to the clean shape " << to_clean);
  CHECK(std::min(r.report.hausdorff, to_clean) < bound);
}

long step_changed(const RepairReport& report, const std::string& name) {
  long total = 0;
  for (const auto& s : report.steps)
    if (s.name.find(name) != std::string::npos) total += s.changed;
  return total;
}

}  // namespace

TEST_CASE("weld merges exact and near duplicates within tolerance only", "[repair]") {
  const std::vector<Vec3> pts = {Vec3(0, 0, 0), Vec3(0, 0, 0),        Vec3(1e-9, 0, 0),
                                 Vec3(1, 0, 0), Vec3(1 + 5e-7, 0, 0), Vec3(2, 0, 0)};
  const WeldResult exact = weld_vertices(pts, 0.0);
  CHECK(exact.merged == 1);
  CHECK(exact.representative[1] == 0);
  CHECK(exact.representative[2] == 2);
  const WeldResult near = weld_vertices(pts, 1e-6);
  CHECK(near.merged == 3);
  CHECK(near.representative[2] == 0);
  CHECK(near.representative[4] == 3);
  CHECK(near.representative[5] == 5);
  // Representatives keep their own position: the first point of each group.
  CHECK(near.representative[3] == 3);
}

TEST_CASE("exact welding treats signed zeros alike and never merges a NaN point", "[repair]") {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const std::vector<Vec3> pts = {Vec3(nan, 0, 0), Vec3(1, -0.0, 2), Vec3(nan, 0, 0),
                                 Vec3(1, 0.0, 2), Vec3(0, 0, 0),    Vec3(1, 0.0, 2)};
  const WeldResult exact = weld_vertices(pts, 0.0);
  CHECK(exact.merged == 2);
  CHECK(exact.representative[0] == 0);
  CHECK(exact.representative[2] == 2);
  CHECK(exact.representative[3] == 1);  // the lowest index of the group
  CHECK(exact.representative[5] == 1);
  CHECK(exact.representative[4] == 4);
}

TEST_CASE("clean_soup triangulates polygons and drops degenerate and duplicate faces", "[repair]") {
  PolygonSoup soup;
  soup.points = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(1, 1, 0), Vec3(0, 1, 0), Vec3(0.5, 0.5, 1), Vec3(5, 5, 5)};
  soup.polygons = {{0, 1, 2, 3}, {0, 1, 4}, {1, 0, 4}, {2, 2, 3}, {0, 1}, {3, 2, 4}};
  std::vector<int> identity(soup.points.size());
  for (std::size_t i = 0; i < identity.size(); ++i) identity[i] = static_cast<int>(i);
  CleanSoupCounts counts;
  const TriangleMesh mesh = clean_soup(soup, identity, &counts);
  CHECK(counts.polygons_triangulated == 1);
  CHECK(counts.duplicates_removed == 1);
  CHECK(counts.degenerate_removed == 2);
  CHECK(counts.unreferenced_removed == 1);
  CHECK(mesh.triangles.size() == 4);  // quad -> 2, one of the doubled pair, the last triangle
  CHECK(mesh.positions.size() == 5);
}

TEST_CASE("verify_genus0 accepts closed spheres and names what is wrong otherwise", "[repair]") {
  CHECK(verify_genus0(make_icosphere(2)).empty());
  CHECK(verify_genus0(make_cube(1.0, 3)).empty());
  CHECK(verify_genus0(make_torus(1.0, 0.3, 24, 12)).find("Euler characteristic 0") != std::string::npos);

  TriangleMesh open = make_icosphere(1);
  open.triangles.pop_back();
  CHECK(verify_genus0(open).find("boundary") != std::string::npos);

  TriangleMesh inward = make_icosphere(1);
  for (auto& t : inward.triangles) std::swap(t[1], t[2]);
  CHECK(verify_genus0(inward).find("volume") != std::string::npos);

  TriangleMesh two = make_icosphere(1);
  const TriangleMesh other = make_tetrahedron();
  const int base = static_cast<int>(two.positions.size());
  for (const Vec3& p : other.positions) two.positions.push_back(p + Vec3(5, 0, 0));
  for (Triangle t : other.triangles) two.triangles.push_back({t[0] + base, t[1] + base, t[2] + base});
  CHECK(verify_genus0(two).find("2 connected components") != std::string::npos);

  // Push one vertex of a sphere through the opposite side: closed, manifold, but intersecting.
  TriangleMesh folded = make_icosphere(2);
  folded.positions[0] = -1.5 * folded.positions[0];
  CHECK(!verify_genus0(folded).empty());
}

TEST_CASE("census of a soup counts non-manifold vertices, boundaries and components", "[repair]") {
  const MeshCensus pinched = census_of(make_two_tetrahedra_sharing_vertex());
  CHECK(pinched.components == 1);
  CHECK(pinched.non_manifold_vertices == 1);
  CHECK(pinched.boundary_edges == 0);
  CHECK_FALSE(pinched.genus.has_value());

  const MeshCensus sphere = census_of(to_soup(make_icosphere(2)));
  REQUIRE(sphere.genus.has_value());
  CHECK(*sphere.genus == 0);
  CHECK(sphere.euler == 2);
  CHECK(sphere.volume == Approx(4.0 / 3.0 * M_PI).epsilon(0.05));

  const MeshCensus torus = census_of(to_soup(make_torus(1.0, 0.3, 24, 12)));
  REQUIRE(torus.genus.has_value());
  CHECK(*torus.genus == 1);
}

TEST_CASE("a clean mesh passes through unchanged", "[repair]") {
  const TriangleMesh sphere = make_icosphere(3);
  const RepairResult r = repair_mesh(to_soup(sphere));
  require_valid(r);
  CHECK(r.report.status == "unchanged");
  CHECK(r.mesh.triangles.size() == sphere.triangles.size());
  CHECK(r.report.hausdorff == 0.0);  // its own faces: exactly 0, not sampled
  CHECK_FALSE(r.report.fallback_used);
}

TEST_CASE("same_faces compares corner coordinates in any order and orientation", "[repair]") {
  const TriangleMesh sphere = make_icosphere(2);
  TriangleMesh flipped = sphere;
  for (auto& t : flipped.triangles) std::swap(t[1], t[2]);
  std::reverse(flipped.triangles.begin(), flipped.triangles.end());
  CHECK(detail::same_faces(sphere, flipped));
  TriangleMesh moved = sphere;
  moved.positions[5].x() += 1e-9;
  CHECK_FALSE(detail::same_faces(sphere, moved));
  TriangleMesh fewer = sphere;
  fewer.triangles.pop_back();
  CHECK_FALSE(detail::same_faces(sphere, fewer));
  TriangleMesh doubled = fewer;  // the same count with one face repeated is not the same
  doubled.triangles.push_back(doubled.triangles.front());
  CHECK_FALSE(detail::same_faces(sphere, doubled));
}

TEST_CASE("an inward-oriented mesh is turned outward", "[repair]") {
  TriangleMesh sphere = make_icosphere(2);
  for (auto& t : sphere.triangles) std::swap(t[1], t[2]);
  const RepairResult r = repair_mesh(to_soup(sphere));
  require_valid(r);
  CHECK(step_changed(r.report, "orient_outward") == static_cast<long>(sphere.triangles.size()));
}

TEST_CASE("every local defect kind on the sample muscle is repaired faithfully", "[repair]") {
  SampleOptions so;
  so.rings = 40;
  so.segments = 24;
  const TriangleMesh muscle = make_fusiform_muscle(so);
  const double volume = signed_volume(muscle);
  struct Case {
    DefectKind kind;
    const char* step;  // the step that must report a change
    double bound = 0.01;
  };
  const std::vector<Case> cases = {
      {DefectKind::duplicate_vertices, "weld_vertices"},
      {DefectKind::near_duplicate_vertices, "weld_vertices"},
      {DefectKind::holes, "fill_holes"},
      {DefectKind::flipped_patch, ""},
      {DefectKind::stray_component, "keep_largest_component"},
      {DefectKind::inner_shell, "keep_largest_component"},
      {DefectKind::pinched_vertex, "", 0.05},
      {DefectKind::non_manifold_edge, ""},
      {DefectKind::slivers, ""},
      {DefectKind::zero_area_faces, ""},  // midpoint splits: collinear only up to rounding
      {DefectKind::self_intersection_fold, "self_intersections", 0.05},
  };
  for (const Case& c : cases) {
    for (std::uint64_t seed : {1u, 2u, 3u}) {
      DYNAMIC_SECTION(defect_name(c.kind) << " seed " << seed) {
        const PolygonSoup broken = inject(muscle, c.kind, seed);
        const RepairResult r = repair_mesh(broken);
        require_valid(r);
        if (std::string(c.step).size() > 0) CHECK(step_changed(r.report, c.step) > 0);
        require_faithful(r, muscle, c.bound);
        CHECK(signed_volume(r.mesh) == Approx(volume).epsilon(0.05));
      }
    }
  }
}

TEST_CASE("scale and offset extremes repair and stay faithful", "[repair]") {
  SampleOptions so;
  so.rings = 30;
  so.segments = 20;
  const TriangleMesh muscle = make_fusiform_muscle(so);
  for (double factor : {1e-6, 1e6}) {
    DefectParams p;
    p.scale_factor = factor;
    const PolygonSoup scaled = inject(inject(muscle, DefectKind::holes, 4), DefectKind::scale, 1, p);
    const RepairResult r = repair_mesh(scaled);
    require_valid(r);
    TriangleMesh clean = muscle;
    for (Vec3& q : clean.positions) q *= factor;
    require_faithful(r, clean);
  }
  const PolygonSoup shifted = inject(inject(muscle, DefectKind::holes, 5), DefectKind::offset, 1);
  const RepairResult r = repair_mesh(shifted);
  require_valid(r);
  TriangleMesh clean = muscle;
  for (Vec3& q : clean.positions) q += DefectParams{}.offset;
  require_faithful(r, clean);
}

TEST_CASE("the built-in sample repairs to a faithful genus-0 mesh", "[repair]") {
  const RepairResult r = repair_mesh(make_sample());
  require_valid(r);
  CHECK_FALSE(r.report.fallback_used);
  require_faithful(r, make_fusiform_muscle());
  CHECK(r.report.input.components > 1);
  CHECK(r.report.input.boundary_edges > 0);
  const nlohmann::json j = r.report.to_json();
  for (const char* key : {"status", "input", "output", "steps", "fallback", "hausdorff", "seconds"})
    CHECK(j.contains(key));
  for (const char* key : {"vertices", "faces", "components", "boundary_edges", "non_manifold_edges", "genus",
                          "self_intersections", "volume"})
    CHECK(j["output"].contains(key));
}

TEST_CASE("a handle is closed by the alpha-wrap fallback, or refused without it", "[repair]") {
  SampleOptions so;
  so.rings = 40;
  so.segments = 24;
  const PolygonSoup with_handle = inject(make_fusiform_muscle(so), DefectKind::handle, 1);
  const RepairResult r = repair_mesh(with_handle);
  require_valid(r);
  CHECK(r.report.fallback_used);
  CHECK_FALSE(r.report.fallback_reason.empty());

  RepairOptions no_wrap;
  no_wrap.allow_wrap = false;
  try {
    repair_mesh(with_handle, no_wrap);
    FAIL("expected a refusal");
  } catch (const TopologyError& e) { CHECK(e.code() == ErrorCode::repair_failed); }
}

TEST_CASE("a torus with a large hole is refused with a clear error", "[repair]") {
  try {
    repair_mesh(to_soup(make_torus(1.0, 0.2, 32, 12)));
    FAIL("expected a refusal");
  } catch (const TopologyError& e) {
    CHECK(e.code() == ErrorCode::repair_failed);
    CHECK(std::string(e.what()).find("genus") != std::string::npos);
  }
}

TEST_CASE("merge policy wraps overlapping components into one and refuses distant ones", "[repair]") {
  // Two overlapping balls (like the overlapping element surfaces of the opendihu muscles).
  const TriangleMesh ball = make_icosphere(3);
  PolygonSoup two = to_soup(ball);
  const int base = static_cast<int>(two.points.size());
  for (const Vec3& p : ball.positions) two.points.push_back(p + Vec3(1.2, 0, 0));
  for (const Triangle& t : ball.triangles) two.polygons.push_back({t[0] + base, t[1] + base, t[2] + base});
  RepairOptions merge;
  merge.components = ComponentPolicy::merge;
  const RepairResult r = repair_mesh(two, merge);
  require_valid(r);
  CHECK(r.report.fallback_used);
  CHECK(r.report.output.volume > signed_volume(ball) * 1.3);  // the union, not one ball

  // A stray shell far away cannot be merged without bridging empty space: refused.
  const PolygonSoup distant = inject(ball, DefectKind::stray_component, 1);
  CHECK_THROWS_AS(repair_mesh(distant, merge), TopologyError);
  // By default the stray shell is dropped instead.
  require_valid(repair_mesh(distant));
}

TEST_CASE("repair refuses NaN coordinates, empty input and bad options", "[repair]") {
  PolygonSoup nan_soup = to_soup(make_tetrahedron());
  nan_soup.points[0].x() = std::nan("");
  CHECK_THROWS_AS(repair_mesh(nan_soup), InputError);
  CHECK_THROWS_AS(repair_mesh(PolygonSoup{}), InputError);
  RepairOptions bad;
  bad.weld_tolerance = -1.0;
  CHECK_THROWS_AS(repair_mesh(to_soup(make_tetrahedron()), bad), OptionError);
  PolygonSoup flat;
  flat.points = {Vec3(0, 0, 0), Vec3(0, 0, 0), Vec3(0, 0, 0)};
  flat.polygons = {{0, 1, 2}};
  CHECK_THROWS_AS(repair_mesh(flat), TopologyError);
}

TEST_CASE("simplify_mesh keeps a closed genus-0 surface and its shape, and leaves a small one as it is",
          "[repair][simplify]") {
  const TriangleMesh sphere = make_icosphere(5, 10.0);  // 20480 faces
  REQUIRE(sphere.triangles.size() == 20480);
  SimplifyReport report;
  const TriangleMesh coarse = simplify_mesh(sphere, 2000, &report);
  CHECK(static_cast<long>(coarse.triangles.size()) <= 2000);
  CHECK(coarse.triangles.size() > 1500);  // it stops at the limit, not far below
  CHECK(report.faces_before == 20480);
  CHECK(report.faces_after == static_cast<long>(coarse.triangles.size()));
  INFO("verification: " << verify_genus0(coarse));
  CHECK(verify_genus0(coarse).empty());
  CHECK(euler_characteristic(coarse) == 2);
  // Outward and faithful: the volume of the sphere within 2 %, every vertex near radius 10.
  CHECK(signed_volume(coarse) == Approx(signed_volume(sphere)).epsilon(0.02));
  for (const Vec3& p : coarse.positions) CHECK(std::abs(p.norm() - 10.0) < 0.2);
  // Deterministic.
  const TriangleMesh again = simplify_mesh(sphere, 2000);
  CHECK(again.positions == coarse.positions);
  CHECK(again.triangles == coarse.triangles);
  // At or under the limit: the same mesh.
  const TriangleMesh same = simplify_mesh(coarse, 2000);
  CHECK(same.positions == coarse.positions);
  CHECK(same.triangles == coarse.triangles);
}

TEST_CASE("simplify_mesh refuses a bad limit and an open surface", "[repair][simplify]") {
  const TriangleMesh sphere = make_icosphere(2);
  CHECK_THROWS_AS(simplify_mesh(sphere, 3), OptionError);
  TriangleMesh open = sphere;
  open.triangles.pop_back();
  CHECK_THROWS_AS(simplify_mesh(open, 100), TopologyError);
}
