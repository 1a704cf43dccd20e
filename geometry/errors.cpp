#include "geometry/errors.h"

namespace fascicle {

const char* error_name(ErrorCode code) {
  switch (code) {
    case ErrorCode::internal: return "internal";
    case ErrorCode::usage: return "usage";
    case ErrorCode::file_missing: return "file_missing";
    case ErrorCode::file_empty: return "file_empty";
    case ErrorCode::unknown_format: return "unknown_format";
    case ErrorCode::truncated: return "truncated";
    case ErrorCode::index_out_of_range: return "index_out_of_range";
    case ErrorCode::bad_number: return "bad_number";
    case ErrorCode::too_large: return "too_large";
    case ErrorCode::malformed: return "malformed";
    case ErrorCode::output_failed: return "output_failed";
    case ErrorCode::repair_failed: return "repair_failed";
    case ErrorCode::topology: return "topology";
    case ErrorCode::solver_diverged: return "solver_diverged";
    case ErrorCode::gpu: return "gpu";
    case ErrorCode::landmarks: return "landmarks";
    case ErrorCode::time_limit: return "time_limit";
    case ErrorCode::invalid_option: return "invalid_option";
    case ErrorCode::quality: return "quality";
  }
  return "unknown";
}

}  // namespace fascicle
