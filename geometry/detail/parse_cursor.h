#pragma once
/// \file parse_cursor.h
/// Private to the mesh readers: a cursor over a file held in memory that reads text tokens
/// (tracking line numbers) and binary scalars (tracking byte offsets), and throws InputError with
/// a one-line message `<file>: line N: <what>` or `<file>: byte N: <what>`.
///
/// Text tokens are parsed with std::from_chars (no locale, no iostream), so large ASCII files
/// read at memory speed.

#include "geometry/errors.h"
#include "geometry/mesh_io.h"
#include "geometry/thesis_format.h"

#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <string>
#include <string_view>

namespace fascicle::detail {

/// The bytes of a file, for the readers. A regular file is mapped read-only (mmap), so its pages
/// are read only when a reader reaches them: a reader that refuses a file at its first bad token
/// or count touches a few pages, not the whole file, and a file that is read in full costs page
/// cache (reclaimable) rather than a private copy. Where mapping is not possible the file is read
/// into memory instead. A file truncated by another process while it is mapped ends the process
/// with SIGBUS when a reader reaches the missing pages (docs/RELIABILITY.md, "Resource limits").
class FileBytes {
 public:
  /// Opens and maps `path`. Throws InputError: file_missing (absent, unreadable, a folder),
  /// too_large (above options.max_file_bytes, before anything is read), file_empty (0 bytes).
  FileBytes(const std::string& path, const ReadOptions& options);
  ~FileBytes();
  FileBytes(const FileBytes&) = delete;
  FileBytes& operator=(const FileBytes&) = delete;
  /// The whole file.
  std::string_view view() const { return {data_, size_}; }

 private:
  const char* data_ = nullptr;
  std::size_t size_ = 0;
  void* mapping_ = nullptr;  // the mmap'ed region, or null when `copy_` holds the bytes
  std::string copy_;
};

/// Scalar types found in PLY and VTK files.
enum class Scalar { i8, u8, i16, u16, i32, u32, i64, u64, f32, f64 };

/// Size in bytes of one scalar.
inline std::size_t scalar_size(Scalar s) {
  switch (s) {
    case Scalar::i8:
    case Scalar::u8: return 1;
    case Scalar::i16:
    case Scalar::u16: return 2;
    case Scalar::i32:
    case Scalar::u32:
    case Scalar::f32: return 4;
    case Scalar::i64:
    case Scalar::u64:
    case Scalar::f64: return 8;
  }
  return 1;
}

inline bool scalar_is_float(Scalar s) { return s == Scalar::f32 || s == Scalar::f64; }

/// Where the cursor stands and how to report it.
class ParseCursor {
 public:
  ParseCursor(std::string file, std::string_view data) : file_(std::move(file)), data_(data) {}

  // ---- state -------------------------------------------------------------------------------
  std::size_t pos() const { return pos_; }
  std::size_t size() const { return data_.size(); }
  std::size_t remaining() const { return data_.size() - pos_; }
  std::size_t line() const { return line_; }
  bool at_end() const { return pos_ >= data_.size(); }
  char peek() const { return at_end() ? '\0' : data_[pos_]; }
  std::string_view data() const { return data_; }
  const std::string& file() const { return file_; }

  /// Error locations in lines (text) or byte offsets (binary sections).
  void set_binary_locations(bool binary) { binary_locations_ = binary; }
  /// Whether a backslash at the end of a line joins it with the next (OBJ).
  void set_line_continuation(bool on) { continuation_ = on; }
  /// Comment character skipped by skip_space_and_comments / at_line_end ('\0' for none).
  void set_comment(char c) { comment_ = c; }

  /// "line N" or "byte N" for the current position.
  std::string where() const {
    return binary_locations_ ? "byte " + std::to_string(pos_) : "line " + std::to_string(line_);
  }

