#include "repair/clean_soup.h"

#include <algorithm>
#include <unordered_set>

namespace fascicle {

namespace {

// Ear clipping of a simple polygon given by corner indices, in the plane orthogonal to its
// Newell normal. Returns false when no ear is found (self-overlapping outline); the caller then
// uses a fan, and any degenerate triangles are removed later.
bool ear_clip(const std::vector<Vec3>& points, std::vector<int> poly, std::vector<Triangle>& out) {
  Vec3 normal = Vec3::Zero();
  for (std::size_t i = 0; i < poly.size(); ++i) {
    const Vec3& a = points[poly[i]];
    const Vec3& b = points[poly[(i + 1) % poly.size()]];
    normal +=
        Vec3((a.y() - b.y()) * (a.z() + b.z()), (a.z() - b.z()) * (a.x() + b.x()), (a.x() - b.x()) * (a.y() + b.y()));
  }
  if (normal.norm() == 0.0) return false;
  normal.normalize();
  const Vec3 u = normal.unitOrthogonal();
  const Vec3 v = normal.cross(u);
  auto p2 = [&](int idx) { return Eigen::Vector2d(points[idx].dot(u), points[idx].dot(v)); };
  auto cross2 = [](const Eigen::Vector2d& a, const Eigen::Vector2d& b, const Eigen::Vector2d& c) {
    return (b - a).x() * (c - a).y() - (b - a).y() * (c - a).x();
  };
  std::vector<Triangle> result;
  while (poly.size() > 3) {
    bool clipped = false;
    const std::size_t n = poly.size();
    for (std::size_t i = 0; i < n && !clipped; ++i) {
      const int ia = poly[(i + n - 1) % n], ib = poly[i], ic = poly[(i + 1) % n];
      const Eigen::Vector2d a = p2(ia), b = p2(ib), c = p2(ic);
      if (cross2(a, b, c) <= 0.0) continue;  // reflex or flat corner
      bool contains = false;
      for (std::size_t j = 0; j < n && !contains; ++j) {
        const int ij = poly[j];
        if (ij == ia || ij == ib || ij == ic) continue;
        const Eigen::Vector2d p = p2(ij);
        contains = cross2(a, b, p) >= 0.0 && cross2(b, c, p) >= 0.0 && cross2(c, a, p) >= 0.0;
      }
      if (contains) continue;
      result.push_back({ia, ib, ic});
      poly.erase(poly.begin() + static_cast<long>(i));
      clipped = true;
    }
    if (!clipped) return false;
  }
  result.push_back({poly[0], poly[1], poly[2]});
  out.insert(out.end(), result.begin(), result.end());
  return true;
}

}  // namespace

TriangleMesh clean_soup(const PolygonSoup& soup, const std::vector<int>& representative, CleanSoupCounts* counts) {
  CleanSoupCounts local;
  std::vector<Triangle> triangles;
  triangles.reserve(soup.polygons.size());
  std::vector<int> poly;
  for (const auto& polygon : soup.polygons) {
    poly.clear();
    for (int idx : polygon) {
      const int r = representative[idx];
      if (poly.empty() || poly.back() != r) poly.push_back(r);
    }
    while (poly.size() > 1 && poly.front() == poly.back()) poly.pop_back();
    if (poly.size() < 3) {
      ++local.degenerate_removed;
      continue;
    }
    if (poly.size() == 3) {
      triangles.push_back({poly[0], poly[1], poly[2]});
      continue;
    }
    ++local.polygons_triangulated;
    if (!ear_clip(soup.points, poly, triangles))
      for (std::size_t k = 2; k < poly.size(); ++k) triangles.push_back({poly[0], poly[k - 1], poly[k]});
  }

  // Drop triangles with a repeated corner (from welding or a figure-eight polygon) and
  // duplicates (same three corners in any order: a doubled face or a zero-thickness fin).
  struct KeyHash {
    std::size_t operator()(const Triangle& t) const {
      return (static_cast<std::size_t>(t[0]) * 73856093u) ^ (static_cast<std::size_t>(t[1]) * 19349663u) ^
             (static_cast<std::size_t>(t[2]) * 83492791u);
    }
  };
  std::unordered_set<Triangle, KeyHash> seen;
  seen.reserve(triangles.size());
  TriangleMesh mesh;
  mesh.triangles.reserve(triangles.size());
  for (const Triangle& t : triangles) {
    if (t[0] == t[1] || t[1] == t[2] || t[0] == t[2]) {
      ++local.degenerate_removed;
      continue;
    }
    Triangle key = t;
    std::sort(key.begin(), key.end());
    if (!seen.insert(key).second) {
      ++local.duplicates_removed;
      continue;
    }
    mesh.triangles.push_back(t);
  }

  // Compact the points.
  std::vector<int> new_index(soup.points.size(), -1);
  for (Triangle& t : mesh.triangles)
    for (int& idx : t) {
      if (new_index[idx] < 0) {
        new_index[idx] = static_cast<int>(mesh.positions.size());
        mesh.positions.push_back(soup.points[idx]);
      }
      idx = new_index[idx];
    }
  // Every weld representative that no remaining face uses is an unreferenced point.
  long representatives = 0;
  for (std::size_t i = 0; i < representative.size(); ++i)
    if (representative[i] == static_cast<int>(i)) ++representatives;
  local.unreferenced_removed = representatives - static_cast<long>(mesh.positions.size());
  if (counts) *counts = local;
  return mesh;
}

}  // namespace fascicle
