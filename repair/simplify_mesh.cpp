// CGAL Surface_mesh_simplification behind the plain TriangleMesh of geometry/mesh.h.
#include "repair/simplify_mesh.h"

#include "geometry/errors.h"

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Surface_mesh.h>
#include <CGAL/Surface_mesh_simplification/Policies/Edge_collapse/Bounded_normal_change_placement.h>
#include <CGAL/Surface_mesh_simplification/Policies/Edge_collapse/Count_stop_predicate.h>
#include <CGAL/Surface_mesh_simplification/Policies/Edge_collapse/Edge_length_cost.h>
#include <CGAL/Surface_mesh_simplification/Policies/Edge_collapse/Midpoint_placement.h>
#include <CGAL/Surface_mesh_simplification/edge_collapse.h>
#include <CGAL/boost/graph/helpers.h>
#include <nlohmann/json.hpp>

#include <chrono>
#include <string>
#include <vector>

namespace fascicle {

namespace {

using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
using Mesh = CGAL::Surface_mesh<Kernel::Point_3>;
namespace SMS = CGAL::Surface_mesh_simplification;

}  // namespace

nlohmann::json SimplifyReport::to_json() const {
  return {{"faces_before", faces_before}, {"faces_after", faces_after}, {"seconds", seconds}};
}

TriangleMesh simplify_mesh(const TriangleMesh& mesh, long max_faces, SimplifyReport* report) {
  if (max_faces < 4) throw OptionError("simplify: max_faces must be >= 4, got " + std::to_string(max_faces));
  const auto start = std::chrono::steady_clock::now();
  const long before = static_cast<long>(mesh.triangles.size());
  const auto finish = [&](TriangleMesh out) {
    if (report) {
      report->faces_before = before;
      report->faces_after = static_cast<long>(out.triangles.size());
      report->seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    }
    return out;
  };
  if (before <= max_faces) return finish(mesh);

  Mesh sm;
  std::vector<Mesh::Vertex_index> vertex;
  vertex.reserve(mesh.positions.size());
  for (const Vec3& p : mesh.positions) vertex.push_back(sm.add_vertex(Kernel::Point_3(p.x(), p.y(), p.z())));
  for (const Triangle& t : mesh.triangles) {
    const auto f = sm.add_face(vertex[static_cast<std::size_t>(t[0])], vertex[static_cast<std::size_t>(t[1])],
                               vertex[static_cast<std::size_t>(t[2])]);
    if (f == Mesh::null_face()) throw TopologyError("simplify: the surface is not a manifold (a face cannot be added)");
  }
  if (!CGAL::is_closed(sm)) throw TopologyError("simplify: the surface is not closed");

  // A closed triangle mesh has 3/2 edges per face: stop once under that many edges.
  SMS::Count_stop_predicate<Mesh> stop(static_cast<std::size_t>(3 * max_faces / 2));
  SMS::Bounded_normal_change_placement<SMS::Midpoint_placement<Mesh>> placement;
  SMS::edge_collapse(sm, stop, CGAL::parameters::get_cost(SMS::Edge_length_cost<Mesh>()).get_placement(placement));
  sm.collect_garbage();

  TriangleMesh out;
  out.positions.reserve(sm.number_of_vertices());
  for (const auto v : sm.vertices()) {
    const auto& p = sm.point(v);
    out.positions.emplace_back(p.x(), p.y(), p.z());
  }
  out.triangles.reserve(sm.number_of_faces());
  for (const auto f : sm.faces()) {
    Triangle t{};
    int i = 0;
    for (const auto v : CGAL::vertices_around_face(sm.halfedge(f), sm)) t[static_cast<std::size_t>(i++)] = static_cast<int>(v.idx());
    out.triangles.push_back(t);
  }
  return finish(std::move(out));
}

}  // namespace fascicle