  /// Throws InputError(code) with the message `<file>: <where>: <what>`.
  [[noreturn]] void fail(ErrorCode code, const std::string& what) const {
    throw InputError(code, file_ + ": " + where() + ": " + what);
  }
  /// Same, at an explicit byte offset.
  [[noreturn]] void fail_at_byte(std::size_t byte, ErrorCode code, const std::string& what) const {
    throw InputError(code, file_ + ": byte " + std::to_string(byte) + ": " + what);
  }
  /// Same, at an explicit line.
  [[noreturn]] void fail_at_line(std::size_t line, ErrorCode code, const std::string& what) const {
    throw InputError(code, file_ + ": line " + std::to_string(line) + ": " + what);
  }

  // ---- text --------------------------------------------------------------------------------
  /// Skips a UTF-8 byte order mark at the start of a text file (some Windows exporters write
  /// one; left in place it would hide the first keyword).
  void skip_byte_order_mark() {
    if (pos_ == 0 && data_.size() >= 3 && data_.compare(0, 3, "\xEF\xBB\xBF") == 0) pos_ = 3;
  }

  /// Skips blanks within the line (and `\` continuations when enabled).
  void skip_blanks() {
    while (pos_ < data_.size()) {
      const char c = data_[pos_];
      if (c == ' ' || c == '\t' || c == '\r' || c == '\f' || c == '\v') {
        ++pos_;
      } else if (continuation_ && c == '\\' && continues_line(pos_ + 1)) {
        ++pos_;
        while (data_[pos_] != '\n') ++pos_;
        ++pos_;
        ++line_;
      } else {
        break;
      }
    }
  }

  /// Skips blanks, newlines and (when set) comments up to the next token.
  void skip_space_and_comments() {
    for (;;) {
      skip_blanks();
      if (pos_ >= data_.size()) return;
      const char c = data_[pos_];
      if (c == '\n') {
        ++pos_;
        ++line_;
      } else if (comment_ != '\0' && c == comment_) {
        skip_to_next_line();
      } else {
        return;
      }
    }
  }

  /// True when only blanks (and a comment) remain on this line.
  bool at_line_end() {
    skip_blanks();
    return pos_ >= data_.size() || data_[pos_] == '\n' || (comment_ != '\0' && data_[pos_] == comment_);
  }

  /// Moves past the next newline (or to the end).
  void skip_to_next_line() {
    while (pos_ < data_.size()) {
      if (data_[pos_] == '\n') {
        ++pos_;
        ++line_;
        return;
      }
      if (continuation_ && data_[pos_] == '\\' && continues_line(pos_ + 1)) {
        skip_blanks();
        continue;
      }
      ++pos_;
    }
  }

  /// The rest of the current line without the newline (and a trailing '\r'); moves past it.
  std::string_view rest_of_line() {
    const std::size_t begin = pos_;
    while (pos_ < data_.size() && data_[pos_] != '\n') ++pos_;
    std::size_t end = pos_;
    if (end > begin && data_[end - 1] == '\r') --end;
    if (pos_ < data_.size()) {
      ++pos_;
      ++line_;
    }
    return data_.substr(begin, end - begin);
  }

  /// Next token on this line ("" at the line end; comments end the line when set).
  std::string_view token_in_line() {
    if (at_line_end()) return {};
    return raw_token();
  }

  /// Next token, crossing newlines and comments ("" at the end of the file).
  std::string_view token_any() {
    skip_space_and_comments();
    if (at_end()) return {};
    return raw_token();
  }

  /// Parses a double token; `what` names the value for messages. `in_line` restricts to this
  /// line. Throws bad_number (unparsable, NaN, Inf), truncated (end of file), malformed (end of
  /// line).
  double number(const char* what, bool in_line) {
    const std::size_t line_before = line_;
    const std::string_view t = in_line ? token_in_line() : token_any();
    if (t.empty()) missing(what, in_line, line_before);
    double value = 0.0;
    if (!parse_double(t, value))
      fail(ErrorCode::bad_number, std::string(what) + " '" + shorten(t) + "' is not a number");
    if (!std::isfinite(value)) fail(ErrorCode::bad_number, std::string(what) + " is " + shorten(t) + " (not finite)");
    return value;
  }

