// Options validation and the JSON form of the repair report (no CGAL here).

#include "geometry/errors.h"
#include "repair/repair.h"

#include <nlohmann/json.hpp>

#include <cmath>

namespace fascicle {

void RepairOptions::validate() const {
  auto bad = [](const std::string& field, double value, const std::string& range) {
    throw OptionError("repair option " + field + " = " + std::to_string(value) + " is out of range (" + range + ")");
  };
  if (!(weld_tolerance >= 0.0 && weld_tolerance < 0.01))
    bad("weld_tolerance", weld_tolerance, "0 <= t < 0.01 of the diagonal");
  if (!(min_largest_share > 0.0 && min_largest_share <= 1.0)) bad("min_largest_share", min_largest_share, "0 < s <= 1");
  if (!(untangle_limit >= 0.0 && untangle_limit <= 0.1)) bad("untangle_limit", untangle_limit, "0 <= l <= 0.1");
  if (!(wrap_alpha > 0.0 && wrap_alpha <= 0.5)) bad("wrap_alpha", wrap_alpha, "0 < alpha <= 0.5 of the diagonal");
  if (!(wrap_offset_ratio > 0.0 && wrap_offset_ratio <= 1.0)) bad("wrap_offset_ratio", wrap_offset_ratio, "0 < r <= 1");
  if (!(wrap_max_distance > 0.0 && wrap_max_distance <= 1.0)) bad("wrap_max_distance", wrap_max_distance, "0 < d <= 1");
  if (wrap_levels < 1 || wrap_levels > 12) bad("wrap_levels", wrap_levels, "1..12");
  if (max_wrap_faces < 1000) bad("max_wrap_faces", static_cast<double>(max_wrap_faces), ">= 1000");
  if (!(wrap_seconds > 0.0)) bad("wrap_seconds", wrap_seconds, "> 0");
  if (hausdorff_samples < 0) bad("hausdorff_samples", hausdorff_samples, ">= 0");
  if (wrap_memory_mb != 0 && wrap_memory_mb < 64)
    bad("wrap_memory_mb", static_cast<double>(wrap_memory_mb), "0 (none) or >= 64");
}

namespace {

nlohmann::json census_json(const MeshCensus& c) {
  nlohmann::json j = {{"vertices", c.vertices},
                      {"faces", c.faces},
                      {"components", c.components},
                      {"boundary_edges", c.boundary_edges},
                      {"non_manifold_edges", c.non_manifold_edges},
                      {"non_manifold_vertices", c.non_manifold_vertices},
                      {"euler", c.euler},
                      {"self_intersections", c.self_intersections},
                      {"volume", c.volume},
                      {"area", c.area}};
  j["genus"] = c.genus ? nlohmann::json(*c.genus) : nlohmann::json(nullptr);
  return j;
}

}  // namespace

nlohmann::json RepairReport::to_json() const {
  nlohmann::json steps_json = nlohmann::json::array();
  for (const RepairStep& s : steps)
    steps_json.push_back({{"name", s.name}, {"changed", s.changed}, {"seconds", s.seconds}, {"note", s.note}});
  nlohmann::json fallback = {{"used", fallback_used}, {"reason", fallback_reason}};
  if (fallback_used) {
    fallback["alpha"] = wrap_alpha;
    fallback["offset"] = wrap_offset;
    fallback["worker"] = wrap_worker;
  }
  return {{"status", status},
          {"input", census_json(input)},
          {"output", census_json(output)},
          {"steps", steps_json},
          {"fallback", fallback},
          {"hausdorff", hausdorff},
          {"hausdorff_whole_input", hausdorff_whole_input},
          {"kept_area_share", kept_area_share},
          {"seconds", seconds}};
}

}  // namespace fascicle
