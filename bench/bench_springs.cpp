// fascicle bench springs: speed of the CPU spring solvers, the counterparts of the thesis's
// tables 7.1/7.2 (ms per iteration) and 7.4-7.6 (iterations to rest against mass and damping),
// plus the speed/accuracy trade of every solver and a memory-bandwidth reference measured in
// the same run. Results and commands are recorded in docs/BENCHMARKS.md.

#include "bench/bench_commands.h"
#include "geometry/atomic_file.h"
#include "geometry/errors.h"
#include "springs/lattice.h"
#include "springs/settle.h"
#include "springs/solvers_internal.h"
#include "springs/template_plot.h"

#include <nlohmann/json.hpp>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <memory>
#include <sstream>

#include <time.h>

namespace fascicle::bench {

namespace {

using clock_type = std::chrono::steady_clock;
using namespace fascicle::springs;

struct SpringsBenchArgs {
  std::string sizes = "10,20,50,100,150";
  std::string rest_sizes = "5,10,20";
  std::string trade_sizes = "20,50,100";
  std::string sections = "bandwidth,speed,rest,trade";
  std::string trade_solvers;  // empty: all
  std::string trade_models = "6,26";
  std::string json;
  std::string plots;                 // folder for the template pictures (section "templates")
  double min_seconds = 0.5;          // per speed measurement
  double trade_limit = 60.0;         // seconds per trade run
  int general_max_size = 100;        // largest lattice the general path is timed on (memory)
  double rest_tolerance = 1e-4;      // "at rest" for tables 7.4-7.6
  double rest_dt = 0.01;             // fixed time step for tables 7.4-7.6 (the thesis's is not stated)
  int local_global_max_size = 20;    // the sparse Cholesky factor grows too fast above this
  std::string spring_loop = "auto";  // structured path's spring loop: auto, avx512, avx2 or plain
  double coarse_start_tolerance = SettleOptions{}.coarse_start_tolerance;  // static momentum's coarse start
  double coarse_start_perturbation = SettleOptions{}.coarse_start_perturbation;
};

std::vector<int> parse_list(const std::string& text, const std::string& option) {
  std::vector<int> values;
  std::stringstream in(text);
  for (std::string item; std::getline(in, item, ',');) {
    if (item.empty()) continue;
    try {
      const int v = std::stoi(item);
      if (v < 2 || v > 400) throw std::out_of_range("size");
      values.push_back(v);
    } catch (const std::exception&) { throw OptionError(option + ": '" + item + "' is not a lattice size in 2..400"); }
  }
  return values;
}

bool has_section(const SpringsBenchArgs& args, const std::string& name) {
  return ("," + args.sections + ",").find("," + name + ",") != std::string::npos;
}

double seconds_since(clock_type::time_point t0) {
  return std::chrono::duration<double>(clock_type::now() - t0).count();
}

// Processor time of this process, all threads (seconds): beside the wall time, it shows how much
// of the machine the run got while other work shared it.
double process_cpu_seconds() {
  timespec t{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
  return static_cast<double>(t.tv_sec) + 1e-9 * static_cast<double>(t.tv_nsec);
}

// The 1-, 5- and 15-minute load averages, as `uptime` prints them.
std::string load_average() {
  std::ifstream in("/proc/loadavg");
  double a = 0, b = 0, c = 0;
  if (!(in >> a >> b >> c)) return "unknown";
  char buffer[64];
  std::snprintf(buffer, sizeof buffer, "%.2f %.2f %.2f", a, b, c);
  return buffer;
}

// The bench problem: a regular n^3 lattice of the unit cube whose boundary points were moved by
// a smooth non-affine map (stretch, bend, shear), interior at rest: the situation of the
// decomposition, where the template surface is pinned to the muscle.
Lattice bench_lattice(int n, SpringModel model, double mass) {
  Lattice lattice = regular_lattice(n, model, 1.0 / (n - 1), mass, true);
  for (std::size_t i = 0; i < lattice.system.positions.size(); ++i) {
    if (!lattice.system.fixed[i]) continue;
    Vec3& p = lattice.system.positions[i];
    p = Vec3(1.3 * p.x() + 0.2 * std::sin(2.0 * p.z()), 0.8 * p.y() + 0.1 * p.x() * p.z(),
             p.z() + 0.15 * p.x() * p.x());
  }
  return lattice;
}

// STREAM-like copy (a = b) and triad (a = b + s c) over arrays far larger than the caches,
// TBB-parallel like the solvers. Bytes counted: copy 16, triad 24 per element (no
// write-allocate traffic). Best of several repetitions.
std::pair<double, double> measure_bandwidth() {
  const std::size_t n = 24'000'000;  // 3 x 192 MB
  std::vector<double> a(n, 0.0), b(n, 1.0), c(n, 2.0);
  double best_copy = 0.0, best_triad = 0.0;
  for (int rep = 0; rep < 6; ++rep) {
    auto t0 = clock_type::now();
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, 1 << 16), [&](const tbb::blocked_range<std::size_t>& r) {
      for (std::size_t i = r.begin(); i != r.end(); ++i) a[i] = b[i];
    });
    best_copy = std::max(best_copy, 16.0 * n / seconds_since(t0) / 1e9);
    t0 = clock_type::now();
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, 1 << 16), [&](const tbb::blocked_range<std::size_t>& r) {
      for (std::size_t i = r.begin(); i != r.end(); ++i) a[i] = b[i] + 3.0 * c[i];
    });
    best_triad = std::max(best_triad, 24.0 * n / seconds_since(t0) / 1e9);
  }
  if (a[n / 2] != 7.0) std::printf("(bandwidth check value %g)\n", a[n / 2]);
  return {best_copy, best_triad};
}

