// fascicle bench gpu: speed of the GPU spring solvers through headless OpenGL, the counterparts
// of the thesis's tables 7.1 and 7.2 (ms per Verlet iteration, model-6 and model-26, CPU and two
// GPU methods) and 7.3 (reading 100^3 positions back with glReadPixels and through a pixel
// buffer object), with the stream bandwidth of a compute-shader copy measured in the same run
// (shaders/stream_bandwidth.h) beside the `gl` kernel. Every record carries the renderer
// string: on a machine without a GPU the figures are Mesa llvmpipe's (software rendering on the
// CPU), not a graphics card's.
// Results and commands are recorded in docs/BENCHMARKS.md.

#include "bench/bench_commands.h"
#include "geometry/atomic_file.h"
#include "geometry/errors.h"

#ifdef FASCICLE_HAVE_SHADERS
#include "shaders/gl_context.h"
#include "shaders/gpu_settle.h"
#include "shaders/stream_bandwidth.h"
#include "springs/lattice.h"
#include "springs/settle.h"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <functional>
#include <memory>
#include <sstream>
#endif

namespace fascicle::bench {

#ifdef FASCICLE_HAVE_SHADERS
namespace {

using clock_type = std::chrono::steady_clock;
using namespace fascicle::springs;
using namespace fascicle::shaders;

struct GpuBenchArgs {
  std::string sizes = "10,20,40,60,80,100";
  std::string readback_sizes = "50,100";
  std::string backends = "cpu,gl,gl-gs";
  std::string models = "6,26";
  std::string json;
  int gl_device = -1;
  double min_seconds = 1.0;   // per ms/iteration measurement
  double give_up_ms = 20000;  // skip larger sizes of a backend once one iteration takes this long
  int stream_mb = 256;        // buffer size of the stream bandwidth probe, MiB; 0 = no probe
};

// Least bytes one `gl` structured-uniform Verlet step moves per lattice point: the current
// position read (its neighbours' reads hit the cache), the previous position read and the new
// one written over it, vec4 of float32 each (shaders/verlet_lattice.comp).
constexpr double gl_uniform_bytes_per_point = 3 * 16.0;

std::vector<int> parse_list(const std::string& text, const std::string& option, int lo, int hi) {
  std::vector<int> values;
  std::stringstream in(text);
  for (std::string item; std::getline(in, item, ',');) {
    if (item.empty()) continue;
    try {
      std::size_t used = 0;
      const int v = std::stoi(item, &used);
      if (used != item.size() || v < lo || v > hi) throw std::out_of_range("value");
      values.push_back(v);
    } catch (const std::exception&) {
      throw OptionError(option + ": '" + item + "' is not a number in " + std::to_string(lo) + ".." +
                        std::to_string(hi));
    }
  }
  return values;
}

std::vector<std::string> parse_names(const std::string& text) {
  std::vector<std::string> names;
  std::stringstream in(text);
  for (std::string item; std::getline(in, item, ',');) {
    if (item.empty()) continue;
    if (item != "cpu" && item != "gl" && item != "gl-gs")
      throw OptionError("backends: '" + item + "' is not cpu, gl or gl-gs");
    names.push_back(item);
  }
  return names;
}

double seconds_since(clock_type::time_point t0) {
  return std::chrono::duration<double>(clock_type::now() - t0).count();
}

// The spring bench's problem: a regular n^3 lattice of the unit cube, boundary moved by a smooth
// non-affine map (stretch, bend, shear), interior at rest.
Lattice bench_lattice(int n, SpringModel model) {
  Lattice lattice = regular_lattice(n, model, 1.0 / (n - 1), 0.01, true);
  for (std::size_t i = 0; i < lattice.system.positions.size(); ++i) {
    if (!lattice.system.fixed[i]) continue;
    Vec3& p = lattice.system.positions[i];
    p = Vec3(1.3 * p.x() + 0.2 * std::sin(2.0 * p.z()), 0.8 * p.y() + 0.1 * p.x() * p.z(),
             p.z() + 0.15 * p.x() * p.x());
  }
  return lattice;
}

SettleOptions timing_options() {
  SettleOptions options;
  options.tolerance = 0.0;
  options.energy_interval = 1 << 30;  // time the step itself
  return options;
}

// ms per iteration of `step_block(k)` (which runs k iterations and waits for them): doubles the
// block until it takes min_seconds; at least one block.
template <class StepBlock>
std::pair<double, int> time_iterations(StepBlock step_block, double min_seconds) {
  int block = 1, total = 0;
  double seconds = 0.0;
  while (true) {
    const auto t0 = clock_type::now();
    step_block(block);
    const double s = seconds_since(t0);
    seconds += s;
    total += block;
    if (seconds >= min_seconds || total >= 4000) break;
    block = std::min(block * 2, 1024);
  }
  return {1e3 * seconds / total, total};
}

void run_gpu_bench(const GpuBenchArgs& args) {
  const std::vector<int> sizes = parse_list(args.sizes, "sizes", 2, 1000);
  const std::vector<int> readback_sizes = parse_list(args.readback_sizes, "readback-sizes", 2, 1000);
  const std::vector<int> models = parse_list(args.models, "models", 6, 26);
  for (int m : models) parse_spring_model(m);
  const std::vector<std::string> backends = parse_names(args.backends);
  if (!(args.min_seconds > 0.0)) throw OptionError("min-seconds: must be > 0");
  if (args.stream_mb < 0) throw OptionError("stream-mb: must be >= 0");

  GlContextOptions context_options;
  context_options.device = args.gl_device;
  GlContext context(context_options);
  const std::string kind = context.hardware() ? "hardware" : "SOFTWARE renderer (no GPU)";
  std::printf("== OpenGL: %s | %s | %s | %s\n", context.renderer().c_str(), context.version().c_str(),
              context.platform().c_str(), kind.c_str());
  nlohmann::json records = nlohmann::json::array();
  auto base_record = [&](const std::string& section) {
    return nlohmann::json{{"section", section},
                          {"renderer", context.renderer()},
                          {"gl_version", context.version()},
                          {"hardware", context.hardware()},
                          {"platform", context.platform()}};
  };

  double stream_gb_per_s = 0.0;
  if (args.stream_mb > 0) {
    StreamBandwidthOptions stream;
    stream.bytes = static_cast<std::size_t>(args.stream_mb) << 20;
    const StreamBandwidth bw = measure_stream_bandwidth(context, stream);
    stream_gb_per_s = bw.gb_per_second;
    std::printf("== stream bandwidth (compute-shader copy of %d MiB, bytes read + written): %.1f GB/s\n",
                args.stream_mb, bw.gb_per_second);
    nlohmann::json record = base_record("bandwidth");
    record.update({{"bytes", bw.bytes},
                   {"gb_per_second", bw.gb_per_second},
                   {"dispatches", bw.dispatches},
                   {"seconds", bw.seconds}});
    records.push_back(record);
  }

  std::printf(
      "\n== ms per Verlet iteration (thesis tables 7.1, 7.2; 2011: CPU 274 ms, GPU geometry shader 33.7 ms at "
      "100^3 model-6)\n");
  std::printf("%6s %6s %-22s %12s %10s %12s %12s %8s\n", "n", "model", "backend", "ms/iter", "timed", "GPU MB",
              "stream ms", "x stream");
  for (int m : models) {
    const SpringModel model = parse_spring_model(m);
    for (const std::string& backend : backends) {
      bool gave_up = false;
      for (int n : sizes) {
        nlohmann::json record = base_record("speed");
        record.update({{"n", n}, {"model", m}, {"solver", "verlet"}});
        if (gave_up) {
          std::printf("%6d %6d %-22s   skipped: a smaller size took over %.0f ms per iteration\n", n, m,
                      backend.c_str(), args.give_up_ms);
          record.update({{"backend", backend}, {"skipped", "slower sizes skipped (--give-up-ms)"}});
          records.push_back(record);
          continue;
        }
        try {
          const Lattice lattice = bench_lattice(n, model);
          const LatticeShape shape = shape_of(lattice);
          double ms = 0.0;
          int timed = 0;
          std::string name;
          std::size_t bytes = 0;
          if (backend == "cpu") {
            std::unique_ptr<SpringSolver> solver = make_solver(lattice.system, timing_options(), &shape);
            solver->step();
            name = "cpu-" + solver->backend();
            std::tie(ms, timed) = time_iterations(
                [&](int k) {
                  for (int i = 0; i < k; ++i) solver->step();
                },
                args.min_seconds);
          } else {
            GpuSettleOptions gpu;
            gpu.backend = parse_gpu_backend(backend);
            std::unique_ptr<GpuSpringSolver> solver =
                make_gpu_solver(context, lattice.system, timing_options(), gpu, &shape);
            solver->run(1);
            solver->finish();
            name = solver->backend();
            bytes = solver->gpu_bytes();
            std::tie(ms, timed) = time_iterations(
                [&](int k) {
                  solver->run(k);
                  solver->finish();
                },
                args.min_seconds);
            if (!std::isfinite(solver->residual())) name += " (diverged)";
          }
          record.update(
              {{"backend", name}, {"ms_per_iteration", ms}, {"iterations_timed", timed}, {"gpu_bytes", bytes}});
          if (stream_gb_per_s > 0.0 && name == "gl-structured-uniform") {
            // The time to move the kernel's least data once at the probe's bandwidth.
            const double stream_ms = 1e3 * gl_uniform_bytes_per_point * lattice.point_count() / (stream_gb_per_s * 1e9);
            record.update({{"stream_ms", stream_ms}, {"stream_ratio", ms / stream_ms}});
            std::printf("%6d %6d %-22s %12.3f %10d %12.1f %12.4f %8.2f\n", n, m, name.c_str(), ms, timed, bytes / 1e6,
                        stream_ms, ms / stream_ms);
          } else {
            std::printf("%6d %6d %-22s %12.3f %10d %12.1f\n", n, m, name.c_str(), ms, timed, bytes / 1e6);
          }
          std::fflush(stdout);
          if (ms > args.give_up_ms) gave_up = true;
        } catch (const Error& e) {
          std::printf("%6d %6d %-22s   skipped: %s\n", n, m, backend.c_str(), e.what());
          record.update({{"backend", backend}, {"skipped", e.what()}});
        } catch (const std::bad_alloc&) {
          std::printf("%6d %6d %-22s   skipped: out of host memory\n", n, m, backend.c_str());
          record.update({{"backend", backend}, {"skipped", "out of host memory"}});
        }
        records.push_back(record);
      }
    }
  }

  std::printf("\n== readback of the positions, ms (thesis table 7.3; 2011: 100^3 28.1 ms glReadPixels, 22.6 ms PBO)\n");
  std::printf("%6s %-14s %12s\n", "n", "method", "ms (best 3)");
  for (int n : readback_sizes) {
    try {
      const Lattice lattice = bench_lattice(n, SpringModel::model6);
      const LatticeShape shape = shape_of(lattice);
      GpuSettleOptions gs;
      gs.backend = GpuBackend::gl_gs;
      std::unique_ptr<GpuSpringSolver> gs_solver =
          make_gpu_solver(context, lattice.system, timing_options(), gs, &shape);
      std::unique_ptr<GpuSpringSolver> gl_solver =
          make_gpu_solver(context, lattice.system, timing_options(), GpuSettleOptions{}, &shape);
      const std::pair<const char*, std::function<double()>> methods[] = {
          {"glReadPixels", [&] { return read_positions(*gs_solver, false).seconds; }},
          {"pbo", [&] { return read_positions(*gs_solver, true).seconds; }},
          {"ssbo", [&] { return read_positions(*gl_solver, false).seconds; }},
      };
      for (const auto& [method, read] : methods) {
        double best = 1e300;
        for (int rep = 0; rep < 3; ++rep) best = std::min(best, read());
        std::printf("%6d %-14s %12.3f\n", n, method, 1e3 * best);
        nlohmann::json record = base_record("readback");
        record.update({{"n", n},
                       {"points", lattice.point_count()},
                       {"method", method},
                       {"ms", 1e3 * best},
                       {"bytes", 16.0 * lattice.point_count()}});
        records.push_back(record);
      }
    } catch (const Error& e) { std::printf("%6d readback skipped: %s\n", n, e.what()); }
  }
  if (!args.json.empty()) write_file_atomically(args.json, [&](std::ostream& out) { out << records.dump(2) << '\n'; });
}

}  // namespace
#endif

void add_gpu_bench(CLI::App& bench) {
#ifdef FASCICLE_HAVE_SHADERS
  auto args = std::make_shared<GpuBenchArgs>();
  CLI::App* cmd = bench.add_subcommand("gpu", "GPU spring solvers (OpenGL): ms/iteration and readback, tables 7.1-7.3");
  cmd->add_option("--sizes", args->sizes, "Lattice sizes n (n^3 points)")->capture_default_str();
  cmd->add_option("--readback-sizes", args->readback_sizes, "Sizes for the readback timing")->capture_default_str();
  cmd->add_option("--backends", args->backends, "Any of cpu,gl,gl-gs")->capture_default_str();
  cmd->add_option("--models", args->models, "Any of 6,26")->capture_default_str();
  cmd->add_option("--gl-device", args->gl_device, "EGL device index (-1: first hardware device, else software)")
      ->capture_default_str();
  cmd->add_option("--min-seconds", args->min_seconds, "Seconds per ms/iteration measurement")->capture_default_str();
  cmd->add_option("--give-up-ms", args->give_up_ms, "Skip larger sizes once an iteration takes longer")
      ->capture_default_str();
  cmd->add_option("--stream-mb", args->stream_mb, "Buffer of the GPU stream bandwidth probe, MiB (0: none)")
      ->capture_default_str();
  cmd->add_option("--json", args->json, "Write the records as JSON here");
  cmd->callback([args] { run_gpu_bench(*args); });
#else
  CLI::App* cmd = bench.add_subcommand("gpu", "GPU spring solvers (not in this build: OpenGL/EGL/GLEW missing)");
  cmd->allow_extras();
  cmd->callback([] {
    throw Error(ErrorCode::gpu, "bench gpu: this build has no OpenGL backend (EGL, GLEW or OpenGL was not found)");
  });
#endif
}

}  // namespace fascicle::bench
