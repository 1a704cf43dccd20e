#pragma once
// Private: the alpha-wrap fallback (CGAL 3D Alpha Wrapping), behind plain data.

#include "geometry/mesh.h"

#include <optional>
#include <string>

namespace fascicle::detail {

/// Wraps the triangles of `soup` (CGAL::alpha_wrap_3) with absolute `alpha` and `offset`, in
/// this process. The result is closed, 2-manifold and free of self-intersections by
/// construction; its genus and number of components are not guaranteed and must be checked.
TriangleMesh alpha_wrap(const TriangleMesh& soup, double alpha, double offset);

/// The wrap worker program to run: `explicit_path` when not empty, else the environment
/// variable FASCICLE_WRAP_WORKER, else `fascicle-wrap-worker` in the folder of the running
/// program (/proc/self/exe), else the one in the build folder configured by CMake. Throws
/// InputError(file_missing), one line naming every place looked at, when none is executable.
std::string find_wrap_worker(const std::string& explicit_path);

/// alpha_wrap() under a time limit, in a separate process: `worker` (a program started with
/// posix_spawn, so nothing of this possibly multithreaded process is inherited but its open
/// standard streams) reads the soup from a socket and sends the wrap back. Past `seconds` the
/// worker is killed and nullopt returned (CGAL's wrap cannot be interrupted otherwise).
/// `memory_mb` > 0 limits the worker's address space. Throws TopologyError(repair_failed),
/// saying whether the worker exited or was killed by a signal, when it ends without a result.
std::optional<TriangleMesh> alpha_wrap_with_time_limit(const TriangleMesh& soup, double alpha, double offset,
                                                       double seconds, const std::string& worker, long memory_mb);

}  // namespace fascicle::detail
