#pragma once
/// \file architecture.h
/// The architecture of a muscle's fibres as musculoskeletal models take it (Lieber and Friden
/// 2000, "Functional and clinical significance of skeletal muscle architecture", Muscle Nerve 23;
/// the measures of Ward et al. 2009, Clin Orthop Relat Res 467, on cadavers):
/// - line of action: the unit vector from the origin area's centroid to the insertion area's;
/// - muscle length: the extent of the muscle's vertices along the line of action;
/// - fibre length: each fibre's arc length (mean, median, standard deviation, range);
/// - pennation angle: per fibre, the acute angle between its chord (first point to last) and the
///   line of action;
/// - physiological cross-sectional area PCSA = V mean(cos pennation) / mean fibre length, V the
///   muscle's volume (Ward's PCSA = M cos(theta) / (rho L_f), with M / rho = V);
/// - maximum isometric force = PCSA x specific tension.
/// Lengths in metres: the mesh's units are converted by ArchitectureOptions::metres_per_unit.
#include "geometry/mesh.h"
#include "morph/attachments.h"

#include <nlohmann/json_fwd.hpp>

#include <string>

namespace fascicle {

/// Units and the specific tension of the architecture figures.
struct ArchitectureOptions {
  double metres_per_unit = 0.001;      ///< length of one mesh unit in metres, > 0 (default 0.001: millimetres)
  double specific_tension = 610000.0;  ///< N / m^2, > 0 (default 61 N/cm^2, Arnold et al. 2010's lower-limb model)
  /// Throws OptionError naming the first field out of range.
  void validate() const;
};

/// Spread of a per-fibre figure.
struct Spread {
  double mean = 0.0, median = 0.0, sd = 0.0, min = 0.0, max = 0.0;
};

/// The architecture figures (SI units).
struct Architecture {
  long fibres = 0;
  Vec3 line_of_action = Vec3::Zero();  ///< unit, origin to insertion
  double volume_m3 = 0.0;
  double muscle_length_m = 0.0;
  Spread fibre_length_m;                ///< arc lengths
  Spread pennation_deg;                 ///< per fibre, degrees in [0, 90]
  double fibre_to_muscle_length = 0.0;  ///< mean fibre length over the muscle length
  double pcsa_m2 = 0.0;
  double max_isometric_force_n = 0.0;
  ArchitectureOptions options;  ///< the units and tension used
  /// The figures as JSON (keys carry their units: `_m`, `_m2`, `_m3`, `_deg`, `_n`; PCSA also in cm^2).
  nlohmann::json to_json() const;
  /// One CSV header line and one row (no newline), the columns of to_json()'s scalar figures.
  static std::string csv_header();
  std::string csv_row() const;
};

/// Measures `fibres` (polylines from origin to insertion, mesh units) of the closed muscle
/// `muscle` with its attachment `areas`. Throws InputError(file_empty) when there is no fibre,
/// InputError(landmarks) when an area has no point or the areas' centroids coincide, OptionError
/// for bad options, TopologyError when the muscle bounds no volume.
Architecture measure_architecture(const Polylines& fibres, const TriangleMesh& muscle, const Attachments& areas,
                                  const ArchitectureOptions& options = {});

/// Writes `architecture` to `path` as JSON (.json) or CSV (.csv: the header and one row),
/// atomically. Throws InputError(unknown_format) for another extension, IoError when it cannot be
/// written.
void write_architecture(const std::string& path, const Architecture& architecture);

}  // namespace fascicle
