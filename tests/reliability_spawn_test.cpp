// Helper processes started from a threaded process (geometry/subprocess.h): the alpha-wrap worker
// (repair/wrap_worker_client.cpp, repair/worker/) and the batch's decompose processes. Each is
// started with posix_spawn; a fork() of this multithreaded process once left the child with the
// dynamic loader in the middle of another thread's dlopen, and the child aborted in ld.so.

#include "geometry/errors.h"
#include "geometry/inject_defects.h"
#include "geometry/mesh_io.h"
#include "geometry/mesh_stats.h"
#include "geometry/primitives.h"
#include "geometry/sample_muscle.h"
#include "geometry/subprocess.h"
#include "repair/detail/alpha_wrap.h"
#include "repair/repair.h"
#include "test_common.h"

#include <catch2/catch.hpp>
#include <tbb/parallel_for.h>

#include <dlfcn.h>
#include <signal.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <iterator>
#include <thread>

using namespace fascicle;
using test::read_text;
namespace fs = std::filesystem;

namespace {

TriangleMesh soup_to_mesh(const PolygonSoup& soup) {
  TriangleMesh mesh;
  mesh.positions = soup.points;
  for (const auto& p : soup.polygons)
    for (std::size_t k = 1; k + 1 < p.size(); ++k) mesh.triangles.push_back({p[0], p[k], p[k + 1]});
  return mesh;
}

// A small broken mesh: a ball with holes and a flipped patch, overlapped by a second ball.
TriangleMesh broken_mesh() {
  TriangleMesh mesh =
      soup_to_mesh(inject(inject(make_icosphere(2), DefectKind::holes, 3), DefectKind::flipped_patch, 5));
  const TriangleMesh other = make_icosphere(2);
  const int base = static_cast<int>(mesh.positions.size());
  for (const Vec3& p : other.positions) mesh.positions.push_back(p + Vec3(0.9, 0.2, 0.0));
  for (const Triangle& t : other.triangles) mesh.triangles.push_back({t[0] + base, t[1] + base, t[2] + base});
  return mesh;
}

PolygonSoup mesh_with_handle() {
  SampleOptions so;
  so.rings = 40;
  so.segments = 24;
  return inject(make_fusiform_muscle(so), DefectKind::handle, 1);
}

// Threads that keep the process busy the way the program is when it wraps: TBB workers running
// parallel loops, and a thread loading and unloading a shared library (the dynamic loader's state
// is "inconsistent" while it does; a fork() at that moment gave a child whose first dlopen
// aborted).
class BusyThreads {
 public:
  BusyThreads() {
    tbb_ = std::thread([this] {
      std::vector<double> values(1 << 16);
      while (!stop_) {
        tbb::parallel_for(std::size_t(0), values.size(),
                          [&](std::size_t i) { values[i] = std::sin(double(i) + values[i]); });
        ++tbb_rounds_;
      }
    });
    for (const char* name : {"libbz2.so.1.0", "libexpat.so.1", "liblzma.so.5", "libz.so.1"}) {
      void* loaded = ::dlopen(name, RTLD_NOW | RTLD_NOLOAD);
      if (loaded != nullptr) {
        ::dlclose(loaded);  // already part of the process: loading it again changes nothing
        continue;
      }
      if (void* h = ::dlopen(name, RTLD_NOW | RTLD_LOCAL)) {
        ::dlclose(h);
        library_ = name;
        break;
      }
    }
    if (!library_.empty())
      loader_ = std::thread([this] {
        while (!stop_) {
          if (void* h = ::dlopen(library_.c_str(), RTLD_NOW | RTLD_LOCAL)) ::dlclose(h);
          ++dlopen_rounds_;
        }
      });
  }
  ~BusyThreads() {
    stop_ = true;
    tbb_.join();
    if (loader_.joinable()) loader_.join();
  }
  BusyThreads(const BusyThreads&) = delete;
  BusyThreads& operator=(const BusyThreads&) = delete;
  long tbb_rounds() const { return tbb_rounds_; }
  long dlopen_rounds() const { return dlopen_rounds_; }
  const std::string& library() const { return library_; }

 private:
  std::atomic<bool> stop_{false};
  std::atomic<long> tbb_rounds_{0}, dlopen_rounds_{0};
  std::string library_;
  std::thread tbb_, loader_;
};

std::string write_script(const test::TempDir& dir, const std::string& name, const std::string& body) {
  const std::string path = dir.file(name);
  std::ofstream(path) << "#!/bin/sh\n" << body << "\n";
  ::chmod(path.c_str(), 0755);
  return path;
}

}  // namespace