// Bytes one Verlet iteration must move at least once (each array read or written once).
double streamed_bytes(const Lattice& lattice, const std::string& backend) {
  const double n = lattice.point_count();
  const double directions = static_cast<double>(half_offsets(lattice.model).size());
  if (backend == "structured-uniform")  // x,y,z read; previous read + written
    return n * (24.0 + 48.0);
  if (backend == "structured")  // x,y,z read; previous read + written; stiffness per direction; a, b; fixed
    return n * (24.0 + 48.0 + 8.0 * directions + 16.0 + 1.0);
  const double entries = 2.0 * lattice.system.springs.size();
  // forces: x, row offsets, (neighbour, stiffness, rest) per entry, force written;
  // integration: x, previous, force, a, b, fixed read, previous written
  return n * (24.0 + 4.0 + 24.0) + entries * 20.0 + n * (24.0 + 24.0 + 24.0 + 16.0 + 1.0 + 24.0);
}

// The compute limit of the structured kernel: every thread steps its own 16^3 lattice (about
// 200 KB of positions, held in the second-level cache), so no iteration waits for memory.
// Returns springs evaluated per second by all threads together; a large lattice's "compute ms"
// is its spring count over this rate (the rows at a lattice's faces have fewer springs, so the
// rate is per spring, not per point).
double springs_per_second_in_cache(SpringModel model, double min_seconds) {
  const int threads = std::max(1, tbb::this_task_arena::max_concurrency());
  std::vector<Lattice> lattices;
  std::vector<std::unique_ptr<SpringSolver>> solvers;
  SettleOptions options;
  options.backend = Backend::structured;
  options.tolerance = 0.0;
  options.energy_interval = 1 << 30;
  for (int t = 0; t < threads; ++t) lattices.push_back(bench_lattice(16, model, 0.01));
  for (int t = 0; t < threads; ++t) {
    const LatticeShape shape = shape_of(lattices[t]);
    solvers.push_back(make_solver(lattices[t].system, options, &shape));
  }
  auto run = [&](int steps) {
    tbb::parallel_for(
        tbb::blocked_range<int>(0, threads, 1),
        [&](const tbb::blocked_range<int>& r) {
          for (int t = r.begin(); t != r.end(); ++t)
            for (int i = 0; i < steps; ++i) solvers[t]->step();
        },
        tbb::simple_partitioner());
  };
  run(20);
  int steps = 100;
  for (;;) {
    const auto t0 = clock_type::now();
    run(steps);
    const double seconds = seconds_since(t0);
    if (seconds >= min_seconds || steps > (1 << 20))
      return static_cast<double>(threads) * steps * lattices[0].system.springs.size() / seconds;
    steps *= 2;
  }
}

