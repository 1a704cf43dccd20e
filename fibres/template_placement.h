#pragma once
/// \file template_placement.h
/// Where the template's surface lattice points go on the muscle (pipeline steps 3-5 of
/// ../shared/docs/METHOD.md): both surfaces on the unit sphere, their origin and insertion areas
/// aligned there, and every template surface point located in the muscle's sphere map.
///
/// Method. The template surface is the boundary of the lattice's index box (r, s, t) in [0,1]^3;
/// its sphere map is the central projection from the box centre, a bijection because the box is
/// convex. The origin face t = 0 and the insertion face t = 1 are opposite, so their centres are
/// antipodal. On the muscle's sphere map (a bijection, morph/sphere_map.h) each attachment area
/// becomes a region: the vertices within `region_radius` (of the muscle length) of an area point.
/// Its centre is the region vertex farthest (on the sphere) from the region's border, so that it
/// lies inside the region even when the region is not convex. A landmark area can be a long strip
/// running down the side of the muscle; centred in the middle of the strip, the face would leave
/// the end of the muscle beyond it without fibres. For landmark areas the centre is therefore
/// moved towards the region's far end: the vertex farthest from the other area among those at
/// least `landmark_centre_keep` of the deepest vertex's distance from the border, so that the
/// fibres start at the muscle's end. A pole frame (fibres/pole_frame.h:
/// rotation + Moebius map) sends the muscle's origin centre to the north pole and its insertion
/// centre to the south pole, exactly; the template's frame is a rotation. In the pole frames a
/// point has polar angle theta and azimuth phi; the correspondence keeps phi (up to a twist that
/// turns the template's r axis to `corner_twist_deg` from the muscle's second principal axis, so
/// that the corners of the lattice's cross-section lie on the muscle's broad axis; with
/// `even_perimeter`, reparametrised in each cross-section so that equal shares of the template's
/// square perimeter go to equal shares of the muscle's) and maps theta by a
/// function that is monotone in theta for every phi, so the whole correspondence is a
/// homeomorphism of the sphere (neighbouring template points stay neighbours, nothing folds):
///  - the origin face (theta below its edge Theta(phi)) goes linearly in tan(theta) onto the
///    muscle's origin region, whose star radius R_o(phi) (first border vertex seen from the pole
///    along azimuth phi, taken conservatively over neighbouring azimuths and shrunk by
///    `region_margin`) bounds it; likewise the insertion face onto the insertion region;
///  - the lateral band between the two faces goes onto the muscle's band between the regions,
///    matching the cumulative surface-area share along the band coordinate
///    u = (theta - R_o) / (pi - R_i - R_o) (template area measured on the template's geometry, so
///    the families' shapes decide how densely each part of the muscle is sampled).
/// This replaces the thesis's rotation + local pull (formula 6.2; kept in morph/align_on_sphere.h)
/// for the decomposition: both centres are matched exactly and the whole attachment faces land
/// inside the attachment areas, so fibre ends neither spill out of their areas nor collapse to a
/// point.
#include "fibres/fibre_check.h"
#include "geometry/mesh.h"
#include "morph/attachments.h"
#include "morph/sphere_locator.h"
#include "springs/lattice.h"

#include <nlohmann/json_fwd.hpp>
#include <vector>

