// The promises of the command line about outputs: every output path and format is checked before
// the work, the outputs of a run appear together and only when it succeeds, a batch resumes only
// what was asked for the same way, every decompose option reaches batch, and fibre files convert
// between every fibre format with their lattice arrays.
#include "geometry/errors.h"
#include "geometry/mesh_io.h"
#include "geometry/primitives.h"
#include "tests/test_common.h"

#include <catch2/catch.hpp>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <sstream>

using namespace fascicle;
namespace fs = std::filesystem;

namespace {

// A capsule along z (a long, round muscle) that decomposes in well under a second.
TriangleMesh capsule() {
  TriangleMesh mesh = make_capsule(10.0, 1.5, 24);
  for (Vec3& p : mesh.positions) p = Vec3(p.y(), p.z(), p.x());
  return mesh;
}

int run(const std::string& args) { return test::run_command(test::program() + " -q " + args + " > /dev/null 2>&1"); }

std::vector<std::string> summary_row(const fs::path& summary, const std::string& muscle) {
  std::ifstream in(summary.string());
  for (std::string line; std::getline(in, line);)
    if (line.rfind(muscle + ",", 0) == 0) {
      std::vector<std::string> fields;
      std::stringstream row(line);
      for (std::string field; std::getline(row, field, ',');) fields.push_back(field);
      return fields;
    }
  return {};
}

nlohmann::json read_json(const fs::path& path) {
  std::ifstream in(path.string());
  return nlohmann::json::parse(in);
}

}  // namespace

TEST_CASE("decompose checks every output before the work and leaves no file of a failed run", "[app][outputs]") {
  test::TempDir dir;
  const std::string muscle = dir.file("capsule.off");
  write_triangle_mesh(muscle, capsule());
  // The input is never read when an output is bad: a file that is no mesh gives the output's
  // error, not the reader's (5 would be the reader's unknown format, 10 malformed).
  const std::string bogus = dir.file("bogus.off");
  std::ofstream(bogus) << "OFF\nthis is not a mesh\n";
  CHECK(run("decompose " + bogus + " -o " + dir.file("missing/f.vtk")) == 11);
  CHECK(run("decompose " + bogus + " -o " + dir.file("f.xyz")) == 5);
  CHECK(run("decompose " + bogus + " -o " + dir.path().string()) == 11);  // a folder
  CHECK(run("decompose " + bogus + " -o " + dir.file("f.vtk") + " --report " + dir.file("missing/r.json")) == 11);
  CHECK(run("decompose " + bogus + " -o " + dir.file("f.vtk") + " --write-repaired " + dir.file("m.xyz")) == 5);
  CHECK(run("decompose " + bogus + " -o " + dir.file("f.vtk") + " --fe-mesh " + dir.file("t.vtk")) == 5);
  CHECK(run("decompose " + bogus + " -o " + dir.file("f.vtk") + " --fe-mesh " + dir.file("t.vtu") + " --fe-cells 5") ==
        18);
  // A bad fibre extension with a good repaired-mesh path: neither file appears.
  CHECK(run("decompose " + muscle + " -o " + dir.file("f.xyz") + " --write-repaired " + dir.file("m.off")) == 5);
  CHECK_FALSE(fs::exists(dir.file("m.off")));
  CHECK(run("decompose " + muscle + " -o " + dir.file("missing/f.vtk") + " --write-repaired " + dir.file("m.off")) ==
        11);
  CHECK_FALSE(fs::exists(dir.file("m.off")));
  // --check-options says whether the options and outputs are good without reading the input.
  CHECK(run("decompose " + bogus + " -o " + dir.file("f.vtk") + " --check-options") == 0);
  CHECK(run("decompose " + bogus + " -o " + dir.file("f.vtk") + " --check-options --fibres 0") == 18);
  CHECK_FALSE(fs::exists(dir.file("f.vtk")));
  // A run that succeeds writes all its outputs, and nothing temporary remains.
  REQUIRE(run("decompose " + muscle + " -o " + dir.file("f.vtu") + " --write-repaired " + dir.file("m.ply") +
              " --report " + dir.file("r.json") + " --fe-mesh " + dir.file("t.vtu") + " --fe-cells 2000") == 0);
  CHECK(read_polylines(dir.file("f.vtu")).lines.size() == 100);
  CHECK(fs::exists(dir.file("m.ply")));
  const nlohmann::json report = read_json(dir.file("r.json"));
  CHECK(report["status"] == "ok");
  CHECK(report["fe_mesh"]["tets"].get<long>() > 1000);
  CHECK(fs::file_size(dir.file("t.vtu")) > 0);
  for (const auto& e : fs::directory_iterator(dir.path()))
    CHECK(e.path().filename().string().find(".tmp.") == std::string::npos);
}

