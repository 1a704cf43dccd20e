#include "fibres/try_policy.h"

#include "geometry/errors.h"

#include <algorithm>

namespace fascicle {

void TryPolicy::validate() const {
  if (!(even_layers_ratio == 0.0 || even_layers_ratio >= 1.0))
    throw OptionError("even_layers_ratio: must be 0 (not a failure mode) or >= 1, got " +
                      std::to_string(even_layers_ratio));
}

std::vector<std::string> failure_modes(const CheckReport& result, const TryPolicy& policy) {
  const auto failed = [&](const char* criterion) {
    return std::find(result.failed.begin(), result.failed.end(), criterion) != result.failed.end();
  };
  std::vector<std::string> modes;
  if (failed("inverted_cells")) modes.emplace_back("folds");
  if (policy.even_layers_ratio > 0.0 && result.steps.layer_ratio > policy.even_layers_ratio)
    modes.emplace_back("uneven_layers");
  if (failed("coverage")) modes.emplace_back("coverage");
  return modes;
}

std::vector<std::string> whole_check_modes(const CheckReport& result) {
  const std::vector<std::string> failed = failed_criteria(result, CheckOptions{});
  const auto shows = [&](const char* criterion) { return std::find(failed.begin(), failed.end(), criterion) != failed.end(); };
  std::vector<std::string> modes;
  if (shows("ends")) modes.emplace_back("gathered_ends");
  if (shows("smooth")) modes.emplace_back(result.turning.max_at_end ? "hooked_ends" : "sharp_joints");
  if (shows("segments")) modes.emplace_back("segments_out");
  return modes;
}

}  // namespace fascicle
