#include "geometry/atomic_file.h"

#include "geometry/errors.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cctype>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <random>

namespace fascicle {
namespace fs = std::filesystem;

namespace {

std::string temporary_name(const fs::path& target) {
  static std::atomic<unsigned> counter{0};
  std::random_device rd;
  const std::string name = "." + target.filename().string() + ".tmp." + std::to_string(::getpid()) + "." +
                           std::to_string(counter++) + "." + std::to_string(rd() % 100000);
  return (target.parent_path() / name).string();
}

void sync_file(const std::string& path) {
  const int fd = ::open(path.c_str(), O_RDONLY);
  if (fd >= 0) {
    ::fsync(fd);
    ::close(fd);
  }
}

}  // namespace

void write_file_atomically(const std::string& path, const std::function<void(std::ostream&)>& write, bool binary) {
  const fs::path target(path);
  if (target.filename().empty()) throw IoError(path + ": output path names no file");
  std::error_code ec;
  if (fs::is_directory(target, ec)) throw IoError(path + ": output path is a directory");
  const fs::path dir = target.parent_path().empty() ? fs::path(".") : target.parent_path();
  if (!fs::is_directory(dir, ec)) throw IoError(path + ": output folder " + dir.string() + " does not exist");

  const std::string tmp = temporary_name(target);
  try {
    {
      std::ofstream out(tmp, binary ? std::ios::binary | std::ios::out : std::ios::out);
      if (!out) throw IoError(path + ": cannot create temporary file " + tmp + ": " + std::strerror(errno));
      write(out);
      out.flush();
      if (!out) throw IoError(path + ": write failed (disk full?)");
    }
    sync_file(tmp);
    if (std::rename(tmp.c_str(), path.c_str()) != 0)
      throw IoError(path + ": cannot rename temporary file into place: " + std::strerror(errno));
  } catch (...) {
    std::remove(tmp.c_str());
    throw;
  }
}

void check_output_path(const std::string& path) {
  const fs::path target(path);
  if (path.empty() || target.filename().empty()) throw IoError("'" + path + "': output path names no file");
  std::error_code ec;
  if (fs::is_directory(target, ec)) throw IoError(path + ": output path is a directory");
  const fs::path dir = target.parent_path().empty() ? fs::path(".") : target.parent_path();
  if (!fs::is_directory(dir, ec)) throw IoError(path + ": output folder " + dir.string() + " does not exist");
  if (::access(dir.c_str(), W_OK | X_OK) != 0)
    throw IoError(path + ": output folder " + dir.string() + " is not writable");
}

StagedOutputs::~StagedOutputs() {
  for (const auto& [temporary, target] : staged_) std::remove(temporary.c_str());
}

void StagedOutputs::stage(const std::string& path, const std::function<void(const std::string&)>& write) {
  check_output_path(path);
  static std::atomic<unsigned> counter{0};
  const fs::path target(path);
  const std::string ext = target.extension().string();
  const std::string temporary =
      (target.parent_path() / ("." + target.filename().string() + ".tmp." + std::to_string(::getpid()) + "." +
                               std::to_string(counter++) + ext))
          .string();
  staged_.emplace_back(temporary, path);
  write(temporary);
}

void StagedOutputs::commit() {
  for (const auto& [temporary, target] : staged_)
    if (std::rename(temporary.c_str(), target.c_str()) != 0)
      throw IoError(target + ": cannot rename temporary file into place: " + std::strerror(errno));
  staged_.clear();
}

void check_not_same_file(const std::string& input, const std::string& output) {
  std::error_code ec;
  if (fs::exists(output, ec) && fs::exists(input, ec) && fs::equivalent(input, output, ec))
    throw IoError(output + ": output would overwrite the input file; choose another name");
}

std::string lower_extension(const std::string& path) {
  std::string ext = fs::path(path).extension().string();
  if (!ext.empty() && ext[0] == '.') ext.erase(0, 1);
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
  return ext;
}

}  // namespace fascicle
