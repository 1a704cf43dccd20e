// The alpha-wrap fallback, in its own translation unit: CGAL's Alpha_wrap_3 headers are the
// heaviest the project includes.

#include "repair/detail/alpha_wrap.h"

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Surface_mesh.h>
#include <CGAL/alpha_wrap_3.h>

#include "geometry/errors.h"

#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <csignal>
#include <sys/prctl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <chrono>
#include <cstdint>
#include <cerrno>
#include <cstring>
#include <vector>

namespace fascicle::detail {

TriangleMesh alpha_wrap(const TriangleMesh& soup, double alpha, double offset) {
  using K = CGAL::Exact_predicates_inexact_constructions_kernel;
  using Point = K::Point_3;
  using Mesh = CGAL::Surface_mesh<Point>;

  std::vector<Point> points;
  points.reserve(soup.positions.size());
  for (const Vec3& p : soup.positions) points.emplace_back(p.x(), p.y(), p.z());
  std::vector<std::array<std::size_t, 3>> faces;
  faces.reserve(soup.triangles.size());
  for (const Triangle& t : soup.triangles)
    faces.push_back({static_cast<std::size_t>(t[0]), static_cast<std::size_t>(t[1]), static_cast<std::size_t>(t[2])});

  Mesh wrap;
  CGAL::alpha_wrap_3(points, faces, alpha, offset, wrap);

  TriangleMesh out;
  std::vector<int> index(wrap.number_of_vertices() + wrap.number_of_removed_vertices(), -1);
  for (auto v : wrap.vertices()) {
    index[v.idx()] = static_cast<int>(out.positions.size());
    const Point& p = wrap.point(v);
    out.positions.emplace_back(p.x(), p.y(), p.z());
  }
  for (auto f : wrap.faces()) {
    Triangle t{};
    int k = 0;
    for (auto v : CGAL::vertices_around_face(wrap.halfedge(f), wrap)) {
      if (k < 3) t[k] = index[v.idx()];
      ++k;
    }
    if (k == 3) out.triangles.push_back(t);
  }
  return out;
}

namespace {

bool write_all(int fd, const void* data, std::size_t size) {
  const char* p = static_cast<const char*>(data);
  while (size > 0) {
    const ssize_t n = ::write(fd, p, size);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return false;
    p += n;
    size -= static_cast<std::size_t>(n);
  }
  return true;
}

}  // namespace

namespace {

// One worker run: the wrap, or nullopt when the time ran out; `died` when the child ended without
// sending a whole result (it crashed or CGAL threw).
std::optional<TriangleMesh> wrap_in_worker(const TriangleMesh& soup, double alpha, double offset, double seconds,
                                           bool& died) {
  died = false;
  int fds[2];
  if (::pipe(fds) != 0) return alpha_wrap(soup, alpha, offset);  // no pipe: wrap unbounded
  const pid_t parent = ::getpid();
  const pid_t pid = ::fork();
  if (pid < 0) {
    ::close(fds[0]);
    ::close(fds[1]);
    return alpha_wrap(soup, alpha, offset);
  }
  if (pid == 0) {
    // Child: wrap, send counts then raw arrays, exit without running the parent's destructors.
    // It dies with its parent (a --time-limit exit or a kill must not leave it running on); the
    // parent may already be gone before the request took effect, hence the second test.
    ::prctl(PR_SET_PDEATHSIG, SIGKILL);
    if (::getppid() != parent) ::_exit(1);
    ::close(fds[0]);
    // The child reports only through the pipe and its exit status: whatever it would print (the
    // dynamic loader's "Inconsistency detected" abort when a parent thread was inside dlopen at
    // the fork, seen in rare runs) must not add lines to the program's one-line errors.
    const int devnull = ::open("/dev/null", O_WRONLY);
    if (devnull >= 0) ::dup2(devnull, STDERR_FILENO);
    int status = 1;
    try {
      const TriangleMesh wrap = alpha_wrap(soup, alpha, offset);
      const std::uint64_t counts[2] = {wrap.positions.size(), wrap.triangles.size()};
      if (write_all(fds[1], counts, sizeof(counts)) &&
          write_all(fds[1], wrap.positions.data(), wrap.positions.size() * sizeof(Vec3)) &&
          write_all(fds[1], wrap.triangles.data(), wrap.triangles.size() * sizeof(Triangle)))
        status = 0;
    } catch (...) {
    }
    ::close(fds[1]);
    ::_exit(status);
  }
  ::close(fds[1]);
  std::vector<char> bytes;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
  bool timed_out = false;
  char buffer[1 << 16];
  for (;;) {
    const double left = std::chrono::duration<double>(deadline - std::chrono::steady_clock::now()).count();
    if (left <= 0) {
      timed_out = true;
      break;
    }
    pollfd pfd{fds[0], POLLIN, 0};
    const int ready = ::poll(&pfd, 1, static_cast<int>(std::min(left * 1000.0, 1000.0)) + 1);
    if (ready < 0 && errno == EINTR) continue;
    if (ready <= 0) continue;
    const ssize_t n = ::read(fds[0], buffer, sizeof(buffer));
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) break;  // end of data
    bytes.insert(bytes.end(), buffer, buffer + n);
  }
  ::close(fds[0]);
  if (timed_out) ::kill(pid, SIGKILL);
  int status = 0;
  while (::waitpid(pid, &status, 0) < 0 && errno == EINTR) {
  }
  if (timed_out) return std::nullopt;
  if (!WIFEXITED(status) || WEXITSTATUS(status) != 0 || bytes.size() < 2 * sizeof(std::uint64_t)) {
    died = true;
    return std::nullopt;
  }
  std::uint64_t counts[2];
  std::memcpy(counts, bytes.data(), sizeof(counts));
  const std::size_t expected = sizeof(counts) + counts[0] * sizeof(Vec3) + counts[1] * sizeof(Triangle);
  FASCICLE_CHECK(bytes.size() == expected, "alpha wrap worker sent an incomplete mesh");
  TriangleMesh out;
  out.positions.resize(counts[0]);
  out.triangles.resize(counts[1]);
  std::memcpy(static_cast<void*>(out.positions.data()), bytes.data() + sizeof(counts), counts[0] * sizeof(Vec3));
  std::memcpy(static_cast<void*>(out.triangles.data()), bytes.data() + sizeof(counts) + counts[0] * sizeof(Vec3),
              counts[1] * sizeof(Triangle));
  return out;
}

}  // namespace

std::optional<TriangleMesh> alpha_wrap_with_time_limit(const TriangleMesh& soup, double alpha, double offset,
                                                        double seconds) {
  // A worker that dies is run once more within the time left (a fork of a threaded process can
  // inherit the loader mid-dlopen and abort; that is rare and does not repeat); a second death
  // is the error.
  const auto start = std::chrono::steady_clock::now();
  for (int attempt = 0;; ++attempt) {
    const double left = seconds - std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    if (left <= 0.0) return std::nullopt;
    bool died = false;
    std::optional<TriangleMesh> wrap = wrap_in_worker(soup, alpha, offset, left, died);
    if (!died) return wrap;
    if (attempt == 1) throw TopologyError("alpha wrapping failed in its worker process", ErrorCode::repair_failed);
  }
}

}  // namespace fascicle::detail
