// STL reader, ASCII and binary. Binary is recognised by its exact size (84 + 50 n bytes for the
// n facets its header declares) even when the 80-byte header starts with "solid", as many
// exporters write; otherwise a file starting with "solid" and holding no NUL byte is ASCII.
// Each facet gives its own three points (STL stores no shared vertices; welding is repair's job).
#include "geometry/detail/parse_cursor.h"

#include <algorithm>
#include <cctype>
#include <climits>

namespace fascicle::detail {

namespace {

bool iequals(std::string_view a, std::string_view b) {
  if (a.size() != b.size()) return false;
  for (std::size_t i = 0; i < a.size(); ++i)
    if (std::tolower(static_cast<unsigned char>(a[i])) != b[i]) return false;
  return true;
}

bool starts_with_solid(std::string_view data) {
  std::size_t p = data.substr(0, 3) == "\xEF\xBB\xBF" ? 3 : 0;
  while (p < data.size() && std::isspace(static_cast<unsigned char>(data[p]))) ++p;
  if (data.size() - p < 5 || !iequals(data.substr(p, 5), "solid")) return false;
  return data.size() - p == 5 || std::isspace(static_cast<unsigned char>(data[p + 5]));
}

bool has_nul(std::string_view data) { return data.find('\0') != std::string_view::npos; }

PolygonSoup read_binary_stl(const std::string& path, std::string_view data, const ReadOptions& options) {
  ParseCursor in(path, data);
  in.set_binary_locations(true);
  in.require(84, "the 84-byte binary STL header");
  in.skip_bytes(80, "header");
  const auto count = static_cast<std::uint64_t>(ParseCursor::load<std::uint32_t>(data.data() + 80, false));
  in.skip_bytes(4, "facet count");
  const std::uint64_t limit = std::min<std::uint64_t>(options.max_elements, INT_MAX / 3);
  if (count > limit)
    in.fail_at_byte(80, ErrorCode::too_large,
                    "declares " + std::to_string(count) + " facets, more than the limit of " + std::to_string(limit));
  const std::uint64_t available = (data.size() - 84) / 50;
  if (count > available)
    in.fail_at_byte(84 + available * 50, ErrorCode::truncated,
                    "file ends inside facet " + std::to_string(available) + " of " + std::to_string(count) +
                        " declared (" + std::to_string(data.size()) + " bytes, " + std::to_string(84 + count * 50) +
                        " needed)");

  PolygonSoup soup;
  soup.points.resize(static_cast<std::size_t>(count) * 3);
  soup.polygons.resize(static_cast<std::size_t>(count));
  const char* p = data.data() + 84;
  for (std::size_t f = 0; f < count; ++f, p += 50) {
    for (int v = 0; v < 3; ++v) {
      const char* q = p + 12 + 12 * v;
      Vec3& point = soup.points[3 * f + static_cast<std::size_t>(v)];
      for (int c = 0; c < 3; ++c) {
        const float value = ParseCursor::load<float>(q + 4 * c, false);
        if (!std::isfinite(value))
          in.fail_at_byte(
              static_cast<std::size_t>(q + 4 * c - data.data()), ErrorCode::bad_number,
              "facet " + std::to_string(f) + " vertex " + std::to_string(v) + " has a coordinate that is not finite");
        point[c] = static_cast<double>(value);
      }
    }
    const int first = static_cast<int>(3 * f);
    soup.polygons[f] = {first, first + 1, first + 2};
  }
  return soup;
}

/// Facets are limited by options.max_elements, as in binary STL (each gives 3 points).
PolygonSoup read_ascii_stl(const std::string& path, std::string_view data, const ReadOptions& options) {
  ParseCursor in(path, data);
  in.skip_byte_order_mark();
  const std::uint64_t limit = std::min<std::uint64_t>(options.max_elements, INT_MAX);
  PolygonSoup soup;
  bool in_solid = false, in_facet = false, in_loop = false;
  std::vector<int> loop;
  for (;;) {
    const std::string_view t = in.token_any();
    if (t.empty()) break;
    if (iequals(t, "vertex")) {
      if (!in_loop) in.fail(ErrorCode::malformed, "'vertex' outside 'outer loop'");
      if (soup.points.size() >= static_cast<std::size_t>(INT_MAX))
        in.fail(ErrorCode::too_large, "more than " + std::to_string(INT_MAX) + " vertices");
      const double x = in.number("x coordinate", false);
      const double y = in.number("y coordinate", false);
      const double z = in.number("z coordinate", false);
      loop.push_back(static_cast<int>(soup.points.size()));
      soup.points.emplace_back(x, y, z);
    } else if (iequals(t, "facet")) {
      if (!in_solid || in_facet) in.fail(ErrorCode::malformed, "unexpected 'facet'");
      in_facet = true;
      const std::string_view normal = in.token_any();
      if (!iequals(normal, "normal"))
        in.fail(ErrorCode::malformed, "expected 'normal' after 'facet', found '" + ParseCursor::shorten(normal) + "'");
      for (int i = 0; i < 3; ++i)  // the normal is recomputed downstream; only its presence matters
        if (in.token_any().empty()) in.fail(ErrorCode::truncated, "file ends inside a facet normal");
    } else if (iequals(t, "outer")) {
      if (!in_facet || in_loop) in.fail(ErrorCode::malformed, "unexpected 'outer'");
      const std::string_view word = in.token_any();
      if (!iequals(word, "loop"))
        in.fail(ErrorCode::malformed, "expected 'loop' after 'outer', found '" + ParseCursor::shorten(word) + "'");
      in_loop = true;
      loop.clear();
    } else if (iequals(t, "endloop")) {
      if (!in_loop) in.fail(ErrorCode::malformed, "unexpected 'endloop'");
      if (soup.polygons.size() >= limit)
        in.fail(ErrorCode::too_large, "more than " + std::to_string(limit) + " facets");
      soup.polygons.push_back(loop);
      in_loop = false;
    } else if (iequals(t, "endfacet")) {
      if (!in_facet || in_loop) in.fail(ErrorCode::malformed, "unexpected 'endfacet'");
      in_facet = false;
    } else if (iequals(t, "solid")) {
      if (in_solid) in.fail(ErrorCode::malformed, "'solid' inside a solid");
      in_solid = true;
      in.rest_of_line();  // the name
    } else if (iequals(t, "endsolid")) {
      if (!in_solid || in_facet) in.fail(ErrorCode::malformed, "unexpected 'endsolid'");
      in_solid = false;
      in.rest_of_line();
    } else {
      in.fail(ErrorCode::malformed, "unexpected '" + ParseCursor::shorten(t) + "' in ASCII STL");
    }
  }
  if (in_facet) in.fail(ErrorCode::truncated, "file ends inside a facet");
  return soup;
}

}  // namespace

PolygonSoup read_stl(const std::string& path, std::string_view data, const ReadOptions& options) {
  if (data.size() >= 84) {
    const auto count = static_cast<std::uint64_t>(ParseCursor::load<std::uint32_t>(data.data() + 80, false));
    if (84 + 50 * count == data.size()) return read_binary_stl(path, data, options);
  }
  // Binary STL has NUL bytes at least in its facet count (below 16 M facets) or attributes.
  const bool text = !has_nul(data.substr(0, 4096));
  if (text) {
    if (starts_with_solid(data) || data.substr(0, 4096).find("facet") != std::string_view::npos)
      return read_ascii_stl(path, data, options);  // the latter reports the missing 'solid'
    if (data.find_first_not_of(" \t\r\n") == std::string_view::npos)
      throw InputError(ErrorCode::file_empty, path + ": line 1: no content (only blanks)");
    throw InputError(ErrorCode::unknown_format, path + ": line 1: not an STL file (text without 'solid' or 'facet')");
  }
  return read_binary_stl(path, data, options);
}

}  // namespace fascicle::detail
