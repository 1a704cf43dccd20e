// Tetrahedral meshes as VTK XML UnstructuredGrid (.vtu, ASCII).
#include "geometry/atomic_file.h"
#include "geometry/detail/parse_cursor.h"
#include "geometry/errors.h"
#include "geometry/mesh_io.h"

namespace fascicle {

namespace {

// One ASCII Float64 DataArray of 3-vectors, a vector a line.
void append_vectors(std::string& out, const std::string& name, const std::vector<Vec3>& vectors) {
  out += "        <DataArray type=\"Float64\" Name=\"" + name + "\" NumberOfComponents=\"3\" format=\"ascii\">\n";
  for (const Vec3& v : vectors) {
    out += "          ";
    for (int k = 0; k < 3; ++k) {
      if (k) out += ' ';
      detail::append_double(out, v[k]);
    }
    out += '\n';
  }
  out += "        </DataArray>\n";
}

}  // namespace

void write_tetrahedra(const std::string& path, const TetMesh& mesh, const std::string& name,
                      const std::vector<Vec3>& cell_vectors) {
  if (lower_extension(path) != "vtu")
    throw InputError(ErrorCode::unknown_format,
                     path + ": cannot write tetrahedra as '" + lower_extension(path) + "' (use .vtu)");
  FASCICLE_CHECK(cell_vectors.empty() || cell_vectors.size() == mesh.tets.size(),
                 "writing " + path + ": the cell array does not hold one vector per tetrahedron");
  for (const Vec3& p : mesh.positions) FASCICLE_CHECK(p.allFinite(), "writing " + path + ": a point is not finite");
  for (const Vec3& v : cell_vectors) FASCICLE_CHECK(v.allFinite(), "writing " + path + ": a cell vector is not finite");
  for (const Tetrahedron& t : mesh.tets)
    for (int v : t)
      FASCICLE_CHECK(v >= 0 && static_cast<std::size_t>(v) < mesh.positions.size(),
                     "writing " + path + ": a tetrahedron index is out of range");
  std::string out = "<?xml version=\"1.0\"?>\n";
  out += "<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" byte_order=\"LittleEndian\" header_type=\"UInt64\">\n";
  out += "  <UnstructuredGrid>\n    <Piece NumberOfPoints=\"" + std::to_string(mesh.positions.size()) +
         "\" NumberOfCells=\"" + std::to_string(mesh.tets.size()) + "\">\n";
  out += "      <Points>\n";
  append_vectors(out, "Points", mesh.positions);
  out += "      </Points>\n      <Cells>\n";
  out += "        <DataArray type=\"Int64\" Name=\"connectivity\" format=\"ascii\">\n";
  for (const Tetrahedron& t : mesh.tets) {
    out += "         ";
    for (int v : t) {
      out += ' ';
      detail::append_int(out, v);
    }
    out += '\n';
  }
  out += "        </DataArray>\n        <DataArray type=\"Int64\" Name=\"offsets\" format=\"ascii\">\n";
  for (std::size_t c = 0; c < mesh.tets.size(); ++c) {
    out += "          ";
    detail::append_int(out, static_cast<long long>(4 * (c + 1)));
    out += '\n';
  }
  out += "        </DataArray>\n        <DataArray type=\"UInt8\" Name=\"types\" format=\"ascii\">\n";
  for (std::size_t c = 0; c < mesh.tets.size(); ++c) out += "          10\n";
  out += "        </DataArray>\n      </Cells>\n";
  if (!cell_vectors.empty()) {
    out += "      <CellData Vectors=\"" + name + "\">\n";
    append_vectors(out, name, cell_vectors);
    out += "      </CellData>\n";
  }
  out += "    </Piece>\n  </UnstructuredGrid>\n</VTKFile>\n";
  write_file_atomically(path, [&](std::ostream& o) { o.write(out.data(), static_cast<std::streamsize>(out.size())); });
}

}  // namespace fascicle
