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
  /// Landmarks farther from the surface than this share of the bounding-box diagonal are an error
  /// (default 0.2: landmarks sit on bone, near but not on the muscle; a wrong muscle's lie far above).
  double max_landmark_distance = 0.2;
  double end_fraction = 0.1;  ///< automatic areas: share of the principal extent at each end (default 0.1)
  /// Automatic areas: widen an end's band that falls apart (two heads, a bump) until it is one piece, up
  /// to max_end_fraction (default true: else the lattice runs through one head and leaves the other empty).
  bool connected_ends = true;
  double max_end_fraction = 0.3;  ///< widest band connected_ends may take, [end_fraction, 0.5) (default 0.3)
  /// A band widened by connected_ends grows by this share of the extent more, up to max_end_fraction,
  /// >= 0 (default 0.02: so that the piece joining the heads is not a thin neck).
  double connect_margin = 0.02;
  /// Automatic areas: largest spacing of the area's points across its triangles, share of the extent,
  /// > 0 (default 0.01: every point of the area's surface then lies within 0.006 of the extent of an
  /// area point, inside the 0.01 by which placement, casts and the check tell a point on the area,
  /// however coarse the mesh; the vertices alone leave gaps wider than that on a coarse mesh).
  double max_point_spacing = 0.01;
  /// Throws OptionError naming the first field out of range.
  void validate() const;
};

/// One attachment area: its points on the surface.
struct AttachmentArea {
  std::string source;                ///< file name, or "automatic"
  /// On the muscle surface (face, barycentric, position). Automatic areas: the band's vertices, then
  /// points across its triangles (AttachmentOptions::max_point_spacing).
  std::vector<SurfacePoint> points;
  double max_distance = 0.0;         ///< largest landmark-to-surface distance, mesh units
  /// Automatic areas: the share of the extent the area's band takes (end_fraction, or wider where
  /// AttachmentOptions::connected_ends joined its pieces), and how many connected pieces the
  /// band of end_fraction had (1 for a simple end). 0 for landmark areas.
  double end_fraction = 0.0;
  int end_pieces = 0;
  /// When not empty, the area's own surface: an area that is not a piece of the muscle's surface
  /// (an aponeurosis inside the muscle, drawn by fibres/pennate_fibres.h). The check's ends
  /// criterion samples it instead of the muscle's surface near the points (default empty).
  TriangleMesh patch;
  /// Mean position of the points on the surface (mesh units).
  Vec3 centroid() const;
  /// Whether `x` lies within `radius` (mesh units) of one of the points: a fibre end placed there
  /// counts as on the area.
  bool near(const Vec3& x, double radius) const;
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
Vec3 sphere_centre(const AttachmentArea& area, const std::vector<Vec3>& sphere, const std::vector<Triangle>& triangles);

}  // namespace fascicle
