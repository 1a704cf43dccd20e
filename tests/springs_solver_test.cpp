// The settle solvers: Verlet on both data paths, static local-global; agreement, invariants,
// stability at extreme parameters, scale invariance, divergence errors.

#include "geometry/errors.h"
#include "springs/coarse_start.h"
#include "springs/lattice.h"
#include "springs/multigrid.h"
#include "springs/settle.h"
#include "springs/solvers_internal.h"

#include <catch2/catch.hpp>
#include <tbb/task_arena.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <random>

using namespace fascicle;
using namespace fascicle::springs;

namespace {

// A template lattice whose surface was moved as the decomposition moves it: a smooth
// non-affine map of the fixed points (bend + stretch), interior left at template positions.
Lattice moved_lattice(TemplateKind kind, int fibres, int resolution, SpringModel model) {
  LatticeOptions options;
  options.kind = kind;
  options.fibres = fibres;
  options.resolution = resolution;
  options.model = model;
  Lattice lattice = build_lattice(options);
  for (std::size_t i = 0; i < lattice.system.positions.size(); ++i) {
    if (!lattice.system.fixed[i]) continue;
    Vec3& p = lattice.system.positions[i];
    p = Vec3(1.3 * p.x() + 0.2 * std::sin(2.0 * p.z()), 0.8 * p.y() + 0.1 * p.x() * p.z(),
             p.z() + 0.15 * p.x() * p.x());
  }
  return lattice;
}

double max_distance(const std::vector<Vec3>& a, const std::vector<Vec3>& b) {
  double d = 0.0;
  for (std::size_t i = 0; i < a.size(); ++i) d = std::max(d, (a[i] - b[i]).norm());
  return d;
}

bool all_finite(const std::vector<Vec3>& points) {
  for (const Vec3& p : points)
    if (!p.allFinite()) return false;
  return true;
}

SettleOptions verlet_options() {
  SettleOptions options;
  options.solver = SolverKind::verlet;
  return options;
}

}  // namespace

TEST_CASE("structured and general Verlet paths agree to 1e-9", "[springs][solver]") {
  // Every spring loop of the structured path.
  for (int loop : {2, 1, 0}) {  // the AVX-512 loop (where the processor has it), AVX2, plain
    const bool simd = loop > 0;
    detail::set_structured_simd(simd);
    detail::set_structured_avx512(loop == 2);
    for (SpringModel model : {SpringModel::model6, SpringModel::model26}) {
      for (TemplateKind kind : {TemplateKind::pennate, TemplateKind::curved}) {
        INFO(template_name(kind) << " model-" << static_cast<int>(model) << " loop " << detail::structured_simd_name());
        const Lattice lattice = moved_lattice(kind, 90, 11, model);
        const LatticeShape shape = shape_of(lattice);
        SettleOptions options = verlet_options();
        options.tolerance = 0.0;
        options.max_iterations = 300;
        options.backend = Backend::structured;
        SpringSystem structured = lattice.system;
        const SettleReport a = settle(structured, options, &shape);
        options.backend = Backend::general;
        SpringSystem general = lattice.system;
        const SettleReport b = settle(general, options, &shape);
        // pennate: every direction's springs have one length (the uniform rows); curved: not
        CHECK(a.backend == (kind == TemplateKind::pennate ? "structured-uniform" : "structured"));
        CHECK(b.backend == "general");
        CHECK(a.iterations == 300);
        CHECK(b.iterations == 300);
        // the systems moved a lot, and moved the same way
        CHECK(max_distance(structured.positions, lattice.system.positions) > 1e-2);
        CHECK(max_distance(structured.positions, general.positions) <= 1e-9 * std::sqrt(3.0));
        REQUIRE(a.residual_history.size() == b.residual_history.size());
        for (std::size_t i = 0; i < a.residual_history.size(); ++i)
          CHECK(a.residual_history[i] == Approx(b.residual_history[i]).epsilon(1e-9).margin(1e-9));
      }
    }
  }
  detail::set_structured_simd(true);
  detail::set_structured_avx512(true);
}

TEST_CASE("the general path's spring-once loop gives the per-point gather's bits on one thread or two",
          "[springs][solver]") {
  // 11^3 points: one block, where the general path evaluates each spring once.
  for (SpringModel model : {SpringModel::model6, SpringModel::model26}) {
    for (SolverKind solver : {SolverKind::verlet, SolverKind::static_equilibrium}) {
      INFO("model-" << static_cast<int>(model) << " " << solver_name(solver));
      const Lattice lattice = moved_lattice(TemplateKind::curved, 90, 11, model);
      SettleOptions options = verlet_options();
      options.solver = solver;
      options.tolerance = 0.0;
      options.max_iterations = 200;
      options.backend = Backend::general;
      options.record_energy = true;
      SpringSystem once = lattice.system;
      const SettleReport a = settle(once, options);
      detail::set_general_spring_once(false);
      SpringSystem gather = lattice.system;
      const SettleReport b = settle(gather, options);
      detail::set_general_spring_once(true);
      // The spring-once loop runs in two halves of the points side by side: on one thread the
      // same bits.
      SpringSystem single = lattice.system;
      SettleReport c;
      tbb::task_arena(1).execute([&] { c = settle(single, options); });
      CHECK(a.iterations == 200);
      CHECK(max_distance(once.positions, lattice.system.positions) > 1e-2);
      CHECK(once.positions == gather.positions);
      CHECK(a.residual_history == b.residual_history);
      CHECK(single.positions == once.positions);
      CHECK(c.residual_history == a.residual_history);
      CHECK(a.energy_history.size() == 201);
      CHECK(a.energy_history == b.energy_history);
      CHECK(c.energy_history == a.energy_history);
    }
  }
}

