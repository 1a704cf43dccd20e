// Target files, lattice recognition in thesis-format models, and the `fascicle settle` command.

#include "geometry/errors.h"
#include "geometry/thesis_format.h"
#include "springs/lattice.h"
#include "springs/settle.h"
#include "springs/thesis_settle.h"
#include "test_common.h"

#include <catch2/catch.hpp>
#include <nlohmann/json.hpp>

#include <filesystem>
#include <fstream>

using namespace fascicle;
using namespace fascicle::springs;

namespace {

void write_text(const std::string& path, const std::string& text) {
  std::ofstream out(path);
  out << text;
}

Lattice small_lattice(SpringModel model) {
  LatticeOptions options;
  options.kind = TemplateKind::curved;
  options.fibres = 20;
  options.resolution = 7;
  options.model = model;
  return build_lattice(options);
}

// A targets file (lines "index x y z") moving every fixed point of `lattice` by
// (x, y, z) -> (1.2 x, scale_y y, z + 0.1 x).
void write_moved_targets(const std::string& path, const Lattice& lattice, double scale_y) {
  std::string text;
  for (int i = 0; i < lattice.point_count(); ++i)
    if (lattice.system.fixed[i]) {
      const Vec3 p = lattice.system.positions[i];
      text += std::to_string(i) + " " + std::to_string(1.2 * p.x()) + " " + std::to_string(scale_y * p.y()) + " " +
              std::to_string(p.z() + 0.1 * p.x()) + "\n";
    }
  write_text(path, text);
}

}  // namespace

TEST_CASE("target files: good lines, comments, and one error per problem", "[springs][settle]") {
  test::TempDir dir;
  const std::string good = dir.file("targets.txt");
  write_text(good, "# index x y z\n0 1 2 3\n\n5 -1e-3 0.5 7 # moved\n");
  const auto targets = read_targets(good);
  REQUIRE(targets.size() == 2);
  CHECK(targets[1].index == 5);
  CHECK(targets[1].position == Vec3(-1e-3, 0.5, 7));
  struct Bad {
    const char* text;
    ErrorCode code;
  };
  for (Bad bad : {Bad{"0 1 2\n", ErrorCode::malformed}, Bad{"0 1 2 nan\n", ErrorCode::bad_number},
                  Bad{"-1 1 2 3\n", ErrorCode::bad_number}, Bad{"x 1 2 3\n", ErrorCode::bad_number},
                  Bad{"# nothing\n", ErrorCode::file_empty}, Bad{"0 1 2 1e999\n", ErrorCode::bad_number}}) {
    INFO(bad.text);
    const std::string path = dir.file("bad.txt");
    write_text(path, bad.text);
    try {
      read_targets(path);
      FAIL("no error");
    } catch (const InputError& e) {
      CHECK(e.code() == bad.code);
      CHECK(std::string(e.what()).find(path) != std::string::npos);
    }
  }
  try {
    read_targets(dir.file("missing.txt"));
    FAIL("no error");
  } catch (const InputError& e) { CHECK(e.code() == ErrorCode::file_missing); }
}

TEST_CASE("targets move only fixed points", "[springs][settle]") {
  const Lattice lattice = small_lattice(SpringModel::model6);
  SpringSystem system = lattice.system;
  apply_targets(system, {{0, Vec3(5, 6, 7)}}, "t.txt");
  CHECK(system.positions[0] == Vec3(5, 6, 7));
  const int interior = lattice.index(1, 1, 1);
  CHECK_THROWS_AS(apply_targets(system, {{interior, Vec3::Zero()}}, "t.txt"), InputError);
  CHECK_THROWS_AS(apply_targets(system, {{100000, Vec3::Zero()}}, "t.txt"), InputError);
  CHECK_THROWS_AS(apply_targets(system, {{0, Vec3::Zero()}, {0, Vec3::Zero()}}, "t.txt"), InputError);
}

TEST_CASE("thesis-format lattices are recognised, other spring systems are not", "[springs][settle]") {
  for (SpringModel model : {SpringModel::model6, SpringModel::model26}) {
    const Lattice lattice = small_lattice(model);
    const ThesisModel file = to_thesis_model(lattice);
    const SpringSystem system = spring_system_from_thesis(file, 1.0);
    const auto shape = detect_lattice(file, system, std::nullopt);
    REQUIRE(shape);
    CHECK(shape->nx == lattice.nx);
    CHECK(shape->ny == lattice.ny);
    CHECK(shape->nz == lattice.nz);
    CHECK(shape->model == model);
    const SpringModel other = model == SpringModel::model6 ? SpringModel::model26 : SpringModel::model6;
    CHECK_FALSE(detect_lattice(file, system, other));
    ThesisModel changed = file;
    changed.springs.pop_back();
    CHECK_FALSE(detect_lattice(changed, spring_system_from_thesis(changed, 1.0), std::nullopt));
    const Polylines fibres = model_fibres(file, file.points, shape);
    REQUIRE(fibres.lines.size() == 20);
    CHECK(fibres.lines[0].size() == 7);
    CHECK(model_fibres(file, file.points, std::nullopt).lines[0].size() == 2);
  }
}

