#include "fibres/landmark_strip.h"

#include "geometry/errors.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

namespace fascicle {

void StripOptions::validate() const {
  if (!(max_gap > 0.0 && max_gap <= 1.0))
    throw OptionError("strip max_gap: must be in (0, 1], got " + std::to_string(max_gap));
  if (!(step > 0.0 && step <= 0.1)) throw OptionError("strip step: must be in (0, 0.1], got " + std::to_string(step));
  if (max_points < 2) throw OptionError("strip max_points: must be >= 2, got " + std::to_string(max_points));
}

nlohmann::json StripReport::to_json() const {
  return {{"joined", joined}, {"landmarks", landmarks}, {"joins", joins},
          {"gaps", gaps},     {"added", added},         {"longest_join", longest_join}};
}

AttachmentArea join_landmark_strip(const AttachmentArea& area, const SurfaceQuery& query, double length,
                                   const StripOptions& options, StripReport* report) {
  options.validate();
  if (!(length > 0.0 && std::isfinite(length)))
    throw OptionError("strip: the muscle length must be positive and finite, got " + std::to_string(length));
  StripReport r;
  const auto n = static_cast<int>(area.points.size());
  r.landmarks = n;
  AttachmentArea out = area;
  if (!options.join || n < 2 || n > options.max_points) {
    if (report) *report = r;
    return out;
  }
  r.joined = true;
  // Prim's algorithm on the complete graph of the points (Euclidean distances).
  const auto at = [&](int i) -> const Vec3& { return area.points[static_cast<std::size_t>(i)].position; };
  std::vector<char> in_tree(static_cast<std::size_t>(n), 0);
  std::vector<double> best(static_cast<std::size_t>(n), std::numeric_limits<double>::infinity());
  std::vector<int> parent(static_cast<std::size_t>(n), -1);
  best[0] = 0.0;
  const double max_gap = options.max_gap * length, step = options.step * length;
  for (int round = 0; round < n; ++round) {
    int u = -1;
    for (int v = 0; v < n; ++v)
      if (!in_tree[static_cast<std::size_t>(v)] &&
          (u < 0 || best[static_cast<std::size_t>(v)] < best[static_cast<std::size_t>(u)]))
        u = v;
    in_tree[static_cast<std::size_t>(u)] = 1;
    const int p = parent[static_cast<std::size_t>(u)];
    if (p >= 0) {
      const double d = (at(u) - at(p)).norm();
      if (d > max_gap) {
        ++r.gaps;
      } else {
        ++r.joins;
        r.longest_join = std::max(r.longest_join, d / length);
        const int pieces = static_cast<int>(std::ceil(d / step));
        for (int s = 1; s < pieces; ++s) {
          const double f = static_cast<double>(s) / pieces;
          SurfacePoint sp = query.closest_point((1.0 - f) * at(p) + f * at(u));
          sp.distance = 0.0;
          out.points.push_back(sp);
          ++r.added;
        }
      }
    }
    for (int v = 0; v < n; ++v) {
      if (in_tree[static_cast<std::size_t>(v)]) continue;
      const double d = (at(v) - at(u)).squaredNorm();
      if (d < best[static_cast<std::size_t>(v)] * best[static_cast<std::size_t>(v)] ||
          !std::isfinite(best[static_cast<std::size_t>(v)])) {
        best[static_cast<std::size_t>(v)] = std::sqrt(d);
        parent[static_cast<std::size_t>(v)] = u;
      }
    }
  }
  if (report) *report = r;
  return out;
}

nlohmann::json join_landmark_strips(Attachments& areas, const SurfaceQuery& query, double length,
                                    const StripOptions& options) {
  options.validate();
  if (!options.join) return {{"face_shape", "landmark_disks"}};
  StripReport origin, insertion;
  areas.origin = join_landmark_strip(areas.origin, query, length, options, &origin);
  areas.insertion = join_landmark_strip(areas.insertion, query, length, options, &insertion);
  return {{"face_shape", "joined_strip"}, {"origin", origin.to_json()}, {"insertion", insertion.to_json()}};
}

}  // namespace fascicle
