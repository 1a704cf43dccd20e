// Legacy VTK reader for POLYDATA (Kitware, "VTK File Formats", legacy section), ASCII and BINARY
// (big endian). Reads POINTS, POLYGONS, TRIANGLE_STRIPS and LINES in the classic cell-array form
// (`n size` then `k i1 .. ik` per cell) and the VTK 5.1 form (OFFSETS + CONNECTIVITY arrays);
// VERTICES are read past; a dataset FIELD or METADATA block is skipped; CELL_DATA scalar and field arrays
// are kept for the LINES cells; reading stops at POINT_DATA or any other attribute, which carries
// no geometry. Tolerates blank lines between the title and the ASCII/BINARY line (ALBA/NMSBuilder).
#include "geometry/detail/parse_cursor.h"

#include <algorithm>
#include <cctype>
#include <climits>
#include <optional>

namespace fascicle::detail {

namespace {

std::optional<Scalar> vtk_scalar(std::string_view name) {
  std::string n(name);
  std::transform(n.begin(), n.end(), n.begin(), [](unsigned char c) { return std::tolower(c); });
  if (n == "char" || n == "vtktypeint8" || n == "signed_char") return Scalar::i8;
  if (n == "unsigned_char" || n == "vtktypeuint8") return Scalar::u8;
  if (n == "short" || n == "vtktypeint16") return Scalar::i16;
  if (n == "unsigned_short" || n == "vtktypeuint16") return Scalar::u16;
  if (n == "int" || n == "vtktypeint32") return Scalar::i32;
  if (n == "unsigned_int" || n == "vtktypeuint32") return Scalar::u32;
  if (n == "long" || n == "vtktypeint64" || n == "vtkidtype") return Scalar::i64;
  if (n == "unsigned_long" || n == "vtktypeuint64") return Scalar::u64;
  if (n == "float" || n == "vtktypefloat32") return Scalar::f32;
  if (n == "double" || n == "vtktypefloat64") return Scalar::f64;
  return std::nullopt;
}

bool iequals(std::string_view a, std::string_view b) {
  if (a.size() != b.size()) return false;
  for (std::size_t i = 0; i < a.size(); ++i)
    if (std::toupper(static_cast<unsigned char>(a[i])) != std::toupper(static_cast<unsigned char>(b[i]))) return false;
  return true;
}

class VtkReader {
 public:
  VtkReader(const std::string& path, std::string_view data, const ReadOptions& options)
      : in_(path, data), options_(options) {}

  VtkPolyData read() {
    read_header();
    bool have_points = false;
    for (;;) {
      const std::string_view keyword = in_.token_any();
      if (keyword.empty()) break;
      if (iequals(keyword, "POINTS")) {
        if (have_points) in_.fail(ErrorCode::malformed, "second POINTS section");
        read_points();
        have_points = true;
      } else if (iequals(keyword, "POLYGONS") || iequals(keyword, "TRIANGLE_STRIPS") || iequals(keyword, "LINES") ||
                 iequals(keyword, "VERTICES")) {
        if (!have_points) in_.fail(ErrorCode::malformed, std::string(keyword) + " before POINTS");
        read_cells(keyword);
      } else if (iequals(keyword, "FIELD")) {
        skip_field();
      } else if (iequals(keyword, "METADATA")) {
        skip_metadata();
      } else if (iequals(keyword, "CELL_DATA")) {
        read_cell_data();
        break;
      } else if (iequals(keyword, "POINT_DATA")) {
        break;  // attributes only from here on
      } else {
        in_.fail(ErrorCode::malformed, "unexpected '" + ParseCursor::shorten(keyword) + "' in POLYDATA");
      }
    }
    if (!have_points) in_.fail(ErrorCode::malformed, "no POINTS section");
    return std::move(out_);
  }

