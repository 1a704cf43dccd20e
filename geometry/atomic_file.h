#pragma once
/// \file atomic_file.h
/// Writing outputs so that nothing is lost: the content goes to a temporary file in the target's
/// folder, is flushed to disk, and is renamed over the target only when complete. A failure
/// (exception in the writer, full disk) removes the temporary file and leaves any existing target
/// untouched.

#include <functional>
#include <ostream>
#include <string>
#include <utility>
#include <vector>

namespace fascicle {

/// Writes `path` atomically. `write` fills the stream; any exception it throws aborts the write.
/// Throws IoError (exit code output_failed) naming the path when the file cannot be created,
/// written, flushed or renamed, or when `path` names an existing input the caller protects
/// (see `protect`).
void write_file_atomically(const std::string& path, const std::function<void(std::ostream&)>& write,
                           bool binary = false);

/// Throws IoError naming `path` when it cannot be an output: it names no file, names a
/// directory, or its folder does not exist or cannot be written to. Commands call it on every
/// output before the work starts, so that a bad path costs no computation.
void check_output_path(const std::string& path);

/// The outputs of one run, made to appear together: stage() writes each to a temporary file
/// beside its target (named `.<file>.tmp.<pid>.<n>.<ext>`, so that writers that choose the format
/// by the extension still see it); commit() renames them all into place. A run that ends
/// without commit() (an exception) removes its temporary files in the destructor, so no file of
/// a failed run appears under a requested name.
class StagedOutputs {
 public:
  StagedOutputs() = default;
  StagedOutputs(const StagedOutputs&) = delete;
  StagedOutputs& operator=(const StagedOutputs&) = delete;
  ~StagedOutputs();
  /// Calls `write(temporary_path)`, which must create that file (e.g. write_polylines()).
  /// Throws what `write` throws (the temporary file is removed) and IoError for a bad `path`.
  void stage(const std::string& path, const std::function<void(const std::string& temporary_path)>& write);
  /// Renames every staged file into place (throws IoError when a rename fails).
  void commit();

 private:
  std::vector<std::pair<std::string, std::string>> staged_;  // (temporary, target)
};

/// Throws IoError when `output` and `input` name the same existing file (inputs are never
/// overwritten).
void check_not_same_file(const std::string& input, const std::string& output);

/// Lowercase extension of a path without the dot ("mesh.OFF" -> "off"; "" when none).
std::string lower_extension(const std::string& path);

}  // namespace fascicle
