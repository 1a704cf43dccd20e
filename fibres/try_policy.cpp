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

}  // namespace fascicle
