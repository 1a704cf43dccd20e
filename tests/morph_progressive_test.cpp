// Progressive-mesh sphere start: the collapse sequence keeps a closed genus-0 manifold down to a
// tetrahedron, the split-back embedding is a bijection on shapes where the Tutte starts are weak
// (long thin capsules, badly scaled and offset coordinates), and the automatic method falls back
// to it.
#include "geometry/errors.h"
#include "morph/mesh_adjacency.h"
#include "morph/sphere_map.h"
#include "morph/sphere_steps.h"
#include "tests/morph_test_shapes.h"

#include <catch2/catch.hpp>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <set>
#include <tuple>

using namespace fascicle;

namespace {

void require_bijective(const TriangleMesh& mesh, const SphereMap& map) {
  INFO("failure: " << map.report.failure);
  REQUIRE(map.positions.size() == mesh.positions.size());
  for (const Vec3& p : map.positions) REQUIRE(std::abs(p.norm() - 1.0) < 1e-12);
  CHECK(map.report.status == "ok");
  CHECK(map.report.quality.flipped == 0);
  CHECK(map.report.quality.degenerate == 0);
  CHECK(map.report.quality.area_sum == Approx(4.0 * M_PI).margin(1e-6));
  CHECK(measure_sphere_map(mesh, map.positions).bijective());
}

/// Capsule with deterministic noise (no ties between equal edge lengths).
TriangleMesh noisy_capsule(double r, double length, int around, double noise) {
  TriangleMesh m = test::capsule(r, length, around);
  for (std::size_t i = 0; i < m.positions.size(); ++i)
    m.positions[i] += noise * Vec3(std::sin(1.7 * i), std::cos(2.3 * i), std::sin(0.7 * i + 1.0));
  return m;
}

/// Tube along z made of rings (vertex count, radius, z), consecutive rings stitched by walking
/// both in angle (so rings of very different counts give fans of long thin triangles), closed
/// by a tip vertex below the first ring and one above the last.
TriangleMesh ringed_tube(const std::vector<std::tuple<int, double, double>>& rings, double bottom, double top) {
  TriangleMesh m;
  std::vector<int> start;
  m.positions.emplace_back(0, 0, bottom);
  for (std::size_t r = 0; r < rings.size(); ++r) {
    const auto [count, radius, z] = rings[r];
    start.push_back(static_cast<int>(m.positions.size()));
    const double shift = 0.37 * static_cast<double>(r);  // rings turned against each other
    for (int k = 0; k < count; ++k) {
      const double phi = 2.0 * M_PI * k / count + shift;
      m.positions.emplace_back(radius * std::cos(phi), radius * std::sin(phi), z);
    }
  }
  m.positions.emplace_back(0, 0, top);
  const int tip_top = static_cast<int>(m.positions.size()) - 1;
  auto id = [&](std::size_t r, int k) {
    const int count = std::get<0>(rings[r]);
    return start[r] + ((k % count) + count) % count;
  };
  const int first = std::get<0>(rings.front()), last = std::get<0>(rings.back());
  for (int k = 0; k < first; ++k) m.triangles.push_back({0, id(0, k + 1), id(0, k)});
  for (std::size_t r = 0; r + 1 < rings.size(); ++r) {
    const int na = std::get<0>(rings[r]), nb = std::get<0>(rings[r + 1]);
    const double sa = 0.37 * static_cast<double>(r), sb = 0.37 * static_cast<double>(r + 1);
    auto angle_a = [&](int i) { return 2.0 * M_PI * i / na + sa; };
    // Ring b's vertex numbering starts at its first vertex at or after ring a's vertex 0.
    int j0 = 0;
    while (2.0 * M_PI * j0 / nb + sb < angle_a(0)) ++j0;
    auto angle_b = [&](int j) { return 2.0 * M_PI * (j + j0) / nb + sb; };
    int i = 0, j = 0;
    while (i < na || j < nb) {
      const bool advance_a = j >= nb || (i < na && angle_a(i + 1) < angle_b(j + 1));
      if (advance_a) {
        m.triangles.push_back({id(r, i), id(r, i + 1), id(r + 1, j + j0)});
        ++i;
      } else {
        m.triangles.push_back({id(r, i), id(r + 1, j + j0 + 1), id(r + 1, j + j0)});
        ++j;
      }
    }
  }
  const std::size_t lr = rings.size() - 1;
  for (int k = 0; k < last; ++k) m.triangles.push_back({tip_top, id(lr, k), id(lr, k + 1)});
  return m;
}

SphereMapOptions progressive_only() {
  SphereMapOptions options;
  options.start = SphereStart::progressive;
  return options;
}

}  // namespace