  /// Parses an integer token (decimal, optional sign).
  std::int64_t integer(const char* what, bool in_line) {
    const std::size_t line_before = line_;
    const std::string_view t = in_line ? token_in_line() : token_any();
    if (t.empty()) missing(what, in_line, line_before);
    std::int64_t value = 0;
    if (!parse_integer(t, value))
      fail(ErrorCode::malformed, std::string(what) + " '" + shorten(t) + "' is not an integer");
    return value;
  }

  /// Parses a non-negative count token.
  std::uint64_t count(const char* what, bool in_line) {
    const std::size_t line_before = line_;
    const std::string_view t = in_line ? token_in_line() : token_any();
    if (t.empty()) missing(what, in_line, line_before);
    std::uint64_t value = 0;
    std::string_view digits = t;
    if (!digits.empty() && digits[0] == '+') digits.remove_prefix(1);
    const auto result = std::from_chars(digits.data(), digits.data() + digits.size(), value);
    if (result.ec == std::errc::result_out_of_range)
      fail(ErrorCode::too_large, std::string(what) + " " + shorten(t) + " is too large");
    if (digits.empty() || result.ec != std::errc() || result.ptr != digits.data() + digits.size())
      fail(ErrorCode::malformed, std::string(what) + " '" + shorten(t) + "' is not a non-negative integer");
    return value;
  }

  /// Expects `keyword` (case-sensitive) as the next token in the line.
  void expect_in_line(std::string_view keyword) {
    const std::string_view t = token_in_line();
    if (t != keyword) fail(ErrorCode::malformed, "expected '" + std::string(keyword) + "', found '" + shorten(t) + "'");
  }

  // ---- binary ------------------------------------------------------------------------------
  /// Throws truncated unless `n` more bytes follow; `what` names the data being read.
  void require(std::size_t n, const char* what) const {
    if (n > remaining())
      fail_at_byte(pos_, ErrorCode::truncated,
                   std::string("file ends inside ") + what + " (" + std::to_string(n) + " bytes needed, " +
                       std::to_string(remaining()) + " left)");
  }

  void skip_bytes(std::size_t n, const char* what) {
    require(n, what);
    pos_ += n;
  }

  /// Reads one scalar as double (no bounds check: call require() first).
  double scalar_unchecked(Scalar s, bool big_endian) {
    const char* p = data_.data() + pos_;
    pos_ += scalar_size(s);
    switch (s) {
      case Scalar::i8: return static_cast<double>(static_cast<std::int8_t>(p[0]));
      case Scalar::u8: return static_cast<double>(static_cast<std::uint8_t>(p[0]));
      case Scalar::i16: return static_cast<double>(load<std::int16_t>(p, big_endian));
      case Scalar::u16: return static_cast<double>(load<std::uint16_t>(p, big_endian));
      case Scalar::i32: return static_cast<double>(load<std::int32_t>(p, big_endian));
      case Scalar::u32: return static_cast<double>(load<std::uint32_t>(p, big_endian));
      case Scalar::i64: return static_cast<double>(load<std::int64_t>(p, big_endian));
      case Scalar::u64: return static_cast<double>(load<std::uint64_t>(p, big_endian));
      case Scalar::f32: return static_cast<double>(load<float>(p, big_endian));
      case Scalar::f64: return load<double>(p, big_endian);
    }
    return 0.0;
  }

  /// Reads one integer scalar (no bounds check); a float type here is a caller error.
  std::int64_t integer_unchecked(Scalar s, bool big_endian) {
    const char* p = data_.data() + pos_;
    pos_ += scalar_size(s);
    switch (s) {
      case Scalar::i8: return static_cast<std::int8_t>(p[0]);
      case Scalar::u8: return static_cast<std::uint8_t>(p[0]);
      case Scalar::i16: return load<std::int16_t>(p, big_endian);
      case Scalar::u16: return load<std::uint16_t>(p, big_endian);
      case Scalar::i32: return load<std::int32_t>(p, big_endian);
      case Scalar::u32: return load<std::uint32_t>(p, big_endian);
      case Scalar::i64: return load<std::int64_t>(p, big_endian);
      case Scalar::u64: {
        const std::uint64_t v = load<std::uint64_t>(p, big_endian);
        return v > static_cast<std::uint64_t>(std::numeric_limits<std::int64_t>::max())
                   ? std::numeric_limits<std::int64_t>::max()
                   : static_cast<std::int64_t>(v);
      }
      case Scalar::f32: return static_cast<std::int64_t>(load<float>(p, big_endian));
      case Scalar::f64: return static_cast<std::int64_t>(load<double>(p, big_endian));
    }
    return 0;
  }

