#pragma once
/// \file coarse_start.h
/// A start for the static solve of a lattice: the equilibrium of the same lattice with every
/// other point (recursively), interpolated back. The slow part of a static solve on a large
/// lattice is its smooth error (the lowest eigenmodes of the stiffness, whose count of
/// iterations grows with the lattice); on the coarse lattice those modes are cheap, so the fine
/// solve starts with them nearly settled and is left mostly the fast, local part. This is the
/// cascadic idea of Deuflhard 1994 ("Cascadic conjugate gradient methods for elliptic partial
/// differential equations") and of Bornemann and Deuflhard 1996, applied to the nonlinear
/// spring problem.
///
/// The coarse lattice keeps the fine indices f(c) = round(c (n - 1) / (m - 1)), m = n / 2 + 1
/// per axis (steps of 2, one step of 1 when n is even), the fixed flags and positions of those
/// points, and the model's neighbour springs; a coarse spring's rest length is the sum of the
/// rest lengths of the fine springs along the lattice path it spans (two springs in series with
/// stiffness 1 / rest each make one of stiffness 1 / (sum of rests): the same chain). Free fine
/// points then move to the trilinear interpolation (in index space) of the settled coarse
/// positions, on model-6 lattices plus a small fixed offset per free point
/// (options.coarse_start_perturbation: a share of the mean axis rest length, hashed from the
/// point's index) that starts the buckling a compressed fine lattice needs and its smooth coarse
/// start lacks; fixed points never move.

#include "springs/settle.h"

namespace fascicle::springs {

/// What a coarse start did.
struct CoarseStartReport {
  int levels = 0;        ///< coarse lattices settled (0: none, the lattice is too small)
  int iterations = 0;    ///< iterations on all coarse lattices
  double seconds = 0.0;  ///< wall time of the whole coarse start
};

/// Moves the free points of `system`, a lattice of `shape` (build_lattice order, springs exactly
/// the model's neighbours), to the interpolated (and perturbed) equilibrium of its coarse lattice, which is
/// settled the same way (static momentum method, relative residual
/// max(options.tolerance, options.coarse_start_tolerance)), recursively while a lattice has more
/// than options.coarse_start_points points and every side at least 5 points. Returns levels = 0
/// and leaves `system` unchanged when the lattice does not qualify (too small, a spring missing,
/// springs that are not the model's neighbours). Throws as settle() on the coarse lattices.
CoarseStartReport coarse_start(SpringSystem& system, const LatticeShape& shape, const SettleOptions& options);

}  // namespace fascicle::springs
