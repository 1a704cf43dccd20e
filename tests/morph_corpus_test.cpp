// Every corpus muscle, after repair, maps onto the sphere with no flipped and no degenerate
// triangle (the thesis managed 3 of its muscles).
#include "geometry/mesh_io.h"
#include "morph/sphere_locator.h"
#include "morph/sphere_map.h"
#include "repair/repair.h"
#include "tests/test_common.h"

#include <catch2/catch.hpp>

using namespace fascicle;

TEST_CASE("all 47 corpus muscles map bijectively after repair", "[morph][corpus][slow]") {
  FASCICLE_REQUIRE_DATA();
  const std::vector<std::string> files = test::corpus_files("muscles", {"stl", "vtk"});
  CHECK(files.size() == 47);
  for (const std::string& file : files) {
    INFO(file);
    const TriangleMesh mesh = repair_mesh(read_polygon_soup(file)).mesh;
    const SphereMap map = map_to_sphere(mesh);
    INFO("failure: " << map.report.failure);
    CHECK(map.report.quality.flipped == 0);
    CHECK(map.report.quality.degenerate == 0);
    CHECK(map.report.quality.area_sum == Approx(4.0 * M_PI).margin(1e-6));
    // Every vertex is found where it is.
    const SphereLocator locator(map.positions, mesh.triangles);
    for (std::size_t v = 0; v < mesh.positions.size(); v += 97) {
      const SurfacePoint hit = locator.locate(map.positions[v]);
      CHECK((point_on_mesh(mesh, hit) - mesh.positions[v]).norm() < 1e-6 * (1.0 + mesh.positions[v].norm()));
    }
  }
}
