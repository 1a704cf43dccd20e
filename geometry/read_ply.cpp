// PLY reader (Turk's Stanford polygon format): ASCII, binary_little_endian and binary_big_endian;
// any scalar property types; `vertex` x/y/z, `face` index lists (vertex_indices or vertex_index),
// `tristrips` (strips separated by -1, alternating winding); every other element and property is
// read past and dropped.
#include "geometry/detail/parse_cursor.h"

#include <algorithm>
#include <climits>
#include <optional>

namespace fascicle::detail {

namespace {

struct Property {
  std::string name;
  bool is_list = false;
  Scalar count_type = Scalar::u8;  ///< lists only
  Scalar type = Scalar::f32;       ///< scalar type or list item type
};

struct Element {
  std::string name;
  std::uint64_t count = 0;
  std::vector<Property> properties;
  std::size_t line = 0;  ///< header line declaring it
};

std::optional<Scalar> ply_scalar(std::string_view name) {
  if (name == "char" || name == "int8") return Scalar::i8;
  if (name == "uchar" || name == "uint8") return Scalar::u8;
  if (name == "short" || name == "int16") return Scalar::i16;
  if (name == "ushort" || name == "uint16") return Scalar::u16;
  if (name == "int" || name == "int32") return Scalar::i32;
  if (name == "uint" || name == "uint32") return Scalar::u32;
  if (name == "float" || name == "float32") return Scalar::f32;
  if (name == "double" || name == "float64") return Scalar::f64;
  return std::nullopt;
}

enum class Encoding { ascii, little, big };

/// Reads property values from the body, ASCII tokens or binary scalars.
class BodyReader {
 public:
  BodyReader(ParseCursor& in, Encoding encoding)
      : in_(in), binary_(encoding != Encoding::ascii), big_(encoding == Encoding::big) {}

  bool binary() const { return binary_; }

  double real(Scalar type, const char* what) {
    if (!binary_) return in_.number(what, false);
    in_.require(scalar_size(type), what);
    const std::size_t at = in_.pos();
    const double value = in_.scalar_unchecked(type, big_);
    if (!std::isfinite(value)) in_.fail_at_byte(at, ErrorCode::bad_number, std::string(what) + " is not finite");
    return value;
  }

  std::int64_t integer(Scalar type, const char* what) {
    if (!binary_) return in_.integer(what, false);
    if (scalar_is_float(type)) in_.fail(ErrorCode::malformed, std::string(what) + " has a floating-point type");
    in_.require(scalar_size(type), what);
    return in_.integer_unchecked(type, big_);
  }

  /// Reads a list length and checks it against the bytes left (before anything is sized by it).
  /// Reads a vertex index and checks it against the point count, reporting the index's own
  /// byte offset (binary) or line (ASCII).
  /// `allow_restart` lets -1 through (triangle strips).
  int index(Scalar type, const char* what, std::size_t point_count, bool allow_restart = false) {
    const std::size_t at = in_.pos();
    const std::int64_t value = integer(type, what);
    if (allow_restart && value == -1) return -1;
    if (value < 0 || static_cast<std::uint64_t>(value) >= point_count)
      fail_here(at, in_.line(), ErrorCode::index_out_of_range,
                std::string(what) + " " + std::to_string(value) + " is out of range (" + std::to_string(point_count) +
                    " points)");
    return static_cast<int>(value);
  }

  std::uint64_t list_length(const Property& p, const char* what) {
    const std::size_t at = in_.pos();
    const std::int64_t n = integer(p.count_type, what);
    const std::size_t line = in_.line();  // ASCII: the line of the token just read
    if (n < 0)
      fail_here(at, line, ErrorCode::malformed, std::string(what) + " is negative (" + std::to_string(n) + ")");
    const std::uint64_t item = binary_ ? scalar_size(p.type) : 2;  // ASCII: a digit and a blank
    if (static_cast<std::uint64_t>(n) > in_.remaining() / item) {
      if (binary_)
        in_.fail_at_byte(at, ErrorCode::truncated,
                         std::string(what) + " " + std::to_string(n) + " runs past the end of the file");
      fail_here(at, line, ErrorCode::truncated,
                std::string(what) + " " + std::to_string(n) + " runs past the end of the file");
    }
    return static_cast<std::uint64_t>(n);
  }