TEST_CASE("the structured path gives bitwise the same result on 1, 2 or 3 threads", "[springs][solver]") {
  // About 40 000 points: large enough to be cut into tiles (slabs of planes x strips of rows),
  // whose sizes follow the thread count; every point's force must still be summed in the same
  // order. A curved template (springs of many lengths: the per-point stiffness arrays) with a
  // few interior points fixed; every spring loop; and the general path agrees to 1e-9. Rows of
  // 40 points (5 vectors) and of 35 (stored padded to 40: the last vector partly padding). With
  // the moved boundary fixed, and free (only the random points fixed): the rows on the faces of
  // the lattice, whose forces are summed from fewer pushes, then move too.
  for (int loop : {2, 1, 0}) {  // the AVX-512 loop (where the processor has it), AVX2, plain
    const bool simd = loop > 0;
    detail::set_structured_simd(simd);
    detail::set_structured_avx512(loop == 2);
    for (int fibres : {1600, 1400})
      for (bool boundary_fixed : {true, false})
        for (SpringModel model : {SpringModel::model6, SpringModel::model26}) {
          Lattice lattice = moved_lattice(TemplateKind::curved, fibres, 25, model);
          REQUIRE(lattice.point_count() > 32768);
          REQUIRE(lattice.nx == (fibres == 1600 ? 40 : 35));
          if (!boundary_fixed) std::fill(lattice.system.fixed.begin(), lattice.system.fixed.end(), 0);
          std::mt19937 rng(3);
          for (int i = 0; i < 40; ++i) lattice.system.fixed[rng() % lattice.system.fixed.size()] = 1;
          const LatticeShape shape = shape_of(lattice);
          std::vector<std::vector<Vec3>> results;
          std::vector<double> residuals;
          SettleOptions options = verlet_options();
          options.tolerance = 0.0;
          options.max_iterations = 40;
          for (int threads : {1, 2, 3}) {
            tbb::task_arena arena(threads);
            arena.execute([&] {
              options.backend = Backend::structured;
              SpringSystem system = lattice.system;
              const SettleReport report = settle(system, options, &shape);
              CHECK(report.backend == "structured");
              results.push_back(system.positions);
              residuals.push_back(report.residual);
            });
          }
          options.backend = Backend::general;
          SpringSystem general = lattice.system;
          settle(general, options, &shape);
          INFO("nx " << lattice.nx << " boundary fixed " << boundary_fixed << " model-" << static_cast<int>(model)
                     << " loop " << detail::structured_simd_name());
          CHECK(max_distance(results[0], lattice.system.positions) > 1e-3);  // it moved
          CHECK(max_distance(results[0], general.positions) <= 1e-9 * std::sqrt(3.0));
          for (int t = 1; t < 3; ++t) {
            CHECK(residuals[t] == residuals[0]);
            for (std::size_t i = 0; i < results[0].size(); ++i)
              REQUIRE(std::memcmp(results[0][i].data(), results[t][i].data(), 3 * sizeof(double)) == 0);
          }
        }
  }
  detail::set_structured_simd(true);
  detail::set_structured_avx512(true);
}

TEST_CASE("portable_loop settles with the portable spring loop whatever the processor has", "[springs][solver]") {
  // The decomposition sets it so that its fibres are the same on every processor: the result must
  // be the portable loop's, bit for bit, with the vector loops allowed (Verlet and the momentum
  // static solver, which share the loops; model-6 and model-26).
  for (SpringModel model : {SpringModel::model6, SpringModel::model26}) {
    for (SolverKind solver : {SolverKind::verlet, SolverKind::static_equilibrium}) {
      INFO("model-" << static_cast<int>(model) << " solver " << static_cast<int>(solver) << " loop "
                    << detail::structured_simd_name());
      const Lattice lattice = moved_lattice(TemplateKind::curved, 90, 11, model);
      const LatticeShape shape = shape_of(lattice);
      SettleOptions options;
      options.solver = solver;
      options.tolerance = 0.0;
      options.max_iterations = 200;
      options.backend = Backend::structured;
      options.portable_loop = true;
      SpringSystem with_option = lattice.system;
      const SettleReport report = settle(with_option, options, &shape);
      CHECK(report.backend.find("structured") != std::string::npos);
      detail::set_structured_simd(false);
      options.portable_loop = false;
      SpringSystem portable = lattice.system;
      settle(portable, options, &shape);
      detail::set_structured_simd(true);
      CHECK(max_distance(with_option.positions, lattice.system.positions) > 1e-3);  // it moved
      for (std::size_t i = 0; i < portable.positions.size(); ++i)
        REQUIRE(std::memcmp(portable.positions[i].data(), with_option.positions[i].data(), 3 * sizeof(double)) == 0);
      if (detail::structured_simd_active()) {  // the vector loop rounds otherwise
        SpringSystem vector = lattice.system;
        settle(vector, options, &shape);
        CHECK(max_distance(vector.positions, portable.positions) > 0.0);
      }
    }
  }
}

TEST_CASE("fixed points are bitwise unchanged by every solver", "[springs][solver]") {
  Lattice lattice = moved_lattice(TemplateKind::fanned, 49, 9, SpringModel::model6);
  // Fix a few interior points too (the structured path takes its checked rows for them).
  std::mt19937 rng(7);
  for (int n = 0; n < 20; ++n) lattice.system.fixed[rng() % lattice.system.fixed.size()] = 1;
  lattice.system.positions[lattice.index(3, 3, 4)] = Vec3(-0.0, 0.5, 0.5);  // a negative zero
  lattice.system.fixed[lattice.index(3, 3, 4)] = 1;
  const LatticeShape shape = shape_of(lattice);
  struct Case {
    SolverKind solver;
    Backend backend;
    StaticMethod method;
  };
  for (Case c : {Case{SolverKind::verlet, Backend::structured, StaticMethod::momentum},
                 Case{SolverKind::verlet, Backend::general, StaticMethod::momentum},
                 Case{SolverKind::static_equilibrium, Backend::automatic, StaticMethod::momentum},
                 Case{SolverKind::static_equilibrium, Backend::general, StaticMethod::momentum},
                 Case{SolverKind::static_equilibrium, Backend::automatic, StaticMethod::newton},
                 Case{SolverKind::static_equilibrium, Backend::automatic, StaticMethod::local_global}}) {
    SettleOptions options;
    options.solver = c.solver;
    options.backend = c.backend;
    options.static_method = c.method;
    options.tolerance = 1e-8;
    SpringSystem system = lattice.system;
    const SettleReport report = settle(system, options, &shape);
    INFO(report.solver << " " << report.backend);
    CHECK(report.converged);
    CHECK(report.iterations > 1);
    for (std::size_t i = 0; i < system.positions.size(); ++i)
      if (lattice.system.fixed[i])
        CHECK(std::memcmp(system.positions[i].data(), lattice.system.positions[i].data(), 3 * sizeof(double)) == 0);
  }
  // Also through the solver object, not only the one-call wrapper.
  SettleOptions options;
  options.backend = Backend::structured;
  auto solver = make_solver(lattice.system, options, &shape);
  for (int i = 0; i < 50; ++i) solver->step();
  const std::vector<Vec3> positions = solver->positions();
  for (std::size_t i = 0; i < positions.size(); ++i)
    if (lattice.system.fixed[i])
      CHECK(std::memcmp(positions[i].data(), lattice.system.positions[i].data(), 3 * sizeof(double)) == 0);
}

