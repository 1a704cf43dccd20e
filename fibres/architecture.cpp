// Muscle architecture from fibres: lengths, pennation against the line of action, PCSA, force.
#include "fibres/architecture.h"

#include "geometry/atomic_file.h"
#include "geometry/detail/parse_cursor.h"
#include "geometry/errors.h"
#include "geometry/mesh_stats.h"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

namespace fascicle {

namespace {

constexpr double kPi = 3.14159265358979323846;

Spread spread_of(std::vector<double> values) {
  Spread s;
  if (values.empty()) return s;
  std::sort(values.begin(), values.end());
  const std::size_t n = values.size();
  s.min = values.front();
  s.max = values.back();
  s.median = n % 2 == 1 ? values[n / 2] : 0.5 * (values[n / 2 - 1] + values[n / 2]);
  double sum = 0.0;
  for (double v : values) sum += v;
  s.mean = sum / static_cast<double>(n);
  double squares = 0.0;
  for (double v : values) squares += (v - s.mean) * (v - s.mean);
  s.sd = n > 1 ? std::sqrt(squares / static_cast<double>(n - 1)) : 0.0;
  return s;
}

nlohmann::json spread_json(const Spread& s) {
  return {{"mean", s.mean}, {"median", s.median}, {"sd", s.sd}, {"min", s.min}, {"max", s.max}};
}

void append(std::string& out, double v) {
  out += ',';
  detail::append_double(out, v);
}

}  // namespace

void ArchitectureOptions::validate() const {
  if (!(metres_per_unit > 0.0) || !std::isfinite(metres_per_unit))
    throw OptionError("metres_per_unit: must be > 0 and finite, got " + std::to_string(metres_per_unit));
  if (!(specific_tension > 0.0) || !std::isfinite(specific_tension))
    throw OptionError("specific_tension: must be > 0 and finite, got " + std::to_string(specific_tension));
}

nlohmann::json Architecture::to_json() const {
  return {{"fibres", fibres},
          {"line_of_action", {line_of_action.x(), line_of_action.y(), line_of_action.z()}},
          {"volume_m3", volume_m3},
          {"muscle_length_m", muscle_length_m},
          {"fibre_length_m", spread_json(fibre_length_m)},
          {"pennation_deg", spread_json(pennation_deg)},
          {"fibre_to_muscle_length", fibre_to_muscle_length},
          {"pcsa_m2", pcsa_m2},
          {"pcsa_cm2", pcsa_m2 * 1e4},
          {"max_isometric_force_n", max_isometric_force_n},
          {"metres_per_unit", options.metres_per_unit},
          {"specific_tension_n_per_m2", options.specific_tension}};
}

std::string Architecture::csv_header() {
  return "fibres,volume_m3,muscle_length_m,fibre_length_mean_m,fibre_length_median_m,fibre_length_sd_m,"
         "fibre_length_min_m,fibre_length_max_m,pennation_mean_deg,pennation_median_deg,pennation_sd_deg,"
         "pennation_max_deg,fibre_to_muscle_length,pcsa_m2,max_isometric_force_n";
}

std::string Architecture::csv_row() const {
  std::string out = std::to_string(fibres);
  for (double v : {volume_m3, muscle_length_m, fibre_length_m.mean, fibre_length_m.median, fibre_length_m.sd,
                   fibre_length_m.min, fibre_length_m.max, pennation_deg.mean, pennation_deg.median, pennation_deg.sd,
                   pennation_deg.max, fibre_to_muscle_length, pcsa_m2, max_isometric_force_n})
    append(out, v);
  return out;
}

Architecture measure_architecture(const Polylines& fibres, const TriangleMesh& muscle, const Attachments& areas,
                                  const ArchitectureOptions& options) {
  options.validate();
  if (fibres.lines.empty()) throw InputError(ErrorCode::file_empty, "architecture: there are no fibres");
  if (areas.origin.points.empty() || areas.insertion.points.empty())
    throw InputError(ErrorCode::landmarks, "architecture: an attachment area has no point");
  const double volume = signed_volume(muscle);
  if (!(volume > 0.0)) throw TopologyError("architecture: the muscle bounds no volume (repair it first)");
  Architecture out;
  out.options = options;
  out.fibres = static_cast<long>(fibres.lines.size());
  const Vec3 axis = areas.insertion.centroid() - areas.origin.centroid();
  if (!(axis.norm() > 0.0))
    throw InputError(ErrorCode::landmarks, "architecture: the origin and insertion areas have the same centroid");
  out.line_of_action = axis.normalized();
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  for (const Vec3& p : muscle.positions) {
    const double t = p.dot(out.line_of_action);
    lo = std::min(lo, t);
    hi = std::max(hi, t);
  }
  const double unit = options.metres_per_unit;
  out.volume_m3 = volume * unit * unit * unit;
  out.muscle_length_m = (hi - lo) * unit;
  std::vector<double> lengths, angles;
  double cos_sum = 0.0;
  for (const auto& line : fibres.lines) {
    double length = 0.0;
    for (std::size_t k = 0; k + 1 < line.size(); ++k) length += (line[k + 1] - line[k]).norm();
    lengths.push_back(length * unit);
    const Vec3 chord = line.back() - line.front();
    const double c = chord.norm() > 0.0 ? std::min(1.0, std::abs(chord.normalized().dot(out.line_of_action))) : 1.0;
    cos_sum += c;
    angles.push_back(std::acos(c) * 180.0 / kPi);
  }
  out.fibre_length_m = spread_of(lengths);
  out.pennation_deg = spread_of(angles);
  out.fibre_to_muscle_length = out.muscle_length_m > 0.0 ? out.fibre_length_m.mean / out.muscle_length_m : 0.0;
  const double mean_cos = cos_sum / static_cast<double>(fibres.lines.size());
  out.pcsa_m2 = out.fibre_length_m.mean > 0.0 ? out.volume_m3 * mean_cos / out.fibre_length_m.mean : 0.0;
  out.max_isometric_force_n = out.pcsa_m2 * options.specific_tension;
  return out;
}

void write_architecture(const std::string& path, const Architecture& architecture) {
  const std::string ext = lower_extension(path);
  if (ext != "json" && ext != "csv")
    throw InputError(ErrorCode::unknown_format,
                     path + ": cannot write the architecture as '" + ext + "' (use .json or .csv)");
  const std::string text = ext == "json" ? architecture.to_json().dump(2) + "\n"
                                         : Architecture::csv_header() + "\n" + architecture.csv_row() + "\n";
  write_file_atomically(path, [&](std::ostream& out) { out << text; });
}

}  // namespace fascicle
