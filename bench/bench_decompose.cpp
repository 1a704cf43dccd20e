// fascicle bench decompose: speed of the decomposition of a repaired muscle by stage, every
// template on the LHDL muscles with their landmark files, and the whole corpus with repair.

#include "bench/bench_commands.h"

#include "fibres/decompose_mesh.h"
#include "geometry/atomic_file.h"
#include "geometry/errors.h"
#include "geometry/mesh_io.h"
#include "geometry/read_points.h"
#include "geometry/subdivide_mesh.h"
#include "repair/repair.h"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <array>
#include <chrono>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <limits>
#include <memory>
#include <optional>
#include <stdexcept>

#include <sys/resource.h>

namespace fascicle::bench {

namespace fs = std::filesystem;

namespace {

struct DecomposeBenchArgs {
  std::string data = FASCICLE_DATA_DIR;
  std::string muscle = "muscles/lhdl/LHDL_R_M081_GluteusMaximus_smooth.312.vtk";
  std::string json;
  int repeat = 5;
  bool skip_speed = false, skip_templates = false, skip_corpus = false;
  std::string scale;                                // "FIBRESxPOINTS,..." for the scale run; empty: no scale run
  bool scale_direct = false;                        // the scale run also with the harmonic start's direct solve forced
  std::string surface;                              // "1,2,3": subdivision levels of the surface run; empty: none
  bool surface_full = false;                        // the surface run also with the map on the whole surface
  double edge_cell = DecomposeOptions{}.edge_cell;  // DecomposeOptions::edge_cell of every run
  // The decomposition options of every run: the defaults but for the edge cells.
  DecomposeOptions options() const {
    DecomposeOptions o;
    o.edge_cell = edge_cell;
    return o;
  }
};

// "100x15,1000x30" -> {{100, 15}, {1000, 30}}.
std::vector<std::array<int, 2>> parse_scale(const std::string& text) {
  std::vector<std::array<int, 2>> sizes;
  std::size_t begin = 0;
  while (begin < text.size()) {
    const std::size_t end = std::min(text.find(',', begin), text.size());
    const std::string item = text.substr(begin, end - begin);
    const std::size_t x = item.find('x');
    try {
      if (x == std::string::npos) throw std::invalid_argument("no x");
      std::size_t used = 0;
      const int fibres = std::stoi(item.substr(0, x), &used);
      if (used != x) throw std::invalid_argument("fibres");
      const std::string points_text = item.substr(x + 1);
      const int points = std::stoi(points_text, &used);
      if (used != points_text.size()) throw std::invalid_argument("points");
      sizes.push_back({fibres, points});
    } catch (const std::exception&) {
      throw OptionError("--scale: '" + item + "' is not FIBRESxPOINTS (e.g. 1000x30)");
    }
    begin = end + 1;
  }
  return sizes;
}

// "1,2,3" -> {1, 2, 3}: subdivision levels, each in 0..4 and not below the one before.
std::vector<int> parse_levels(const std::string& text) {
  std::vector<int> levels;
  std::size_t begin = 0;
  while (begin < text.size()) {
    const std::size_t end = std::min(text.find(',', begin), text.size());
    const std::string item = text.substr(begin, end - begin);
    std::size_t used = 0;
    int level = -1;
    try {
      level = std::stoi(item, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    if (used != item.size() || item.empty() || level < 0 || level > 4 || (!levels.empty() && level < levels.back()))
      throw OptionError("--surface: '" + item + "' is not a level in 0..4 at or above the one before (e.g. 1,2,3)");
    levels.push_back(level);
    begin = end + 1;
  }
  return levels;
}

long peak_resident_kib() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return usage.ru_maxrss;
}

double cpu_seconds() { return static_cast<double>(std::clock()) / CLOCKS_PER_SEC; }
double since(std::chrono::steady_clock::time_point t) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count();
}
double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.empty() ? 0.0 : v[v.size() / 2];
}

nlohmann::json quality_json(const CheckReport& q) {
  return {{"pass", q.pass},
          {"inside_fraction", q.inside_fraction},
          {"inverted_cells", q.inverted_cells},
          {"coverage_p95", q.coverage.p95},
          {"attachment", std::max(q.attachment.origin_max, q.attachment.insertion_max)},
          {"crossing_segments", q.crossing_segments},
          {"max_segment_excursion_relative", q.max_segment_excursion_relative}};
}

// The stage times, wall time, peak memory so far and check figures of one decomposition.
nlohmann::json run_json(const Decomposition& d, double wall, long peak) {
  return {{"sphere_seconds", d.report.sphere_seconds},
          {"placement_seconds", d.report.placement_seconds},
          {"settle_seconds", d.report.settle_seconds},
          {"check_seconds", d.report.check_seconds},
          {"seconds", wall},
          {"peak_resident_kib_so_far", peak},
          {"quality", quality_json(d.report.quality)}};
}

void print_quality(const std::string& name, const std::string& status, const CheckReport& q, double seconds) {
  std::printf("%-52s %-8s %8.6f %6ld %7.3f %8.4f %8.3f\n", name.c_str(), status.c_str(), q.inside_fraction,
              q.inverted_cells, q.coverage.p95, std::max(q.attachment.origin_max, q.attachment.insertion_max), seconds);
}

void run_decompose_bench(const DecomposeBenchArgs& args) {
  nlohmann::json out = {{"speed", nlohmann::json::array()},
                        {"templates", nlohmann::json::array()},
                        {"corpus", nlohmann::json::array()},
                        {"scale", nlohmann::json::array()},
                        {"surface", nlohmann::json::array()}};
  const fs::path data(args.data);
  const std::vector<std::array<int, 2>> scale = parse_scale(args.scale);
  // The speed and scale runs decompose the same muscle: repaired once, when the first needs it.
  std::optional<TriangleMesh> repaired;
  const auto speed_muscle = [&]() -> const TriangleMesh& {
    if (!repaired) repaired = repair_mesh(read_polygon_soup((data / args.muscle).string())).mesh;
    return *repaired;
  };
  if (!args.skip_speed) {
    const TriangleMesh& muscle = speed_muscle();
    const fs::path tmp = fs::temp_directory_path() / "fascicle-bench-decompose.vtk";
    std::vector<double> wall, cpu, sphere, placement, settle, check, write;
    Decomposition d;
    for (int r = 0; r < args.repeat; ++r) {
      const auto t0 = std::chrono::steady_clock::now();
      const double c0 = cpu_seconds();
      d = decompose_repaired(muscle, Landmarks{}, args.options());
      const auto t1 = std::chrono::steady_clock::now();
      write_polylines(tmp.string(), d.fibres);
      write.push_back(since(t1));
      wall.push_back(since(t0));
      cpu.push_back(cpu_seconds() - c0);
      sphere.push_back(d.report.sphere_seconds);
      placement.push_back(d.report.placement_seconds);
      settle.push_back(d.report.settle_seconds);
      check.push_back(d.report.check_seconds);
    }
    fs::remove(tmp);
    const double without_check = median(wall) - median(check);
    std::printf("decompose %s: %zu vertices, %zu triangles, 100 fibres x 15 points, edge cells %g, median of %d\n",
                fs::path(args.muscle).filename().string().c_str(), muscle.positions.size(), muscle.triangles.size(),
                args.edge_cell, args.repeat);
    std::printf(
        "  sphere %.3f s, placement %.3f s, settle %.3f s, output %.3f s, check %.3f s; total %.3f s "
        "(cpu %.3f s), without the check %.3f s\n",
        median(sphere), median(placement), median(settle), median(write), median(check), median(wall), median(cpu),
        without_check);
    out["speed"].push_back({{"muscle", args.muscle},
                            {"vertices", muscle.positions.size()},
                            {"triangles", muscle.triangles.size()},
                            {"repeat", args.repeat},
                            {"edge_cell", args.edge_cell},
                            {"median_seconds", median(wall)},
                            {"median_cpu_seconds", median(cpu)},
                            {"median_without_check_seconds", without_check},
                            {"sphere_seconds", median(sphere)},
                            {"placement_seconds", median(placement)},
                            {"settle_seconds", median(settle)},
                            {"output_seconds", median(write)},
                            {"check_seconds", median(check)},
                            {"quality", quality_json(d.report.quality)}});
  }
  if (!scale.empty()) {
    // Larger lattices: where the time goes as the fibres and their points grow, and the harmonic
    // start's direct solve against the multigrid (DecomposeOptions::harmonic_direct_points).
    const TriangleMesh& muscle = speed_muscle();
    std::printf("scale: %s, %zu triangles, one decomposition each (seconds; memory: the bench's peak so far)\n",
                fs::path(args.muscle).filename().string().c_str(), muscle.triangles.size());
    std::printf("%7s %6s %8s %-13s %9s %8s %8s %8s %8s %6s %7s %9s\n", "fibres", "points", "lattice", "harmonic",
                "harm s", "sphere", "settle", "check", "total", "invert", "cov95", "peak MiB");
    for (const auto& [fibres, points] : scale) {
      for (const bool direct : {false, true}) {
        if (direct && !args.scale_direct) continue;
        DecomposeOptions options = args.options();
        options.fibres = fibres;
        options.resolution = points;
        if (direct) options.harmonic_direct_points = std::numeric_limits<long>::max();
        const auto t0 = std::chrono::steady_clock::now();
        const Decomposition d = decompose_repaired(muscle, Landmarks{}, options);
        const double wall = since(t0);
        const nlohmann::json& h = d.report.settle["harmonic"];
        const double harmonic_seconds =
            h["factor_seconds"].get<double>() + h["setup_seconds"].get<double>() + h["seconds"].get<double>();
        const long lattice = d.report.lattice["points"].get<long>();
        const long peak = peak_resident_kib();
        std::printf("%7d %6d %8ld %-13s %9.3f %8.3f %8.3f %8.3f %8.3f %6ld %7.3f %9.1f\n", fibres, points, lattice,
                    h["backend"].get<std::string>().c_str(), harmonic_seconds, d.report.sphere_seconds,
                    d.report.settle_seconds, d.report.check_seconds, wall, d.report.quality.inverted_cells,
                    d.report.quality.coverage.p95, static_cast<double>(peak) / 1024.0);
        nlohmann::json row = run_json(d, wall, peak);
        row.update({{"muscle", args.muscle},
                    {"fibres", fibres},
                    {"resolution", points},
                    {"lattice_points", lattice},
                    {"harmonic_backend", h["backend"]},
                    {"harmonic_factor_seconds", h["factor_seconds"]},
                    {"harmonic_setup_seconds", h["setup_seconds"]},
                    {"harmonic_solve_seconds", h["seconds"]},
                    {"harmonic_iterations", h["iterations"]}});
        out["scale"].push_back(std::move(row));
      }
    }
  }
  if (!args.surface.empty()) {
    // Finer surfaces of the same muscle (midpoint subdivision: the same shape, 4 times the
    // triangles a level): the map on the surface simplified to DecomposeOptions::map_faces, and
    // with --surface-full on the whole surface, each judged by the whole check's figures.
    const std::vector<int> levels = parse_levels(args.surface);
    TriangleMesh surface = speed_muscle();
    int level_made = 0;
    std::printf("surface: %s subdivided, one decomposition each (seconds; memory: the bench's peak so far)\n",
                fs::path(args.muscle).filename().string().c_str());
    std::printf("%5s %9s %-10s %9s %8s %8s %8s %8s %6s %7s %9s %11s %9s\n", "level", "triangles", "map", "simplify",
                "sphere", "check", "total", "pass", "segs", "turn", "ends", "", "peak MiB");
    for (const int level : levels) {
      while (level_made < level) surface = subdivide_mesh(surface), ++level_made;
      for (const bool full : {false, true}) {
        // A surface at or under map_faces is mapped whole anyway.
        if (full && (!args.surface_full || static_cast<long>(surface.triangles.size()) <= args.options().map_faces))
          continue;
        DecomposeOptions options = args.options();
        if (full) options.map_faces = std::numeric_limits<long>::max();
        const auto t0 = std::chrono::steady_clock::now();
        const Decomposition d = decompose_repaired(surface, Landmarks{}, options);
        const double wall = since(t0);
        const CheckReport& q = d.report.quality;
        const bool simplified = d.report.sphere.contains("simplified");
        const double simplify_seconds = simplified ? d.report.sphere["simplified"]["seconds"].get<double>() : 0.0;
        const long map_triangles =
            simplified ? d.report.sphere["simplified"]["faces_after"].get<long>() : static_cast<long>(surface.triangles.size());
        const long peak = peak_resident_kib();
        std::printf("%5d %9zu %-10ld %9.3f %8.3f %8.3f %8.3f %8s %6ld %7.1f %5.2f/%5.2f %9.1f\n", level,
                    surface.triangles.size(), map_triangles, simplify_seconds, d.report.sphere_seconds,
                    d.report.check_seconds, wall, q.pass ? "pass" : "FAIL", q.crossing_segments, q.turning.max_deg,
                    q.origin_ends.share, q.insertion_ends.share, static_cast<double>(peak) / 1024.0);
        nlohmann::json row = run_json(d, wall, peak);
        row.update({{"muscle", args.muscle},
                    {"level", level},
                    {"triangles", surface.triangles.size()},
                    {"map_triangles", map_triangles},
                    {"simplify_seconds", simplify_seconds},
                    {"max_turning_deg", q.turning.max_deg},
                    {"ends", {q.origin_ends.share, q.insertion_ends.share}}});
        out["surface"].push_back(std::move(row));
      }
    }
  }
  if (!args.skip_templates || !args.skip_corpus)
    std::printf("%-52s %-8s %8s %6s %7s %8s %8s\n", "muscle", "status", "inside", "invert", "cov95", "attach",
                "seconds");
  if (!args.skip_templates) {
    const fs::path lhdl = data / "muscles" / "lhdl";
    for (const char* name :
         {"LHDL_R_M081_GluteusMaximus", "LHDL_R_M082_GluteusMedius", "LHDL_R_M090_Psoas", "LHDL_R_M091_Iliacus"}) {
      fs::path mesh;
      for (const auto& e : fs::directory_iterator(lhdl))
        if (e.path().filename().string().rfind(std::string(name) + "_smooth", 0) == 0) mesh = e.path();
      if (mesh.empty()) continue;
      Landmarks landmarks;
      landmarks.origin_source = (lhdl / (std::string(name) + ".origin.xyz")).string();
      landmarks.insertion_source = (lhdl / (std::string(name) + ".insertion.xyz")).string();
      landmarks.origin = read_points(landmarks.origin_source);
      landmarks.insertion = read_points(landmarks.insertion_source);
      for (springs::TemplateKind kind : springs::all_template_kinds()) {
        DecomposeOptions options = args.options();
        options.kind = kind;
        const std::string label = std::string(name) + " " + springs::template_name(kind);
        const auto t0 = std::chrono::steady_clock::now();
        try {
          const Decomposition d = decompose(read_polygon_soup(mesh.string()), landmarks, options);
          print_quality(label, d.report.status, d.report.quality, since(t0));
          out["templates"].push_back({{"muscle", name},
                                      {"template", springs::template_name(kind)},
                                      {"status", d.report.status},
                                      {"seconds", since(t0)},
                                      {"quality", quality_json(d.report.quality)}});
        } catch (const Error& e) {
          std::printf("%-52s %-8s %s\n", label.c_str(), "error", e.what());
          out["templates"].push_back({{"muscle", name},
                                      {"template", springs::template_name(kind)},
                                      {"status", "error"},
                                      {"error", e.what()},
                                      {"seconds", since(t0)}});
        }
      }
    }
  }
  if (!args.skip_corpus) {
    std::vector<fs::path> meshes;
    for (const auto& e : fs::recursive_directory_iterator(data / "muscles")) {
      const std::string ext = e.path().extension().string();
      if (e.is_regular_file() && (ext == ".vtk" || ext == ".stl" || ext == ".off" || ext == ".obj" || ext == ".ply"))
        meshes.push_back(e.path());
    }
    std::sort(meshes.begin(), meshes.end());
    const auto start = std::chrono::steady_clock::now();
    int ok = 0;
    for (const fs::path& mesh : meshes) {
      const auto t0 = std::chrono::steady_clock::now();
      const std::string label = mesh.filename().string();
      try {
        const Decomposition d = decompose(read_polygon_soup(mesh.string()), Landmarks{}, args.options());
        print_quality(label, d.report.status, d.report.quality, since(t0));
        ok += d.report.status == "ok";
        out["corpus"].push_back({{"muscle", label},
                                 {"status", d.report.status},
                                 {"seconds", since(t0)},
                                 {"repair_seconds", d.report.repair_seconds},
                                 {"quality", quality_json(d.report.quality)}});
      } catch (const Error& e) {
        std::printf("%-52s %-8s %s\n", label.c_str(), "error", e.what());
        out["corpus"].push_back({{"muscle", label}, {"status", "error"}, {"error", e.what()}, {"seconds", since(t0)}});
      }
    }
    std::printf("corpus: %d of %zu pass every criterion; %.1f s for all, one after another, with repair\n", ok,
                meshes.size(), since(start));
    out["corpus_seconds"] = since(start);
    out["corpus_pass"] = ok;
  }
  if (!args.json.empty()) write_file_atomically(args.json, [&](std::ostream& s) { s << out.dump(2) << '\n'; });
}

}  // namespace