TEST_CASE("model-26 with nothing fixed returns to its shape after a random displacement", "[springs][solver]") {
  const Lattice lattice = regular_lattice(5, SpringModel::model26, 0.25, 0.01, false);
  SpringSystem system = lattice.system;
  std::mt19937 rng(1);
  std::uniform_real_distribution<double> jitter(-0.04, 0.04);
  for (Vec3& p : system.positions) p += Vec3(jitter(rng), jitter(rng), jitter(rng));
  // Springs keep the rest lengths of the undisplaced lattice.
  SettleOptions options = verlet_options();
  options.damping_mode = DampingMode::critical;
  options.tolerance = 1e-10;
  const LatticeShape shape = shape_of(lattice);
  const SettleReport report = settle(system, options, &shape);
  CHECK(report.converged);
  double worst = 0.0;
  for (std::size_t i = 0; i < system.positions.size(); ++i)
    for (std::size_t j = i + 1; j < system.positions.size(); ++j) {
      const double now = (system.positions[i] - system.positions[j]).norm();
      const double then = (lattice.system.positions[i] - lattice.system.positions[j]).norm();
      worst = std::max(worst, std::abs(now - then));
    }
  CHECK(worst < 1e-8);
}

TEST_CASE("model-6 with nothing fixed restores every spring length", "[springs][solver]") {
  const Lattice lattice = regular_lattice(6, SpringModel::model6, 0.2, 0.01, false);
  SpringSystem system = lattice.system;
  std::mt19937 rng(2);
  std::uniform_real_distribution<double> jitter(-0.04, 0.04);
  for (Vec3& p : system.positions) p += Vec3(jitter(rng), jitter(rng), jitter(rng));
  double before = 0.0;
  for (const Spring& s : system.springs)
    before = std::max(before, std::abs((system.positions[s.a] - system.positions[s.b]).norm() - s.rest));
  SettleOptions options = verlet_options();
  options.damping_mode = DampingMode::critical;
  options.tolerance = 1e-10;
  const LatticeShape shape = shape_of(lattice);
  const SettleReport report = settle(system, options, &shape);
  CHECK(report.converged);
  CHECK(before > 1e-2);
  for (const Spring& s : system.springs)
    CHECK(std::abs((system.positions[s.a] - system.positions[s.b]).norm() - s.rest) < 1e-9 * s.rest);
}

TEST_CASE("damped Verlet runs lose energy monotonically", "[springs][solver]") {
  for (DampingMode mode : {DampingMode::estimate, DampingMode::critical}) {
    for (SpringModel model : {SpringModel::model6, SpringModel::model26}) {
      const Lattice lattice = moved_lattice(TemplateKind::parallel, 64, 8, model);
      SettleOptions options = verlet_options();
      options.damping_mode = mode;
      options.record_energy = true;
      options.tolerance = 1e-6;
      SpringSystem system = lattice.system;
      const LatticeShape shape = shape_of(lattice);
      const SettleReport report = settle(system, options, &shape);
      CHECK(report.converged);
      REQUIRE(report.energy_history.size() > 10);
      for (std::size_t i = 1; i < report.energy_history.size(); ++i)
        CHECK(report.energy_history[i] <= report.energy_history[i - 1]);
      CHECK(report.energy_history.back() < 0.5 * report.energy_history.front());
    }
  }
}

TEST_CASE("extreme masses converge or stop with SolverError, never NaN", "[springs][solver]") {
  const Lattice lattice = moved_lattice(TemplateKind::pennate, 36, 7, SpringModel::model6);
  const LatticeShape shape = shape_of(lattice);
  int diverged = 0, converged = 0;
  for (double mass : {1e-6, 1e-4, 1e-2, 1.0, 1e2, 1e3}) {
    for (double dt : {0.0, 1e-2}) {
      for (Backend backend : {Backend::structured, Backend::general}) {
        SettleOptions options = verlet_options();
        options.mass = mass;
        options.dt = dt;
        options.backend = backend;
        options.tolerance = 1e-6;
        options.max_iterations = 20000;
        SpringSystem system = lattice.system;
        try {
          const SettleReport report = settle(system, options, &shape);
          CHECK(all_finite(system.positions));
          CHECK(std::isfinite(report.residual));
          if (report.converged) ++converged;
        } catch (const SolverError& e) {
          ++diverged;
          CHECK(std::string(e.what()).find("--dt") != std::string::npos);
          CHECK(system.positions == lattice.system.positions);  // nothing written
        }
      }
    }
  }
  CHECK(diverged > 0);     // a fixed step too large for the small masses is caught
  CHECK(converged >= 12);  // the automatic step converges at every mass
}

TEST_CASE("stiffness scaled over 6 orders converges or stops with SolverError, never NaN", "[springs][solver]") {
  const Lattice lattice = moved_lattice(TemplateKind::curved, 36, 7, SpringModel::model26);
  int diverged = 0, converged = 0;
  for (double scale : {1e-3, 1e-1, 1.0, 1e1, 1e3}) {
    for (double dt : {0.0, 5e-3}) {
      SpringSystem system = lattice.system;
      for (Spring& s : system.springs) s.stiffness *= scale;  // general path: k != 1 / rest
      SettleOptions options = verlet_options();
      options.dt = dt;
      options.damping_mode = DampingMode::critical;
      options.tolerance = 1e-6;
      options.max_iterations = 20000;
      try {
        const SettleReport report = settle(system, options);
        CHECK(report.backend == "general");
        CHECK(all_finite(system.positions));
        if (report.converged) ++converged;
      } catch (const SolverError&) { ++diverged; }
      SettleOptions statics;
      statics.solver = SolverKind::static_equilibrium;
      statics.tolerance = 1e-9;
      SpringSystem again = lattice.system;
      for (Spring& s : again.springs) s.stiffness *= scale;
      CHECK(settle(again, statics).converged);
      CHECK(all_finite(again.positions));
    }
  }
  CHECK(diverged > 0);
  CHECK(converged >= 5);
}

