// Polyline readers: the dispatch by extension, VTK XML PolyData (.vtp, ASCII DataArrays) and
// CSV (fibre,r,s,point,x,y,z). Legacy VTK and OBJ are read by read_vtk.cpp / read_obj.cpp.
//
// VTP: Kitware, "VTK File Formats", XML section: one <Piece> with NumberOfPoints and
// NumberOfLines, <Points> with one 3-component DataArray, <Lines> with the `connectivity` and
// `offsets` arrays (offsets[i] = end of line i in connectivity), and <CellData> arrays in the
// cell order Verts, Lines, Strips, Polys, of which the lines' slice is kept. Only format="ascii"
// arrays are read (binary and appended data are base64/raw blocks this reader does not decode;
// ParaView saves ASCII with "Data Mode: Ascii"). A small XML scanner of our own: the subset VTK
// writes (tags, attributes in double or single quotes, the five predefined entities, comments,
// processing instructions), with line numbers for every error.
#include "geometry/detail/parse_cursor.h"
#include "geometry/atomic_file.h"
#include "geometry/errors.h"
#include "geometry/mesh_io.h"

#include <algorithm>
#include <cctype>
#include <charconv>
#include <climits>
#include <cmath>
#include <map>
#include <optional>

namespace fascicle {

namespace {

/// Throws InputError "<file>: line N: <what>".
[[noreturn]] void fail_line(const std::string& path, std::size_t line, ErrorCode code, const std::string& what) {
  throw InputError(code, path + ": line " + std::to_string(line) + ": " + what);
}

std::uint64_t element_limit(const ReadOptions& options) {
  return std::min<std::uint64_t>(options.max_elements, INT_MAX);
}

// ---- VTP --------------------------------------------------------------------------------------

struct XmlTag {
  std::string name;
  std::map<std::string, std::string> attributes;
  bool closing = false;       ///< </name>
  bool self_closing = false;  ///< <name ... />
  std::size_t line = 1;
};

/// Pull scanner over the XML subset VTK writes.
class XmlScanner {
 public:
  XmlScanner(const std::string& path, std::string_view data) : path_(path), data_(data) {
    if (data_.size() >= 3 && data_.compare(0, 3, "\xEF\xBB\xBF") == 0) pos_ = 3;
  }

  [[noreturn]] void fail(ErrorCode code, const std::string& what) const { fail_line(path_, line_, code, what); }
  std::size_t line() const { return line_; }

  /// The next tag, skipping text, comments, processing instructions and declarations; nullopt at
  /// the end of the file. Text between tags is skipped (callers that need it use read_text).
  std::optional<XmlTag> next_tag() {
    for (;;) {
      while (pos_ < data_.size() && data_[pos_] != '<') advance();
      if (pos_ >= data_.size()) return std::nullopt;
      if (starts_with("<!--")) {
        skip_past("-->", "a comment");
      } else if (starts_with("<?")) {
        skip_past("?>", "a processing instruction");
      } else if (starts_with("<!")) {
        skip_past(">", "a declaration");
      } else {
        return tag();
      }
    }
  }

  /// Reads the text up to the next '<' (the content of a DataArray) and calls `token(t, line)`
  /// for each blank-separated token.
  template <class F>
  void read_text(F&& token) {
    for (;;) {
      while (pos_ < data_.size() && is_space(data_[pos_])) advance();
      if (pos_ >= data_.size()) fail(ErrorCode::truncated, "file ends inside a DataArray");
      if (data_[pos_] == '<') return;
      const std::size_t begin = pos_;
      while (pos_ < data_.size() && !is_space(data_[pos_]) && data_[pos_] != '<') ++pos_;
      token(data_.substr(begin, pos_ - begin), line_);
    }
  }

