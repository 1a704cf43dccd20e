// Polyline writers: legacy VTK polydata (POINTS + LINES + the cell arrays as one CELL_DATA FIELD
// block), VTK XML PolyData (.vtp) and UnstructuredGrid of line cells (.vtu), both ASCII, OBJ
// (`v` + `l`; cell data has no place in OBJ and is not written) and CSV (one row per point:
// fibre,r,s,point,x,y,z). An array whose values are all integers is written as integers.
#include "geometry/atomic_file.h"
#include "geometry/detail/parse_cursor.h"
#include "geometry/errors.h"
#include "geometry/mesh_io.h"

#include <cctype>
#include <cmath>
#include <functional>
#include <vector>

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

bool integral(const CellArray& array) {
  for (double v : array.values)
    if (!(v == std::floor(v) && std::abs(v) <= 2147483647.0)) return false;
  return true;
}

void append_value(std::string& out, double v, bool as_integer) {
  if (as_integer)
    detail::append_int(out, static_cast<long long>(v));
  else
    detail::append_double(out, v);
}

// The <Points> block of the XML formats.
std::string xml_points(const Polylines& lines) {
  std::string out =
      "      <Points>\n        <DataArray type=\"Float64\" Name=\"Points\" NumberOfComponents=\"3\" "
      "format=\"ascii\">\n";
  for (const auto& line : lines.lines)
    for (const Vec3& p : line) {
      out += "          ";
      append_point(out, p);
    }
  return out + "        </DataArray>\n      </Points>\n";
}

std::string xml_escape(const std::string& text);

