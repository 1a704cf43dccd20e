#pragma once
/// \file render_png.h
/// PNG files of rendered pictures through libpng 1.6: 8-bit RGB, encoded in memory (zlib level 9,
/// adaptive filters) and written atomically; read back through libpng's simplified API.

#include "shaders/render_scene.h"

#include <string>

namespace fascicle::shaders {

/// Encodes an 8-bit RGB picture as a PNG file's bytes. Throws Error(internal) when the picture's
/// buffer does not hold width * height * 3 bytes, IoError when libpng fails (message included).
std::string encode_png(const Image& image);

/// Decodes PNG bytes into an 8-bit RGB picture (any PNG: palette, grey, 16-bit and alpha are
/// converted by libpng; alpha is composited over black). `name` names the source in errors.
/// Throws InputError(malformed) with libpng's message when the bytes are not a readable PNG.
Image decode_png(const std::string& bytes, const std::string& name);

/// Writes `image` as a PNG file at `path` through write_file_atomically (nothing is left under
/// `path` on failure). Throws IoError.
void write_png(const std::string& path, const Image& image);

/// Reads a PNG file. Throws InputError(file_missing) when it cannot be opened,
/// InputError(file_empty) for an empty file, InputError(malformed) as decode_png.
Image read_png(const std::string& path);

}  // namespace fascicle::shaders