TEST_CASE("the same lattice at 1e-6 and 1e4 length scale gives the same relative result", "[springs][solver]") {
  for (SolverKind solver : {SolverKind::verlet, SolverKind::static_equilibrium}) {
    for (StaticMethod method :
         {StaticMethod::momentum, StaticMethod::newton, StaticMethod::local_global, StaticMethod::multigrid}) {
      if (solver == SolverKind::verlet && method != StaticMethod::momentum) continue;
      std::vector<std::vector<Vec3>> results;
      std::vector<SettleReport> reports;
      for (double scale : {1e-6, 1.0, 1e4}) {
        Lattice lattice = moved_lattice(TemplateKind::fanned, 25, 6, SpringModel::model6);
        SpringSystem& system = lattice.system;
        for (Vec3& p : system.positions) p *= scale;
        for (Spring& s : system.springs) {
          s.rest *= scale;
          s.stiffness = 1.0 / s.rest;
        }
        for (double& m : system.mass) m *= scale * scale * scale;  // density x volume
        SettleOptions options;
        options.solver = solver;
        options.static_method = method;
        options.damping_mode = DampingMode::critical;
        // Verlet: a fixed number of steps; static: to a tight tolerance.
        options.tolerance = solver == SolverKind::verlet ? 0.0 : 1e-10;
        options.max_iterations = solver == SolverKind::verlet ? 400 : 10000;
        const LatticeShape shape = shape_of(lattice);
        reports.push_back(settle(system, options, &shape));
        for (Vec3& p : system.positions) p /= scale;
        results.push_back(system.positions);
      }
      INFO(solver_name(solver) << " method " << static_cast<int>(method));
      CHECK(max_distance(results[0], results[1]) < 1e-9);
      CHECK(max_distance(results[2], results[1]) < 1e-9);
      if (solver == SolverKind::verlet) {
        CHECK(reports[0].residual == Approx(reports[1].residual).epsilon(1e-6));
        CHECK(reports[2].residual == Approx(reports[1].residual).epsilon(1e-6));
        CHECK(reports[1].residual < 1e-2);  // it did settle
      } else {
        for (const SettleReport& r : reports) CHECK(r.converged);
      }
    }
  }
}

TEST_CASE("static equilibrium matches a long Verlet run", "[springs][solver]") {
  for (SpringModel model : {SpringModel::model6, SpringModel::model26}) {
    const Lattice lattice = moved_lattice(TemplateKind::curved, 49, 9, model);
    const LatticeShape shape = shape_of(lattice);
    SettleOptions statics;
    statics.solver = SolverKind::static_equilibrium;
    statics.static_method = StaticMethod::newton;
    statics.tolerance = 1e-11;
    SpringSystem a = lattice.system;
    const SettleReport ra = settle(a, statics, &shape);
    SettleOptions verlet = verlet_options();
    verlet.damping_mode = DampingMode::critical;
    verlet.tolerance = 1e-11;
    SpringSystem b = lattice.system;
    const SettleReport rb = settle(b, verlet, &shape);
    CHECK(ra.converged);
    CHECK(rb.converged);
    CHECK(ra.iterations < rb.iterations);
    CHECK(max_distance(a.positions, b.positions) < 1e-8);
    CHECK(max_distance(a.positions, lattice.system.positions) > 1e-2);
    CHECK(ra.backend == "newton-cg");
    CHECK(ra.inner_iterations >= ra.iterations);
    // The momentum method, on both data paths, reaches the same equilibrium.
    for (Backend backend : {Backend::automatic, Backend::general}) {
      SettleOptions momentum;
      momentum.solver = SolverKind::static_equilibrium;
      momentum.static_method = StaticMethod::momentum;
      momentum.backend = backend;
      momentum.tolerance = 1e-11;
      SpringSystem m = lattice.system;
      const SettleReport rm = settle(m, momentum, &shape);
      CHECK(rm.converged);
      CHECK(rm.backend == (backend == Backend::general ? "momentum-general" : "momentum-structured"));
      CHECK(max_distance(a.positions, m.positions) < 1e-8);
    }
    // Local-global (Liu et al. 2013), Anderson-accelerated and plain, reach the same equilibrium.
    statics.static_method = StaticMethod::local_global;
    SpringSystem c = lattice.system;
    const SettleReport rc = settle(c, statics, &shape);
    CHECK(rc.backend == "ldlt");
    CHECK(rc.converged);
    CHECK(max_distance(a.positions, c.positions) < 1e-8);
    statics.acceleration = Acceleration::none;
    SpringSystem d = lattice.system;
    const SettleReport rd = settle(d, statics, &shape);
    CHECK(rd.converged);
    CHECK(rd.iterations >= rc.iterations);
    CHECK(max_distance(a.positions, d.positions) < 1e-8);
    // The multigrid method (a 7 x 7 x 9 grid: below the default coarsest size, one level solved
    // directly; with a coarsest size of 16 points, three levels and V-cycles).
    for (int coarsest : {4096, 16}) {
      statics.static_method = StaticMethod::multigrid;
      statics.multigrid_coarsest_points = coarsest;
      SpringSystem e = lattice.system;
      const SettleReport re = settle(e, statics, &shape);
      CHECK(re.converged);
      CHECK(re.backend == (coarsest == 16 ? "multigrid-3" : "multigrid-1"));
      CHECK(max_distance(a.positions, e.positions) < 1e-8);
    }
  }
}

TEST_CASE("static with zero rest lengths is exact in one solve", "[springs][solver]") {
  SpringSystem system;
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> coordinate(-1.0, 1.0), stiffness(0.5, 5.0);
  const int n = 40;
  for (int i = 0; i < n; ++i) {
    system.positions.push_back(Vec3(coordinate(rng), coordinate(rng), coordinate(rng)));
    system.fixed.push_back(i < 6 ? 1 : 0);
    system.mass.push_back(1.0);
  }
  for (int i = 0; i < n; ++i)
    for (int k = 1; k <= 3; ++k) system.springs.push_back({i, (i + 7 * k) % n, 0.0, stiffness(rng)});
  SettleOptions options;
  options.solver = SolverKind::static_equilibrium;
  options.static_method = StaticMethod::local_global;
  options.tolerance = 1e-12;
  SpringSystem copy = system;
  const SettleReport report = settle(copy, options);
  CHECK(report.converged);
  CHECK(report.iterations == 1);
  CHECK(report.residual < 1e-12);
  // Newton reaches the same point (the energy is quadratic: a few steps).
  options.static_method = StaticMethod::newton;
  const SettleReport newton = settle(system, options);
  CHECK(newton.converged);
  for (std::size_t i = 0; i < system.positions.size(); ++i)
    CHECK((system.positions[i] - copy.positions[i]).norm() < 1e-10);
}

