#include "geometry/mesh_io.h"

#include "geometry/atomic_file.h"
#include "geometry/detail/parse_cursor.h"
#include "geometry/errors.h"
#include "geometry/thesis_format.h"

#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <charconv>
#include <climits>
#include <cstring>
#include <limits>

namespace fascicle {

namespace detail {

FileBytes::FileBytes(const std::string& path, const ReadOptions& options) {
  options.validate();
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) throw InputError(ErrorCode::file_missing, path + ": cannot open: " + std::strerror(errno));
  struct ::stat info {};
  if (::fstat(fd, &info) != 0) {
    const int err = errno;
    ::close(fd);
    throw InputError(ErrorCode::file_missing, path + ": cannot read: " + std::strerror(err));
  }
  if (S_ISDIR(info.st_mode)) {
    ::close(fd);
    throw InputError(ErrorCode::file_missing, path + ": is a folder, not a file");
  }
  const auto size = static_cast<std::uint64_t>(info.st_size);
  if (size > options.max_file_bytes) {
    ::close(fd);
    throw InputError(ErrorCode::too_large,
                     path + ": file has " + std::to_string(size) +
                         " bytes, more than the limit max_file_bytes = " + std::to_string(options.max_file_bytes));
  }
  if (size == 0) {
    ::close(fd);
    throw InputError(ErrorCode::file_empty, path + ": line 1: file is empty (0 bytes)");
  }
  if (S_ISREG(info.st_mode)) {
    void* map = ::mmap(nullptr, static_cast<std::size_t>(size), PROT_READ, MAP_PRIVATE, fd, 0);
    if (map != MAP_FAILED) {
      ::close(fd);                                                      // the mapping stays valid
      ::madvise(map, static_cast<std::size_t>(size), MADV_SEQUENTIAL);  // read ahead, drop behind
      mapping_ = map;
      data_ = static_cast<const char*>(map);
      size_ = static_cast<std::size_t>(size);
      return;
    }
  }
  // Not mappable (a device, a special file system): read it into memory.
  copy_.assign(static_cast<std::size_t>(size), '\0');
  std::size_t done = 0;
  while (done < copy_.size()) {
    const ssize_t n = ::read(fd, copy_.data() + done, copy_.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) {
      const int err = errno;
      ::close(fd);
      throw InputError(ErrorCode::file_missing,
                       path + ": byte " + std::to_string(done) + ": read failed: " + std::strerror(err));
    }
    if (n == 0) break;  // the file shrank while reading
    done += static_cast<std::size_t>(n);
  }
  ::close(fd);
  copy_.resize(done);
  if (copy_.empty()) throw InputError(ErrorCode::file_empty, path + ": line 1: file is empty (0 bytes)");
  data_ = copy_.data();
  size_ = copy_.size();
}

FileBytes::~FileBytes() {
  if (mapping_ != nullptr) ::munmap(mapping_, size_);
}

void check_declared_count(const ParseCursor& cursor, std::uint64_t count, std::uint64_t min_bytes,
                          std::uint64_t available, const char* what, const ReadOptions& options) {
  const std::uint64_t limit = std::min<std::uint64_t>(options.max_elements, INT_MAX);
  if (count > limit)
    cursor.fail(ErrorCode::too_large, std::string("declares ") + std::to_string(count) + " " + what +
                                          ", more than the limit of " + std::to_string(limit));
  if (min_bytes > 0 && count > available / min_bytes)
    cursor.fail(ErrorCode::too_large, std::string("declares ") + std::to_string(count) + " " + what +
                                          " but the file has only " + std::to_string(available) +
                                          " bytes (each needs at least " + std::to_string(min_bytes) + ")");
}

void append_double(std::string& out, double value) {
  char buffer[64];
  const auto result = std::to_chars(buffer, buffer + sizeof(buffer), value, std::chars_format::general,
                                    std::numeric_limits<double>::max_digits10);
  out.append(buffer, result.ptr);
}

void append_int(std::string& out, long long value) {
  char buffer[32];
  const auto result = std::to_chars(buffer, buffer + sizeof(buffer), value);
  out.append(buffer, result.ptr);
}

}  // namespace detail

void ReadOptions::validate() const {
  if (max_elements == 0) throw OptionError("ReadOptions::max_elements must be at least 1 (got 0)");
  if (max_file_bytes == 0) throw OptionError("ReadOptions::max_file_bytes must be at least 1 (got 0)");
}

MeshFormat mesh_format_from_path(const std::string& path) {
  const std::string ext = lower_extension(path);
  if (ext == "off") return MeshFormat::off;
  if (ext == "obj") return MeshFormat::obj;
  if (ext == "stl") return MeshFormat::stl;
  if (ext == "ply") return MeshFormat::ply;
  if (ext == "vtk") return MeshFormat::vtk;
  if (ext == "txt") return MeshFormat::thesis;
  throw InputError(ErrorCode::unknown_format,
                   path + ": unknown mesh format '" + ext + "' (expected .off .obj .stl .ply .vtk .txt)");
}

PolygonSoup read_polygon_soup(const std::string& path, const ReadOptions& options) {
  const MeshFormat format = mesh_format_from_path(path);
  PolygonSoup soup;
  if (format == MeshFormat::thesis) {
    ThesisModel model = read_thesis_model(path, options);
    soup.points = std::move(model.points);
    soup.polygons.reserve(model.triangles.size());
    for (const Triangle& t : model.triangles) soup.polygons.push_back({t[0], t[1], t[2]});
  } else {
    const detail::FileBytes file(path, options);
    const std::string_view data = file.view();
    switch (format) {
      case MeshFormat::off: soup = detail::read_off(path, data, options); break;
      case MeshFormat::obj: soup = detail::read_obj(path, data, options); break;
      case MeshFormat::stl: soup = detail::read_stl(path, data, options); break;
      case MeshFormat::ply: soup = detail::read_ply(path, data, options); break;
      case MeshFormat::vtk: {
        detail::VtkPolyData vtk = detail::read_vtk(path, data, options);
        soup.points = std::move(vtk.points);
        soup.polygons = std::move(vtk.polygons);
        break;
      }
      case MeshFormat::thesis: break;
    }
  }
  if (soup.polygons.empty())
    throw InputError(ErrorCode::file_empty,
                     path + ": holds " + std::to_string(soup.points.size()) + " points but no faces");
  return soup;
}

// read_polylines: read_polylines.cpp.

}  // namespace fascicle