namespace fascicle {

/// Options of the template placement.
struct PlacementOptions {
  /// An attachment region is every muscle vertex within this share of the muscle length of an area
  /// point (default 0.01: fibre ends then lie within about that distance of their area).
  double region_radius = 0.01;
  /// Factor on a region's star radius before the face is mapped into it (default 0.9: face points
  /// stay clear of the region's border).
  double region_margin = 0.9;
  int azimuth_bins = 72;  ///< azimuth bins for a region's star radius (default 72, every 5 degrees)
  /// Least polar-angle gap (radians) left for the lateral band; both regions' star radii shrink
  /// together to keep it (default 0.3).
  double min_band = 0.3;
  /// Largest attachment face depth along the end axis, share of the distance to the first ring
  /// (default 0.1: a face wrapped deeper than the first ring folds the first layer, so it is shrunk).
  double max_face_depth = 0.1;
  int face_shrink_rounds = 12;  ///< largest number of face shrinking rounds (default 12)
  /// Lateral rings at even steps of length along the muscle (true) or of surface area (false)
  /// (default true: keeps the layers flat where the muscle narrows to a tendon).
  bool band_by_length = true;
  /// With band_by_length: largest turn (degrees) of the muscle's centre line between two rings;
  /// the rings between the first and the last close up where it turns faster, [0, 180]
  /// (default 0: off, rings by length alone; docs/decompose.md, step 4, measures 5, 10 and 20).
  double bend_step_deg = 0.0;
  /// With band_by_length: each ring point at the same share of its own meridian's length (true) or
  /// one sphere-map level per ring (false) (default false; the second try for folds and uneven layers, fibres/try_policy.h).
  bool meridian_rings = false;
  /// Automatic areas: azimuth (degrees) of the template's r axis from the muscle's second principal
  /// axis, [-180, 180] (default 0: the lattice's sides face the ends of the cross-section's broad
  /// axis, which folds the fewest cells where a section is concave; a coverage gap at a flat
  /// muscle's thin edges calls a second try with 45, corners there, fibres/try_policy.h).
  double corner_twist_deg = 0.0;
  /// Landmark areas, and templates whose fibres cross the lattice (their aponeuroses are the broad
  /// faces between the corners): the same azimuth, [-180, 180] (default 45: corners on the thin
  /// edges; with landmark areas the sides there lose decompose passes, docs/decompose.md step 4).
  double edge_corner_twist_deg = 45.0;
  /// Automatic areas: a muscle whose cross-sections are at least this many times as broad as
  /// thick (median over its middle, geometry/cross_section.h) gets edge_corner_twist_deg from the
  /// first try: the sides' middles cannot follow a flat muscle's acute edges, 0 or >= 1 (default
  /// 2; 0: never, the coverage gap's second try then puts the corners there, docs/decompose.md step 4).
  double flat_section_aspect = 2.0;
  /// The corner twist of a placement: corner_twist_deg where the fibres are the lattice's lines
  /// between automatic areas (`lines_between_automatic_areas`), else edge_corner_twist_deg.
  double twist_for(bool lines_between_automatic_areas) const {
    return lines_between_automatic_areas ? corner_twist_deg : edge_corner_twist_deg;
  }
  /// Ring points at even shares of each cross-section's perimeter (true) or at the azimuth plus the
  /// twist (false) (default false).
  bool even_perimeter = false;
  /// Landmark areas only: region centre at the vertex farthest from the other area among those at
  /// least this share of the deepest from the border, (0, 1] (default 0.35; 1: the deepest vertex).
  double landmark_centre_keep = 0.35;
  /// Throws OptionError naming the first field out of range.
  void validate() const;
};

/// What the placement did.
struct PlacementReport {
  int origin_region_vertices = 0, insertion_region_vertices = 0;
  double centre_angle_deg = 0.0;         ///< angle between the two region centres on the muscle sphere
  Vec3 origin_centre = Vec3::Zero();     ///< the origin region's centre on the muscle (a vertex)
  Vec3 insertion_centre = Vec3::Zero();  ///< ... and the insertion region's
  double moebius_scale = 1.0;            ///< scale of the muscle's pole frame (median area at the equator)
  double twist_deg = 0.0;                ///< azimuth of the template's r axis at the origin face
  double twist_end_deg = 0.0;            ///< ... and at the insertion face (it varies along the band)
  double origin_radius_min_deg = 0.0, origin_radius_max_deg = 0.0;        ///< R_o(phi) range
  double insertion_radius_min_deg = 0.0, insertion_radius_max_deg = 0.0;  ///< R_i(phi) range
  double origin_face_scale = 1.0, insertion_face_scale = 1.0;             ///< share of R(phi) the faces use
  double centre_turn_deg = 0.0;  ///< with bend_step_deg: the smoothed centre line's whole turn
  double bend_share = 0.0;       ///< with bend_step_deg: share of the band measure its rule adds
  long located = 0;  ///< template surface points located on the muscle
  double seconds = 0.0;
  nlohmann::json to_json() const;
};

/// Template surface points on the muscle: `points[q]` for every fixed (surface) point q of the
/// lattice (other entries default, face -1).
struct Placement {
  std::vector<SurfacePoint> points;
  PlacementReport report;
};

/// Places the surface points of `lattice` (index box boundary, fixed points) on `muscle`
/// (closed genus 0) through its bijective sphere map `sphere` (#V unit vectors) and `locator`
/// (built on it), with the attachment areas `areas` of the muscle. Method: see the file comment.
/// Throws InputError(landmarks) when an area has no vertex within its region radius or the two
/// regions share their centre, OptionError for bad options.
Placement place_template(const TriangleMesh& muscle, const std::vector<Vec3>& sphere, const SphereLocator& locator,
                         const Attachments& areas, const springs::Lattice& lattice,
                         const PlacementOptions& options = {});

}  // namespace fascicle
