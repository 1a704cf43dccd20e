#pragma once
/// \file splitmix64.h
/// The SplitMix64 finaliser (Steele, Lea and Flood 2014, "Fast splittable pseudorandom number
/// generators", OOPSLA): a fixed 64-bit mix, one serves every place that derives numbers from an
/// index or a seed (the defect injector's seeds, the coarse start's offsets), so the same input
/// gives the same bits on every run and thread count.

#include <cstdint>

namespace fascicle {

/// The SplitMix64 output for state x (x plus the golden-ratio increment, then mixed).
inline std::uint64_t splitmix64(std::uint64_t x) {
  x += 0x9E3779B97F4A7C15ULL;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ULL;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBULL;
  return x ^ (x >> 31);
}

/// A number in [0, 1) from x: the top 53 bits of splitmix64(x).
inline double splitmix64_unit(std::uint64_t x) { return static_cast<double>(splitmix64(x) >> 11) * 0x1.0p-53; }

}  // namespace fascicle