TEST_CASE("spawn: 20 alpha wraps in the worker while TBB threads run and another thread loads libraries",
          "[spawn][reliability]") {
  const TriangleMesh mesh = broken_mesh();
  const double diagonal = bounding_box(mesh.positions).diagonal();
  const std::string worker = detail::find_wrap_worker("");
  BusyThreads busy;
  INFO("library loaded and unloaded meanwhile: " << (busy.library().empty() ? "(none available)" : busy.library()));
  std::size_t faces = 0;
  for (int run = 0; run < 20; ++run) {
    INFO("run " << run);
    const std::optional<TriangleMesh> wrap =
        detail::alpha_wrap_with_time_limit(mesh, 0.05 * diagonal, 0.05 * diagonal / 30.0, 120.0, worker, 0);
    REQUIRE(wrap.has_value());
    REQUIRE(verify_genus0(*wrap).empty());
    if (run == 0) faces = wrap->triangles.size();
    CHECK(wrap->triangles.size() == faces);  // the wrap is deterministic: every run the same
  }
  // The whole repair stage too (its wrap fallback closes the handle), with the threads still busy.
  const PolygonSoup handle = mesh_with_handle();
  for (int run = 0; run < 3; ++run) {
    const RepairResult r = repair_mesh(handle);
    CHECK(r.report.fallback_used);
    CHECK(verify_genus0(r.mesh).empty());
  }
  CHECK(busy.tbb_rounds() > 0);
  if (!busy.library().empty()) CHECK(busy.dlopen_rounds() > 0);
}

TEST_CASE("spawn: a missing wrap worker is a one-line error naming where it was looked for", "[spawn][reliability]") {
  test::TempDir dir;
  const std::string missing = dir.file("no-such-worker");
  const PolygonSoup handle = mesh_with_handle();

  // An explicit path.
  try {
    detail::find_wrap_worker(missing);
    FAIL("expected an error");
  } catch (const InputError& e) {
    CHECK(e.code() == ErrorCode::file_missing);
    CHECK(std::string(e.what()).find(missing) != std::string::npos);
  }
  // The environment variable, through the repair stage (its wrap fallback needs the worker).
  ::setenv("FASCICLE_WRAP_WORKER", missing.c_str(), 1);
  try {
    repair_mesh(handle);
    ::unsetenv("FASCICLE_WRAP_WORKER");
    FAIL("expected an error");
  } catch (const InputError& e) {
    ::unsetenv("FASCICLE_WRAP_WORKER");
    const std::string what = e.what();
    CHECK(e.code() == ErrorCode::file_missing);
    CHECK(what.find(missing) != std::string::npos);
    CHECK(what.find("FASCICLE_WRAP_WORKER") != std::string::npos);
    CHECK(what.find('\n') == std::string::npos);
  }
  // No wrap needed, no worker needed.
  ::setenv("FASCICLE_WRAP_WORKER", missing.c_str(), 1);
  RepairOptions no_wrap;
  no_wrap.allow_wrap = false;
  CHECK_NOTHROW(repair_mesh(to_soup(make_icosphere(2)), no_wrap));
  ::unsetenv("FASCICLE_WRAP_WORKER");
  // Found automatically: beside this test program (the build folder).
  const std::string found = detail::find_wrap_worker("");
  CHECK(fs::path(found).filename() == "fascicle-wrap-worker");
  CHECK(::access(found.c_str(), X_OK) == 0);

  // The program: one line, exit code 3, no output.
  const TriangleMesh handle_mesh = soup_to_mesh(handle);
  const std::string input = dir.file("handle.off"), output = dir.file("out.off"), errors = dir.file("err.txt");
  write_triangle_mesh(input, handle_mesh);
  const int code = test::run_command("FASCICLE_WRAP_WORKER='" + missing + "' '" + test::program() +
                                     "' --quiet repair '" + input + "' -o '" + output + "' 2> '" + errors + "'");
  CHECK(code == exit_code(ErrorCode::file_missing));
  const std::string message = read_text(errors);
  INFO(message);
  CHECK(message.rfind("fascicle: error: ", 0) == 0);
  CHECK(std::count(message.begin(), message.end(), '\n') == 1);
  CHECK(message.find(missing) != std::string::npos);
  CHECK_FALSE(fs::exists(output));
  // With the worker found, the same command wraps.
  CHECK(test::run_command("'" + test::program() + "' --quiet repair '" + input + "' -o '" + output + "'") == 0);
  CHECK(fs::exists(output));
}