TEST_CASE("collapse sequence keeps a closed genus-0 manifold down to a tetrahedron", "[morph]") {
  for (const TriangleMesh& mesh : {test::capsule(1.0, 30.0, 8), test::icosphere(2), test::subdivided_cube(3)}) {
    const MeshAdjacency adjacency = check_sphere_topology(mesh);
    const detail::CollapseSequence seq = detail::collapse_to_tetrahedron(mesh, adjacency, 12);
    const std::size_t n = seq.removed.size();
    REQUIRE(n == mesh.positions.size() - 4);
    REQUIRE(seq.kept.size() == n);
    REQUIRE(seq.dead.size() == n);
    REQUIRE(seq.moved_start.size() == n + 1);
    // Every vertex but the base four is removed exactly once, never after it was removed.
    std::set<int> removed(seq.removed.begin(), seq.removed.end());
    CHECK(removed.size() == n);
    for (int b : seq.base) CHECK(removed.count(b) == 0);
    for (std::size_t i = 0; i < n; ++i) {
      INFO("collapse " << i);
      CHECK(seq.removed[i] != seq.kept[i]);
      CHECK(std::find(seq.removed.begin(), seq.removed.begin() + static_cast<long>(i), seq.kept[i]) ==
            seq.removed.begin() + static_cast<long>(i));
    }
    // Every level passes the full topology check (closed, oriented, manifold, Euler 2).
    for (std::size_t k = 0; k <= n; ++k) {
      INFO("after " << k << " collapses");
      const TriangleMesh level = detail::collapsed_mesh(mesh, seq, k);
      REQUIRE(level.positions.size() == mesh.positions.size() - k);
      REQUIRE(level.triangles.size() == mesh.triangles.size() - 2 * k);
      REQUIRE_NOTHROW(check_sphere_topology(level));
    }
    const TriangleMesh base = detail::collapsed_mesh(mesh, seq, n);
    CHECK(base.positions.size() == 4);
    CHECK(base.triangles.size() == 4);
  }
}

TEST_CASE("collapse_to_tetrahedron refuses a mesh that is not a sphere", "[morph]") {
  // A torus-like triangulation passes no genus-0 check; the collapse must not loop forever on it.
  TriangleMesh torus;
  const int n = 6, m = 4;
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < m; ++j) {
      const double a = 2.0 * M_PI * i / n, b = 2.0 * M_PI * j / m;
      torus.positions.emplace_back((2.0 + std::cos(b)) * std::cos(a), (2.0 + std::cos(b)) * std::sin(a), std::sin(b));
    }
  auto id = [&](int i, int j) { return ((i + n) % n) * m + (j + m) % m; };
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < m; ++j) {
      torus.triangles.push_back({id(i, j), id(i + 1, j), id(i + 1, j + 1)});
      torus.triangles.push_back({id(i, j), id(i + 1, j + 1), id(i, j + 1)});
    }
  CHECK_THROWS_AS(check_sphere_topology(torus), TopologyError);
  CHECK_THROWS_AS(detail::collapse_to_tetrahedron(torus, MeshAdjacency{}, 12), TopologyError);
}

TEST_CASE("progressive embedding keeps every triangle positive and far from degenerate", "[morph]") {
  const TriangleMesh mesh = test::capsule(1.0, 100.0, 12);  // 100:1, thin
  const MeshAdjacency adjacency = check_sphere_topology(mesh);
  const detail::ProgressiveResult result = detail::progressive_embedding(mesh, adjacency, 12, 2);
  CHECK(result.collapses == static_cast<long>(mesh.positions.size()) - 4);
  CHECK(result.failed_splits == 0);
  double smallest = 1.0;
  for (const Triangle& t : mesh.triangles)
    smallest = std::min(smallest, detail::sphere_det(result.sphere[t[0]], result.sphere[t[1]], result.sphere[t[2]]));
  CHECK(smallest > detail::min_step_det);
  CHECK(measure_sphere_map(mesh, result.sphere).bijective());
}

TEST_CASE("progressive start maps long thin capsules bijectively", "[morph]") {
  for (const TriangleMesh& mesh : {test::capsule(1.0, 100.0, 12), test::capsule(1.0, 300.0, 6),
                                   test::bent_capsule(1.0, 60.0, 10, 300.0), test::icosphere(3)}) {
    const SphereMap map = map_to_sphere(mesh, progressive_only());
    CHECK(map.report.initial_map == "progressive");
    CHECK(map.report.starts_tried == std::vector<std::string>{"progressive"});
    require_bijective(mesh, map);
  }
}

TEST_CASE("progressive start does not depend on scale or CT offsets", "[morph]") {
  const TriangleMesh base = noisy_capsule(1.0, 40.0, 10, 0.01);
  TriangleMesh tiny = base, far = base;
  for (Vec3& p : tiny.positions) p *= 1e-6;
  for (Vec3& p : far.positions) p += Vec3(1e7, -2e7, 1e7);
  const SphereMap a = map_to_sphere(base, progressive_only());
  const SphereMap b = map_to_sphere(tiny, progressive_only());
  const SphereMap c = map_to_sphere(far, progressive_only());
  require_bijective(base, a);
  require_bijective(tiny, b);
  require_bijective(far, c);
  // The collapse order depends on edge lengths only: the 1e-6 copy gives the same sequence.
  const detail::CollapseSequence sa = detail::collapse_to_tetrahedron(base, check_sphere_topology(base), 12);
  const detail::CollapseSequence sb = detail::collapse_to_tetrahedron(tiny, check_sphere_topology(tiny), 12);
  CHECK(sa.removed == sb.removed);
  CHECK(sa.kept == sb.kept);
}

