// Landmark point files: `x y z` rows, CSV with a header row, 3D Slicer markups (.fcsv, .mrk.json).
#include "geometry/read_points.h"

#include "geometry/detail/parse_cursor.h"
#include "geometry/errors.h"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <array>
#include <cctype>
#include <charconv>
#include <optional>

namespace fascicle {

namespace {

bool blank(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\v' || c == '\f'; }

std::string_view trim(std::string_view s) {
  while (!s.empty() && blank(s.front())) s.remove_prefix(1);
  while (!s.empty() && blank(s.back())) s.remove_suffix(1);
  return s;
}

// A row's fields: split at commas or semicolons when the row has one, else at blanks.
std::vector<std::string_view> fields_of(std::string_view row) {
  std::vector<std::string_view> fields;
  const char separator = row.find(',') != std::string_view::npos   ? ','
                         : row.find(';') != std::string_view::npos ? ';'
                                                                   : '\0';
  if (separator != '\0') {
    for (;;) {
      const std::size_t at = row.find(separator);
      fields.push_back(trim(row.substr(0, at)));
      if (at == std::string_view::npos) break;
      row.remove_prefix(at + 1);
    }
    return fields;
  }
  std::size_t i = 0;
  while (i < row.size()) {
    while (i < row.size() && blank(row[i])) ++i;
    const std::size_t start = i;
    while (i < row.size() && !blank(row[i])) ++i;
    if (i > start) fields.push_back(row.substr(start, i - start));
  }
  return fields;
}

bool parse_number(std::string_view t, double& value) {
  if (!t.empty() && t.front() == '+') t.remove_prefix(1);
  if (t.empty()) return false;
  const auto result = std::from_chars(t.data(), t.data() + t.size(), value);
  return result.ec == std::errc() && result.ptr == t.data() + t.size();
}

std::string column_name(std::string_view field) {
  field = trim(field);
  if (field.size() >= 2 && field.front() == '"' && field.back() == '"') field = field.substr(1, field.size() - 2);
  std::string name(trim(field));
  for (char& c : name) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return name;
}

// The x, y and z columns a header names (x / y / z, or ParaView's Points:0 / 1 / 2), if it names all three.
std::optional<std::array<std::size_t, 3>> xyz_columns(const std::vector<std::string_view>& header) {
  std::array<std::size_t, 3> at{};
  std::array<bool, 3> found{};
  for (std::size_t c = 0; c < header.size(); ++c) {
    const std::string name = column_name(header[c]);
    for (int k = 0; k < 3; ++k)
      if (!found[k] && (name == std::string(1, "xyz"[k]) || name == "points:" + std::to_string(k))) {
        at[k] = c;
        found[k] = true;
      }
  }
  if (!found[0] || !found[1] || !found[2]) return std::nullopt;
  return at;
}

// 3D Slicer's markups JSON: every control point's position, in every markup of the file.
std::vector<Vec3> read_markups_json(const std::string& path, std::string_view data, const ReadOptions& options) {
  const nlohmann::json j = nlohmann::json::parse(data.begin(), data.end(), nullptr, false);
  if (j.is_discarded()) throw InputError(ErrorCode::malformed, path + ": not valid JSON");
  if (!j.is_object() || !j.contains("markups") || !j["markups"].is_array())
    throw InputError(ErrorCode::malformed, path + ": JSON without a \"markups\" list (3D Slicer markups expected)");
  std::vector<Vec3> points;
  for (const nlohmann::json& markup : j["markups"]) {
    if (!markup.is_object() || !markup.contains("controlPoints")) continue;
    for (const nlohmann::json& point : markup["controlPoints"]) {
      if (!point.is_object() || !point.contains("position")) continue;
      const nlohmann::json& p = point["position"];
      if (!p.is_array() || p.size() != 3 || !p[0].is_number() || !p[1].is_number() || !p[2].is_number())
        throw InputError(ErrorCode::malformed, path + ": control point " + std::to_string(points.size() + 1) +
                                                   ": \"position\" is not three numbers");
      const Vec3 v(p[0].get<double>(), p[1].get<double>(), p[2].get<double>());
      if (!v.allFinite())
        throw InputError(ErrorCode::bad_number,
                         path + ": control point " + std::to_string(points.size() + 1) + " is not finite");
      if (points.size() >= options.max_elements)
        throw InputError(ErrorCode::too_large,
                         path + ": more than " + std::to_string(options.max_elements) + " points");
      points.push_back(v);
    }
  }
  if (points.empty()) throw InputError(ErrorCode::file_empty, path + ": no control point in the markups");
  return points;
}

}  // namespace

std::vector<Vec3> read_points(const std::string& path, const ReadOptions& options) {
  const detail::FileBytes file(path, options);
  return detail::read_points(path, file.view(), options);
}

std::vector<Vec3> detail::read_points(const std::string& path, std::string_view data, const ReadOptions& options) {
  options.validate();
  if (data.substr(0, 3) == "\xEF\xBB\xBF") data.remove_prefix(3);  // UTF-8 byte order mark
  const std::size_t first = data.find_first_not_of(" \t\r\n");
  if (first != std::string_view::npos && data[first] == '{') return read_markups_json(path, data, options);

  std::vector<Vec3> points;
  std::optional<std::array<std::size_t, 3>> columns;  // set by a header row or a "# columns =" comment
  bool data_seen = false;
  std::size_t line = 0;
  const auto fail = [&](ErrorCode code, const std::string& what) {
    throw InputError(code, path + ": line " + std::to_string(line) + ": " + what);
  };
  while (!data.empty()) {
    ++line;
    const std::size_t end = data.find('\n');
    std::string_view row = data.substr(0, end);
    data.remove_prefix(end == std::string_view::npos ? data.size() : end + 1);
    const std::size_t hash = row.find('#');
    if (hash != std::string_view::npos) {
      // 3D Slicer's .fcsv names its columns in a comment: "# columns = id,x,y,z,...".
      std::string_view comment = trim(row.substr(hash + 1));
      if (!data_seen && comment.substr(0, 7) == "columns") {
        comment = trim(comment.substr(7));
        if (!comment.empty() && comment.front() == '=') columns = xyz_columns(fields_of(comment.substr(1)));
      }
      row = row.substr(0, hash);
    }
    row = trim(row);
    if (row.empty()) continue;
    const std::vector<std::string_view> fields = fields_of(row);
    if (!data_seen) {
      data_seen = true;
      // A first row that is not all numbers and names x, y and z columns is a header.
      double ignored = 0.0;
      const bool all_numbers = std::all_of(fields.begin(), fields.end(),
                                           [&](std::string_view f) { return parse_number(f, ignored); });
      if (!all_numbers) {
        if (const auto named = xyz_columns(fields)) {
          columns = named;
          continue;
        }
      }
    }
    if (points.size() >= options.max_elements)
      fail(ErrorCode::too_large, "more than " + std::to_string(options.max_elements) + " points");
    static const char* const names[] = {"x coordinate", "y coordinate", "z coordinate"};
    Vec3 p;
    if (columns) {
      for (int k = 0; k < 3; ++k) {
        const std::size_t c = (*columns)[static_cast<std::size_t>(k)];
        if (c >= fields.size())
          fail(ErrorCode::malformed, std::string("no ") + names[k] + " (the row has " +
                                         std::to_string(fields.size()) + " fields)");
        if (!parse_number(fields[c], p[k]))
          fail(ErrorCode::bad_number, std::string(names[k]) + " '" + detail::ParseCursor::shorten(fields[c]) +
                                          "' is not a number");
      }
    } else {
      for (int k = 0; k < 3; ++k) {
        if (static_cast<std::size_t>(k) >= fields.size()) fail(ErrorCode::malformed, std::string("missing ") + names[k]);
        if (!parse_number(fields[static_cast<std::size_t>(k)], p[k]))
          fail(ErrorCode::bad_number, std::string(names[k]) + " '" +
                                          detail::ParseCursor::shorten(fields[static_cast<std::size_t>(k)]) +
                                          "' is not a number");
      }
      if (fields.size() > 3)
        fail(ErrorCode::malformed,
             "unexpected '" + detail::ParseCursor::shorten(fields[3]) + "' after the three coordinates");
    }
    if (!p.allFinite()) fail(ErrorCode::bad_number, "a coordinate is not finite");
    points.push_back(p);
  }
  ++line;
  if (points.empty()) fail(ErrorCode::file_empty, "no point (only blanks, comments and a header)");
  return points;
}

}  // namespace fascicle
