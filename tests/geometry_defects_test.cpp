// The defect injector and the sample muscle: each defect kind changes exactly what it should,
// results are reproducible per seed, and the clean sample is a closed genus-0 outward surface.

#include "geometry/errors.h"
#include "geometry/inject_defects.h"
#include "geometry/mesh_io.h"
#include "geometry/mesh_stats.h"
#include "geometry/primitives.h"
#include "geometry/sample_muscle.h"
#include "test_common.h"

#include <catch2/catch.hpp>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <array>
#include <cstring>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <functional>
#include <limits>
#include <map>
#include <numeric>
#include <set>
#include <utility>

using namespace fascicle;

namespace {

// ------------------------------------------------------------------------------------------
// Small counting helpers (deliberately independent of the injector's own adjacency code).

struct EdgeCounts {
  int boundary = 0;      // used by one face
  int manifold = 0;      // used by two faces
  int non_manifold = 0;  // used by three or more
  int inconsistent = 0;  // two users traversing it the same way
};

EdgeCounts count_edges(const PolygonSoup& soup) {
  std::map<std::pair<int, int>, std::pair<int, int>> uses;
  for (const auto& p : soup.polygons)
    for (std::size_t k = 0; k < p.size(); ++k) {
      const int a = p[k], b = p[(k + 1) % p.size()];
      if (a == b) continue;
      if (a < b)
        ++uses[{a, b}].first;
      else
        ++uses[{b, a}].second;
    }
  EdgeCounts c;
  for (const auto& [edge, u] : uses) {
    const int n = u.first + u.second;
    if (n == 1)
      ++c.boundary;
    else if (n == 2) {
      ++c.manifold;
      if (u.first != 1) ++c.inconsistent;
    } else
      ++c.non_manifold;
  }
  return c;
}

bool closed_and_oriented(const PolygonSoup& soup) {
  const EdgeCounts e = count_edges(soup);
  return e.boundary == 0 && e.non_manifold == 0 && e.inconsistent == 0 && e.manifold > 0;
}

TriangleMesh as_mesh(const PolygonSoup& soup) {
  TriangleMesh m;
  m.positions = soup.points;
  for (const auto& p : soup.polygons) {
    REQUIRE(p.size() == 3);
    m.triangles.push_back({p[0], p[1], p[2]});
  }
  return m;
}

// Connected components of faces joined through shared point indices.
int components(const PolygonSoup& soup) {
  std::vector<int> parent(soup.points.size());
  std::iota(parent.begin(), parent.end(), 0);
  std::function<int(int)> find = [&](int i) { return parent[i] == i ? i : parent[i] = find(parent[i]); };
  std::vector<char> used(soup.points.size(), 0);
  for (const auto& p : soup.polygons)
    for (int v : p) {
      used[v] = 1;
      parent[find(v)] = find(p[0]);
    }
  int n = 0;
  for (std::size_t v = 0; v < used.size(); ++v) n += used[v] && find(static_cast<int>(v)) == static_cast<int>(v);
  return n;
}

// Face fans around each vertex: faces at v joined when they share an edge at v.
int max_fans(const PolygonSoup& soup) {
  std::vector<std::vector<int>> at(soup.points.size());
  for (std::size_t f = 0; f < soup.polygons.size(); ++f)
    for (int v : soup.polygons[f]) at[v].push_back(static_cast<int>(f));
  int worst = 0;
  for (std::size_t v = 0; v < at.size(); ++v) {
    auto& faces = at[v];
    faces.erase(std::unique(faces.begin(), faces.end()), faces.end());
    if (faces.empty()) continue;
    std::map<int, std::vector<int>> by_neighbour;  // neighbour vertex -> faces with edge (v, it)
    for (std::size_t i = 0; i < faces.size(); ++i) {
      const auto& p = soup.polygons[faces[i]];
      for (std::size_t k = 0; k < p.size(); ++k)
        if (p[k] == static_cast<int>(v)) {
          by_neighbour[p[(k + 1) % p.size()]].push_back(static_cast<int>(i));
          by_neighbour[p[(k + p.size() - 1) % p.size()]].push_back(static_cast<int>(i));
        }
    }
    std::vector<int> parent(faces.size());
    std::iota(parent.begin(), parent.end(), 0);
    std::function<int(int)> find = [&](int i) { return parent[i] == i ? i : parent[i] = find(parent[i]); };
    for (const auto& [n, list] : by_neighbour)
      for (int i : list) parent[find(i)] = find(list[0]);
    int fans = 0;
    for (std::size_t i = 0; i < faces.size(); ++i) fans += find(static_cast<int>(i)) == static_cast<int>(i);
    worst = std::max(worst, fans);
  }
  return worst;
}

bool same_soup(const PolygonSoup& a, const PolygonSoup& b) {
  if (a.points.size() != b.points.size() || a.polygons != b.polygons) return false;
  for (std::size_t i = 0; i < a.points.size(); ++i)
    for (int k = 0; k < 3; ++k)  // bit-for-bit (NaN compares by bits too)
      if (std::memcmp(&a.points[i][k], &b.points[i][k], sizeof(double)) != 0) return false;
  return true;
}

double triangle_area(const PolygonSoup& s, const std::vector<int>& p) {
  return 0.5 * (s.points[p[1]] - s.points[p[0]]).cross(s.points[p[2]] - s.points[p[0]]).norm();
}

double min_angle(const PolygonSoup& s) {
  double worst = 10;
  for (const auto& p : s.polygons)
    for (int k = 0; k < 3; ++k) {
      const Vec3 u = s.points[p[(k + 1) % 3]] - s.points[p[k]], w = s.points[p[(k + 2) % 3]] - s.points[p[k]];
      worst = std::min(worst, std::atan2(u.cross(w).norm(), u.dot(w)));
    }
  return worst;
}

// Segment pq against triangle abc (Moller-Trumbore restricted to the segment).
bool segment_hits_triangle(const Vec3& p, const Vec3& q, const Vec3& a, const Vec3& b, const Vec3& c) {
  const Vec3 d = q - p, e1 = b - a, e2 = c - a, h = d.cross(e2);
  const double det = e1.dot(h);
  if (std::abs(det) < 1e-14) return false;
  const Vec3 s = p - a;
  const double u = s.dot(h) / det;
  if (u < 0 || u > 1) return false;
  const Vec3 r = s.cross(e1);
  const double v = d.dot(r) / det;
  if (v < 0 || u + v > 1) return false;
  const double t = e2.dot(r) / det;
  return t > 0 && t < 1;
}

// Some edge crosses a triangle it does not touch.
bool has_edge_through_triangle(const PolygonSoup& s) {
  std::set<std::pair<int, int>> edges;
  for (const auto& p : s.polygons)
    for (int k = 0; k < 3; ++k) edges.insert({std::min(p[k], p[(k + 1) % 3]), std::max(p[k], p[(k + 1) % 3])});
  for (const auto& [a, b] : edges)
    for (const auto& t : s.polygons) {
      if (std::find(t.begin(), t.end(), a) != t.end() || std::find(t.begin(), t.end(), b) != t.end()) continue;
      if (segment_hits_triangle(s.points[a], s.points[b], s.points[t[0]], s.points[t[1]], s.points[t[2]])) return true;
    }
  return false;
}

std::set<std::array<double, 3>> distinct_positions(const PolygonSoup& s) {
  std::set<std::array<double, 3>> set;
  for (const Vec3& p : s.points) set.insert({p.x(), p.y(), p.z()});
  return set;
}

PolygonSoup ball() { return to_soup(make_icosphere(3, 10.0)); }

}  // namespace

