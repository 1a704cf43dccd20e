// Wavefront OBJ reader: `v` positions, `f` faces (i, i/t, i//n, i/t/n, negative = relative to the
// last vertex defined), `l` polylines, `\` line continuations. Every other statement (vt, vn, g,
// o, s, usemtl, mtllib, ...) is ignored.
#include "geometry/detail/parse_cursor.h"

#include <algorithm>
#include <climits>

namespace fascicle::detail {

namespace {

/// Resolves one face/line corner token ("12", "-3/4/5", "7//2") to a 0-based point index.
int corner_index(const ParseCursor& in, std::string_view token, std::size_t points_so_far) {
  const std::string_view head = token.substr(0, token.find('/'));
  std::int64_t value = 0;
  if (!ParseCursor::parse_integer(head, value))
    in.fail(ErrorCode::malformed, "vertex reference '" + ParseCursor::shorten(token) + "' is not an index");
  if (value == 0) in.fail(ErrorCode::index_out_of_range, "vertex index 0 (OBJ indices start at 1)");
  // Negative indices count back from the last vertex defined so far.
  const std::int64_t index = value > 0 ? value - 1 : static_cast<std::int64_t>(points_so_far) + value;
  if (index < 0 || static_cast<std::uint64_t>(index) >= points_so_far)
    in.fail(ErrorCode::index_out_of_range, "vertex index " + std::to_string(value) + " is out of range (" +
                                               std::to_string(points_so_far) + " vertices defined so far)");
  return static_cast<int>(index);
}

}  // namespace

ObjData read_obj_data(const std::string& path, std::string_view data, const ReadOptions& options) {
  ParseCursor in(path, data);
  in.skip_byte_order_mark();
  in.set_comment('#');
  in.set_line_continuation(true);
  const std::uint64_t limit = std::min<std::uint64_t>(options.max_elements, INT_MAX);

  ObjData obj;
  bool any_statement = false;
  for (;;) {
    in.skip_space_and_comments();
    if (in.at_end()) break;
    const std::string_view keyword = in.token_in_line();
    any_statement = true;
    if (keyword == "v") {
      if (obj.points.size() >= limit) in.fail(ErrorCode::too_large, "more than " + std::to_string(limit) + " vertices");
      const double x = in.number("x coordinate", true);
      const double y = in.number("y coordinate", true);
      const double z = in.number("z coordinate", true);
      obj.points.emplace_back(x, y, z);
    } else if (keyword == "f" || keyword == "l") {
      auto& target = keyword == "f" ? obj.faces : obj.lines;
      if (target.size() >= limit)
        in.fail(ErrorCode::too_large, "more than " + std::to_string(limit) + " faces or lines");
      std::vector<int> element;
      for (std::string_view t = in.token_in_line(); !t.empty(); t = in.token_in_line())
        element.push_back(corner_index(in, t, obj.points.size()));
      target.push_back(std::move(element));
    }
    in.skip_to_next_line();
  }
  if (!any_statement) in.fail(ErrorCode::file_empty, "no content (only blanks and comments)");
  if (obj.points.empty() && obj.faces.empty() && obj.lines.empty())
    in.fail(ErrorCode::unknown_format, "not an OBJ file: no 'v', 'f' or 'l' statement");
  return obj;
}

PolygonSoup read_obj(const std::string& path, std::string_view data, const ReadOptions& options) {
  ObjData obj = read_obj_data(path, data, options);
  PolygonSoup soup;
  soup.points = std::move(obj.points);
  soup.polygons = std::move(obj.faces);
  return soup;
}

}  // namespace fascicle::detail
