// The compute-backend factory (springs/compute_backend.h): names, auto's choice, the CPU backend
// settling as springs::settle() does, and, where the build has OpenGL, the GPU backend.

#include "geometry/errors.h"
#include "springs/compute_backend.h"
#include "springs/lattice.h"
#include "springs/settle.h"

#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>

using namespace fascicle;
using namespace fascicle::springs;

namespace {

// A small lattice with its surface bent, so that the interior has something to settle.
Lattice bent_lattice() {
  LatticeOptions options;
  options.fibres = 16;
  options.resolution = 6;
  Lattice lattice = build_lattice(options);
  for (std::size_t i = 0; i < lattice.system.positions.size(); ++i)
    if (lattice.system.fixed[i]) {
      Vec3& p = lattice.system.positions[i];
      p = Vec3(1.2 * p.x() + 0.1 * std::sin(2.0 * p.z()), p.y(), p.z() + 0.1 * p.x() * p.x());
    }
  return lattice;
}

}  // namespace

TEST_CASE("the cpu backend settles exactly as springs::settle", "[springs][compute]") {
  ComputeRequest request;
  request.name = "cpu";
  const auto backend = make_compute_backend(request);
  CHECK(backend->name() == "cpu");
  CHECK(backend->reason().find("requested") != std::string::npos);
  CHECK(backend->device().renderer.empty());
  Lattice a = bent_lattice(), b = bent_lattice();
  SettleOptions options;
  const LatticeShape shape = shape_of(a);
  const SettleReport direct = settle(a.system, options, &shape);
  GpuSettleFigures figures;
  figures.gpu_bytes = 7;  // the CPU leaves the figures as they are
  const SettleReport through = backend->settle(b.system, options, &shape, &figures);
  CHECK(figures.gpu_bytes == 7);
  CHECK(direct.iterations == through.iterations);
  REQUIRE(a.system.positions.size() == b.system.positions.size());
  for (std::size_t i = 0; i < a.system.positions.size(); ++i) CHECK(a.system.positions[i] == b.system.positions[i]);
}

TEST_CASE("auto settles on the cpu where a gpu would not pay, and says why", "[springs][compute]") {
  ComputeRequest request;
  request.name = "auto";
  request.solver = SolverKind::static_equilibrium;
  request.points = 1000;
  const auto backend = make_compute_backend(request);
  CHECK(backend->name() == "cpu");
  CHECK_FALSE(backend->reason().empty());
  request.solver = SolverKind::verlet;
  const auto small = make_compute_backend(request);
  CHECK(small->name() == "cpu");
  if (gpu_backends_built()) CHECK(small->reason().find("below") != std::string::npos);
  // Chosen for the settle's size, not a fall-back for want of a context.
  CHECK_FALSE(backend->fell_back());
  CHECK_FALSE(small->fell_back());
}

TEST_CASE("an unknown backend name is an option error", "[springs][compute]") {
  ComputeRequest request;
  request.name = "cuda";
  CHECK_THROWS_AS(make_compute_backend(request), OptionError);
}

TEST_CASE("the gl backend settles on the GPU where the build has it, else is a gpu error", "[springs][compute][gpu]") {
  ComputeRequest request;
  request.name = "gl";
  if (!gpu_backends_built()) {
    try {
      make_compute_backend(request);
      FAIL("gl made without the GPU backends");
    } catch (const Error& e) {
      CHECK(e.code() == ErrorCode::gpu);
    }
    return;
  }
  const auto backend = make_compute_backend(request);
  CHECK(backend->name() == "gl");
  CHECK_FALSE(backend->device().renderer.empty());
  Lattice lattice = bent_lattice(), reference = bent_lattice();
  SettleOptions options;
  GpuSettleFigures figures;
  const LatticeShape shape = shape_of(lattice);
  const SettleReport report = backend->settle(lattice.system, options, &shape, &figures);
  CHECK(report.converged);
  CHECK(figures.gpu_bytes > 0);
  settle(reference.system, options, &shape);
  // Float32 on the GPU, polished in double on the CPU: the same equilibrium to the tolerance.
  double largest = 0.0;
  for (std::size_t i = 0; i < lattice.system.positions.size(); ++i)
    largest = std::max(largest, (lattice.system.positions[i] - reference.system.positions[i]).norm());
  CHECK(largest < 1e-3);
}
