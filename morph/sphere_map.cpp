#include "morph/sphere_map.h"

#include "geometry/errors.h"
#include "geometry/detail/for_each_index.h"
#include "morph/mesh_adjacency.h"
#include "morph/sphere_steps.h"

#include <nlohmann/json.hpp>

#include <array>
#include <algorithm>
#include <chrono>
#include <cmath>

namespace fascicle {

const char* to_string(SphereMethod method) { return method == SphereMethod::relax ? "relax" : "tutte"; }

const char* to_string(SphereStart start) {
  switch (start) {
    case SphereStart::tube: return "tube";
    case SphereStart::progressive: return "progressive";
    case SphereStart::stereographic: return "stereographic";
    default: return "automatic";
  }
}

SphereStart sphere_start_from_string(const std::string& name) {
  for (SphereStart s :
       {SphereStart::automatic, SphereStart::tube, SphereStart::progressive, SphereStart::stereographic})
    if (name == to_string(s)) return s;
  throw OptionError("--sphere-start: '" + name +
                    "' is not a start (use automatic, tube, progressive or stereographic)");
}

SphereMethod sphere_method_from_string(const std::string& name) {
  if (name == "tutte") return SphereMethod::tutte;
  if (name == "relax") return SphereMethod::relax;
  throw OptionError("--sphere-method: '" + name + "' is not a method (use tutte or relax)");
}

void SphereMapOptions::validate() const {
  auto bad = [](const std::string& field, const std::string& value, const std::string& why) {
    throw OptionError("sphere map option " + field + " = " + value + ": " + why);
  };
  if (mobius_steps < 0) bad("mobius_steps", std::to_string(mobius_steps), "must be >= 0");
  if (!(mobius_tolerance > 0.0 && mobius_tolerance < 1.0))
    bad("mobius_tolerance", std::to_string(mobius_tolerance), "must be in (0, 1)");
  if (balance_sweeps < 0) bad("balance_sweeps", std::to_string(balance_sweeps), "must be >= 0");
  if (!(balance_tolerance >= 0.0 && balance_tolerance < 1.0))
    bad("balance_tolerance", std::to_string(balance_tolerance), "must be in [0, 1)");
  if (!(relax_threshold > 0.0 && relax_threshold < 1.0))
    bad("relax_threshold", std::to_string(relax_threshold), "must be in (0, 1)");
  if (relax_max_iterations < 1) bad("relax_max_iterations", std::to_string(relax_max_iterations), "must be >= 1");
  if (relax_restarts < 0) bad("relax_restarts", std::to_string(relax_restarts), "must be >= 0");
  if (!(tube_elongation >= 0.0)) bad("tube_elongation", std::to_string(tube_elongation), "must be >= 0");
  if (!(reweight_exponent > 0.0 && reweight_exponent <= 2.0))
    bad("reweight_exponent", std::to_string(reweight_exponent), "must be in (0, 2]");
  if (!(reweight_target >= 0.0)) bad("reweight_target", std::to_string(reweight_target), "must be >= 0");
  if (reweight_rounds < 0) bad("reweight_rounds", std::to_string(reweight_rounds), "must be >= 0");
  if (progressive_max_valence < 6)
    bad("progressive_max_valence", std::to_string(progressive_max_valence), "must be >= 6");
  if (progressive_relax_rounds < 0)
    bad("progressive_relax_rounds", std::to_string(progressive_relax_rounds), "must be >= 0");
  if (untangle_sweeps < 0) bad("untangle_sweeps", std::to_string(untangle_sweeps), "must be >= 0");
  if (relax_threshold_lowerings < 0)
    bad("relax_threshold_lowerings", std::to_string(relax_threshold_lowerings), "must be >= 0");
}

nlohmann::json SphereMapReport::to_json() const {
  nlohmann::json j{{"method", method},         {"status", status},
                   {"failure", failure},       {"quality", fascicle::to_json(quality)},
                   {"iterations", iterations}, {"seconds", seconds}};
  if (method == "tutte") {
    j["initial_map"] = initial_map;
    j["starts_tried"] = starts_tried;
    j["elongation"] = elongation;
    j["reweight_rounds"] = reweight_rounds;
    j["cut_face"] = cut_face;
    j["lift_margin"] = lift_margin;
    j["mobius_steps"] = mobius_steps;
    j["mobius_residual"] = mobius_residual;
    j["rejected_moves"] = rejected_moves;
    j["solve_seconds"] = solve_seconds;
  } else {
    j["restarts"] = restarts;
    j["threshold_lowerings"] = threshold_lowerings;
    j["center_moved_inside"] = center_moved_inside;
  }
  return j;
}

SphereMap map_to_sphere(const TriangleMesh& mesh, const SphereMapOptions& options) {
  options.validate();
  using Clock = std::chrono::steady_clock;
  const auto start = Clock::now();
  const auto since = [](Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); };
  const MeshAdjacency adjacency = check_sphere_topology(mesh);
  SphereMap map;
  SphereMapReport& report = map.report;
  report.method = to_string(options.method);
  if (options.method == SphereMethod::tutte) {
    const std::vector<double> shares = detail::area_shares(mesh);
    // Long shapes start from the tube map, round ones from the progressive-mesh embedding; if the
    // first is not a bijection after untangling, the others are tried and the best one kept.
    std::array<int, 2> ends{};
    const double elongation = detail::elongation(mesh, adjacency, ends);
    report.elongation = elongation;
    const bool tube_first = elongation > options.tube_elongation;
    detail::TubeEmbedder tube_embedder(mesh, adjacency, ends);
    detail::TutteLift best;
    long best_bad = -1;
    // Starts in order of preference; the first without a bad triangle wins, else the one with
    // the fewest.
    enum class Start { prism, lambert, progressive, stereographic };
    const std::vector<Start> starts = [&]() -> std::vector<Start> {
      switch (options.start) {
        case SphereStart::tube: return {Start::prism, Start::lambert};
        case SphereStart::progressive: return {Start::progressive};
        case SphereStart::stereographic: return {Start::stereographic};
        default: break;
      }
      if (tube_first) return {Start::prism, Start::lambert, Start::progressive, Start::stereographic};
      return {Start::progressive, Start::prism, Start::lambert, Start::stereographic};
    }();
    std::vector<double> scale(mesh.triangles.size(), 1.0);
    std::vector<Eigen::Vector2d> uv;
    detail::TubeFold best_fold = detail::TubeFold::prism;
    // Reweighting rounds (tube start): every edge's Tutte weight is multiplied by the geometric
    // mean of (spherical share / surface share)^exponent of its faces, so crowded regions pull less
    // and grow, spread ones pull more and shrink; each round is again a Tutte embedding with
    // positive weights, hence bijective in the plane; a round is kept only when the lifted map
    // has no more bad triangles and a lower mean |log area ratio|. They run once the tube folds
    // are done, before any other start: they often clear the folds' last bad triangles.
    auto reweight_tube = [&]() {
      if (best.kind != "tube" || options.reweight_rounds <= 0) return;
      // Each face's ratio and |log ratio| on threads, summed in the faces' order (the same bits
      // as one loop).
      std::vector<double> logs(mesh.triangles.size());
      auto log_mean = [&](const std::vector<Vec3>& x, std::vector<double>& ratio) {
        for_each_index(mesh.triangles.size(), [&](std::size_t f) {
          const Triangle& t = mesh.triangles[f];
          ratio[f] = detail::sphere_triangle_area(x[t[0]], x[t[1]], x[t[2]]) / (4.0 * M_PI) / shares[f];
          logs[f] = std::abs(std::log(std::max(ratio[f], 1e-300)));
        });
        double sum = 0.0;
        for (double l : logs) sum += l;
        return sum / static_cast<double>(mesh.triangles.size());
      };
      std::vector<double> ratio(mesh.triangles.size());
      double current = log_mean(best.sphere, ratio);
      for (int round = 0; round < options.reweight_rounds && current > options.reweight_target; ++round) {
        for_each_index(scale.size(), [&](std::size_t f) {
          scale[f] = std::clamp(scale[f] * std::pow(std::max(ratio[f], 1e-12), options.reweight_exponent), 1e-8, 1e8);
        });
        detail::TutteLift next = tube_embedder.lift(tube_embedder.solve(&scale), best_fold);
        long bad = detail::untangle(mesh, adjacency, next.sphere, options.untangle_sweeps);
        if (bad > 0) bad = detail::reembed_patches(mesh, adjacency, next.sphere, 12);
        std::vector<double> next_ratio(mesh.triangles.size());
        const double value = log_mean(next.sphere, next_ratio);
        // Better means fewer bad triangles, or as few and less distortion.
        if (bad > best_bad || (bad == best_bad && !(value < current))) break;
        best_bad = bad;
        ++report.reweight_rounds;
        current = value;
        ratio.swap(next_ratio);
        best = std::move(next);
      }
    };
    bool reweighted = false;
    for (const Start start_kind : starts) {
      detail::TutteLift lift;
      long bad = 0;
      const detail::TubeFold fold = start_kind == Start::lambert ? detail::TubeFold::lambert : detail::TubeFold::prism;
      if (start_kind == Start::progressive) {
        // Bijective by construction: no untangling; a triangle counts as bad only if precision
        // ran out (then the other starts are tried).
        detail::ProgressiveResult progressive = detail::progressive_embedding(
            mesh, adjacency, options.progressive_max_valence, options.progressive_relax_rounds);
        lift.sphere = std::move(progressive.sphere);
        lift.kind = "progressive";
        for (const Triangle& t : mesh.triangles)
          if (!(detail::sphere_triangle_area(lift.sphere[t[0]], lift.sphere[t[1]], lift.sphere[t[2]]) >
                degenerate_area))
            ++bad;
        report.starts_tried.push_back("progressive");
      } else {
        if (start_kind == Start::stereographic) {
          lift = detail::tutte_lift(mesh, adjacency, options.anisotropic);
          lift.kind = "stereographic";
        } else {
          if (!tube_embedder.valid()) continue;
          if (uv.empty()) uv = tube_embedder.solve();
          lift = tube_embedder.lift(uv, fold);
        }
        if (lift.sphere.empty()) continue;
        report.starts_tried.push_back(start_kind == Start::stereographic ? "stereographic"
                                      : start_kind == Start::prism       ? "tube-prism"
                                                                         : "tube-lambert");
        bad = detail::untangle(mesh, adjacency, lift.sphere, options.untangle_sweeps);
        if (bad > 0) bad = detail::reembed_patches(mesh, adjacency, lift.sphere, 12);
      }
      if (best_bad < 0 || bad < best_bad) {
        best = std::move(lift);
        best_bad = bad;
        best_fold = fold;
      }
      if (!reweighted && (start_kind == Start::lambert || best_bad == 0) && best.kind == "tube") {
        reweight_tube();
        reweighted = true;
      }
      if (best_bad == 0) break;
    }
    FASCICLE_CHECK(!best.sphere.empty(), "a sphere start was computed");
    report.solve_seconds = since(start);
    report.initial_map = best.kind;
    report.cut_face = best.cut_face;
    report.lift_margin = best.margin;
    map.positions = std::move(best.sphere);
    // The tube map is area-centred by construction (equal-area lift of an arc-length layout);
    // the progressive start is area-weighted from its tetrahedron on (measured: centring changes
    // nothing after it); the stereographic start needs the Moebius centring.
    if (report.initial_map == "stereographic")
      report.mobius_steps = detail::mobius_center(mesh, shares, map.positions, options.mobius_steps,
                                                  options.mobius_tolerance, report.mobius_residual);
    report.iterations = detail::balance_areas(mesh, adjacency, shares, map.positions, options.balance_sweeps,
                                              options.balance_tolerance, report.rejected_moves);
  } else {
    map.positions = detail::thesis_relax(mesh, adjacency, options, report);
  }
  report.seconds = since(start);
  report.quality = measure_sphere_map(mesh, map.positions);
  if (report.failure.empty() && !report.quality.bijective())
    report.failure = std::to_string(report.quality.flipped) + " flipped and " +
                     std::to_string(report.quality.degenerate) + " degenerate triangles, spherical areas sum to " +
                     std::to_string(report.quality.area_sum) + " instead of 4 pi";
  report.status = report.failure.empty() ? "ok" : "failed";
  return map;
}

}  // namespace fascicle
