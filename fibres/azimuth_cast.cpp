#include "fibres/azimuth_cast.h"

#include <algorithm>
#include <cmath>

namespace fascicle {

namespace {

constexpr double kTwoPi = 6.283185307179586476925286766559;

// The bin below an offset's azimuth and the weight of the one above it.
std::pair<int, double> locate(const AzimuthCast& cast, const Vec3& offset) {
  double phi = std::atan2(offset.dot(cast.v), offset.dot(cast.u));
  if (!std::isfinite(phi)) phi = 0.0;
  const double x = (phi < 0.0 ? phi + kTwoPi : phi) / kTwoPi * AzimuthCast::kBins;
  const double below = std::floor(x);
  const int bin = static_cast<int>(below) % AzimuthCast::kBins;
  return {bin < 0 ? bin + AzimuthCast::kBins : bin, std::clamp(x - below, 0.0, 1.0)};
}

}  // namespace

double AzimuthCast::factor(const Vec3& offset) const {
  const auto [bin, w] = locate(*this, offset);
  return (1.0 - w) * bins[static_cast<std::size_t>(bin)] + w * bins[static_cast<std::size_t>((bin + 1) % kBins)];
}

double AzimuthCast::smallest() const { return placed ? *std::min_element(bins.begin(), bins.end()) : 0.0; }

double AzimuthCast::largest() const { return placed ? *std::max_element(bins.begin(), bins.end()) : 0.0; }

AzimuthCast cast_azimuth_face(const Vec3& centre, const std::vector<Vec3>& offsets, const Vec3& axis,
                              const std::function<bool(const Vec3&, const Vec3&, Vec3&)>& hit,
                              const std::function<bool(const Vec3&)>& near,
                              const std::function<bool(const Vec3&)>& inside, int steps) {
  AzimuthCast out;
  const Vec3 n = axis.normalized();
  if (offsets.empty() || steps < 1 || !n.allFinite()) return out;
  out.u = n.unitOrthogonal();
  out.v = n.cross(out.u);
  const auto lands = [&](const Vec3& offset, double factor, Vec3& end) {
    return hit(centre + factor * offset, n, end) && near(end);
  };
  // The one factor for the whole face first: the largest step at which every end lands.
  std::vector<double> step(static_cast<std::size_t>(steps), 1.0);
  for (std::size_t s = 1; s < step.size(); ++s) step[s] = 0.8 * step[s - 1];
  std::vector<Vec3> ends(offsets.size());
  std::size_t first = 0;
  bool all = false;
  for (; first < step.size(); ++first) {
    all = true;
    for (std::size_t q = 0; q < offsets.size() && all; ++q) all = lands(offsets[q], step[first], ends[q]);
    if (all) break;
  }
  if (!all) return out;
  const double uniform = step[first];
  // Its ends' depths along the axis: a larger factor for an end is kept only while its end lands
  // on the area within them, so that the face stays as deep as the uniform one (an end cast far
  // past the others, along a tendon or into a fold of the area, would pull the lattice with it).
  double shallowest = 1e300, deepest = -1e300;
  for (const Vec3& e : ends) {
    const double depth = (e - centre).dot(n);
    shallowest = std::min(shallowest, depth);
    deepest = std::max(deepest, depth);
  }
  const double slack = 1e-9 * (1.0 + std::abs(deepest) + std::abs(shallowest));
  // A start outside the muscle (an affine fit wider than a bent end) meets the surface from
  // outside, where the first hit can lie on the far side of the end.
  const auto in_band = [&](const Vec3& offset, double factor, Vec3& end) {
    if (factor > uniform && !inside(centre + factor * offset)) return false;
    if (!lands(offset, factor, end)) return false;
    const double depth = (end - centre).dot(n);
    return depth >= shallowest - slack && depth <= deepest + slack;
  };
  // Each end's largest factor reached by steps of 1 / 0.8 up from the uniform one, every step
  // landing in the band; both bins bracketing its azimuth are held at or below it.
  out.bins.fill(1.0);
  for (const Vec3& o : offsets) {
    double found = uniform;
    Vec3 end;
    for (std::size_t s = first; s > 0 && in_band(o, step[s - 1], end); --s) found = step[s - 1];
    const int bin = locate(out, o).first;
    double& below = out.bins[static_cast<std::size_t>(bin)];
    double& above = out.bins[static_cast<std::size_t>((bin + 1) % AzimuthCast::kBins)];
    below = std::min(below, found);
    above = std::min(above, found);
  }
  // Between its steps an end can still miss (the area is not star-shaped seen from the centre):
  // its two bins step down, never below the uniform factor, at which every end lands in the band.
  std::vector<Vec3> trial(offsets.size());
  for (int round = 0; round <= steps; ++round) {
    std::vector<int> lower;
    for (std::size_t q = 0; q < offsets.size(); ++q)
      if (!in_band(offsets[q], out.factor(offsets[q]), trial[q])) {
        const int bin = locate(out, offsets[q]).first;
        lower.push_back(bin);
        lower.push_back((bin + 1) % AzimuthCast::kBins);
      }
    if (lower.empty()) {
      out.placed = true;
      out.ends = std::move(trial);
      return out;
    }
    std::sort(lower.begin(), lower.end());
    lower.erase(std::unique(lower.begin(), lower.end()), lower.end());
    for (int bin : lower) {
      double& b = out.bins[static_cast<std::size_t>(bin)];
      b = std::max(uniform, b * 0.8);
    }
  }
  out.bins.fill(uniform);
  out.placed = true;
  out.ends = std::move(ends);
  return out;
}

}  // namespace fascicle
