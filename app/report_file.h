#pragma once
/// \file report_file.h
/// Writing a JSON report atomically, pretty-printed, numbers with round-trip precision.

#include <nlohmann/json_fwd.hpp>

#include <string>

namespace fascicle {
class Error;
}

namespace fascicle::app {

/// Writes `report` to `path` (atomically; throws IoError).
void write_json_report(const std::string& path, const nlohmann::json& report);

/// For a command that failed with `error`: unless `path` is empty (no --report) or `report`
/// already has a "status" (the command wrote it when it found the failure), sets "status":
/// "failed", "error" (the message) and "error_code" (its name) in `report` and writes it to
/// `path` (atomically; throws IoError). Called from the commands' catch blocks before rethrowing.
void write_failure_report(const std::string& path, nlohmann::json& report, const Error& error);

}  // namespace fascicle::app
