// The command line as a user meets it: one test per error exit code of `fascicle repair`
// (and `convert`), each checking the code, a one-line message and that no output appears.

#include "geometry/errors.h"
#include "geometry/mesh_io.h"
#include "geometry/primitives.h"
#include "test_common.h"

#include <catch2/catch.hpp>
#include <nlohmann/json.hpp>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <tuple>
#include <vector>

using namespace fascicle;
namespace fs = std::filesystem;

namespace {

struct Run {
  int code;
  std::string err;
};

Run run(const test::TempDir& dir, const std::string& args) {
  const std::string err = dir.file("stderr.txt");
  const int code = test::run_command("'" + test::program() + "' " + args + " 2>'" + err + "' >/dev/null");
  std::ifstream in(err);
  std::stringstream ss;
  ss << in.rdbuf();
  return {code, ss.str()};
}

void write_text(const std::string& path, const std::string& text) { std::ofstream(path, std::ios::binary) << text; }

// Expects the exit code, a single "fascicle: error:" line mentioning `needle`, and no output.
void expect_failure(const test::TempDir& dir, const std::string& input, ErrorCode code, const std::string& needle,
                    const std::string& extra = "") {
  const std::string out = dir.file("out.off");
  const Run r = run(dir, "--quiet repair '" + input + "' -o '" + out + "'" + extra);
  INFO("stderr: " << r.err);
  CHECK(r.code == exit_code(code));
  CHECK(r.err.rfind("fascicle: error: ", 0) == 0);
  CHECK(std::count(r.err.begin(), r.err.end(), '\n') == 1);
  CHECK(r.err.find(needle) != std::string::npos);
  CHECK_FALSE(fs::exists(out));
}

}  // namespace

TEST_CASE("repair exit codes: one per kind of bad input", "[app]") {
  test::TempDir dir;
  SECTION("missing file -> 3") { expect_failure(dir, dir.file("nope.off"), ErrorCode::file_missing, "nope.off"); }
  SECTION("empty file -> 4") {
    write_text(dir.file("empty.off"), "");
    expect_failure(dir, dir.file("empty.off"), ErrorCode::file_empty, "empty.off");
  }
  SECTION("unknown format -> 5") {
    write_text(dir.file("mesh.xyz3"), "hello");
    expect_failure(dir, dir.file("mesh.xyz3"), ErrorCode::unknown_format, "mesh.xyz3");
  }
  SECTION("truncated binary STL -> 6") {
    std::string stl(80, ' ');
    const std::uint32_t n = 10;
    stl.append(reinterpret_cast<const char*>(&n), 4);
    stl.append(50 * 3, '\0');
    write_text(dir.file("short.stl"), stl);
    expect_failure(dir, dir.file("short.stl"), ErrorCode::truncated, "short.stl");
  }
  SECTION("index out of range -> 7") {
    write_text(dir.file("bad.off"), "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n");
    expect_failure(dir, dir.file("bad.off"), ErrorCode::index_out_of_range, "line 6");
  }
  SECTION("NaN coordinate -> 8") {
    write_text(dir.file("nan.off"), "OFF\n3 1 0\n0 0 0\nnan 0 0\n0 1 0\n3 0 1 2\n");
    expect_failure(dir, dir.file("nan.off"), ErrorCode::bad_number, "line 4");
  }
  SECTION("absurd declared count -> 9") {
    write_text(dir.file("huge.off"), "OFF\n1000000000000 1 0\n0 0 0\n");
    expect_failure(dir, dir.file("huge.off"), ErrorCode::too_large, "huge.off");
  }
  SECTION("malformed text -> 10") {
    write_text(dir.file("junk.off"), "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 two\n");
    expect_failure(dir, dir.file("junk.off"), ErrorCode::malformed, "junk.off");
  }
  SECTION("unrepairable mesh -> 12, and the report says failed") {
    write_triangle_mesh(dir.file("torus.off"), make_torus(1.0, 0.2, 32, 12));
    expect_failure(dir, dir.file("torus.off"), ErrorCode::repair_failed, "genus",
                   " --report '" + dir.file("r.json") + "'");
    std::ifstream in(dir.file("r.json"));
    const nlohmann::json j = nlohmann::json::parse(in);
    CHECK(j["status"] == "failed");
    CHECK(j["error_code"] == "repair_failed");
  }
  SECTION("option out of range -> 18") {
    write_triangle_mesh(dir.file("ball.off"), make_icosphere(2));
    expect_failure(dir, dir.file("ball.off"), ErrorCode::invalid_option, "--weld-tolerance = 5", " --weld-tolerance 5");
  }
}

