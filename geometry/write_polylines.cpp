// Polyline writers: legacy VTK polydata (POINTS + LINES + one CELL_DATA SCALARS array per
// cell_data entry), VTK XML PolyData (.vtp, ASCII), OBJ (`v` + `l`; cell data has no place in
// OBJ and is not written) and CSV (one row per point: fibre,r,s,point,x,y,z).
#include "geometry/atomic_file.h"
#include "geometry/detail/parse_cursor.h"
#include "geometry/errors.h"
#include "geometry/mesh_io.h"

#include <cctype>
#include <cmath>

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
  out += "      <Points>\n        <DataArray type=\"Float64\" Name=\"Points\" NumberOfComponents=\"3\" format=\"ascii\">\n";
  for (const auto& line : lines.lines)
    for (const Vec3& p : line) {
      out += "          ";
      append_point(out, p);
    }
  out += "        </DataArray>\n      </Points>\n";
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
  if (!lines.cell_data.empty()) {
    out += "      <CellData>\n";
    for (std::size_t a = 0; a < lines.cell_data.size(); ++a) {
      const CellArray& array = lines.cell_data[a];
      out += "        <DataArray type=\"Float64\" Name=\"" +
             xml_escape(array.name.empty() ? "array" + std::to_string(a) : array.name) + "\" format=\"ascii\">\n";
      for (double v : array.values) {
        out += "          ";
        detail::append_double(out, v);
        out += '\n';
      }
      out += "        </DataArray>\n";
    }
    out += "      </CellData>\n";
  }
  out += "    </Piece>\n  </PolyData>\n</VTKFile>\n";
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
  if (ext != "vtk" && ext != "vtp" && ext != "obj" && ext != "csv")
    throw InputError(ErrorCode::unknown_format,
                     path + ": cannot write polylines as '" + ext + "' (use .vtk, .vtp, .obj or .csv)");
  for (const auto& line : lines.lines)
    for (const Vec3& p : line) FASCICLE_CHECK(p.allFinite(), "writing " + path + ": a polyline point is not finite");
  for (const CellArray& array : lines.cell_data) {
    FASCICLE_CHECK(array.values.size() == lines.lines.size(),
                   "writing " + path + ": cell array '" + array.name + "' does not hold one value per line");
    for (double v : array.values) FASCICLE_CHECK(std::isfinite(v), "writing " + path + ": cell array '" + array.name + "' holds a value that is not finite");
  }
  const std::string content = ext == "vtk"   ? vtk_text(lines)
                              : ext == "vtp" ? vtp_text(lines)
                              : ext == "csv" ? csv_text(lines)
                                             : obj_text(lines);
  write_file_atomically(path, [&](std::ostream& out) { out.write(content.data(), static_cast<std::streamsize>(content.size())); });
}

}  // namespace fascicle
