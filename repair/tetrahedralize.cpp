// CGAL Mesh_3 on a polyhedral domain, behind the plain TetMesh of geometry/mesh.h.
#include "repair/tetrahedralize.h"

#include "geometry/errors.h"

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Mesh_complex_3_in_triangulation_3.h>
#include <CGAL/Mesh_criteria_3.h>
#include <CGAL/Mesh_triangulation_3.h>
#include <CGAL/Polyhedral_mesh_domain_3.h>
#include <CGAL/Surface_mesh.h>
#include <CGAL/boost/graph/helpers.h>
#include <CGAL/make_mesh_3.h>
#include <nlohmann/json.hpp>

#include <chrono>
#include <cmath>
#include <string>
#include <unordered_map>

namespace fascicle {

namespace {

using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
using Surface = CGAL::Surface_mesh<Kernel::Point_3>;
using Domain = CGAL::Polyhedral_mesh_domain_3<Surface, Kernel>;
using Triangulation = CGAL::Mesh_triangulation_3<Domain, CGAL::Default, CGAL::Sequential_tag>::type;
using Complex = CGAL::Mesh_complex_3_in_triangulation_3<Triangulation>;
using Criteria = CGAL::Mesh_criteria_3<Triangulation>;

}  // namespace

void TetrahedralizeOptions::validate() const {
  const auto positive = [](const char* field, double value) {
    if (!(value > 0.0) || !std::isfinite(value))
      throw OptionError(std::string("tetrahedralize: ") + field + " must be > 0 and finite, got " +
                        std::to_string(value));
  };
  positive("cell_size", cell_size);
  positive("facet_size", facet_size);
  positive("facet_distance", facet_distance);
  if (!(facet_angle_deg > 0.0 && facet_angle_deg <= 30.0))
    throw OptionError("tetrahedralize: facet_angle_deg must be in (0, 30], got " + std::to_string(facet_angle_deg));
  if (!(radius_edge_ratio >= 2.0) || !std::isfinite(radius_edge_ratio))
    throw OptionError("tetrahedralize: radius_edge_ratio must be >= 2, got " + std::to_string(radius_edge_ratio));
}

TetrahedralizeOptions sized_tetrahedra(double volume, long tets) {
  if (!(volume > 0.0) || tets < 1)
    throw OptionError("tetrahedralize: the volume and the number of tetrahedra must be > 0");
  const double edge = std::cbrt(6.0 * std::sqrt(2.0) * volume / static_cast<double>(tets));
  TetrahedralizeOptions options;
  options.cell_size = 0.8 * edge;
  options.facet_size = 0.8 * edge;
  options.facet_distance = edge / 6.0;
  return options;
}

nlohmann::json TetrahedralizeReport::to_json() const {
  return {{"vertices", vertices}, {"tets", tets}, {"boundary_vertices", boundary_vertices}, {"seconds", seconds}};
}

TetMesh tetrahedralize(const TriangleMesh& surface, const TetrahedralizeOptions& options,
                       TetrahedralizeReport* report) {
  options.validate();
  const auto start = std::chrono::steady_clock::now();
  if (surface.triangles.empty()) throw TopologyError("tetrahedralize: the surface has no triangles");
  Surface mesh;
  std::vector<Surface::Vertex_index> vertex;
  vertex.reserve(surface.positions.size());
  for (const Vec3& p : surface.positions) vertex.push_back(mesh.add_vertex(Kernel::Point_3(p.x(), p.y(), p.z())));
  for (const Triangle& t : surface.triangles)
    if (mesh.add_face(vertex[static_cast<std::size_t>(t[0])], vertex[static_cast<std::size_t>(t[1])],
                      vertex[static_cast<std::size_t>(t[2])]) == Surface::null_face())
      throw TopologyError("tetrahedralize: the surface is not an oriented 2-manifold (repair it first)");
  // An open surface bounds no volume: the domain's inside test would be undefined.
  if (!CGAL::is_closed(mesh)) throw TopologyError("tetrahedralize: the surface is open (repair it first)");
  const Domain domain(mesh);
  namespace params = CGAL::parameters;
  const Criteria criteria(params::facet_angle = options.facet_angle_deg, params::facet_size = options.facet_size,
                          params::facet_distance = options.facet_distance,
                          params::cell_radius_edge_ratio = options.radius_edge_ratio,
                          params::cell_size = options.cell_size);
  const Complex complex = CGAL::make_mesh_3<Complex>(domain, criteria, params::no_perturb(), params::no_exude());

  TetMesh out;
  std::unordered_map<Triangulation::Vertex_handle, int> index;
  const auto index_of = [&](Triangulation::Vertex_handle v) {
    const auto [it, inserted] = index.emplace(v, static_cast<int>(out.positions.size()));
    if (inserted) {
      const auto& p = v->point();
      out.positions.emplace_back(CGAL::to_double(p.x()), CGAL::to_double(p.y()), CGAL::to_double(p.z()));
    }
    return it->second;
  };
  for (auto c = complex.cells_in_complex_begin(); c != complex.cells_in_complex_end(); ++c)
    out.tets.push_back(
        {index_of(c->vertex(0)), index_of(c->vertex(1)), index_of(c->vertex(2)), index_of(c->vertex(3))});
  out.boundary.assign(out.positions.size(), 0);
  for (auto f = complex.facets_in_complex_begin(); f != complex.facets_in_complex_end(); ++f)
    for (int i = 0; i < 4; ++i)
      if (i != f->second) {
        const auto found = index.find(f->first->vertex(i));
        if (found != index.end()) out.boundary[static_cast<std::size_t>(found->second)] = 1;
      }
  if (out.tets.empty())
    throw TopologyError("tetrahedralize: the surface bounds no volume the mesh generator could fill");
  // Cells of a CGAL triangulation are positively oriented; make sure of it where rounding of
  // the weighted points could say otherwise.
  for (Tetrahedron& t : out.tets) {
    const Vec3& a = out.positions[static_cast<std::size_t>(t[0])];
    if ((out.positions[static_cast<std::size_t>(t[1])] - a)
            .cross(out.positions[static_cast<std::size_t>(t[2])] - a)
            .dot(out.positions[static_cast<std::size_t>(t[3])] - a) < 0.0)
      std::swap(t[2], t[3]);
  }
  if (report) {
    report->vertices = static_cast<long>(out.positions.size());
    report->tets = static_cast<long>(out.tets.size());
    report->boundary_vertices = 0;
    for (char b : out.boundary) report->boundary_vertices += b;
    report->seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  }
  return out;
}

}  // namespace fascicle
