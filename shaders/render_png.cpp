// PNG encoding and decoding of rendered pictures (see render_png.h).

#include "shaders/render_png.h"

#include "geometry/atomic_file.h"
#include "geometry/errors.h"

#include <png.h>

#include <csetjmp>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <iterator>
#include <sstream>

namespace fascicle::shaders {

namespace {

// libpng's write callbacks: bytes go to a std::string; errors are kept and end the write.
struct PngSink {
  std::string* out = nullptr;
  char message[256] = {};
};

void append_bytes(png_structp png, png_bytep data, png_size_t size) {
  PngSink* sink = static_cast<PngSink*>(png_get_io_ptr(png));
  try {
    sink->out->append(reinterpret_cast<const char*>(data), size);
  } catch (...) { png_error(png, "out of memory"); }
}

void no_flush(png_structp) {}

[[noreturn]] void on_png_error(png_structp png, png_const_charp message) {
  PngSink* sink = static_cast<PngSink*>(png_get_error_ptr(png));
  std::snprintf(sink->message, sizeof sink->message, "%s", message ? message : "unknown libpng error");
  png_longjmp(png, 1);
}

void on_png_warning(png_structp, png_const_charp) {}

// The libpng calls, in a frame holding no C++ object with a destructor (libpng leaves through
// longjmp on error). Returns false with sink.message set on failure.
bool encode_rows(const Image& image, PngSink& sink) {
  png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, &sink, on_png_error, on_png_warning);
  if (!png) {
    std::snprintf(sink.message, sizeof sink.message, "png_create_write_struct failed");
    return false;
  }
  png_infop info = png_create_info_struct(png);
  if (!info) {
    png_destroy_write_struct(&png, nullptr);
    std::snprintf(sink.message, sizeof sink.message, "png_create_info_struct failed");
    return false;
  }
  if (setjmp(png_jmpbuf(png))) {
    png_destroy_write_struct(&png, &info);
    return false;
  }
  png_set_write_fn(png, &sink, append_bytes, no_flush);
  // Pictures are written once and kept (docs/): the smallest file is worth the time.
  png_set_compression_level(png, 9);
  png_set_filter(png, PNG_FILTER_TYPE_BASE, PNG_ALL_FILTERS);
  png_set_IHDR(png, info, static_cast<png_uint_32>(image.width), static_cast<png_uint_32>(image.height), 8,
               PNG_COLOR_TYPE_RGB, PNG_INTERLACE_NONE, PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
  png_write_info(png, info);
  const std::size_t stride = static_cast<std::size_t>(image.width) * 3;
  for (int y = 0; y < image.height; ++y)
    png_write_row(png, const_cast<png_bytep>(image.rgb.data() + stride * static_cast<std::size_t>(y)));
  png_write_end(png, nullptr);
  png_destroy_write_struct(&png, &info);
  return true;
}

}  // namespace

std::string encode_png(const Image& image) {
  FASCICLE_CHECK(image.width > 0 && image.height > 0 &&
                     image.rgb.size() == static_cast<std::size_t>(image.width) * image.height * 3,
                 "PNG picture size does not match its buffer");
  std::string bytes;
  PngSink sink;
  sink.out = &bytes;
  if (!encode_rows(image, sink)) throw IoError(std::string("PNG encoding failed: ") + sink.message);
  return bytes;
}

Image decode_png(const std::string& bytes, const std::string& name) {
  png_image png;
  std::memset(&png, 0, sizeof png);
  png.version = PNG_IMAGE_VERSION;
  if (!png_image_begin_read_from_memory(&png, bytes.data(), bytes.size()))
    throw InputError(ErrorCode::malformed, name + ": not a readable PNG file (" + png.message + ")");
  png.format = PNG_FORMAT_RGB;
  Image image;
  image.width = static_cast<int>(png.width);
  image.height = static_cast<int>(png.height);
  image.rgb.assign(PNG_IMAGE_SIZE(png), 0);
  const png_color black{0, 0, 0};
  if (!png_image_finish_read(&png, &black, image.rgb.data(), 0, nullptr)) {
    const std::string why = png.message;
    png_image_free(&png);
    throw InputError(ErrorCode::malformed, name + ": PNG data is damaged (" + why + ")");
  }
  return image;
}

void write_png(const std::string& path, const Image& image) {
  const std::string bytes = encode_png(image);
  write_file_atomically(
      path, [&](std::ostream& out) { out.write(bytes.data(), static_cast<std::streamsize>(bytes.size())); }, true);
}

Image read_png(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(ErrorCode::file_missing, path + ": cannot open the file");
  std::ostringstream buffer;
  buffer << in.rdbuf();
  const std::string bytes = buffer.str();
  if (bytes.empty()) throw InputError(ErrorCode::file_empty, path + ": the file is empty");
  return decode_png(bytes, path);
}

}  // namespace fascicle::shaders