TEST_CASE("a spring matrix factor made ahead gives the local-global solve's bits", "[springs][solver]") {
  // The factor is made from the template lattice (rest lengths and positions play no part); the
  // solves then move the fixed points and change the rest lengths, as the decomposition does.
  const Lattice lattice = moved_lattice(TemplateKind::curved, 36, 6, SpringModel::model6);
  const std::shared_ptr<const SpringMatrixFactor> factor = factor_spring_matrix(build_lattice([] {
                                                                                  LatticeOptions o;
                                                                                  o.kind = TemplateKind::curved;
                                                                                  o.fibres = 36;
                                                                                  o.resolution = 6;
                                                                                  return o;
                                                                                }())
                                                                                    .system);
  for (bool zero_rest : {true, false}) {
    INFO("zero rest lengths " << zero_rest);
    SpringSystem system = lattice.system;
    if (zero_rest)
      for (Spring& s : system.springs) s.rest = 0.0;
    SettleOptions options;
    options.solver = SolverKind::static_equilibrium;
    options.static_method = StaticMethod::local_global;
    options.acceleration = Acceleration::none;
    options.tolerance = 1e-10;
    options.max_iterations = 30;
    SpringSystem own = system, ahead = system;
    const SettleReport a = settle(own, options);
    const SettleReport b = settle(ahead, options, nullptr, factor);
    CHECK(a.iterations == b.iterations);
    CHECK(a.residual_history == b.residual_history);
    CHECK(own.positions == ahead.positions);
    CHECK(max_distance(own.positions, lattice.system.positions) > 1e-2);
    if (zero_rest) CHECK(a.iterations == 1);
  }
  // A factor made for another system is refused: other fixed flags, another stiffness, other ends.
  SettleOptions options;
  options.solver = SolverKind::static_equilibrium;
  options.static_method = StaticMethod::local_global;
  SpringSystem refixed = lattice.system;
  for (std::size_t i = 0; i < refixed.fixed.size(); ++i)
    if (!refixed.fixed[i]) {
      refixed.fixed[i] = 1;
      break;
    }
  SpringSystem stiffer = lattice.system;
  stiffer.springs[5].stiffness *= 2.0;
  SpringSystem rewired = lattice.system;
  std::swap(rewired.springs[3].a, rewired.springs[3].b);
  for (SpringSystem* other : {&refixed, &stiffer, &rewired}) {
    try {
      settle(*other, options, nullptr, factor);
      FAIL("a factor made for another system was used");
    } catch (const Error& e) { CHECK(e.code() == ErrorCode::internal); }
  }
  // The other methods ignore it.
  options.static_method = StaticMethod::momentum;
  SpringSystem momentum = stiffer;
  CHECK_NOTHROW(settle(momentum, options, nullptr, factor));
}

TEST_CASE("tolerance 0 runs exactly max_iterations", "[springs][solver]") {
  const Lattice lattice = moved_lattice(TemplateKind::parallel, 16, 5, SpringModel::model6);
  for (SolverKind solver : {SolverKind::verlet, SolverKind::static_equilibrium}) {
    SettleOptions options;
    options.solver = solver;
    options.tolerance = 0.0;
    options.max_iterations = 37;
    SpringSystem system = lattice.system;
    const SettleReport report = settle(system, options);
    CHECK(report.iterations == 37);
    CHECK_FALSE(report.converged);
    CHECK(report.residual_history.size() == 38);
  }
}

TEST_CASE("solver errors and option errors", "[springs][solver]") {
  const Lattice free_lattice = regular_lattice(4, SpringModel::model6, 1.0, 1.0, false);
  SettleOptions statics;
  statics.solver = SolverKind::static_equilibrium;
  statics.static_method = StaticMethod::newton;
  SpringSystem system = free_lattice.system;
  CHECK_THROWS_AS(settle(system, statics), SolverError);
  statics.static_method = StaticMethod::local_global;
  CHECK_THROWS_AS(settle(system, statics), SolverError);
  CHECK_THROWS_AS(parse_static_method("cholesky"), OptionError);

  const Lattice lattice = moved_lattice(TemplateKind::parallel, 16, 5, SpringModel::model6);
  SettleOptions options;
  options.tolerance = -1.0;
  CHECK_THROWS_AS(make_solver(lattice.system, options), OptionError);
  options = SettleOptions();
  options.max_iterations = 0;
  CHECK_THROWS_AS(make_solver(lattice.system, options), OptionError);
  options = SettleOptions();
  options.dt = -1.0;
  CHECK_THROWS_AS(make_solver(lattice.system, options), OptionError);
  options = SettleOptions();
  options.backend = Backend::structured;  // no shape given
  CHECK_THROWS_AS(make_solver(lattice.system, options), OptionError);
  SpringSystem scaled = lattice.system;
  for (Spring& s : scaled.springs) s.stiffness *= 2.0;  // not 1 / rest
  const LatticeShape shape = shape_of(lattice);
  CHECK_THROWS_AS(make_solver(scaled, options, &shape), OptionError);
  CHECK_THROWS_AS(parse_solver_kind("implicit"), OptionError);
  CHECK_THROWS_AS(parse_backend("gpu"), OptionError);

  // A time step far too large diverges with the error, not NaN.
  options = SettleOptions();
  options.dt = 10.0;
  SpringSystem diverging = lattice.system;
  CHECK_THROWS_AS(settle(diverging, options), SolverError);
}

