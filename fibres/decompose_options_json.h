#pragma once
/// \file decompose_options_json.h
/// Every setting of a decomposition as JSON, and back: the report's `options` (what a run used,
/// in full) and expert tuning from a file (`fascicle decompose --tuning FILE`), so that a
/// setting the command line does not offer is still reachable, and a run can be repeated from
/// its report. The JSON nests as DecomposeOptions does (`{"placement": {"max_face_depth": 0.5}}`);
/// enums are their command-line names ("parallel", "static", "tutte", ...), the spring model its
/// number (6 or 26). `progress` is not a setting and is left out.
#include "fibres/decompose.h"

#include <nlohmann/json.hpp>

namespace fascicle {

/// Every setting of `options` (all of its fields, nested structs as objects).
nlohmann::json decompose_options_json(const DecomposeOptions& options);

/// `options` with the settings of `tuning` applied: an object with any subset of the keys of
/// decompose_options_json(). Throws OptionError naming the first key that is not a setting or
/// whose value has the wrong type or name ("tuning: placement.max_face_deph is not a setting").
/// The result is not validated (DecomposeOptions::validate() names a value out of range).
DecomposeOptions apply_tuning(DecomposeOptions options, const nlohmann::json& tuning);

/// The options of a run given both a tuning file and command-line options: `reference` (what the
/// command gives with no option), `given` (with the command line's options) and `tuning` (the
/// file). The file's settings apply, except where `given` differs from `reference`: a setting
/// the command line changed wins. Throws as apply_tuning().
DecomposeOptions tune_options(const DecomposeOptions& reference, const DecomposeOptions& given,
                              const nlohmann::json& tuning);

}  // namespace fascicle
