#pragma once
// Helpers shared by the tests: where the corpus and the program are, temporary folders,
// running the program as a user would.

#include <sys/wait.h>

#include <algorithm>
#include <cctype>
#include <cstdlib>
#include <filesystem>
#include <random>
#include <string>
#include <vector>

namespace fascicle::test {

/// The shared corpus folder, or "" when absent (a user's clone): tests then skip with a message.
inline std::string data_dir() {
  const std::string dir = FASCICLE_DATA_DIR;
  return std::filesystem::is_directory(dir) ? dir : std::string();
}

/// The built program.
inline std::string program() { return FASCICLE_PROGRAM; }

/// A fresh empty folder under the system temp folder, removed by the destructor.
class TempDir {
 public:
  TempDir() {
    std::random_device rd;
    path_ = std::filesystem::temp_directory_path() / ("fascicle-test-" + std::to_string(rd()) + std::to_string(rd()));
    std::filesystem::create_directories(path_);
  }
  ~TempDir() {
    std::error_code ec;
    std::filesystem::remove_all(path_, ec);
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  std::string file(const std::string& name) const { return (path_ / name).string(); }
  const std::filesystem::path& path() const { return path_; }

 private:
  std::filesystem::path path_;
};

/// Files under `sub` of the corpus with one of the given lowercase extensions, sorted.
inline std::vector<std::string> corpus_files(const std::string& sub, const std::vector<std::string>& exts) {
  std::vector<std::string> files;
  const std::string root = data_dir();
  if (root.empty()) return files;
  for (const auto& entry : std::filesystem::recursive_directory_iterator(root + "/" + sub)) {
    if (!entry.is_regular_file()) continue;
    std::string ext = entry.path().extension().string();
    for (auto& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    for (const auto& e : exts)
      if (ext == "." + e) files.push_back(entry.path().string());
  }
  std::sort(files.begin(), files.end());
  return files;
}

/// Runs a shell command, returns its exit status (0..255), output discarded unless `log` given.
inline int run_command(const std::string& command) {
  const int status = std::system(command.c_str());
  if (status == -1) return -1;
  return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
}

}  // namespace fascicle::test

#define FASCICLE_REQUIRE_DATA()                                                       \
  do {                                                                                \
    if (fascicle::test::data_dir().empty()) {                                         \
      WARN("skipped: corpus folder " FASCICLE_DATA_DIR " is absent");                 \
      return;                                                                         \
    }                                                                                 \
  } while (0)
