#pragma once
/// \file report_file.h
/// Writing a JSON report atomically, pretty-printed, numbers with round-trip precision.

#include <nlohmann/json_fwd.hpp>

#include <string>

namespace fascicle::app {

/// Writes `report` to `path` (atomically; throws IoError).
void write_json_report(const std::string& path, const nlohmann::json& report);

}  // namespace fascicle::app
