#pragma once
// Private: the alpha-wrap fallback (CGAL 3D Alpha Wrapping), behind plain data.

#include "geometry/mesh.h"

#include <optional>

namespace fascicle::detail {

/// Wraps the triangles of `soup` (CGAL::alpha_wrap_3) with absolute `alpha` and `offset`.
/// The result is closed, 2-manifold and free of self-intersections by construction; its genus
/// and number of components are not guaranteed and must be checked.
TriangleMesh alpha_wrap(const TriangleMesh& soup, double alpha, double offset);

/// alpha_wrap() under a time limit: the wrap runs in a forked child process that sends the result
/// back through a pipe; past `seconds` the child is killed and nullopt returned (CGAL's wrap
/// cannot be interrupted otherwise). The child's standard error goes to /dev/null; a child that
/// dies is run once more within the time left. Throws TopologyError(repair_failed) if it dies twice.
std::optional<TriangleMesh> alpha_wrap_with_time_limit(const TriangleMesh& soup, double alpha, double offset,
                                                        double seconds);

}  // namespace fascicle::detail