TEST_CASE("fascicle settle on a thesis-format lattice", "[springs][settle][program]") {
  if (!std::filesystem::exists(test::program())) {
    WARN("skipped: " << test::program() << " is not built");
    return;
  }
  test::TempDir dir;
  const Lattice lattice = small_lattice(SpringModel::model6);
  const std::string input = dir.file("lattice.txt");
  write_thesis_model(input, to_thesis_model(lattice));
  const std::string targets = dir.file("targets.txt");
  write_moved_targets(targets, lattice, 0.9);
  const std::string output = dir.file("out.txt"), report = dir.file("report.json");
  for (const char* solver : {"verlet", "static", "static --static-method multigrid"}) {
    INFO(solver);
    const std::string command = test::program() + " --quiet settle " + input + " --targets " + targets + " --solver " +
                                solver + " --tolerance 1e-8 -o " + output + " --report " + report;
    REQUIRE(test::run_command(command) == 0);
    std::ifstream in(report);
    const nlohmann::json j = nlohmann::json::parse(in);
    CHECK(j["converged"] == true);
    if (std::string(solver).find("multigrid") != std::string::npos)  // the detected lattice runs it
      CHECK(j["backend"].get<std::string>().rfind("multigrid-", 0) == 0);
    CHECK(j["residual"].get<double>() <= 1e-8);
    CHECK(j["lattice"]["nx"] == lattice.nx);
    const ThesisModel settled = read_thesis_model(output);
    SpringSystem check = spring_system_from_thesis(to_thesis_model(lattice), 1.0);
    CHECK(relative_residual(check, settled.points) <= 1e-8);
    for (int i = 0; i < lattice.point_count(); ++i)
      if (lattice.system.fixed[i])
        CHECK(settled.points[i].x() == Approx(1.2 * lattice.system.positions[i].x()).margin(1e-6));
  }
  // --tolerance 0 runs exactly K iterations; .vtk writes the fibres.
  REQUIRE(test::run_command(test::program() + " --quiet settle " + input + " --targets " + targets +
                            " --tolerance 0 --max-iterations 9 -o " + dir.file("f.vtk") + " --report " + report) == 0);
  std::ifstream in(report);
  CHECK(nlohmann::json::parse(in)["iterations"] == 9);
  CHECK(read_polylines(dir.file("f.vtk")).lines.size() == 20);
  // Errors: a step too large diverges (exit 14), an interior target (exit 10), bad damping (18).
  CHECK(test::run_command(test::program() + " --quiet settle " + input + " --targets " + targets + " --dt 1 -o " +
                          output + " 2>/dev/null") == exit_code(ErrorCode::solver_diverged));
  write_text(dir.file("inner.txt"), std::to_string(lattice.index(1, 1, 1)) + " 0 0 0\n");
  CHECK(test::run_command(test::program() + " --quiet settle " + input + " --targets " + dir.file("inner.txt") +
                          " -o " + output + " 2>/dev/null") == exit_code(ErrorCode::malformed));
  CHECK(test::run_command(test::program() + " --quiet settle " + input + " --damping soft -o " + output +
                          " 2>/dev/null") == exit_code(ErrorCode::invalid_option));
}

TEST_CASE("fascicle settle --coarse-start", "[springs][settle][program]") {
  if (!std::filesystem::exists(test::program())) {
    WARN("skipped: " << test::program() << " is not built");
    return;
  }
  test::TempDir dir;
  LatticeOptions options;
  options.kind = TemplateKind::curved;
  options.fibres = 36;  // 6 x 6 fibres of 9 points: 324 points
  options.resolution = 9;
  options.model = SpringModel::model26;
  const Lattice lattice = build_lattice(options);
  const std::string input = dir.file("lattice.txt");
  write_thesis_model(input, to_thesis_model(lattice));
  write_moved_targets(dir.file("targets.txt"), lattice, 1.1);
  const std::string base = test::program() + " --quiet settle " + input + " --targets " + dir.file("targets.txt") +
                           " --solver static --tolerance 1e-9";
  std::vector<ThesisModel> settled;
  for (int points : {100, 0}) {  // 6 x 6 x 9 = 324 points > 100 -> one coarse lattice of 4 x 4 x 5
    INFO("--coarse-start " << points);
    const std::string out = dir.file("out" + std::to_string(points) + ".txt"), report = dir.file("r.json");
    REQUIRE(test::run_command(base + " --coarse-start " + std::to_string(points) + " -o " + out + " --report " +
                              report) == 0);
    std::ifstream in(report);
    const nlohmann::json j = nlohmann::json::parse(in);
    CHECK(j["converged"] == true);
    CHECK(j["start_levels"] == (points == 0 ? 0 : 1));  // 4 x 4 x 5 has sides below 5: one level
    if (points != 0) CHECK(j["start_iterations"].get<int>() > 0);
    settled.push_back(read_thesis_model(out));
  }
  double largest = 0.0;
  for (std::size_t i = 0; i < settled[0].points.size(); ++i)
    largest = std::max(largest, (settled[0].points[i] - settled[1].points[i]).norm());
  CHECK(largest < 1e-6);
  CHECK(test::run_command(base + " --coarse-start 3 -o " + dir.file("bad.txt") + " 2>/dev/null") ==
        exit_code(ErrorCode::invalid_option));
  CHECK(!std::filesystem::exists(dir.file("bad.txt")));
}
