// `fascicle settle --backend cpu|gl|gl-gs|auto` as a user runs it: the GPU backends give the CPU's
// settled model, the report names the renderer and why a backend was picked, and the errors of
// the backend options have their exit codes. Runs on the software renderer; tagged [gpu].

#ifdef FASCICLE_HAVE_SHADERS

#include "geometry/errors.h"
#include "geometry/mesh_io.h"
#include "geometry/thesis_format.h"
#include "shaders/gl_context.h"
#include "springs/lattice.h"
#include "test_common.h"

#include <catch2/catch.hpp>
#include <nlohmann/json.hpp>

#include <filesystem>
#include <fstream>

using namespace fascicle;
using namespace fascicle::springs;

namespace {

nlohmann::json read_json(const std::string& path) {
  std::ifstream in(path);
  return nlohmann::json::parse(in);
}

}  // namespace

TEST_CASE("fascicle settle --backend gl and gl-gs give the CPU's result", "[gpu][program]") {
  if (!std::filesystem::exists(test::program())) {
    WARN("skipped: " << test::program() << " is not built");
    return;
  }
  test::TempDir dir;
  LatticeOptions lattice_options;
  lattice_options.kind = TemplateKind::pennate;
  lattice_options.fibres = 25;
  lattice_options.resolution = 9;
  lattice_options.model = SpringModel::model26;
  const Lattice lattice = build_lattice(lattice_options);
  const std::string input = dir.file("lattice.txt");
  write_thesis_model(input, to_thesis_model(lattice));
  std::ofstream targets(dir.file("targets.txt"));
  for (int i = 0; i < lattice.point_count(); ++i)
    if (lattice.system.fixed[i]) {
      const Vec3 p = lattice.system.positions[i];
      targets << i << " " << 1.2 * p.x() << " " << 0.9 * p.y() << " " << p.z() + 0.1 * p.x() << "\n";
    }
  targets.close();
  const std::string base = test::program() + " --quiet settle " + input + " --targets " + dir.file("targets.txt") +
                           " --tolerance 0 --max-iterations 300";
  REQUIRE(test::run_command(base + " --backend cpu -o " + dir.file("cpu.txt") + " --report " + dir.file("cpu.json")) ==
          0);
  const ThesisModel cpu = read_thesis_model(dir.file("cpu.txt"));
  const nlohmann::json cpu_report = read_json(dir.file("cpu.json"));
  CHECK(cpu_report["compute_backend"] == "cpu");
  CHECK(cpu_report["gpu"].is_null());
  for (const std::string backend : {"gl", "gl-gs"}) {
    for (const std::string path : {"auto", "general"}) {
      INFO(backend << " --path " << path);
      const std::string out = dir.file(backend + "-" + path + ".txt"), report = dir.file(backend + ".json");
      REQUIRE(test::run_command(base + " --backend " + backend + " --path " + path + " -o " + out + " --report " +
                                report) == 0);
      const nlohmann::json j = read_json(report);
      CHECK(j["compute_backend"] == backend);
      CHECK(j["iterations"] == 300);
      CHECK(!j["gpu"]["renderer"].get<std::string>().empty());
      CHECK(j["backend_reason"].get<std::string>().find("requested") != std::string::npos);
      const std::string kernel = j["backend"];
      if (backend == "gl" && path == "auto") CHECK(kernel.rfind("gl-structured", 0) == 0);  // lattice detected
      if (backend == "gl" && path == "general") CHECK(kernel == "gl-general");
      const ThesisModel gpu = read_thesis_model(out);
      REQUIRE(gpu.points.size() == cpu.points.size());
      double difference = 0.0, moved = 0.0;
      for (std::size_t i = 0; i < gpu.points.size(); ++i) {
        difference = std::max(difference, (gpu.points[i] - cpu.points[i]).norm());
        moved = std::max(moved, (cpu.points[i] - lattice.system.positions[i]).norm());
      }
      CHECK(difference < 1e-5);  // template units: the lattice is about 1 across
      CHECK(moved > 0.05);
    }
  }
  // auto: the CPU unless a hardware GPU and a large lattice; the report says why.
  REQUIRE(test::run_command(base + " --backend auto -o " + dir.file("auto.txt") + " --report " +
                            dir.file("auto.json")) == 0);
  const nlohmann::json automatic = read_json(dir.file("auto.json"));
  CHECK(automatic["compute_backend"] == "cpu");
  CHECK(automatic["backend_reason"].get<std::string>().find("below") != std::string::npos);
  // Errors: unknown backend or path (18), a GPU backend for a static method other than momentum or
  // gl-gs for the static solver (18), no such device (18).
  const std::string out = " -o " + dir.file("x.txt") + " 2>/dev/null";
  CHECK(test::run_command(base + " --backend vulkan" + out) == exit_code(ErrorCode::invalid_option));
  CHECK(test::run_command(base + " --path diagonal" + out) == exit_code(ErrorCode::invalid_option));
  CHECK(test::run_command(base + " --backend gl --solver static --static-method newton" + out) ==
        exit_code(ErrorCode::invalid_option));
  CHECK(test::run_command(base + " --backend gl-gs --solver static" + out) == exit_code(ErrorCode::invalid_option));
  CHECK(test::run_command(base + " --backend gl --gl-device 999" + out) == exit_code(ErrorCode::invalid_option));
  CHECK(test::run_command(base + " --backend gl --gpu-check-interval 0" + out) == exit_code(ErrorCode::invalid_option));
  CHECK(!std::filesystem::exists(dir.file("x.txt")));
  // The static solver's momentum method runs on gl.
  CHECK(test::run_command(base + " --backend gl --solver static -o " + dir.file("static.txt") + " --report " +
                          dir.file("static.json")) == 0);
  const nlohmann::json statics = read_json(dir.file("static.json"));
  CHECK(statics["compute_backend"] == "gl");
  CHECK(statics["solver"] == "static");
}

