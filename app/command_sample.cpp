// fascicle sample -o OUT [--seed N] [--clean] [--log LOG.json] [--kind SHAPE] [--inject KIND ...]
// [--random-defects N]: writes the built-in sample muscle (with CT-like defects unless --clean),
// or a test shape, optionally with chosen defects, and a JSON log of what was injected.

#include "app/commands.h"
#include "app/report_file.h"
#include "geometry/atomic_file.h"
#include "geometry/errors.h"
#include "geometry/inject_defects.h"
#include "geometry/mesh_io.h"
#include "geometry/primitives.h"
#include "geometry/sample_muscle.h"

#include <nlohmann/json.hpp>
#include <spdlog/spdlog.h>

#include <memory>
#include <string>
#include <vector>

namespace fascicle::app {

namespace {

constexpr double kPi = 3.14159265358979323846;

struct SampleArgs {
  std::string output, log;
  std::string kind = "muscle";
  std::vector<std::string> inject;
  int random_defects = 0;
  bool clean = false;
  SampleOptions options;
};

// The test shapes, in millimetres, sized like small muscles.
TriangleMesh make_shape(const std::string& kind, const SampleOptions& options) {
  if (kind == "muscle") return make_fusiform_muscle(options);
  if (kind == "capsule") return make_capsule(100.0, 1.0, 24);  // aspect 50:1
  if (kind == "icosphere") return make_icosphere(4, 20.0);
  if (kind == "cube") return make_cube(40.0, 10);
  if (kind == "tube") return make_bent_tube(40.0, 8.0, 2.0 * kPi / 3.0, 32);
  if (kind == "torus") return make_torus(30.0, 8.0, 64, 32);
  if (kind == "tetrahedron") return make_tetrahedron(10.0);
  throw OptionError("--kind " + kind + " is invalid");
}

void run_sample(const SampleArgs& args) {
  args.options.validate();
  if (args.clean && (!args.inject.empty() || args.random_defects > 0))
    throw OptionError("--clean cannot be combined with --inject or --random-defects");
  if (!args.log.empty()) check_not_same_file(args.output, args.log);
  std::vector<DefectKind> kinds;
  for (const std::string& name : args.inject) {
    kinds.push_back(defect_kind_from_name(name));
    // The mesh writers refuse non-finite coordinates by design (a file must mean what was
    // computed), so a NaN sample could never be written; NaN is for in-memory tests only.
    if (kinds.back() == DefectKind::nan_coordinates)
      throw OptionError("--inject nan_coordinates cannot be written: mesh writers refuse non-finite coordinates");
  }

  DefectLog log;
  PolygonSoup soup;
  const bool default_defects = args.kind == "muscle" && !args.clean && kinds.empty() && args.random_defects == 0;
  if (default_defects) {
    soup = make_sample(args.options, &log);
  } else {
    soup = to_soup(make_shape(args.kind, args.options));
    for (std::size_t i = 0; i < kinds.size(); ++i)
      soup = inject(soup, kinds[i], derive_seed(args.options.seed, 100 + i), DefectParams{}, &log);
    if (args.random_defects > 0)
      soup = inject_random_combination(soup, derive_seed(args.options.seed, 99), args.random_defects, &log);
  }
  write_triangle_mesh(args.output, soup_triangles(soup));
  spdlog::info("wrote {}: {} {}, {} points, {} triangles, {} defect kind(s)", args.output, args.kind,
               default_defects || !log.records.empty() ? "with defects" : "clean", soup.points.size(),
               soup.polygons.size(), log.records.size());
  for (const DefectRecord& r : log.records) spdlog::debug("{} x{}: {}", defect_name(r.kind), r.count, r.note);

  if (!args.log.empty()) {
    nlohmann::json defects = nlohmann::json::array();
    for (const DefectRecord& r : log.records)
      defects.push_back({{"kind", defect_name(r.kind)}, {"count", r.count}, {"note", r.note}});
    nlohmann::json report = {
        {"shape", args.kind},         {"seed", args.options.seed},    {"clean", log.records.empty()},
        {"output_file", args.output}, {"points", soup.points.size()}, {"faces", soup.polygons.size()},
        {"defects", defects}};
    write_json_report(args.log, report);
  }
}

}  // namespace

void add_sample_command(CLI::App& app) {
  auto args = std::make_shared<SampleArgs>();
  CLI::App* cmd = app.add_subcommand(
      "sample", "Write the built-in sample muscle (with CT-like defects unless --clean) or a test shape");
  cmd->add_option("-o,--output", args->output, "Output mesh (off, obj, stl, ply, vtk)")->required();
  cmd->add_option("--seed", args->options.seed, "Seed of every random defect choice")->capture_default_str();
  cmd->add_flag("--clean", args->clean, "Write the clean surface, without defects");
  cmd->add_option("--log", args->log, "Write a JSON log of the injected defects");
  cmd->add_option("--kind", args->kind,
                  "Shape: the sample muscle or a test shape (test shapes are clean "
                  "unless --inject or --random-defects)")
      ->check(CLI::IsMember({"muscle", "capsule", "icosphere", "cube", "tube", "torus", "tetrahedron"}))
      ->capture_default_str();
  std::vector<std::string> names;
  for (DefectKind k : all_defect_kinds()) names.push_back(defect_name(k));
  cmd->add_option("--inject", args->inject,
                  "Inject these defect kinds, in the order given, instead of the sample's default set")
      ->check(CLI::IsMember(names));
  cmd->add_option("--random-defects", args->random_defects,
                  "Inject this many distinct defect kinds drawn by the seed (no NaN)")
      ->check(CLI::Range(0, 15));
  cmd->add_option("--length", args->options.length, "Muscle length tip to tip (mm)")->capture_default_str();
  cmd->add_option("--belly-radius", args->options.belly_radius, "Muscle belly radius (mm)")->capture_default_str();
  cmd->add_option("--tendon-radius", args->options.tendon_radius, "Muscle tendon radius (mm)")->capture_default_str();
  cmd->add_option("--rings", args->options.rings, "Muscle rings between the tips")->capture_default_str();
  cmd->add_option("--segments", args->options.segments, "Muscle points per ring")->capture_default_str();
  cmd->callback([args] { run_sample(*args); });
}

}  // namespace fascicle::app