namespace {

// The problem of `fascicle bench springs` (docs/BENCHMARKS.md): a regular n^3 lattice of the unit
// cube whose boundary is moved by a smooth non-affine map (stretch, squeeze, bend, shear).
Lattice moved_cube(int n, SpringModel model) {
  Lattice lattice = regular_lattice(n, model, 1.0 / (n - 1), 1.0, true);
  for (std::size_t i = 0; i < lattice.system.positions.size(); ++i) {
    if (!lattice.system.fixed[i]) continue;
    Vec3& p = lattice.system.positions[i];
    p = Vec3(1.3 * p.x() + 0.2 * std::sin(2.0 * p.z()), 0.8 * p.y() + 0.1 * p.x() * p.z(),
             p.z() + 0.15 * p.x() * p.x());
  }
  return lattice;
}

// Largest residual reduction factor of V-cycles 3..10 on L x = b from a random start.
double vcycle_factor(LatticeMultigrid& multigrid, std::size_t points) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> value(-1.0, 1.0);
  std::vector<double> b(3 * points), x(3 * points), r;
  for (double& v : b) v = value(rng);
  for (double& v : x) v = value(rng);
  double previous = multigrid.residual(b, x, r), worst = 0.0;
  for (int cycle = 1; cycle <= 10; ++cycle) {
    multigrid.cycle(b, x);
    const double now = multigrid.residual(b, x, r);
    if (cycle >= 3) worst = std::max(worst, now / previous);
    previous = now;
  }
  return worst;
}

}  // namespace

TEST_CASE("the multigrid V-cycle reduces the Laplacian residual by a factor independent of n", "[springs][multigrid]") {
  for (SpringModel model : {SpringModel::model6, SpringModel::model26}) {
    for (bool lines : {true, false}) {
      std::vector<int> levels;
      for (int n : {9, 17, 33}) {
        const Lattice lattice = moved_cube(n, model);
        MultigridOptions options;
        options.line_smoothing = lines;
        options.coarsest_points = 512;  // 9^3 gets two levels too
        LatticeMultigrid multigrid(lattice.system, shape_of(lattice), options);
        const double factor = vcycle_factor(multigrid, lattice.system.positions.size());
        INFO("n " << n << " model-" << static_cast<int>(model) << " line smoothing " << lines);
        CHECK(factor < 0.3);
        CHECK(factor > 0.0);
        levels.push_back(multigrid.levels());
        CHECK(multigrid.level_points().front() == n * n * n);
      }
      CHECK(levels[0] >= 2);
      CHECK(levels[2] > levels[1]);
      CHECK(levels[1] > levels[0]);
    }
  }
  // Springs of many lengths and stiffnesses (a curved template), a non-cubic grid with an even
  // dimension, interior points pinned, and per-coordinate weights.
  for (SpringModel model : {SpringModel::model6, SpringModel::model26}) {
    Lattice lattice = moved_lattice(TemplateKind::curved, 600, 24, model);
    std::mt19937 rng(5);
    for (int i = 0; i < 30; ++i) lattice.system.fixed[rng() % lattice.system.fixed.size()] = 1;
    std::vector<std::array<double, 3>> weights(lattice.system.springs.size());
    std::uniform_real_distribution<double> scale(0.05, 1.0);
    for (std::size_t s = 0; s < weights.size(); ++s)
      for (int c = 0; c < 3; ++c) weights[s][c] = lattice.system.springs[s].stiffness * scale(rng);
    MultigridOptions options;
    options.coarsest_points = 200;
    const std::vector<std::array<double, 3>>* none = nullptr;
    for (const std::vector<std::array<double, 3>>* w :
         {none, static_cast<const std::vector<std::array<double, 3>>*>(&weights)}) {
      LatticeMultigrid multigrid(lattice.system, shape_of(lattice), options, w);
      INFO("model-" << static_cast<int>(model) << " weighted " << (w != nullptr) << " levels " << multigrid.levels());
      CHECK(multigrid.levels() >= 3);
      CHECK(vcycle_factor(multigrid, lattice.system.positions.size()) < 0.5);
    }
  }
}

TEST_CASE("the multigrid preconditioner is symmetric and zero at fixed points", "[springs][multigrid]") {
  const Lattice lattice = moved_lattice(TemplateKind::pennate, 200, 15, SpringModel::model26);
  MultigridOptions options;
  options.coarsest_points = 100;
  LatticeMultigrid multigrid(lattice.system, shape_of(lattice), options);
  const std::size_t n = lattice.system.positions.size();
  std::mt19937 rng(2);
  std::uniform_real_distribution<double> value(-1.0, 1.0);
  std::vector<double> a(3 * n), b(3 * n), ma, mb;
  for (double& v : a) v = value(rng);
  for (double& v : b) v = value(rng);
  const double aa = multigrid.precondition(a, ma);
  multigrid.precondition(b, mb);
  CHECK(aa > 0.0);
  double a_mb = 0.0, b_ma = 0.0;
  for (std::size_t k = 0; k < 3 * n; ++k) {
    if (lattice.system.fixed[k / 3]) {
      CHECK(ma[k] == 0.0);
      continue;
    }
    a_mb += a[k] * mb[k];
    b_ma += b[k] * ma[k];
  }
  CHECK(a_mb == Approx(b_ma).epsilon(1e-10));
}

TEST_CASE("static multigrid reaches 1e-6 and the momentum method's equilibrium", "[springs][multigrid]") {
  for (SpringModel model : {SpringModel::model6, SpringModel::model26}) {
    // The bench problem (its boundary squeezes y by 0.8, so model-6 springs buckle sideways and
    // the equilibrium is not unique: only convergence is checked here).
    {
      const Lattice lattice = moved_cube(20, model);
      const LatticeShape shape = shape_of(lattice);
      SettleOptions options;
      options.solver = SolverKind::static_equilibrium;
      options.static_method = StaticMethod::multigrid;
      SpringSystem a = lattice.system;
      const SettleReport ra = settle(a, options, &shape);
      INFO("bench map, model-" << static_cast<int>(model) << " iterations " << ra.iterations);
      CHECK(ra.converged);
      CHECK(ra.residual <= 1e-6);
      CHECK(relative_residual(a, a.positions) <= 1e-6);
      CHECK(ra.backend == "multigrid-2");
      CHECK(ra.residual_history.size() == static_cast<std::size_t>(ra.iterations) + 1);
      CHECK(ra.residual_history.front() > 1e-2);
      CHECK(max_distance(a.positions, lattice.system.positions) > 1e-2);
    }
    // Every spring stretched (a unique equilibrium): multigrid at 1e-6 lies within 1e-4 spacings of
    // the momentum method's at 1e-10, with and without the harmonic start and with the
    // directional preconditioner.
    Lattice lattice = regular_lattice(20, model, 1.0 / 19, 1.0, true);
    for (std::size_t i = 0; i < lattice.system.positions.size(); ++i) {
      if (!lattice.system.fixed[i]) continue;
      Vec3& p = lattice.system.positions[i];
      p = Vec3(1.25 * p.x() + 0.1 * std::sin(2.0 * p.z()), 1.2 * p.y() + 0.1 * p.x() * p.z(),
               1.15 * p.z() + 0.1 * p.x() * p.x());
    }
    const LatticeShape shape = shape_of(lattice);
    SettleOptions momentum;
    momentum.solver = SolverKind::static_equilibrium;
    momentum.static_method = StaticMethod::momentum;
    momentum.tolerance = 1e-10;
    SpringSystem b = lattice.system;
    REQUIRE(settle(b, momentum, &shape).converged);
    for (int variant = 0; variant < 3; ++variant) {
      SettleOptions options;
      options.solver = SolverKind::static_equilibrium;
      options.static_method = StaticMethod::multigrid;
      options.multigrid_harmonic_start = variant != 1;
      options.multigrid_directional = variant == 2;
      SpringSystem a = lattice.system;
      const SettleReport ra = settle(a, options, &shape);
      INFO("stretched, model-" << static_cast<int>(model) << " variant " << variant << " iterations " << ra.iterations);
      CHECK(ra.converged);
      CHECK(ra.residual <= 1e-6);
      CHECK(max_distance(a.positions, lattice.system.positions) > 1e-2);
      CHECK(max_distance(a.positions, b.positions) < 1e-4 / 19);
      for (std::size_t i = 0; i < a.positions.size(); ++i)
        if (lattice.system.fixed[i]) CHECK(a.positions[i] == lattice.system.positions[i]);
    }
  }
}

