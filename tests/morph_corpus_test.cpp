// Every corpus muscle, after repair, maps onto the sphere with no flipped and no degenerate
// triangle (the thesis managed 3 of its muscles). On the LHDL psoas and the opendihu left biceps
// the tube start fails (flat slivers near one end that every lift bending lines into latitude
// circles turns over), and they must come out bijective from the progressive-mesh fallback.
#include "geometry/mesh_io.h"
#include "morph/sphere_locator.h"
#include "morph/sphere_map.h"
#include "repair/repair.h"
#include "tests/test_common.h"

#include <catch2/catch.hpp>

#include <set>

using namespace fascicle;

TEST_CASE("corpus muscles map bijectively after repair", "[morph][corpus][slow]") {
  FASCICLE_REQUIRE_DATA();
  const std::set<std::string> tube_failures = {"LHDL_R_M090_Psoas_smooth.415.vtk", "left_biceps_brachii.stl"};
  const std::vector<std::string> files = test::corpus_files("muscles", {"stl", "vtk"});
  CHECK(files.size() == 47);
  int bijective = 0;
  for (const std::string& file : files) {
    INFO(file);
    const std::string name = file.substr(file.rfind('/') + 1);
    const TriangleMesh mesh = repair_mesh(read_polygon_soup(file)).mesh;
    const SphereMap map = map_to_sphere(mesh);
    INFO("failure: " << map.report.failure);
    if (tube_failures.count(name)) {
      CHECK(map.report.initial_map == "progressive");
      CHECK(map.report.starts_tried.size() >= 2);
    }
    CHECK(map.report.status == "ok");
    CHECK(map.report.quality.flipped == 0);
    CHECK(map.report.quality.degenerate == 0);
    CHECK(map.report.quality.area_sum == Approx(4.0 * M_PI).margin(1e-6));
    bijective += map.report.quality.bijective() ? 1 : 0;
    // Vertices are found where they are.
    const SphereLocator locator(map.positions, mesh.triangles);
    for (std::size_t v = 0; v < mesh.positions.size(); v += 97) {
      const SurfacePoint hit = locator.locate(map.positions[v]);
      CHECK((point_on_mesh(mesh, hit) - mesh.positions[v]).norm() < 1e-6 * (1.0 + mesh.positions[v].norm()));
    }
  }
  CHECK(bijective == 47);
  WARN(bijective << " of " << files.size() << " corpus muscles map bijectively");
}
