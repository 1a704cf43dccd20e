#pragma once
/// \file untangle.h
/// Untangling a tetrahedral mesh with fixed points: moves the free points until every
/// tetrahedron has a positive volume, keeping the cells close to a reference shape.
///
/// Method: the regularised barrier of Garanzha, Kaporin, Kudryavtseva, Protais, Ray and
/// Sokolov 2021 ("Foldover-free maps in 50 lines of code", ACM Trans. Graph. 40(4)). For a
/// tetrahedron with Jacobian J = D S^-1 (D its edge vectors, S those of its reference shape)
///     f(J) = (1 - lambda) tr(J^T J) / chi(det J)^(2/3) + lambda (det^2 J + 1) / chi(det J),
///     chi(d) = (d + sqrt(eps^2 + d^2)) / 2,
/// a shape term and a volume term that are finite for any J while eps > 0 and become a
/// barrier against det J <= 0 as eps -> 0. The total (weighted sum) is minimised by L-BFGS
/// with a backtracking line search, eps lowered after each stage by the paper's rule (from the
/// smallest det J and the energy's relative decrease, at least `min_sigma`), until every
/// tetrahedron is positive, then a few more iterations improve the shapes with the barrier in
/// force. A run that ends worse than the best state it met returns that state
/// (UntangleOptions::keep_best).
///
/// The fibre lattice uses it to unfold the cells that the settle leaves inverted
/// (fibres/decompose.h): hexahedral cells split into the six tetrahedra of the Kuhn
/// triangulation that fibres/fibre_check.h counts.

#include "geometry/mesh.h"

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <functional>
#include <nlohmann/json.hpp>
#include <vector>