// <CellData> with `arrays`, cell c taking the value of line line_of(c); Int32 for arrays of
// integers, else Float64.
std::string xml_cell_data(const std::vector<CellArray>& arrays, const std::function<std::size_t(std::size_t)>& line_of,
                          std::size_t cells) {
  if (arrays.empty()) return "";
  std::string out = "      <CellData>\n";
  for (std::size_t a = 0; a < arrays.size(); ++a) {
    const CellArray& array = arrays[a];
    const bool as_integer = integral(array);
    out += "        <DataArray type=\"" + std::string(as_integer ? "Int32" : "Float64") + "\" Name=\"" +
           xml_escape(array.name.empty() ? "array" + std::to_string(a) : array.name) + "\" format=\"ascii\">\n";
    for (std::size_t c = 0; c < cells; ++c) {
      out += "          ";
      append_value(out, array.values[line_of(c)], as_integer);
      out += '\n';
    }
    out += "        </DataArray>\n";
  }
  return out + "      </CellData>\n";
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
  // One FIELD block for all cell arrays: VTK's legacy readers keep every array of a FIELD,
  // where of several SCALARS blocks they keep only the first as the cell scalars.
  if (!lines.cell_data.empty()) {
    out += "CELL_DATA " + std::to_string(lines.lines.size()) + "\n";
    out += "FIELD FieldData " + std::to_string(lines.cell_data.size()) + "\n";
    for (std::size_t a = 0; a < lines.cell_data.size(); ++a) {
      const bool as_integer = integral(lines.cell_data[a]);
      out += vtk_name(lines.cell_data[a].name, a) + " 1 " + std::to_string(lines.lines.size()) +
             (as_integer ? " int\n" : " double\n");
      for (double v : lines.cell_data[a].values) {
        append_value(out, v, as_integer);
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

/// XML attribute text: the five predefined entities.
std::string xml_escape(const std::string& text) {
  std::string out;
  for (char c : text) {
    switch (c) {
      case '&': out += "&amp;"; break;
      case '<': out += "&lt;"; break;
      case '>': out += "&gt;"; break;
      case '"': out += "&quot;"; break;
      case '\'': out += "&apos;"; break;
      default: out += static_cast<unsigned char>(c) < 32 ? ' ' : c;
    }
  }
  return out;
}

// VTK XML PolyData, ASCII: the layout ParaView and VTK's vtkXMLPolyDataReader read.
std::string vtp_text(const Polylines& lines) {
  std::size_t total = 0;
  for (const auto& line : lines.lines) total += line.size();
  std::string out = "<?xml version=\"1.0\"?>\n";
  out += "<VTKFile type=\"PolyData\" version=\"1.0\" byte_order=\"LittleEndian\" header_type=\"UInt64\">\n";
  out += "  <PolyData>\n";
  out += "    <Piece NumberOfPoints=\"" + std::to_string(total) + "\" NumberOfVerts=\"0\" NumberOfLines=\"" +
         std::to_string(lines.lines.size()) + "\" NumberOfStrips=\"0\" NumberOfPolys=\"0\">\n";
  out += xml_points(lines);
  out += "      <Lines>\n        <DataArray type=\"Int64\" Name=\"connectivity\" format=\"ascii\">\n";
  std::size_t next = 0;
  for (const auto& line : lines.lines) {
    out += "         ";
    for (std::size_t i = 0; i < line.size(); ++i) {
      out += ' ';
      detail::append_int(out, static_cast<long long>(next++));
    }
    out += '\n';
  }
  out += "        </DataArray>\n        <DataArray type=\"Int64\" Name=\"offsets\" format=\"ascii\">\n";
  next = 0;
  for (const auto& line : lines.lines) {
    next += line.size();
    out += "          ";
    detail::append_int(out, static_cast<long long>(next));
    out += '\n';
  }
  out += "        </DataArray>\n      </Lines>\n";
  std::vector<CellArray> arrays = lines.cell_data;
  out += xml_cell_data(
      arrays, [](std::size_t line) { return line; }, lines.lines.size());
  out += "    </Piece>\n  </PolyData>\n</VTKFile>\n";
  return out;
}

// VTK XML UnstructuredGrid, ASCII: one line cell (VTK type 3) per fibre segment, with the cell
// arrays `fibre` (the fibre's number) and each of the fibres' arrays per segment. Line cells,
// not one poly-line per fibre, because meshio (5.0, Debian's) reads line cells and no poly-lines;
// read_polylines joins the segments back into fibres by `fibre`.
std::string vtu_text(const Polylines& lines) {
  std::size_t total = 0, segments = 0;
  for (const auto& line : lines.lines) total += line.size(), segments += line.size() > 0 ? line.size() - 1 : 0;
  std::string out = "<?xml version=\"1.0\"?>\n";
  out += "<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" byte_order=\"LittleEndian\" header_type=\"UInt64\">\n";
  out += "  <UnstructuredGrid>\n";
  out += "    <Piece NumberOfPoints=\"" + std::to_string(total) + "\" NumberOfCells=\"" + std::to_string(segments) +
         "\">\n";
  out += xml_points(lines);
  out += "      <Cells>\n        <DataArray type=\"Int64\" Name=\"connectivity\" format=\"ascii\">\n";
  std::vector<std::size_t> owner;  // fibre of each segment
  std::size_t base = 0;
  for (std::size_t f = 0; f < lines.lines.size(); ++f) {
    for (std::size_t i = 0; i + 1 < lines.lines[f].size(); ++i) {
      out += "          ";
      detail::append_int(out, static_cast<long long>(base + i));
      out += ' ';
      detail::append_int(out, static_cast<long long>(base + i + 1));
      out += '\n';
      owner.push_back(f);
    }
    base += lines.lines[f].size();
  }
  out += "        </DataArray>\n        <DataArray type=\"Int64\" Name=\"offsets\" format=\"ascii\">\n";
  for (std::size_t c = 0; c < segments; ++c) {
    out += "          ";
    detail::append_int(out, static_cast<long long>(2 * (c + 1)));
    out += '\n';
  }
  out += "        </DataArray>\n        <DataArray type=\"UInt8\" Name=\"types\" format=\"ascii\">\n";
  for (std::size_t c = 0; c < segments; ++c) out += "          3\n";
  out += "        </DataArray>\n      </Cells>\n";
  CellArray fibre{"fibre", {}};
  for (std::size_t f = 0; f < lines.lines.size(); ++f) fibre.values.push_back(static_cast<double>(f));
  std::vector<CellArray> arrays{fibre};
  for (const CellArray& a : lines.cell_data)
    if (a.name != "fibre") arrays.push_back(a);
  out += xml_cell_data(
      arrays, [&](std::size_t cell) { return owner[cell]; }, segments);
  out += "    </Piece>\n  </UnstructuredGrid>\n</VTKFile>\n";
  return out;
}

const CellArray* find_cell_array(const Polylines& lines, const char* name) {
  for (const CellArray& array : lines.cell_data)
    if (array.name == name) return &array;
  return nullptr;
}

// CSV: r and s from the lattice arrays fibre_r / fibre_s when both exist, else r = the fibre's
// index and s = 0; other cell arrays have no column and are not written.
std::string csv_text(const Polylines& lines) {
  const CellArray* r_array = find_cell_array(lines, "fibre_r");
  const CellArray* s_array = find_cell_array(lines, "fibre_s");
  const bool lattice = r_array != nullptr && s_array != nullptr;
  std::string out = "fibre,r,s,point,x,y,z\n";
  for (std::size_t f = 0; f < lines.lines.size(); ++f) {
    std::string prefix;
    detail::append_int(prefix, static_cast<long long>(f));
    prefix += ',';
    if (lattice) {
      detail::append_double(prefix, r_array->values[f]);
      prefix += ',';
      detail::append_double(prefix, s_array->values[f]);
    } else {
      detail::append_int(prefix, static_cast<long long>(f));
      prefix += ",0";
    }
    prefix += ',';
    const auto& line = lines.lines[f];
    for (std::size_t i = 0; i < line.size(); ++i) {
      out += prefix;
      detail::append_int(out, static_cast<long long>(i));
      for (int k = 0; k < 3; ++k) {
        out += ',';
        detail::append_double(out, line[i][k]);
      }
      out += '\n';
    }
  }
  return out;
}

}  // namespace

void write_polylines(const std::string& path, const Polylines& lines) {
  const std::string ext = lower_extension(path);
  if (!is_polyline_extension(ext))
    throw InputError(ErrorCode::unknown_format,
                     path + ": cannot write polylines as '" + ext + "' (use .vtk, .vtp, .vtu, .obj or .csv)");
  for (const auto& line : lines.lines)
    for (const Vec3& p : line) FASCICLE_CHECK(p.allFinite(), "writing " + path + ": a polyline point is not finite");
  for (const CellArray& array : lines.cell_data) {
    FASCICLE_CHECK(array.values.size() == lines.lines.size(),
                   "writing " + path + ": cell array '" + array.name + "' does not hold one value per line");
    for (double v : array.values)
      FASCICLE_CHECK(std::isfinite(v),
                     "writing " + path + ": cell array '" + array.name + "' holds a value that is not finite");
  }
  const std::string content = ext == "vtk"   ? vtk_text(lines)
                              : ext == "vtp" ? vtp_text(lines)
                              : ext == "vtu" ? vtu_text(lines)
                              : ext == "csv" ? csv_text(lines)
                                             : obj_text(lines);
  write_file_atomically(
      path, [&](std::ostream& out) { out.write(content.data(), static_cast<std::streamsize>(content.size())); });
}

}  // namespace fascicle