 private:
  static bool is_space(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\n' || c == '\f' || c == '\v'; }
  static bool is_name_char(char c) {
    return std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '-' || c == '.' || c == ':';
  }
  void advance() {
    if (data_[pos_] == '\n') ++line_;
    ++pos_;
  }
  bool starts_with(std::string_view s) const { return data_.compare(pos_, s.size(), s) == 0; }
  void skip_past(std::string_view end, const char* what) {
    const std::size_t start_line = line_;
    while (pos_ < data_.size() && !starts_with(end)) advance();
    if (pos_ >= data_.size())
      fail_line(path_, start_line, ErrorCode::truncated, std::string("file ends inside ") + what);
    pos_ += end.size();
  }
  void skip_spaces() {
    while (pos_ < data_.size() && is_space(data_[pos_])) advance();
  }
  void require_more(const char* what) const {
    if (pos_ >= data_.size()) fail(ErrorCode::truncated, std::string("file ends inside ") + what);
  }
  std::string name() {
    const std::size_t begin = pos_;
    while (pos_ < data_.size() && is_name_char(data_[pos_])) ++pos_;
    return std::string(data_.substr(begin, pos_ - begin));
  }

  std::string unescape(std::string_view raw) const {
    std::string out;
    for (std::size_t i = 0; i < raw.size(); ++i) {
      if (raw[i] != '&') {
        out += raw[i];
        continue;
      }
      const std::size_t semi = raw.find(';', i);
      if (semi == std::string_view::npos) fail(ErrorCode::malformed, "unterminated '&' entity in an attribute");
      const std::string_view entity = raw.substr(i + 1, semi - i - 1);
      if (entity == "amp")
        out += '&';
      else if (entity == "lt")
        out += '<';
      else if (entity == "gt")
        out += '>';
      else if (entity == "quot")
        out += '"';
      else if (entity == "apos")
        out += '\'';
      else
        fail(ErrorCode::malformed, "unknown entity '&" + detail::ParseCursor::shorten(entity) + ";'");
      i = semi;
    }
    return out;
  }

  XmlTag tag() {
    XmlTag t;
    t.line = line_;
    ++pos_;  // '<'
    if (pos_ < data_.size() && data_[pos_] == '/') {
      t.closing = true;
      ++pos_;
    }
    t.name = name();
    if (t.name.empty()) {
      require_more("a tag");
      fail(ErrorCode::malformed, "expected a tag name after '<'");
    }
    for (;;) {
      skip_spaces();
      require_more(("tag <" + t.name + ">").c_str());
      const char c = data_[pos_];
      if (c == '>') {
        ++pos_;
        return t;
      }
      if (c == '/' && !t.closing) {
        ++pos_;
        require_more(("tag <" + t.name + ">").c_str());
        if (data_[pos_] != '>') fail(ErrorCode::malformed, "expected '>' after '/' in tag <" + t.name + ">");
        ++pos_;
        t.self_closing = true;
        return t;
      }
      if (t.closing) fail(ErrorCode::malformed, "unexpected '" + std::string(1, c) + "' in end tag </" + t.name + ">");
      const std::string key = name();
      if (key.empty()) fail(ErrorCode::malformed, "unexpected '" + std::string(1, c) + "' in tag <" + t.name + ">");
      skip_spaces();
      require_more(("tag <" + t.name + ">").c_str());
      if (data_[pos_] != '=') fail(ErrorCode::malformed, "attribute '" + key + "' of <" + t.name + "> has no value");
      ++pos_;
      skip_spaces();
      require_more(("tag <" + t.name + ">").c_str());
      const char quote = data_[pos_];
      if (quote != '"' && quote != '\'')
        fail(ErrorCode::malformed, "value of attribute '" + key + "' of <" + t.name + "> is not quoted");
      ++pos_;
      const std::size_t begin = pos_;
      while (pos_ < data_.size() && data_[pos_] != quote) advance();
      require_more(("attribute '" + key + "'").c_str());
      t.attributes[key] = unescape(data_.substr(begin, pos_ - begin));
      ++pos_;
    }
  }

  const std::string& path_;
  std::string_view data_;
  std::size_t pos_ = 0;
  std::size_t line_ = 1;
};

/// A DataArray's attributes that matter here.
struct ArrayInfo {
  std::string name, type, format;
  std::uint64_t components = 1;
  std::size_t line = 1;
};

class VtpReader {
 public:
  /// `grid`: a .vtu UnstructuredGrid of line and poly-line cells instead of a .vtp PolyData.
  VtpReader(const std::string& path, std::string_view data, const ReadOptions& options, bool grid = false)
      : path_(path), data_size_(data.size()), options_(options), xml_(path, data), grid_(grid) {}

