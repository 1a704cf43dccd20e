#include "morph/attachments.h"

#include "geometry/errors.h"
#include "geometry/mesh_stats.h"
#include "morph/sphere_locator.h"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <functional>
#include <set>
#include <cstdio>
#include <numeric>

namespace fascicle {
namespace {

std::string number(double value) {
  char buffer[64];
  std::snprintf(buffer, sizeof buffer, "%.4g", value);
  return buffer;
}

// Each vertex's neighbours over the triangles' edges, in compressed rows (an edge may be listed
// twice; harmless for connectivity).
struct VertexNeighbours {
  std::vector<int> start, list;
  explicit VertexNeighbours(const TriangleMesh& mesh) : start(mesh.positions.size() + 1, 0) {
    for (const Triangle& t : mesh.triangles)
      for (int k = 0; k < 3; ++k) start[t[k] + 1] += 2;
    std::partial_sum(start.begin(), start.end(), start.begin());
    list.resize(start.back());
    std::vector<int> fill(start.begin(), start.end() - 1);
    for (const Triangle& t : mesh.triangles)
      for (int k = 0; k < 3; ++k) {
        list[fill[t[k]]++] = t[(k + 1) % 3];
        list[fill[t[k]]++] = t[(k + 2) % 3];
      }
  }
};

struct EndBand {
  double threshold;  // the band is every vertex with `along` on the end's side of this value
  int pieces;        // connected pieces of the band at the requested fraction
};

// The band at one end (`upper`: along >= threshold, else along <= threshold), starting at
// `threshold` and, when `connect` and it is several pieces, widened vertex by vertex (nearest
// the end first) until it is one connected piece (then by `margin` more, within `limit`) or
// reaches `limit`. Union-find over the vertices added so far.
EndBand end_band(const std::vector<double>& along, const std::vector<char>& used, const VertexNeighbours& nb,
                 bool upper, double threshold, double limit, bool connect, double margin) {
  auto inside = [&](double a, double t) { return upper ? a >= t : a <= t; };
  std::vector<int> parent(along.size(), -1);  // -1: not in the band yet
  auto find = [&](int v) {
    while (parent[v] != v) v = parent[v] = parent[parent[v]];
    return v;
  };
  int pieces = 0;
  auto add = [&](int v) {
    parent[v] = v;
    ++pieces;
    for (int i = nb.start[v]; i < nb.start[v + 1]; ++i) {
      const int w = nb.list[i];
      if (parent[w] < 0) continue;
      const int a = find(v), b = find(w);
      if (a != b) {
        parent[a] = b;
        --pieces;
      }
    }
  };
  for (std::size_t v = 0; v < along.size(); ++v)
    if (used[v] && inside(along[v], threshold)) add(static_cast<int>(v));
  EndBand out{threshold, pieces};
  if (!connect || pieces <= 1) return out;
  // Widen, nearest the end first, by whole groups of equal `along`, so that the band is exactly
  // what its threshold selects.
  std::vector<int> order;
  for (std::size_t v = 0; v < along.size(); ++v)
    if (used[v] && parent[v] < 0 && inside(along[v], limit)) order.push_back(static_cast<int>(v));
  std::sort(order.begin(), order.end(),
            [&](int a, int b) { return upper ? along[a] > along[b] : along[a] < along[b]; });
  for (std::size_t next = 0; next < order.size();) {
    const double value = along[order[next]];
    while (next < order.size() && along[order[next]] == value) add(order[next++]);
    if (pieces == 1) {
      out.threshold = upper ? std::max(value - margin, limit) : std::min(value + margin, limit);
      return out;
    }
  }
  return out;  // not connected within the limit: the requested band
}

}  // namespace

void AttachmentOptions::validate() const {
  if (!(max_landmark_distance > 0.0))
    throw OptionError("attachment option max_landmark_distance = " + std::to_string(max_landmark_distance) +
                      ": must be > 0");
  if (!(end_fraction > 0.0 && end_fraction < 0.5))
    throw OptionError("attachment option end_fraction = " + std::to_string(end_fraction) + ": must be in (0, 0.5)");
  if (!(connect_margin >= 0.0))
    throw OptionError("attachment option connect_margin = " + std::to_string(connect_margin) + ": must be >= 0");
  if (!(max_point_spacing > 0.0))
    throw OptionError("attachment option max_point_spacing = " + std::to_string(max_point_spacing) +
                      ": must be > 0");
  if (!(max_end_fraction >= end_fraction && max_end_fraction < 0.5))
    throw OptionError("attachment option max_end_fraction = " + std::to_string(max_end_fraction) +
                      ": must be in [end_fraction, 0.5)");
}

Vec3 AttachmentArea::centroid() const {
  Vec3 sum = Vec3::Zero();
  for (const SurfacePoint& p : points) sum += p.position;
  return points.empty() ? sum : Vec3(sum / static_cast<double>(points.size()));
}

bool AttachmentArea::near(const Vec3& x, double radius) const {
  const double r2 = radius * radius;
  return std::any_of(points.begin(), points.end(),
                     [&](const SurfacePoint& p) { return (p.position - x).squaredNorm() <= r2; });
}

nlohmann::json AttachmentArea::to_json() const {
  nlohmann::json j = {{"source", source}, {"points", points.size()}, {"max_distance", max_distance}};
  if (end_pieces > 0) {
    j["end_fraction"] = end_fraction;
    j["end_pieces"] = end_pieces;
  }
  if (!patch.triangles.empty()) j["patch_triangles"] = patch.triangles.size();
  return j;
}

AttachmentArea project_landmarks(const SurfaceQuery& query, double diagonal, const std::vector<Vec3>& landmarks,
                                 const std::string& source, const AttachmentOptions& options) {
  options.validate();
  if (landmarks.empty()) throw InputError(ErrorCode::landmarks, source + ": no landmark points");
  AttachmentArea area;
  area.source = source;
  const double tolerance = options.max_landmark_distance * diagonal;
  for (std::size_t i = 0; i < landmarks.size(); ++i) {
    SurfacePoint p = query.closest_point(landmarks[i]);
    if (p.distance > tolerance)
      throw InputError(ErrorCode::landmarks,
                       source + ": landmark " + std::to_string(i + 1) + " is " + number(p.distance) +
                           " from the muscle surface; at most " + number(tolerance) + " (" +
                           number(options.max_landmark_distance) +
                           " of the muscle's bounding-box diagonal) is accepted: is it the right muscle's file?");
    area.max_distance = std::max(area.max_distance, p.distance);
    area.points.push_back(p);
  }
  return area;
}

Attachments landmark_attachments(const TriangleMesh& mesh, const std::vector<Vec3>& origin,
                                 const std::string& origin_source, const std::vector<Vec3>& insertion,
                                 const std::string& insertion_source, const AttachmentOptions& options) {
  const SurfaceQuery query(mesh);
  const double diagonal = bounding_box(mesh.positions).diagonal();
  Attachments out;
  out.origin = project_landmarks(query, diagonal, origin, origin_source, options);
  out.insertion = project_landmarks(query, diagonal, insertion, insertion_source, options);
  if ((out.origin.centroid() - out.insertion.centroid()).norm() < 1e-6 * diagonal)
    throw InputError(ErrorCode::landmarks,
                     origin_source + " and " + insertion_source + ": origin and insertion areas have the same centre");
  return out;
}

Attachments automatic_attachments(const TriangleMesh& mesh, const AttachmentOptions& options) {
  options.validate();
  if (mesh.positions.empty() || mesh.triangles.empty()) throw TopologyError("automatic attachments: the mesh is empty");
  const std::size_t nv = mesh.positions.size();
  const PrincipalAxes principal = principal_axes(mesh.positions);
  const Vec3& mean = principal.mean;
  Vec3 axis = principal.major();
  if (axis.z() < 0.0) axis = -axis;
  double lo = 1e300, hi = -1e300;
  std::vector<double> along(nv);
  for (std::size_t v = 0; v < nv; ++v) {
    along[v] = (mesh.positions[v] - mean).dot(axis);
    lo = std::min(lo, along[v]);
    hi = std::max(hi, along[v]);
  }
  const double extent = hi - lo;
  const double band = options.end_fraction * extent;
  // One face and corner per vertex, to express vertices as surface points.
  std::vector<int> face_of(nv, -1), corner_of(nv, 0);
  for (std::size_t f = 0; f < mesh.triangles.size(); ++f)
    for (int k = 0; k < 3; ++k) {
      const int v = mesh.triangles[f][k];
      if (face_of[v] < 0) {
        face_of[v] = static_cast<int>(f);
        corner_of[v] = k;
      }
    }
  std::vector<char> used(nv);
  for (std::size_t v = 0; v < nv; ++v) used[v] = face_of[v] >= 0;
  const VertexNeighbours neighbours(mesh);
  const double widest = options.max_end_fraction * extent;
  const double margin = options.connect_margin * extent;
  const EndBand upper = end_band(along, used, neighbours, true, hi - band, hi - widest, options.connected_ends, margin);
  const EndBand lower =
      end_band(along, used, neighbours, false, lo + band, lo + widest, options.connected_ends, margin);
  Attachments out;
  out.automatic = true;
  out.origin.source = out.insertion.source = "automatic";
  out.origin.end_fraction = extent > 0.0 ? (hi - upper.threshold) / extent : options.end_fraction;
  out.insertion.end_fraction = extent > 0.0 ? (lower.threshold - lo) / extent : options.end_fraction;
  out.origin.end_pieces = upper.pieces;
  out.insertion.end_pieces = lower.pieces;
  for (std::size_t v = 0; v < nv; ++v) {
    if (face_of[v] < 0) continue;
    SurfacePoint p;
    p.face = face_of[v];
    p.barycentric = Vec3::Zero();
    p.barycentric[corner_of[v]] = 1.0;
    p.position = mesh.positions[v];
    if (along[v] >= upper.threshold) out.origin.points.push_back(p);
    if (along[v] <= lower.threshold) out.insertion.points.push_back(p);
  }
  // Points across the band's triangles (all three corners in the band): on each edge longer than
  // the spacing, and inside each such triangle, on a barycentric grid of n steps a side. A point
  // of the area's surface is then near an area point however long the mesh's edges.
  const double spacing = options.max_point_spacing * extent;
  if (spacing > 0.0) {
    const auto densify = [&](AttachmentArea& area, const std::function<bool(int)>& in) {
      std::set<std::pair<int, int>> edges_done;
      for (std::size_t f = 0; f < mesh.triangles.size(); ++f) {
        const Triangle& t = mesh.triangles[f];
        if (!in(t[0]) || !in(t[1]) || !in(t[2])) continue;
        const Vec3 &a = mesh.positions[t[0]], &b = mesh.positions[t[1]], &c = mesh.positions[t[2]];
        const double longest = std::max({(b - a).norm(), (c - b).norm(), (a - c).norm()});
        const int n = static_cast<int>(std::ceil(longest / spacing));
        if (n < 2) continue;
        const auto add = [&](int i, int j) {  // barycentric (n - i - j, i, j) / n
          SurfacePoint p;
          p.face = static_cast<int>(f);
          p.barycentric = Vec3(n - i - j, i, j) / n;
          p.position = p.barycentric[0] * a + p.barycentric[1] * b + p.barycentric[2] * c;
          area.points.push_back(p);
        };
        for (int i = 1; i < n; ++i)
          for (int j = 1; i + j < n; ++j) add(i, j);
        // Each edge once, from the first band triangle that has it (its neighbour skips it).
        for (int e = 0; e < 3; ++e) {
          const int u = t[e], w = t[(e + 1) % 3];
          if (!edges_done.insert({std::min(u, w), std::max(u, w)}).second) continue;
          for (int s = 1; s < n; ++s) {
            if (e == 0) add(s, 0);          // a -> b
            else if (e == 1) add(n - s, s);  // b -> c
            else add(0, n - s);             // c -> a
          }
        }
      }
    };
    densify(out.origin, [&](int v) { return face_of[v] >= 0 && along[v] >= upper.threshold; });
    densify(out.insertion, [&](int v) { return face_of[v] >= 0 && along[v] <= lower.threshold; });
  }
  return out;
}

Vec3 sphere_centre(const AttachmentArea& area, const std::vector<Vec3>& sphere,
                   const std::vector<Triangle>& triangles) {
  Vec3 sum = Vec3::Zero();
  for (const SurfacePoint& p : area.points) sum += point_on_sphere(sphere, triangles, p);
  const double n = sum.norm();
  return n > 0.0 ? Vec3(sum / n) : Vec3::UnitZ();
}

}  // namespace fascicle
