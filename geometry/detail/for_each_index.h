#pragma once
/// \file detail/for_each_index.h
/// body(i) for every i in [0, n), on TBB's threads in ranges of at least `grain` indices. For
/// loops whose iterations are independent (each writes only its own slots): the result is the
/// same, bit for bit, as the serial loop's, whatever the threads. A library that uses it links
/// TBB (not installed: the public headers are TBB-free).

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <cstddef>

namespace fascicle {

template <class Body>
void for_each_index(std::size_t n, const Body& body, std::size_t grain = 256) {
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, grain), [&](const tbb::blocked_range<std::size_t>& r) {
    for (std::size_t i = r.begin(); i != r.end(); ++i) body(i);
  });
}

}  // namespace fascicle
