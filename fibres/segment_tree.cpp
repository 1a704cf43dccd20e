#include "fibres/segment_tree.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace fascicle {

namespace {

double box_distance2(const Vec3& lo, const Vec3& hi, const Vec3& p) {
  const Vec3 d = (lo - p).cwiseMax(p - hi).cwiseMax(0.0);
  return d.squaredNorm();
}

}  // namespace

double segment_distance2(const Vec3& p, const Vec3& a, const Vec3& b) {
  const Vec3 d = b - a;
  const double dd = d.squaredNorm();
  double t = dd > 0.0 ? (p - a).dot(d) / dd : 0.0;
  t = std::clamp(t, 0.0, 1.0);
  return (a + t * d - p).squaredNorm();
}

SegmentTree::SegmentTree(const Polylines& fibres) {
  for (const auto& line : fibres.lines)
    for (std::size_t k = 0; k + 1 < line.size(); ++k) segments_.push_back({line[k], line[k + 1]});
  order_.resize(segments_.size());
  for (std::size_t i = 0; i < order_.size(); ++i) order_[i] = static_cast<int>(i);
  nodes_.reserve(segments_.size() / 2 + 2);
  if (!segments_.empty()) build(0, static_cast<int>(segments_.size()));
}

double SegmentTree::nearest(const Vec3& p, int* segment) const {
  double best = std::numeric_limits<double>::infinity();
  int best_segment = -1;
  if (nodes_.empty()) return best;
  std::vector<int> stack;
  stack.reserve(64);
  stack.push_back(0);
  while (!stack.empty()) {
    const Node& node = nodes_[static_cast<std::size_t>(stack.back())];
    stack.pop_back();
    if (box_distance2(node.lo, node.hi, p) >= best) continue;
    if (node.left < 0) {
      for (int i = node.begin; i < node.end; ++i) {
        const int s = order_[static_cast<std::size_t>(i)];
        const auto& seg = segments_[static_cast<std::size_t>(s)];
        const double d = segment_distance2(p, seg[0], seg[1]);
        if (d < best) best = d, best_segment = s;
      }
      continue;
    }
    const Node& l = nodes_[static_cast<std::size_t>(node.left)];
    const Node& r = nodes_[static_cast<std::size_t>(node.right)];
    const double dl = box_distance2(l.lo, l.hi, p), dr = box_distance2(r.lo, r.hi, p);
    const int near = dl <= dr ? node.left : node.right, far = dl <= dr ? node.right : node.left;
    if (std::max(dl, dr) < best) stack.push_back(far);  // popped after the nearer child
    if (std::min(dl, dr) < best) stack.push_back(near);
  }
  if (segment) *segment = best_segment;
  return std::sqrt(best);
}

int SegmentTree::build(int begin, int end) {
  Node node;
  node.lo = Vec3::Constant(std::numeric_limits<double>::infinity());
  node.hi = -node.lo;
  Vec3 clo = node.lo, chi = node.hi;
  for (int i = begin; i < end; ++i) {
    const auto& seg = segments_[static_cast<std::size_t>(order_[static_cast<std::size_t>(i)])];
    node.lo = node.lo.cwiseMin(seg[0]).cwiseMin(seg[1]);
    node.hi = node.hi.cwiseMax(seg[0]).cwiseMax(seg[1]);
    const Vec3 c = 0.5 * (seg[0] + seg[1]);
    clo = clo.cwiseMin(c);
    chi = chi.cwiseMax(c);
  }
  node.begin = begin;
  node.end = end;
  const int index = static_cast<int>(nodes_.size());
  nodes_.push_back(node);
  if (end - begin <= 4) return index;
  int axis = 0;
  (chi - clo).maxCoeff(&axis);
  const int mid = begin + (end - begin) / 2;
  std::nth_element(order_.begin() + begin, order_.begin() + mid, order_.begin() + end, [&](int a, int b) {
    const auto& sa = segments_[static_cast<std::size_t>(a)];
    const auto& sb = segments_[static_cast<std::size_t>(b)];
    return sa[0][axis] + sa[1][axis] < sb[0][axis] + sb[1][axis];
  });
  const int left = build(begin, mid);
  const int right = build(mid, end);
  nodes_[static_cast<std::size_t>(index)].left = left;
  nodes_[static_cast<std::size_t>(index)].right = right;
  return index;
}

}  // namespace fascicle
