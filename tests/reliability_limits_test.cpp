// Resource bounds for hostile input (docs/RELIABILITY.md, "Limits"): a header that declares huge
// counts in every format, a large file of random bytes, a file above the size limit, and a mesh
// of many tiny components. Each must end in a clear error (or a result) without allocating
// what the file merely claims; no test here asserts a time.

#include "geometry/errors.h"
#include "geometry/mesh_io.h"
#include "geometry/mesh_stats.h"
#include "geometry/primitives.h"
#include "geometry/read_points.h"
#include "geometry/thesis_format.h"
#include "test_common.h"

#include <signal.h>
#include <sys/resource.h>
#include <unistd.h>

#include <catch2/catch.hpp>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cctype>

#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>

using namespace fascicle;
namespace fs = std::filesystem;

namespace {

void write_bytes(const std::string& path, const std::string& data) {
  std::ofstream out(path, std::ios::binary);
  out.write(data.data(), static_cast<std::streamsize>(data.size()));
  REQUIRE(out.good());
}

std::string u32le(std::uint32_t v) {
  std::string s(4, '\0');
  std::memcpy(&s[0], &v, 4);
  return s;
}

std::string u32be(std::uint32_t v) {
  std::string s(4, '\0');
  for (int i = 0; i < 4; ++i) s[static_cast<std::size_t>(i)] = static_cast<char>((v >> (24 - 8 * i)) & 0xFFu);
  return s;
}

/// Peak resident memory of this process so far, bytes.
long long peak_rss_bytes() {
  struct rusage usage {};
  ::getrusage(RUSAGE_SELF, &usage);
  return static_cast<long long>(usage.ru_maxrss) * 1024;
}

/// Reads `path` with the reader for its kind; returns the error (fails the test when none).
Error read_error(const std::string& path) {
  const std::string ext = path.substr(path.rfind('.') + 1);
  try {
    if (ext == "txt")
      (void)read_thesis_model(path);
    else if (ext == "xyz")
      (void)read_points(path);
    else
      (void)read_polygon_soup(path);
  } catch (const Error& e) { return e; }
  FAIL("no error reading " << path);
  return Error(ErrorCode::internal, "unreachable");
}

/// Reads `path`, which must be refused: a one-line error naming the file, never `internal`, and
/// this process grows by less than 64 MB while reading it.
void check_refused_in_bounded_memory(const std::string& path) {
  INFO(path);
  const long long before = peak_rss_bytes();
  const Error e = read_error(path);
  INFO(e.what());
  CHECK(e.code() != ErrorCode::internal);
  CHECK(std::string(e.what()).find(path) == 0);
  CHECK(std::string(e.what()).find('\n') == std::string::npos);
  CHECK(peak_rss_bytes() - before < (64LL << 20));
}

}  // namespace

