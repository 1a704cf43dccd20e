// Fibre templates and lattices: geometry of the five families, lattice counts, springs,
// masses, surface, thesis-format conversion.

#include "geometry/errors.h"
#include "springs/fibre_template.h"
#include "springs/lattice.h"
#include "springs/spring_system.h"
#include "springs/template_plot.h"

#include <catch2/catch.hpp>

#include <cmath>
#include <set>

using namespace fascicle;
using namespace fascicle::springs;

TEST_CASE("every template maps the unit cube into itself, from origin area to insertion area", "[springs][template]") {
  for (TemplateKind kind : all_template_kinds()) {
    INFO(template_name(kind));
    const TemplateArea origin = origin_area(kind), insertion = insertion_area(kind);
    for (int a = 0; a <= 10; ++a)
      for (int b = 0; b <= 10; ++b) {
        const double r = a / 10.0, s = b / 10.0;
        CHECK(origin.contains(template_point(kind, r, s, 0.0)));
        CHECK(insertion.contains(template_point(kind, r, s, 1.0)));
        CHECK_FALSE(origin.contains(template_point(kind, r, s, 1.0)));
        Vec3 previous = template_point(kind, r, s, 0.0);
        for (int c = 1; c <= 20; ++c) {
          const Vec3 p = template_point(kind, r, s, c / 20.0);
          CHECK(p.minCoeff() >= -1e-12);
          CHECK(p.maxCoeff() <= 1.0 + 1e-12);
          // Continuous along the fibre: no step longer than the cube's diagonal / 10.
          CHECK((p - previous).norm() < std::sqrt(3.0) / 10.0);
          CHECK((p - previous).norm() > 0.0);  // fibres have length and no stalls
          previous = p;
        }
      }
  }
}

TEST_CASE("template names parse and bad names are refused", "[springs][template]") {
  for (TemplateKind kind : all_template_kinds()) CHECK(parse_template_kind(template_name(kind)) == kind);
  CHECK_THROWS_AS(parse_template_kind("multipennate"), OptionError);
}

TEST_CASE("distinct lattice parameters give distinct template points", "[springs][template]") {
  for (TemplateKind kind : all_template_kinds()) {
    INFO(template_name(kind));
    LatticeOptions options;
    options.kind = kind;
    options.fibres = 36;
    options.resolution = 7;
    const Lattice lattice = build_lattice(options);  // throws when two points coincide
    CHECK(lattice.point_count() == 6 * 6 * 7);
  }
}

TEST_CASE("near-square split of the fibre count", "[springs][lattice]") {
  CHECK(near_square_split(100) == std::array<int, 2>{10, 10});
  CHECK(near_square_split(50) == std::array<int, 2>{5, 10});
  CHECK(near_square_split(12) == std::array<int, 2>{3, 4});
  const auto prime = near_square_split(7);  // no exact split within ratio 2: at least 7 fibres
  CHECK(prime[0] * prime[1] >= 7);
  CHECK(prime[1] <= 2 * prime[0]);
  CHECK_THROWS_AS(near_square_split(3), OptionError);
}

namespace {

long expected_springs(int nx, int ny, int nz, SpringModel model) {
  long count = 0;
  for (const auto& o : half_offsets(model))
    count += static_cast<long>(nx - std::abs(o[0])) * (ny - std::abs(o[1])) * (nz - std::abs(o[2]));
  return count;
}

}  // namespace

TEST_CASE("lattice counts, springs, fixed points and masses", "[springs][lattice]") {
  for (SpringModel model : {SpringModel::model6, SpringModel::model26}) {
    LatticeOptions options;
    options.fibres = 12;
    options.resolution = 5;
    options.model = model;
    options.density = 2.0;
    const Lattice lattice = build_lattice(options);
    CHECK(lattice.nx == 3);
    CHECK(lattice.ny == 4);
    CHECK(lattice.nz == 5);
    CHECK(lattice.point_count() == 60);
    CHECK(static_cast<long>(lattice.system.springs.size()) == expected_springs(3, 4, 5, model));
    if (model == SpringModel::model6) CHECK(lattice.system.springs.size() == 2 * 4 * 5 + 3 * 3 * 5 + 3 * 4 * 4);
    CHECK(half_offsets(model).size() == (model == SpringModel::model6 ? 3u : 13u));
    int fixed = 0;
    for (char f : lattice.system.fixed) fixed += f;
    CHECK(fixed == 60 - 1 * 2 * 3);
    CHECK(lattice.origin.size() == 12);
    CHECK(lattice.insertion.size() == 12);
    for (const Spring& s : lattice.system.springs) {
      CHECK(s.rest == Approx((lattice.system.positions[s.a] - lattice.system.positions[s.b]).norm()));
      CHECK(s.stiffness == Approx(1.0 / s.rest));
    }
    // parallel template: volume 1, so mass = density / points
    for (double m : lattice.system.mass) CHECK(m == Approx(2.0 / 60));
  }
}