void add_decompose_bench(CLI::App& bench) {
  auto args = std::make_shared<DecomposeBenchArgs>();
  CLI::App* cmd = bench.add_subcommand("decompose", "Decomposition speed by stage; templates on LHDL; the corpus");
  cmd->add_option("--data", args->data, "Data folder (../shared/data)")->capture_default_str();
  cmd->add_option("--muscle", args->muscle, "Muscle for the speed run, relative to --data")->capture_default_str();
  cmd->add_option("--repeat", args->repeat, "Repetitions of the speed run (median)")->capture_default_str();
  cmd->add_option("--json", args->json, "Write the records as JSON");
  cmd->add_flag("--skip-speed", args->skip_speed, "Skip the speed run");
  cmd->add_flag("--skip-templates", args->skip_templates, "Skip the templates on the LHDL muscles");
  cmd->add_flag("--skip-corpus", args->skip_corpus, "Skip the corpus run");
  cmd->add_option("--scale", args->scale,
                  "Also decompose the --muscle with these lattices, FIBRESxPOINTS,... (e.g. 100x15,1000x30,2000x50)");
  cmd->add_option("--edge-cell", args->edge_cell,
                  "Every run with this width of the edge cells (decompose --edge-cell), in fibre spacings")
      ->capture_default_str();
  cmd->add_option("--surface", args->surface,
                  "Subdivision levels of the speed muscle for the surface run, e.g. 1,2,3 (4 times the triangles a "
                  "level); empty: no surface run");
  cmd->add_flag("--surface-full", args->surface_full,
                "The surface run also with the sphere map on the whole surface (no simplification)");
  cmd->add_flag("--scale-direct", args->scale_direct,
                "Scale run: each size also with the harmonic start's direct solve forced (for comparison)");
  cmd->callback([args] { run_decompose_bench(*args); });
}

}  // namespace fascicle::bench
