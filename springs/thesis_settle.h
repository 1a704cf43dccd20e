#pragma once
/// \file thesis_settle.h
/// What `fascicle settle` needs around the solvers: target files that move fixed points, and
/// recognising a thesis-format model as a lattice (for the structured path and for writing the
/// fibres as full polylines).

#include "geometry/mesh.h"
#include "geometry/mesh_io.h"
#include "geometry/thesis_format.h"
#include "springs/settle.h"

#include <optional>
#include <string>
#include <vector>

namespace fascicle::springs {

/// One target: point `index` (0-based) moves to `position` (file units).
struct Target {
  int index = 0;
  Vec3 position = Vec3::Zero();
};

/// Reads a target file: one `index x y z` per line, `#` starts a comment, blank lines ignored.
/// Throws InputError naming the file and line: file_missing, file_empty (no target),
/// bad_number (unparsable or non-finite number, negative index), malformed (wrong field count),
/// too_large (more lines than options.max_elements).
std::vector<Target> read_targets(const std::string& path, const ReadOptions& options = {});

/// Moves the fixed points named by `targets` (the decomposition pins surface points to the muscle
/// this way). Throws InputError naming `source` and the target's position in the list:
/// index_out_of_range for an index >= #points, malformed for a point that is not fixed
/// (surface flag 'm') or named twice.
void apply_targets(SpringSystem& system, const std::vector<Target>& targets, const std::string& source);

/// Recognises `model` as a lattice written by to_thesis_model (lattice.h): F fibres from points
/// 0..F-1 to the last layer, N = F nz points, index i + nx (j + ny k), springs exactly the
/// model-6 or model-26 neighbours with stiffness 1 / rest length (`springs` gives the rest
/// lengths). Tries `model` if given, else both. Returns nothing when it is not such a lattice.
std::optional<LatticeShape> detect_lattice(const ThesisModel& model, const SpringSystem& springs,
                                           std::optional<SpringModel> wanted);

/// Fibre polylines at `positions`: for a lattice `shape`, every lattice line along t; otherwise
/// one two-point line per fibre of the model (its end points).
Polylines model_fibres(const ThesisModel& model, const std::vector<Vec3>& positions,
                       const std::optional<LatticeShape>& shape);

}  // namespace fascicle::springs
