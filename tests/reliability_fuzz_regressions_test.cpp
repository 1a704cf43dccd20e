// Regression inputs for the readers: every file under tests/data/fuzz/<reader>/ is an input that
// once crashed, hung or over-allocated a reader (minimised by libFuzzer, see docs/RELIABILITY.md)
// or a hand-made hostile input of the same kind. Each must now give a clean fascicle::Error: a
// one-line message naming the file, with an error code other than `internal`.
//
// Folders: off obj stl_ascii stl_binary ply vtk (read_polygon_soup), thesis (read_thesis_model),
// points (read_points), polylines (read_polylines). A file's extension picks the reader's format.

#include "geometry/errors.h"
#include "geometry/mesh_io.h"
#include "geometry/read_points.h"
#include "geometry/thesis_format.h"

#include <catch2/catch.hpp>

#include <algorithm>
#include <filesystem>
#include <string>
#include <vector>

using namespace fascicle;
namespace fs = std::filesystem;

namespace {

/// tests/data/fuzz next to this source: from FASCICLE_SOURCE_DIR when the build defines it,
/// else from __FILE__, which is absolute or (ccache with a base folder) relative to the folder
/// the test compiled in: <build>/tests under CMake, or the current folder.
fs::path fuzz_data_root() {
  std::vector<fs::path> candidates;
#ifdef FASCICLE_SOURCE_DIR
  candidates.push_back(fs::path(FASCICLE_SOURCE_DIR) / "tests");
#endif
  const fs::path source(__FILE__);
  if (source.is_absolute()) {
    candidates.push_back(source.parent_path());
  } else {
    candidates.push_back((fs::path(FASCICLE_PROGRAM).parent_path() / "tests" / source).parent_path());
    candidates.push_back(fs::current_path() / source.parent_path());
  }
  for (const fs::path& dir : candidates)
    if (fs::is_directory(dir / "data" / "fuzz")) return (dir / "data" / "fuzz").lexically_normal();
  return (candidates.front() / "data" / "fuzz").lexically_normal();
}

std::vector<std::string> files_of(const std::string& reader) {
  std::vector<std::string> files;
  const fs::path dir = fuzz_data_root() / reader;
  if (!fs::is_directory(dir)) return files;
  for (const auto& entry : fs::directory_iterator(dir))
    if (entry.is_regular_file()) files.push_back(entry.path().string());
  std::sort(files.begin(), files.end());
  return files;
}

void read_with(const std::string& reader, const std::string& path) {
  if (reader == "thesis")
    (void)read_thesis_model(path);
  else if (reader == "points")
    (void)read_points(path);
  else if (reader == "polylines")
    (void)read_polylines(path);
  else
    (void)read_polygon_soup(path);
}

}  // namespace

TEST_CASE("fuzz regressions: every stored input gives a clean one-line error", "[reliability][io]") {
  std::size_t total = 0;
  for (const char* reader : {"off", "obj", "stl_ascii", "stl_binary", "ply", "vtk", "thesis", "points", "polylines"}) {
    for (const std::string& path : files_of(reader)) {
      ++total;
      INFO(reader << ": " << path);
      try {
        read_with(reader, path);
        FAIL("read without an error");
      } catch (const Error& e) {
        const std::string message = e.what();
        INFO("error: " << message);
        CHECK(e.code() != ErrorCode::internal);
        CHECK(message.rfind(path, 0) == 0);
        CHECK(message.find('\n') == std::string::npos);
        CHECK(message.size() < 400);
      }
    }
  }
  // The folder ships with the sources; an empty walk means it moved.
  INFO("folder: " << fuzz_data_root());
  REQUIRE(total > 0);
}
