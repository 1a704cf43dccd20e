// Triangle mesh writers: OFF, OBJ, legacy VTK (text, max_digits10), PLY (binary little endian,
// double coordinates), STL (binary float32, the format's only precision). All atomic.
#include "geometry/atomic_file.h"
#include "geometry/detail/parse_cursor.h"
#include "geometry/errors.h"
#include "geometry/mesh_io.h"

#include <cmath>
#include <cstring>
#include <limits>

namespace fascicle {

namespace {

void check_mesh(const std::string& path, const TriangleMesh& mesh) {
  const auto n = static_cast<long long>(mesh.positions.size());
  for (const Vec3& p : mesh.positions)
    FASCICLE_CHECK(p.allFinite(), "writing " + path + ": a vertex position is not finite");
  for (const Triangle& t : mesh.triangles)
    for (int i : t) FASCICLE_CHECK(i >= 0 && i < n, "writing " + path + ": a triangle index is out of range");
}

void append_point(std::string& out, const Vec3& p) {
  detail::append_double(out, p.x());
  out += ' ';
  detail::append_double(out, p.y());
  out += ' ';
  detail::append_double(out, p.z());
}

/// Appends `value` in little-endian byte order.
template <class T>
void append_le(std::string& out, T value) {
  char bytes[sizeof(T)];
  std::memcpy(bytes, &value, sizeof(T));
  if (detail::ParseCursor::host_is_big_endian())
    for (std::size_t i = 0; i < sizeof(T) / 2; ++i) std::swap(bytes[i], bytes[sizeof(T) - 1 - i]);
  out.append(bytes, sizeof(T));
}

std::string off_text(const TriangleMesh& mesh) {
  std::string out = "OFF\n";
  out += std::to_string(mesh.positions.size()) + " " + std::to_string(mesh.triangles.size()) + " 0\n";
  for (const Vec3& p : mesh.positions) {
    append_point(out, p);
    out += '\n';
  }
  for (const Triangle& t : mesh.triangles)
    out += "3 " + std::to_string(t[0]) + " " + std::to_string(t[1]) + " " + std::to_string(t[2]) + "\n";
  return out;
}

std::string obj_text(const TriangleMesh& mesh) {
  std::string out = "# written by fascicle\n";
  for (const Vec3& p : mesh.positions) {
    out += "v ";
    append_point(out, p);
    out += '\n';
  }
  for (const Triangle& t : mesh.triangles)
    out += "f " + std::to_string(t[0] + 1) + " " + std::to_string(t[1] + 1) + " " + std::to_string(t[2] + 1) + "\n";
  return out;
}

std::string vtk_text(const TriangleMesh& mesh) {
  std::string out = "# vtk DataFile Version 3.0\nfascicle triangle mesh\nASCII\nDATASET POLYDATA\n";
  out += "POINTS " + std::to_string(mesh.positions.size()) + " double\n";
  for (const Vec3& p : mesh.positions) {
    append_point(out, p);
    out += '\n';
  }
  out += "POLYGONS " + std::to_string(mesh.triangles.size()) + " " + std::to_string(4 * mesh.triangles.size()) + "\n";
  for (const Triangle& t : mesh.triangles)
    out += "3 " + std::to_string(t[0]) + " " + std::to_string(t[1]) + " " + std::to_string(t[2]) + "\n";
  return out;
}

std::string ply_bytes(const TriangleMesh& mesh) {
  std::string out = "ply\nformat binary_little_endian 1.0\ncomment written by fascicle\n";
  out += "element vertex " + std::to_string(mesh.positions.size()) + "\n";
  out += "property double x\nproperty double y\nproperty double z\n";
  out += "element face " + std::to_string(mesh.triangles.size()) + "\n";
  out += "property list uchar int vertex_indices\nend_header\n";
  out.reserve(out.size() + 24 * mesh.positions.size() + 13 * mesh.triangles.size());
  for (const Vec3& p : mesh.positions)
    for (int c = 0; c < 3; ++c) append_le<double>(out, p[c]);
  for (const Triangle& t : mesh.triangles) {
    out += static_cast<char>(3);
    for (int i : t) append_le<std::int32_t>(out, i);
  }
  return out;
}

std::string stl_bytes(const std::string& path, const TriangleMesh& mesh) {
  FASCICLE_CHECK(mesh.triangles.size() <= std::numeric_limits<std::uint32_t>::max(),
                 "writing " + path + ": too many triangles for STL");
  // The header must not start with "solid", or readers may take the file for ASCII STL.
  std::string out = "binary STL written by fascicle";
  out.resize(80, ' ');
  append_le<std::uint32_t>(out, static_cast<std::uint32_t>(mesh.triangles.size()));
  out.reserve(84 + 50 * mesh.triangles.size());
  // STL holds float32 only: where rounding to it merges a triangle's distinct corners (large
  // offsets against a small mesh), the file would hold a different mesh, so nothing is written.
  const auto as_float = [](const Vec3& p) {
    return Eigen::Vector3f(static_cast<float>(p.x()), static_cast<float>(p.y()), static_cast<float>(p.z()));
  };
  long collapsed = 0;
  for (const Triangle& t : mesh.triangles) {
    const Vec3& a = mesh.positions[static_cast<std::size_t>(t[0])];
    const Vec3& b = mesh.positions[static_cast<std::size_t>(t[1])];
    const Vec3& c = mesh.positions[static_cast<std::size_t>(t[2])];
    const Eigen::Vector3f fa = as_float(a), fb = as_float(b), fc = as_float(c);
    if ((a != b && fa == fb) || (b != c && fb == fc) || (c != a && fc == fa)) ++collapsed;
    Vec3 normal = (b - a).cross(c - a);
    const double length = normal.norm();
    normal = length > 0 ? Vec3(normal / length) : Vec3::Zero();
    for (int k = 0; k < 3; ++k) append_le<float>(out, static_cast<float>(normal[k]));
    for (const Eigen::Vector3f* p : {&fa, &fb, &fc})
      for (int k = 0; k < 3; ++k) append_le<float>(out, (*p)[k]);
    append_le<std::uint16_t>(out, 0);
  }
  if (collapsed > 0)
    throw IoError("writing " + path + ": STL's single-precision coordinates merge distinct corners of " +
                  std::to_string(collapsed) + " triangle(s) (coordinates too large for the mesh's size); " +
                  "write .off, .obj, .ply or .vtk, which keep double precision");
  return out;
}

}  // namespace

void write_triangle_mesh(const std::string& path, const TriangleMesh& mesh) {
  const std::string ext = lower_extension(path);
  if (ext != "off" && ext != "obj" && ext != "ply" && ext != "stl" && ext != "vtk")
    throw InputError(ErrorCode::unknown_format,
                     path + ": cannot write mesh format '" + ext + "' (use .off .obj .ply .stl .vtk)");
  check_mesh(path, mesh);
  std::string content;
  const bool binary = ext == "ply" || ext == "stl";
  if (ext == "off")
    content = off_text(mesh);
  else if (ext == "obj")
    content = obj_text(mesh);
  else if (ext == "vtk")
    content = vtk_text(mesh);
  else if (ext == "ply")
    content = ply_bytes(mesh);
  else
    content = stl_bytes(path, mesh);
  write_file_atomically(
      path, [&](std::ostream& out) { out.write(content.data(), static_cast<std::streamsize>(content.size())); },
      binary);
}

}  // namespace fascicle
