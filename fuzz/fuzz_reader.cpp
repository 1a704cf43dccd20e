// libFuzzer target for one Fascicle reader, chosen at compile time by FASCICLE_FUZZ_READER
// (off obj stl_ascii stl_binary ply vtk thesis points polylines). Built by fuzz/CMakeLists.txt
// (make fuzz) with clang -fsanitize=fuzzer,address,undefined; see docs/RELIABILITY.md.
//
// The contract checked on every input: the reader either returns data that meets its documented
// guarantees (every index in range, every coordinate finite) or throws fascicle::Error with a
// one-line message naming the file. Anything else (a crash, a sanitizer report, another
// exception type such as std::bad_alloc, a broken guarantee) aborts, which libFuzzer records.
#include "geometry/detail/parse_cursor.h"
#include "geometry/errors.h"
#include "geometry/mesh_io.h"
#include "geometry/read_points.h"
#include "geometry/thesis_format.h"

#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <string_view>

namespace {

constexpr const char* kFile = "fuzz-input";

[[noreturn]] void broken(const std::string& what) {
  std::fprintf(stderr, "fuzz contract broken: %s\n", what.c_str());
  std::abort();
}

void check_points(const std::vector<fascicle::Vec3>& points) {
  for (const auto& p : points)
    if (!p.allFinite()) broken("a point is not finite");
}

void check_index(long long i, std::size_t n) {
  if (i < 0 || static_cast<std::size_t>(i) >= n) broken("index " + std::to_string(i) + " out of range");
}

[[maybe_unused]] void check_soup(const fascicle::PolygonSoup& soup) {
  check_points(soup.points);
  for (const auto& polygon : soup.polygons)
    for (int i : polygon) check_index(i, soup.points.size());
}

/// Writes `data` to a per-process temporary file with extension `ext` (for readers that take a
/// path only) and returns its path.
[[maybe_unused]] std::string temp_file(std::string_view data, const char* ext) {
  static const std::string base = [] {
    const char* dir = std::getenv("FUZZ_TMPDIR");
    return std::string(dir != nullptr ? dir : "/tmp") + "/fascicle-fuzz-" + std::to_string(::getpid());
  }();
  const std::string path = base + "." + ext;
  std::FILE* f = std::fopen(path.c_str(), "wb");
  if (f == nullptr) broken("cannot write " + path);
  if (!data.empty() && std::fwrite(data.data(), 1, data.size(), f) != data.size()) broken("short write " + path);
  std::fclose(f);
  return path;
}

void run(std::string_view input) {
  using namespace fascicle;
  const ReadOptions options;  // the defaults every command uses
  const std::string name = std::string(kFile) + "." FASCICLE_FUZZ_EXT;
#if defined(FASCICLE_FUZZ_OFF)
  check_soup(detail::read_off(name, input, options));
#elif defined(FASCICLE_FUZZ_OBJ)
  const detail::ObjData obj = detail::read_obj_data(name, input, options);
  check_points(obj.points);
  for (const auto* list : {&obj.faces, &obj.lines})
    for (const auto& element : *list)
      for (int i : element) check_index(i, obj.points.size());
#elif defined(FASCICLE_FUZZ_STL_ASCII)
  check_soup(detail::read_stl(name, input, options));
#elif defined(FASCICLE_FUZZ_STL_BINARY)
  // Half of the inputs get a facet count that matches their size, so that most of them take
  // the binary path (which is recognised by that exact size) rather than failing the header.
  std::string data(input);
  if (data.size() >= 84 && (static_cast<unsigned char>(data[0]) & 1u) == 0) {
    const auto count = static_cast<std::uint32_t>((data.size() - 84) / 50);
    data.resize(84 + 50 * static_cast<std::size_t>(count));
    std::memcpy(&data[80], &count, 4);  // little endian host (x86-64)
  }
  check_soup(detail::read_stl(name, data, options));
#elif defined(FASCICLE_FUZZ_PLY)
  check_soup(detail::read_ply(name, input, options));
#elif defined(FASCICLE_FUZZ_VTK)
  const detail::VtkPolyData vtk = detail::read_vtk(name, input, options);
  check_points(vtk.points);
  for (const auto* list : {&vtk.polygons, &vtk.lines})
    for (const auto& element : *list)
      for (int i : element) check_index(i, vtk.points.size());
  for (const auto& array : vtk.line_cell_data)
    if (array.values.size() != vtk.lines.size()) broken("cell array size differs from the line count");
#elif defined(FASCICLE_FUZZ_THESIS)
  const ThesisModel model = detail::read_thesis(name, input, options);
  check_points(model.points);
  if (model.surface.size() != model.points.size()) broken("surface flags differ from points");
  const std::size_t n = model.points.size();
  for (const auto& t : model.triangles)
    for (int i : t) check_index(i, n);
  for (const auto& s : model.springs) {
    check_index(s.a, n);
    check_index(s.b, n);
    if (!std::isfinite(s.stiffness)) broken("stiffness not finite");
  }
  for (const auto& f : model.fibres) {
    check_index(f[0], n);
    check_index(f[1], n);
  }
  for (int i : model.origin) check_index(i, n);
  for (int i : model.insertion) check_index(i, n);
#elif defined(FASCICLE_FUZZ_POINTS)
  const auto points = detail::read_points(name, input, options);
  if (points.empty()) broken("no point returned without an error");
  check_points(points);
#elif defined(FASCICLE_FUZZ_POLYLINES)
  // read_polylines takes a path: the input goes through a temporary file. A leading "# vtk"
  // picks the VTK reader, anything else the OBJ one.
  const bool vtk = input.substr(0, 5) == "# vtk";
  const Polylines lines = read_polylines(temp_file(input, vtk ? "vtk" : "obj"), options);
  if (lines.lines.empty()) broken("no polyline returned without an error");
  for (const auto& line : lines.lines) check_points(line);
  for (const auto& array : lines.cell_data)
    if (array.values.size() != lines.lines.size()) broken("cell array size differs from the line count");
#else
#error "define one FASCICLE_FUZZ_<READER>"
#endif
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view input(reinterpret_cast<const char*>(data), size);
  try {
    run(input);
  } catch (const fascicle::Error& error) {
    const std::string_view message = error.what();
    if (message.empty()) broken("empty error message");
    if (message.find('\n') != std::string_view::npos) broken("error message is not one line: " + std::string(message));
    if (message.find(kFile) == std::string_view::npos && message.find("fascicle-fuzz-") == std::string_view::npos)
      broken("error message does not name the file: " + std::string(message));
  }
  // Any other exception (std::bad_alloc, std::length_error, ...) escapes: libFuzzer reports it.
  return 0;
}