  Polylines read() {
    std::optional<XmlTag> root = xml_.next_tag();
    if (!root || root->closing || root->name != "VTKFile")
      fail_line(path_, root ? root->line : xml_.line(), ErrorCode::unknown_format,
                "not a VTK XML file (expected a <VTKFile> element)");
    const auto type = root->attributes.find("type");
    const std::string expected = grid_ ? "UnstructuredGrid" : "PolyData";
    if (type == root->attributes.end() || type->second != expected)
      fail_line(path_, root->line, ErrorCode::unknown_format,
                "VTK XML file of type '" + (type == root->attributes.end() ? std::string() : type->second) +
                    "', expected " + expected);
    if (root->self_closing) fail_line(path_, root->line, ErrorCode::file_empty, "holds no polylines");
    std::vector<XmlTag> stack{*root};
    while (!stack.empty()) {
      std::optional<XmlTag> tag = xml_.next_tag();
      if (!tag) xml_.fail(ErrorCode::truncated, "file ends inside <" + stack.back().name + ">");
      if (tag->closing) {
        if (tag->name != stack.back().name)
          fail_line(path_, tag->line, ErrorCode::malformed,
                    "end tag </" + tag->name + "> does not close <" + stack.back().name + ">");
        stack.pop_back();
        continue;
      }
      if (tag->name == "Piece") start_piece(*tag);
      if (tag->name == "DataArray") {
        const std::string parent = stack.back().name;
        const bool in_piece = stack.size() >= 2 && stack[stack.size() - 2].name == "Piece";
        if (!tag->self_closing) read_array(*tag, in_piece ? parent : std::string());
        // read_array stops at the array's end tag, which closes it.
        continue;
      }
      if (!tag->self_closing) stack.push_back(*tag);
    }
    return finish();
  }

 private:
  std::uint64_t count_attribute(const XmlTag& tag, const char* key, bool required) {
    const auto it = tag.attributes.find(key);
    if (it == tag.attributes.end()) {
      if (required) fail_line(path_, tag.line, ErrorCode::malformed, "<" + tag.name + "> has no " + key);
      return 0;
    }
    std::uint64_t value = 0;
    const std::string& text = it->second;
    const auto result = std::from_chars(text.data(), text.data() + text.size(), value);
    if (result.ec == std::errc::result_out_of_range)
      fail_line(path_, tag.line, ErrorCode::too_large,
                std::string(key) + " " + detail::ParseCursor::shorten(text) + " is too large");
    if (text.empty() || result.ec != std::errc() || result.ptr != text.data() + text.size())
      fail_line(path_, tag.line, ErrorCode::malformed,
                std::string(key) + " '" + detail::ParseCursor::shorten(text) + "' is not a non-negative integer");
    return value;
  }

  /// A declared count must be below the element limit and fit in the file (at least 2 bytes per
  /// value: a digit and a blank), checked before anything is allocated.
  void check_count(std::size_t line, std::uint64_t count, std::uint64_t values_each, const char* what) const {
    const std::uint64_t limit = element_limit(options_);
    if (count > limit)
      fail_line(path_, line, ErrorCode::too_large,
                "declares " + std::to_string(count) + " " + what + ", more than the limit of " + std::to_string(limit));
    if (count > data_size_ / (2 * values_each))
      fail_line(path_, line, ErrorCode::too_large,
                "declares " + std::to_string(count) + " " + what + " but the file has only " +
                    std::to_string(data_size_) + " bytes");
  }

  void start_piece(const XmlTag& tag) {
    if (have_piece_) fail_line(path_, tag.line, ErrorCode::malformed, "second <Piece> (only one piece is read)");
    have_piece_ = true;
    n_points_ = count_attribute(tag, "NumberOfPoints", true);
    n_lines_ = count_attribute(tag, grid_ ? "NumberOfCells" : "NumberOfLines", grid_);
    n_verts_ = count_attribute(tag, "NumberOfVerts", false);
    n_strips_ = count_attribute(tag, "NumberOfStrips", false);
    n_polys_ = count_attribute(tag, "NumberOfPolys", false);
    check_count(tag.line, n_points_, 3, "points");
    check_count(tag.line, n_lines_, 1, "lines");
    check_count(tag.line, n_verts_, 1, "vertex cells");
    check_count(tag.line, n_strips_, 1, "strips");
    check_count(tag.line, n_polys_, 1, "polygons");
    check_count(tag.line, n_verts_ + n_lines_ + n_strips_ + n_polys_, 1, "cells");
  }