void run_speed(const SpringsBenchArgs& args, double triad, nlohmann::json& records) {
  std::printf(
      "\n== ms per Verlet iteration (thesis tables 7.1, 7.2: 2011 CPU 100^3 model-6 274 ms, model-26 907 ms)\n");
  std::printf(
      "   (structured spring loop: %s; cpu ms = processor time of all threads per iteration;\n"
      "    load average before: %s)\n",
      springs::detail::structured_simd_name(), load_average().c_str());
  double in_cache_rate[2] = {0.0, 0.0};  // model-6, model-26: springs per second, all threads
  in_cache_rate[0] = springs_per_second_in_cache(SpringModel::model6, args.min_seconds);
  in_cache_rate[1] = springs_per_second_in_cache(SpringModel::model26, args.min_seconds);
  std::printf(
      "   compute limit (structured kernel, each of %d threads on its own 16^3 lattice in cache): "
      "model-6 %.0f, model-26 %.0f million springs/s\n",
      std::max(1, tbb::this_task_arena::max_concurrency()), in_cache_rate[0] / 1e6, in_cache_rate[1] / 1e6);
  std::printf("%6s %6s %-19s %10s %10s %10s %12s %8s %11s %8s\n", "n", "model", "backend", "ms/iter", "cpu ms",
              "MB/iter", "stream ms", "ratio", "compute ms", "ratio");
  for (int n : parse_list(args.sizes, "sizes")) {
    for (SpringModel model : {SpringModel::model6, SpringModel::model26}) {
      std::unique_ptr<Lattice> lattice;
      try {
        lattice = std::make_unique<Lattice>(bench_lattice(n, model, 0.01));
      } catch (const std::bad_alloc&) {
        std::printf("%6d %6d   skipped: out of memory\n", n, static_cast<int>(model));
        continue;
      }
      const LatticeShape shape = shape_of(*lattice);
      for (Backend backend : {Backend::structured, Backend::general}) {
        if (backend == Backend::general && n > args.general_max_size) continue;
        SettleOptions options;
        options.backend = backend;
        options.tolerance = 0.0;
        options.energy_interval = 1 << 30;  // time the step itself
        std::unique_ptr<SpringSolver> solver;
        try {
          solver = make_solver(lattice->system, options, &shape);
        } catch (const std::bad_alloc&) {
          std::printf("%6d %6d %-11s skipped: out of memory\n", n, static_cast<int>(model), backend_name(backend));
          continue;
        }
        for (int i = 0; i < 2; ++i) solver->step();
        int iterations = 0;
        const double c0 = process_cpu_seconds();
        const auto t0 = clock_type::now();
        while (iterations < 3 || (seconds_since(t0) < args.min_seconds && iterations < 2000)) {
          solver->step();
          ++iterations;
        }
        const double ms = 1e3 * seconds_since(t0) / iterations;
        const double cpu_ms = 1e3 * (process_cpu_seconds() - c0) / iterations;
        const double bytes = streamed_bytes(*lattice, solver->backend());
        const double stream_ms = 1e3 * bytes / (triad * 1e9);
        const double rate = in_cache_rate[model == SpringModel::model6 ? 0 : 1];
        const bool structured = solver->backend().rfind("structured", 0) == 0;
        const double compute_ms = structured && rate > 0.0 ? 1e3 * lattice->system.springs.size() / rate : 0.0;
        std::printf("%6d %6d %-19s %10.3f %10.3f %10.1f %12.3f %8.2f", n, static_cast<int>(model),
                    solver->backend().c_str(), ms, cpu_ms, bytes / 1e6, stream_ms, ms / stream_ms);
        if (compute_ms > 0.0) std::printf(" %11.3f %8.2f", compute_ms, ms / compute_ms);
        std::printf("\n");
        std::fflush(stdout);
        records.push_back(
            {{"section", "speed"},
             {"n", n},
             {"model", static_cast<int>(model)},
             {"solver", "verlet"},
             {"backend", solver->backend()},
             {"ms_per_iteration", ms},
             {"cpu_ms_per_iteration", cpu_ms},
             {"spring_loop", springs::detail::structured_simd_name()},
             {"load_average", load_average()},
             {"iterations_timed", iterations},
             {"streamed_bytes", bytes},
             {"stream_ms", stream_ms},
             {"ratio_to_stream", ms / stream_ms},
             {"compute_ms", compute_ms > 0.0 ? nlohmann::json(compute_ms) : nlohmann::json(nullptr)},
             {"ratio_to_compute", compute_ms > 0.0 ? nlohmann::json(ms / compute_ms) : nlohmann::json(nullptr)}});
      }
    }
  }
}