// ------------------------------------------------------------------------------------------

TEST_CASE("defect names round-trip and unknown names are rejected", "[geometry][defects]") {
  const auto kinds = all_defect_kinds();
  CHECK(kinds.size() == 16);
  std::set<std::string> names;
  for (DefectKind k : kinds) {
    names.insert(defect_name(k));
    CHECK(defect_kind_from_name(defect_name(k)) == k);
  }
  CHECK(names.size() == kinds.size());
  CHECK_THROWS_AS(defect_kind_from_name("wormhole"), OptionError);
}

TEST_CASE("defect params are validated", "[geometry][defects]") {
  DefectParams p;
  CHECK_NOTHROW(p.validate());
  p.count = 0;
  CHECK_THROWS_AS(p.validate(), OptionError);
  p = {};
  p.fraction = 1.5;
  CHECK_THROWS_AS(p.validate(), OptionError);
  p = {};
  p.scale_factor = 0;
  CHECK_THROWS_AS(inject(ball(), DefectKind::scale, 1, p), OptionError);
  CHECK_THROWS_AS(inject(PolygonSoup{}, DefectKind::holes, 1), TopologyError);
}

TEST_CASE("holes open the surface", "[geometry][defects]") {
  const PolygonSoup clean = ball();
  REQUIRE(closed_and_oriented(clean));
  DefectParams p;
  p.count = 3;
  p.patch_faces = 7;
  DefectLog log;
  const PolygonSoup s = inject(clean, DefectKind::holes, 42, p, &log);
  CHECK(s.polygons.size() == clean.polygons.size() - 21);
  CHECK(count_edges(s).boundary >= 3 * 3);
  CHECK(count_edges(s).non_manifold == 0);
  CHECK(count_edges(s).inconsistent == 0);
  REQUIRE(log.records.size() == 1);
  CHECK(log.records[0].kind == DefectKind::holes);
  CHECK(log.records[0].count == 3);
  // Unreferenced points were dropped.
  std::vector<char> used(s.points.size(), 0);
  for (const auto& poly : s.polygons)
    for (int v : poly) used[v] = 1;
  CHECK(std::count(used.begin(), used.end(), 0) == 0);
}

