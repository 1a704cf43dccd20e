#include "app/report_file.h"

#include "geometry/atomic_file.h"

#include <nlohmann/json.hpp>

namespace fascicle::app {

void write_json_report(const std::string& path, const nlohmann::json& report) {
  // nlohmann::json prints doubles with enough digits to round-trip.
  write_file_atomically(path, [&](std::ostream& out) { out << report.dump(2) << '\n'; });
}

}  // namespace fascicle::app
