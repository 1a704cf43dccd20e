#pragma once
/// \file try_policy.h
/// At most two whole decompositions of a muscle: the first with the options as given, and a
/// second only where the first's check shows a failure mode whose cause the second changes:
///   folds          cells still inverted after the untangling: the rings, placed along levels of
///                  the sphere map, crowd where the muscle bends   -> rings placed by meridian
///   uneven_layers  a layer of fibre segments over even_layers_ratio times the median (the rings
///                  skipped a stretch of muscle)                    -> rings placed by meridian
///   coverage       coverage p95 over the check's limit: the outermost fibres stay away from a
///                  flat muscle's acute edge, where a lattice side's middle lies -> corners on
///                  the edges (corner twist 45); with them there already, the outermost fibres
///                  lie a whole spacing in from the surface           -> edge cells of 0.5
/// and where the first passes decompose's check but not the whole check (CheckOptions' defaults):
///   gathered_ends  an area's ends cover less than the ends criterion asks: cast along the end
///                  axis, they gather in the shadow of the layer next to them (on automatic
///                  areas only: on a landmark strip deeper faces do not spread them)
///   hooked_ends    a joint turns by more than the smooth criterion allows, the largest at a
///                  fibre's first or last joint
///   segments_out   a segment leaves the muscle                     -> faces as deep as the first
///                  ring: the end layers of cells curve round the muscle's ends, and the ends
///                  cast from them spread over their areas
///   sharp_joints   the same, the largest inside the fibre (a bend of the muscle that 15 points
///                  cannot follow): deeper faces do not reach it  -> no second try
/// decompose_repaired() (fibres/decompose.h) keeps the better of the two (after a first that
/// fails decompose's check by better_result(); after one that passes it, the second only where it
/// passes too and fails fewer of the whole check's criteria, or as many and is evener) and names
/// the failure modes in its report.
#include "fibres/fibre_check.h"

#include <string>
#include <vector>

namespace fascicle {

/// When a decomposition is tried a second time.
struct TryPolicy {
  /// One second try where the first shows a failure mode above (default true; false: one try).
  bool second_try = true;
  /// A longest layer of fibre segments over this many times the median one is the failure mode
  /// "uneven_layers", >= 1 (default 2.5; 0: not a failure mode).
  double even_layers_ratio = 2.5;
  /// Throws OptionError naming the first bad field.
  void validate() const;
};

/// The failure modes of a try's check, in the order above ("folds", "uneven_layers",
/// "coverage"); empty when it shows none (which can be a failed check: the other criteria have
/// no second try).
std::vector<std::string> failure_modes(const CheckReport& result, const TryPolicy& policy);

/// The whole check's failure modes of a try's check ("gathered_ends", "hooked_ends" or
/// "sharp_joints", "segments_out"), judged with CheckOptions' defaults (failed_criteria()).
std::vector<std::string> whole_check_modes(const CheckReport& result);

}  // namespace fascicle