TEST_CASE("limits: a header declaring huge counts is refused before anything is allocated", "[reliability]") {
  test::TempDir dir;
  struct Hostile {
    const char* name;
    std::string content;
  };
  const std::string pt = std::string(12, '\0');
  const std::vector<Hostile> files = {
      {"vertices.off", "OFF\n4000000000 1 0\n0 0 0\n"},
      {"faces.off", "OFF\n3 2000000000 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n"},
      {"face-size.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n2000000000 0 1 2\n"},
      {"count-overflow.off", "OFF\n99999999999999999999999 1 0\n"},
      {"facets.stl", std::string(80, ' ') + u32le(0xFFFFFFFFu) + std::string(50, '\0')},
      {"vertex.ply",
       "ply\nformat ascii 1.0\nelement vertex 4000000000\nproperty float x\nproperty float y\n"
       "property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n"},
      {"face.ply",
       "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
       "property float z\nelement face 2000000000\nproperty list uchar int vertex_indices\nend_header\n" +
           std::string(36, '\0')},
      {"list.ply",
       "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
       "property float z\nelement face 1\nproperty list int int vertex_indices\nend_header\n" +
           std::string(36, '\0') + u32le(0x7FFFFFFFu) + std::string(12, '\0')},
      {"points.vtk", "# vtk DataFile Version 3.0\nx\nASCII\nDATASET POLYDATA\nPOINTS 3000000000 float\n0 0 0\n"},
      {"polygons.vtk",
       "# vtk DataFile Version 3.0\nx\nASCII\nDATASET POLYDATA\nPOINTS 3 float\n0 0 0 1 0 0 0 1 0\n"
       "POLYGONS 2000000000 8000000000\n3 0 1 2\n"},
      {"cell.vtk", "# vtk DataFile Version 3.0\nx\nBINARY\nDATASET POLYDATA\nPOINTS 3 float\n" + std::string(36, '\0') +
                       "\nPOLYGONS 1 4\n" + u32be(0x7FFFFFFFu) + std::string(12, '\0') + "\n"},
      {"points.txt", "3000000000 0\n0 0 0 i\n"},
      {"springs.txt", "1 1\n0 0 0 m\n0\n2000000000\n0 0 1\n"},
  };
  for (const Hostile& h : files) {
    const std::string path = dir.file(h.name);
    write_bytes(path, h.content);
    INFO(h.name);
    const long long before = peak_rss_bytes();
    const Error e = read_error(path);
    INFO(e.what());
    CHECK((e.code() == ErrorCode::too_large || e.code() == ErrorCode::truncated || e.code() == ErrorCode::malformed));
    CHECK(std::string(e.what()).find(path) == 0);
    CHECK(std::string(e.what()).find('\n') == std::string::npos);
    CHECK(peak_rss_bytes() - before < (64LL << 20));  // nothing near the declared size was touched
  }
}

TEST_CASE("limits: a file above max_file_bytes is refused without being read", "[reliability]") {
  test::TempDir dir;
  const std::string path = dir.file("huge.stl");
  { std::ofstream(path).put('x'); }
  // A sparse file: 5 GiB long, no disk used.
  std::filesystem::resize_file(path, 5ULL << 30);
  const long long before = peak_rss_bytes();
  try {
    (void)read_polygon_soup(path);
    FAIL("read a 5 GiB file");
  } catch (const InputError& e) {
    CHECK(e.code() == ErrorCode::too_large);
    CHECK(std::string(e.what()).find("max_file_bytes") != std::string::npos);
  }
  CHECK(peak_rss_bytes() - before < (64LL << 20));
}

TEST_CASE("limits: 200 MB of random bytes in every format gives a clear error", "[reliability][resource]") {
  test::TempDir dir;
  const std::size_t size = 200u << 20;
  std::string garbage(size, '\0');
  std::mt19937_64 random(20261121);
  for (std::size_t i = 0; i + 8 <= size; i += 8) {
    const std::uint64_t v = random();
    std::memcpy(&garbage[i], &v, 8);
  }
  for (const char* ext : {"off", "obj", "stl", "ply", "vtk", "txt", "xyz"}) {
    const std::string path = dir.file(std::string("garbage.") + ext);
    write_bytes(path, garbage);
    // The file is mapped, not copied (detail::FileBytes): refused at its first bad token or
    // count, only the pages read so far become resident, far less than the 200 MB.
    check_refused_in_bounded_memory(path);
    fs::remove(path);
  }
  // Below the file size limit the file is refused outright.
  const std::string path = dir.file("garbage.off");
  write_bytes(path, garbage);
  ReadOptions small;
  small.max_file_bytes = 100u << 20;
  try {
    (void)read_polygon_soup(path, small);
    FAIL("read a file above max_file_bytes");
  } catch (const InputError& e) { CHECK(e.code() == ErrorCode::too_large); }
}