TEST_CASE("fibre files convert between every fibre format and keep their lattice arrays", "[app][outputs]") {
  test::TempDir dir;
  const std::string muscle = dir.file("capsule.off");
  write_triangle_mesh(muscle, capsule());
  REQUIRE(run("decompose " + muscle + " -o " + dir.file("f.vtk") + " --fibres 36 --resolution 7") == 0);
  const Polylines original = read_polylines(dir.file("f.vtk"));
  REQUIRE(original.cell_data.size() == 2);
  std::string from = dir.file("f.vtk");
  for (const char* ext : {"vtu", "vtp", "csv", "vtk"}) {
    CAPTURE(ext);
    const std::string to = dir.file(std::string("g.") + ext);
    REQUIRE(run("convert " + from + " -o " + to) == 0);
    const Polylines back = read_polylines(to);
    CHECK(back.lines == original.lines);
    REQUIRE(back.cell_data.size() == 2);
    CHECK(back.cell_data[0].name == "fibre_r");
    CHECK(back.cell_data[0].values == original.cell_data[0].values);
    CHECK(back.cell_data[1].values == original.cell_data[1].values);
    from = to;
  }
  // Fibres to .obj keep the lines; fibres cannot become a mesh, nor a mesh fibres.
  REQUIRE(run("convert " + from + " -o " + dir.file("g.obj")) == 0);
  CHECK(read_polylines(dir.file("g.obj")).lines == original.lines);
  CHECK(run("convert " + from + " -o " + dir.file("g.off")) == 5);
  CHECK(run("convert " + muscle + " -o " + dir.file("m.csv")) == 5);
  REQUIRE(run("convert " + muscle + " -o " + dir.file("m.vtk")) == 0);
  CHECK(read_polygon_soup(dir.file("m.vtk")).polygons.size() == capsule().triangles.size());
}

TEST_CASE("batch resumes only what was asked for the same way, and takes every decompose option",
          "[app][outputs][batch]") {
  test::TempDir dir;
  const fs::path in = dir.path() / "in";
  fs::create_directories(in);
  write_triangle_mesh((in / "a.off").string(), capsule());
  write_triangle_mesh((in / "b.off").string(), capsule());
  std::ofstream((in / "broken.off").string()) << "not a mesh\n";
  const fs::path out = dir.path() / "out";
  const std::string batch = "batch " + in.string() + " -o " + out.string() + " --jobs 2";
  // A failed muscle that is not the quality check's: the batch exits with its code (5), not 19.
  CHECK(run(batch) == 5);
  const auto first = summary_row(out / "summary.csv", "a");
  REQUIRE(first.size() >= 4);
  CHECK(first[1] == "ok");
  CHECK(first[3].find('.') != std::string::npos);
  CHECK(first[3].size() - first[3].find('.') == 4);  // seconds to the millisecond
  CHECK(read_polylines((out / "a.vtk").string()).lines.size() == 100);
  // The same request again: nothing is redone; skipped rows keep their exit code and seconds.
  const auto stamp = fs::last_write_time(out / "a.vtk");
  CHECK(run(batch) == 5);
  CHECK(fs::last_write_time(out / "a.vtk") == stamp);
  const auto again = summary_row(out / "summary.csv", "a");
  CHECK(again == first);
  const auto broken = summary_row(out / "summary.csv", "broken");
  REQUIRE(broken.size() >= 3);
  CHECK(broken[1] == "failed");
  CHECK(broken[2] == "5");
  // Other options or another format redo the muscles: the new files are there.
  CHECK(run(batch + " --fibres 36") == 5);
  CHECK(read_polylines((out / "a.vtk").string()).lines.size() == 36);
  CHECK(run(batch + " --fibres 36 --format csv") == 5);
  CHECK(read_polylines((out / "b.csv").string()).lines.size() == 36);
  CHECK(read_json(out / "b.report.json")["batch"]["exit_code"] == 0);
  // A bad option value is one error before any muscle, and the results stay as they were.
  const auto csv_stamp = fs::last_write_time(out / "b.csv");
  CHECK(run(batch + " --fibres 0 --format csv") == 18);
  CHECK(fs::last_write_time(out / "b.csv") == csv_stamp);
  CHECK(read_json(out / "b.report.json")["status"] == "ok");
  // --retry-failed redoes the failed muscle only (it fails again the same way).
  CHECK(run(batch + " --fibres 36 --format csv --retry-failed") == 5);
  CHECK(fs::last_write_time(out / "b.csv") == csv_stamp);
  // A decompose option batch did not take before (every one is passed through now).
  const fs::path out2 = dir.path() / "out2";
  CHECK(run("batch " + (in / "a.off").string() + " -o " + out2.string() +
            " --untangle false --sphere-method tutte "
            "--max-landmark-distance 0.3 --second-try false") == 0);
  CHECK(read_polylines((out2 / "a.vtk").string()).lines.size() == 100);
}

