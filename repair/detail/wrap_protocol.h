#pragma once
// Private: what the repair stage and the wrap worker (repair/worker/wrap_worker_main.cpp) send
// each other over the worker's standard input and output, a socket. Raw native-endian values:
// both ends are the same build on the same machine.
//
// Request:  magic (8 bytes "FASWRAP1"), alpha, offset (double), point count, triangle count
//           (uint64), points (3 doubles each), triangles (3 int each).
// Response: kind (uint64): kResultMesh, then point count, triangle count (uint64), points,
//           triangles; or kResultError, then a message length (uint64) and the message (one line).

#include <cstdint>
#include <cstring>

namespace fascicle::detail {

inline constexpr char kWrapMagic[8] = {'F', 'A', 'S', 'W', 'R', 'A', 'P', '1'};
inline constexpr std::uint64_t kResultMesh = 0;
inline constexpr std::uint64_t kResultError = 1;

/// Exit status of the worker when it could not even report through its output.
inline constexpr int kWorkerBadRequest = 2;
inline constexpr int kWorkerWriteFailed = 3;
inline constexpr int kWorkerOutOfMemory = 4;

/// Largest message a worker sends (longer ones are cut).
inline constexpr std::uint64_t kMaxWorkerMessage = 4096;

}  // namespace fascicle::detail