TEST_CASE("spawn: a worker that crashes, hangs or talks nonsense is reported, killed and reaped",
          "[spawn][reliability]") {
  test::TempDir dir;
  const TriangleMesh mesh = broken_mesh();
  const std::string mark = test::unique_mark();
  const std::string name = mark.substr(0, mark.find('=')), value = mark.substr(mark.find('=') + 1);
  ::setenv(name.c_str(), value.c_str(), 1);  // inherited by the workers: how we find them below

  auto failure = [&](const std::string& worker) -> std::string {
    try {
      detail::alpha_wrap_with_time_limit(mesh, 0.1, 0.003, 60.0, worker, 0);
    } catch (const TopologyError& e) {
      CHECK(e.code() == ErrorCode::repair_failed);
      CHECK(std::string(e.what()).find('\n') == std::string::npos);
      return e.what();
    }
    return "(no error)";
  };
  // Dies by a signal before reading anything.
  const std::string crash = failure(write_script(dir, "crash.sh", "kill -SEGV $$"));
  CHECK(crash.find("killed by signal 11") != std::string::npos);
  // Exits with a status.
  CHECK(failure(write_script(dir, "exit.sh", "exit 7")).find("exited with status 7") != std::string::npos);
  // Exits 0 with garbage, or with nothing.
  CHECK(failure(write_script(dir, "garbage.sh", "cat > /dev/null; printf 'xxxxxxxxxxxxxxxxxxxxxxxx'"))
            .find("malformed") != std::string::npos);
  CHECK(failure(write_script(dir, "silent.sh", "cat > /dev/null")).find("no result") != std::string::npos);
  // Never answers: killed at the time limit, nothing returned, nothing left running.
  const std::string hang = write_script(dir, "hang.sh", "exec sleep 600");
  CHECK_FALSE(detail::alpha_wrap_with_time_limit(mesh, 0.1, 0.003, 1.0, hang, 0).has_value());
  ::unsetenv(name.c_str());
  const std::vector<int> left = test::processes_with_environment(mark);
  for (int pid : left) ::kill(pid, SIGKILL);
  CHECK(left.empty());
}

#if !defined(__SANITIZE_ADDRESS__)  // AddressSanitizer cannot run under an address-space limit
TEST_CASE("spawn: the wrap worker's memory limit", "[spawn][reliability]") {
  const TriangleMesh fine = make_icosphere(6);  // 81 920 triangles; a fine wrap needs far more than 64 MiB
  const std::string worker = detail::find_wrap_worker("");
  try {
    detail::alpha_wrap_with_time_limit(fine, 0.004, 0.004 / 30.0, 300.0, worker, 64);
    FAIL("expected the memory limit to stop the wrap");
  } catch (const TopologyError& e) {
    INFO(e.what());
    CHECK(e.code() == ErrorCode::repair_failed);
    CHECK(std::string(e.what()).find("memory limit 64 MiB") != std::string::npos);
  }
  // A coarse wrap fits in a generous limit.
  const std::optional<TriangleMesh> wrap =
      detail::alpha_wrap_with_time_limit(fine, 0.2, 0.2 / 30.0, 300.0, worker, 4096);
  REQUIRE(wrap.has_value());
  CHECK(verify_genus0(*wrap).empty());
  RepairOptions bad;
  bad.wrap_memory_mb = 10;
  CHECK_THROWS_AS(bad.validate(), OptionError);
}
#endif

TEST_CASE("spawn: a killed batch takes its decompose processes with it", "[spawn][reliability][batch]") {
  test::TempDir dir;
  const fs::path in = dir.path() / "in";
  fs::create_directories(in);
  SampleOptions so;
  for (int i = 0; i < 4; ++i)
    write_triangle_mesh((in / ("m" + std::to_string(i) + ".off")).string(), make_fusiform_muscle(so));
  const std::string mark = test::unique_mark();
  const std::string pid_file = dir.file("pid");
  // Start the batch in the background with a mark in its environment (decompose made to run for
  // hours: a fixed, huge number of settle iterations), kill it once a decompose runs, then look
  // for anything still carrying the mark.
  REQUIRE(test::run_command(
              mark + " '" + test::program() + "' -q batch '" + in.string() + "' -o '" + (dir.path() / "out").string() +
              "' --jobs 2 --solver verlet --tolerance 0 --max-iterations 100000000 > /dev/null 2>&1 & echo $! > '" +
              pid_file + "'") == 0);
  std::string pid;
  for (int wait = 0; wait < 100 && pid.empty(); ++wait) {
    ::usleep(50 * 1000);
    std::ifstream(pid_file) >> pid;
  }
  REQUIRE_FALSE(pid.empty());
  bool children = false;
  for (int wait = 0; wait < 200 && !children; ++wait) {  // up to 10 s for a decompose to start
    ::usleep(50 * 1000);
    children = test::processes_with_environment(mark).size() > 1;
  }
  CHECK(children);
  ::kill(std::stoi(pid), SIGKILL);
  std::vector<int> left;
  for (int wait = 0; wait < 40; ++wait) {  // the kernel delivers the parent-death signal at once
    ::usleep(50 * 1000);
    left = test::processes_with_environment(mark);
    if (left.empty()) break;
  }
  for (int p : left) ::kill(p, SIGKILL);
  CHECK(left.empty());
}
