#pragma once
/// \file attachments.h
/// Origin and insertion areas of a muscle (pipeline steps 4-5 of ../shared/docs/METHOD.md):
/// from landmark points projected to the surface, or found automatically as the two end regions
/// along the muscle's principal direction.

#include "geometry/mesh.h"
#include "morph/surface_query.h"

#include <nlohmann/json_fwd.hpp>

#include <string>
#include <vector>

namespace fascicle {

/// Options for attachment areas.
struct AttachmentOptions {
  /// Landmarks farther from the surface than this fraction of the muscle's bounding-box diagonal
  /// are an error (default 0.2). Attachment landmarks sit on bone, not on the muscle surface: the
  /// LHDL files are up to 29 mm (0.1 of the diagonal) from their muscle; the landmark cloud of a
  /// wrong muscle (`*.insertion-far.xyz`, about 310 mm) is far above.
  double max_landmark_distance = 0.2;
  /// Automatic areas: the share of the muscle's extent along its principal direction taken at
  /// each end (default 0.1).
  double end_fraction = 0.1;
  /// Automatic areas: where an end's band of end_fraction falls apart into several pieces of
  /// surface (a muscle with two heads at that end, or a bump), widen that end's band just enough
  /// that it is one connected piece (over the mesh's edges), at most to max_end_fraction; an end
  /// that is not connected even then keeps end_fraction (default true). Why: the opendihu left
  /// biceps brachii's two heads are two separate pieces of its upper band at 0.1 (one at 0.16);
  /// with the origin on one head's tip the lattice ran through that head and left the other
  /// empty (14 folded cells); with the band widened past the fork the fibres start where the
  /// heads join the belly, none inside either head's tendon (docs/BENCHMARKS.md, "Decompose",
  /// seventeenth session).
  bool connected_ends = true;
  /// The widest band connected_ends may take at an end, as a share of the extent, in
  /// [end_fraction, 0.5) (default 0.3).
  double max_end_fraction = 0.3;
  /// A band widened by connected_ends is widened by this share of the extent more (still at most
  /// max_end_fraction), so that the piece joining the heads is not a thin neck, >= 0 (default
  /// 0.02; left biceps, inverted cells with margins 0 / 0.01 / 0.02 / 0.03 / 0.04 / 0.05 / 0.1:
  /// 11 / 0 / 0 / 1 / 1 / 0 / 2, docs/BENCHMARKS.md, "Decompose", seventeenth session).
  double connect_margin = 0.02;
  /// Throws OptionError naming the first field out of range.
  void validate() const;
};

/// One attachment area: its points on the surface.
struct AttachmentArea {
  std::string source;                 ///< file name, or "automatic"
  std::vector<SurfacePoint> points;   ///< on the muscle surface (face, barycentric, position)
  double max_distance = 0.0;          ///< largest landmark-to-surface distance, mesh units
  /// Automatic areas: the share of the extent the area's band takes (end_fraction, or wider where
  /// AttachmentOptions::connected_ends joined its pieces), and how many connected pieces the
  /// band of end_fraction had (1 for a simple end). 0 for landmark areas.
  double end_fraction = 0.0;
  int end_pieces = 0;
  /// Mean position of the points on the surface (mesh units).
  Vec3 centroid() const;
  /// For reports: source, points (the count), max_distance and, for automatic areas,
  /// end_fraction and end_pieces.
  nlohmann::json to_json() const;
};

/// Origin and insertion areas.
struct Attachments {
  AttachmentArea origin, insertion;
  bool automatic = false;
};

/// Projects landmarks (mesh units, any count >= 1) to the closest surface points.
/// Throws InputError(landmarks) naming `source`, the landmark's number (1-based), its distance
/// and the tolerance when a landmark is farther than options.max_landmark_distance times the
/// bounding-box diagonal of the mesh `query` was built on (`diagonal`, mesh units); and when
/// `landmarks` is empty.
AttachmentArea project_landmarks(const SurfaceQuery& query, double diagonal, const std::vector<Vec3>& landmarks,
                                 const std::string& source, const AttachmentOptions& options = {});

/// Automatic areas for muscles without landmarks: the principal direction of the vertices
/// (largest eigenvector of their covariance) is oriented so that its z component is >= 0 (the
/// proximal end is up in scanner coordinates, and the origin of a limb muscle is proximal); the
/// origin is every vertex within options.end_fraction of the extent from the upper end, the
/// insertion every vertex within it from the lower end; an end whose band is not one connected
/// piece of surface is widened (options.connected_ends). A sensible default for fusiform and
/// strap muscles; for fan-shaped muscles give landmarks. Throws TopologyError for an empty mesh.
Attachments automatic_attachments(const TriangleMesh& mesh, const AttachmentOptions& options = {});

/// Both areas from landmarks: see project_landmarks. Throws InputError(landmarks) as there, and
/// when the two areas' centroids coincide (closer than 1e-6 of the diagonal).
Attachments landmark_attachments(const TriangleMesh& mesh, const std::vector<Vec3>& origin,
                                 const std::string& origin_source, const std::vector<Vec3>& insertion,
                                 const std::string& insertion_source, const AttachmentOptions& options = {});

/// Centre of an area on a sphere map: the normalised mean of its points' sphere images
/// (`sphere`: #V unit vectors of the map of the mesh whose triangles are `triangles`).
Vec3 sphere_centre(const AttachmentArea& area, const std::vector<Vec3>& sphere,
                   const std::vector<Triangle>& triangles);

}  // namespace fascicle
