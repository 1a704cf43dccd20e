// `fascicle sphere` end to end: output on the sphere, report, landmark errors, the thesis method.
#include "geometry/mesh_io.h"
#include "tests/morph_test_shapes.h"
#include "tests/test_common.h"

#include <catch2/catch.hpp>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <fstream>
#include <sstream>

using namespace fascicle;

namespace {

std::string slurp(const std::string& path) {
  std::ifstream in(path);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

}  // namespace

TEST_CASE("fascicle sphere writes a bijective sphere mesh and a report", "[morph][cli]") {
  test::TempDir dir;
  const TriangleMesh capsule = test::capsule(2.0, 60.0, 16);
  write_triangle_mesh(dir.file("in.off"), capsule);
  const std::string cmd = test::program() + " -q sphere " + dir.file("in.off") + " -o " + dir.file("out.obj") +
                          " --report " + dir.file("r.json");
  REQUIRE(test::run_command(cmd) == 0);
  const PolygonSoup out = read_polygon_soup(dir.file("out.obj"));
  CHECK(out.polygons.size() == capsule.triangles.size());
  for (const Vec3& p : out.points) CHECK(p.norm() == Approx(1.0).epsilon(1e-9));
  const nlohmann::json report = nlohmann::json::parse(slurp(dir.file("r.json")));
  CHECK(report.at("status") == "ok");
  CHECK(report.at("sphere").at("quality").at("flipped") == 0);
  CHECK(report.at("sphere").at("quality").at("degenerate") == 0);
  CHECK(report.at("origin").at("source") == "automatic");
  CHECK(report.at("origin").at("sphere_centre").size() == 3);
  // The template's lattice surface map is aligned to the automatic areas without a flip.
  CHECK(report.at("attachments") == "automatic");
  const nlohmann::json& align = report.at("alignment");
  CHECK(align.at("template").at("kind") == "parallel");
  CHECK(align.at("template").at("sphere_map").at("status") == "ok");
  CHECK(align.at("flipped") == 0);
  CHECK(align.at("flipped_after") == 0);
  CHECK(align.at("degenerate_after") == 0);
  CHECK(align.at("bijective_after") == true);
  CHECK(align.at("origin_error_deg").get<double>() < 1e-6);
  CHECK(align.at("insertion_error_deg").get<double>() <= align.at("insertion_error_rotation_deg").get<double>() + 1e-9);
  CHECK(align.at("insertion_error_deg").get<double>() < 1.0);
}

TEST_CASE("fascicle sphere names the far landmark file and exits with the landmarks code", "[morph][cli]") {
  test::TempDir dir;
  write_triangle_mesh(dir.file("in.off"), test::capsule(1.0, 10.0, 12));
  {
    std::ofstream o(dir.file("o.xyz"));
    o << "# origin\n0 0 10\n0.5 0 9.9\n";
    std::ofstream i(dir.file("far.xyz"));
    i << "0 0 0\n100 0 0\n";
  }
  const std::string cmd = test::program() + " -q sphere " + dir.file("in.off") + " -o " + dir.file("out.off") +
                          " --origin " + dir.file("o.xyz") + " --insertion " + dir.file("far.xyz") + " 2> " +
                          dir.file("err.txt");
  CHECK(test::run_command(cmd) == 16);
  const std::string err = slurp(dir.file("err.txt"));
  CHECK(err.find("far.xyz") != std::string::npos);
  CHECK(err.find("landmark 2") != std::string::npos);
  CHECK(err.find("from the muscle surface") != std::string::npos);
  CHECK(std::count(err.begin(), err.end(), '\n') == 1);  // one line
  CHECK_FALSE(std::ifstream(dir.file("out.off")).good());
  // Only one of the two files: a usage error with its own code.
  CHECK(test::run_command(test::program() + " -q sphere " + dir.file("in.off") + " -o " + dir.file("out.off") +
                          " --origin " + dir.file("o.xyz") + " 2>/dev/null") == 18);
}

TEST_CASE("fascicle sphere --sphere-method relax succeeds or says how it failed", "[morph][cli]") {
  test::TempDir dir;
  write_triangle_mesh(dir.file("round.off"), test::icosphere(2));
  CHECK(test::run_command(test::program() + " -q sphere " + dir.file("round.off") + " -o " + dir.file("a.off") +
                          " --sphere-method relax --report " + dir.file("a.json")) == 0);
  CHECK(nlohmann::json::parse(slurp(dir.file("a.json"))).at("sphere").at("method") == "relax");
  write_triangle_mesh(dir.file("thin.off"), test::capsule(1.0, 100.0, 12));
  const int rc = test::run_command(test::program() + " -q sphere " + dir.file("thin.off") + " -o " + dir.file("b.off") +
                                   " --sphere-method relax --relax-iterations 2000 --report " + dir.file("b.json") +
                                   " 2>/dev/null");
  const nlohmann::json b = nlohmann::json::parse(slurp(dir.file("b.json")));
  if (rc == 0) {
    CHECK(b.at("sphere").at("quality").at("bijective") == true);
  } else {
    CHECK(rc == 14);
    CHECK(b.at("status") == "failed");
    CHECK_FALSE(b.at("sphere").at("failure").get<std::string>().empty());
  }
}

TEST_CASE("fascicle sphere --sphere-start picks the start and reports it", "[morph][cli]") {
  test::TempDir dir;
  write_triangle_mesh(dir.file("in.off"), test::capsule(1.0, 30.0, 12));
  CHECK(test::run_command(test::program() + " -q sphere " + dir.file("in.off") + " -o " + dir.file("a.off") +
                          " --sphere-start progressive --report " + dir.file("a.json")) == 0);
  const nlohmann::json a = nlohmann::json::parse(slurp(dir.file("a.json")));
  CHECK(a.at("status") == "ok");
  CHECK(a.at("sphere").at("initial_map") == "progressive");
  CHECK(a.at("sphere").at("starts_tried") == nlohmann::json::array({"progressive"}));
  CHECK(a.at("sphere").at("quality").at("bijective") == true);
  // The template lattice is mapped from the tube start whatever the muscle's start is.
  CHECK(a.at("alignment").at("template").at("sphere_map").at("initial_map") == "tube");
  CHECK(a.at("alignment").at("insertion_error_deg").get<double>() < 1.0);
  // The default for this long capsule is the tube start.
  CHECK(test::run_command(test::program() + " -q sphere " + dir.file("in.off") + " -o " + dir.file("b.off") +
                          " --report " + dir.file("b.json")) == 0);
  CHECK(nlohmann::json::parse(slurp(dir.file("b.json"))).at("sphere").at("initial_map") == "tube");
  // An unknown start or method is an invalid option (exit 18), and nothing is written.
  CHECK(test::run_command(test::program() + " -q sphere " + dir.file("in.off") + " -o " + dir.file("c.off") +
                          " --sphere-start lambert 2>/dev/null") == 18);
  CHECK(test::run_command(test::program() + " -q sphere " + dir.file("in.off") + " -o " + dir.file("c.off") +
                          " --sphere-method spin 2>/dev/null") == 18);
  CHECK_FALSE(std::ifstream(dir.file("c.off")).good());
}

TEST_CASE("the real far landmark file of the corpus is refused", "[morph][cli][corpus]") {
  FASCICLE_REQUIRE_DATA();
  const std::string lhdl = test::data_dir() + "/muscles/lhdl/";
  test::TempDir dir;
  const std::string cmd = test::program() + " -q sphere " + lhdl + "LHDL_R_M081_GluteusMaximus_smooth.312.vtk -o " +
                          dir.file("out.off") + " --origin " + lhdl + "LHDL_R_M081_GluteusMaximus.origin.xyz" +
                          " --insertion " + lhdl + "LHDL_R_M081_GluteusMaximus.insertion-far.xyz 2> " +
                          dir.file("err.txt");
  CHECK(test::run_command(cmd) == 16);
  const std::string err = slurp(dir.file("err.txt"));
  CHECK(err.find("insertion-far.xyz") != std::string::npos);
  CHECK(err.find("from the muscle surface") != std::string::npos);
  CHECK(std::count(err.begin(), err.end(), '\n') == 1);  // one line
  CHECK_FALSE(std::ifstream(dir.file("out.off")).good());
  // The genuine landmark files are accepted, and the template aligns to their areas.
  CHECK(test::run_command(test::program() + " -q sphere " + lhdl + "LHDL_R_M081_GluteusMaximus_smooth.312.vtk -o " +
                          dir.file("ok.off") + " --origin " + lhdl + "LHDL_R_M081_GluteusMaximus.origin.xyz" +
                          " --insertion " + lhdl + "LHDL_R_M081_GluteusMaximus.insertion.xyz --report " +
                          dir.file("ok.json")) == 0);
  const nlohmann::json report = nlohmann::json::parse(slurp(dir.file("ok.json")));
  CHECK(report.at("attachments") == "landmarks");
  CHECK(report.at("insertion").at("source").get<std::string>().find("insertion.xyz") != std::string::npos);
  const nlohmann::json& align = report.at("alignment");
  CHECK(align.at("flipped_after") == 0);
  CHECK(align.at("bijective_after") == true);
  CHECK(align.at("origin_error_deg").get<double>() < 1e-6);
  CHECK(align.at("insertion_error_deg").get<double>() < align.at("insertion_error_rotation_deg").get<double>());
}
