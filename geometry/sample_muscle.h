#pragma once
/// \file sample_muscle.h
/// The built-in sample: a smooth fusiform (spindle-shaped) muscle surface, and the same surface
/// with the defects a CT/MRI segmentation exported as STL typically has. It lets a user try the
/// whole pipeline without data (`fascicle sample`) and gives tests a realistic mesh of known shape.

#include "geometry/inject_defects.h"
#include "geometry/mesh.h"

#include <cstdint>

namespace fascicle {

/// Shape, resolution and defects of the sample muscle. Lengths in millimetres.
struct SampleOptions {
  double length = 120.0;             ///< tip-to-tip length along the axis, mm (default 120)
  double belly_radius = 15.0;        ///< largest cross-section semi-axis at mid-belly, mm (default 15)
  double tendon_radius = 2.5;        ///< radius where the belly tapers into the rounded tips, mm (default 2.5)
  double ellipticity = 0.7;          ///< minor / major semi-axis of every cross-section, (0, 1] (default 0.7)
  double axis_bend = 6.0;            ///< sagitta of the curved axis from the tip-to-tip chord, mm (default 6)
  int rings = 80;                    ///< rings between the tips, 2 * rings * segments triangles (default 80)
  int segments = 48;                 ///< points per ring (default 48)
  std::uint64_t seed = 1;            ///< seed of the defect injector; the clean shape ignores it (default 1)
  bool defects = true;               ///< inject defects; false: the clean surface as a soup (default true)
  int holes = 3;                     ///< holes cut into the surface (default 3)
  int hole_faces = 10;               ///< faces removed per hole (default 10)
  int flipped_faces = 30;            ///< faces in the one flipped patch (default 30)
  double duplicate_fraction = 0.02;  ///< share of vertices duplicated as exact copies (default 0.02)

  /// Throws OptionError naming the first field out of range: lengths and radii must be finite
  /// and positive, tendon_radius < belly_radius, 2 * belly_radius < length,
  /// |axis_bend| <= length / 4, rings in [3, 10000], segments in [3, 10000], holes in [0, 100],
  /// hole_faces in [1, 10000], flipped_faces in [1, 10000], duplicate_fraction in [0, 1].
  void validate() const;
};

/// The clean sample muscle: a closed, genus-0, outward triangle mesh.
/// Method: a surface of revolution around a gently curved (parabolic) axis of length `length`
/// along x, bowed by `axis_bend` towards +z. The radius profile along the normalised arc
/// parameter s in [0, 1] is r(s) = tendon + (belly - tendon) sin^2(pi s), multiplied near each
/// tip (within tendon_radius of it) by a quarter-circle factor so the ends are rounded; every
/// cross-section is an ellipse with semi-axes r and ellipticity * r, in the plane normal to the
/// axis. Rings are spaced by s_i = (1 - cos(pi i / (rings + 1))) / 2, denser near the tips where
/// the curvature is high; the tips are the two poles. Vertex count rings * segments + 2,
/// triangle count 2 * rings * segments (7680 with the defaults). Deterministic: no randomness.
/// Throws OptionError from options.validate().
TriangleMesh make_fusiform_muscle(const SampleOptions& options = {});

/// The sample as a user's scan would deliver it: make_fusiform_muscle with, when
/// options.defects, these defects injected in order (inject_defects.h), each from its own seed
/// derived from options.seed: `holes` holes of `hole_faces` faces, one flipped patch of
/// `flipped_faces` faces, one pinched (non-manifold) vertex, one small stray closed component
/// outside the muscle, and exact duplicate vertices (`duplicate_fraction` of them) re-referenced
/// by some of their faces. Every polygon is a triangle. Bit-for-bit reproducible for the same
/// options on the same platform and build; a different seed gives a different soup.
/// `log` (may be null) receives one record per defect kind. Throws OptionError from
/// options.validate(), TopologyError when the options make a mesh too coarse for the defects.
PolygonSoup make_sample(const SampleOptions& options = {}, DefectLog* log = nullptr);

}  // namespace fascicle
