#include "geometry/primitives.h"

#include "geometry/errors.h"
#include "geometry/mesh_stats.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <map>
#include <string>
#include <utility>

namespace fascicle {

namespace {

constexpr double kPi = 3.14159265358979323846;

std::string number(double value) {
  char buffer[64];
  std::snprintf(buffer, sizeof(buffer), "%.17g", value);
  return buffer;
}

void require(bool ok, const std::string& field, double value, const char* rule) {
  if (!ok) throw OptionError(field + " = " + number(value) + " is invalid: " + rule);
}

void flip_all(TriangleMesh& mesh) {
  for (Triangle& t : mesh.triangles) std::swap(t[1], t[2]);
}

// The constructions below are oriented by design; this keeps them outward even if a future edit
// changes a winding, and is what makes make_closed_tube independent of the rings' direction.
void orient_outward(TriangleMesh& mesh) {
  if (signed_volume(mesh) < 0.0) flip_all(mesh);
}

// One ring of `segments` points around `center` in the plane spanned by u and v.
std::vector<Vec3> ring(const Vec3& center, const Vec3& u, const Vec3& v, double radius, int segments) {
  std::vector<Vec3> points(static_cast<std::size_t>(segments));
  for (int j = 0; j < segments; ++j) {
    const double a = 2.0 * kPi * j / segments;
    points[static_cast<std::size_t>(j)] = center + radius * (std::cos(a) * u + std::sin(a) * v);
  }
  return points;
}

}  // namespace

TriangleMesh make_tetrahedron(double size) {
  require(std::isfinite(size) && size > 0, "tetrahedron size", size, "must be positive");
  TriangleMesh m;
  m.positions = {Vec3(0, 0, 0), Vec3(size, 0, 0), Vec3(0, size, 0), Vec3(0, 0, size)};
  m.triangles = {{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}};
  return m;
}

TriangleMesh make_cube(double size, int per_edge) {
  require(std::isfinite(size) && size > 0, "cube size", size, "must be positive");
  require(per_edge >= 1 && per_edge <= 4096, "cube per_edge", per_edge, "must be in [1, 4096]");
  const int n = per_edge;
  TriangleMesh m;
  // Lattice points (i, j, k) in [0, n]^3 on the cube's surface, shared between faces.
  std::map<std::array<int, 3>, int> index;
  auto vertex = [&](const std::array<int, 3>& ijk) {
    auto it = index.find(ijk);
    if (it != index.end()) return it->second;
    const int id = static_cast<int>(m.positions.size());
    m.positions.emplace_back(size * (ijk[0] / double(n) - 0.5), size * (ijk[1] / double(n) - 0.5),
                             size * (ijk[2] / double(n) - 0.5));
    index.emplace(ijk, id);
    return id;
  };
  // Each face: fixed axis and side, and (u, v) axes with u x v = outward normal.
  struct Face {
    int axis, side, u, v;
  };
  const Face faces[6] = {{0, 1, 1, 2}, {0, 0, 2, 1}, {1, 1, 2, 0}, {1, 0, 0, 2}, {2, 1, 0, 1}, {2, 0, 1, 0}};
  for (const Face& f : faces) {
    auto at = [&](int a, int b) {
      std::array<int, 3> ijk{};
      ijk[static_cast<std::size_t>(f.axis)] = f.side * n;
      ijk[static_cast<std::size_t>(f.u)] = a;
      ijk[static_cast<std::size_t>(f.v)] = b;
      return vertex(ijk);
    };
    for (int a = 0; a < n; ++a)
      for (int b = 0; b < n; ++b) {
        const int p00 = at(a, b), p10 = at(a + 1, b), p11 = at(a + 1, b + 1), p01 = at(a, b + 1);
        m.triangles.push_back({p00, p10, p11});
        m.triangles.push_back({p00, p11, p01});
      }
  }
  orient_outward(m);
  return m;
}

TriangleMesh make_icosphere(int subdivisions, double radius) {
  require(std::isfinite(radius) && radius > 0, "icosphere radius", radius, "must be positive");
  require(subdivisions >= 0 && subdivisions <= 8, "icosphere subdivisions", subdivisions, "must be in [0, 8]");
  const double g = (1.0 + std::sqrt(5.0)) / 2.0;
  TriangleMesh m;
  m.positions = {Vec3(-1, g, 0),  Vec3(1, g, 0),  Vec3(-1, -g, 0), Vec3(1, -g, 0), Vec3(0, -1, g),  Vec3(0, 1, g),
                 Vec3(0, -1, -g), Vec3(0, 1, -g), Vec3(g, 0, -1),  Vec3(g, 0, 1),  Vec3(-g, 0, -1), Vec3(-g, 0, 1)};
  m.triangles = {{0, 11, 5},  {0, 5, 1},  {0, 1, 7},  {0, 7, 10}, {0, 10, 11}, {1, 5, 9}, {5, 11, 4},
                 {11, 10, 2}, {10, 7, 6}, {7, 1, 8},  {3, 9, 4},  {3, 4, 2},   {3, 2, 6}, {3, 6, 8},
                 {3, 8, 9},   {4, 9, 5},  {2, 4, 11}, {6, 2, 10}, {8, 6, 7},   {9, 8, 1}};
  for (Vec3& p : m.positions) p.normalize();
  for (int level = 0; level < subdivisions; ++level) {
    std::map<std::pair<int, int>, int> midpoint;
    auto mid = [&](int a, int b) {
      const std::pair<int, int> key(std::min(a, b), std::max(a, b));
      auto it = midpoint.find(key);
      if (it != midpoint.end()) return it->second;
      const int id = static_cast<int>(m.positions.size());
      m.positions.push_back(
          (m.positions[static_cast<std::size_t>(a)] + m.positions[static_cast<std::size_t>(b)]).normalized());
      midpoint.emplace(key, id);
      return id;
    };
    std::vector<Triangle> finer;
    finer.reserve(m.triangles.size() * 4);
    for (const Triangle& t : m.triangles) {
      const int ab = mid(t[0], t[1]), bc = mid(t[1], t[2]), ca = mid(t[2], t[0]);
      finer.push_back({t[0], ab, ca});
      finer.push_back({t[1], bc, ab});
      finer.push_back({t[2], ca, bc});
      finer.push_back({ab, bc, ca});
    }
    m.triangles = std::move(finer);
  }
  for (Vec3& p : m.positions) p *= radius;
  orient_outward(m);
  return m;
}

TriangleMesh make_closed_tube(const std::vector<std::vector<Vec3>>& rings, const Vec3& first_pole,
                              const Vec3& last_pole) {
  if (rings.empty()) throw OptionError("make_closed_tube: rings is empty");
  const std::size_t segments = rings.front().size();
  if (segments < 3) throw OptionError("make_closed_tube: a ring has fewer than 3 points");
  for (const auto& r : rings)
    if (r.size() != segments) throw OptionError("make_closed_tube: rings differ in size");
  const int m = static_cast<int>(segments);
  const int count = static_cast<int>(rings.size());
  TriangleMesh mesh;
  mesh.positions.reserve(rings.size() * segments + 2);
  mesh.positions.push_back(first_pole);
  for (const auto& r : rings) mesh.positions.insert(mesh.positions.end(), r.begin(), r.end());
  mesh.positions.push_back(last_pole);
  const int last = static_cast<int>(mesh.positions.size()) - 1;
  auto id = [m](int i, int j) { return 1 + i * m + (j % m); };
  for (int j = 0; j < m; ++j) mesh.triangles.push_back({0, id(0, j + 1), id(0, j)});
  for (int i = 0; i + 1 < count; ++i)
    for (int j = 0; j < m; ++j) {
      const int a = id(i, j), b = id(i, j + 1), c = id(i + 1, j + 1), d = id(i + 1, j);
      mesh.triangles.push_back({a, b, c});
      mesh.triangles.push_back({a, c, d});
    }
  for (int j = 0; j < m; ++j) mesh.triangles.push_back({last, id(count - 1, j), id(count - 1, j + 1)});
  orient_outward(mesh);
  return mesh;
}

TriangleMesh make_capsule(double length, double radius, int segments) {
  require(std::isfinite(radius) && radius > 0, "capsule radius", radius, "must be positive");
  require(std::isfinite(length) && length >= 2 * radius, "capsule length", length, "must be at least twice the radius");
  require(segments >= 3, "capsule segments", segments, "must be at least 3");
  const int cap_rings = std::max(2, segments / 4);
  const double cylinder = length - 2 * radius;
  const double spacing = 2 * kPi * radius / segments;
  const double between = std::round(cylinder / spacing);
  require(between < 1e6, "capsule length", length, "gives more than 1e6 rings; raise radius");
  const int cylinder_rings = std::max(0, static_cast<int>(between) - 1);
  const Vec3 u(0, 1, 0), v(0, 0, 1);
  std::vector<std::vector<Vec3>> rings;
  const double x0 = -0.5 * cylinder, x1 = 0.5 * cylinder;
  for (int k = 1; k <= cap_rings; ++k) {  // left hemisphere, pole side first
    const double phi = 0.5 * kPi * k / cap_rings;
    rings.push_back(ring(Vec3(x0 - radius * std::cos(phi), 0, 0), u, v, radius * std::sin(phi), segments));
  }
  for (int k = 1; k <= cylinder_rings; ++k) {
    const double x = x0 + cylinder * k / (cylinder_rings + 1);
    rings.push_back(ring(Vec3(x, 0, 0), u, v, radius, segments));
  }
  if (cylinder > 0) rings.push_back(ring(Vec3(x1, 0, 0), u, v, radius, segments));
  for (int k = cap_rings - 1; k >= 1; --k) {
    const double phi = 0.5 * kPi * k / cap_rings;
    rings.push_back(ring(Vec3(x1 + radius * std::cos(phi), 0, 0), u, v, radius * std::sin(phi), segments));
  }
  return make_closed_tube(rings, Vec3(-0.5 * length, 0, 0), Vec3(0.5 * length, 0, 0));
}

TriangleMesh make_bent_tube(double bend_radius, double tube_radius, double angle, int segments, int rings) {
  require(std::isfinite(tube_radius) && tube_radius > 0, "bent tube tube_radius", tube_radius, "must be positive");
  require(std::isfinite(bend_radius) && bend_radius > tube_radius, "bent tube bend_radius", bend_radius,
          "must exceed tube_radius");
  require(std::isfinite(angle) && angle > 0 && angle < 2 * kPi, "bent tube angle", angle,
          "must be in (0, 2 pi) radians");
  require(segments >= 3, "bent tube segments", segments, "must be at least 3");
  require(rings >= 0 && rings <= 1000000, "bent tube rings", rings, "must be in [0, 1e6]");
  int count = rings;
  if (count == 0) {
    const double spacing = 2 * kPi * tube_radius / segments;
    count = std::max(2, static_cast<int>(std::min(1e6, std::ceil(angle * bend_radius / spacing))) + 1);
  }
  count = std::max(count, 2);
  std::vector<std::vector<Vec3>> all;
  all.reserve(static_cast<std::size_t>(count));
  const Vec3 z(0, 0, 1);
  for (int i = 0; i < count; ++i) {
    const double a = angle * i / (count - 1);
    const Vec3 radial(std::cos(a), std::sin(a), 0);
    all.push_back(ring(bend_radius * radial, radial, z, tube_radius, segments));
  }
  return make_closed_tube(all, Vec3(bend_radius, 0, 0), bend_radius * Vec3(std::cos(angle), std::sin(angle), 0));
}

TriangleMesh make_torus(double major_radius, double minor_radius, int major_segments, int minor_segments) {
  require(std::isfinite(minor_radius) && minor_radius > 0, "torus minor_radius", minor_radius, "must be positive");
  require(std::isfinite(major_radius) && major_radius > minor_radius, "torus major_radius", major_radius,
          "must exceed minor_radius");
  require(major_segments >= 3 && major_segments <= 100000, "torus major_segments", major_segments,
          "must be in [3, 1e5]");
  require(minor_segments >= 3 && minor_segments <= 100000, "torus minor_segments", minor_segments,
          "must be in [3, 1e5]");
  TriangleMesh m;
  const Vec3 z(0, 0, 1);
  for (int i = 0; i < major_segments; ++i) {
    const double a = 2 * kPi * i / major_segments;
    const Vec3 radial(std::cos(a), std::sin(a), 0);
    const auto r = ring(major_radius * radial, radial, z, minor_radius, minor_segments);
    m.positions.insert(m.positions.end(), r.begin(), r.end());
  }
  auto id = [&](int i, int j) { return (i % major_segments) * minor_segments + (j % minor_segments); };
  for (int i = 0; i < major_segments; ++i)
    for (int j = 0; j < minor_segments; ++j) {
      const int a = id(i, j), b = id(i, j + 1), c = id(i + 1, j + 1), d = id(i + 1, j);
      m.triangles.push_back({a, b, c});
      m.triangles.push_back({a, c, d});
    }
  orient_outward(m);
  return m;
}

PolygonSoup make_two_tetrahedra_sharing_vertex() {
  const TriangleMesh tet = make_tetrahedron(1.0);
  PolygonSoup soup;
  soup.points = tet.positions;                                                                      // 0..3
  for (int k = 1; k <= 3; ++k) soup.points.push_back(-tet.positions[static_cast<std::size_t>(k)]);  // 4..6
  for (const Triangle& t : tet.triangles) soup.polygons.push_back({t[0], t[1], t[2]});
  // Mirroring through the origin reverses orientation, so each mirrored triangle is reversed.
  auto mirrored = [](int i) { return i == 0 ? 0 : i + 3; };
  for (const Triangle& t : tet.triangles) soup.polygons.push_back({mirrored(t[0]), mirrored(t[2]), mirrored(t[1])});
  return soup;
}

}  // namespace fascicle