  /// Reads the values of one DataArray (its start tag just read) when `section` is Points, Lines
  /// or CellData of the piece, else skips them; consumes the end tag.
  void read_array(const XmlTag& tag, const std::string& section) {
    ArrayInfo info;
    info.line = tag.line;
    if (auto it = tag.attributes.find("Name"); it != tag.attributes.end()) info.name = it->second;
    if (auto it = tag.attributes.find("type"); it != tag.attributes.end()) info.type = it->second;
    if (auto it = tag.attributes.find("format"); it != tag.attributes.end()) info.format = it->second;
    info.components = tag.attributes.count("NumberOfComponents") ? count_attribute(tag, "NumberOfComponents", true) : 1;
    const std::string cells = grid_ ? "Cells" : "Lines";
    const bool wanted = section == "Points" ||
                        (section == cells &&
                         (info.name == "connectivity" || info.name == "offsets" || (grid_ && info.name == "types"))) ||
                        (section == "CellData" && info.components == 1);
    if (wanted && info.format != "ascii")
      fail_line(path_, tag.line, ErrorCode::unknown_format,
                "DataArray '" + info.name + "' has format '" + info.format +
                    "'; only format=\"ascii\" is read (save as ASCII)");
    if (!wanted) {
      // Skipped arrays may hold anything up to their end tag (ASCII or base64).
      skip_to_end_of_array();
      return;
    }
    const bool integer = section == cells;
    std::vector<double> reals;
    std::vector<std::int64_t> integers;
    const std::uint64_t limit = element_limit(options_);
    std::uint64_t count = 0;
    xml_.read_text([&](std::string_view t, std::size_t line) {
      if (++count > limit)
        fail_line(path_, line, ErrorCode::too_large,
                  "DataArray '" + info.name + "' holds more than " + std::to_string(limit) + " values");
      if (integer) {
        std::int64_t v = 0;
        if (!detail::ParseCursor::parse_integer(t, v))
          fail_line(
              path_, line, ErrorCode::malformed,
              "value '" + detail::ParseCursor::shorten(t) + "' of DataArray '" + info.name + "' is not an integer");
        integers.push_back(v);
      } else {
        double v = 0.0;
        if (!detail::ParseCursor::parse_double(t, v))
          fail_line(path_, line, ErrorCode::bad_number,
                    "value '" + detail::ParseCursor::shorten(t) + "' of DataArray '" + info.name + "' is not a number");
        if (!std::isfinite(v))
          fail_line(path_, line, ErrorCode::bad_number,
                    "value " + detail::ParseCursor::shorten(t) + " of DataArray '" + info.name + "' is not finite");
        reals.push_back(v);
      }
    });
    expect_array_end();
    if (!have_piece_) fail_line(path_, info.line, ErrorCode::malformed, "DataArray outside a <Piece>");
    if (section == "Points") {
      if (info.components != 3)
        fail_line(path_, info.line, ErrorCode::malformed,
                  "Points DataArray has " + std::to_string(info.components) + " components, expected 3");
      if (reals.size() != 3 * n_points_)
        fail_line(path_, info.line, ErrorCode::malformed,
                  "Points DataArray holds " + std::to_string(reals.size()) + " values, NumberOfPoints = " +
                      std::to_string(n_points_) + " needs " + std::to_string(3 * n_points_));
      points_.resize(static_cast<std::size_t>(n_points_));
      for (std::size_t i = 0; i < points_.size(); ++i)
        points_[i] = Vec3(reals[3 * i], reals[3 * i + 1], reals[3 * i + 2]);
      have_points_ = true;
    } else if (section == cells) {
      if (info.name == "types") {
        for (std::size_t i = 0; i < integers.size(); ++i)
          if (integers[i] != 3 && integers[i] != 4)
            fail_line(path_, info.line, ErrorCode::unknown_format,
                      "cell " + std::to_string(i) + " has VTK type " + std::to_string(integers[i]) +
                          "; a polyline file holds lines (3) and poly-lines (4) only");
        if (integers.size() != n_lines_)
          fail_line(path_, info.line, ErrorCode::malformed,
                    "types array holds " + std::to_string(integers.size()) +
                        " values for NumberOfCells = " + std::to_string(n_lines_));
        have_types_ = true;
        return;
      }
      (info.name == "connectivity" ? connectivity_ : offsets_) = std::move(integers);
      (info.name == "connectivity" ? connectivity_line_ : offsets_line_) = info.line;
    } else {
      const std::uint64_t cell_count = n_verts_ + n_lines_ + n_strips_ + n_polys_;
      if (reals.size() != cell_count)
        fail_line(path_, info.line, ErrorCode::malformed,
                  "CellData array '" + info.name + "' holds " + std::to_string(reals.size()) + " values for " +
                      std::to_string(cell_count) + " cells");
      CellArray array;
      array.name = info.name;
      array.values.assign(reals.begin() + static_cast<std::ptrdiff_t>(n_verts_),
                          reals.begin() + static_cast<std::ptrdiff_t>(n_verts_ + n_lines_));
      cell_data_.push_back(std::move(array));
    }
  }