namespace fascicle {

/// Options of untangle().
struct UntangleOptions {
  double lambda = 0.05;       ///< weight of the volume term against the shape term, (0, 1) (default 0.05)
  int history = 8;            ///< L-BFGS pairs kept, >= 1 (default 8)
  int stage_iterations = 40;  ///< L-BFGS iterations per eps stage, >= 1 (default 40)
  int max_stages = 60;        ///< eps stages at most, >= 1 (default 60)
  /// Stop when neither the smallest det J has grown nor the inverted count fallen (nor a contained
  /// point come inside) for this many stages, >= 1 (default 5: the lattice untangling's later
  /// attempts start elsewhere, so a longer wait on resisting folds only costs time).
  int stall_stages = 5;
  /// Least sigma of the eps rule (each stage aims eps at (1 - sigma) chi(min det J)), (0, 1) (default
  /// 0.1, the paper's: larger values take fewer stages but leave some folds).
  double min_sigma = 0.1;
  int polish_iterations = 30;  ///< iterations after the last tetrahedron turned positive, >= 0 (default 30)
  /// A tetrahedron counts as positive when det J > min_det (J relative to its reference)
  /// (default 1e-4: well clear of the round-off limit of the quality check).
  double min_det = 1e-4;
  /// Return the best state met (fewest inverted, then fewest outside, then largest least det J; earlier on a
  /// tie) when the run ends worse (true), or the last (false) (default true; the polish runs from it).
  bool keep_best = true;
  /// Throws OptionError naming the first bad field.
  void validate() const;
};

/// One tetrahedron of an untangle problem: vertex indices (positive orientation = the
/// reference's), the inverse of its reference edge matrix S (columns v1 - v0, v2 - v0, v3 - v0,
/// det S > 0) and its weight (e.g. its reference volume share).
struct UntangleTet {
  std::array<int, 4> v{};
  Eigen::Matrix3d reference_inverse = Eigen::Matrix3d::Identity();
  double weight = 1.0;
  /// Whether the tetrahedron counts: the stopping rule and the census look at counted ones only;
  /// the others (e.g. cells against fixed boundary points that may stay inverted) still pull
  /// through the energy (default true).
  bool counted = true;
  /// Lower bound of eps for this tetrahedron (default 0: the barrier tightens with the stage's
  /// eps). A positive floor makes its term a soft preference for positive volume that never
  /// becomes a barrier (for tetrahedra that may be impossible to unfold).
  double eps_floor = 0.0;
};

/// A soft pin: the energy gains weight |x_point - target|^2 (a zero-length spring), so that a
/// point can be held near a place (e.g. just inside the muscle) and still give way where the
/// cells need it. Two one-sided kinds: with a `radius` > 0 only the distance beyond it counts,
/// weight max(0, |x - target| - radius)^2 (a ball the point may move in freely: a fibre end
/// near its attachment area); with a unit `normal` only the part of the offset along the normal
/// counts, weight max(0, normal . (x - target))^2 (a half-space: a point outside the muscle is
/// pushed under the tangent plane and may slide along it).
struct UntangleAnchor {
  int point = 0;
  Vec3 target = Vec3::Zero();
  double weight = 0.0;         ///< energy per squared length unit, >= 0
  double radius = 0.0;         ///< free ball round the target, >= 0 (default 0: a zero-length spring)
  Vec3 normal = Vec3::Zero();  ///< unit outward normal of a half-space pin (default zero: not one)
  /// With a normal: only the side outside counts (true: a half-space) or both (false: the point is
  /// held on the plane through the target and may slide along it) (default true).
  bool one_sided = true;
};

/// Signed distance to a closed surface at a point: negative inside, positive outside, in length
/// units; writes its gradient into `gradient` when that is not null. untangle() calls it from one
/// thread, in a fixed order, so a lazily filled cache behind it keeps the result deterministic.
using SignedDistanceFunction = std::function<double(const Vec3& point, Vec3* gradient)>;

/// Containment as part of the energy: each listed point that is free pays
///     weight * scale * max(0, d(x) + margin)^2,
/// d the signed distance, so the minimum the untangling seeks already has the points at least
/// `margin` inside. `scale` starts at 1 and is multiplied by `growth` after each eps stage that
/// leaves a listed point outside (d > 0), at most `max_scale`; the stages go on while a listed
/// point is outside even when no tetrahedron is inverted (the barrier then keeps the cells
/// unfolded while the penalty pulls the points in).
struct UntangleContainment {
  struct Point {
    int point = 0;
    double weight = 0.0;  ///< energy per squared length unit, >= 0
    double margin = 0.0;  ///< depth it is pushed to, length units, >= 0
  };
  SignedDistanceFunction signed_distance;  ///< empty: no containment
  std::vector<Point> points;
  double growth = 4.0;        ///< factor of the scale per stage with a point outside, >= 1 (default 4)
  double max_scale = 4096.0;  ///< largest scale, >= 1 (default 4096 = 4^6)
  bool active() const { return signed_distance && !points.empty(); }
};

/// What untangle() did.
struct UntangleReport {
  long tets = 0;                                     ///< tetrahedra in the problem
  long free_points = 0;                              ///< points it may move
  long counted = 0;                                  ///< of them, counted ones
  long inverted_before = 0;                          ///< counted tetrahedra with det J <= min_det before
  long inverted_after = 0;                           ///< and after
  long uncounted_inverted_after = 0;                 ///< tetrahedra not counted with det J <= 0 after
  double min_det_before = 0.0, min_det_after = 0.0;  ///< smallest counted det J before and after
  int stages = 0;                                    ///< eps stages run
  int iterations = 0;                                ///< L-BFGS iterations in all
  int evaluations = 0;                               ///< energy and gradient evaluations
  double eps = 0.0;                                  ///< eps of the last stage
  double seconds = 0.0;
  long outside_before = 0;         ///< containment points with d > 0 before (0 without containment)
  long outside_after = 0;          ///< and after
  double containment_scale = 1.0;  ///< the containment's last scale
  int reverted = 0;                ///< 1 when the run returned an earlier, better state (keep_best)
  bool untangled() const { return inverted_after == 0; }
  nlohmann::json to_json() const;
};

/// Untangles `positions` (#P) in place: only points with fixed[q] == 0 move. Tetrahedra whose
/// four points are all fixed are counted but cannot change. Does nothing (but count) when no
/// tetrahedron is inverted, no anchor is given and no containment point is outside. With
/// `containment` (UntangleContainment) the stages go on until no tetrahedron is inverted and no
/// containment point is outside. Throws OptionError for bad options, InputError(internal) for a
/// vertex index out of range or a non-finite position.
UntangleReport untangle(std::vector<Vec3>& positions, const std::vector<char>& fixed,
                        const std::vector<UntangleTet>& tets, const UntangleOptions& options = {},
                        const std::vector<UntangleAnchor>& anchors = {}, const UntangleContainment& containment = {});

/// det J of every tetrahedron at `positions` (its signed volume relative to its reference).
std::vector<double> tet_jacobian_dets(const std::vector<Vec3>& positions, const std::vector<UntangleTet>& tets);

}  // namespace fascicle