// Iterations until the relative residual <= tolerance, or -1 when it did not get there
// (divergence or the cap).
int iterations_to_rest(const Lattice& lattice, double mass, DampingMode mode, double damping, double dt,
                       double tolerance, int cap) {
  SettleOptions options;
  options.mass = mass;
  options.damping_mode = mode;
  options.damping = damping;
  options.dt = dt;
  options.tolerance = tolerance;
  options.max_iterations = cap;
  const LatticeShape shape = shape_of(lattice);
  SpringSystem system = lattice.system;
  try {
    const SettleReport report = settle(system, options, &shape);
    return report.converged ? report.iterations : -1;
  } catch (const SolverError&) { return -1; }
}

void run_rest(const SpringsBenchArgs& args, nlohmann::json& records) {
  std::printf("\n== Verlet iterations to rest (relative residual <= %g, dt = %g) against mass and damping\n",
              args.rest_tolerance, args.rest_dt);
  std::printf("   (thesis tables 7.4-7.6; best c from a scan of 32 log-spaced values in [0.05, 100])\n");
  std::printf("%4s %6s %7s %10s %9s %10s %9s %10s\n", "n", "model", "mass", "best c", "iters", "c (7.2)", "iters",
              "critical");
  const int cap = 20000;
  for (int n : parse_list(args.rest_sizes, "rest-sizes")) {
    for (SpringModel model : {SpringModel::model6, SpringModel::model26}) {
      const Lattice lattice = bench_lattice(n, model, 1.0);
      double rest_sum = 0.0;
      for (const Spring& s : lattice.system.springs) rest_sum += s.rest;
      const double mean_rest = rest_sum / lattice.system.springs.size();
      for (double mass : {8.0, 4.0, 2.0, 1.0, 0.5, 0.25, 0.125}) {
        double best_c = 0.0;
        int best = -1;
        for (int k = 0; k < 32; ++k) {
          const double c = 0.05 * std::pow(2000.0, k / 31.0);
          // A run that cannot beat the best so far is stopped there.
          const int it = iterations_to_rest(lattice, mass, DampingMode::value, c, args.rest_dt, args.rest_tolerance,
                                            best >= 0 ? best : cap);
          if (it >= 0 && (best < 0 || it < best)) {
            best = it;
            best_c = c;
          }
        }
        const double estimate = thesis_damping_estimate(mean_rest, mass);
        const int at_estimate =
            iterations_to_rest(lattice, mass, DampingMode::estimate, 0.0, args.rest_dt, args.rest_tolerance, cap);
        const int at_critical =
            iterations_to_rest(lattice, mass, DampingMode::critical, 0.0, args.rest_dt, args.rest_tolerance, cap);
        std::printf("%4d %6d %7.3f %10.3f %9d %10.3f %9d %10d\n", n, static_cast<int>(model), mass, best_c, best,
                    estimate, at_estimate, at_critical);
        std::fflush(stdout);
        records.push_back({{"section", "rest"},
                           {"n", n},
                           {"model", static_cast<int>(model)},
                           {"solver", "verlet"},
                           {"backend", "structured"},
                           {"mass", mass},
                           {"dt", args.rest_dt},
                           {"tolerance", args.rest_tolerance},
                           {"best_damping", best_c},
                           {"best_iterations", best},
                           {"estimate_damping", estimate},
                           {"estimate_iterations", at_estimate},
                           {"critical_iterations", at_critical}});
      }
    }
  }
}