TEST_CASE("static multigrid falls back to the momentum method off the lattice grid", "[springs][multigrid]") {
  const Lattice lattice = moved_lattice(TemplateKind::parallel, 16, 5, SpringModel::model6);
  SettleOptions options;
  options.solver = SolverKind::static_equilibrium;
  options.static_method = StaticMethod::multigrid;
  // no shape: a general spring system
  SpringSystem a = lattice.system;
  const SettleReport ra = settle(a, options);
  CHECK(ra.backend == "momentum-general");
  CHECK(ra.converged);
  // a shape, but a spring that is not between grid neighbours
  SpringSystem b = lattice.system;
  b.springs.push_back({0, lattice.point_count() - 1, 1.0, 1.0});
  const LatticeShape shape = shape_of(lattice);
  CHECK_FALSE(detail::multigrid_fits(b, &shape));
  CHECK(detail::multigrid_fits(lattice.system, &shape));
  CHECK_THROWS_AS(LatticeMultigrid(b, shape), OptionError);
  const SettleReport rb = settle(b, options, &shape);
  CHECK(rb.backend.rfind("momentum-", 0) == 0);
  // a shape that does not describe the system
  LatticeShape wrong = shape;
  wrong.nz += 1;
  CHECK_THROWS_AS(LatticeMultigrid(lattice.system, wrong), OptionError);
  SpringSystem c = lattice.system;
  CHECK(settle(c, options, &wrong).backend.rfind("momentum-", 0) == 0);
  // the lattice itself runs multigrid
  SpringSystem d = lattice.system;
  CHECK(settle(d, options, &shape).backend.rfind("multigrid-", 0) == 0);
}

TEST_CASE("static multigrid options and errors", "[springs][multigrid]") {
  CHECK(parse_static_method("multigrid") == StaticMethod::multigrid);
  const Lattice lattice = moved_lattice(TemplateKind::parallel, 16, 5, SpringModel::model6);
  const LatticeShape shape = shape_of(lattice);
  SettleOptions options;
  options.solver = SolverKind::static_equilibrium;
  options.static_method = StaticMethod::multigrid;
  for (double step : {0.0, -1.0, 2.5}) {
    options.multigrid_step = step;
    CHECK_THROWS_WITH(make_solver(lattice.system, options, &shape), Catch::Contains("multigrid_step"));
  }
  options = SettleOptions();
  options.multigrid_smoothing_steps = 0;
  CHECK_THROWS_WITH(options.validate(), Catch::Contains("multigrid_smoothing_steps"));
  options = SettleOptions();
  options.multigrid_coarsest_points = 2;
  CHECK_THROWS_WITH(options.validate(), Catch::Contains("multigrid_coarsest_points"));
  // a part of the lattice without a fixed point
  const Lattice free_lattice = regular_lattice(5, SpringModel::model6, 1.0, 1.0, false);
  const LatticeShape free_shape = shape_of(free_lattice);
  SettleOptions statics;
  statics.solver = SolverKind::static_equilibrium;
  statics.static_method = StaticMethod::multigrid;
  SpringSystem system = free_lattice.system;
  CHECK_THROWS_AS(settle(system, statics, &free_shape), SolverError);
}

TEST_CASE("the coarse start reproduces a rigid motion and reaches the fine solve's equilibrium", "[springs][solver]") {
  for (SpringModel model : {SpringModel::model6, SpringModel::model26}) {
    for (int n : {19, 20}) {  // odd: steps of 2; even: one step of 1 per axis
      INFO("model-" << static_cast<int>(model) << ", n = " << n);
      // Boundary moved rigidly, interior left behind: the coarse lattice's equilibrium is the
      // same rigid motion, and so is its interpolation (any affine map is reproduced exactly).
      Lattice lattice = regular_lattice(n, model, 1.0 / (n - 1), 1.0, true);
      const Eigen::Matrix3d rotation = Eigen::AngleAxisd(0.4, Vec3(1.0, 2.0, 3.0).normalized()).toRotationMatrix();
      const Vec3 shift(0.3, -0.2, 0.7);
      std::vector<Vec3> rigid = lattice.system.positions;
      for (std::size_t i = 0; i < rigid.size(); ++i) {
        rigid[i] = rotation * rigid[i] + shift;
        if (lattice.system.fixed[i]) lattice.system.positions[i] = rigid[i];
      }
      SettleOptions options;
      options.solver = SolverKind::static_equilibrium;
      options.tolerance = 1e-10;
      options.coarse_start_tolerance = 1e-11;  // the coarse lattices to 1e-10 too
      options.coarse_start_points = 500;
      options.coarse_start_perturbation = 0.0;  // the interpolation alone (perturbation: below)
      const LatticeShape shape = shape_of(lattice);
      SpringSystem started = lattice.system;
      const CoarseStartReport report = coarse_start(started, shape, options);
      CHECK(report.levels == 2);  // n^3 -> (n/2 + 1)^3 -> 6^3 (216 <= 500)
      CHECK(report.iterations > 0);
      CHECK(max_distance(started.positions, rigid) < 1e-8);
      for (std::size_t i = 0; i < rigid.size(); ++i)
        if (lattice.system.fixed[i]) CHECK(started.positions[i] == lattice.system.positions[i]);
    }
    // The bench problem (model-26: a unique equilibrium): with and without the coarse start the
    // solve ends within 1e-6 spacings of the same positions, and the start is reported.
    if (model == SpringModel::model26) {
      const Lattice lattice = moved_cube(20, model);
      const LatticeShape shape = shape_of(lattice);
      SettleOptions options;
      options.solver = SolverKind::static_equilibrium;
      options.tolerance = 1e-9;
      SpringSystem a = lattice.system, b = lattice.system;
      options.coarse_start_points = 2000;  // 20^3 -> 11^3 (1331 points): one level
      const SettleReport ra = settle(a, options, &shape);
      options.coarse_start_points = 0;
      const SettleReport rb = settle(b, options, &shape);
      CHECK(ra.converged);
      CHECK(rb.converged);
      CHECK(ra.start_levels == 1);
      CHECK(ra.start_iterations > 0);
      CHECK(rb.start_levels == 0);
      CHECK(max_distance(a.positions, b.positions) < 1e-6 / 19);
    }
  }
}

