// The repair stage's side of the wrap worker (repair/worker/wrap_worker_main.cpp): finds the
// program, starts it with posix_spawn (never fork: this process may run TBB threads, and a forked
// child of a threaded process inherited the dynamic loader mid-dlopen and aborted in rare runs),
// sends the soup, reads the wrap back and kills the worker past its time.

#include "geometry/errors.h"
#include "geometry/subprocess.h"
#include "repair/detail/alpha_wrap.h"
#include "repair/detail/wrap_protocol.h"

#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <vector>

#ifndef FASCICLE_WRAP_WORKER_BUILD_PATH
#define FASCICLE_WRAP_WORKER_BUILD_PATH ""
#endif

namespace fascicle::detail {

namespace {

namespace fs = std::filesystem;

const char kWorkerName[] = "fascicle-wrap-worker";

bool executable(const std::string& path) { return !path.empty() && ::access(path.c_str(), X_OK) == 0; }

// Closes a descriptor on every path.
struct Descriptor {
  int fd = -1;
  ~Descriptor() {
    if (fd >= 0) ::close(fd);
  }
};

// Appends `count` values of T as raw bytes.
template <class T>
void append(std::vector<char>& bytes, const T* values, std::size_t count) {
  const char* p = reinterpret_cast<const char*>(values);
  bytes.insert(bytes.end(), p, p + count * sizeof(T));
}

}  // namespace

std::string find_wrap_worker(const std::string& explicit_path) {
  if (!explicit_path.empty()) {
    if (executable(explicit_path)) return explicit_path;
    throw InputError(ErrorCode::file_missing,
                     "alpha wrap worker " + explicit_path + " does not exist or is not executable");
  }
  if (const char* variable = std::getenv("FASCICLE_WRAP_WORKER"); variable != nullptr && *variable != '\0') {
    if (executable(variable)) return variable;
    throw InputError(ErrorCode::file_missing, std::string("alpha wrap worker ") + variable +
                                                  " (FASCICLE_WRAP_WORKER) does not exist or is not executable");
  }
  std::string looked;
  std::error_code ec;
  const fs::path self = fs::read_symlink("/proc/self/exe", ec);
  if (!ec) {
    const std::string beside = (self.parent_path() / kWorkerName).string();
    if (executable(beside)) return beside;
    looked = beside;
  }
  const std::string configured = FASCICLE_WRAP_WORKER_BUILD_PATH;
  if (executable(configured)) return configured;
  if (!configured.empty()) looked += (looked.empty() ? "" : ", ") + configured;
  throw InputError(ErrorCode::file_missing, std::string("alpha wrap worker ") + kWorkerName + " not found (looked at " +
                                                (looked.empty() ? std::string("nothing") : looked) +
                                                "); set FASCICLE_WRAP_WORKER to its path");
}

std::optional<TriangleMesh> alpha_wrap_with_time_limit(const TriangleMesh& soup, double alpha, double offset,
                                                       double seconds, const std::string& worker, long memory_mb) {
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
  std::vector<char> request;
  request.reserve(64 + soup.positions.size() * sizeof(Vec3) + soup.triangles.size() * sizeof(Triangle));
  append(request, kWrapMagic, sizeof(kWrapMagic));
  const double numbers[2] = {alpha, offset};
  append(request, numbers, 2);
  const std::uint64_t counts[2] = {soup.positions.size(), soup.triangles.size()};
  append(request, counts, 2);
  append(request, soup.positions.data(), soup.positions.size());
  append(request, soup.triangles.data(), soup.triangles.size());

  int pair[2];
  if (::socketpair(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0, pair) != 0)
    throw Error(ErrorCode::internal,
                std::string("alpha wrap: cannot make a socket for the worker: ") + std::strerror(errno));
  Descriptor ours{pair[0]}, theirs{pair[1]};
  SpawnOptions spawn;
  spawn.argv = {worker};
  if (memory_mb > 0) spawn.argv.insert(spawn.argv.end(), {"--memory-mb", std::to_string(memory_mb)});
  spawn.stdin_fd = theirs.fd;
  spawn.stdout_fd = theirs.fd;
  const pid_t pid = spawn_process(spawn);
  ::close(theirs.fd);
  theirs.fd = -1;
  ::fcntl(ours.fd, F_SETFL, ::fcntl(ours.fd, F_GETFL) | O_NONBLOCK);

  // Send the request and read the response together (the worker reads all before it answers,
  // but a worker that dies early must not leave us blocked on a full socket).
  std::vector<char> response;
  std::size_t sent = 0;
  bool timed_out = false;
  char buffer[1 << 16];
  for (;;) {
    const double left = std::chrono::duration<double>(deadline - std::chrono::steady_clock::now()).count();
    if (left <= 0) {
      timed_out = true;
      break;
    }
    pollfd pfd{ours.fd, static_cast<short>(POLLIN | (sent < request.size() ? POLLOUT : 0)), 0};
    const int ready = ::poll(&pfd, 1, static_cast<int>(std::min(left * 1000.0, 1000.0)) + 1);
    if (ready < 0 && errno == EINTR) continue;
    if (ready <= 0) continue;
    if (sent < request.size() && (pfd.revents & POLLOUT)) {
      const ssize_t n = ::send(ours.fd, request.data() + sent, request.size() - sent, MSG_NOSIGNAL);
      if (n > 0) {
        sent += static_cast<std::size_t>(n);
        if (sent == request.size()) ::shutdown(ours.fd, SHUT_WR);
      } else if (n < 0 && errno != EINTR && errno != EAGAIN) {
        sent = request.size();  // the worker is gone; read what it left and wait for it below
      }
    }
    if (pfd.revents & (POLLIN | POLLHUP | POLLERR)) {
      const ssize_t n = ::read(ours.fd, buffer, sizeof(buffer));
      if (n < 0 && (errno == EINTR || errno == EAGAIN)) continue;
      if (n <= 0) break;  // end of data
      response.insert(response.end(), buffer, buffer + n);
    }
  }
  if (timed_out) ::kill(pid, SIGKILL);
  const int status = wait_process(pid);
  if (timed_out) return std::nullopt;

  auto failed = [&](const std::string& why) {
    return TopologyError("alpha wrapping failed in its worker process (" + worker + "): " + why,
                         ErrorCode::repair_failed);
  };
  if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) {
    std::string why = "it " + describe_wait_status(status);
    if (WIFEXITED(status) && WEXITSTATUS(status) == kWorkerOutOfMemory) why += " (out of memory)";
    if (memory_mb > 0 && (WIFSIGNALED(status) || WEXITSTATUS(status) == kWorkerOutOfMemory))
      why += "; its memory limit was " + std::to_string(memory_mb) + " MiB";
    throw failed(why);
  }
  std::uint64_t header[3] = {0, 0, 0};
  if (response.size() < 2 * sizeof(std::uint64_t)) throw failed("it sent no result");
  std::memcpy(header, response.data(), 2 * sizeof(std::uint64_t));
  if (header[0] == kResultError) {
    const std::size_t length = std::min<std::size_t>(header[1], response.size() - 2 * sizeof(std::uint64_t));
    std::string message(response.data() + 2 * sizeof(std::uint64_t), length);
    if (message == "out of memory" && memory_mb > 0) message += " (memory limit " + std::to_string(memory_mb) + " MiB)";
    throw failed(message);
  }
  if (header[0] != kResultMesh || response.size() < sizeof(header)) throw failed("it sent a malformed result");
  std::memcpy(header, response.data(), sizeof(header));
  const std::uint64_t points = header[1], triangles = header[2];
  const std::size_t expected = sizeof(header) + points * sizeof(Vec3) + triangles * sizeof(Triangle);
  if (points > response.size() || triangles > response.size() || response.size() != expected)
    throw failed("it sent an incomplete mesh");
  TriangleMesh out;
  out.positions.resize(points);
  out.triangles.resize(triangles);
  std::memcpy(static_cast<void*>(out.positions.data()), response.data() + sizeof(header), points * sizeof(Vec3));
  std::memcpy(static_cast<void*>(out.triangles.data()), response.data() + sizeof(header) + points * sizeof(Vec3),
              triangles * sizeof(Triangle));
  for (const Triangle& t : out.triangles)
    for (int v : t)
      if (v < 0 || static_cast<std::uint64_t>(v) >= points) throw failed("it sent a triangle with a bad index");
  return out;
}

}  // namespace fascicle::detail
