#pragma once
// Helpers shared by the tests: where the corpus and the program are, temporary folders,
// running the program as a user would.

#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <random>
#include <string>
#include <vector>

namespace fascicle::test {

/// The shared corpus folder (the environment's FASCICLE_DATA_DIR when set, else the one found
/// at configure time), or "" when absent (a user's clone): tests then skip with a message.
inline std::string data_dir() {
  const char* from_environment = std::getenv("FASCICLE_DATA_DIR");
  const std::string dir = from_environment != nullptr ? from_environment : FASCICLE_DATA_DIR;
  return std::filesystem::is_directory(dir) ? dir : std::string();
}

/// The built program.
inline std::string program() { return FASCICLE_PROGRAM; }

/// A whole file's bytes ("" when it cannot be read).
inline std::string read_text(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

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
/// Factor for the time budgets a test gives the program (FASCICLE_TEST_TIME_SCALE, default 1):
/// scripts/run-sanitized-tests.sh sets it, where ASan makes every run several times slower.
inline double time_scale() {
  const char* value = std::getenv("FASCICLE_TEST_TIME_SCALE");
  const double scale = value ? std::atof(value) : 1.0;
  return scale >= 1.0 ? scale : 1.0;
}

inline int run_command(const std::string& command) {
  const int status = std::system(command.c_str());
  if (status == -1) return -1;
  return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
}

/// Processes other than this one whose environment holds `entry` (NAME=VALUE, exactly): how a test
/// finds the processes it started, and theirs, whatever their command lines (a child inherits the
/// environment). A zombie's environment is unreadable, so a process that died and awaits its
/// parent's wait is not counted.
inline std::vector<int> processes_with_environment(const std::string& entry) {
  std::vector<int> pids;
  std::error_code ec;
  for (const auto& dir : std::filesystem::directory_iterator("/proc", ec)) {
    const std::string name = dir.path().filename().string();
    if (name.empty() || !std::all_of(name.begin(), name.end(), ::isdigit) || std::stoi(name) == ::getpid()) continue;
    std::ifstream in(dir.path() / "environ", std::ios::binary);
    const std::string environment((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    for (std::size_t at = 0; (at = environment.find(entry, at)) != std::string::npos; at += entry.size()) {
      if ((at == 0 || environment[at - 1] == '\0') &&
          (at + entry.size() == environment.size() || environment[at + entry.size()] == '\0')) {
        pids.push_back(std::stoi(name));
        break;
      }
    }
  }
  return pids;
}

/// A NAME=VALUE environment entry no other run uses, to mark the processes a test starts.
inline std::string unique_mark() {
  return "FASCICLE_TEST_MARK=" + std::to_string(::getpid()) + "-" + std::to_string(std::random_device{}());
}

}  // namespace fascicle::test

#define FASCICLE_REQUIRE_DATA()                                       \
  do {                                                                \
    if (fascicle::test::data_dir().empty()) {                         \
      WARN("skipped: corpus folder " FASCICLE_DATA_DIR " is absent"); \
      return;                                                         \
    }                                                                 \
  } while (0)