 private:
  void read_header() {
    in_.skip_byte_order_mark();
    // "# " first, checked before the first line's end is searched for (garbage may have none:
    // the whole file would be read to find it).
    if (in_.data().substr(in_.pos(), 2) != "# ")
      in_.fail_at_line(1, ErrorCode::unknown_format,
                       "not a legacy VTK file (first line is not '# vtk DataFile Version ...')");
    const std::string_view first = in_.rest_of_line();
    if (first.substr(0, 2) != "# " || first.find("vtk") == std::string_view::npos ||
        first.find("DataFile") == std::string_view::npos)
      in_.fail_at_line(1, ErrorCode::unknown_format,
                       "not a legacy VTK file (first line is not '# vtk DataFile Version ...')");
    if (in_.at_end()) in_.fail(ErrorCode::truncated, "file ends after the first line");
    in_.rest_of_line();                                 // title
    const std::string_view encoding = in_.token_any();  // ALBA writes a blank line before it
    if (encoding.empty()) in_.fail(ErrorCode::truncated, "file ends before ASCII/BINARY");
    if (iequals(encoding, "BINARY"))
      binary_ = true;
    else if (!iequals(encoding, "ASCII"))
      in_.fail(ErrorCode::malformed, "expected ASCII or BINARY, found '" + ParseCursor::shorten(encoding) + "'");
    end_line();
    const std::string_view dataset = in_.token_any();
    if (!iequals(dataset, "DATASET")) {
      if (dataset.empty()) in_.fail(ErrorCode::truncated, "file ends before DATASET");
      in_.fail(ErrorCode::malformed, "expected DATASET, found '" + ParseCursor::shorten(dataset) + "'");
    }
    const std::string_view type = in_.token_in_line();
    if (!iequals(type, "POLYDATA"))
      in_.fail(ErrorCode::unknown_format,
               "dataset type '" + ParseCursor::shorten(type) + "' is not supported (only POLYDATA)");
    end_line();
  }

  /// Ends a keyword line: nothing else may follow on it; binary data starts after its newline.
  void end_line() {
    if (!in_.at_line_end())
      in_.fail(ErrorCode::malformed, "unexpected '" + ParseCursor::shorten(in_.token_in_line()) + "'");
    in_.skip_to_next_line();
    if (binary_) in_.set_binary_locations(true);
  }

  Scalar type_in_line(bool integer_only) {
    const std::string_view name = in_.token_in_line();
    const auto type = vtk_scalar(name);
    if (!type) in_.fail(ErrorCode::malformed, "unknown data type '" + ParseCursor::shorten(name) + "'");
    if (integer_only && scalar_is_float(*type))
      in_.fail(ErrorCode::malformed, "cell indices must have an integer type");
    return *type;
  }

  /// Checks a declared count of values (not elements: max_elements applies to the point and
  /// cell counts) against the file size; then makes sure binary data is all there.
  void check_values(std::uint64_t count, Scalar type, const char* what) {
    const std::uint64_t min_bytes = binary_ ? scalar_size(type) : 2;  // ASCII: a digit and a blank
    if (count > in_.size() / min_bytes)
      in_.fail(ErrorCode::too_large, std::string("declares ") + std::to_string(count) + " values in " + what +
                                         " but the file has only " + std::to_string(in_.size()) + " bytes");
    if (binary_ && count * scalar_size(type) > in_.remaining())
      in_.fail(ErrorCode::truncated, std::string("file ends inside ") + what + " (" +
                                         std::to_string(count * scalar_size(type)) + " bytes declared, " +
                                         std::to_string(in_.remaining()) + " left)");
  }

  double real(Scalar type, const char* what) {
    if (!binary_) return in_.number(what, false);
    const std::size_t at = in_.pos();
    const double value = in_.scalar_unchecked(type, true);  // bounds checked by check_values
    if (!std::isfinite(value)) in_.fail_at_byte(at, ErrorCode::bad_number, std::string(what) + " is not finite");
    return value;
  }

  std::int64_t integer(Scalar type, const char* what) {
    if (!binary_) return in_.integer(what, false);
    return in_.integer_unchecked(type, true);
  }

  /// Reads a point index, reporting a bad one at its own byte offset (binary) or line (ASCII).
  int point_index(Scalar type) {
    const std::size_t at = in_.pos();
    const std::int64_t value = integer(type, "point index");
    if (value < 0 || static_cast<std::uint64_t>(value) >= out_.points.size()) {
      const std::string what = "point index " + std::to_string(value) + " is out of range (" +
                               std::to_string(out_.points.size()) + " points)";
      if (binary_) in_.fail_at_byte(at, ErrorCode::index_out_of_range, what);
      in_.fail(ErrorCode::index_out_of_range, what);
    }
    return static_cast<int>(value);
  }

  void read_points() {
    const std::uint64_t n = in_.count("point count", true);
    const Scalar type = type_in_line(false);
    end_line();
    check_declared_count(in_, n, binary_ ? 3 * scalar_size(type) : 6, in_.size(), "points", options_);
    check_values(3 * n, type, "point coordinates");
    out_.points.resize(static_cast<std::size_t>(n));
    for (auto& p : out_.points) {
      p.x() = real(type, "x coordinate");
      p.y() = real(type, "y coordinate");
      p.z() = real(type, "z coordinate");
    }
  }

