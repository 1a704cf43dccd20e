// Tetrahedra of a closed surface (repair/tetrahedralize.h) and the fibre direction per tetrahedron
// (fibres/fibre_field.h): positive, filling the volume, the size asked for, and the direction of
// the nearest fibre.
#include "fibres/fibre_field.h"
#include "geometry/errors.h"
#include "geometry/mesh_stats.h"
#include "geometry/primitives.h"
#include "repair/tetrahedralize.h"

#include <catch2/catch.hpp>

#include <cmath>

using namespace fascicle;

namespace {

double tet_volume(const TetMesh& mesh, const Tetrahedron& t) {
  const Vec3& a = mesh.positions[static_cast<std::size_t>(t[0])];
  return (mesh.positions[static_cast<std::size_t>(t[1])] - a)
             .cross(mesh.positions[static_cast<std::size_t>(t[2])] - a)
             .dot(mesh.positions[static_cast<std::size_t>(t[3])] - a) /
         6.0;
}

}  // namespace

TEST_CASE("tetrahedralize: a capsule fills with positive tetrahedra of the size asked for", "[repair]") {
  const TriangleMesh capsule = make_capsule(4.0, 1.0, 24);
  const double volume = signed_volume(capsule);
  REQUIRE(volume > 0.0);
  TetrahedralizeReport report;
  const TetMesh tets = tetrahedralize(capsule, sized_tetrahedra(volume, 3000), &report);
  REQUIRE(report.tets == static_cast<long>(tets.tets.size()));
  REQUIRE(report.vertices == static_cast<long>(tets.positions.size()));
  // Within a factor 2 of the count asked for: the refinement's sizes are bounds, not targets.
  CHECK(report.tets > 1500);
  CHECK(report.tets < 6000);
  double total = 0.0;
  long inverted = 0;
  for (const Tetrahedron& t : tets.tets) {
    const double v = tet_volume(tets, t);
    total += v;
    inverted += v <= 0.0;
  }
  CHECK(inverted == 0);
  // The facets stay within a sixth of an edge of the surface: the volume within 3 %.
  CHECK(std::abs(total - volume) < 0.03 * volume);
  CHECK(report.boundary_vertices > 0);
  CHECK(report.boundary_vertices < report.vertices);
  // Same surface and options, same mesh (sequential, no random stages).
  const TetMesh again = tetrahedralize(capsule, sized_tetrahedra(volume, 3000));
  CHECK(again.tets == tets.tets);
}

TEST_CASE("tetrahedralize: bad sizes and an open surface are refused", "[repair]") {
  CHECK_THROWS_AS(sized_tetrahedra(0.0, 100), OptionError);
  CHECK_THROWS_AS(sized_tetrahedra(1.0, 0), OptionError);
  TetrahedralizeOptions options;
  options.facet_angle_deg = 40.0;
  CHECK_THROWS_AS(options.validate(), OptionError);
  TriangleMesh open = make_icosphere(2);
  open.triangles.pop_back();
  CHECK_THROWS_AS(tetrahedralize(open, TetrahedralizeOptions{}), TopologyError);
}

TEST_CASE("fibre field: each tetrahedron takes the direction of its nearest fibre", "[fibres]") {
  const TriangleMesh capsule = make_capsule(4.0, 1.0, 24);
  const TetMesh tets = tetrahedralize(capsule, sized_tetrahedra(signed_volume(capsule), 2000));
  // Fibres along the capsule's axis on the half z < 0 and across it (along y) on z > 0.
  Polylines fibres;
  for (int i = -2; i <= 2; ++i) {
    std::vector<Vec3> along, across;
    for (int k = 0; k <= 10; ++k) {
      const double u = -1.0 + 0.2 * k;
      along.push_back(Vec3(2.5 * u, 0.3 * i, -0.5));
      across.push_back(Vec3(0.8 * i, 0.9 * u, 0.5));
    }
    fibres.lines.push_back(along);
    fibres.lines.push_back(across);
  }
  const Vec3 axis = Vec3::UnitX();
  const std::vector<Vec3> directions = cell_fibre_directions(tets, fibres);
  REQUIRE(directions.size() == tets.tets.size());
  long low = 0, high = 0, low_along = 0, high_across = 0;
  for (std::size_t t = 0; t < tets.tets.size(); ++t) {
    CHECK(std::abs(directions[t].norm() - 1.0) < 1e-12);
    double z = 0.0;
    for (int v : tets.tets[t]) z += 0.25 * tets.positions[static_cast<std::size_t>(v)].z();
    if (z < -0.2) {
      ++low;
      low_along += std::abs(directions[t].dot(axis)) > 0.999;
    } else if (z > 0.2) {
      ++high;
      high_across += std::abs(directions[t].y()) > 0.999;
    }
  }
  REQUIRE(low > 0);
  REQUIRE(high > 0);
  CHECK(low_along == low);
  CHECK(high_across == high);
  CHECK_THROWS_AS(cell_fibre_directions(tets, Polylines{}), InputError);
}
