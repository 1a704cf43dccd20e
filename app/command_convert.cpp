// fascicle convert IN -o OUT: reads any supported mesh or fibre file and writes it in another
// format, without repairing it (a mesh's polygons become triangle fans). Fibre files (.vtp,
// .vtu, .csv, and .vtk or .obj files that hold lines) stay fibres with their cell arrays; handy
// to check what a reader understood or to hand fibres to another tool.

#include "app/commands.h"
#include "geometry/atomic_file.h"
#include "geometry/errors.h"
#include "geometry/mesh_io.h"

#include <spdlog/spdlog.h>

#include <memory>

namespace fascicle::app {

namespace {

bool is_mesh_extension(const std::string& ext) {
  return ext == "off" || ext == "obj" || ext == "stl" || ext == "ply" || ext == "vtk" || ext == "txt";
}

// Whether `path` holds polylines: by extension, and for formats that hold either (.vtk, .obj)
// by whether it has lines.
bool holds_polylines(const std::string& path) {
  const std::string ext = lower_extension(path);
  if (ext == "vtp" || ext == "vtu" || ext == "csv") return true;
  if (ext != "vtk" && ext != "obj") return false;
  try {
    read_polylines(path);
    return true;
  } catch (const InputError& e) {
    if (e.code() == ErrorCode::file_empty) return false;  // no lines: a mesh
    throw;
  }
}

}  // namespace

void add_convert_command(CLI::App& app) {
  struct Args {
    std::string input, output;
  };
  auto args = std::make_shared<Args>();
  CLI::App* cmd = app.add_subcommand(
      "convert", "Convert a mesh or a fibre file between formats (no repair; a mesh's polygons become fans)");
  cmd->add_option("input", args->input, "Input mesh (off, obj, stl, ply, vtk, txt) or fibres (vtk, vtp, vtu, obj, csv)")
      ->required();
  cmd->add_option("-o,--output", args->output,
                  "Output in the same kind: mesh (off, obj, stl, ply, vtk) or fibres "
                  "(vtk, vtp, vtu, obj, csv)")
      ->required();
  cmd->callback([args] {
    check_not_same_file(args->input, args->output);
    const std::string out_ext = lower_extension(args->output);
    if (!is_mesh_extension(out_ext) && !is_polyline_extension(out_ext))
      throw InputError(ErrorCode::unknown_format,
                       args->output + ": unknown output format '" + out_ext +
                           "' (meshes: off, obj, stl, ply, vtk; fibres: vtk, vtp, vtu, obj, csv)");
    check_output_path(args->output);
    if (holds_polylines(args->input)) {
      if (!is_polyline_extension(out_ext))
        throw InputError(ErrorCode::unknown_format, args->input + " holds fibres, which cannot be written as '" +
                                                        out_ext + "' (use vtk, vtp, vtu, obj or csv)");
      const Polylines fibres = read_polylines(args->input);
      write_polylines(args->output, fibres);
      spdlog::info("wrote {}: {} fibres", args->output, fibres.lines.size());
      return;
    }
    if (!is_mesh_extension(out_ext) || out_ext == "txt")
      throw InputError(ErrorCode::unknown_format, args->input + " holds a mesh, which cannot be written as '" +
                                                      out_ext + "' (use off, obj, stl, ply or vtk)");
    const PolygonSoup soup = read_polygon_soup(args->input);
    TriangleMesh mesh;
    mesh.positions = soup.points;
    for (const auto& polygon : soup.polygons)
      for (std::size_t k = 2; k < polygon.size(); ++k)
        mesh.triangles.push_back({polygon[0], polygon[k - 1], polygon[k]});
    write_triangle_mesh(args->output, mesh);
    spdlog::info("wrote {}: {} points, {} triangles", args->output, mesh.positions.size(), mesh.triangles.size());
  });
}

}  // namespace fascicle::app
