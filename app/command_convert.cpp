// fascicle convert IN -o OUT: reads any supported mesh and writes it in another format, without
// repairing it (triangulating polygons as fans). Handy to check what a reader understood.

#include "app/commands.h"
#include "geometry/atomic_file.h"
#include "geometry/mesh_io.h"

#include <spdlog/spdlog.h>

#include <memory>

namespace fascicle::app {

void add_convert_command(CLI::App& app) {
  struct Args {
    std::string input, output;
  };
  auto args = std::make_shared<Args>();
  CLI::App* cmd = app.add_subcommand("convert", "Convert a mesh between formats (no repair; polygons become fans)");
  cmd->add_option("input", args->input, "Input mesh")->required();
  cmd->add_option("-o,--output", args->output, "Output mesh")->required();
  cmd->callback([args] {
    check_not_same_file(args->input, args->output);
    const PolygonSoup soup = read_polygon_soup(args->input);
    TriangleMesh mesh;
    mesh.positions = soup.points;
    for (const auto& polygon : soup.polygons)
      for (std::size_t k = 2; k < polygon.size(); ++k)
        mesh.triangles.push_back({polygon[0], polygon[k - 1], polygon[k]});
    write_triangle_mesh(args->output, mesh);
    spdlog::info("wrote {}: {} points, {} triangles", args->output, mesh.positions.size(),
                 mesh.triangles.size());
  });
}

}  // namespace fascicle::app