TEST_CASE("lattice surface is closed and outward for every template", "[springs][lattice]") {
  for (TemplateKind kind : all_template_kinds()) {
    INFO(template_name(kind));
    LatticeOptions options;
    options.kind = kind;
    options.fibres = 16;
    options.resolution = 6;
    const Lattice lattice = build_lattice(options);
    const int nx = lattice.nx, ny = lattice.ny, nz = lattice.nz;
    CHECK(lattice.surface.size() ==
          static_cast<std::size_t>(4 * ((nx - 1) * (ny - 1) + (nx - 1) * (nz - 1) + (ny - 1) * (nz - 1))));
    // closed: every directed edge has its reverse exactly once
    std::multiset<std::pair<int, int>> edges;
    for (const Triangle& t : lattice.surface)
      for (int e = 0; e < 3; ++e) edges.insert({t[e], t[(e + 1) % 3]});
    for (const auto& e : edges) CHECK(edges.count({e.second, e.first}) == 1);
    double volume = 0.0;
    const auto& p = lattice.system.positions;
    for (const Triangle& t : lattice.surface) volume += p[t[0]].dot(p[t[1]].cross(p[t[2]])) / 6.0;
    CHECK(volume > 0.0);
    for (const Triangle& t : lattice.surface)
      for (int v : t) CHECK(lattice.system.fixed[v] == 1);  // surface vertices are the fixed points
  }
}

TEST_CASE("narrow edge cells put the inner lines at the centres of their shares", "[springs][lattice]") {
  // 12 x 12 lines (10 x 10 fibres and the ring): with edge cells of 0.5 the inner lines lie at
  // (i - 0.5) / 10 along r and s, the boundary lines at 0 and 1; t is not affected.
  CHECK(lattice_line_position(0, 12, 0.5) == 0.0);
  CHECK(lattice_line_position(1, 12, 0.5) == 0.5);
  CHECK(lattice_line_position(10, 12, 0.5) == 9.5);
  CHECK(lattice_line_position(11, 12, 0.5) == 10.0);
  for (int i = 0; i < 12; ++i) CHECK(lattice_line_position(i, 12, 1.0) == static_cast<double>(i));
  LatticeOptions options;
  options.nr = 12;
  options.ns = 12;
  options.resolution = 5;
  options.edge_cell = 0.5;
  const Lattice narrow = build_lattice(options);
  CHECK(narrow.edge_cell == 0.5);
  for (int j = 0; j < narrow.ny; ++j)
    for (int i = 0; i < narrow.nx; ++i) {
      const Vec3 c = lattice_coordinates(narrow, narrow.index(i, j, 2));
      const double r = i == 0 ? 0.0 : i == 11 ? 1.0 : (i - 0.5) / 10.0;
      const double s = j == 0 ? 0.0 : j == 11 ? 1.0 : (j - 0.5) / 10.0;
      CHECK(c.x() == Approx(r).margin(1e-15));
      CHECK(c.y() == Approx(s).margin(1e-15));
      CHECK(c.z() == 0.5);
      // The parallel template is the identity of the unit cube.
      CHECK((narrow.system.positions[static_cast<std::size_t>(narrow.index(i, j, 2))] - c).norm() < 1e-12);
    }
  // The edge springs are half as long (stiffness 1 / rest length), the others unchanged.
  double shortest = 1e300, longest = 0.0;
  for (const Spring& spring : narrow.system.springs)
    shortest = std::min(shortest, spring.rest), longest = std::max(longest, spring.rest);
  CHECK(shortest == Approx(0.05));
  CHECK(longest == Approx(0.25));  // along t: 4 steps of the unit length
  // Even edge cells: the coordinates i / (n - 1) to the bit.
  options.edge_cell = 1.0;
  const Lattice even = build_lattice(options);
  for (int q = 0; q < even.point_count(); ++q) {
    const int i = q % even.nx, j = (q / even.nx) % even.ny, k = q / (even.nx * even.ny);
    const Vec3 c = lattice_coordinates(even, q);
    CHECK(c.x() == static_cast<double>(i) / 11);
    CHECK(c.y() == static_cast<double>(j) / 11);
    CHECK(c.z() == static_cast<double>(k) / 4);
  }
}

