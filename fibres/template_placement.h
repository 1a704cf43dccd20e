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
/// running down the side of the muscle (LHDL gluteus medius: its origin landmarks span 0.54-1.00
/// of the principal axis); centred in the middle of the strip, the face leaves the end of the
/// muscle beyond it without fibres (the top tenth 94 % uncovered, coverage p95 2.34). For landmark
/// areas the centre is therefore moved towards the region's far end: the vertex farthest from the
/// other area among those at least `landmark_centre_keep` of the deepest vertex's distance from
/// the border (fibres then start at the muscle's end: coverage p95 1.60; docs/BENCHMARKS.md,
/// "LHDL landmark regions centred towards their far ends"). A pole frame (fibres/pole_frame.h:
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
  /// An attachment region is every muscle vertex within this fraction of the muscle length of an
  /// area point (default 0.01; fibre ends then lie within about that distance of their area).
  double region_radius = 0.01;
  /// The star radius of a region is multiplied by this before the template face is mapped into
  /// it, so that face points stay clear of the region's border (default 0.9).
  double region_margin = 0.9;
  /// Azimuth bins for the star radius of a region (default 72, every 5 degrees).
  int azimuth_bins = 72;
  /// The two regions' star radii are scaled down together where they would leave less than this
  /// polar-angle gap (radians) for the lateral band (default 0.3).
  double min_band = 0.3;
  /// Largest depth of an attachment face on the muscle (the spread of its points along the
  /// muscle's end axis) as a share of the distance from its shallowest point to the first lateral
  /// ring (default 0.1, measured on the sample muscle: 0.5 leaves 90 of 1134 cells inverted, 0.1
  /// leaves 17, 0.05 leaves 8). A face wrapped round a rounded end deeper than the first ring of fibre
  /// points would fold the first layer of cells; the face is shrunk (by 0.3 to 0.8 a round, from
  /// the measured depth) until it fits.
  double max_face_depth = 0.1;
  /// Largest number of shrinking rounds (default 12).
  int face_shrink_rounds = 12;
  /// Lateral rings of the lattice go to even steps of length along the muscle (area per level
  /// circumference) when true, to even steps of surface area when false (default true: keeps the
  /// layers flat where the muscle narrows to a tendon).
  bool band_by_length = true;
  /// With band_by_length: each lateral ring point goes to the same share of the length of its
  /// own meridian (the curve of its azimuth from the origin region to the insertion region,
  /// through the area-weighted face centres of up to 48 levels in 24 azimuth sectors, each
  /// sector's window three sectors wide, the curve smoothed twice by (1, 2, 1)), so a ring need
  /// not follow one level of the sphere map; its azimuth stays the level ring's (default false:
  /// one level per ring). Where the sphere map's levels run obliquely along a thin tendon, a
  /// level ring skips it (LHDL psoas: layers of 15-28 mm, then one of 70 mm round its hooked
  /// insertion end, the tendon's hook left without fibres); by meridian its lateral layers are
  /// 20-39 mm, the fibres following the hook. As the first choice it passed 45 of the 47 corpus muscles
  /// (the two opendihu biceps fold), so decompose tries it only for a result with a layer that
  /// long (DecomposeOptions::even_layers_ratio; docs/BENCHMARKS.md, "Decompose", twenty-second
  /// session).
  bool meridian_rings = false;
  /// Azimuth (degrees) of the template's r axis from the muscle's second principal axis in each
  /// cross-section, in [-180, 180] (default 45: a corner of the lattice's square cross-section
  /// at each end of the muscle's broad axis). With 0 the middle of a lattice side lies on the
  /// thin edge of a flat muscle, where the interior cannot follow the surface into the edge: the
  /// settled lattice stays away from that flank (VHF iliacus, vastus lateralis: 11-16 % of the
  /// volume farther than 2 ideal spacings from every fibre, coverage p95 3.8-4.0; with 45:
  /// 1.6-1.7; docs/BENCHMARKS.md, "Decompose").
  double corner_twist_deg = 45.0;
  /// Around each cross-section, template points go to the muscle azimuth at the same share of
  /// the perimeter (surface area by azimuth), counted from a lattice corner, when true; to the
  /// same azimuth (plus the twist) when false (default false; the second try of a failed
  /// decomposition switches it, DecomposeOptions::retry_alternative. The sphere map compresses
  /// the thin edges of a flat muscle, and by azimuth alone the lattice corners crowd into them;
  /// even shares spread the ring evenly (ring spacing max/min 2.1 against 3.5 on a 5 : 1 flat
  /// capsule), but as the first choice (with contact_depth_min 0.05) it passed 34 of the 38
  /// corpus muscles the other passes, and 2 others: docs/BENCHMARKS.md, "Decompose",
  /// 2026-11-21 21:24-21:30).
  bool even_perimeter = false;
  /// Landmark areas only: the centre of each region is the region vertex farthest (in space) from
  /// the other area's centroid among those at least this share of the largest distance from the
  /// region's border (on the sphere), in (0, 1] (default 0.35; 1: the vertex farthest from the
  /// border, the rule for automatic areas). On the LHDL matrix without the psoas, 0.35 passes 15
  /// of 15 muscle and template pairs, 0.5 passes 14 (gluteus maximus with rectus: coverage p95
  /// 2.03); 0.7 leaves the centre too deep in the strip. The psoas folds with either (more than
  /// with 1: 1411 / 1231 / 1155 inverted cells over its five templates with 0.35 / 0.5 / 1;
  /// docs/BENCHMARKS.md, "LHDL landmark regions centred towards their far ends").
  double landmark_centre_keep = 0.35;
  /// Throws OptionError naming the first field out of range.
  void validate() const;
};

/// What the placement did.
struct PlacementReport {
  int origin_region_vertices = 0, insertion_region_vertices = 0;
  double centre_angle_deg = 0.0;   ///< angle between the two region centres on the muscle sphere
  Vec3 origin_centre = Vec3::Zero();     ///< the origin region's centre on the muscle (a vertex)
  Vec3 insertion_centre = Vec3::Zero();  ///< ... and the insertion region's
  double moebius_scale = 1.0;      ///< scale of the muscle's pole frame (median area at the equator)
  double twist_deg = 0.0;          ///< azimuth of the template's r axis at the origin face
  double twist_end_deg = 0.0;      ///< ... and at the insertion face (it varies along the band)
  double origin_radius_min_deg = 0.0, origin_radius_max_deg = 0.0;        ///< R_o(phi) range
  double insertion_radius_min_deg = 0.0, insertion_radius_max_deg = 0.0;  ///< R_i(phi) range
  double origin_face_scale = 1.0, insertion_face_scale = 1.0;  ///< share of R(phi) the faces use
  long located = 0;                ///< template surface points located on the muscle
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
