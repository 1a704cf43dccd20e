// Polyline writers: legacy VTK polydata (POINTS + LINES + one CELL_DATA SCALARS array per
// cell_data entry) and OBJ (`v` + `l`; cell data has no place in OBJ and is not written).
#include "geometry/atomic_file.h"
#include "geometry/detail/parse_cursor.h"
#include "geometry/errors.h"
#include "geometry/mesh_io.h"

#include <cctype>

namespace fascicle {

namespace {

void append_point(std::string& out, const Vec3& p) {
  detail::append_double(out, p.x());
  out += ' ';
  detail::append_double(out, p.y());
  out += ' ';
  detail::append_double(out, p.z());
  out += '\n';
}

/// VTK array names cannot hold blanks.
std::string vtk_name(const std::string& name, std::size_t index) {
  std::string result = name.empty() ? "array" + std::to_string(index) : name;
  for (auto& c : result)
    if (std::isspace(static_cast<unsigned char>(c)) || static_cast<unsigned char>(c) < 32) c = '_';
  return result;
}

std::string vtk_text(const Polylines& lines) {
  std::size_t total = 0;
  for (const auto& line : lines.lines) total += line.size();
  std::string out = "# vtk DataFile Version 3.0\nfascicle polylines\nASCII\nDATASET POLYDATA\n";
  out += "POINTS " + std::to_string(total) + " double\n";
  for (const auto& line : lines.lines)
    for (const Vec3& p : line) append_point(out, p);
  out += "LINES " + std::to_string(lines.lines.size()) + " " + std::to_string(lines.lines.size() + total) + "\n";
  std::size_t next = 0;
  for (const auto& line : lines.lines) {
    out += std::to_string(line.size());
    for (std::size_t i = 0; i < line.size(); ++i) {
      out += ' ';
      detail::append_int(out, static_cast<long long>(next++));
    }
    out += '\n';
  }
  if (!lines.cell_data.empty()) {
    out += "CELL_DATA " + std::to_string(lines.lines.size()) + "\n";
    for (std::size_t a = 0; a < lines.cell_data.size(); ++a) {
      out += "SCALARS " + vtk_name(lines.cell_data[a].name, a) + " double 1\nLOOKUP_TABLE default\n";
      for (double v : lines.cell_data[a].values) {
        detail::append_double(out, v);
        out += '\n';
      }
    }
  }
  return out;
}

std::string obj_text(const Polylines& lines) {
  std::string out = "# polylines written by fascicle\n";
  for (const auto& line : lines.lines)
    for (const Vec3& p : line) {
      out += "v ";
      append_point(out, p);
    }
  std::size_t next = 1;
  for (const auto& line : lines.lines) {
    out += 'l';
    for (std::size_t i = 0; i < line.size(); ++i) {
      out += ' ';
      detail::append_int(out, static_cast<long long>(next++));
    }
    out += '\n';
  }
  return out;
}

}  // namespace

void write_polylines(const std::string& path, const Polylines& lines) {
  const std::string ext = lower_extension(path);
  if (ext != "vtk" && ext != "obj")
    throw InputError(ErrorCode::unknown_format, path + ": cannot write polylines as '" + ext + "' (use .vtk or .obj)");
  for (const auto& line : lines.lines)
    for (const Vec3& p : line) FASCICLE_CHECK(p.allFinite(), "writing " + path + ": a polyline point is not finite");
  for (const CellArray& array : lines.cell_data) {
    FASCICLE_CHECK(array.values.size() == lines.lines.size(),
                   "writing " + path + ": cell array '" + array.name + "' does not hold one value per line");
    for (double v : array.values) FASCICLE_CHECK(std::isfinite(v), "writing " + path + ": cell array '" + array.name + "' holds a value that is not finite");
  }
  const std::string content = ext == "vtk" ? vtk_text(lines) : obj_text(lines);
  write_file_atomically(path, [&](std::ostream& out) { out.write(content.data(), static_cast<std::streamsize>(content.size())); });
}

}  // namespace fascicle
