// The thesis's text format (Zeleny 2011, appendix 2): sections of a count followed by one record
// per line. Indices are 0-based. Every section is required; '#' comments are tolerated.
#include "geometry/thesis_format.h"

#include "geometry/atomic_file.h"
#include "geometry/detail/parse_cursor.h"
#include "geometry/errors.h"

namespace fascicle {

namespace {

/// Reads a section's count on its own line; `min_line_bytes` is the shortest record line.
std::size_t section_count(detail::ParseCursor& in, const char* what, std::uint64_t min_line_bytes,
                          const ReadOptions& options) {
  in.skip_space_and_comments();
  if (in.at_end()) in.fail(ErrorCode::truncated, std::string("file ends before the ") + what + " count");
  const std::uint64_t n = in.count(what, true);
  detail::check_declared_count(in, n, min_line_bytes, in.size(), what, options);
  if (!in.at_line_end()) in.fail(ErrorCode::malformed, std::string("unexpected value after the ") + what + " count");
  in.skip_to_next_line();
  return static_cast<std::size_t>(n);
}

/// Moves to the next record line of a section (truncated when the file ends first).
void next_record(detail::ParseCursor& in, const char* what, std::size_t index, std::size_t count) {
  in.skip_space_and_comments();
  if (in.at_end())
    in.fail(ErrorCode::truncated,
            "file ends after " + std::to_string(index) + " of " + std::to_string(count) + " " + what);
}

void end_record(detail::ParseCursor& in) {
  if (!in.at_line_end())
    in.fail(ErrorCode::malformed,
            "unexpected '" + detail::ParseCursor::shorten(in.token_in_line()) + "' at the end of the line");
  in.skip_to_next_line();
}

int index_in_line(detail::ParseCursor& in, std::size_t point_count) {
  return detail::checked_index(in, in.integer("point index", true), point_count);
}

}  // namespace

ThesisModel read_thesis_model(const std::string& path, const ReadOptions& options) {
  const detail::FileBytes file(path, options);
  return detail::read_thesis(path, file.view(), options);
}

namespace detail {

ThesisModel read_thesis(const std::string& path, std::string_view data, const ReadOptions& options) {
  options.validate();
  detail::ParseCursor in(path, data);
  in.skip_byte_order_mark();
  in.set_comment('#');
  in.skip_space_and_comments();
  if (in.at_end()) in.fail(ErrorCode::file_empty, "no content (only blanks and comments)");

  ThesisModel model;
  const std::size_t header_line = in.line();
  const std::uint64_t n = in.count("point count", true);
  const std::uint64_t surface_declared = in.count("surface point count", true);
  detail::check_declared_count(in, n, 8, in.size(), "points", options);  // "0 0 0 m\n"
  end_record(in);
  model.points.reserve(static_cast<std::size_t>(n));
  model.surface.reserve(static_cast<std::size_t>(n));
  std::uint64_t surface = 0;
  for (std::size_t i = 0; i < n; ++i) {
    next_record(in, "points", i, static_cast<std::size_t>(n));
    const double x = in.number("x coordinate", true);
    const double y = in.number("y coordinate", true);
    const double z = in.number("z coordinate", true);
    const std::string_view flag = in.token_in_line();
    if (flag != "m" && flag != "i")
      in.fail(ErrorCode::malformed,
              "point flag '" + detail::ParseCursor::shorten(flag) + "' is neither 'm' (surface) nor 'i' (inner)");
    model.points.emplace_back(x, y, z);
    model.surface.push_back(flag == "m" ? 1 : 0);
    surface += flag == "m" ? 1 : 0;
    end_record(in);
  }
  if (surface != surface_declared)
    in.fail_at_line(header_line, ErrorCode::malformed,
                    "declares " + std::to_string(surface_declared) + " surface points but " + std::to_string(surface) +
                        " points are marked 'm'");

  const std::size_t points = model.points.size();
  const std::size_t t = section_count(in, "triangles", 6, options);
  model.triangles.reserve(t);
  for (std::size_t i = 0; i < t; ++i) {
    next_record(in, "triangles", i, t);
    Triangle tri{};
    for (int& v : tri) v = index_in_line(in, points);
    model.triangles.push_back(tri);
    end_record(in);
  }
  const std::size_t s = section_count(in, "springs", 6, options);
  model.springs.reserve(s);
  for (std::size_t i = 0; i < s; ++i) {
    next_record(in, "springs", i, s);
    ThesisModel::Spring spring;
    spring.a = index_in_line(in, points);
    spring.b = index_in_line(in, points);
    spring.stiffness = in.number("stiffness", true);
    model.springs.push_back(spring);
    end_record(in);
  }
  const std::size_t f = section_count(in, "fibres", 4, options);
  model.fibres.reserve(f);
  for (std::size_t i = 0; i < f; ++i) {
    next_record(in, "fibres", i, f);
    const int a = index_in_line(in, points);
    const int b = index_in_line(in, points);
    model.fibres.push_back({a, b});
    end_record(in);
  }
  for (auto* area : {&model.origin, &model.insertion}) {
    const char* what = area == &model.origin ? "origin-area points" : "insertion-area points";
    const std::size_t k = section_count(in, what, 2, options);
    area->reserve(k);
    for (std::size_t i = 0; i < k; ++i) {
      next_record(in, what, i, k);
      area->push_back(index_in_line(in, points));
      end_record(in);
    }
  }
  in.skip_space_and_comments();
  if (!in.at_end()) in.fail(ErrorCode::malformed, "unexpected content after the insertion area");
  return model;
}

}  // namespace detail

void write_thesis_model(const std::string& path, const ThesisModel& model) {
  const auto n = static_cast<long long>(model.points.size());
  FASCICLE_CHECK(model.surface.size() == model.points.size(), "writing " + path + ": one surface flag per point");
  auto check = [&](int i) { FASCICLE_CHECK(i >= 0 && i < n, "writing " + path + ": an index is out of range"); };
  std::string out;
  std::size_t surface = 0;
  for (char s : model.surface) surface += s != 0 ? 1 : 0;
  out += std::to_string(model.points.size()) + " " + std::to_string(surface) + "\n";
  for (std::size_t i = 0; i < model.points.size(); ++i) {
    const Vec3& p = model.points[i];
    FASCICLE_CHECK(p.allFinite(), "writing " + path + ": a point is not finite");
    for (int c = 0; c < 3; ++c) {
      detail::append_double(out, p[c]);
      out += ' ';
    }
    out += model.surface[i] != 0 ? "m\n" : "i\n";
  }
  out += std::to_string(model.triangles.size()) + "\n";
  for (const Triangle& t : model.triangles) {
    for (int i : t) check(i);
    out += std::to_string(t[0]) + " " + std::to_string(t[1]) + " " + std::to_string(t[2]) + "\n";
  }
  out += std::to_string(model.springs.size()) + "\n";
  for (const auto& s : model.springs) {
    check(s.a);
    check(s.b);
    FASCICLE_CHECK(std::isfinite(s.stiffness), "writing " + path + ": a stiffness is not finite");
    out += std::to_string(s.a) + " " + std::to_string(s.b) + " ";
    detail::append_double(out, s.stiffness);
    out += '\n';
  }
  out += std::to_string(model.fibres.size()) + "\n";
  for (const auto& f : model.fibres) {
    check(f[0]);
    check(f[1]);
    out += std::to_string(f[0]) + " " + std::to_string(f[1]) + "\n";
  }
  for (const auto* area : {&model.origin, &model.insertion}) {
    out += std::to_string(area->size()) + "\n";
    for (int i : *area) {
      check(i);
      out += std::to_string(i) + "\n";
    }
  }
  write_file_atomically(
      path, [&](std::ostream& stream) { stream.write(out.data(), static_cast<std::streamsize>(out.size())); });
}

}  // namespace fascicle
