// Mesh readers on bad input: one test per error code, each checking the code and that the
// one-line message names the file and the line (text) or byte offset (binary).
#include "geometry/errors.h"
#include "geometry/mesh_io.h"
#include "geometry/read_points.h"
#include "geometry/thesis_format.h"
#include "test_common.h"

#include <catch2/catch.hpp>

#include <atomic>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <new>
#include <random>

using namespace fascicle;
using fascicle::test::TempDir;

// ---- allocation probe: the largest single allocation while tracking is on ---------------------
namespace {
std::atomic<bool> g_tracking{false};
std::atomic<std::size_t> g_largest{0};
}  // namespace

void* operator new(std::size_t n) {
  if (g_tracking.load(std::memory_order_relaxed) && n > g_largest.load(std::memory_order_relaxed)) g_largest = n;
  if (void* p = std::malloc(n == 0 ? 1 : n)) return p;
  throw std::bad_alloc();
}
void* operator new(std::size_t n, const std::nothrow_t&) noexcept {
  try {
    return ::operator new(n);
  } catch (...) { return nullptr; }
}
// GCC flags free() on memory from a replaced operator new; here both sides are malloc/free.
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmismatched-new-delete"
void operator delete(void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
#pragma GCC diagnostic pop

namespace {

void write_bytes(const std::string& path, const std::string& content) {
  std::ofstream out(path, std::ios::binary);
  out.write(content.data(), static_cast<std::streamsize>(content.size()));
  REQUIRE(out.good());
}

template <class T>
void put(std::string& out, T value, bool big_endian = false) {
  char bytes[sizeof(T)];
  std::memcpy(bytes, &value, sizeof(T));
  if (big_endian)
    for (std::size_t i = 0; i < sizeof(T) / 2; ++i) std::swap(bytes[i], bytes[sizeof(T) - 1 - i]);
  out.append(bytes, sizeof(T));
}

/// Runs `read`, requires an InputError with `code` whose one-line message starts with the file
/// name and contains `where` (e.g. "line 3:" or "byte 84:"; "" to skip that check).
template <class Read>
void require_error(Read read, ErrorCode code, const std::string& file, const std::string& where) {
  try {
    read();
    FAIL("no exception for " << file);
  } catch (const InputError& e) {
    const std::string message = e.what();
    INFO(message);
    CHECK(e.code() == code);
    CHECK(message.rfind(file + ": ", 0) == 0);
    CHECK(message.find('\n') == std::string::npos);
    if (!where.empty()) CHECK(message.find(": " + where + ": ") != std::string::npos);
  }
}

void require_soup_error(const std::string& file, ErrorCode code, const std::string& where,
                        const ReadOptions& options = {}) {
  require_error([&] { read_polygon_soup(file, options); }, code, file, where);
}

std::string binary_stl(std::uint32_t facets, const std::string& header = "binary") {
  std::string bytes = header;
  bytes.resize(80, ' ');
  put<std::uint32_t>(bytes, facets);
  for (std::uint32_t f = 0; f < facets; ++f) {
    for (int i = 0; i < 3; ++i) put<float>(bytes, 0.0f);
    for (int v = 0; v < 3; ++v)
      for (int c = 0; c < 3; ++c) put<float>(bytes, static_cast<float>(v == c));
    put<std::uint16_t>(bytes, 0);
  }
  return bytes;
}

std::string binary_ply_tetra() {
  std::string s =
      "ply\nformat binary_little_endian 1.0\nelement vertex 4\nproperty float x\nproperty float y\n"
      "property float z\nelement face 4\nproperty list uchar int vertex_indices\nend_header\n";
  for (int v = 0; v < 4; ++v)
    for (int c = 0; c < 3; ++c) put<float>(s, static_cast<float>(v == c + 1));
  for (const auto& f : {std::array<int, 3>{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}}) {
    put<std::uint8_t>(s, 3);
    for (int i : f) put<std::int32_t>(s, i);
  }
  return s;
}

std::string binary_vtk_tetra() {
  std::string s = "# vtk DataFile Version 3.0\ntitle\n\nBINARY\nDATASET POLYDATA\nPOINTS 4 float\n";
  for (int v = 0; v < 4; ++v)
    for (int c = 0; c < 3; ++c) put<float>(s, static_cast<float>(v == c + 1), true);
  s += "\nPOLYGONS 4 16\n";
  for (int i : {3, 0, 2, 1, 3, 0, 1, 3, 3, 0, 3, 2, 3, 1, 2, 3}) put<std::int32_t>(s, i, true);
  s += "\n";
  return s;
}

const std::string tetra_off = "OFF\n4 4 0\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 2 1\n3 0 1 3\n3 0 3 2\n3 1 2 3\n";

}  // namespace

TEST_CASE("error file_missing: absent file or a folder", "[geometry][io][errors]") {
  TempDir dir;
  require_soup_error(dir.file("absent.off"), ErrorCode::file_missing, "");
  require_error([&] { read_points(dir.file("absent.xyz")); }, ErrorCode::file_missing, dir.file("absent.xyz"), "");
  std::filesystem::create_directories(dir.file("folder.stl"));
  require_soup_error(dir.file("folder.stl"), ErrorCode::file_missing, "");
}

TEST_CASE("error file_empty: no bytes, only comments, no faces", "[geometry][io][errors]") {
  TempDir dir;
  for (const char* name : {"e.off", "e.obj", "e.stl", "e.ply", "e.vtk", "e.txt"}) {
    write_bytes(dir.file(name), "");
    require_soup_error(dir.file(name), ErrorCode::file_empty, "line 1");
  }
  write_bytes(dir.file("c.off"), "# only\n\n# comments\n");
  require_soup_error(dir.file("c.off"), ErrorCode::file_empty, "line 4");
  write_bytes(dir.file("c.obj"), "   \n# nothing\n");
  require_soup_error(dir.file("c.obj"), ErrorCode::file_empty, "line 3");
  write_bytes(dir.file("points.off"), "OFF\n3 0 0\n0 0 0\n1 0 0\n0 1 0\n");
  require_soup_error(dir.file("points.off"), ErrorCode::file_empty, "");
  write_bytes(dir.file("p.xyz"), "# no points\n");
  require_error([&] { read_points(dir.file("p.xyz")); }, ErrorCode::file_empty, dir.file("p.xyz"), "line 2");
}

TEST_CASE("error unknown_format: extension or content", "[geometry][io][errors]") {
  TempDir dir;
  write_bytes(dir.file("mesh.xyz"), tetra_off);
  require_soup_error(dir.file("mesh.xyz"), ErrorCode::unknown_format, "");
  write_bytes(dir.file("x.off"), "HELLO 4 4 0\n");
  require_soup_error(dir.file("x.off"), ErrorCode::unknown_format, "line 1");
  write_bytes(dir.file("x.ply"), "\n\nply\n");
  require_soup_error(dir.file("x.ply"), ErrorCode::unknown_format, "line 1");
  write_bytes(dir.file("x.vtk"), "solid x\n");
  require_soup_error(dir.file("x.vtk"), ErrorCode::unknown_format, "line 1");
  write_bytes(dir.file("x.stl"),
              "this is some text that is not an STL file at all, and it is long enough for a header\n");
  require_soup_error(dir.file("x.stl"), ErrorCode::unknown_format, "line 1");
  write_bytes(dir.file("x.obj"), "hello world\nfoo bar\n");
  require_soup_error(dir.file("x.obj"), ErrorCode::unknown_format, "");
  write_bytes(dir.file("grid.vtk"), "# vtk DataFile Version 3.0\nt\nASCII\nDATASET STRUCTURED_POINTS\n");
  require_soup_error(dir.file("grid.vtk"), ErrorCode::unknown_format, "line 4");
}

TEST_CASE("error truncated: binary STL, PLY, VTK cut short, ASCII with fewer elements than declared",
          "[geometry][io][errors]") {
  TempDir dir;
  SECTION("binary STL, including one whose header starts with 'solid'") {
    for (const std::string header : {"binary", "solid but binary"}) {
      std::string stl = binary_stl(3, header);
      stl.resize(stl.size() - 30);  // inside the third facet
      write_bytes(dir.file("t.stl"), stl);
      require_soup_error(dir.file("t.stl"), ErrorCode::truncated, "byte 184");
    }
    write_bytes(dir.file("h.stl"), binary_stl(0).substr(0, 60) + std::string(1, '\0'));
    require_soup_error(dir.file("h.stl"), ErrorCode::truncated, "byte 0");
  }
  SECTION("binary PLY cut inside the faces") {
    const std::string ply = binary_ply_tetra();
    write_bytes(dir.file("t.ply"), ply.substr(0, ply.size() - 5));
    // The last face's list (count byte and 3 indices) starts 13 bytes before the original end.
    require_soup_error(dir.file("t.ply"), ErrorCode::truncated, "byte " + std::to_string(ply.size() - 13));
  }
  SECTION("binary VTK cut inside the cells") {
    const std::string vtk = binary_vtk_tetra();
    write_bytes(dir.file("t.vtk"), vtk.substr(0, vtk.size() - 20));
    require_soup_error(dir.file("t.vtk"), ErrorCode::truncated, "byte " + std::to_string(vtk.size() - 1 - 64));
  }
  SECTION("ASCII OFF and PLY with fewer elements than declared") {
    write_bytes(dir.file("t.off"), "OFF\n4 4 0\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 2 1\n");
    require_soup_error(dir.file("t.off"), ErrorCode::truncated, "line 8");
    write_bytes(dir.file("t.ply"),
                "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                "property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n"
                "0 0 0\n1 0 0\n0 1 0\n3 0 1\n");
    require_soup_error(dir.file("t.ply"), ErrorCode::truncated, "line 13");
  }
  SECTION("thesis file without its last sections") {
    write_bytes(dir.file("t.txt"), "3 3\n0 0 0 m\n1 0 0 m\n0 1 0 m\n1\n0 1 2\n0\n");
    require_error([&] { read_thesis_model(dir.file("t.txt")); }, ErrorCode::truncated, dir.file("t.txt"), "line 8");
  }
}

TEST_CASE("error index_out_of_range", "[geometry][io][errors]") {
  TempDir dir;
  write_bytes(dir.file("i.off"), "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n");
  require_soup_error(dir.file("i.off"), ErrorCode::index_out_of_range, "line 6");
  write_bytes(dir.file("n.off"), "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 -1 2\n");
  require_soup_error(dir.file("n.off"), ErrorCode::index_out_of_range, "line 6");
  write_bytes(dir.file("i.obj"), "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n");
  require_soup_error(dir.file("i.obj"), ErrorCode::index_out_of_range, "line 4");
  write_bytes(dir.file("z.obj"), "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n");
  require_soup_error(dir.file("z.obj"), ErrorCode::index_out_of_range, "line 4");
  write_bytes(dir.file("neg.obj"), "v 0 0 0\nv 1 0 0\nv 0 1 0\n\nf -1 -2 -4\n");
  require_soup_error(dir.file("neg.obj"), ErrorCode::index_out_of_range, "line 5");
  std::string ply = binary_ply_tetra();
  const std::size_t last = ply.size() - 4;
  std::int32_t bad = 4;
  std::memcpy(ply.data() + last, &bad, 4);
  write_bytes(dir.file("i.ply"), ply);
  require_soup_error(dir.file("i.ply"), ErrorCode::index_out_of_range, "byte " + std::to_string(last));
  std::string vtk = binary_vtk_tetra();
  const std::size_t last_vtk = vtk.size() - 5;  // the last index, before the final newline
  std::string five;
  put<std::int32_t>(five, 5, true);
  vtk.replace(last_vtk, 4, five);
  write_bytes(dir.file("i2.vtk"), vtk);
  require_soup_error(dir.file("i2.vtk"), ErrorCode::index_out_of_range, "byte " + std::to_string(last_vtk));
  write_bytes(dir.file("i.vtk"),
              "# vtk DataFile Version 3.0\nt\nASCII\nDATASET POLYDATA\nPOINTS 3 float\n0 0 0 1 0 0 0 1 0\n"
              "POLYGONS 1 4\n3 0 1 7\n");
  require_soup_error(dir.file("i.vtk"), ErrorCode::index_out_of_range, "line 8");
  write_bytes(dir.file("i.txt"), "3 3\n0 0 0 m\n1 0 0 m\n0 1 0 m\n1\n0 1 9\n0\n0\n0\n0\n");
  require_soup_error(dir.file("i.txt"), ErrorCode::index_out_of_range, "line 6");
}

TEST_CASE("error bad_number: NaN, Inf, unparsable coordinates", "[geometry][io][errors]") {
  TempDir dir;
  for (const std::string value : {"nan", "inf", "-Infinity", "1.2.3", "0x", "1e999"}) {
    INFO(value);
    write_bytes(dir.file("b.off"), "OFF\n3 1 0\n0 0 0\n1 " + value + " 0\n0 1 0\n3 0 1 2\n");
    require_soup_error(dir.file("b.off"), ErrorCode::bad_number, "line 4");
  }
  write_bytes(dir.file("b.obj"), "v 0 0 0\nv 1 0 nan\n");
  require_soup_error(dir.file("b.obj"), ErrorCode::bad_number, "line 2");
  write_bytes(dir.file("b.stl"), "solid s\nfacet normal 0 0 0\nouter loop\nvertex 0 0 0\nvertex 1 0 inf\n");
  require_soup_error(dir.file("b.stl"), ErrorCode::bad_number, "line 5");
  std::string stl = binary_stl(2);
  const float nan = std::numeric_limits<float>::quiet_NaN();
  std::memcpy(stl.data() + 84 + 50 + 12 + 4, &nan, 4);  // facet 1, vertex 0, y
  write_bytes(dir.file("nan.stl"), stl);
  require_soup_error(dir.file("nan.stl"), ErrorCode::bad_number, "byte 150");
  std::string ply = binary_ply_tetra();
  const std::size_t header = ply.find("end_header\n") + 11;
  const float inf = std::numeric_limits<float>::infinity();
  std::memcpy(ply.data() + header + 12 + 8, &inf, 4);  // vertex 1, z
  write_bytes(dir.file("inf.ply"), ply);
  require_soup_error(dir.file("inf.ply"), ErrorCode::bad_number, "byte " + std::to_string(header + 20));
  write_bytes(dir.file("b.xyz"), "1 2 3\n1 2 x\n");
  require_error([&] { read_points(dir.file("b.xyz")); }, ErrorCode::bad_number, dir.file("b.xyz"), "line 2");
}

TEST_CASE("error too_large: absurd declared counts allocate nothing", "[geometry][io][errors]") {
  TempDir dir;
  const std::string huge = "1000000000000";
  const std::vector<std::pair<std::string, std::string>> files = {
      {"h.off", "OFF\n" + huge + " 1 0\n0 0 0\n"},
      {"h2.off", "OFF\n3 " + huge + " 0\n0 0 0\n1 0 0\n0 1 0\n"},
      {"h.ply", "ply\nformat binary_little_endian 1.0\nelement vertex " + huge +
                    "\nproperty float x\nproperty float y\nproperty float z\nend_header\n" + std::string(64, '\0')},
      {"h.vtk",
       "# vtk DataFile Version 3.0\nt\nBINARY\nDATASET POLYDATA\nPOINTS " + huge + " float\n" + std::string(64, '\0')},
      {"h.txt", huge + " 0\n0 0 0 i\n"},
  };
  // Binary VTK reports byte offsets from its BINARY line on: here the end of the POINTS line.
  const std::string vtk_data_start = std::to_string(files[3].second.find(" float\n") + 7);
  const std::vector<std::string> where = {"line 2", "line 2", "line 3", "byte " + vtk_data_start, "line 1"};
  for (std::size_t i = 0; i < files.size(); ++i) {
    INFO(files[i].first);
    const std::string path = dir.file(files[i].first);
    write_bytes(path, files[i].second);
    g_largest = 0;
    g_tracking = true;
    try {
      read_polygon_soup(path);
      g_tracking = false;
      FAIL("no exception");
    } catch (const InputError& e) {
      g_tracking = false;
      INFO(e.what());
      CHECK(e.code() == ErrorCode::too_large);
      CHECK(std::string(e.what()).find(path + ": " + where[i] + ": ") == 0);
    }
    CHECK(g_largest.load() < (1u << 20));
  }
  // A list length inside a binary face claiming far more than the file holds.
  std::string ply =
      "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
      "element face 1\nproperty list int int vertex_indices\nend_header\n";
  ply += std::string(36, '\0');
  put<std::int32_t>(ply, 2000000000);
  write_bytes(dir.file("list.ply"), ply);
  g_largest = 0;
  g_tracking = true;
  CHECK_THROWS_AS(read_polygon_soup(dir.file("list.ply")), InputError);
  g_tracking = false;
  CHECK(g_largest.load() < (1u << 20));
}

TEST_CASE("error too_large: limits from ReadOptions", "[geometry][io][errors]") {
  TempDir dir;
  write_bytes(dir.file("t.off"), tetra_off);
  ReadOptions small;
  small.max_elements = 3;
  require_soup_error(dir.file("t.off"), ErrorCode::too_large, "line 2", small);
  ReadOptions tiny_file;
  tiny_file.max_file_bytes = 10;
  require_soup_error(dir.file("t.off"), ErrorCode::too_large, "", tiny_file);
  write_bytes(dir.file("s.stl"), binary_stl(4));
  require_soup_error(dir.file("s.stl"), ErrorCode::too_large, "byte 80", small);
  write_bytes(dir.file("m.obj"), "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\n");
  require_soup_error(dir.file("m.obj"), ErrorCode::too_large, "line 4", small);
  // The limit counts points and faces, not the values that store them (3 per point, 4 per cell).
  ReadOptions four;
  four.max_elements = 4;
  write_bytes(dir.file("t.vtk"), binary_vtk_tetra());
  CHECK(read_polygon_soup(dir.file("t.vtk"), four).polygons.size() == 4);
  CHECK(read_polygon_soup(dir.file("t.off"), four).polygons.size() == 4);
  CHECK(read_polygon_soup(dir.file("s.stl"), four).polygons.size() == 4);  // STL counts facets
  std::string ascii_stl = "solid x\n";
  for (int f = 0; f < 4; ++f)
    ascii_stl += "facet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\nendloop\nendfacet\n";
  write_bytes(dir.file("a.stl"), ascii_stl + "endsolid x\n");
  CHECK(read_polygon_soup(dir.file("a.stl"), four).polygons.size() == 4);
  four.max_elements = 3;
  const std::size_t points_data = binary_vtk_tetra().find("float\n") + 6;
  require_soup_error(dir.file("t.vtk"), ErrorCode::too_large, "byte " + std::to_string(points_data), four);
  require_soup_error(dir.file("a.stl"), ErrorCode::too_large, "line 28", four);  // the 4th endloop: 1 + 3 * 7 + 6
}

TEST_CASE("ReadOptions::validate names the bad field", "[geometry][io][errors]") {
  TempDir dir;
  write_bytes(dir.file("t.off"), tetra_off);
  ReadOptions options;
  CHECK_NOTHROW(options.validate());
  options.max_elements = 0;
  CHECK_THROWS_WITH(read_polygon_soup(dir.file("t.off"), options), Catch::Contains("max_elements"));
  CHECK_THROWS_AS(read_points(dir.file("t.off"), options), OptionError);
  options = ReadOptions{};
  options.max_file_bytes = 0;
  CHECK_THROWS_WITH(options.validate(), Catch::Contains("max_file_bytes"));
}

TEST_CASE("error malformed: syntax errors name the line", "[geometry][io][errors]") {
  TempDir dir;
  write_bytes(dir.file("m.off"), "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1\n");
  require_soup_error(dir.file("m.off"), ErrorCode::malformed, "line 6");
  write_bytes(dir.file("m2.off"), "OFF\n3 1 0\n0 0\n1 0 0\n0 1 0\n3 0 1 2\n");
  require_soup_error(dir.file("m2.off"), ErrorCode::malformed, "line 3");
  write_bytes(dir.file("bin.off"), "OFF BINARY\n");
  require_soup_error(dir.file("bin.off"), ErrorCode::malformed, "line 1");
  write_bytes(dir.file("4d.off"), "4OFF\n1 0 0\n0 0 0 1\n");
  require_soup_error(dir.file("4d.off"), ErrorCode::malformed, "line 1");
  write_bytes(dir.file("m.obj"), "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 x\n");
  require_soup_error(dir.file("m.obj"), ErrorCode::malformed, "line 4");
  write_bytes(dir.file("m.ply"), "ply\nformat ascii 1.0\nelement vertex 1\nproperty quad x\nend_header\n");
  require_soup_error(dir.file("m.ply"), ErrorCode::malformed, "line 4");
  write_bytes(dir.file("m.vtk"),
              "# vtk DataFile Version 3.0\nt\nASCII\nDATASET POLYDATA\nPOINTS 1 float\n0 0 0\nPOLYHEDRA 1 2\n");
  require_soup_error(dir.file("m.vtk"), ErrorCode::malformed, "line 7");
  write_bytes(dir.file("c.vtk"),
              "# vtk DataFile Version 3.0\nt\nASCII\nDATASET POLYDATA\nPOINTS 3 float\n0 0 0 1 0 0 0 1 0\n"
              "POLYGONS 1 5\n3 0 1 2\n");
  require_soup_error(dir.file("c.vtk"), ErrorCode::malformed, "line 8");  // 1 cell of 4 values, 5 declared
  write_bytes(dir.file("m.stl"), "solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nbanana\n");
  require_soup_error(dir.file("m.stl"), ErrorCode::malformed, "line 5");
  write_bytes(dir.file("m.txt"), "3 3\n0 0 0 m\n1 0 0 m\n0 1 0 x\n");
  require_error([&] { read_thesis_model(dir.file("m.txt")); }, ErrorCode::malformed, dir.file("m.txt"), "line 4");
  write_bytes(dir.file("o.txt"), "3 2\n0 0 0 m\n1 0 0 m\n0 1 0 m\n0\n0\n0\n0\n0\n");
  require_error([&] { read_thesis_model(dir.file("o.txt")); }, ErrorCode::malformed, dir.file("o.txt"), "line 1");
  write_bytes(dir.file("m.xyz"), "1 2 3 4\n");
  require_error([&] { read_points(dir.file("m.xyz")); }, ErrorCode::malformed, dir.file("m.xyz"), "line 1");
}

// ---- corrupted files: never a crash, a hang or another exception type -----------------------

namespace {

std::vector<std::pair<std::string, std::string>> seed_files() {
  std::string stl_ascii =
      "solid s\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\nendloop\nendfacet\nendsolid "
      "s\n";
  std::string ply_ascii =
      "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n"
      "element face 2\nproperty list uchar int vertex_indices\nelement tristrips 1\n"
      "property list int int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n1 1 0\n3 0 1 2\n3 1 3 2\n"
      "6 0 1 2 -1 2 3\n";
  std::string ply_be =
      "ply\nformat binary_big_endian 1.0\nelement vertex 3\nproperty double x\nproperty double y\n"
      "property double z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n";
  for (int v = 0; v < 3; ++v)
    for (int c = 0; c < 3; ++c) put<double>(ply_be, v == c ? 1.0 : 0.0, true);
  put<std::uint8_t>(ply_be, 3);
  for (int i : {0, 1, 2}) put<std::int32_t>(ply_be, i, true);
  std::string vtk_ascii =
      "# vtk DataFile Version 3.0\nt\n\nASCII\nDATASET POLYDATA\nPOINTS 4 float\n0 0 0 1 0 0 0 1 0 1 1 0\n"
      "LINES 1 3\n2 0 3\nPOLYGONS 1 4\n3 0 1 2\nTRIANGLE_STRIPS 1 4\n3 1 3 2\nCELL_DATA 3\n"
      "SCALARS a float 1\nLOOKUP_TABLE default\n1 2 3\n";
  return {{"a.off", tetra_off},
          {"a.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1/1 2/2 3/3\nf -1 -2 \\\n -3\nl 1 2\n"},
          {"a.stl", stl_ascii},
          {"b.stl", binary_stl(3, "solid header")},
          {"a.ply", ply_ascii},
          {"b.ply", binary_ply_tetra()},
          {"c.ply", ply_be},
          {"a.vtk", vtk_ascii},
          {"b.vtk", binary_vtk_tetra()},
          {"a.txt", "4 3\n0 0 0 m\n1 0 0 m\n0 1 0 m\n0.2 0.2 0.2 i\n1\n0 1 2\n1\n0 3 1.5\n1\n0 3\n1\n0\n1\n2\n"}};
}

std::string mutate(const std::string& original, std::mt19937& rng) {
  std::string s = original;
  const auto pick = [&](std::size_t n) { return std::uniform_int_distribution<std::size_t>(0, n - 1)(rng); };
  const char alphabet[] = "0123456789-+.eE \n\\/#abcOFFnanif\xff";
  const int edits = 1 + static_cast<int>(pick(3));
  for (int e = 0; e < edits && !s.empty(); ++e) {
    switch (pick(5)) {
      case 0: s.resize(pick(s.size())); break;                                           // truncate
      case 1: s[pick(s.size())] = static_cast<char>(pick(256)); break;                   // random byte
      case 2: s[pick(s.size())] = alphabet[pick(sizeof(alphabet) - 1)]; break;           // plausible char
      case 3: s.insert(pick(s.size()), 1, alphabet[pick(sizeof(alphabet) - 1)]); break;  // insertion
      default: {                                                                         // a huge count
        const std::size_t at = pick(s.size());
        s.insert(at, pick(2) ? "999999999999" : "2147483647");
      }
    }
  }
  return s;
}

}  // namespace

TEST_CASE("corrupted files give an InputError or a valid soup, nothing else", "[geometry][io][errors][fuzz]") {
  TempDir dir;
  std::mt19937 rng(20111);  // fixed seed: the same corruptions on every run
  std::size_t errors = 0, successes = 0;
  for (const auto& [name, content] : seed_files()) {
    const std::string path = dir.file(name);
    write_bytes(path, content);
    {
      INFO(name);
      REQUIRE_NOTHROW(read_polygon_soup(path));  // the seeds themselves are valid
    }
    for (int round = 0; round < 400; ++round) {
      const std::string bad = mutate(content, rng);
      std::filesystem::remove(path);  // rewriting by truncation makes ext4 flush on close: slow
      write_bytes(path, bad);
      try {
        const PolygonSoup soup = read_polygon_soup(path);
        for (const Vec3& p : soup.points) REQUIRE(p.allFinite());
        for (const auto& polygon : soup.polygons)
          for (int i : polygon) REQUIRE((i >= 0 && static_cast<std::size_t>(i) < soup.points.size()));
        ++successes;
      } catch (const InputError& e) {
        const std::string message = e.what();
        INFO(name << ": " << message);
        REQUIRE(message.rfind(path + ": ", 0) == 0);
        REQUIRE(message.find('\n') == std::string::npos);
        ++errors;
      }
    }
  }
  CHECK(errors > 1000);  // most corruptions are caught
  CHECK(successes > 0);  // some are harmless (a changed digit)
}

TEST_CASE("landmark points as CSV: separators, a header row naming x, y and z, ParaView's Points columns",
          "[geometry][io]") {
  TempDir dir;
  const std::vector<Vec3> expected{Vec3(1.5, 2, -3), Vec3(40, 5, 6)};
  write_bytes(dir.file("a.csv"), "1.5,2,-3\n40, 5 ,6\n");
  CHECK(read_points(dir.file("a.csv")) == expected);
  write_bytes(dir.file("b.csv"), "1.5;2;-3\r\n40;5;6\r\n");
  CHECK(read_points(dir.file("b.csv")) == expected);
  write_bytes(dir.file("c.csv"), "label,\"X\",\"Y\",\"Z\",note\nA,1.5,2,-3,crest\nB,4e1,5,6,\n");
  CHECK(read_points(dir.file("c.csv")) == expected);
  write_bytes(dir.file("d.csv"), "\"Points:2\",\"vtkOriginalIndices\",\"Points:0\",\"Points:1\"\n-3,0,1.5,2\n6,1,40,5\n");
  CHECK(read_points(dir.file("d.csv")) == expected);
  // Errors stay one line with the row: a header without a z column is no header.
  write_bytes(dir.file("e.csv"), "x,y,w\n1,2,3\n");
  require_error([&] { read_points(dir.file("e.csv")); }, ErrorCode::bad_number, dir.file("e.csv"), "line 1");
  write_bytes(dir.file("f.csv"), "id,x,y,z\n1,1.5,2\n");
  require_error([&] { read_points(dir.file("f.csv")); }, ErrorCode::malformed, dir.file("f.csv"), "line 2");
  write_bytes(dir.file("g.csv"), "x,y,z\n");
  require_error([&] { read_points(dir.file("g.csv")); }, ErrorCode::file_empty, dir.file("g.csv"), "line 2");
}

TEST_CASE("landmark points from 3D Slicer markups: .fcsv and .mrk.json", "[geometry][io]") {
  TempDir dir;
  const std::vector<Vec3> expected{Vec3(-12.5, 30.25, 7), Vec3(4, 5, 6)};
  write_bytes(dir.file("f.fcsv"),
              "# Markups fiducial file version = 4.11\n# CoordinateSystem = LPS\n"
              "# columns = id,x,y,z,ow,ox,oy,oz,vis,sel,lock,label,desc,associatedNodeID\n"
              "1,-12.5,30.25,7,0,0,0,1,1,1,0,F-1,,\n"
              "2,4,5,6,0,0,0,1,1,1,0,F-2,,vtkMRMLScalarVolumeNode1\n");
  CHECK(read_points(dir.file("f.fcsv")) == expected);
  write_bytes(dir.file("m.mrk.json"),
              R"({"@schema": "https://example.org/markups-schema-v1.0.3.json#",
                  "markups": [{"type": "Fiducial", "coordinateSystem": "LPS", "controlPoints": [
                    {"id": "1", "label": "F-1", "position": [-12.5, 30.25, 7.0], "positionStatus": "defined"},
                    {"id": "2", "label": "F-2", "position": [4, 5, 6], "positionStatus": "defined"}]}]})");
  CHECK(read_points(dir.file("m.mrk.json")) == expected);
  write_bytes(dir.file("n.mrk.json"), R"({"markups": [{"type": "Fiducial", "controlPoints": []}]})");
  require_error([&] { read_points(dir.file("n.mrk.json")); }, ErrorCode::file_empty, dir.file("n.mrk.json"), "");
  write_bytes(dir.file("o.mrk.json"), R"({"markups": [{"controlPoints": [{"position": [1, 2]}]}]})");
  require_error([&] { read_points(dir.file("o.mrk.json")); }, ErrorCode::malformed, dir.file("o.mrk.json"), "");
  write_bytes(dir.file("p.mrk.json"), "{\"markups\": [");
  require_error([&] { read_points(dir.file("p.mrk.json")); }, ErrorCode::malformed, dir.file("p.mrk.json"), "");
}