TEST_CASE("tetrahedron and octahedron map without any split trouble", "[morph]") {
  TriangleMesh tet;
  tet.positions = {{1, 1, 1}, {1, -1, -1}, {-1, 1, -1}, {-1, -1, 1}};
  tet.triangles = {{0, 1, 2}, {0, 3, 1}, {0, 2, 3}, {1, 3, 2}};
  // Orient outward: flip all if the first face points inward.
  const Vec3 n = (tet.positions[1] - tet.positions[0]).cross(tet.positions[2] - tet.positions[0]);
  if (n.dot(tet.positions[0] + tet.positions[1] + tet.positions[2]) < 0)
    for (Triangle& t : tet.triangles) std::swap(t[1], t[2]);
  require_bijective(tet, map_to_sphere(tet, progressive_only()));
  TriangleMesh oct;
  oct.positions = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};
  oct.triangles = {{0, 2, 4}, {2, 1, 4}, {1, 3, 4}, {3, 0, 4}, {2, 0, 5}, {1, 2, 5}, {3, 1, 5}, {0, 3, 5}};
  require_bijective(oct, map_to_sphere(oct, progressive_only()));
}

TEST_CASE("sphere start option is parsed, validated and reported", "[morph]") {
  CHECK(sphere_start_from_string("progressive") == SphereStart::progressive);
  CHECK(sphere_start_from_string("automatic") == SphereStart::automatic);
  CHECK(sphere_start_from_string("tube") == SphereStart::tube);
  CHECK(sphere_start_from_string("stereographic") == SphereStart::stereographic);
  CHECK_THROWS_AS(sphere_start_from_string("lambert"), OptionError);
  SphereMapOptions options;
  options.progressive_max_valence = 5;
  CHECK_THROWS_AS(options.validate(), OptionError);
  options = SphereMapOptions{};
  options.progressive_relax_rounds = -1;
  CHECK_THROWS_AS(options.validate(), OptionError);
  const TriangleMesh mesh = test::capsule(1.0, 8.0, 12);
  const SphereMap automatic = map_to_sphere(mesh);
  // A capsule this easy needs no fallback: the first start already is a bijection.
  CHECK(automatic.report.initial_map == "tube");
  CHECK(std::find(automatic.report.starts_tried.begin(), automatic.report.starts_tried.end(), "progressive") ==
        automatic.report.starts_tried.end());
  CHECK(automatic.report.to_json()["starts_tried"].size() == automatic.report.starts_tried.size());
  const SphereMap forced = map_to_sphere(mesh, progressive_only());
  CHECK(forced.report.to_json()["initial_map"] == "progressive");
  // Round shapes start from the progressive embedding.
  const TriangleMesh ball = test::icosphere(3);
  const SphereMap round = map_to_sphere(ball);
  CHECK(round.report.starts_tried == std::vector<std::string>{"progressive"});
  require_bijective(ball, round);
}

TEST_CASE("automatic start falls back to the progressive start where the tube start fails", "[morph]") {
  // A short wide tube of 160 vertices per ring whose ends are 3-vertex rings round a tip: each
  // vertex next to a tip fans out over a third of the circumference in flat slivers, as at a
  // hooked muscle end; both tube folds leave flipped triangles there.
  std::vector<std::tuple<int, double, double>> rings;
  rings.emplace_back(3, 0.1, 0.1);
  for (int k = 0; k <= 120; ++k) rings.emplace_back(160, 1.0, 0.2 + 4.0 * k / 120);
  rings.emplace_back(3, 0.1, 4.3);
  const TriangleMesh mesh = ringed_tube(rings, 0.0, 4.4);
  REQUIRE_NOTHROW(check_sphere_topology(mesh));
  // Without reweighting rounds (which clear the folds' bad triangles on this shape, not on the
  // psoas) the tube start fails here, and the automatic start must fall back.
  SphereMapOptions tube_only;
  tube_only.start = SphereStart::tube;
  tube_only.reweight_rounds = 0;
  const SphereMap tube = map_to_sphere(mesh, tube_only);
  // The Lambert fold is tried only when the prism fold kept bad triangles after untangling.
  CHECK(tube.report.starts_tried == std::vector<std::string>{"tube-prism", "tube-lambert"});
  CHECK(tube.report.status == "failed");
  CHECK(tube.report.quality.flipped + tube.report.quality.degenerate > 0);
  SphereMapOptions automatic;
  automatic.reweight_rounds = 0;
  const SphereMap map = map_to_sphere(mesh, automatic);
  INFO("starts tried: " << nlohmann::json(map.report.starts_tried).dump());
  CHECK(map.report.starts_tried == std::vector<std::string>{"tube-prism", "tube-lambert", "progressive"});
  CHECK(map.report.initial_map == "progressive");
  // With the default options the reweighting rounds repair the tube map.
  const SphereMap repaired = map_to_sphere(mesh);
  CHECK(repaired.report.initial_map == "tube");
  CHECK(repaired.report.reweight_rounds > 0);
  require_bijective(mesh, repaired);
  require_bijective(mesh, map);
}
