#pragma once
/// \file spring_system.h
/// A general mass-spring system (any spring list) and the quantities every solver shares:
/// spring forces (Hooke, formula 3.1 of Zeleny 2011), potential energy and the relative residual
/// used as the stopping criterion.

#include "geometry/mesh.h"
#include "geometry/thesis_format.h"

#include <vector>

namespace fascicle::springs {

/// One spring between points a and b.
struct Spring {
  int a = 0, b = 0;        ///< end points, indices into SpringSystem::positions, a != b
  double rest = 0.0;       ///< rest length |l0|, length units, >= 0
  double stiffness = 0.0;  ///< Hooke constant D (force per length), > 0
};

/// A mass-spring system.
/// - positions: #N points, length units (any: the solvers are scale-free when stiffness = 1/rest)
/// - fixed: #N flags, 1 = the point never moves (surface points of a template lattice)
/// - mass: #N point masses, > 0 (only the Verlet solver uses them)
/// - springs: #S springs
struct SpringSystem {
  std::vector<Vec3> positions;
  std::vector<char> fixed;
  std::vector<double> mass;
  std::vector<Spring> springs;
};

/// Checks sizes, indices, finiteness and signs. Throws OptionError naming the first bad element.
void validate(const SpringSystem& system);

/// Spring forces on every point at `positions` (#N), Hooke's law (3.1): a spring pulls its end
/// points together with D (|l| - |l0|) / |l| l. Returns #N force vectors (fixed points included).
std::vector<Vec3> spring_forces(const SpringSystem& system, const std::vector<Vec3>& positions);

/// Potential energy sum over springs of D/2 (|l| - |l0|)^2 at `positions`.
double potential_energy(const SpringSystem& system, const std::vector<Vec3>& positions);

/// The force unit of the relative residual: the mean over springs of D |l0| (the force of a spring
/// stretched to twice its rest length; 1 when D = 1/|l0|). For a system whose springs all have
/// zero rest length it is the mean of D |l| at the system's own positions; 1 if that is 0 too.
double residual_force_scale(const SpringSystem& system);

/// Relative residual: the largest spring-force magnitude at a free point divided by
/// residual_force_scale(system). 0 when every point is fixed.
double relative_residual(const SpringSystem& system, const std::vector<Vec3>& positions);

/// The thesis's damping estimate for model-6 lattices (Zeleny 2011, formula 7.2):
/// c = sqrt(4 k6 * 2 m), k6 = 2 + 4 L, with L the mean spring rest length and m the point mass.
double thesis_damping_estimate(double mean_rest_length, double mass);

/// Converts a thesis-format model (appendix 2 of the thesis) to a spring system: springs take
/// their stiffness from the file and their rest length from the distance of their end points in
/// the file; surface points ('m') are fixed; every point gets mass `mass` (> 0).
/// Throws InputError (index_out_of_range, malformed for a spring joining a point to itself,
/// bad_number for a stiffness that is not > 0) naming the spring, OptionError for mass <= 0.
SpringSystem spring_system_from_thesis(const ThesisModel& model, double mass);

/// Writes `positions` back into a copy of `model` (springs, areas, triangles unchanged).
ThesisModel with_positions(const ThesisModel& model, const std::vector<Vec3>& positions);

}  // namespace fascicle::springs