  void expect_array_end() {
    std::optional<XmlTag> end = xml_.next_tag();
    if (!end) xml_.fail(ErrorCode::truncated, "file ends inside a DataArray");
    if (!end->closing || end->name != "DataArray")
      fail_line(path_, end->line, ErrorCode::malformed,
                "expected </DataArray>, found <" + std::string(end->closing ? "/" : "") + end->name + ">");
  }

  void skip_to_end_of_array() {
    for (;;) {
      std::optional<XmlTag> t = xml_.next_tag();
      if (!t) xml_.fail(ErrorCode::truncated, "file ends inside a DataArray");
      if (t->closing && t->name == "DataArray") return;
    }
  }

  Polylines finish() {
    if (!have_piece_ || n_lines_ == 0) throw InputError(ErrorCode::file_empty, path_ + ": holds no polylines");
    if (!have_points_) throw InputError(ErrorCode::malformed, path_ + ": the <Piece> has no <Points> DataArray");
    if (offsets_line_ == 0 || connectivity_line_ == 0 || (grid_ && !have_types_))
      throw InputError(ErrorCode::malformed,
                       path_ + (grid_ ? ": <Cells> needs the DataArrays 'connectivity', 'offsets' and 'types'"
                                      : ": <Lines> needs the DataArrays 'connectivity' and 'offsets'"));
    if (offsets_.size() != n_lines_)
      fail_line(path_, offsets_line_, ErrorCode::malformed,
                "offsets array holds " + std::to_string(offsets_.size()) +
                    " values for NumberOfLines = " + std::to_string(n_lines_));
    Polylines result;
    result.lines.reserve(static_cast<std::size_t>(n_lines_));
    std::int64_t begin = 0;
    for (std::size_t i = 0; i < offsets_.size(); ++i) {
      const std::int64_t end = offsets_[i];
      if (end < begin || end > static_cast<std::int64_t>(connectivity_.size()))
        fail_line(path_, offsets_line_, ErrorCode::malformed,
                  "offset " + std::to_string(i) + " (" + std::to_string(end) + ") is not between the previous offset " +
                      std::to_string(begin) + " and the connectivity size " + std::to_string(connectivity_.size()));
      std::vector<Vec3> line;
      line.reserve(static_cast<std::size_t>(end - begin));
      for (std::int64_t k = begin; k < end; ++k) {
        const std::int64_t index = connectivity_[static_cast<std::size_t>(k)];
        if (index < 0 || static_cast<std::uint64_t>(index) >= points_.size())
          fail_line(path_, connectivity_line_, ErrorCode::index_out_of_range,
                    "connectivity entry " + std::to_string(k) + ": point index " + std::to_string(index) +
                        " is out of range (" + std::to_string(points_.size()) + " points)");
        line.push_back(points_[static_cast<std::size_t>(index)]);
      }
      result.lines.push_back(std::move(line));
      begin = end;
    }
    if (begin != static_cast<std::int64_t>(connectivity_.size()))
      fail_line(path_, offsets_line_, ErrorCode::malformed,
                "the last offset (" + std::to_string(begin) + ") does not match the connectivity size " +
                    std::to_string(connectivity_.size()));
    result.cell_data = std::move(cell_data_);
    if (grid_) join_segments(result);
    return result;
  }

