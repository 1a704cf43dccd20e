#pragma once
/// \file attachments.h
/// Origin and insertion areas of a muscle (pipeline steps 4-5 of ../shared/docs/METHOD.md):
/// from landmark points projected to the surface, or found automatically as the two end regions
/// along the muscle's principal direction.

#include "geometry/mesh.h"
#include "morph/surface_query.h"

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
  /// Throws OptionError naming the first field out of range.
  void validate() const;
};

/// One attachment area: its points on the surface.
struct AttachmentArea {
  std::string source;                 ///< file name, or "automatic"
  std::vector<SurfacePoint> points;   ///< on the muscle surface (face, barycentric, position)
  double max_distance = 0.0;          ///< largest landmark-to-surface distance, mesh units
  /// Mean position of the points on the surface (mesh units).
  Vec3 centroid() const;
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
/// insertion every vertex within it from the lower end. A sensible default for fusiform and
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