TEST_CASE("lattice options are validated", "[springs][lattice]") {
  LatticeOptions options;
  options.fibres = 2;
  CHECK_THROWS_AS(build_lattice(options), OptionError);
  options = LatticeOptions();
  options.resolution = 1;
  CHECK_THROWS_AS(build_lattice(options), OptionError);
  options = LatticeOptions();
  options.density = 0.0;
  CHECK_THROWS_AS(build_lattice(options), OptionError);
  for (const double edge : {0.0, -0.5, 1.5}) {
    options = LatticeOptions();
    options.edge_cell = edge;
    CHECK_THROWS_WITH(build_lattice(options), Catch::Contains("edge_cell"));
  }
  CHECK_THROWS_AS(parse_spring_model(8), OptionError);
}

TEST_CASE("lattice converts to the thesis format and back", "[springs][lattice]") {
  LatticeOptions options;
  options.kind = TemplateKind::fanned;
  options.fibres = 9;
  options.resolution = 4;
  options.model = SpringModel::model26;
  const Lattice lattice = build_lattice(options);
  const ThesisModel model = to_thesis_model(lattice);
  CHECK(model.points.size() == 36);
  CHECK(model.springs.size() == lattice.system.springs.size());
  CHECK(model.fibres.size() == 9);
  CHECK(model.origin.size() == 9);
  CHECK(model.triangles.size() == lattice.surface.size());
  for (const auto& f : model.fibres) {
    CHECK(origin_area(TemplateKind::fanned).contains(model.points[f[0]]));
    CHECK(insertion_area(TemplateKind::fanned).contains(model.points[f[1]]));
  }
  const SpringSystem system = spring_system_from_thesis(model, 0.5);
  CHECK(system.fixed == lattice.system.fixed);
  for (std::size_t s = 0; s < system.springs.size(); ++s) {
    CHECK(system.springs[s].rest == lattice.system.springs[s].rest);
    CHECK(system.springs[s].stiffness == lattice.system.springs[s].stiffness);
  }
  for (double m : system.mass) CHECK(m == 0.5);
  ThesisModel bad = model;
  bad.springs[0].b = bad.springs[0].a;
  CHECK_THROWS_AS(spring_system_from_thesis(bad, 1.0), InputError);
  bad = model;
  bad.springs[0].b = 1000;
  CHECK_THROWS_AS(spring_system_from_thesis(bad, 1.0), InputError);
  const Polylines fibres = fibre_polylines(lattice, lattice.system.positions);
  CHECK(fibres.lines.size() == 9);
  CHECK(fibres.lines[0].size() == 4);
}

TEST_CASE("template pictures draw every fibre and both areas", "[springs][template]") {
  for (TemplateKind kind : all_template_kinds()) {
    const std::string svg = template_svg(kind, 4, 2, 10);
    CHECK(svg.rfind("<svg", 0) == 0);
    std::size_t lines = 0, polygons = 0;
    for (std::size_t at = 0; (at = svg.find("<polyline", at)) != std::string::npos; ++at) ++lines;
    for (std::size_t at = 0; (at = svg.find("<polygon", at)) != std::string::npos; ++at) ++polygons;
    CHECK(lines == 12 + 8);  // cube edges + fibres
    CHECK(polygons == origin_area(kind).parts.size() + insertion_area(kind).parts.size());
    CHECK(svg.find(template_name(kind)) != std::string::npos);
  }
  CHECK_THROWS_AS(template_svg(TemplateKind::parallel, 0, 1, 10), OptionError);
}