  /// Loads a T stored at p in the given byte order.
  template <class T>
  static T load(const char* p, bool big_endian) {
    unsigned char bytes[sizeof(T)];
    std::memcpy(bytes, p, sizeof(T));
    if (big_endian != host_is_big_endian()) {
      for (std::size_t i = 0; i < sizeof(T) / 2; ++i) std::swap(bytes[i], bytes[sizeof(T) - 1 - i]);
    }
    T value;
    std::memcpy(&value, bytes, sizeof(T));
    return value;
  }

  static constexpr bool host_is_big_endian() {
#if defined(__BYTE_ORDER__) && defined(__ORDER_BIG_ENDIAN__) && __BYTE_ORDER__ == __ORDER_BIG_ENDIAN__
    return true;
#else
    return false;
#endif
  }

  // ---- helpers -----------------------------------------------------------------------------
  /// A token for messages: at most 40 characters, non-printable bytes shown as '?'.
  static std::string shorten(std::string_view t) {
    std::string s(t.substr(0, 40));
    for (auto& c : s)
      if (static_cast<unsigned char>(c) < 32 || static_cast<unsigned char>(c) > 126) c = '?';
    if (t.size() > 40) s += "...";
    return s;
  }

  /// std::from_chars for doubles, also accepting a leading '+'. True when the whole token parsed.
  static bool parse_double(std::string_view t, double& value) {
    if (!t.empty() && t[0] == '+') t.remove_prefix(1);
    if (t.empty()) return false;
    const auto result = std::from_chars(t.data(), t.data() + t.size(), value);
    if (result.ec == std::errc::result_out_of_range) {
      // Too small for a double (a negative exponent) reads as a signed zero; too large as
      // infinity, which the callers reject as not finite. No strtod: it depends on the locale.
      const std::size_t e = t.find_first_of("eE");
      const bool tiny = e != std::string_view::npos && e + 1 < t.size() && t[e + 1] == '-';
      const bool negative = t[0] == '-';
      value = tiny ? (negative ? -0.0 : 0.0)
                   : (negative ? -std::numeric_limits<double>::infinity() : std::numeric_limits<double>::infinity());
      return result.ptr == t.data() + t.size();
    }
    return result.ec == std::errc() && result.ptr == t.data() + t.size();
  }

  static bool parse_integer(std::string_view t, std::int64_t& value) {
    if (!t.empty() && t[0] == '+') t.remove_prefix(1);
    if (t.empty()) return false;
    const auto result = std::from_chars(t.data(), t.data() + t.size(), value);
    return result.ec == std::errc() && result.ptr == t.data() + t.size();
  }

  /// Position setter for binary readers (the line count is not updated).
  void seek(std::size_t p) { pos_ = p; }

  /// A saved position (with its line) to scan ahead and come back.
  struct Mark {
    std::size_t pos;
    std::size_t line;
  };
  Mark mark() const { return {pos_, line_}; }
  void reset(const Mark& m) {
    pos_ = m.pos;
    line_ = m.line;
  }

 private:
  std::string_view raw_token() {
    const std::size_t begin = pos_;
    while (pos_ < data_.size()) {
      const char c = data_[pos_];
      if (c == ' ' || c == '\t' || c == '\r' || c == '\n' || c == '\f' || c == '\v') break;
      if (comment_ != '\0' && c == comment_) break;
      ++pos_;
    }
    return data_.substr(begin, pos_ - begin);
  }

  bool continues_line(std::size_t p) const {
    while (p < data_.size() && (data_[p] == '\r' || data_[p] == ' ' || data_[p] == '\t')) ++p;
    return p < data_.size() && data_[p] == '\n';
  }

