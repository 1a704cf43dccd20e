#pragma once
/// \file segment_tree.h
/// Nearest fibre segment to a point: a bounding-volume hierarchy over the segments of a set of
/// polylines (median split of the segment centres along the longest axis, leaves of up to 4
/// segments), searched nearest child first and pruned by box distance; exact distances, and a
/// cost that does not depend on how evenly the fibres fill the space (a uniform grid's ring
/// search slows down by orders of magnitude where fibres leave much of a muscle empty).
#include "geometry/mesh.h"

#include <array>
#include <vector>

namespace fascicle {

class SegmentTree {
 public:
  explicit SegmentTree(const Polylines& fibres);
  /// Distance from p to the nearest segment (infinity when there is none); the nearest one's
  /// number into `segment` when given (segments are numbered fibre by fibre, point by point).
  double nearest(const Vec3& p, int* segment = nullptr) const;
  /// Segment `i`'s end points.
  const std::array<Vec3, 2>& segment(int i) const { return segments_[static_cast<std::size_t>(i)]; }

 private:
  struct Node {
    Vec3 lo, hi;
    int left = -1, right = -1;  ///< children, -1 for a leaf
    int begin = 0, end = 0;     ///< leaf: range in order_
  };
  int build(int begin, int end);
  std::vector<std::array<Vec3, 2>> segments_;
  std::vector<int> order_;
  std::vector<Node> nodes_;
};

/// Squared distance from p to the segment [a, b].
double segment_distance2(const Vec3& p, const Vec3& a, const Vec3& b);

}  // namespace fascicle