  // A .vtu of segments with a `fibre` array: consecutive cells of one fibre become one polyline.
  static void join_segments(Polylines& result) {
    const auto fibre = std::find_if(result.cell_data.begin(), result.cell_data.end(),
                                    [](const CellArray& a) { return a.name == "fibre"; });
    if (fibre == result.cell_data.end()) return;
    Polylines joined;
    std::vector<std::size_t> first_cell;
    for (std::size_t c = 0; c < result.lines.size(); ++c) {
      const bool same = c > 0 && fibre->values[c] == fibre->values[c - 1] && !joined.lines.back().empty() &&
                        !result.lines[c].empty() && joined.lines.back().back() == result.lines[c].front();
      if (!same) {
        joined.lines.push_back(result.lines[c]);
        first_cell.push_back(c);
        continue;
      }
      joined.lines.back().insert(joined.lines.back().end(), result.lines[c].begin() + 1, result.lines[c].end());
    }
    for (const CellArray& a : result.cell_data) {
      if (a.name == "fibre") continue;
      CellArray kept{a.name, {}};
      for (std::size_t c : first_cell) kept.values.push_back(a.values[c]);
      joined.cell_data.push_back(std::move(kept));
    }
    result = std::move(joined);
  }

  const std::string& path_;
  std::size_t data_size_;
  const ReadOptions& options_;
  XmlScanner xml_;
  bool grid_ = false, have_types_ = false;
  bool have_piece_ = false, have_points_ = false;
  std::uint64_t n_points_ = 0, n_lines_ = 0, n_verts_ = 0, n_strips_ = 0, n_polys_ = 0;
  std::vector<Vec3> points_;
  std::vector<std::int64_t> connectivity_, offsets_;
  std::size_t connectivity_line_ = 0, offsets_line_ = 0;
  std::vector<CellArray> cell_data_;
};

// ---- CSV --------------------------------------------------------------------------------------

Polylines read_csv(const std::string& path, std::string_view data, const ReadOptions& options) {
  static constexpr std::string_view header = "fibre,r,s,point,x,y,z";
  std::size_t pos = 0, line = 0;
  if (data.size() >= 3 && data.compare(0, 3, "\xEF\xBB\xBF") == 0) pos = 3;
  auto next_line = [&](std::string_view& text) {
    if (pos >= data.size()) return false;
    const std::size_t end = std::min(data.find('\n', pos), data.size());
    text = data.substr(pos, end - pos);
    if (!text.empty() && text.back() == '\r') text.remove_suffix(1);
    pos = end + 1;
    ++line;
    return true;
  };
  std::string_view text;
  next_line(text);
  if (text != header)
    fail_line(path, 1, ErrorCode::malformed,
              "expected the header '" + std::string(header) + "', found '" + detail::ParseCursor::shorten(text) + "'");

  struct Row {
    std::int64_t point;
    Vec3 position;
  };
  struct Fibre {
    double r, s;
    std::size_t first_line;
    std::vector<Row> rows;
  };
  std::map<std::int64_t, Fibre> fibres;
  const std::uint64_t limit = element_limit(options);
  std::uint64_t rows = 0;
  while (next_line(text)) {
    if (text.find_first_not_of(" \t") == std::string_view::npos) continue;  // blank line
    if (++rows > limit) fail_line(path, line, ErrorCode::too_large, "more than " + std::to_string(limit) + " rows");
    std::string_view fields[7];
    std::size_t n = 0, begin = 0;
    for (;;) {
      const std::size_t comma = text.find(',', begin);
      const std::string_view field =
          text.substr(begin, comma == std::string_view::npos ? std::string_view::npos : comma - begin);
      if (n < 7) fields[n] = field;
      ++n;
      if (comma == std::string_view::npos) break;
      begin = comma + 1;
    }
    if (n != 7)
      fail_line(path, line, ErrorCode::malformed, "expected 7 comma-separated values, found " + std::to_string(n));
    auto trim = [](std::string_view f) {
      while (!f.empty() && (f.front() == ' ' || f.front() == '\t')) f.remove_prefix(1);
      while (!f.empty() && (f.back() == ' ' || f.back() == '\t')) f.remove_suffix(1);
      return f;
    };
    static const char* const names[7] = {"fibre", "r", "s", "point", "x", "y", "z"};
    std::int64_t integers[2] = {0, 0};  // fibre, point
    double reals[5] = {0, 0, 0, 0, 0};  // r, s, x, y, z
    for (std::size_t k = 0; k < 7; ++k) {
      const std::string_view f = trim(fields[k]);
      if (k == 0 || k == 3) {
        std::int64_t v = 0;
        if (!detail::ParseCursor::parse_integer(f, v) || v < 0)
          fail_line(path, line, ErrorCode::malformed,
                    std::string(names[k]) + " '" + detail::ParseCursor::shorten(f) + "' is not a non-negative integer");
        integers[k == 0 ? 0 : 1] = v;
      } else {
        double v = 0.0;
        if (!detail::ParseCursor::parse_double(f, v))
          fail_line(path, line, ErrorCode::bad_number,
                    std::string(names[k]) + " '" + detail::ParseCursor::shorten(f) + "' is not a number");
        if (!std::isfinite(v))
          fail_line(path, line, ErrorCode::bad_number,
                    std::string(names[k]) + " is " + detail::ParseCursor::shorten(f) + " (not finite)");
        reals[k < 3 ? k - 1 : k - 2] = v;
      }
    }
    auto [it, inserted] = fibres.try_emplace(integers[0], Fibre{reals[0], reals[1], line, {}});
    Fibre& fibre = it->second;
    if (!inserted && (fibre.r != reals[0] || fibre.s != reals[1]))
      fail_line(path, line, ErrorCode::malformed,
                "fibre " + std::to_string(integers[0]) + " has r, s different from its first row (line " +
                    std::to_string(fibre.first_line) + ")");
    fibre.rows.push_back({integers[1], Vec3(reals[2], reals[3], reals[4])});
  }
  if (fibres.empty()) throw InputError(ErrorCode::file_empty, path + ": holds no polylines (only the header)");

  Polylines result;
  result.lines.reserve(fibres.size());
  CellArray r_array{"fibre_r", {}}, s_array{"fibre_s", {}};
  for (auto& [id, fibre] : fibres) {
    std::stable_sort(fibre.rows.begin(), fibre.rows.end(),
                     [](const Row& a, const Row& b) { return a.point < b.point; });
    for (std::size_t i = 1; i < fibre.rows.size(); ++i)
      if (fibre.rows[i].point == fibre.rows[i - 1].point)
        fail_line(path, fibre.first_line, ErrorCode::malformed,
                  "fibre " + std::to_string(id) + " has point " + std::to_string(fibre.rows[i].point) + " twice");
    std::vector<Vec3> points;
    points.reserve(fibre.rows.size());
    for (const Row& row : fibre.rows) points.push_back(row.position);
    result.lines.push_back(std::move(points));
    r_array.values.push_back(fibre.r);
    s_array.values.push_back(fibre.s);
  }
  result.cell_data.push_back(std::move(r_array));
  result.cell_data.push_back(std::move(s_array));
  return result;
}

}  // namespace

bool is_polyline_extension(const std::string& ext) {
  return ext == "vtk" || ext == "vtp" || ext == "vtu" || ext == "obj" || ext == "csv";
}

Polylines read_polylines(const std::string& path, const ReadOptions& options) {
  const std::string ext = lower_extension(path);
  if (!is_polyline_extension(ext))
    throw InputError(ErrorCode::unknown_format,
                     path + ": unknown polyline format '" + ext + "' (expected .vtk, .vtp, .vtu, .obj or .csv)");
  const detail::FileBytes file(path, options);
  const std::string_view data = file.view();
  if (ext == "vtp" || ext == "vtu") return VtpReader(path, data, options, ext == "vtu").read();
  if (ext == "csv") return read_csv(path, data, options);
  std::vector<Vec3> points;
  std::vector<std::vector<int>> index_lines;
  Polylines result;
  if (ext == "vtk") {
    detail::VtkPolyData vtk = detail::read_vtk(path, data, options);
    points = std::move(vtk.points);
    index_lines = std::move(vtk.lines);
    result.cell_data = std::move(vtk.line_cell_data);
  } else {
    detail::ObjData obj = detail::read_obj_data(path, data, options);
    points = std::move(obj.points);
    index_lines = std::move(obj.lines);
  }
  if (index_lines.empty()) throw InputError(ErrorCode::file_empty, path + ": holds no polylines");
  result.lines.reserve(index_lines.size());
  for (const auto& indices : index_lines) {
    std::vector<Vec3> line;
    line.reserve(indices.size());
    for (int i : indices) line.push_back(points[static_cast<std::size_t>(i)]);
    result.lines.push_back(std::move(line));
  }
  return result;
}

}  // namespace fascicle