  /// Reads one cell section into index lists (VERTICES are read and dropped).
  void read_cells(std::string_view keyword) {
    const std::uint64_t cells = in_.count("cell count", true);
    const std::uint64_t size = in_.count("cell array size", true);
    end_line();
    const bool strips = iequals(keyword, "TRIANGLE_STRIPS");
    std::vector<std::vector<int>> lists;
    const std::string_view next = peek_token();
    if (iequals(next, "OFFSETS")) {
      lists = read_offsets_connectivity(cells, size);
    } else {
      check_declared_count(in_, cells, binary_ ? 4 : 2, in_.size(), "cells", options_);
      check_values(size, Scalar::i32, "cell array");
      if (cells > size)
        in_.fail(ErrorCode::malformed,
                 "cell count " + std::to_string(cells) + " exceeds the cell array size " + std::to_string(size));
      lists.reserve(static_cast<std::size_t>(cells));
      std::uint64_t used = 0;
      for (std::uint64_t c = 0; c < cells; ++c) {
        const std::int64_t k = integer(Scalar::i32, "cell size");
        if (k < 0 || used + 1 + static_cast<std::uint64_t>(k) > size)
          in_.fail(ErrorCode::malformed, "cell " + std::to_string(c) + " has " + std::to_string(k) +
                                             " points, beyond the declared cell array size " + std::to_string(size));
        used += 1 + static_cast<std::uint64_t>(k);
        std::vector<int> cell(static_cast<std::size_t>(k));
        for (auto& index : cell) index = point_index(Scalar::i32);
        lists.push_back(std::move(cell));
      }
      if (used != size)
        in_.fail(ErrorCode::malformed, std::to_string(cells) + " cells use " + std::to_string(used) +
                                           " values, the header declares " + std::to_string(size));
    }
    if (iequals(keyword, "VERTICES")) {
      vertex_cells_ += lists.size();
    } else if (iequals(keyword, "LINES")) {
      line_cells_ += lists.size();
      for (auto& l : lists) out_.lines.push_back(std::move(l));
    } else if (strips) {
      for (const auto& strip : lists) append_strip_triangles(strip, out_.polygons);
    } else {
      for (auto& l : lists) out_.polygons.push_back(std::move(l));
    }
  }

  /// VTK 5.1: `OFFSETS type` with `offsets` values, then `CONNECTIVITY type` with `size` values.
  std::vector<std::vector<int>> read_offsets_connectivity(std::uint64_t offsets, std::uint64_t size) {
    in_.token_any();  // OFFSETS
    const Scalar offset_type = type_in_line(true);
    end_line();
    check_declared_count(in_, offsets, binary_ ? scalar_size(offset_type) : 2, in_.size(), "cell offsets", options_);
    check_values(offsets, offset_type, "OFFSETS array");
    std::vector<std::int64_t> offset(static_cast<std::size_t>(offsets));
    for (std::size_t i = 0; i < offset.size(); ++i) {
      offset[i] = integer(offset_type, "offset");
      const std::int64_t previous = i == 0 ? 0 : offset[i - 1];
      if (offset[i] < previous || static_cast<std::uint64_t>(offset[i]) > size || (i == 0 && offset[i] != 0))
        in_.fail(ErrorCode::malformed,
                 "offset " + std::to_string(offset[i]) + " is out of order or beyond the connectivity size");
    }
    if (!offset.empty() && static_cast<std::uint64_t>(offset.back()) != size)
      in_.fail(ErrorCode::malformed, "last offset " + std::to_string(offset.back()) +
                                         " differs from the connectivity size " + std::to_string(size));
    const std::string_view keyword = in_.token_any();
    if (!iequals(keyword, "CONNECTIVITY"))
      in_.fail(ErrorCode::malformed, "expected CONNECTIVITY, found '" + ParseCursor::shorten(keyword) + "'");
    const Scalar type = type_in_line(true);
    end_line();
    check_values(size, type, "CONNECTIVITY array");
    std::vector<std::vector<int>> lists;
    lists.reserve(offset.empty() ? 0 : offset.size() - 1);
    for (std::size_t c = 0; c + 1 < offset.size(); ++c) {
      std::vector<int> cell(static_cast<std::size_t>(offset[c + 1] - offset[c]));
      for (auto& index : cell) index = point_index(type);
      lists.push_back(std::move(cell));
    }
    return lists;
  }

  /// The next keyword (letters only) without moving: binary data may follow instead.
  std::string_view peek_token() {
    const ParseCursor::Mark mark = in_.mark();
    in_.skip_space_and_comments();
    std::size_t end = in_.pos();
    while (end < in_.size() && (std::isalpha(static_cast<unsigned char>(in_.data()[end])) || in_.data()[end] == '_'))
      ++end;
    const std::string_view t = in_.data().substr(in_.pos(), end - in_.pos());
    in_.reset(mark);
    return t;
  }

