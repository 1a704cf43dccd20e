#pragma once
// Closed genus-0 test meshes built in code for the morph tests (icosphere, subdivided cube,
// capsule of any aspect, bent capsule). Outward counter-clockwise triangles.

#include "geometry/mesh.h"

#include <cmath>
#include <map>
#include <tuple>

namespace fascicle::test {

/// Icosphere of radius 1: icosahedron subdivided `levels` times (20 * 4^levels triangles).
inline TriangleMesh icosphere(int levels) {
  const double t = (1.0 + std::sqrt(5.0)) / 2.0;
  TriangleMesh m;
  m.positions = {{-1, t, 0},  {1, t, 0},  {-1, -t, 0}, {1, -t, 0}, {0, -1, t},  {0, 1, t},
                 {0, -1, -t}, {0, 1, -t}, {t, 0, -1},  {t, 0, 1},  {-t, 0, -1}, {-t, 0, 1}};
  for (auto& p : m.positions) p.normalize();
  m.triangles = {{0, 11, 5},  {0, 5, 1},  {0, 1, 7},  {0, 7, 10}, {0, 10, 11}, {1, 5, 9}, {5, 11, 4},
                 {11, 10, 2}, {10, 7, 6}, {7, 1, 8},  {3, 9, 4},  {3, 4, 2},   {3, 2, 6}, {3, 6, 8},
                 {3, 8, 9},   {4, 9, 5},  {2, 4, 11}, {6, 2, 10}, {8, 6, 7},   {9, 8, 1}};
  for (int level = 0; level < levels; ++level) {
    std::map<std::pair<int, int>, int> mid;
    auto midpoint = [&](int a, int b) {
      const auto key = std::minmax(a, b);
      auto it = mid.find(key);
      if (it != mid.end()) return it->second;
      m.positions.push_back((m.positions[a] + m.positions[b]).normalized());
      const int id = static_cast<int>(m.positions.size()) - 1;
      mid.emplace(key, id);
      return id;
    };
    std::vector<Triangle> next;
    for (const Triangle& f : m.triangles) {
      const int a = midpoint(f[0], f[1]), b = midpoint(f[1], f[2]), c = midpoint(f[2], f[0]);
      next.push_back({f[0], a, c});
      next.push_back({f[1], b, a});
      next.push_back({f[2], c, b});
      next.push_back({a, b, c});
    }
    m.triangles = std::move(next);
  }
  return m;
}

/// Cube [-1,1]^3 with every face cut into n x n squares, two triangles each.
inline TriangleMesh subdivided_cube(int n) {
  TriangleMesh m;
  std::map<std::tuple<int, int, int>, int> ids;
  auto vertex = [&](int i, int j, int k) {
    const auto key = std::make_tuple(i, j, k);
    auto it = ids.find(key);
    if (it != ids.end()) return it->second;
    m.positions.emplace_back(2.0 * i / n - 1.0, 2.0 * j / n - 1.0, 2.0 * k / n - 1.0);
    const int id = static_cast<int>(m.positions.size()) - 1;
    ids.emplace(key, id);
    return id;
  };
  // For each axis and side, a grid with (u, v) axes chosen so that u x v points outward.
  for (int axis = 0; axis < 3; ++axis)
    for (int side = 0; side < 2; ++side) {
      const int u_axis = (axis + 1) % 3, v_axis = (axis + 2) % 3;
      for (int a = 0; a < n; ++a)
        for (int b = 0; b < n; ++b) {
          int corner[4];
          const int du[4] = {0, 1, 1, 0}, dv[4] = {0, 0, 1, 1};
          for (int c = 0; c < 4; ++c) {
            int idx[3];
            idx[axis] = side * n;
            idx[u_axis] = a + du[c];
            idx[v_axis] = b + dv[c];
            corner[c] = vertex(idx[0], idx[1], idx[2]);
          }
          if (side == 1) {
            m.triangles.push_back({corner[0], corner[1], corner[2]});
            m.triangles.push_back({corner[0], corner[2], corner[3]});
          } else {
            m.triangles.push_back({corner[0], corner[2], corner[1]});
            m.triangles.push_back({corner[0], corner[3], corner[2]});
          }
        }
    }
  return m;
}

/// Capsule along z: radius `r`, total length `length` (from pole to pole), `around` vertices per
/// ring, rings spaced about as far apart as neighbours on a ring.
inline TriangleMesh capsule(double r, double length, int around) {
  TriangleMesh m;
  const double cylinder = std::max(0.0, length - 2.0 * r);
  const double spacing = 2.0 * M_PI * r / around;
  const int cap_rings = std::max(2, static_cast<int>(std::ceil(0.5 * M_PI * r / spacing)));
  const int body_rings = std::max(1, static_cast<int>(std::ceil(cylinder / spacing)));
  std::vector<std::pair<double, double>> profile;  // (ring radius, z)
  for (int i = 1; i <= cap_rings; ++i) {
    const double a = 0.5 * M_PI * i / cap_rings;
    profile.emplace_back(r * std::sin(a), r - r * std::cos(a));
  }
  for (int i = 1; i < body_rings; ++i) profile.emplace_back(r, r + cylinder * i / body_rings);
  for (int i = cap_rings; i >= 1; --i) {
    const double a = 0.5 * M_PI * i / cap_rings;
    profile.emplace_back(r * std::sin(a), r + cylinder + r * std::cos(a));
  }
  m.positions.emplace_back(0, 0, 0);
  for (std::size_t ring = 0; ring < profile.size(); ++ring)
    for (int k = 0; k < around; ++k) {
      const double phi = 2.0 * M_PI * (k + 0.5 * (ring % 2)) / around;
      m.positions.emplace_back(profile[ring].first * std::cos(phi), profile[ring].first * std::sin(phi),
                               profile[ring].second);
    }
  m.positions.emplace_back(0, 0, length);
  const int rings = static_cast<int>(profile.size());
  const int top = static_cast<int>(m.positions.size()) - 1;
  auto id = [&](int ring, int k) { return 1 + ring * around + ((k % around) + around) % around; };
  for (int k = 0; k < around; ++k) m.triangles.push_back({0, id(0, k + 1), id(0, k)});
  for (int ring = 0; ring + 1 < rings; ++ring)
    for (int k = 0; k < around; ++k) {
      // Odd rings are rotated by half a step.
      const int s = ring % 2;
      m.triangles.push_back({id(ring, k), id(ring, k + 1), id(ring + 1, k + s)});
      m.triangles.push_back({id(ring, k + 1), id(ring + 1, k + 1 + s), id(ring + 1, k + s)});
    }
  for (int k = 0; k < around; ++k) m.triangles.push_back({top, id(rings - 1, k), id(rings - 1, k + 1)});
  return m;
}

/// A capsule bent along a circular arc of `degrees` in the xz-plane.
inline TriangleMesh bent_capsule(double r, double length, int around, double degrees) {
  TriangleMesh m = capsule(r, length, around);
  const double bend = length / (degrees * M_PI / 180.0);
  for (Vec3& p : m.positions) {
    const double phi = p.z() / bend;
    p = Vec3(bend - (bend - p.x()) * std::cos(phi), p.y(), (bend - p.x()) * std::sin(phi));
  }
  return m;
}

}  // namespace fascicle::test