TEST_CASE("flipped patch makes edges inconsistently oriented, nothing else", "[geometry][defects]") {
  const PolygonSoup clean = ball();
  const PolygonSoup s = inject(clean, DefectKind::flipped_patch, 7);
  const EdgeCounts e = count_edges(s);
  CHECK(e.inconsistent > 0);
  CHECK(e.boundary == 0);
  CHECK(e.non_manifold == 0);
  CHECK(s.points.size() == clean.points.size());
  CHECK(s.polygons.size() == clean.polygons.size());
}

TEST_CASE("pinched vertex makes one vertex with two fans and keeps edges manifold", "[geometry][defects]") {
  for (const PolygonSoup& clean : {ball(), to_soup(make_capsule(40, 4, 16))}) {
    REQUIRE(max_fans(clean) == 1);
    const PolygonSoup s = inject(clean, DefectKind::pinched_vertex, 3);
    CHECK(max_fans(s) == 2);
    const EdgeCounts e = count_edges(s);
    CHECK(e.boundary == 0);
    CHECK(e.non_manifold == 0);
    CHECK(e.inconsistent == 0);
    CHECK(s.points.size() == clean.points.size() - 1);
  }
}

TEST_CASE("non-manifold edge: a fin gives an edge with three faces", "[geometry][defects]") {
  const PolygonSoup s = inject(ball(), DefectKind::non_manifold_edge, 5);
  const EdgeCounts e = count_edges(s);
  CHECK(e.non_manifold == 1);
  CHECK(e.boundary == 2);  // the fin's two free edges
}

TEST_CASE("handle: closed, oriented, one component, Euler characteristic 0", "[geometry][defects]") {
  SampleOptions clean_options;
  clean_options.defects = false;
  for (const PolygonSoup& clean : {ball(), to_soup(make_cube(2.0, 6)), make_sample(clean_options)}) {
    for (std::uint64_t seed : {1u, 2u, 3u}) {
      const PolygonSoup s = inject(clean, DefectKind::handle, seed);
      CHECK(closed_and_oriented(s));
      CHECK(components(s) == 1);
      CHECK(euler_characteristic(as_mesh(s)) == 0);
      CHECK(signed_volume(as_mesh(s)) > 0);
      CHECK(signed_volume(as_mesh(s)) < signed_volume(as_mesh(clean)));
    }
  }
  DefectParams two;
  two.count = 2;
  const PolygonSoup s = inject(ball(), DefectKind::handle, 9, two);
  CHECK(closed_and_oriented(s));
  CHECK(euler_characteristic(as_mesh(s)) == -2);
  // A tetrahedron has no two vertex stars apart from each other.
  CHECK_THROWS_AS(inject(make_tetrahedron(), DefectKind::handle, 1), TopologyError);
}

TEST_CASE("self-intersection fold pushes an edge through a triangle", "[geometry][defects]") {
  const PolygonSoup clean = to_soup(make_icosphere(2, 1.0));
  REQUIRE_FALSE(has_edge_through_triangle(clean));
  const PolygonSoup s = inject(clean, DefectKind::self_intersection_fold, 11);
  CHECK(has_edge_through_triangle(s));
  CHECK(s.polygons == clean.polygons);  // connectivity untouched
  CHECK(closed_and_oriented(s));
}