TEST_CASE("repair exit codes: command line, output and time limit", "[app]") {
  test::TempDir dir;
  write_triangle_mesh(dir.file("ball.off"), make_icosphere(2));
  SECTION("bad command line -> 2") {
    const Run r = run(dir, "repair '" + dir.file("ball.off") + "'");  // no -o
    CHECK(r.code == exit_code(ErrorCode::usage));
  }
  SECTION("output folder missing -> 11") {
    const Run r = run(dir, "repair '" + dir.file("ball.off") + "' -o '" + dir.file("no/such/out.off") + "'");
    CHECK(r.code == exit_code(ErrorCode::output_failed));
    CHECK(r.err.find("does not exist") != std::string::npos);
  }
  SECTION("output over the input -> 11, input untouched") {
    const auto before = fs::file_size(dir.file("ball.off"));
    const Run r = run(dir, "repair '" + dir.file("ball.off") + "' -o '" + dir.file("ball.off") + "'");
    CHECK(r.code == exit_code(ErrorCode::output_failed));
    CHECK(fs::file_size(dir.file("ball.off")) == before);
  }
  SECTION("time limit -> 17, no output") {
    // A 1.2 M-triangle sample with defects takes several seconds to repair.
    REQUIRE(run(dir, "sample --rings 1500 --segments 400 -o '" + dir.file("big.ply") + "'").code == 0);
    const Run r = run(dir, "--time-limit 1 repair '" + dir.file("big.ply") + "' -o '" + dir.file("out.off") + "'");
    CHECK(r.code == exit_code(ErrorCode::time_limit));
    CHECK_FALSE(fs::exists(dir.file("out.off")));
  }
  SECTION("an existing output is replaced only on success") {
    write_text(dir.file("keep.off"), "old content");
    write_text(dir.file("bad.off"), "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n");
    run(dir, "repair '" + dir.file("bad.off") + "' -o '" + dir.file("keep.off") + "'");
    std::ifstream in(dir.file("keep.off"));
    std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    CHECK(text == "old content");
  }
}

// repair, sphere and decompose share one "report on error" (app/report_file.h): each must leave a
// report that says failed, with the message and the code's name, and no output.
TEST_CASE("a failed repair, sphere or decompose still writes its report", "[app]") {
  test::TempDir dir;
  const std::string input = dir.file("torus.off");
  write_triangle_mesh(input, make_torus(1.0, 0.2, 32, 12));
  for (const char* command : {"repair", "sphere", "decompose"}) {
    INFO(command);
    const std::string out = dir.file(std::string(command) + "-out.vtk");  // a mesh or polylines
    const std::string report = dir.file(std::string(command) + ".json");
    const Run r =
        run(dir, std::string("--quiet ") + command + " '" + input + "' -o '" + out + "' --report '" + report + "'");
    INFO("stderr: " << r.err);
    CHECK(r.code == exit_code(ErrorCode::repair_failed));
    CHECK_FALSE(fs::exists(out));
    REQUIRE(fs::exists(report));
    std::ifstream in(report);
    const nlohmann::json j = nlohmann::json::parse(in);
    CHECK(j.at("status") == "failed");
    CHECK(j.at("error_code") == "repair_failed");
    CHECK(j.at("input_file") == input);
    CHECK(j.at("error").get<std::string>().find("genus") != std::string::npos);
    CHECK(r.err.find(j.at("error").get<std::string>()) != std::string::npos);
  }
}

