// fascicle sphere IN -o OUT [--report R.json] [--sphere-method tutte|relax]
//                 [--sphere-start automatic|tube|progressive|stereographic]
//                 [--origin O.xyz --insertion I.xyz]: repairs the mesh, maps it onto the unit
// sphere (same connectivity) and reports the map's quality; with landmark files (or
// automatically) also the attachment areas' centres on the sphere, and how well the sphere map
// of the `parallel` template's lattice surface aligns to them (pipeline step 4).

#include "app/commands.h"
#include "app/report_file.h"
#include "geometry/atomic_file.h"
#include "geometry/errors.h"
#include "geometry/mesh_io.h"
#include "geometry/read_points.h"
#include "morph/align_on_sphere.h"
#include "morph/attachments.h"
#include "morph/sphere_locator.h"
#include "morph/sphere_map.h"
#include "repair/repair.h"
#if FASCICLE_HAVE_SPRINGS
#include "springs/lattice.h"
#endif

#include <nlohmann/json.hpp>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>
#include <memory>

namespace fascicle::app {

namespace {

struct SphereArgs {
  std::string input, output, report, method = "tutte", start = "automatic", origin, insertion;
  SphereMapOptions options;
  AttachmentOptions attachments;
};

nlohmann::json area_json(const AttachmentArea& area, const SphereMap& map, const TriangleMesh& mesh) {
  const Vec3 c = sphere_centre(area, map.positions, mesh.triangles);
  const Vec3 s = area.centroid();
  nlohmann::json j = area.to_json();
  j["max_landmark_distance"] = area.max_distance;  // this report's older name for max_distance, kept for readers
  j["surface_centroid"] = {s.x(), s.y(), s.z()};
  j["sphere_centre"] = {c.x(), c.y(), c.z()};
  return j;
}

#if FASCICLE_HAVE_SPRINGS
/// Normalised mean of the sphere images of `vertices`.
Vec3 mean_direction(const std::vector<Vec3>& sphere, const std::vector<int>& vertices) {
  Vec3 c = Vec3::Zero();
  for (int v : vertices) c += sphere[v];
  return c.normalized();
}

/// Aligns the sphere map of the default (`parallel`, 100 fibres x 20) template lattice's surface
/// to the muscle's attachment centres on its sphere map: the template's origin / insertion
/// centres are the mean sphere directions of its t = 0 / t = 1 surface points. Returns the
/// "alignment" object of the report.
nlohmann::json align_template(const Vec3& target_origin, const Vec3& target_insertion,
                              const SphereMapOptions& options) {
  const springs::Lattice lattice = springs::build_lattice(springs::LatticeOptions{});
  // The surface uses only the boundary points of the lattice: renumber them compactly.
  std::vector<int> compact(lattice.system.positions.size(), -1);
  TriangleMesh surface;
  for (const Triangle& t : lattice.surface) {
    Triangle c{};
    for (int k = 0; k < 3; ++k) {
      int& id = compact[t[k]];
      if (id < 0) {
        id = static_cast<int>(surface.positions.size());
        surface.positions.push_back(lattice.system.positions[t[k]]);
      }
      c[k] = id;
    }
    surface.triangles.push_back(c);
  }
  auto area_vertices = [&](const std::vector<int>& points) {
    std::vector<int> out;
    for (int p : points)
      if (compact[p] >= 0) out.push_back(compact[p]);
    return out;
  };
  SphereMapOptions template_options = options;
  template_options.method = SphereMethod::tutte;
  // The lattice is a box whose attachment faces are its two ends: the tube start (cut end to end)
  // puts them on the poles, whatever --sphere-start says for the muscle; the progressive start's
  // map of the box is not symmetric and would misalign the insertion by degrees.
  template_options.start = SphereStart::automatic;
  template_options.tube_elongation = 0.0;
  SphereMap map = map_to_sphere(surface, template_options);
  if (!map.report.quality.bijective())
    throw SolverError("sphere map of the template lattice surface failed: " + map.report.failure);
  const std::vector<int> origin = area_vertices(lattice.origin), insertion = area_vertices(lattice.insertion);
  const SphereLocator locator(map.positions, surface.triangles);
  const SurfacePoint o = locator.locate(mean_direction(map.positions, origin));
  const SurfacePoint i = locator.locate(mean_direction(map.positions, insertion));
  const AlignReport aligned = align_on_sphere(surface.triangles, map.positions, o, i, target_origin, target_insertion);
  const SphereQuality after = measure_sphere_map(surface, map.positions);
  nlohmann::json j = aligned.to_json();
  j["template"] = {{"kind", "parallel"},
                   {"surface_vertices", surface.positions.size()},
                   {"surface_triangles", surface.triangles.size()},
                   {"sphere_map", map.report.to_json()}};
  j["flipped_after"] = after.flipped;
  j["degenerate_after"] = after.degenerate;
  j["bijective_after"] = after.bijective();
  return j;
}
#endif

void run_sphere(const SphereArgs& args) {
  SphereMapOptions options = args.options;
  options.method = sphere_method_from_string(args.method);
  options.start = sphere_start_from_string(args.start);
  options.validate();
  args.attachments.validate();
  if ((args.origin.empty()) != (args.insertion.empty()))
    throw OptionError("--origin and --insertion go together (give both, or neither for automatic areas)");
  check_not_same_file(args.input, args.output);
  if (!args.report.empty()) check_not_same_file(args.input, args.report);
  const PolygonSoup soup = read_polygon_soup(args.input);
  spdlog::info("read {}: {} points, {} faces", args.input, soup.points.size(), soup.polygons.size());
  nlohmann::json report = {{"input_file", args.input}, {"output_file", args.output}};
  try {
    const RepairResult repaired = repair_mesh(soup, RepairOptions{});
    report["repair"] = repaired.report.to_json();
    const TriangleMesh& mesh = repaired.mesh;
    // Landmarks are checked before the map: a wrong file is the user's first thing to fix.
    Attachments areas;
    if (!args.origin.empty())
      areas = landmark_attachments(mesh, read_points(args.origin), args.origin, read_points(args.insertion),
                                   args.insertion, args.attachments);
    else
      areas = automatic_attachments(mesh, args.attachments);
    const SphereMap map = map_to_sphere(mesh, options);
    report["sphere"] = map.report.to_json();
    report["origin"] = area_json(areas.origin, map, mesh);
    report["insertion"] = area_json(areas.insertion, map, mesh);
    report["attachments"] = areas.automatic ? "automatic" : "landmarks";
    if (map.report.status != "ok") {
      report["status"] = map.report.status;
      if (!args.report.empty()) write_json_report(args.report, report);
      throw SolverError("sphere map (" + map.report.method + ") failed: " + map.report.failure + "; no output written" +
                        (args.report.empty() ? "" : ", details in " + args.report));
    }
#if FASCICLE_HAVE_SPRINGS
    const Vec3 target_o = sphere_centre(areas.origin, map.positions, mesh.triangles);
    const Vec3 target_i = sphere_centre(areas.insertion, map.positions, mesh.triangles);
    report["alignment"] = align_template(target_o, target_i, options);
    spdlog::info("template aligned: origin error {:.3g} deg, insertion error {:.3g} deg, {} flipped",
                 report["alignment"]["origin_error_deg"].get<double>(),
                 report["alignment"]["insertion_error_deg"].get<double>(),
                 report["alignment"]["flipped_after"].get<long>());
#endif
    report["status"] = map.report.status;
    write_triangle_mesh(args.output, TriangleMesh{map.positions, mesh.triangles});
    if (!args.report.empty()) write_json_report(args.report, report);
    const SphereQuality& q = map.report.quality;
    spdlog::info(
        "wrote {}: {} vertices on the sphere ({} start), {} flipped, {} degenerate, area ratio {:.3g}..{:.3g}, "
        "mean |log| {:.3f} ({:.3f} s)",
        args.output, map.positions.size(), map.report.initial_map.empty() ? map.report.method : map.report.initial_map,
        q.flipped, q.degenerate, q.area_ratio_min, q.area_ratio_max, q.area_log_mean, map.report.seconds);
  } catch (const Error& e) {
    write_failure_report(args.report, report, e);
    throw;
  }
}

}  // namespace

void add_sphere_command(CLI::App& app) {
  auto args = std::make_shared<SphereArgs>();
  CLI::App* cmd = app.add_subcommand("sphere", "Repair a muscle and map it onto the unit sphere (bijective)");
  cmd->add_option("input", args->input, "Input mesh (off, obj, stl, ply, vtk, txt)")->required();
  cmd->add_option("-o,--output", args->output, "Sphere mesh, same connectivity (off, obj, stl, ply, vtk)")->required();
  cmd->add_option("--report", args->report, "Write a JSON report (repair, map quality, attachment centres)");
  cmd->add_option("--sphere-method", args->method,
                  "tutte: Tutte embedding, checked bijective (default); relax: the thesis's method")
      ->capture_default_str();
  cmd->add_option("--sphere-start", args->start,
                  "tutte: automatic (long shapes: tube start, progressive-mesh start when it is not bijective; "
                  "round ones: progressive; default), or one start only: tube, progressive, stereographic")
      ->capture_default_str();
  cmd->add_option("--origin", args->origin, "Origin landmark points (x y z rows, CSV naming x, y, z columns, or 3D Slicer .fcsv / .mrk.json); default: automatic end");
  cmd->add_option("--insertion", args->insertion, "Insertion landmark points; default: automatic end");
  cmd->add_option("--max-landmark-distance", args->attachments.max_landmark_distance,
                  "Landmarks farther from the surface than this fraction of the diagonal are an error")
      ->capture_default_str();
  add_automatic_area_options(cmd, args->attachments);
  cmd->add_option("--balance-sweeps", args->options.balance_sweeps, "Area-balancing sweeps (tutte)")
      ->capture_default_str();
  cmd->add_option("--reweight-rounds", args->options.reweight_rounds, "Tutte reweighting rounds (tutte)")
      ->capture_default_str();
  cmd->add_option("--relax-iterations", args->options.relax_max_iterations, "Iteration cap per relaxation (relax)")
      ->capture_default_str();
  cmd->add_option("--seed", args->options.seed, "Seed of the random tetrahedron (relax)")->capture_default_str();
  cmd->callback([args] { run_sphere(*args); });
}

}  // namespace fascicle::app