TEST_CASE("stray, inner and outer shells add closed outward components where they belong", "[geometry][defects]") {
  const PolygonSoup clean = ball();  // radius 10 at the origin
  const std::size_t n = clean.points.size();
  const double volume = signed_volume(as_mesh(clean));

  const PolygonSoup stray = inject(clean, DefectKind::stray_component, 1);
  CHECK(components(stray) == 2);
  CHECK(closed_and_oriented(stray));
  for (std::size_t i = n; i < stray.points.size(); ++i) CHECK(stray.points[i].norm() > 10.0);
  CHECK(signed_volume(as_mesh(stray)) > volume);

  const PolygonSoup inner = inject(clean, DefectKind::inner_shell, 2);
  CHECK(components(inner) == 2);
  CHECK(closed_and_oriented(inner));
  for (std::size_t i = n; i < inner.points.size(); ++i) CHECK(inner.points[i].norm() < 9.5);
  CHECK(signed_volume(as_mesh(inner)) > volume);

  const PolygonSoup outer = inject(clean, DefectKind::outer_shell, 3);
  CHECK(components(outer) == 2);
  CHECK(closed_and_oriented(outer));
  // Every original point is strictly inside every face plane of the (convex) outer sphere.
  for (std::size_t f = clean.polygons.size(); f < outer.polygons.size(); ++f) {
    const auto& t = outer.polygons[f];
    const Vec3 a = outer.points[t[0]];
    const Vec3 normal = (outer.points[t[1]] - a).cross(outer.points[t[2]] - a);
    for (std::size_t i = 0; i < n; ++i) REQUIRE(normal.dot(outer.points[i] - a) < 0);
  }
}

TEST_CASE("slivers and zero-area faces keep the surface closed and the volume", "[geometry][defects]") {
  const PolygonSoup clean = ball();
  const double volume = signed_volume(as_mesh(clean));
  const double area = surface_area(as_mesh(clean));
  REQUIRE(min_angle(clean) > 0.5);

  const PolygonSoup slivers = inject(clean, DefectKind::slivers, 4);
  CHECK(closed_and_oriented(slivers));
  CHECK(slivers.polygons.size() > clean.polygons.size());
  CHECK(min_angle(slivers) < 0.01);
  CHECK(signed_volume(as_mesh(slivers)) == Approx(volume).epsilon(1e-12));
  CHECK(surface_area(as_mesh(slivers)) == Approx(area).epsilon(1e-12));

  auto degenerate = [](const PolygonSoup& s) {
    int n = 0;
    for (const auto& p : s.polygons) n += triangle_area(s, p) < 1e-12;
    return n;
  };
  DefectLog log;
  const PolygonSoup zero = inject(clean, DefectKind::zero_area_faces, 4, DefectParams{}, &log);
  CHECK(degenerate(clean) == 0);
  CHECK(degenerate(zero) == log.records.at(0).count);
  CHECK(degenerate(zero) >= 1);
  CHECK(closed_and_oriented(zero));
  CHECK(signed_volume(as_mesh(zero)) == Approx(volume).epsilon(1e-12));
}

TEST_CASE("duplicate vertices: more points, same geometry", "[geometry][defects]") {
  const PolygonSoup clean = ball();
  DefectLog log;
  const PolygonSoup s = inject(clean, DefectKind::duplicate_vertices, 8, DefectParams{}, &log);
  const int copies = log.records.at(0).count;
  CHECK(copies == static_cast<int>(std::round(0.02 * clean.points.size())));
  CHECK(s.points.size() == clean.points.size() + static_cast<std::size_t>(copies));
  CHECK(distinct_positions(s) == distinct_positions(clean));
  CHECK(s.polygons.size() == clean.polygons.size());
  CHECK(surface_area(as_mesh(s)) == Approx(surface_area(as_mesh(clean))).epsilon(1e-14));
  CHECK(signed_volume(as_mesh(s)) == Approx(signed_volume(as_mesh(clean))).epsilon(1e-14));
  CHECK(count_edges(s).boundary > 0);  // by index the copies cut the surface

  const PolygonSoup near = inject(clean, DefectKind::near_duplicate_vertices, 8);
  CHECK(near.points.size() == s.points.size());
  const double diagonal = bounding_box(clean.points).diagonal();
  for (std::size_t i = clean.points.size(); i < near.points.size(); ++i) {
    double nearest = 1e300;
    for (const Vec3& p : clean.points) nearest = std::min(nearest, (p - near.points[i]).norm());
    CHECK(nearest > 0);
    CHECK(nearest < 2e-7 * diagonal);
  }
}