  [[noreturn]] void missing(const char* what, bool in_line, std::size_t line_before) const {
    if (at_end()) fail(ErrorCode::truncated, std::string("file ends where ") + what + " was expected");
    if (in_line) fail_at_line(line_before, ErrorCode::malformed, std::string(what) + " missing at the end of the line");
    fail(ErrorCode::malformed, std::string(what) + " missing");
  }

  std::string file_;
  std::string_view data_;
  std::size_t pos_ = 0;
  std::size_t line_ = 1;
  bool binary_locations_ = false;
  bool continuation_ = false;
  char comment_ = '\0';
};

/// Throws too_large when `count` elements of at least `min_bytes` bytes each cannot fit in the
/// `available` bytes of the file, or exceed options.max_elements (or what an int index holds).
/// Called before any allocation sized by a declared count.
void check_declared_count(const ParseCursor& cursor, std::uint64_t count, std::uint64_t min_bytes,
                          std::uint64_t available, const char* what, const ReadOptions& options);

/// Throws index_out_of_range unless 0 <= index < point_count.
inline int checked_index(const ParseCursor& cursor, std::int64_t index, std::size_t point_count) {
  if (index < 0 || static_cast<std::uint64_t>(index) >= point_count)
    cursor.fail(ErrorCode::index_out_of_range, "vertex index " + std::to_string(index) + " is out of range (" +
                                                   std::to_string(point_count) + " points)");
  return static_cast<int>(index);
}

/// Appends the triangles of one triangle strip (indices already checked): triangle i uses strip
/// entries i, i+1, i+2, with the first two swapped for odd i so that all keep the strip's winding.
/// Triangles with repeated indices are kept (repair drops them).
inline void append_strip_triangles(const std::vector<int>& strip, std::vector<std::vector<int>>& polygons) {
  for (std::size_t i = 2; i < strip.size(); ++i) {
    if (i % 2 == 0)
      polygons.push_back({strip[i - 2], strip[i - 1], strip[i]});
    else
      polygons.push_back({strip[i - 1], strip[i - 2], strip[i]});
  }
}

// Readers, one per format (read_<format>.cpp). `data` is the whole file.
PolygonSoup read_off(const std::string& path, std::string_view data, const ReadOptions& options);
PolygonSoup read_obj(const std::string& path, std::string_view data, const ReadOptions& options);
PolygonSoup read_stl(const std::string& path, std::string_view data, const ReadOptions& options);
PolygonSoup read_ply(const std::string& path, std::string_view data, const ReadOptions& options);

/// Everything the legacy VTK polydata reader keeps: points, polygons (POLYGONS and the
/// triangles of TRIANGLE_STRIPS), polylines (LINES, as point index lists) and the scalar
/// CELL_DATA arrays restricted to the LINES cells.
struct VtkPolyData {
  std::vector<Vec3> points;
  std::vector<std::vector<int>> polygons;
  std::vector<std::vector<int>> lines;
  std::vector<CellArray> line_cell_data;
};
VtkPolyData read_vtk(const std::string& path, std::string_view data, const ReadOptions& options);

/// OBJ points, faces (`f`) and polylines (`l`).
struct ObjData {
  std::vector<Vec3> points;
  std::vector<std::vector<int>> faces;
  std::vector<std::vector<int>> lines;
};
ObjData read_obj_data(const std::string& path, std::string_view data, const ReadOptions& options);

/// The thesis text format (thesis_format.h) and landmark point files (read_points.h) from
/// memory; read_thesis_model() and read_points() load the file and call these. The fuzz
/// targets (fuzz/) call every reader through these in-memory entry points.
ThesisModel read_thesis(const std::string& path, std::string_view data, const ReadOptions& options);
std::vector<Vec3> read_points(const std::string& path, std::string_view data, const ReadOptions& options);

/// Appends `value` with max_digits10 significant digits (shortest form that round-trips is not
/// required; this is what iostream with precision max_digits10 prints).
void append_double(std::string& out, double value);
void append_int(std::string& out, long long value);

}  // namespace fascicle::detail
