// OFF reader (Geomview Object File Format): header word, counts, one vertex per line, one face
// per line. Tolerates the header glued to the counts ("OFF8 6 12"), a missing header word,
// comments, the C/N/ST prefixes (extra values on a vertex line are ignored), colours after a
// face's indices.
#include "geometry/detail/parse_cursor.h"

#include <cctype>

namespace fascicle::detail {

namespace {

bool is_digit_start(std::string_view t) {
  return !t.empty() && (std::isdigit(static_cast<unsigned char>(t[0])) || t[0] == '+' || t[0] == '-');
}

}  // namespace

PolygonSoup read_off(const std::string& path, std::string_view data, const ReadOptions& options) {
  ParseCursor in(path, data);
  in.skip_byte_order_mark();
  in.set_comment('#');

  std::string_view first = in.token_any();
  if (first.empty()) in.fail(ErrorCode::file_empty, "no content (only blanks and comments)");

  // The header word: [ST][C][N][4][n]OFF, possibly glued to the first count.
  std::string_view glued;
  if (!is_digit_start(first)) {
    const std::size_t at = first.find("OFF");
    if (at == std::string_view::npos)
      in.fail(ErrorCode::unknown_format,
              "not an OFF file: expected 'OFF', found '" + ParseCursor::shorten(first) + "'");
    const std::string_view prefix = first.substr(0, at);
    for (char c : prefix) {
      if (c == '4' || c == 'n')
        in.fail(ErrorCode::malformed, "'" + ParseCursor::shorten(first) + "': only 3-D OFF is supported");
      if (c != 'S' && c != 'T' && c != 'C' && c != 'N')
        in.fail(ErrorCode::unknown_format, "not an OFF file: unknown header '" + ParseCursor::shorten(first) + "'");
    }
    glued = first.substr(at + 3);
    if (glued.empty()) {
      const ParseCursor::Mark mark = in.mark();
      const std::string_view next = in.token_in_line();
      if (next == "BINARY") in.fail(ErrorCode::malformed, "binary OFF is not supported");
      if (!next.empty()) in.reset(mark);  // counts on the header line
    }
  } else {
    glued = first;  // no header word: the file starts with the counts
  }

  std::uint64_t vertex_count = 0;
  if (!glued.empty()) {
    std::string_view digits = glued;
    const auto result = std::from_chars(digits.data(), digits.data() + digits.size(), vertex_count);
    if (result.ec != std::errc() || result.ptr != digits.data() + digits.size())
      in.fail(ErrorCode::malformed, "vertex count '" + ParseCursor::shorten(glued) + "' is not a non-negative integer");
  } else {
    vertex_count = in.count("vertex count", false);
  }
  const std::uint64_t face_count = in.count("face count", false);
  if (!in.at_line_end()) (void)in.count("edge count", true);
  // "0 0 0\n" and "0\n" are the shortest vertex and face lines.
  check_declared_count(in, vertex_count, 6, in.size(), "vertices", options);
  check_declared_count(in, face_count, 2, in.size(), "faces", options);
  if (!in.at_line_end())
    in.fail(ErrorCode::malformed, "unexpected '" + ParseCursor::shorten(in.token_in_line()) + "' after the counts");
  in.skip_to_next_line();

  PolygonSoup soup;
  soup.points.reserve(static_cast<std::size_t>(vertex_count));
  for (std::uint64_t i = 0; i < vertex_count; ++i) {
    in.skip_space_and_comments();
    if (in.at_end())
      in.fail(ErrorCode::truncated,
              "file ends after " + std::to_string(i) + " of " + std::to_string(vertex_count) + " vertices");
    const double x = in.number("x coordinate", true);
    const double y = in.number("y coordinate", true);
    const double z = in.number("z coordinate", true);
    soup.points.emplace_back(x, y, z);
    in.skip_to_next_line();  // normals, colours, texture coordinates
  }

  soup.polygons.reserve(static_cast<std::size_t>(face_count));
  for (std::uint64_t f = 0; f < face_count; ++f) {
    in.skip_space_and_comments();
    if (in.at_end())
      in.fail(ErrorCode::truncated,
              "file ends after " + std::to_string(f) + " of " + std::to_string(face_count) + " faces");
    const std::uint64_t n = in.count("face vertex count", true);
    check_declared_count(in, n, 2, in.size(), "face vertices", options);
    std::vector<int> face(static_cast<std::size_t>(n));
    for (auto& index : face) index = checked_index(in, in.integer("vertex index", true), vertex_count);
    soup.polygons.push_back(std::move(face));
    in.skip_to_next_line();  // face colour
  }
  return soup;
}

}  // namespace fascicle::detail