TEST_CASE("limits: a 2 GiB file of garbage is refused without reading it all", "[reliability][resource]") {
  // 8 MiB of random bytes, then a hole up to 2 GiB (a sparse file: no disk used). Every mesh
  // reader refuses it at its first bad header, token or count, within the random head; the file
  // is mapped, not copied (detail::FileBytes), so the process does not grow by the file's size.
  // OBJ skips statements it does not know, so it refuses only at the first line that starts
  // with a bare 'v', 'f' or 'l' (about one random line in 3 700; the head holds some 33 000
  // lines); garbage without any is read to the end (docs/RELIABILITY.md, "Resource limits").
  // (scripts/hostile-inputs.sh runs 2 GB of real garbage through the program.)
  test::TempDir dir;
  std::string head(8u << 20, '\0');
  std::mt19937_64 random(7);
  for (std::size_t i = 0; i + 8 <= head.size(); i += 8) {
    const std::uint64_t v = random();
    std::memcpy(&head[i], &v, 8);
  }
  // `head` then a hole up to 2 GiB, as NAME.EXT.
  auto refused_in_bounded_memory = [&](const std::string& name, const char* ext) {
    const std::string path = dir.file(name + "." + ext);
    write_bytes(path, head);
    fs::resize_file(path, 2ULL << 30);
    check_refused_in_bounded_memory(path);
    fs::remove(path);
  };
  for (const char* ext : {"off", "obj", "stl", "ply", "vtk"}) refused_in_bounded_memory("sparse", ext);
  // The same with printable text and no line end anywhere: the PLY and VTK readers decide on the
  // first bytes, not after searching the first line's end. (OBJ reads such a file to the end.)
  for (char& c : head) c = static_cast<char>(' ' + static_cast<unsigned char>(c) % 95);
  for (const char* ext : {"off", "stl", "ply", "vtk"}) refused_in_bounded_memory("one-line", ext);
}

TEST_CASE("limits: a muscle among 20 000 tiny tetrahedra is kept as repaired alone", "[reliability][resource]") {
  // The small form of scripts/hostile-inputs.sh's "one muscle plus a million tiny components":
  // keep-largest must drop every tetrahedron and give the surface repaired alone.
  test::TempDir dir;
  const TriangleMesh ball = make_icosphere(4, 10.0);
  TriangleMesh mesh = ball;
  constexpr int n = 20000;
  const double spacing = 0.04, edge = 0.002;  // tiny beside the ball: 1e-4 of the diagonal
  for (int t = 0; t < n; ++t) {
    const Vec3 o(12.0 + spacing * (t % 28), -10.0 + spacing * ((t / 28) % 28), -10.0 + spacing * (t / 784));
    const int k = static_cast<int>(mesh.positions.size());
    mesh.positions.insert(mesh.positions.end(), {o, o + Vec3(edge, 0, 0), o + Vec3(0, edge, 0), o + Vec3(0, 0, edge)});
    mesh.triangles.insert(mesh.triangles.end(),
                          {{k, k + 2, k + 1}, {k, k + 1, k + 3}, {k, k + 3, k + 2}, {k + 1, k + 2, k + 3}});
  }
  const std::string alone_in = dir.file("ball.ply"), input = dir.file("ball-and-tets.ply");
  write_triangle_mesh(alone_in, ball);
  write_triangle_mesh(input, mesh);
  const std::string alone_out = dir.file("alone.off"), out = dir.file("out.off"), report = dir.file("r.json");
  REQUIRE(test::run_command("'" + test::program() + "' --quiet repair '" + alone_in + "' -o '" + alone_out + "'") == 0);
  const int code = test::run_command("'" + test::program() + "' --quiet --time-limit 120 repair '" + input + "' -o '" +
                                     out + "' --report '" + report + "'");
  REQUIRE(code == 0);
  const PolygonSoup alone = read_polygon_soup(alone_out), kept = read_polygon_soup(out);
  CHECK(kept.points.size() == alone.points.size());
  CHECK(kept.polygons.size() == alone.polygons.size());
  CHECK(bounding_box(kept.points).diagonal() == Approx(bounding_box(alone.points).diagonal()));
  std::ifstream in(report);
  const nlohmann::json j = nlohmann::json::parse(in);
  CHECK(j.at("status") == "repaired");
}