struct TradeSolver {
  std::string name;
  SettleOptions options;
};

void run_trade(const SpringsBenchArgs& args, nlohmann::json& records) {
  std::printf(
      "\n== Speed/accuracy: wall seconds (setup included) to reach relative residual 1e-2, 1e-4, 1e-6 "
      "(limit %g s a run)\n",
      args.trade_limit);
  std::printf("%5s %6s %-22s %10s %10s %10s %10s %12s\n", "n", "model", "solver", "setup s", "1e-2", "1e-4", "1e-6",
              "iterations");
  std::vector<TradeSolver> solvers;
  {
    TradeSolver s;
    s.name = "verlet-estimate";
    s.options.damping_mode = DampingMode::estimate;
    solvers.push_back(s);
    s.name = "verlet-critical";
    s.options.damping_mode = DampingMode::critical;
    solvers.push_back(s);
    s = TradeSolver();
    s.name = "static-momentum";
    s.options.solver = SolverKind::static_equilibrium;
    s.options.static_method = StaticMethod::momentum;
    solvers.push_back(s);
    s.name = "static-momentum-fine";  // without the coarse start (coarse_start.h)
    s.options.coarse_start_points = 0;
    solvers.push_back(s);
    s.options.coarse_start_points = SettleOptions{}.coarse_start_points;
    s.name = "static-newton";
    s.options.static_method = StaticMethod::newton;
    solvers.push_back(s);
    s.name = "static-multigrid";
    s.options.static_method = StaticMethod::multigrid;
    solvers.push_back(s);
    s.name = "static-local-global";
    s.options.static_method = StaticMethod::local_global;
    solvers.push_back(s);
    s.name = "static-local-global-plain";
    s.options.acceleration = Acceleration::none;
    solvers.push_back(s);
  }
  const double thresholds[3] = {1e-2, 1e-4, 1e-6};
  for (int n : parse_list(args.trade_sizes, "trade-sizes")) {
    for (SpringModel model : {SpringModel::model6, SpringModel::model26}) {
      if (("," + args.trade_models + ",").find("," + std::to_string(static_cast<int>(model)) + ",") ==
          std::string::npos)
        continue;
      const Lattice lattice = bench_lattice(n, model, 1.1 / (static_cast<double>(n) * n * n));
      const LatticeShape shape = shape_of(lattice);
      for (const TradeSolver& entry : solvers) {
        if (!args.trade_solvers.empty() &&
            ("," + args.trade_solvers + ",").find("," + entry.name + ",") == std::string::npos)
          continue;
        if (entry.options.solver == SolverKind::static_equilibrium &&
            entry.options.static_method == StaticMethod::local_global && n > args.local_global_max_size) {
          std::printf("%5d %6d %-22s   skipped: sparse Cholesky factor too large above %d^3\n", n,
                      static_cast<int>(model), entry.name.c_str(), args.local_global_max_size);
          continue;
        }
        SettleOptions options = entry.options;
        options.tolerance = 1e-6;
        options.coarse_start_tolerance = args.coarse_start_tolerance;
        options.coarse_start_perturbation = args.coarse_start_perturbation;
        const std::string load_before = load_average();
        const double c0 = process_cpu_seconds();
        const auto t0 = clock_type::now();
        std::unique_ptr<SpringSolver> solver = make_solver(lattice.system, options, &shape);
        const double setup = seconds_since(t0);
        double reached[3] = {-1.0, -1.0, -1.0};
        int iterations = 0, next = 0;
        double residual = solver->residual(), last = residual;
        std::string status = "ok";
        try {
          while (next < 3) {
            while (next < 3 && residual <= thresholds[next]) reached[next++] = seconds_since(t0);
            if (next == 3) break;
            if (seconds_since(t0) > args.trade_limit) {
              status = "time limit";
              break;
            }
            last = solver->step();
            ++iterations;
            // Verlet measures before its step; confirm crossings at the current positions.
            residual = last <= thresholds[next] ? solver->residual() : last;
            if (solver->stalled()) {
              status = "stalled";
              residual = solver->residual();
              while (next < 3 && residual <= thresholds[next]) reached[next++] = seconds_since(t0);
              break;
            }
          }
        } catch (const SolverError& e) { status = std::string("diverged: ") + e.what(); }
        const double wall = seconds_since(t0), cpu = process_cpu_seconds() - c0;
        auto cell = [](double v) {
          char buffer[32];
          if (v < 0)
            std::snprintf(buffer, sizeof buffer, "%10s", "-");
          else
            std::snprintf(buffer, sizeof buffer, "%10.3f", v);
          return std::string(buffer);
        };
        const std::string start = solver->start_levels() > 0
                                      ? ", coarse start " + std::to_string(solver->start_levels()) + " levels " +
                                            std::to_string(solver->start_iterations()) + " iterations"
                                      : "";
        std::printf("%5d %6d %-22s %10.3f %s %s %s %12d  wall %.1f s, cpu %.1f s, load %s%s%s\n", n,
                    static_cast<int>(model), entry.name.c_str(), setup, cell(reached[0]).c_str(),
                    cell(reached[1]).c_str(), cell(reached[2]).c_str(), iterations, wall, cpu, load_before.c_str(),
                    start.c_str(),
                    status == "ok" ? "" : ("  (" + status + ", residual " + std::to_string(residual) + ")").c_str());
        std::fflush(stdout);
        for (int k = 0; k < 3; ++k)
          records.push_back({{"section", "trade"},
                             {"n", n},
                             {"model", static_cast<int>(model)},
                             {"solver", entry.name},
                             {"backend", solver->backend()},
                             {"tolerance", thresholds[k]},
                             {"seconds", reached[k] >= 0 ? nlohmann::json(reached[k]) : nlohmann::json(nullptr)},
                             {"setup_seconds", setup},
                             {"iterations", iterations},
                             {"inner_iterations", solver->inner_iterations()},
                             {"status", status},
                             {"start_levels", solver->start_levels()},
                             {"start_iterations", solver->start_iterations()},
                             {"coarse_start_perturbation", options.coarse_start_perturbation},
                             {"final_residual", residual},
                             {"wall_seconds", wall},
                             {"cpu_seconds", cpu},
                             {"load_average_before", load_before}});
      }
    }
  }
}

