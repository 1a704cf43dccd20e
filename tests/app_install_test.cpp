// The installed program (`cmake --install`, `make install PREFIX=...`): the program, its
// alpha-wrap worker and the module libraries land in PREFIX/bin and PREFIX/lib, the program loads
// the installed libraries (not the build tree's), finds the installed worker beside itself, and
// still works after the installed tree is moved elsewhere; another CMake project finds the
// library with find_package(fascicle) and decomposes with it.

#include "test_common.h"

#include <catch2/catch.hpp>
#include <nlohmann/json.hpp>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

using namespace fascicle;
using test::read_text;
namespace fs = std::filesystem;

namespace {

bool executable(const fs::path& path) {
  std::error_code ec;
  return fs::is_regular_file(path, ec) && ::access(path.c_str(), X_OK) == 0;
}

// Installs the build into dir/prefix and moves the tree to dir/moved (so that nothing may point
// back into the prefix it was installed to); returns dir/moved.
fs::path install_and_move(const test::TempDir& dir) {
  const fs::path prefix = dir.path() / "prefix";
  REQUIRE(test::run_command("'" + std::string(FASCICLE_CMAKE_COMMAND) + "' --install '" + FASCICLE_BUILD_DIR +
                            "' --prefix '" + prefix.string() + "' >'" + dir.file("install.log") + "' 2>&1") == 0);
  const fs::path moved = dir.path() / "moved";
  fs::rename(prefix, moved);
  return moved;
}

// The libfascicle_* paths `ldd` resolves for `binary`; fails on any library not found.
std::vector<fs::path> fascicle_libraries(const test::TempDir& dir, const fs::path& binary) {
  REQUIRE(test::run_command("ldd '" + binary.string() + "' >'" + dir.file("ldd.txt") + "' 2>&1") == 0);
  std::istringstream ldd(read_text(dir.file("ldd.txt")));
  std::vector<fs::path> found;
  for (std::string line; std::getline(ldd, line);) {
    INFO(line);
    CHECK(line.find("not found") == std::string::npos);
    if (line.find("libfascicle_") == std::string::npos) continue;
    const std::size_t arrow = line.find("=> ");
    REQUIRE(arrow != std::string::npos);
    found.push_back(fs::canonical(line.substr(arrow + 3, line.find(" (") - arrow - 3)));
  }
  return found;
}

}  // namespace

TEST_CASE("the installed program runs from its own folder with its own libraries and worker", "[app][install]") {
  test::TempDir dir;
  const fs::path moved = install_and_move(dir);
  const fs::path bin = moved / "bin", lib = moved / FASCICLE_INSTALL_LIBDIR;
  const fs::path program = bin / "fascicle", worker = bin / "fascicle-wrap-worker";
  REQUIRE(executable(program));
  REQUIRE(executable(worker));
  for (const char* module : {"geometry", "repair", "morph", "springs", "fibres", "bench"})
    CHECK(fs::is_regular_file(lib / ("libfascicle_" + std::string(module) + ".so")));

  // Every libfascicle_* the program loads is the moved tree's.
  const std::vector<fs::path> loaded = fascicle_libraries(dir, program);
  CHECK(loaded.size() >= 6);
  for (const fs::path& path : loaded) CHECK(path.parent_path() == fs::canonical(lib));

  // It runs: a sample muscle decomposed, and a repair that needs the alpha wrap runs the
  // worker beside the program (the report names it).
  const std::string run = "'" + program.string() + "' -q ";
  CHECK(test::run_command(run + "--version >/dev/null") == 0);
  REQUIRE(test::run_command(run + "sample -o '" + dir.file("muscle.off") + "'") == 0);
  CHECK(test::run_command(run + "decompose '" + dir.file("muscle.off") + "' -o '" + dir.file("fibres.vtk") +
                          "' --report '" + dir.file("decompose.json") + "'") == 0);
  CHECK(fs::is_regular_file(dir.file("fibres.vtk")));
  CHECK(nlohmann::json::parse(read_text(dir.file("decompose.json")))["status"] == "ok");
  REQUIRE(test::run_command(run + "sample --kind capsule --inject inner_shell -o '" + dir.file("shells.off") + "'") ==
          0);
  REQUIRE(test::run_command("env -u FASCICLE_WRAP_WORKER " + run + "repair '" + dir.file("shells.off") + "' -o '" +
                            dir.file("wrapped.off") + "' --components merge --report '" + dir.file("repair.json") +
                            "'") == 0);
  const nlohmann::json report = nlohmann::json::parse(read_text(dir.file("repair.json")));
  REQUIRE(report["fallback"]["used"] == true);
  CHECK(fs::canonical(report["fallback"]["worker"].get<std::string>()) == fs::canonical(worker));
}

// Not under the sanitizers: the consumer is built without them and cannot load sanitized libraries.
TEST_CASE("another CMake project builds against the installed library and decomposes with it",
          "[app][install][no-sanitize]") {
  test::TempDir dir;
  const fs::path moved = install_and_move(dir);
  const fs::path include = moved / "include" / "fascicle";
  for (const char* header :
       {"fibres/decompose.h", "fibres/decompose_mesh.h", "geometry/mesh.h", "repair/repair.h", "morph/sphere_map.h",
        "springs/settle.h"})
    CHECK(fs::is_regular_file(include / header));
  CHECK_FALSE(fs::exists(include / "repair" / "detail"));  // CGAL inside; not part of the interface
  const std::string cmake = "'" + std::string(FASCICLE_CMAKE_COMMAND) + "' ";
  const fs::path build = dir.path() / "consumer-build";
  REQUIRE(test::run_command(cmake + "-S '" + FASCICLE_SOURCE_DIR + "/tests/install_consumer' -B '" + build.string() +
                            "' -DCMAKE_BUILD_TYPE=Release -DCMAKE_CXX_COMPILER='" + FASCICLE_CXX_COMPILER +
                            "' -DCMAKE_PREFIX_PATH='" + moved.string() + "' >'" + dir.file("configure.log") +
                            "' 2>&1") == 0);
  REQUIRE(test::run_command(cmake + "--build '" + build.string() + "' >'" + dir.file("build.log") + "' 2>&1") == 0);
  const fs::path consumer = build / "consumer";
  for (const fs::path& path : fascicle_libraries(dir, consumer))
    CHECK(path.parent_path() == fs::canonical(moved / FASCICLE_INSTALL_LIBDIR));
  CHECK(test::run_command("'" + consumer.string() + "' >'" + dir.file("consumer.txt") + "' 2>&1") == 0);
  CHECK(read_text(dir.file("consumer.txt")).find("fibres 16, status ok") != std::string::npos);
}
