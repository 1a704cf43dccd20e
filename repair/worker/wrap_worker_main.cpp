// fascicle-wrap-worker [--memory-mb N]: runs one CGAL alpha wrap for the repair stage, in a
// process of its own so that the caller can bound its time and memory and survive its crash
// (repair/wrap_worker_client.cpp starts it with posix_spawn). Reads the request on standard input
// and writes the response on standard output (repair/detail/wrap_protocol.h). It prints nothing
// on purpose: the caller reports failures as one line. Exit status 0 when a response was sent
// (a wrap or an error message), kWorkerBadRequest, kWorkerWriteFailed or kWorkerOutOfMemory
// otherwise.

#include "geometry/subprocess.h"
#include "repair/detail/alpha_wrap.h"
#include "repair/detail/wrap_protocol.h"

#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <new>
#include <string>

namespace {

using fascicle::detail::kWorkerBadRequest;
using fascicle::detail::kWorkerOutOfMemory;
using fascicle::detail::kWorkerWriteFailed;

bool read_all(int fd, void* data, std::size_t size) {
  char* p = static_cast<char*>(data);
  while (size > 0) {
    const ssize_t n = ::read(fd, p, size);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return false;
    p += n;
    size -= static_cast<std::size_t>(n);
  }
  return true;
}

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

int send_error(const std::string& message) {
  const std::uint64_t header[2] = {fascicle::detail::kResultError,
                                   std::min<std::uint64_t>(message.size(), fascicle::detail::kMaxWorkerMessage)};
  return write_all(STDOUT_FILENO, header, sizeof(header)) && write_all(STDOUT_FILENO, message.data(), header[1])
             ? 0
             : kWorkerWriteFailed;
}

int serve() {
  char magic[8];
  double numbers[2];
  std::uint64_t counts[2];
  if (!read_all(STDIN_FILENO, magic, sizeof(magic)) ||
      std::memcmp(magic, fascicle::detail::kWrapMagic, sizeof(magic)) != 0 ||
      !read_all(STDIN_FILENO, numbers, sizeof(numbers)) || !read_all(STDIN_FILENO, counts, sizeof(counts)))
    return kWorkerBadRequest;
  // The caller sends at most what a soup can hold (int indices).
  if (counts[0] > 0x7fffffffULL || counts[1] > 0x7fffffffULL) return kWorkerBadRequest;
  fascicle::TriangleMesh soup;
  soup.positions.resize(counts[0]);
  soup.triangles.resize(counts[1]);
  if (!read_all(STDIN_FILENO, soup.positions.data(), counts[0] * sizeof(fascicle::Vec3)) ||
      !read_all(STDIN_FILENO, soup.triangles.data(), counts[1] * sizeof(fascicle::Triangle)))
    return kWorkerBadRequest;
  for (const fascicle::Triangle& t : soup.triangles)
    for (int v : t)
      if (v < 0 || static_cast<std::uint64_t>(v) >= counts[0]) return kWorkerBadRequest;

  fascicle::TriangleMesh wrap;
  try {
    wrap = fascicle::detail::alpha_wrap(soup, numbers[0], numbers[1]);
  } catch (const std::bad_alloc&) {
    return send_error("out of memory") == 0 ? 0 : kWorkerOutOfMemory;
  } catch (const std::exception& e) {
    std::string what = e.what();
    for (char& c : what)
      if (c == '\n' || c == '\r') c = ' ';
    return send_error("CGAL's alpha wrap threw: " + what);
  }
  const std::uint64_t header[3] = {fascicle::detail::kResultMesh, wrap.positions.size(), wrap.triangles.size()};
  if (!write_all(STDOUT_FILENO, header, sizeof(header)) ||
      !write_all(STDOUT_FILENO, wrap.positions.data(), wrap.positions.size() * sizeof(fascicle::Vec3)) ||
      !write_all(STDOUT_FILENO, wrap.triangles.data(), wrap.triangles.size() * sizeof(fascicle::Triangle)))
    return kWorkerWriteFailed;
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  fascicle::die_with_parent_if_asked();
  long memory_mb = 0;
  for (int i = 1; i < argc; ++i) {
    if (std::strcmp(argv[i], "--memory-mb") == 0 && i + 1 < argc) {
      memory_mb = std::strtol(argv[++i], nullptr, 10);
    } else {
      return kWorkerBadRequest;  // only the repair stage starts this program
    }
  }
#if !defined(__SANITIZE_ADDRESS__)
  if (memory_mb > 0) {
    const rlim_t bytes = static_cast<rlim_t>(memory_mb) * 1024 * 1024;
    const rlimit limit{bytes, bytes};
    if (::setrlimit(RLIMIT_AS, &limit) != 0) return kWorkerBadRequest;
  }
#else
  (void)memory_mb;  // AddressSanitizer reserves terabytes of address space: no limit under it
#endif
  try {
    return serve();
  } catch (const std::bad_alloc&) { return kWorkerOutOfMemory; }
}