void run_springs_bench(const SpringsBenchArgs& args) {
  const std::string& loop = args.spring_loop;
  if (loop != "auto" && loop != "avx512" && loop != "avx2" && loop != "plain")
    throw OptionError("spring-loop: one of auto, avx512, avx2, plain, got " + loop);
  springs::detail::set_structured_simd(loop != "plain");
  springs::detail::set_structured_avx512(loop == "auto" || loop == "avx512");
  if (loop != "auto" && loop != springs::detail::structured_simd_name())
    throw OptionError("spring-loop: this processor cannot run the " + loop + " loop");
  nlohmann::json records = nlohmann::json::array();
  if (has_section(args, "templates")) {
    if (args.plots.empty()) throw OptionError("plots: section templates needs --plots FOLDER");
    for (TemplateKind kind : all_template_kinds()) {
      const std::string path = args.plots + "/" + template_name(kind) + ".svg";
      const std::string svg = template_svg(kind);
      write_file_atomically(path, [&](std::ostream& out) { out << svg; });
      std::printf("wrote %s\n", path.c_str());
    }
  }
  double triad = 0.0;
  if (has_section(args, "bandwidth") || has_section(args, "speed")) {
    const auto [copy, best_triad] = measure_bandwidth();
    triad = best_triad;
    std::printf("== memory bandwidth (STREAM-like, %zu threads): copy %.1f GB/s, triad %.1f GB/s\n",
                static_cast<std::size_t>(tbb::this_task_arena::max_concurrency()), copy, triad);
    records.push_back({{"section", "bandwidth"},
                       {"copy_gb_per_s", copy},
                       {"triad_gb_per_s", triad},
                       {"threads", tbb::this_task_arena::max_concurrency()}});
  }
  if (has_section(args, "speed")) run_speed(args, triad, records);
  if (has_section(args, "rest")) run_rest(args, records);
  if (has_section(args, "trade")) run_trade(args, records);
  if (!args.json.empty()) write_file_atomically(args.json, [&](std::ostream& out) { out << records.dump(2) << '\n'; });
}

}  // namespace

