// fascicle check FIBRES MUSCLE [--origin O.xyz --insertion I.xyz] [--json] [--report R.json]
// [--strict]: the fibre quality check (fibres/fibre_check.h) on fibres from any tool. The muscle
// is repaired with default options when it is not already a closed genus-0 manifold; areas are
// automatic without landmark files. Prints a table (or the JSON report with --json); --strict
// exits with code 19 (quality) when a criterion fails.

#include "app/commands.h"
#include "app/report_file.h"
#include "fibres/architecture.h"
#include "fibres/fibre_check.h"
#include "fibres/landmark_strip.h"
#include "geometry/atomic_file.h"
#include "geometry/errors.h"
#include "geometry/mesh_io.h"
#include "geometry/read_points.h"
#include "morph/attachments.h"
#include "repair/repair.h"

#include <nlohmann/json.hpp>
#include <spdlog/spdlog.h>

#include <cstdio>
#include <memory>

namespace fascicle::app {

namespace {

struct CheckArgs {
  std::string fibres, muscle, origin, insertion, report, architecture;
  ArchitectureOptions architecture_options;
  bool json = false, strict = false, summary = false;
  CheckOptions options;
  AttachmentOptions attachments;
  StripOptions strip;  ///< landmark areas joined into strips, as `fascicle decompose` does (default on)
};

/// The soup as a triangle mesh when every polygon is a triangle, else nullopt.
bool as_triangle_mesh(const PolygonSoup& soup, TriangleMesh& mesh) {
  mesh.positions = soup.points;
  mesh.triangles.clear();
  mesh.triangles.reserve(soup.polygons.size());
  for (const auto& polygon : soup.polygons) {
    if (polygon.size() != 3) return false;
    mesh.triangles.push_back({polygon[0], polygon[1], polygon[2]});
  }
  return true;
}

void run_check(const CheckArgs& args) {
  args.options.validate();
  args.attachments.validate();
  args.strip.validate();
  if (args.origin.empty() != args.insertion.empty())
    throw OptionError("--origin and --insertion go together (give both, or neither for automatic areas)");
  args.architecture_options.validate();
  if (!args.report.empty()) {
    check_not_same_file(args.fibres, args.report);
    check_not_same_file(args.muscle, args.report);
    check_output_path(args.report);
  }
  if (!args.architecture.empty()) {
    check_output_path(args.architecture);
    const std::string ext = lower_extension(args.architecture);
    if (ext != "json" && ext != "csv")
      throw InputError(ErrorCode::unknown_format,
                       args.architecture + ": cannot write the architecture as '" + ext + "' (use .json or .csv)");
  }
  const Polylines fibres = read_polylines(args.fibres);
  spdlog::info("read {}: {} fibres", args.fibres, fibres.lines.size());
  const PolygonSoup soup = read_polygon_soup(args.muscle);
  TriangleMesh muscle;
  std::string problem = as_triangle_mesh(soup, muscle) ? verify_genus0(muscle) : "it has faces that are not triangles";
  const bool repaired = !problem.empty();
  if (repaired) {
    spdlog::info("{} is not a closed genus-0 manifold ({}): repairing it with default options", args.muscle, problem);
    RepairResult result = repair_mesh(soup, RepairOptions{});
    muscle = std::move(result.mesh);
    spdlog::info("repaired {}: {} vertices, {} triangles", args.muscle, muscle.positions.size(),
                 muscle.triangles.size());
  }
  Attachments areas = args.origin.empty()
                          ? automatic_attachments(muscle, args.attachments)
                          : landmark_attachments(muscle, read_points(args.origin), args.origin,
                                                 read_points(args.insertion), args.insertion, args.attachments);
  // Landmark areas are measured as `fascicle decompose` measures them: joined into strips along
  // their spanning tree (fibres/landmark_strip.h), unless --landmark-strip false.
  const SurfaceQuery query(muscle);
  const bool strips = !args.origin.empty() && args.strip.join;
  nlohmann::json strip_report;
  if (!args.origin.empty()) strip_report = join_landmark_strips(areas, query, muscle_length(muscle), args.strip);
  const CheckReport report = check_fibres(fibres, muscle, query, areas, args.options);
  const Architecture architecture = measure_architecture(fibres, muscle, areas, args.architecture_options);

  nlohmann::json json = report.to_json();
  json["fibres_file"] = args.fibres;
  json["muscle_file"] = args.muscle;
  json["muscle_repaired"] = repaired;
  json["architecture"] = architecture.to_json();
  json["areas"] = {{"origin", areas.origin.source},         {"insertion", areas.insertion.source},
                   {"automatic", areas.automatic},          {"landmark_strip", strips},
                   {"origin_area", areas.origin.to_json()}, {"insertion_area", areas.insertion.to_json()}};
  if (!strip_report.is_null()) json["areas"]["strip"] = strip_report;
  if (!args.report.empty()) write_json_report(args.report, json);
  if (!args.architecture.empty()) write_architecture(args.architecture, architecture);
  if (args.json) {
    const std::string text = json.dump(2);
    std::printf("%s\n", text.c_str());
  } else if (args.summary) {
    std::printf("%s\n", report.summary().c_str());
  } else {
    std::printf("%s", report.to_table().c_str());
    std::printf(
        "architecture: fibre length %.4g mm (sd %.3g), muscle length %.4g mm, pennation %.3g deg (sd %.3g), "
        "PCSA %.4g cm^2, maximum isometric force %.4g N\n",
        architecture.fibre_length_m.mean * 1e3, architecture.fibre_length_m.sd * 1e3,
        architecture.muscle_length_m * 1e3, architecture.pennation_deg.mean, architecture.pennation_deg.sd,
        architecture.pcsa_m2 * 1e4, architecture.max_isometric_force_n);
  }
  std::fflush(stdout);
  if (args.strict && !report.pass) {
    std::string failed;
    for (const auto& f : report.failed) failed += (failed.empty() ? "" : ", ") + f;
    throw Error(ErrorCode::quality, args.fibres + ": fibres fail the quality check (" + failed + ")");
  }
}

}  // namespace

void add_check_command(CLI::App& app) {
  auto args = std::make_shared<CheckArgs>();
  CLI::App* cmd = app.add_subcommand("check",
                                     "Check fibres against their muscle: inside, crossing, coverage, attachment, "
                                     "segments, smoothness, spread of the ends");
  cmd->add_option("fibres", args->fibres, "Fibres (vtk, vtp, obj, csv), each from origin to insertion")->required();
  cmd->add_option("muscle", args->muscle,
                  "Muscle surface (off, obj, stl, ply, vtk, txt); repaired when not closed genus 0")
      ->required();
  cmd->add_option("--origin", args->origin, "Origin landmark points (x y z rows, CSV naming x, y, z columns, or 3D Slicer .fcsv / .mrk.json); default: automatic end");
  cmd->add_option("--insertion", args->insertion, "Insertion landmark points; default: automatic end");
  cmd->add_flag("--json", args->json, "Print the JSON report to stdout instead of the table");
  cmd->add_option("--report", args->report, "Write the JSON report to this file");
  cmd->add_option("--architecture", args->architecture,
                  "Write the fibres' architecture (lengths, pennation, PCSA, force) to this file (.json or .csv)");
  add_architecture_options(cmd, args->architecture_options);
  cmd->add_flag("--strict", args->strict, "Exit with code 19 when a criterion fails");
  cmd->add_flag("--summary", args->summary,
                "Print the one-line verdict (each criterion, its value and threshold) instead of the table");
  cmd->add_option("--samples", args->options.coverage_samples, "Volume samples for the coverage figures")
      ->capture_default_str();
  cmd->add_option("--seed", args->options.seed, "Seed of the volume samples")->capture_default_str();
  cmd->add_option("--max-crossing-segments", args->options.max_crossing_segments,
                  "Fibre segments that may leave the muscle between their points by more than --segment-tolerance "
                  "(-1: report them without judging)")
      ->capture_default_str();
  cmd->add_option("--segment-tolerance", args->options.segment_tolerance,
                  "A segment leaves the muscle when it goes out by more than this fraction of the diagonal")
      ->capture_default_str();
  cmd->add_option("--max-turning-angle", args->options.max_turning_angle_deg,
                  "Largest turning angle between consecutive segments, degrees")
      ->capture_default_str();
  cmd->add_option("--min-end-coverage", args->options.min_end_coverage,
                  "Smallest share of each attachment area within one ideal end spacing of a fibre end")
      ->capture_default_str();
  cmd->add_option("--end-tolerance", args->options.end_tolerance,
                  "Fibre ends may lie this far outside the surface (fraction of the diagonal)")
      ->capture_default_str();
  cmd->add_option("--max-landmark-distance", args->attachments.max_landmark_distance,
                  "Landmarks farther from the surface than this fraction of the diagonal are an error")
      ->capture_default_str();
  cmd->add_option("--landmark-strip", args->strip.join,
                  "Landmark areas: measure fibre ends against each area's points joined into a strip along their "
                  "spanning tree, as decompose does (true), or against the points themselves (false)")
      ->capture_default_str();
  cmd->add_option("--strip-max-gap", args->strip.max_gap,
                  "Longest join of landmark points into a strip, as a fraction of the muscle length")
      ->capture_default_str();
  add_automatic_area_options(cmd, args->attachments);
  cmd->callback([args] { run_check(*args); });
}

}  // namespace fascicle::app