  /// FIELD name n, then n arrays `name components tuples type` with their values.
  void skip_field() {
    in_.token_in_line();  // field name
    const std::uint64_t arrays = in_.count("array count", true);
    end_line();
    for (std::uint64_t a = 0; a < arrays; ++a) {
      const std::string_view name = in_.token_any();
      if (name.empty()) in_.fail(ErrorCode::truncated, "file ends inside a FIELD");
      const std::uint64_t components = in_.count("component count", true);
      const std::uint64_t tuples = in_.count("tuple count", true);
      const Scalar type = type_in_line(false);
      end_line();
      if (components > 0 && tuples > UINT64_MAX / components)
        in_.fail(ErrorCode::too_large, "FIELD array is too large");
      skip_values(components * tuples, type, "FIELD array");
    }
  }

  void skip_values(std::uint64_t count, Scalar type, const char* what) {
    check_values(count, type, what);
    if (binary_) {
      in_.skip_bytes(static_cast<std::size_t>(count * scalar_size(type)), what);
    } else {
      for (std::uint64_t i = 0; i < count; ++i)
        if (in_.token_any().empty()) in_.fail(ErrorCode::truncated, std::string("file ends inside ") + what);
    }
  }

  /// METADATA blocks (VTK >= 8) end at the first blank line.
  void skip_metadata() {
    in_.skip_to_next_line();
    while (!in_.at_end()) {
      const std::string_view line = in_.rest_of_line();
      if (line.find_first_not_of(" \t") == std::string_view::npos) break;
    }
  }

  /// CELL_DATA n, then SCALARS arrays and FIELD blocks: their one-component arrays are kept for
  /// the LINES cells; stops at the first attribute of another kind.
  void read_cell_data() {
    const std::uint64_t n = in_.count("cell data count", true);
    end_line();
    for (;;) {
      const std::string_view keyword = in_.token_any();
      if (keyword.empty()) break;
      if (iequals(keyword, "FIELD")) {
        in_.token_in_line();  // field name
        const std::uint64_t arrays = in_.count("array count", true);
        end_line();
        for (std::uint64_t a = 0; a < arrays; ++a) {
          const std::string_view name = in_.token_any();
          if (name.empty()) in_.fail(ErrorCode::truncated, "file ends inside a FIELD");
          CellArray array;
          array.name = std::string(name);
          const std::uint64_t components = in_.count("component count", true);
          const std::uint64_t tuples = in_.count("tuple count", true);
          const Scalar type = type_in_line(false);
          end_line();
          if (components > 0 && tuples > UINT64_MAX / components)
            in_.fail(ErrorCode::too_large, "FIELD array is too large");
          keep_or_skip(std::move(array), n, tuples, components, type, "FIELD array");
        }
        continue;
      }
      if (!iequals(keyword, "SCALARS")) break;
      CellArray array;
      array.name = std::string(in_.token_in_line());
      const Scalar type = type_in_line(false);
      std::uint64_t components = 1;
      if (!in_.at_line_end()) components = in_.count("component count", true);
      end_line();
      if (iequals(peek_token(), "LOOKUP_TABLE")) {
        in_.token_any();
        in_.token_in_line();
        end_line();
      }
      if (components > 0 && n > UINT64_MAX / components) in_.fail(ErrorCode::too_large, "SCALARS array is too large");
      keep_or_skip(std::move(array), n, n, components, type, "SCALARS array");
    }
  }

  /// An array of `tuples` x `components` values: kept (its LINES slice) when it has one component
  /// and one value per cell of the `cells` declared, else skipped.
  void keep_or_skip(CellArray array, std::uint64_t cells, std::uint64_t tuples, std::uint64_t components, Scalar type,
                    const char* what) {
    if (components != 1 || tuples != cells || line_cells_ == 0 || vertex_cells_ + line_cells_ > cells) {
      skip_values(tuples * components, type, what);
      return;
    }
    check_values(cells, type, what);
    array.values.reserve(static_cast<std::size_t>(line_cells_));
    for (std::uint64_t i = 0; i < cells; ++i) {
      const double value = real(type, "cell value");
      if (i >= vertex_cells_ && i < vertex_cells_ + line_cells_) array.values.push_back(value);
    }
    out_.line_cell_data.push_back(std::move(array));
  }

  ParseCursor in_;
  const ReadOptions& options_;
  bool binary_ = false;
  std::uint64_t vertex_cells_ = 0;
  std::uint64_t line_cells_ = 0;
  VtkPolyData out_;
};

}  // namespace

VtkPolyData read_vtk(const std::string& path, std::string_view data, const ReadOptions& options) {
  return VtkReader(path, data, options).read();
}

}  // namespace fascicle::detail