TEST_CASE("coordinate defects: NaN, offset, scale", "[geometry][defects]") {
  const PolygonSoup clean = ball();
  const PolygonSoup nan = inject(clean, DefectKind::nan_coordinates, 1);
  CHECK(std::any_of(nan.points.begin(), nan.points.end(), [](const Vec3& p) { return !p.allFinite(); }));
  CHECK(std::all_of(clean.points.begin(), clean.points.end(), [](const Vec3& p) { return p.allFinite(); }));

  const BoundingBox box = bounding_box(clean.points);
  const PolygonSoup moved = inject(clean, DefectKind::offset, 1);
  const BoundingBox moved_box = bounding_box(moved.points);
  CHECK((moved_box.min - box.min - Vec3::Constant(1e7)).norm() < 1e-6);
  CHECK(moved_box.diagonal() == Approx(box.diagonal()).epsilon(1e-9));
  CHECK(signed_volume(as_mesh(moved)) == Approx(signed_volume(as_mesh(clean))).epsilon(1e-6));

  DefectParams p;
  p.scale_factor = 1e6;
  const PolygonSoup big = inject(clean, DefectKind::scale, 1, p);
  CHECK(bounding_box(big.points).diagonal() == Approx(1e6 * box.diagonal()));
  CHECK(bounding_box(inject(clean, DefectKind::scale, 1).points).diagonal() == Approx(1e-3 * box.diagonal()));
}

TEST_CASE("every kind applies to several shapes and is reproducible per seed", "[geometry][defects]") {
  SampleOptions clean_options;
  clean_options.defects = false;
  const std::vector<PolygonSoup> shapes = {ball(), to_soup(make_cube(5.0, 4)), to_soup(make_capsule(60, 3, 16)),
                                           to_soup(make_bent_tube(30, 5, 2.0, 16)), make_sample(clean_options)};
  for (std::size_t i = 0; i < shapes.size(); ++i)
    for (DefectKind kind : all_defect_kinds()) {
      INFO("shape " << i << " kind " << defect_name(kind));
      DefectLog log;
      const PolygonSoup a = inject(shapes[i], kind, 1234, DefectParams{}, &log);
      const PolygonSoup b = inject(shapes[i], kind, 1234);
      CHECK(same_soup(a, b));
      CHECK_FALSE(same_soup(a, shapes[i]));
      REQUIRE(log.records.size() == 1);
      CHECK(log.records[0].kind == kind);
      CHECK(log.records[0].count >= 1);
      CHECK_FALSE(log.records[0].note.empty());
    }
  // Random choices depend on the seed.
  CHECK_FALSE(same_soup(inject(shapes[0], DefectKind::holes, 1), inject(shapes[0], DefectKind::holes, 2)));
}

TEST_CASE("random combinations are reproducible and logged", "[geometry][defects]") {
  const PolygonSoup clean = to_soup(make_icosphere(3, 5.0));
  for (std::uint64_t seed = 0; seed < 6; ++seed) {
    INFO("seed " << seed);
    DefectLog log;
    const PolygonSoup a = inject_random_combination(clean, seed, 4, &log);
    CHECK(log.records.size() == 4);
    std::set<DefectKind> kinds;
    for (const auto& r : log.records) kinds.insert(r.kind);
    CHECK(kinds.size() == 4);
    CHECK(kinds.count(DefectKind::nan_coordinates) == 0);
    CHECK(std::is_sorted(log.records.begin(), log.records.end(),
                         [](const DefectRecord& x, const DefectRecord& y) { return x.kind < y.kind; }));
    CHECK(same_soup(a, inject_random_combination(clean, seed, 4)));
  }
  CHECK(same_soup(inject_random_combination(clean, 3, 0), clean));
  CHECK(same_soup(inject_random_combination(make_icosphere(3, 5.0), 3, 2), inject_random_combination(clean, 3, 2)));
  CHECK_THROWS_AS(inject_random_combination(clean, 3, 16), OptionError);
}