TEST_CASE("the coarse start's perturbation is fixed and bounded and moves only free model-6 points",
          "[springs][solver]") {
  // The bench problem (squeezed along y) at 12^3: one coarse level of 7^3, no start of its own, so
  // the perturbed and the plain start share the coarse equilibrium and differ by the offsets only.
  SettleOptions options;
  options.solver = SolverKind::static_equilibrium;
  options.tolerance = 1e-8;
  options.coarse_start_points = 500;
  for (SpringModel model : {SpringModel::model6, SpringModel::model26}) {
    INFO("model-" << static_cast<int>(model));
    const Lattice lattice = moved_cube(12, model);
    const LatticeShape shape = shape_of(lattice);
    double rest_sum = 0.0;
    int axis_springs = 0;
    for (const Spring& spring : lattice.system.springs) {
      const long delta = std::labs(static_cast<long>(spring.b) - spring.a);
      if (delta == 1 || delta == 12 || delta == 144) {  // along x, y or z
        rest_sum += spring.rest;
        ++axis_springs;
      }
    }
    REQUIRE(axis_springs == 3 * 11 * 144);
    const double amplitude = options.coarse_start_perturbation * rest_sum / axis_springs;
    SettleOptions plain_options = options;
    plain_options.coarse_start_perturbation = 0.0;
    SpringSystem plain = lattice.system, perturbed = lattice.system, again = lattice.system;
    REQUIRE(coarse_start(plain, shape, plain_options).levels == 1);
    REQUIRE(coarse_start(perturbed, shape, options).levels == 1);
    REQUIRE(coarse_start(again, shape, options).levels == 1);
    CHECK(perturbed.positions == again.positions);  // the same offsets every time
    double largest = 0.0, sum = 0.0;
    int free_coordinates = 0;
    for (std::size_t i = 0; i < plain.positions.size(); ++i) {
      if (lattice.system.fixed[i]) {
        CHECK(perturbed.positions[i] == lattice.system.positions[i]);
        continue;
      }
      for (int c = 0; c < 3; ++c) {
        const double offset = perturbed.positions[i][c] - plain.positions[i][c];
        largest = std::max(largest, std::abs(offset));
        sum += offset;
        ++free_coordinates;
      }
    }
    if (model == SpringModel::model6) {
      CHECK(largest <= 0.5 * amplitude * (1.0 + 1e-9));
      CHECK(largest > 0.45 * amplitude);                           // 3000 uniform draws reach the edge
      CHECK(std::abs(sum / free_coordinates) < 0.02 * amplitude);  // centred (about 0.005 expected)
      // The solve from the perturbed start comes to rest.
      SpringSystem settled = lattice.system;
      const SettleReport report = settle(settled, options, &shape);
      CHECK(report.converged);
      CHECK(report.start_levels == 1);
      CHECK(report.residual <= 1e-8);
    } else {
      CHECK(largest == 0.0);  // model-26 starts are not perturbed
    }
  }
  SettleOptions bad;
  bad.coarse_start_perturbation = -0.1;
  CHECK_THROWS_AS(bad.validate(), OptionError);
  bad.coarse_start_perturbation = 1.5;
  CHECK_THROWS_AS(bad.validate(), OptionError);
}

TEST_CASE("the coarse start declines what is not a full lattice and checks its options", "[springs][solver]") {
  SettleOptions options;
  options.solver = SolverKind::static_equilibrium;
  options.coarse_start_points = 100;
  // Too small a side (4 < 5): unchanged.
  {
    Lattice lattice = regular_lattice(4, SpringModel::model6, 1.0, 1.0, true);
    SpringSystem s = lattice.system;
    CHECK(coarse_start(s, shape_of(lattice), options).levels == 0);
    CHECK(s.positions == lattice.system.positions);
  }
  // A spring missing: unchanged.
  {
    Lattice lattice = regular_lattice(9, SpringModel::model6, 1.0, 1.0, true);
    lattice.system.springs.erase(lattice.system.springs.begin() + 400);
    SpringSystem s = lattice.system;
    CHECK(coarse_start(s, shape_of(lattice), options).levels == 0);
    CHECK(s.positions == lattice.system.positions);
  }
  // A model-6 lattice described as model-26: its diagonal springs are missing, unchanged.
  {
    Lattice lattice = regular_lattice(9, SpringModel::model6, 1.0, 1.0, true);
    LatticeShape shape = shape_of(lattice);
    shape.model = SpringModel::model26;
    SpringSystem s = lattice.system;
    CHECK(coarse_start(s, shape, options).levels == 0);
    CHECK(s.positions == lattice.system.positions);
  }
  SettleOptions bad;
  bad.coarse_start_points = 3;
  CHECK_THROWS_AS(bad.validate(), OptionError);
  bad.coarse_start_points = 0;
  bad.coarse_start_tolerance = 1.0;
  CHECK_THROWS_AS(bad.validate(), OptionError);
}
