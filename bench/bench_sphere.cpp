// fascicle bench sphere: speed of the sphere map and of point location, and the map quality of
// every corpus muscle (after repair) beside the thesis's relaxation on the same mesh.

#include "bench/bench_commands.h"

#include "geometry/errors.h"
#include "geometry/mesh_io.h"
#include "geometry/subdivide_mesh.h"
#include "morph/sphere_locator.h"
#include "morph/sphere_map.h"
#include "repair/repair.h"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <ctime>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <random>

namespace fascicle::bench {

namespace fs = std::filesystem;

namespace {

struct SphereBenchArgs {
  std::string data = FASCICLE_DATA_DIR;
  std::string muscle = "muscles/lhdl/LHDL_R_M081_GluteusMaximus_smooth.312.vtk";
  std::string json;
  int repeat = 5;
  long points = 1'000'000;
  int relax_iterations = 3000;
  bool skip_corpus = false;
  bool skip_speed = false;
  bool skip_relax = false;
};

/// Processor time of this process so far, seconds (all threads).
double cpu_seconds() { return static_cast<double>(std::clock()) / CLOCKS_PER_SEC; }

double seconds_since(std::chrono::steady_clock::time_point t) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count();
}

/// Median wall time of `repeat` maps (and through `cpu` the median processor time); the last
/// map is returned through `map`.
double time_map(const TriangleMesh& mesh, const SphereMapOptions& options, int repeat, SphereMap& map, double& cpu) {
  std::vector<double> times, cpus;
  for (int r = 0; r < repeat; ++r) {
    const auto t0 = std::chrono::steady_clock::now();
    const double c0 = cpu_seconds();
    map = map_to_sphere(mesh, options);
    cpus.push_back(cpu_seconds() - c0);
    times.push_back(seconds_since(t0));
  }
  std::sort(times.begin(), times.end());
  std::sort(cpus.begin(), cpus.end());
  cpu = cpus[cpus.size() / 2];
  return times[times.size() / 2];
}

void run_sphere_bench(const SphereBenchArgs& args) {
  nlohmann::json out = {{"speed", nlohmann::json::array()}, {"corpus", nlohmann::json::array()}};
  if (!args.skip_speed) {
    const std::string path = (fs::path(args.data) / args.muscle).string();
    const TriangleMesh muscle = repair_mesh(read_polygon_soup(path)).mesh;
    SphereMap map;
    const TriangleMesh big = subdivide_mesh(subdivide_mesh(muscle));
    struct Case {
      std::string name;
      const TriangleMesh* mesh;
      SphereMapOptions options;
    };
    SphereMapOptions progressive;
    progressive.start = SphereStart::progressive;
    std::printf("%-44s %9s %9s %9s %9s %8s %8s %7s\n", "case", "vertices", "triangles", "wall s", "cpu s", "flipped",
                "degen", "log|A|");
    // The default-start map of the subdivided muscle comes last: its map is the locator's.
    for (const Case& c : {Case{"map " + fs::path(args.muscle).filename().string(), &muscle, SphereMapOptions{}},
                          Case{"map same, progressive start", &muscle, progressive},
                          Case{"map subdivided twice, progressive start", &big, progressive},
                          Case{"map same, subdivided twice", &big, SphereMapOptions{}}}) {
      double cpu = 0.0;
      const double t = time_map(*c.mesh, c.options, args.repeat, map, cpu);
      const SphereQuality& q = map.report.quality;
      std::printf("%-44s %9zu %9zu %9.3f %9.3f %8ld %8ld %7.3f\n", c.name.c_str(), c.mesh->positions.size(),
                  c.mesh->triangles.size(), t, cpu, q.flipped, q.degenerate, q.area_log_mean);
      out["speed"].push_back({{"case", c.name},
                              {"vertices", c.mesh->positions.size()},
                              {"triangles", c.mesh->triangles.size()},
                              {"median_seconds", t},
                              {"median_cpu_seconds", cpu},
                              {"repeat", args.repeat},
                              {"report", map.report.to_json()}});
    }
    // Point location: `points` random directions in the subdivided muscle's map.
    std::mt19937 random(12345);
    std::normal_distribution<double> gauss;
    std::vector<Vec3> directions(static_cast<std::size_t>(args.points));
    for (Vec3& d : directions) d = Vec3(gauss(random), gauss(random), gauss(random));
    auto t0 = std::chrono::steady_clock::now();
    const SphereLocator locator(map.positions, big.triangles);
    const double build = seconds_since(t0);
    std::vector<double> times, cpus;
    std::vector<SurfacePoint> hits;
    for (int r = 0; r < std::max(1, args.repeat / 2); ++r) {
      t0 = std::chrono::steady_clock::now();
      const double c0 = cpu_seconds();
      hits = locator.locate_all(directions);
      cpus.push_back(cpu_seconds() - c0);
      times.push_back(seconds_since(t0));
    }
    std::sort(times.begin(), times.end());
    std::sort(cpus.begin(), cpus.end());
    const double locate = times[times.size() / 2], locate_cpu = cpus[cpus.size() / 2];
    std::printf("%-44s %9zu %9zu %9.3f %9.3f  (locator build %.3f s, TBB threads)\n",
                ("locate " + std::to_string(args.points) + " points").c_str(), big.positions.size(),
                big.triangles.size(), locate, locate_cpu, build);
    out["speed"].push_back({{"case", "locate"},
                            {"points", args.points},
                            {"triangles", big.triangles.size()},
                            {"median_seconds", locate},
                            {"median_cpu_seconds", locate_cpu},
                            {"locator_build_seconds", build}});
  }
  if (!args.skip_corpus) {
    std::vector<fs::path> files;
    for (const auto& e : fs::recursive_directory_iterator(fs::path(args.data) / "muscles")) {
      if (!e.is_regular_file()) continue;
      std::string ext = e.path().extension().string();
      std::transform(ext.begin(), ext.end(), ext.begin(), ::tolower);
      if (ext == ".stl" || ext == ".vtk") files.push_back(e.path());
    }
    std::sort(files.begin(), files.end());
    std::printf("\n%-48s %7s | %-5s %5s %5s %8s %8s %6s %7s | %-6s %6s %6s %7s %7s\n", "muscle", "verts", "start",
                "flip", "degen", "A_min", "A_max", "log|A|", "sec", "relax", "flip", "iter", "log|A|", "sec");
    SphereMapOptions relax;
    relax.method = SphereMethod::relax;
    relax.relax_max_iterations = args.relax_iterations;
    for (const fs::path& file : files) {
      nlohmann::json rec = {{"mesh", fs::relative(file, args.data).string()}};
      try {
        const TriangleMesh mesh = repair_mesh(read_polygon_soup(file.string())).mesh;
        const SphereMap a = map_to_sphere(mesh);
        SphereMap b;
        if (args.skip_relax) {
          b.report.status = "skipped";
        } else {
          b = map_to_sphere(mesh, relax);
        }
        const SphereQuality &qa = a.report.quality, &qb = b.report.quality;
        rec["vertices"] = mesh.positions.size();
        rec["tutte"] = a.report.to_json();
        if (!args.skip_relax) rec["relax"] = b.report.to_json();
        std::printf("%-48s %7zu | %-5s %5ld %5ld %8.2g %8.3g %6.3f %7.3f | %-6s %6ld %6d %7.3f %7.2f\n",
                    file.filename().string().substr(0, 48).c_str(), mesh.positions.size(),
                    a.report.initial_map.substr(0, 5).c_str(), qa.flipped, qa.degenerate, qa.area_ratio_min,
                    qa.area_ratio_max, qa.area_log_mean, a.report.seconds, b.report.status.c_str(), qb.flipped,
                    b.report.iterations, qb.area_log_mean, b.report.seconds);
      } catch (const Error& e) {
        rec["error"] = e.what();
        std::printf("%-48s error: %s\n", file.filename().string().substr(0, 48).c_str(), e.what());
      }
      std::fflush(stdout);
      out["corpus"].push_back(rec);
    }
  }
  if (!args.json.empty()) {
    std::ofstream file(args.json);
    file << out.dump(2) << '\n';
  }
}

}  // namespace

void add_sphere_bench(CLI::App& bench) {
  auto args = std::make_shared<SphereBenchArgs>();
  CLI::App* cmd = bench.add_subcommand("sphere", "Sphere map speed, point location speed, corpus map quality");
  cmd->add_option("--data", args->data, "Corpus folder")->capture_default_str();
  cmd->add_option("--muscle", args->muscle, "Speed-test muscle, relative to --data")->capture_default_str();
  cmd->add_option("--repeat", args->repeat, "Runs per timing (median reported)")->capture_default_str();
  cmd->add_option("--points", args->points, "Directions to locate")->capture_default_str();
  cmd->add_option("--relax-iterations", args->relax_iterations, "Iteration cap of the thesis method")
      ->capture_default_str();
  cmd->add_flag("--skip-corpus", args->skip_corpus, "Only the speed cases");
  cmd->add_flag("--skip-speed", args->skip_speed, "Only the corpus table");
  cmd->add_flag("--skip-relax", args->skip_relax, "Corpus table without the thesis method");
  cmd->add_option("--json", args->json, "Write the records as JSON");
  cmd->callback([args] { run_sphere_bench(*args); });
}

}  // namespace fascicle::bench
