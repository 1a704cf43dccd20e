// Landmark point files: `x y z` per line, '#' comments, blank lines ignored.
#include "geometry/read_points.h"

#include "geometry/detail/parse_cursor.h"
#include "geometry/errors.h"

#include <algorithm>

namespace fascicle {

std::vector<Vec3> read_points(const std::string& path, const ReadOptions& options) {
  const detail::FileBytes file(path, options);
  return detail::read_points(path, file.view(), options);
}

std::vector<Vec3> detail::read_points(const std::string& path, std::string_view data, const ReadOptions& options) {
  options.validate();
  detail::ParseCursor in(path, data);
  in.skip_byte_order_mark();
  in.set_comment('#');
  std::vector<Vec3> points;
  for (;;) {
    in.skip_space_and_comments();
    if (in.at_end()) break;
    if (points.size() >= options.max_elements)
      in.fail(ErrorCode::too_large, "more than " + std::to_string(options.max_elements) + " points");
    const double x = in.number("x coordinate", true);
    const double y = in.number("y coordinate", true);
    const double z = in.number("z coordinate", true);
    if (!in.at_line_end())
      in.fail(ErrorCode::malformed,
              "unexpected '" + detail::ParseCursor::shorten(in.token_in_line()) + "' after the three coordinates");
    points.emplace_back(x, y, z);
    in.skip_to_next_line();
  }
  if (points.empty()) in.fail(ErrorCode::file_empty, "no point (only blanks and comments)");
  return points;
}

}  // namespace fascicle