TEST_CASE("clean sample muscle is a closed genus-0 outward spindle", "[geometry][sample]") {
  SampleOptions options;
  options.defects = false;
  const TriangleMesh m = make_fusiform_muscle(options);
  CHECK(m.triangles.size() == static_cast<std::size_t>(2 * options.rings * options.segments));
  CHECK(m.triangles.size() >= 5000);
  CHECK(m.triangles.size() <= 10000);
  CHECK(closed_and_oriented(to_soup(m)));
  CHECK(euler_characteristic(m) == 2);
  const BoundingBox box = bounding_box(m.positions);
  // The poles (first and last vertex) are the tips, `length` apart; the tilted rounded tips
  // reach a little beyond them along x.
  CHECK((m.positions.back() - m.positions.front()).norm() == Approx(options.length).epsilon(1e-12));
  CHECK(box.max.x() - box.min.x() == Approx(options.length).epsilon(0.002));
  CHECK(box.max.z() > options.belly_radius + 0.5 * options.axis_bend);  // the axis bows towards +z
  CHECK(box.max.z() - box.min.z() == Approx(2 * options.belly_radius).epsilon(0.01));
  CHECK(box.max.y() - box.min.y() == Approx(2 * options.ellipticity * options.belly_radius).epsilon(0.01));
  // Between a cylinder of the belly's ellipse and one of the tendon's, and clearly above the latter.
  const double v = signed_volume(m);
  const double belly = 3.14159265358979 * options.belly_radius * options.belly_radius * options.ellipticity;
  CHECK(v > 0.3 * belly * options.length);
  CHECK(v < belly * options.length);
  CHECK(make_sample(options).polygons.size() == m.triangles.size());
  options.belly_radius = 100;
  CHECK_THROWS_AS(make_fusiform_muscle(options), OptionError);
}

TEST_CASE("defective sample has every advertised defect and is reproducible", "[geometry][sample]") {
  SampleOptions options;
  DefectLog log;
  const PolygonSoup s = make_sample(options, &log);
  REQUIRE(log.records.size() == 5);
  CHECK(std::string(defect_name(log.records[0].kind)) == "holes");
  CHECK(std::string(defect_name(log.records[4].kind)) == "duplicate_vertices");
  for (const auto& p : s.polygons) CHECK(p.size() == 3);
  const EdgeCounts e = count_edges(s);
  CHECK(e.boundary > 0);
  CHECK(e.inconsistent > 0);
  CHECK(max_fans(s) >= 2);
  CHECK(components(s) >= 2);
  CHECK(distinct_positions(s).size() < s.points.size());
  // Same seed: the same soup bit for bit; another seed: a different one.
  CHECK(same_soup(s, make_sample(options)));
  options.seed = 2;
  CHECK_FALSE(same_soup(s, make_sample(options)));
}

