#pragma once
/// \file atomic_file.h
/// Writing outputs so that nothing is lost: the content goes to a temporary file in the target's
/// folder, is flushed to disk, and is renamed over the target only when complete. A failure
/// (exception in the writer, full disk) removes the temporary file and leaves any existing target
/// untouched.

#include <functional>
#include <ostream>
#include <string>

namespace fascicle {

/// Writes `path` atomically. `write` fills the stream; any exception it throws aborts the write.
/// Throws IoError (exit code output_failed) naming the path when the file cannot be created,
/// written, flushed or renamed, or when `path` names an existing input the caller protects
/// (see `protect`).
void write_file_atomically(const std::string& path, const std::function<void(std::ostream&)>& write,
                           bool binary = false);

/// Throws IoError when `output` and `input` name the same existing file (inputs are never
/// overwritten).
void check_not_same_file(const std::string& input, const std::string& output);

/// Lowercase extension of a path without the dot ("mesh.OFF" -> "off"; "" when none).
std::string lower_extension(const std::string& path);

}  // namespace fascicle