TEST_CASE("repair and convert succeed on good input with a complete report", "[app]") {
  test::TempDir dir;
  REQUIRE(run(dir, "sample -o '" + dir.file("sample.stl") + "'").code == 0);
  const Run r = run(dir, "repair '" + dir.file("sample.stl") + "' -o '" + dir.file("fixed.vtk") + "' --report '" +
                             dir.file("r.json") + "'");
  INFO(r.err);
  REQUIRE(r.code == 0);
  const PolygonSoup fixed = read_polygon_soup(dir.file("fixed.vtk"));
  CHECK(fixed.polygons.size() > 1000);
  std::ifstream in(dir.file("r.json"));
  const nlohmann::json j = nlohmann::json::parse(in);
  CHECK(j["status"] == "repaired");
  CHECK(j["output"]["genus"] == 0);
  CHECK(j["input"]["boundary_edges"].get<long>() > 0);
  for (const char* ext : {"off", "obj", "ply", "stl", "vtk"}) {
    const std::string out = dir.file(std::string("copy.") + ext);
    CHECK(run(dir, "convert '" + dir.file("fixed.vtk") + "' -o '" + out + "'").code == 0);
    CHECK(read_polygon_soup(out).polygons.size() == fixed.polygons.size());
  }
}

TEST_CASE("decompose --muscle takes its preset's template and pennation, explicit options win", "[app]") {
  test::TempDir dir;
  REQUIRE(run(dir, "sample --kind muscle --clean -o '" + dir.file("muscle.off") + "'").code == 0);
  const std::string input = "--quiet decompose '" + dir.file("muscle.off") + "' -o '" + dir.file("f.vtk") + "'";
  // An unknown name: one line naming the presets, the option error's exit code, no output.
  const Run bad = run(dir, input + " --muscle vastus_lateral");
  CHECK(bad.code == exit_code(ErrorCode::invalid_option));
  CHECK(std::count(bad.err.begin(), bad.err.end(), '\n') == 1);
  CHECK(bad.err.find("vastus_lateralis") != std::string::npos);
  CHECK_FALSE(fs::exists(dir.file("f.vtk")));
  const auto report_of = [&](const std::string& extra) {
    const Run r = run(dir, input + " --report '" + dir.file("r.json") + "' " + extra);
    INFO(r.err);
    REQUIRE(r.code == 0);
    std::ifstream in(dir.file("r.json"));
    return nlohmann::json::parse(in);
  };
  const nlohmann::json preset = report_of("--muscle vastus_lateralis");
  CHECK(preset.at("muscle").at("name") == "vastus_lateralis");
  CHECK(preset.at("lattice").at("template") == "unipennate");
  CHECK(preset.at("pennate").at("target_deg") == 18.4);
  const nlohmann::json given = report_of("--muscle vastus_lateralis --template bipennate --pennation 25");
  CHECK(given.at("lattice").at("template") == "bipennate");
  CHECK(given.at("pennate").at("target_deg") == 25.0);
  CHECK(given.at("muscle").at("pennation_deg") == 25.0);
}

TEST_CASE("decompose and its bench take the edge cells' width", "[app]") {
  test::TempDir dir;
  REQUIRE(run(dir, "sample --kind capsule -o '" + dir.file("capsule.off") + "'").code == 0);
  // Out of (0, 1]: a one-line option error, its exit code, no output.
  for (const char* bad : {"0", "1.5"}) {
    INFO(bad);
    const Run r = run(
        dir, "--quiet decompose '" + dir.file("capsule.off") + "' -o '" + dir.file("bad.vtk") + "' --edge-cell " + bad);
    CHECK(r.code == exit_code(ErrorCode::invalid_option));
    CHECK(std::count(r.err.begin(), r.err.end(), '\n') == 1);
    CHECK(r.err.find("edge") != std::string::npos);
    CHECK_FALSE(fs::exists(dir.file("bad.vtk")));
  }
  const Run ok = run(dir, "--quiet decompose '" + dir.file("capsule.off") + "' -o '" + dir.file("f.vtk") +
                              "' --edge-cell 0.5 --report '" + dir.file("r.json") + "'");
  INFO(ok.err);
  REQUIRE(ok.code == 0);
  std::ifstream in(dir.file("r.json"));
  const nlohmann::json j = nlohmann::json::parse(in);
  CHECK(j.at("attempts").at(0).at("edge_cell") == 0.5);
  // The batch passes it on to every muscle.
  fs::create_directories(dir.file("in"));
  fs::copy_file(dir.file("capsule.off"), dir.file("in/capsule.off"));
  const Run batch =
      run(dir, "--quiet batch '" + dir.file("in") + "' -o '" + dir.file("out") + "' --jobs 1 --edge-cell 0.5");
  INFO(batch.err);
  REQUIRE(batch.code == 0);
  std::ifstream bin_report(dir.file("out/capsule.report.json"));
  REQUIRE(bin_report.good());
  CHECK(nlohmann::json::parse(bin_report).at("attempts").at(0).at("edge_cell") == 0.5);

  FASCICLE_REQUIRE_DATA();
  const Run bench =
      run(dir, "bench decompose --data '" + test::data_dir() +
                   "' --repeat 1 --skip-templates --skip-corpus --edge-cell 0.5 --json '" + dir.file("b.json") + "'");
  INFO(bench.err);
  REQUIRE(bench.code == 0);
  std::ifstream bin(dir.file("b.json"));
  const nlohmann::json b = nlohmann::json::parse(bin);
  CHECK(b.at("speed").at(0).at("edge_cell") == 0.5);
  CHECK(b.at("speed").at(0).at("quality").at("pass") == true);
}