TEST_CASE("fascicle sample writes the same soup make_sample builds, and its log", "[geometry][sample][cli]") {
  const std::string program = fascicle::test::program();
  REQUIRE(std::filesystem::exists(program));
  fascicle::test::TempDir dir;
  const std::string out = dir.file("s.off"), again = dir.file("again.off"), log = dir.file("s.json");
  REQUIRE(fascicle::test::run_command(program + " -q sample -o " + out + " --seed 5 --log " + log) == 0);
  SampleOptions options;
  options.seed = 5;
  const PolygonSoup expected = make_sample(options);
  const PolygonSoup read = read_polygon_soup(out);
  CHECK(same_soup(read, expected));  // OFF text keeps every bit (max_digits10)
  std::ifstream in(log);
  const nlohmann::json json = nlohmann::json::parse(in);
  CHECK(json.at("seed") == 5);
  CHECK(json.at("clean") == false);
  REQUIRE(json.at("defects").size() == 5);
  CHECK(json.at("defects")[0].at("kind") == "holes");
  CHECK(json.at("faces") == expected.polygons.size());
  // Same seed, same bytes.
  REQUIRE(fascicle::test::run_command(program + " -q sample -o " + again + " --seed 5") == 0);
  std::ifstream a(out), b(again);
  const std::string text_a((std::istreambuf_iterator<char>(a)), {}), text_b((std::istreambuf_iterator<char>(b)), {});
  CHECK(text_a == text_b);

  const std::string clean = dir.file("clean.off");
  REQUIRE(fascicle::test::run_command(program + " -q sample --clean -o " + clean) == 0);
  const PolygonSoup clean_soup = read_polygon_soup(clean);
  CHECK(closed_and_oriented(clean_soup));
  CHECK(euler_characteristic(as_mesh(clean_soup)) == 2);

  const std::string torus = dir.file("torus.off");
  REQUIRE(fascicle::test::run_command(program + " -q sample --kind torus --inject holes -o " + torus) == 0);
  CHECK(count_edges(read_polygon_soup(torus)).boundary > 0);

  // Bad options: exit codes of geometry/errors.h, and no output left behind.
  const std::string none = dir.file("none.off");
  CHECK(fascicle::test::run_command(program + " -q sample --clean --inject holes -o " + none + " 2>/dev/null") ==
        exit_code(ErrorCode::invalid_option));
  CHECK(fascicle::test::run_command(program + " -q sample --inject nan_coordinates -o " + none + " 2>/dev/null") ==
        exit_code(ErrorCode::invalid_option));
  CHECK(fascicle::test::run_command(program + " -q sample --kind tetrahedron --inject handle -o " + none +
                                    " 2>/dev/null") == exit_code(ErrorCode::topology));
  CHECK(fascicle::test::run_command(program + " -q sample --inject wormhole -o " + none + " 2>/dev/null") ==
        exit_code(ErrorCode::usage));
  CHECK_FALSE(std::filesystem::exists(none));
}

namespace {
// FNV-1a over the polygon indices only (integers: the same on every platform and library).
std::uint64_t index_hash(const PolygonSoup& s) {
  std::uint64_t h = 1469598103934665603ULL;
  for (const auto& p : s.polygons) {
    for (int v : p) h = (h ^ static_cast<std::uint64_t>(v + 1)) * 1099511628211ULL;
    h = (h ^ 0xFFULL) * 1099511628211ULL;
  }
  return h;
}
}  // namespace

TEST_CASE("random choices are pinned: same indices with any standard library", "[geometry][defects][golden]") {
  // The cube's coordinates are exact and mt19937_64's sequence is fixed by the C++ standard, so
  // which faces and vertices each kind picks is the same everywhere. These values were recorded
  // from this implementation; they change only when an injection algorithm changes on purpose
  // (then record the new values), and they catch a switch to std::uniform_*_distribution, whose
  // output differs between standard libraries.
  const PolygonSoup cube = to_soup(make_cube(2.0, 4));
  CHECK(index_hash(inject(cube, DefectKind::holes, 2024)) == 0xdfa9ff5bc8143323ULL);
  CHECK(index_hash(inject(cube, DefectKind::flipped_patch, 2024)) == 0x9502dcac25f7cbabULL);
  CHECK(index_hash(inject(cube, DefectKind::duplicate_vertices, 2024)) == 0xee90264153fe8b8bULL);
  // Seed 2025 draws non_manifold_edge, duplicate_vertices and scale: index choices only.
  CHECK(index_hash(inject_random_combination(cube, 2025, 3)) == 0x54ae571673e323f0ULL);
}

TEST_CASE("sample options are validated field by field", "[geometry][sample]") {
  auto message = [](const SampleOptions& o) {
    try {
      o.validate();
    } catch (const OptionError& e) { return std::string(e.what()); }
    return std::string();
  };
  CHECK(message(SampleOptions{}).empty());
  SampleOptions o;
  o.ellipticity = 0;
  CHECK_THAT(message(o), Catch::Contains("ellipticity"));
  o = {};
  o.rings = 2;
  CHECK_THAT(message(o), Catch::Contains("rings"));
  o = {};
  o.tendon_radius = 20;
  CHECK_THAT(message(o), Catch::Contains("tendon_radius"));
  o = {};
  o.duplicate_fraction = 2;
  CHECK_THAT(message(o), Catch::Contains("duplicate_fraction"));
  o = {};
  o.axis_bend = std::nan("");
  CHECK_THAT(message(o), Catch::Contains("axis_bend"));
  o.defects = true;
  CHECK_THROWS_AS(make_sample(o), OptionError);
}
