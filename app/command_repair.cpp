// fascicle repair IN -o OUT [--report R.json]: any mesh in, a closed genus-0 manifold out.

#include "app/commands.h"
#include "app/report_file.h"
#include "geometry/atomic_file.h"
#include "geometry/errors.h"
#include "geometry/mesh_io.h"
#include "repair/repair.h"

#include <nlohmann/json.hpp>
#include <spdlog/spdlog.h>

#include <memory>

namespace fascicle::app {

namespace {

struct RepairArgs {
  std::string input, output, report;
  RepairOptions options;
  std::string components = "largest";
  bool no_wrap = false;
};

void run_repair(const RepairArgs& args) {
  RepairOptions options = args.options;
  options.components = args.components == "merge" ? ComponentPolicy::merge : ComponentPolicy::largest;
  options.allow_wrap = !args.no_wrap;
  options.validate();
  check_not_same_file(args.input, args.output);
  if (!args.report.empty()) check_not_same_file(args.input, args.report);
  const PolygonSoup soup = read_polygon_soup(args.input);
  spdlog::info("read {}: {} points, {} faces", args.input, soup.points.size(), soup.polygons.size());
  try {
    const RepairResult result = repair_mesh(soup, options);
    write_triangle_mesh(args.output, result.mesh);
    nlohmann::json report = result.report.to_json();
    report["input_file"] = args.input;
    report["output_file"] = args.output;
    if (!args.report.empty()) write_json_report(args.report, report);
    spdlog::info("wrote {}: {} vertices, {} faces, {}{} ({:.2f} s)", args.output, result.mesh.positions.size(),
                 result.mesh.triangles.size(), result.report.status,
                 result.report.fallback_used ? " by alpha wrap" : "", result.report.seconds);
  } catch (const Error& e) {
    nlohmann::json report = {{"input_file", args.input}};
    write_failure_report(args.report, report, e);
    throw;
  }
}

}  // namespace

void add_repair_command(CLI::App& app) {
  auto args = std::make_shared<RepairArgs>();
  CLI::App* cmd = app.add_subcommand("repair", "Repair a mesh into one closed, genus-0, outward 2-manifold");
  cmd->add_option("input", args->input, "Input mesh (off, obj, stl, ply, vtk, txt)")->required();
  cmd->add_option("-o,--output", args->output, "Output mesh (off, obj, stl, ply, vtk)")->required();
  cmd->add_option("--report", args->report, "Write a JSON report of every step");
  cmd->add_option("--weld-tolerance", args->options.weld_tolerance,
                  "Weld vertices closer than this fraction of the bounding-box diagonal")
      ->capture_default_str();
  cmd->add_option("--components", args->components,
                  "largest: keep the largest component; merge: wrap all components into one")
      ->check(CLI::IsMember({"largest", "merge"}))
      ->capture_default_str();
  cmd->add_option("--min-largest-share", args->options.min_largest_share,
                  "Largest component's minimum area share for keep-largest; below it, wrap")
      ->capture_default_str();
  cmd->add_flag("--no-wrap", args->no_wrap, "Refuse instead of falling back to alpha wrapping");
  cmd->add_option("--wrap-alpha", args->options.wrap_alpha, "Finest alpha-wrap alpha as a fraction of the diagonal")
      ->capture_default_str();
  cmd->add_option("--wrap-seconds", args->options.wrap_seconds, "Time budget of the alpha-wrap fallback")
      ->capture_default_str();
  cmd->add_option("--wrap-memory-mb", args->options.wrap_memory_mb,
                  "Address-space limit of each alpha-wrap worker process, MiB (0: none)")
      ->capture_default_str();
  cmd->callback([args] { run_repair(*args); });
}

}  // namespace fascicle::app
