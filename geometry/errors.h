#pragma once
/// \file errors.h
/// The exception types at Fascicle's public boundary and the exit code of each failure kind.
/// The command line catches fascicle::Error, prints what() as one line and exits with
/// exit_code(error.code()). Codes are stable: scripts may test them.

#include <stdexcept>
#include <string>

namespace fascicle {

/// What went wrong, one value per exit code of the `fascicle` program.
enum class ErrorCode : int {
  internal = 1,            ///< a bug: an unexpected exception
  usage = 2,               ///< bad command line (unknown flag, missing argument)
  file_missing = 3,        ///< input file does not exist or cannot be opened
  file_empty = 4,          ///< input file has no content
  unknown_format = 5,      ///< extension or content matches no supported format
  truncated = 6,           ///< file ends before the data its header declares
  index_out_of_range = 7,  ///< a face or spring refers to a point that does not exist
  bad_number = 8,          ///< a coordinate is NaN/Inf or a number cannot be parsed
  too_large = 9,           ///< a declared count is absurd for the file size or above a limit
  malformed = 10,          ///< any other syntax error in an input file
  output_failed = 11,      ///< an output file could not be written
  repair_failed = 12,      ///< the mesh could not be brought to a closed genus-0 manifold
  topology = 13,           ///< a mesh does not have the topology a stage requires
  solver_diverged = 14,    ///< an iterative solver produced NaN/Inf or growing energy
  gpu = 15,                ///< OpenGL/EGL context, shader compile or link failure
  landmarks = 16,          ///< attachment landmarks are unusable (far from surface, equal areas)
  time_limit = 17,         ///< a stage ran past its time limit
  invalid_option = 18,     ///< an option value is out of its valid range
  quality = 19,            ///< fibres fail the quality check (`fascicle check --strict`)
};

/// Exit code of the program for an error kind.
inline int exit_code(ErrorCode code) { return static_cast<int>(code); }

/// Short stable name of an error kind (used in JSON reports), e.g. "truncated".
const char* error_name(ErrorCode code);

/// Base of every exception Fascicle throws on purpose. what() is one line, no trailing newline.
class Error : public std::runtime_error {
 public:
  Error(ErrorCode code, const std::string& message) : std::runtime_error(message), code_(code) {}
  ErrorCode code() const { return code_; }

 private:
  ErrorCode code_;
};

/// A bad input file. The message names the file, where (line or byte offset) and what is wrong.
class InputError : public Error {
 public:
  using Error::Error;
};

/// A mesh whose topology a stage cannot accept, or a repair that cannot reach genus 0.
class TopologyError : public Error {
 public:
  explicit TopologyError(const std::string& message, ErrorCode code = ErrorCode::topology) : Error(code, message) {}
};

/// An iterative solve that diverged; the message names the likely cause and the option to change.
class SolverError : public Error {
 public:
  explicit SolverError(const std::string& message) : Error(ErrorCode::solver_diverged, message) {}
};

/// An output that could not be written (the target is left untouched).
class IoError : public Error {
 public:
  explicit IoError(const std::string& message) : Error(ErrorCode::output_failed, message) {}
};

/// An option value outside its valid range; the message names the option and the value.
class OptionError : public Error {
 public:
  explicit OptionError(const std::string& message) : Error(ErrorCode::invalid_option, message) {}
};

/// Checked assertion for internal invariants: throws Error(internal) with file and line.
#define FASCICLE_CHECK(cond, msg)                                                                                      \
  do {                                                                                                                 \
    if (!(cond))                                                                                                       \
      throw ::fascicle::Error(::fascicle::ErrorCode::internal, std::string("internal check failed: ") + (msg) + " (" + \
                                                                   __FILE__ + ":" + std::to_string(__LINE__) + ")");   \
  } while (0)

}  // namespace fascicle