TEST_CASE("limits: 200 000 disjoint triangles read in bounded memory and repair ends cleanly",
          "[reliability][resource]") {
  test::TempDir dir;
  constexpr int n = 200000;
  TriangleMesh mesh;
  mesh.positions.reserve(3 * n);
  for (int i = 0; i < n; ++i) {
    const Vec3 base(static_cast<double>(i % 500) * 2.0, static_cast<double>((i / 500) % 400) * 2.0, 0.0);
    const int k = static_cast<int>(mesh.positions.size());
    mesh.positions.push_back(base);
    mesh.positions.push_back(base + Vec3(1, 0, 0));
    mesh.positions.push_back(base + Vec3(0, 1, 0.5));
    mesh.triangles.push_back({k, k + 1, k + 2});
  }
  const std::string input = dir.file("components.ply");
  write_triangle_mesh(input, mesh);
  const PolygonSoup soup = read_polygon_soup(input);
  CHECK(soup.polygons.size() == static_cast<std::size_t>(n));
  CHECK(soup.points.size() == static_cast<std::size_t>(3 * n));

  // The command line: a mesh in 200 000 pieces cannot be repaired by keeping its largest piece
  // and must be refused (or wrapped) cleanly; the time limit bounds the run.
  const std::string out = dir.file("out.off"), err = dir.file("stderr.txt");
  const int code = test::run_command("'" + test::program() + "' --quiet --time-limit 120 repair '" + input + "' -o '" +
                                     out + "' --no-wrap 2> '" + err + "'");
  std::ifstream in(err);
  const std::string stderr_text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  INFO("exit " << code << ", stderr: " << stderr_text);
  REQUIRE((code == exit_code(ErrorCode::repair_failed) || code == exit_code(ErrorCode::time_limit)));
  CHECK_FALSE(fs::exists(out));
  CHECK(stderr_text.rfind("fascicle: error: ", 0) == 0);
  CHECK(std::count(stderr_text.begin(), stderr_text.end(), '\n') == 1);
  // Peak memory of the child: far below what 200 000 triangles could justify wasting.
  struct rusage usage {};
  ::getrusage(RUSAGE_CHILDREN, &usage);
  CHECK(static_cast<long long>(usage.ru_maxrss) * 1024 < (2LL << 30));
}

// The alpha-wrap worker dies with its parent (PR_SET_PDEATHSIG asked for through
// geometry/subprocess.h): a --time-limit that fires during a wrap must not leave it running on as
// an orphan. The worker's command line does not name the input, so the processes are found by a
// mark in their environment, which the worker inherits.
TEST_CASE("limits: a time limit during alpha wrapping leaves no worker process behind", "[orphan][reliability]") {
  test::TempDir dir;
  constexpr int n = 60000;  // disjoint triangles: local repair cannot merge them, wrapping must
  TriangleMesh mesh;
  for (int i = 0; i < n; ++i) {
    const Vec3 base(static_cast<double>(i % 300) * 2.0, static_cast<double>(i / 300) * 2.0, 0.0);
    const int k = static_cast<int>(mesh.positions.size());
    mesh.positions.push_back(base);
    mesh.positions.push_back(base + Vec3(1, 0, 0));
    mesh.positions.push_back(base + Vec3(0, 1, 0.5));
    mesh.triangles.push_back({k, k + 1, k + 2});
  }
  const std::string input = dir.file("pieces.ply");
  write_triangle_mesh(input, mesh);
  // A very fine alpha makes the wrap far longer than the 3 s limit.
  const std::string mark = test::unique_mark();
  const int code = test::run_command(mark + " '" + test::program() + "' --quiet --time-limit 3 repair '" + input +
                                     "' -o '" + dir.file("out.off") +
                                     "' --components merge --wrap-alpha 0.00005 --wrap-seconds 600 2>/dev/null");
  REQUIRE(code == exit_code(ErrorCode::time_limit));
  ::usleep(500 * 1000);
  const std::vector<int> left = test::processes_with_environment(mark);
  for (int pid : left) ::kill(pid, SIGKILL);  // do not leave them running after the test
  CHECK(left.empty());
}
