#include "app/report_file.h"

#include "geometry/atomic_file.h"
#include "geometry/errors.h"

#include <nlohmann/json.hpp>

namespace fascicle::app {

void write_json_report(const std::string& path, const nlohmann::json& report) {
  // nlohmann::json prints doubles with enough digits to round-trip.
  write_file_atomically(path, [&](std::ostream& out) { out << report.dump(2) << '\n'; });
}

void write_failure_report(const std::string& path, nlohmann::json& report, const Error& error) {
  if (path.empty() || report.contains("status")) return;
  report["status"] = "failed";
  report["error"] = error.what();
  report["error_code"] = error_name(error.code());
  write_json_report(path, report);
}

}  // namespace fascicle::app
