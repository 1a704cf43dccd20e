// fascicle decompose MUSCLE -o FIBRES [options]: the whole job (fibres/decompose.h): repair,
// sphere map, alignment of the attachment areas, location of the template's surface, settle of
// the interior, fibres out (vtk, vtp, obj, csv), checked.

#include "app/commands.h"
#include "app/report_file.h"
#include "fibres/decompose_mesh.h"
#include "fibres/decompose_options_json.h"
#include "fibres/muscle_presets.h"
#include "fibres/fibre_field.h"
#include "repair/tetrahedralize.h"
#include "geometry/mesh_stats.h"
#include "geometry/atomic_file.h"
#include "geometry/errors.h"
#include "geometry/mesh_io.h"
#include "geometry/read_points.h"

#include <nlohmann/json.hpp>
#include <spdlog/spdlog.h>

#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <fstream>
#include <memory>
#include <string>
#include <vector>

namespace fascicle::app {

namespace {

struct DecomposeArgs {
  std::string input, output, report, origin, insertion, repaired_output, architecture, fe_mesh;
  long fe_cells = 20000;
  std::string rest = "tension", quality = "standard";
  const CLI::App* command = nullptr;  // for which options were given explicitly
  std::string kind = "parallel", solver = "static", backend = "cpu", sphere_method = "tutte";
  std::string muscle;  // --muscle: a preset by anatomical name (fibres/muscle_presets.h)
  std::string tuning;  // --tuning: a JSON file of settings (fibres/decompose_options_json.h)
  int model = 6;
  bool keep_failed = false, check_options = false;
  DecomposeOptions options;
};

// The options of the command line (defaults where none is given), not yet validated.
DecomposeOptions options_of(const DecomposeArgs& args) {
  DecomposeOptions options = args.options;
  // --quality sets the options its level names, except those given explicitly.
  {
    const DecomposeOptions level = with_quality(options, parse_quality(args.quality));
    const auto given = [&](const char* name) { return args.command != nullptr && args.command->count(name) > 0; };
    if (!given("--fibres")) options.fibres = level.fibres;
    if (!given("--resolution")) options.resolution = level.resolution;
    if (!given("--tolerance")) options.settle.tolerance = level.settle.tolerance;
    options.check.coverage_samples = level.check.coverage_samples;
  }
  options.kind = springs::parse_template_kind(args.kind);
  // --muscle sets the template and pennation of its preset, except those given explicitly.
  if (!args.muscle.empty()) {
    const MusclePreset& preset = muscle_preset(args.muscle);
    const auto given = [&](const char* name) { return args.command != nullptr && args.command->count(name) > 0; };
    if (!given("--template")) options.kind = preset.kind;
    if (!given("--pennation")) options.pennate.pennation_deg = preset.pennation_deg;
  }
  options.model = springs::parse_spring_model(args.model);
  options.settle.solver = springs::parse_solver_kind(args.solver);
  options.sphere.method = sphere_method_from_string(args.sphere_method);
  options.backend = args.backend;
  options.rest = parse_rest_shape(args.rest);
  return options;
}

// A --tuning file: a JSON object of settings (fibres/decompose_options_json.h).
nlohmann::json read_tuning(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw InputError(ErrorCode::file_missing, path + ": cannot open the tuning file");
  try {
    return nlohmann::json::parse(in);
  } catch (const nlohmann::json::parse_error& e) {
    throw InputError(ErrorCode::malformed, path + ": the tuning file is not JSON (" + e.what() + ")");
  }
}

void run_decompose(const DecomposeArgs& args) {
  DecomposeOptions options = options_of(args);
  // The file's settings, except those the command line changes (a setting given there wins).
  if (!args.tuning.empty()) options = tune_options(options_of(DecomposeArgs{}), options, read_tuning(args.tuning));
  options.validate();
  if (args.origin.empty() != args.insertion.empty())
    throw OptionError("--origin and --insertion go together (give both, or neither for automatic areas)");
  // Every output is checked before the work: its folder and its format.
  check_not_same_file(args.input, args.output);
  check_output_path(args.output);
  if (!is_polyline_extension(lower_extension(args.output)))
    throw InputError(ErrorCode::unknown_format, args.output + ": cannot write fibres as '" +
                                                    lower_extension(args.output) +
                                                    "' (use .vtk, .vtp, .vtu, .obj or .csv)");
  if (!args.report.empty()) {
    check_not_same_file(args.input, args.report);
    check_output_path(args.report);
  }
  if (!args.fe_mesh.empty()) {
    check_not_same_file(args.input, args.fe_mesh);
    check_output_path(args.fe_mesh);
    if (lower_extension(args.fe_mesh) != "vtu")
      throw InputError(ErrorCode::unknown_format, args.fe_mesh + ": the finite-element mesh is written as .vtu");
    if (args.fe_cells < 100 || args.fe_cells > 10'000'000)
      throw OptionError("--fe-cells: must be in 100..10000000, got " + std::to_string(args.fe_cells));
  }
  if (!args.architecture.empty()) {
    check_not_same_file(args.input, args.architecture);
    check_output_path(args.architecture);
    const std::string ext = lower_extension(args.architecture);
    if (ext != "json" && ext != "csv")
      throw InputError(ErrorCode::unknown_format,
                       args.architecture + ": cannot write the architecture as '" + ext + "' (use .json or .csv)");
  }
  if (!args.repaired_output.empty()) {
    check_not_same_file(args.input, args.repaired_output);
    check_output_path(args.repaired_output);
    const std::string ext = lower_extension(args.repaired_output);
    if (ext != "off" && ext != "obj" && ext != "stl" && ext != "ply" && ext != "vtk")
      throw InputError(ErrorCode::unknown_format, args.repaired_output + ": cannot write a mesh as '" + ext +
                                                      "' (use .off, .obj, .stl, .ply or .vtk)");
  }

  if (args.check_options) return;  // --check-options: options and outputs checked, no work

  const PolygonSoup soup = read_polygon_soup(args.input);
  spdlog::info("read {}: {} points, {} faces", args.input, soup.points.size(), soup.polygons.size());
  Landmarks landmarks;
  if (!args.origin.empty()) {
    landmarks.origin = read_points(args.origin);
    landmarks.insertion = read_points(args.insertion);
    landmarks.origin_source = args.origin;
    landmarks.insertion_source = args.insertion;
  }
  nlohmann::json report = {
      {"input_file", args.input}, {"output_file", args.output}, {"options", decompose_options_json(options)}};
  if (!args.muscle.empty()) {
    const MusclePreset& preset = muscle_preset(args.muscle);
    report["muscle"] = {{"name", preset.name},
                        {"template", springs::template_name(options.kind)},
                        {"pennation_deg", options.pennate.pennation_deg},
                        {"arrangement", preset.arrangement}};
  }
  // On a terminal, each stage as it starts on one line of stderr (-q: errors only, so none).
  const bool terminal = isatty(2) != 0 && spdlog::get_level() <= spdlog::level::info;
  const auto started = std::chrono::steady_clock::now();
  if (terminal)
    options.progress = [started](const std::string& stage) {
      const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
      std::fprintf(stderr, "\r\033[Kdecompose: %6.1f s  %s", seconds, stage.c_str());
      std::fflush(stderr);
    };
  struct EndLine {
    bool on;
    ~EndLine() {
      if (on) std::fprintf(stderr, "\r\033[K");
    }
  } end_line{terminal};
  try {
    const Decomposition result = decompose(soup, landmarks, options);
    if (end_line.on) std::fprintf(stderr, "\r\033[K");
    end_line.on = false;
    report.update(result.report.to_json());
    const CheckReport& q = result.report.quality;
    const DecomposeReport& r = result.report;
    // The outputs of the run appear together, after the work: a failure on the way leaves none.
    StagedOutputs outputs;
    const bool write_fibres = q.pass || args.keep_failed;
    if (write_fibres) {
      outputs.stage(args.output, [&](const std::string& path) { write_polylines(path, result.fibres); });
      if (!args.repaired_output.empty())
        outputs.stage(args.repaired_output, [&](const std::string& path) { write_triangle_mesh(path, result.muscle); });
    }
    if (write_fibres && !args.fe_mesh.empty()) {
      // The muscle's volume as tetrahedra, each with the direction of its nearest fibre.
      TetrahedralizeReport made;
      const TetMesh tets =
          tetrahedralize(result.muscle, sized_tetrahedra(signed_volume(result.muscle), args.fe_cells), &made);
      const std::vector<Vec3> directions = cell_fibre_directions(tets, result.fibres);
      report["fe_mesh"] = made.to_json();
      outputs.stage(args.fe_mesh,
                    [&](const std::string& path) { write_tetrahedra(path, tets, "fibre_direction", directions); });
    }
    if (write_fibres && !args.architecture.empty())
      outputs.stage(args.architecture, [&](const std::string& path) { write_architecture(path, r.architecture); });
    if (!args.report.empty())
      outputs.stage(args.report, [&](const std::string& path) { write_json_report(path, report); });
    outputs.commit();
    const std::string kept =
        r.attempts.size() > 1
            ? "; try " + std::to_string(r.kept_attempt + 1) + " of " + std::to_string(r.attempts.size()) + " kept (" +
                  r.attempts[static_cast<std::size_t>(r.kept_attempt)].value("change", "none") + ")"
            : "";
    if (!q.pass) {
      std::string failed;
      for (const std::string& f : q.failed) failed += (failed.empty() ? "" : ", ") + f;
      spdlog::info("{}{}", q.summary(), kept);
      throw Error(ErrorCode::quality,
                  "decompose: the fibres fail the check (" + failed + ")" +
                      std::string(args.keep_failed ? "; fibres written (--keep-failed)" : "; no output written") +
                      (args.report.empty() ? "" : ", details in " + args.report));
    }
    spdlog::info("wrote {}: {} fibres x {} points in {:.3f} s; {}{}", args.output, result.fibres.lines.size(),
                 options.resolution, r.seconds, q.summary(), kept);
  } catch (const Error& e) {
    write_failure_report(args.report, report, e);
    throw;
  }
}

}  // namespace

void add_decompose_command(CLI::App& app) {
  auto args = std::make_shared<DecomposeArgs>();
  DecomposeOptions& o = args->options;
  CLI::App* cmd =
      app.add_subcommand("decompose", "Muscle surface in, muscle fibres out (repaired, mapped, settled, checked)");
  cmd->add_option("input", args->input, "Muscle surface (off, obj, stl, ply, vtk, txt); repaired first")->required();
  cmd->add_option("-o,--output", args->output, "Fibres: .vtk, .vtp, .vtu, .obj (polylines) or .csv")->required();
  cmd->add_option("--report", args->report, "Write a JSON report (every stage, quality)");
  cmd->add_option("--write-repaired", args->repaired_output,
                  "Also write the repaired muscle (off, obj, stl, ply, vtk)");
  cmd->add_option("--architecture", args->architecture,
                  "Also write the fibres' architecture (lengths, pennation, PCSA, force) (.json or .csv)");
  add_architecture_options(cmd, o.architecture);
  cmd->add_option("--fe-mesh", args->fe_mesh,
                  "Also write a tetrahedral mesh of the muscle (CGAL 3D mesh generation) with a unit fibre direction "
                  "per cell, for finite-element models (.vtu)");
  cmd->add_option("--fe-cells", args->fe_cells, "About this many tetrahedra in --fe-mesh")->capture_default_str();
  cmd->add_option("--origin", args->origin, "Origin landmark points (x y z rows, CSV naming x, y, z columns, or 3D Slicer .fcsv / .mrk.json); default: automatic end");
  cmd->add_option("--insertion", args->insertion, "Insertion landmark points; default: automatic end");
  cmd->add_option("--template", args->kind,
                  "Fibre template: parallel, pennate, curved, fanned, rectus, unipennate, bipennate")
      ->capture_default_str();
  cmd->add_option("--muscle", args->muscle,
                  "Anatomical name (snake_case, as vastus_lateralis): its template and pennation (Ward et al. 2009) "
                  "unless --template or --pennation are given");
  cmd->add_option("--pennation", o.pennate.pennation_deg,
                  "unipennate and bipennate: mean angle of the fibres to the line of action, degrees")
      ->capture_default_str();
  cmd->add_option("--fibres", o.fibres, "Number of fibres (split near-square)")->capture_default_str();
  cmd->add_option("--resolution", o.resolution, "Points per fibre")->capture_default_str();
  cmd->add_option("--model", args->model, "Springs: 6 (face neighbours) or 26 (all neighbours)")->capture_default_str();
  cmd->add_option("--solver", args->solver, "Settle: static (equilibrium) or verlet (the thesis's dynamics)")
      ->capture_default_str();
  cmd->add_option("--tolerance", o.settle.tolerance, "Stop the settle at this relative residual")
      ->capture_default_str();
  cmd->add_option("--max-iterations", o.settle.max_iterations, "Iteration cap of the settle")->capture_default_str();
  cmd->add_option("--portable-loop", o.settle.portable_loop,
                  "Settle with the portable spring loop, the same settle on every processor (true), or the fastest "
                  "loop the processor has (false)")
      ->capture_default_str();
  cmd->add_option("--backend", args->backend,
                  "Settle on cpu, gl (OpenGL compute shaders, float32, finished on the CPU in double "
                  "where it stops short of the tolerance) or auto (the CPU)")
      ->capture_default_str();
  cmd->add_option("--contain-segments", o.contain_segments,
                  "Move fibre segments that leave the muscle between their points back inside (true) or leave them "
                  "(false)")
      ->capture_default_str();
  cmd->add_option("--sphere-method", args->sphere_method, "Sphere map: tutte (default) or relax (the thesis's)")
      ->capture_default_str();
  cmd->add_option("--max-landmark-distance", o.attachments.max_landmark_distance,
                  "Landmarks farther from the surface than this fraction of the diagonal are an error")
      ->capture_default_str();
  add_automatic_area_options(cmd, o.attachments);
  cmd->add_option("--placement-end-share", o.placement_end_share,
                  "Automatic areas: the fibre ends are placed on this share of each --end-fraction area (the check "
                  "keeps the whole areas)")
      ->capture_default_str();
  cmd->add_option("--region-radius", o.placement.region_radius,
                  "Attachment region: vertices within this fraction of the muscle length of an area point")
      ->capture_default_str();
  cmd->add_option("--landmark-strip", o.strip.join,
                  "Join each landmark area's points along their spanning tree into a gapless strip (true) or keep "
                  "disks round the points (false)")
      ->capture_default_str();
  cmd->add_option("--strip-max-gap", o.strip.max_gap,
                  "Longest join of landmark points into a strip, as a fraction of the muscle length")
      ->capture_default_str();
  cmd->add_option("--rest", args->rest,
                  "Spring rest lengths: tension (template, stretched, all springs start in tension), template "
                  "(stretched), zero (harmonic map)")
      ->capture_default_str();
  cmd->add_option("--harmonic-direct-points", o.harmonic_direct_points,
                  "The first (harmonic) settle is one sparse Cholesky solve on lattices of at most this many points, "
                  "a multigrid solve on larger ones (0: always multigrid)")
      ->capture_default_str();
  cmd->add_option("--map-faces", o.map_faces,
                  "Largest surface, in triangles, the sphere map and the placement work on; a finer muscle is "
                  "simplified for them, the fibres still fill and are checked on the muscle itself")
      ->capture_default_str();
  cmd->add_option("--max-face-depth", o.placement.max_face_depth,
                  "Largest depth of an attachment face, as a share of the distance to the first ring of fibre points")
      ->capture_default_str();
  cmd->add_option("--landmark-centre-keep", o.placement.landmark_centre_keep,
                  "Landmark areas: the face centre is the region point farthest from the other area among those at "
                  "least this share of the deepest point's distance from the region's border (1: the deepest)")
      ->capture_default_str();
  cmd->add_option_function<double>(
      "--corner-twist",
      [&o](double degrees) { o.placement.corner_twist_deg = o.placement.edge_corner_twist_deg = degrees; },
      "Degrees from the muscle's broad axis to the lattice's r axis, in [-180, 180] (default 0 with automatic areas "
      "on a round muscle, sides on the thin edges; 45 on a flat one, whose cross-sections are at least twice as broad "
      "as thick, with landmark areas or unipennate and bipennate, corners there)");
  cmd->add_option("--even-perimeter", o.placement.even_perimeter,
                  "Lattice surface points at even shares of each cross-section's perimeter (true) or at the "
                  "sphere map's azimuths (false)")
      ->capture_default_str();
  cmd->add_option("--cast-rounds", o.cast_rounds,
                  "Rounds of fibre ends cast onto the surface under the layer next to them, each followed by a settle")
      ->capture_default_str();
  cmd->add_option("--cast-rim", o.cast_rim,
                  "Cast the rim of each attachment face with its fibre ends (true) or leave it where the placement "
                  "put it (false)")
      ->capture_default_str();
  cmd->add_option("--cast-by-azimuth", o.cast_by_azimuth,
                  "Shrink the fibre ends' cast by one factor per azimuth round the cast axis (true) or by one "
                  "factor for the whole face (false)")
      ->capture_default_str();
  cmd->add_option("--align-ends", o.align_ends,
                  "Continue each fibre's end along its last segment onto its attachment area where that folds no "
                  "cell (true) or keep the cast ends (false)")
      ->capture_default_str();
  cmd->add_option("--smooth-steps", o.smoothing.steps,
                  "Steps smoothing each fibre's joints that turn by more than 30 degrees, under the check's guards "
                  "(0: none)")
      ->capture_default_str();
  cmd->add_option("--smooth-above", o.smoothing.max_turning_deg,
                  "Only joints turning by more than this many degrees are smoothed")
      ->capture_default_str();
  cmd->add_option("--band-by-length", o.placement.band_by_length,
                  "Lattice rings at even steps of length (true) or of surface area (false) along the muscle")
      ->capture_default_str();
  cmd->add_option("--bend-step", o.placement.bend_step_deg,
                  "With --band-by-length: largest turn (degrees) of the muscle's centre line between two rings of "
                  "fibre points; the inner rings close up where it turns faster (0: rings by length alone)")
      ->capture_default_str();
  cmd->add_option("--meridian-rings", o.placement.meridian_rings,
                  "With --band-by-length: each ring point at the same share of its own meridian's length (true) or "
                  "each ring along one level of the sphere map (false)")
      ->capture_default_str();
  cmd->add_option("--second-try", o.tries.second_try,
                  "Decompose once more where the first result shows folds or uneven layers (with --meridian-rings "
                  "true) or a coverage gap (with --edge-cell 0.5), and keep the better result (false: one try)")
      ->capture_default_str();
  cmd->add_option("--even-layers-ratio", o.tries.even_layers_ratio,
                  "A longest layer of fibre segments over this many times the median layer calls the second try "
                  "(uneven layers; 0: never)")
      ->capture_default_str();
  cmd->add_option("--edge-cell", o.edge_cell,
                  "Width of the lattice cells between the surface ring and the outermost fibres, in fibre spacings "
                  "(0.5: the outermost fibres half a spacing from the surface; 1: the ring spaced like the fibres)")
      ->capture_default_str();
  cmd->add_option("--contact-rounds", o.contact_rounds,
                  "Containment rounds: points the settle leaves outside are fixed just inside and the settle rerun")
      ->capture_default_str();
  cmd->add_option("--contact-segments", o.contact_segments,
                  "Untangling: a last attempt whose containment rounds also pin the fibre segments that leave the "
                  "muscle between their points back inside, kept when it folds no more cells")
      ->capture_default_str();
  cmd->add_option("--untangle", o.untangle_cells,
                  "Unfold the cells the settle leaves inverted (barrier untangling, fibres/untangle.h)")
      ->capture_default_str();
  cmd->add_option("--untangle-iterations", o.untangle.iterations,
                  "Untangling: L-BFGS iterations each attempt may spend, all its rounds together")
      ->capture_default_str();
  cmd->add_option("--untangle-contact-rounds", o.untangle.contact_rounds,
                  "Untangling: rounds in which the points left outside get soft pins just inside and the untangling "
                  "runs again (the points still outside after them are fixed just inside)")
      ->capture_default_str();
  cmd->add_option("--untangle-across-spacing", o.untangle.across_spacing,
                  "Untangling: measure depths under the surface in the lattice spacing across the fibres (true) or "
                  "in the mean length of all springs at a point, along the fibres too (false); pin weights use the "
                  "latter either way")
      ->capture_default_str();
  cmd->add_option("--untangle-keep-best", o.untangle.solver.keep_best,
                  "Untangling: each run returns the best state it met when it ends worse")
      ->capture_default_str();
  cmd->add_option("--end-anchor-weight", o.untangle.end_anchor_weight,
                  "Untangling: weight of the soft pins holding the fibre ends at their cast places")
      ->capture_default_str();
  cmd->add_option("--untangle-free-ring", o.untangle.free_ring,
                  "Untangling: free the surface ring with the fibre ends (held just under the surface, sliding along "
                  "it) so that the rings next to a hooked end can turn")
      ->capture_default_str();
  cmd->add_option("--untangle-containment-energy", o.untangle.containment_energy,
                  "Untangling: in the attempts with the surface ring free, a penalty on each free point's signed "
                  "distance outside the muscle is part of the energy (raised while a point is outside)")
      ->capture_default_str();
  cmd->add_option("--untangle-containment-everywhere", o.untangle.containment_energy_everywhere,
                  "Untangling: the containment energy in every attempt, not only those with the ring free")
      ->capture_default_str();
  cmd->add_option("--untangle-containment-margin", o.untangle.containment_margin,
                  "Untangling: depth (local spacings) the containment energy pushes a point to")
      ->capture_default_str();
  cmd->add_option("--untangle-containment-band", o.untangle.containment_band,
                  "Untangling: points farther inside than this many local spacings are left out of the containment "
                  "energy")
      ->capture_default_str();
  cmd->add_option("--end-area-margin", o.untangle.end_area_margin,
                  "Untangling: farthest a freed fibre end may lie from its attachment area, as a share of the muscle "
                  "length (0: within the end shift of its cast place)")
      ->capture_default_str();
  cmd->add_option("--tuning", args->tuning,
                  "JSON file of settings, nested as the report's \"options\" (any of them, for experts; a report's "
                  "options repeat its run); options given on the command line win");
  cmd->add_flag("--check-options", args->check_options,
                "Check the options and the output paths, then exit without reading the input (0: all good)");
  cmd->add_flag("--keep-failed", args->keep_failed,
                "Write the fibres even when they fail the check, for inspection (the exit code is still 19)");
  cmd->add_option("--quality", args->quality,
                  "Speed against accuracy: draft (36 fibres x 9 points, tolerance 1e-4), standard (100 x 15, 1e-6) or "
                  "fine (144 x 19, 1e-7); --fibres, --resolution and --tolerance given explicitly win")
      ->check(CLI::IsMember({"draft", "standard", "fine"}))
      ->capture_default_str();
  args->command = cmd;
  group_options(
      cmd,
      {{"Inputs and outputs",
        {"input", "--output", "--report", "--write-repaired", "--architecture", "--fe-mesh", "--keep-failed",
         "--check-options", "--tuning"}},
       {"Attachment areas", {"--origin", "--insertion", "--end-fraction", "--max-landmark-distance"}},
       {"Template and fibres",
        {"--muscle", "--template", "--pennation", "--fibres", "--resolution", "--length-unit", "--specific-tension"}},
       {"Quality and speed", {"--quality", "--backend", "--tolerance"}}},
      "Advanced (the method's knobs; defaults are measured on the corpus, docs/decompose.md)");
  cmd->footer(show_all_options() ? "" : "Advanced options: fascicle decompose --help-all");
  cmd->callback([args] { run_decompose(*args); });
}

}  // namespace fascicle::app