TEST_CASE("help, suggestions, global options anywhere, errors that name the option, quality levels", "[app][cli]") {
  test::TempDir dir;
  const std::string muscle = dir.file("capsule.off");
  write_triangle_mesh(muscle, capsule());
  const auto output_of = [&](const std::string& args) {
    const std::string out = dir.file("out.txt");
    test::run_command(test::program() + " " + args + " > " + out + " 2>&1");
    std::ifstream in(out);
    std::stringstream text;
    text << in.rdbuf();
    return text.str();
  };
  // --help shows the main options in groups and points at --help-all for the rest.
  const std::string help = output_of("decompose --help");
  CHECK(help.find("Inputs and outputs:") != std::string::npos);
  CHECK(help.find("--quality") != std::string::npos);
  CHECK(help.find("--untangle-keep-best") == std::string::npos);
  CHECK(help.find("--help-all") != std::string::npos);
  CHECK(std::count(help.begin(), help.end(), '\n') < 50);
  CHECK(output_of("decompose --help-all").find("--untangle-keep-best") != std::string::npos);
  // A mistyped option: usage error and the nearest option.
  CHECK(run("decompose " + muscle + " -o " + dir.file("f.vtk") + " --fibers 36") == 2);
  CHECK(output_of("decompose " + muscle + " -o " + dir.file("f.vtk") + " --fibers 36").find("did you mean --fibres?") !=
        std::string::npos);
  // Global options after the command.
  CHECK(output_of("decompose " + muscle + " -o " + dir.file("f.vtk") + " -q").empty());
  // An option error names the option, not the field.
  CHECK(output_of("decompose " + muscle + " -o " + dir.file("f.vtk") + " --end-fraction 0.9").find("--end-fraction") !=
        std::string::npos);
  CHECK(output_of("decompose " + muscle + " -o " + dir.file("f.vtk") + " --fibres 3").find("--fibres:") !=
        std::string::npos);
  // Quality levels set the fibre count and resolution, explicit values win.
  REQUIRE(run("decompose " + muscle + " -o " + dir.file("d.vtk") + " --quality draft") == 0);
  const Polylines draft = read_polylines(dir.file("d.vtk"));
  CHECK(draft.lines.size() == 36);
  CHECK(draft.lines.front().size() == 9);
  REQUIRE(run("decompose " + muscle + " -o " + dir.file("e.vtk") + " --quality draft --fibres 49 --resolution 11") ==
          0);
  const Polylines explicit_values = read_polylines(dir.file("e.vtk"));
  CHECK(explicit_values.lines.size() == 49);
  CHECK(explicit_values.lines.front().size() == 11);
  CHECK(run("decompose " + muscle + " -o " + dir.file("e.vtk") + " --quality best") == 2);
}

TEST_CASE("architecture from check, decompose and batch, and an OpenSim table over a batch", "[app][architecture]") {
  test::TempDir dir;
  const fs::path in = dir.path() / "in";
  fs::create_directories(in);
  write_triangle_mesh((in / "a.off").string(), capsule());
  const std::string muscle = (in / "a.off").string();
  REQUIRE(run("decompose " + muscle + " -o " + dir.file("f.vtk") + " --architecture " + dir.file("a.json") +
              " --report " + dir.file("r.json")) == 0);
  const nlohmann::json arch = read_json(dir.file("a.json"));
  // The capsule's fibres run along it: pennation near 0, fibres about as long as the muscle.
  CHECK(arch.at("pennation_deg").at("mean").get<double>() < 5.0);
  CHECK(arch.at("fibre_to_muscle_length").get<double>() > 0.8);
  CHECK(arch.at("fibre_to_muscle_length").get<double>() < 1.2);
  CHECK(read_json(dir.file("r.json")).at("architecture") == arch);
  // check measures the same fibres the same way; --length-unit m scales the lengths.
  REQUIRE(run("check " + dir.file("f.vtk") + " " + muscle + " --architecture " + dir.file("b.csv")) == 0);
  CHECK(test::read_text(dir.file("b.csv")).rfind("fibres,volume_m3,", 0) == 0);
  REQUIRE(run("check " + dir.file("f.vtk") + " " + muscle + " --architecture " + dir.file("m.json") +
              " --length-unit m") == 0);
  CHECK(read_json(dir.file("m.json")).at("muscle_length_m").get<double>() ==
        Approx(1000.0 * arch.at("muscle_length_m").get<double>()));
  CHECK(run("check " + dir.file("f.vtk") + " " + muscle + " --architecture " + dir.file("a.txt")) == 5);
  // A batch: the summary's architecture columns and opensim.csv in metres, radians and newtons.
  const fs::path out = dir.path() / "out";
  REQUIRE(run("batch " + in.string() + " -o " + out.string()) == 0);
  const auto row = summary_row(out / "summary.csv", "a");
  REQUIRE(row.size() >= 15);
  CHECK(std::stod(row[11]) == Approx(arch.at("fibre_length_m").at("mean").get<double>()));
  const std::string opensim = test::read_text((out / "opensim.csv").string());
  CHECK(opensim.rfind("muscle,optimal_fiber_length,pennation_angle_at_optimal,max_isometric_force\na,", 0) == 0);
}