void add_springs_bench(CLI::App& bench) {
  auto args = std::make_shared<SpringsBenchArgs>();
  CLI::App* cmd = bench.add_subcommand("springs", "Spring solvers: ms/iteration, iterations to rest, speed/accuracy");
  cmd->add_option("--sizes", args->sizes, "Lattice sizes n (n^3 points) for ms/iteration")->capture_default_str();
  cmd->add_option("--rest-sizes", args->rest_sizes, "Sizes for iterations to rest (tables 7.4-7.6)")
      ->capture_default_str();
  cmd->add_option("--trade-sizes", args->trade_sizes, "Sizes for the speed/accuracy trade")->capture_default_str();
  cmd->add_option("--sections", args->sections, "Any of bandwidth,speed,rest,trade,templates")->capture_default_str();
  cmd->add_option("--trade-limit", args->trade_limit, "Seconds per trade run")->capture_default_str();
  cmd->add_option("--trade-solvers", args->trade_solvers,
                  "Only these trade solvers (verlet-estimate, verlet-critical, static-momentum, static-momentum-fine, "
                  "static-newton, static-multigrid, "
                  "static-local-global, static-local-global-plain); default all");
  cmd->add_option("--trade-models", args->trade_models, "Spring models for the trade (6, 26)")->capture_default_str();
  cmd->add_option("--min-seconds", args->min_seconds, "Seconds per ms/iteration measurement")->capture_default_str();
  cmd->add_option("--general-max-size", args->general_max_size, "Largest n timed on the general path")
      ->capture_default_str();
  cmd->add_option("--rest-dt", args->rest_dt, "Time step for the iterations-to-rest tables")->capture_default_str();
  cmd->add_option("--rest-tolerance", args->rest_tolerance, "Relative residual that counts as rest")
      ->capture_default_str();
  cmd->add_option("--coarse-start-tolerance", args->coarse_start_tolerance,
                  "Relative residual of the coarse lattices of static-momentum's coarse start")
      ->capture_default_str();
  cmd->add_option("--coarse-start-perturbation", args->coarse_start_perturbation,
                  "Share of the mean rest length by which static-momentum's coarse start offsets its free points "
                  "(model-6 lattices only; 0: none)")
      ->capture_default_str();
  cmd->add_option("--spring-loop", args->spring_loop,
                  "Structured path's spring loop: auto (the fastest the processor has), avx512, avx2 or plain")
      ->capture_default_str();
  cmd->add_option("--json", args->json, "Write the records as JSON here");
  cmd->add_option("--plots", args->plots, "Folder for the template pictures (section templates)");
  cmd->callback([args] { run_springs_bench(*args); });
}

}  // namespace fascicle::bench