TEST_CASE("fascicle settle --backend gl polishes a float32 stall on the CPU (--gpu-polish)", "[gpu][program]") {
  if (!std::filesystem::exists(test::program())) {
    WARN("skipped: " << test::program() << " is not built");
    return;
  }
  // The boundary moved to 1000 times the template's size: every spring pulls with about 1000
  // times stiffness x rest, the measure of the residual, and float32 stops far above 1e-5.
  test::TempDir dir;
  LatticeOptions lattice_options;
  lattice_options.fibres = 36;
  lattice_options.resolution = 8;
  const Lattice lattice = build_lattice(lattice_options);
  const std::string input = dir.file("lattice.txt");
  write_thesis_model(input, to_thesis_model(lattice));
  std::ofstream targets(dir.file("targets.txt"));
  targets.precision(17);
  for (int i = 0; i < lattice.point_count(); ++i)
    if (lattice.system.fixed[i]) {
      const Vec3 p = 1000.0 * (lattice.system.positions[i] - Vec3(0.5, 0.5, 0.5));
      targets << i << " " << 1.2 * p.x() << " " << 0.9 * p.y() << " " << p.z() + 0.1 * p.x() << "\n";
    }
  targets.close();
  const std::string base = test::program() + " --quiet settle " + input + " --targets " + dir.file("targets.txt") +
                           " --solver static --tolerance 1e-5 --max-iterations 20000";
  REQUIRE(test::run_command(base + " --backend gl --gpu-polish false -o " + dir.file("raw.txt") + " --report " +
                            dir.file("raw.json")) == 0);
  const nlohmann::json raw = read_json(dir.file("raw.json"));
  INFO(raw.dump());
  REQUIRE(raw["gpu"]["stalled"] == true);  // the premise
  CHECK(raw["converged"] == false);
  CHECK(raw["gpu"]["polish"] == false);
  CHECK(raw["gpu"]["polished"] == false);
  CHECK(raw["gpu"]["polish_iterations"] == 0);
  CHECK(raw["residual"].get<double>() > 1e-4);
  REQUIRE(test::run_command(base + " --backend gl -o " + dir.file("polished.txt") + " --report " +
                            dir.file("polished.json")) == 0);
  const nlohmann::json polished = read_json(dir.file("polished.json"));
  INFO(polished.dump());
  CHECK(polished["gpu"]["stalled"] == true);
  CHECK(polished["gpu"]["polish"] == true);
  CHECK(polished["gpu"]["polished"] == true);
  CHECK(polished["gpu"]["polish_iterations"].get<int>() > 0);
  CHECK(polished["gpu"]["gpu_residual"].get<double>() > 1e-4);
  CHECK(polished["converged"] == true);
  CHECK(polished["residual"].get<double>() <= 1e-5);
  // The CPU's equilibrium, to the tolerance (the lattice is about 1000 across).
  REQUIRE(test::run_command(base + " --backend cpu -o " + dir.file("cpu.txt")) == 0);
  const ThesisModel cpu = read_thesis_model(dir.file("cpu.txt")), gpu = read_thesis_model(dir.file("polished.txt"));
  REQUIRE(gpu.points.size() == cpu.points.size());
  double difference = 0.0;
  for (std::size_t i = 0; i < gpu.points.size(); ++i)
    difference = std::max(difference, (gpu.points[i] - cpu.points[i]).norm());
  CHECK(difference < 1e-3);
}

#else  // built without OpenGL/EGL/GLEW: the GPU backends are errors with exit code 15

#include "geometry/errors.h"
#include "geometry/thesis_format.h"
#include "springs/lattice.h"
#include "test_common.h"

#include <catch2/catch.hpp>

#include <filesystem>

TEST_CASE("fascicle settle --backend gl fails cleanly in a build without OpenGL", "[gpu][program]") {
  using namespace fascicle;
  if (!std::filesystem::exists(test::program())) {
    WARN("skipped: " << test::program() << " is not built");
    return;
  }
  test::TempDir dir;
  springs::LatticeOptions options;
  options.fibres = 9;
  options.resolution = 4;
  write_thesis_model(dir.file("in.txt"), springs::to_thesis_model(springs::build_lattice(options)));
  const std::string base = test::program() + " --quiet settle " + dir.file("in.txt") + " -o " + dir.file("out.txt");
  CHECK(test::run_command(base + " --backend gl 2>/dev/null") == exit_code(ErrorCode::gpu));
  CHECK(!std::filesystem::exists(dir.file("out.txt")));
  CHECK(test::run_command(base + " --backend auto") == 0);
}

#endif