  void skip(const Property& p) {
    if (p.is_list) {
      const std::uint64_t n = list_length(p, "list length");
      if (binary_) {
        in_.skip_bytes(static_cast<std::size_t>(n * scalar_size(p.type)), "list");
      } else {
        for (std::uint64_t i = 0; i < n; ++i) skip_token();
      }
    } else if (binary_) {
      in_.skip_bytes(scalar_size(p.type), "property value");
    } else {
      skip_token();
    }
  }

  [[noreturn]] void fail_here(std::size_t byte, std::size_t line, ErrorCode code, const std::string& what) const {
    if (binary_) in_.fail_at_byte(byte, code, what);
    in_.fail_at_line(line, code, what);
  }

 private:
  void skip_token() {
    if (in_.token_any().empty()) in_.fail(ErrorCode::truncated, "file ends inside an element");
  }

  ParseCursor& in_;
  bool binary_;
  bool big_;
};

int property_index(const Element& e, std::string_view name) {
  for (std::size_t i = 0; i < e.properties.size(); ++i)
    if (e.properties[i].name == name) return static_cast<int>(i);
  return -1;
}

}  // namespace

PolygonSoup read_ply(const std::string& path, std::string_view data, const ReadOptions& options) {
  ParseCursor in(path, data);
  in.skip_byte_order_mark();

  // ---- header ----
  // The first three bytes decide, before the first line's end is searched for (garbage may
  // have none: the whole file would be read to find it).
  if (in.data().substr(in.pos(), 3) != "ply")
    in.fail_at_line(1, ErrorCode::unknown_format, "not a PLY file (first line is not 'ply')");
  const std::string_view magic = in.rest_of_line();
  if (magic != "ply") in.fail_at_line(1, ErrorCode::unknown_format, "not a PLY file (first line is not 'ply')");
  std::optional<Encoding> encoding;
  std::vector<Element> elements;
  bool ended = false;
  while (!in.at_end()) {
    const std::size_t line = in.line();
    const std::string_view keyword = in.token_in_line();
    if (keyword.empty()) {
      in.skip_to_next_line();
      continue;
    }
    if (keyword == "comment" || keyword == "obj_info") {
      in.skip_to_next_line();
      continue;
    }
    if (keyword == "end_header") {
      in.rest_of_line();
      ended = true;
      break;
    }
    if (keyword == "format") {
      const std::string_view kind = in.token_in_line();
      if (kind == "ascii")
        encoding = Encoding::ascii;
      else if (kind == "binary_little_endian")
        encoding = Encoding::little;
      else if (kind == "binary_big_endian")
        encoding = Encoding::big;
      else
        in.fail(ErrorCode::malformed, "unknown PLY format '" + ParseCursor::shorten(kind) + "'");
      in.token_in_line();  // version, always 1.0
    } else if (keyword == "element") {
      Element e;
      e.name = std::string(in.token_in_line());
      if (e.name.empty()) in.fail(ErrorCode::malformed, "element without a name");
      e.count = in.count("element count", true);
      e.line = line;
      elements.push_back(std::move(e));
    } else if (keyword == "property") {
      if (elements.empty()) in.fail(ErrorCode::malformed, "property before any element");
      Property p;
      std::string_view type = in.token_in_line();
      if (type == "list") {
        p.is_list = true;
        const std::string_view count_type = in.token_in_line();
        const auto ct = ply_scalar(count_type);
        if (!ct || scalar_is_float(*ct))
          in.fail(ErrorCode::malformed, "bad list count type '" + ParseCursor::shorten(count_type) + "'");
        p.count_type = *ct;
        type = in.token_in_line();
      }
      const auto t = ply_scalar(type);
      if (!t) in.fail(ErrorCode::malformed, "unknown property type '" + ParseCursor::shorten(type) + "'");
      p.type = *t;
      p.name = std::string(in.token_in_line());
      if (p.name.empty()) in.fail(ErrorCode::malformed, "property without a name");
      elements.back().properties.push_back(std::move(p));
    } else {
      in.fail(ErrorCode::malformed, "unknown PLY header keyword '" + ParseCursor::shorten(keyword) + "'");
    }
    if (!in.at_line_end())
      in.fail(ErrorCode::malformed, "unexpected '" + ParseCursor::shorten(in.token_in_line()) + "'");
    in.skip_to_next_line();
  }
  if (!ended) in.fail(ErrorCode::truncated, "file ends inside the PLY header (no 'end_header')");
  if (!encoding) in.fail(ErrorCode::malformed, "PLY header has no 'format' line");

  // ---- counts against the body size, before anything is allocated ----
  const std::uint64_t body = in.remaining();
  const std::uint64_t limit = std::min<std::uint64_t>(options.max_elements, INT_MAX);
  const Element* vertex = nullptr;
  for (const Element& e : elements) {
    std::uint64_t min_bytes = 0;
    for (const Property& p : e.properties)
      min_bytes += *encoding == Encoding::ascii ? 2 : (p.is_list ? scalar_size(p.count_type) : scalar_size(p.type));
    if (e.count > limit)
      in.fail_at_line(e.line, ErrorCode::too_large,
                      "element '" + e.name + "' declares " + std::to_string(e.count) +
                          " items, more than the limit of " + std::to_string(limit));
    if (min_bytes > 0 && e.count > body / min_bytes)
      in.fail_at_line(e.line, ErrorCode::too_large,
                      "element '" + e.name + "' declares " + std::to_string(e.count) + " items but the data has only " +
                          std::to_string(body) + " bytes (each item needs at least " + std::to_string(min_bytes) + ")");
    if (e.name == "vertex") vertex = &e;
  }
  if (vertex == nullptr) in.fail(ErrorCode::malformed, "PLY header declares no 'vertex' element");
  const int ix = property_index(*vertex, "x"), iy = property_index(*vertex, "y"), iz = property_index(*vertex, "z");
  if (ix < 0 || iy < 0 || iz < 0)
    in.fail_at_line(vertex->line, ErrorCode::malformed, "vertex element lacks an x, y or z property");
  for (int i : {ix, iy, iz})
    if (vertex->properties[static_cast<std::size_t>(i)].is_list)
      in.fail_at_line(vertex->line, ErrorCode::malformed, "vertex coordinate is declared as a list");
  const std::size_t point_count = static_cast<std::size_t>(vertex->count);

  // ---- body ----
  if (*encoding != Encoding::ascii) in.set_binary_locations(true);
  BodyReader reader(in, *encoding);
  const bool big = *encoding == Encoding::big;
  PolygonSoup soup;
  std::vector<int> run;
  for (const Element& e : elements) {
    if (&e == vertex) {
      soup.points.resize(point_count);
      bool all_scalar = true;
      std::size_t stride = 0;
      for (const Property& p : e.properties) {
        all_scalar = all_scalar && !p.is_list;
        stride += scalar_size(p.type);
      }
      if (reader.binary() && all_scalar) {
        // Fixed-size records: one bounds check for the whole element.
        if (point_count * stride > in.remaining())
          in.fail_at_byte(in.pos() + (in.remaining() / stride) * stride, ErrorCode::truncated,
                          "file ends inside vertex " + std::to_string(in.remaining() / stride) + " of " +
                              std::to_string(point_count));
        std::size_t offset[3] = {0, 0, 0};
        std::size_t o = 0;
        for (std::size_t i = 0; i < e.properties.size(); ++i) {
          if (static_cast<int>(i) == ix) offset[0] = o;
          if (static_cast<int>(i) == iy) offset[1] = o;
          if (static_cast<int>(i) == iz) offset[2] = o;
          o += scalar_size(e.properties[i].type);
        }
        const Scalar types[3] = {e.properties[static_cast<std::size_t>(ix)].type,
                                 e.properties[static_cast<std::size_t>(iy)].type,
                                 e.properties[static_cast<std::size_t>(iz)].type};
        const std::size_t base = in.pos();
        for (std::size_t v = 0; v < point_count; ++v) {
          for (int c = 0; c < 3; ++c) {
            in.seek(base + v * stride + offset[c]);
            const double value = in.scalar_unchecked(types[c], big);
            if (!std::isfinite(value))
              in.fail_at_byte(base + v * stride + offset[c], ErrorCode::bad_number,
                              "vertex " + std::to_string(v) + " has a coordinate that is not finite");
            soup.points[v][c] = value;
          }
        }
        in.seek(base + point_count * stride);
      } else {
        for (std::size_t v = 0; v < point_count; ++v) {
          for (std::size_t i = 0; i < e.properties.size(); ++i) {
            const int k = static_cast<int>(i);
            if (k == ix)
              soup.points[v][0] = reader.real(e.properties[i].type, "x coordinate");
            else if (k == iy)
              soup.points[v][1] = reader.real(e.properties[i].type, "y coordinate");
            else if (k == iz)
              soup.points[v][2] = reader.real(e.properties[i].type, "z coordinate");
            else
              reader.skip(e.properties[i]);
          }
        }
      }
      continue;
    }

    const bool is_face = e.name == "face";
    const bool is_strips = e.name == "tristrips";
    int list = -1;
    if (is_face || is_strips) {
      list = property_index(e, "vertex_indices");
      if (list < 0) list = property_index(e, "vertex_index");
      if (list < 0 || !e.properties[static_cast<std::size_t>(list)].is_list)
        in.fail_at_line(e.line, ErrorCode::malformed, "element '" + e.name + "' has no vertex_indices list");
      if (scalar_is_float(e.properties[static_cast<std::size_t>(list)].type))
        in.fail_at_line(e.line, ErrorCode::malformed, "vertex_indices has a floating-point type");
    }
    if (is_face) soup.polygons.reserve(soup.polygons.size() + static_cast<std::size_t>(e.count));
    for (std::uint64_t item = 0; item < e.count; ++item) {
      if (in.at_end() && !e.properties.empty())
        in.fail(ErrorCode::truncated, "file ends after " + std::to_string(item) + " of " + std::to_string(e.count) +
                                          " '" + e.name + "' items");
      for (std::size_t i = 0; i < e.properties.size(); ++i) {
        const Property& p = e.properties[i];
        if (static_cast<int>(i) != list) {
          reader.skip(p);
          continue;
        }
        const std::uint64_t n = reader.list_length(p, "index list length");
        if (is_face) {
          std::vector<int> face(static_cast<std::size_t>(n));
          for (auto& index : face) index = reader.index(p.type, "vertex index", point_count);
          soup.polygons.push_back(std::move(face));
        } else {
          run.clear();
          for (std::uint64_t k = 0; k < n; ++k) {
            const int index = reader.index(p.type, "strip index", point_count, true);
            if (index == -1) {  // restart
              append_strip_triangles(run, soup.polygons);
              run.clear();
            } else {
              run.push_back(index);
            }
          }
          append_strip_triangles(run, soup.polygons);
          if (soup.polygons.size() > limit)
            in.fail(ErrorCode::too_large, "strips give more than " + std::to_string(limit) + " triangles");
        }
      }
    }
  }
  return soup;
}

}  // namespace fascicle::detail