TEST_CASE("decompose --tuning sets any setting from a JSON file, the command line wins, a report repeats its run",
          "[app]") {
  test::TempDir dir;
  REQUIRE(run(dir, "sample --kind capsule -o '" + dir.file("capsule.off") + "'").code == 0);
  const std::string input = "--quiet decompose '" + dir.file("capsule.off") + "' -o '" + dir.file("f.vtk") + "'";
  // Bad files: one line, the exit code of their kind, no output.
  write_text(dir.file("typo.json"), R"({"placement": {"max_face_deph": 0.2}})");
  write_text(dir.file("broken.json"), R"({"fibres": )");
  write_text(dir.file("range.json"), R"({"fibres": 2})");
  for (const auto& [file, code, needle] :
       std::vector<std::tuple<std::string, ErrorCode, std::string>>{
           {"typo.json", ErrorCode::invalid_option, "placement.max_face_deph is not a setting"},
           {"broken.json", ErrorCode::malformed, "not JSON"},
           {"range.json", ErrorCode::invalid_option, "fibres"},
           {"absent.json", ErrorCode::file_missing, "absent.json"}}) {
    INFO(file);
    const Run r = run(dir, input + " --tuning '" + dir.file(file) + "'");
    CHECK(r.code == exit_code(code));
    CHECK(std::count(r.err.begin(), r.err.end(), '\n') == 1);
    CHECK(r.err.find(needle) != std::string::npos);
    CHECK_FALSE(fs::exists(dir.file("f.vtk")));
  }
  const auto report_of = [&](const std::string& extra, const std::string& fibres) {
    const Run r = run(dir, "--quiet decompose '" + dir.file("capsule.off") + "' -o '" + dir.file(fibres) +
                               "' --report '" + dir.file("r.json") + "' " + extra);
    INFO(r.err);
    REQUIRE(r.code == 0);
    std::ifstream in(dir.file("r.json"));
    return nlohmann::json::parse(in);
  };
  write_text(dir.file("t.json"), R"({"fibres": 36, "resolution": 9, "placement": {"max_face_depth": 0.2}})");
  const nlohmann::json tuned = report_of("--tuning '" + dir.file("t.json") + "'", "a.vtk");
  CHECK(tuned.at("options").at("fibres") == 36);
  CHECK(tuned.at("options").at("resolution") == 9);
  CHECK(tuned.at("options").at("placement").at("max_face_depth") == 0.2);
  CHECK(tuned.at("lattice").at("fibres") == 36);
  CHECK(tuned.at("attempts").at(0).at("max_face_depth") == 0.2);
  const nlohmann::json both = report_of("--tuning '" + dir.file("t.json") + "' --fibres 49", "b.vtk");
  CHECK(both.at("options").at("fibres") == 49);
  CHECK(both.at("options").at("resolution") == 9);
  // The report's options as a tuning file repeat the run, byte for byte.
  std::ofstream(dir.file("again.json")) << both.at("options").dump();
  report_of("--tuning '" + dir.file("again.json") + "'", "c.vtk");
  std::ifstream b(dir.file("b.vtk"), std::ios::binary), c(dir.file("c.vtk"), std::ios::binary);
  const std::string bytes_b((std::istreambuf_iterator<char>(b)), std::istreambuf_iterator<char>());
  const std::string bytes_c((std::istreambuf_iterator<char>(c)), std::istreambuf_iterator<char>());
  CHECK(!bytes_b.empty());
  CHECK(bytes_b == bytes_c);
}
