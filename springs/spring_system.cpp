// General spring-system quantities: Hooke forces (3.1), energy, residual, thesis conversions.

#include "springs/spring_system.h"

#include "geometry/errors.h"

#include <algorithm>
#include <cmath>
#include <string>

namespace fascicle::springs {

void validate(const SpringSystem& system) {
  const std::size_t n = system.positions.size();
  if (system.fixed.size() != n)
    throw OptionError("spring system: fixed has " + std::to_string(system.fixed.size()) + " flags for " +
                      std::to_string(n) + " points");
  if (system.mass.size() != n)
    throw OptionError("spring system: mass has " + std::to_string(system.mass.size()) + " values for " +
                      std::to_string(n) + " points");
  for (std::size_t i = 0; i < n; ++i) {
    if (!system.positions[i].allFinite())
      throw OptionError("spring system: point " + std::to_string(i) + " is not finite");
    if (!(system.mass[i] > 0.0) || !std::isfinite(system.mass[i]))
      throw OptionError("spring system: mass of point " + std::to_string(i) + " is " + std::to_string(system.mass[i]) +
                        " (must be > 0)");
  }
  for (std::size_t s = 0; s < system.springs.size(); ++s) {
    const Spring& spring = system.springs[s];
    if (spring.a < 0 || spring.b < 0 || static_cast<std::size_t>(spring.a) >= n ||
        static_cast<std::size_t>(spring.b) >= n || spring.a == spring.b)
      throw OptionError("spring system: spring " + std::to_string(s) + " joins " + std::to_string(spring.a) + " and " +
                        std::to_string(spring.b) + " (need two distinct points below " + std::to_string(n) + ")");
    if (!(spring.rest >= 0.0) || !std::isfinite(spring.rest))
      throw OptionError("spring system: spring " + std::to_string(s) + " has rest length " +
                        std::to_string(spring.rest));
    if (!(spring.stiffness > 0.0) || !std::isfinite(spring.stiffness))
      throw OptionError("spring system: spring " + std::to_string(s) + " has stiffness " +
                        std::to_string(spring.stiffness) + " (must be > 0)");
  }
}

std::vector<Vec3> spring_forces(const SpringSystem& system, const std::vector<Vec3>& positions) {
  std::vector<Vec3> forces(positions.size(), Vec3::Zero());
  for (const Spring& s : system.springs) {
    const Vec3 l = positions[s.a] - positions[s.b];
    const double len = l.norm();
    if (len == 0.0) continue;  // direction undefined; zero-length springs push nothing
    const Vec3 f = s.stiffness * (len - s.rest) / len * l;
    forces[s.a] -= f;
    forces[s.b] += f;
  }
  return forces;
}

double potential_energy(const SpringSystem& system, const std::vector<Vec3>& positions) {
  double energy = 0.0;
  for (const Spring& s : system.springs) {
    const double stretch = (positions[s.a] - positions[s.b]).norm() - s.rest;
    energy += 0.5 * s.stiffness * stretch * stretch;
  }
  return energy;
}

double residual_force_scale(const SpringSystem& system) {
  if (system.springs.empty()) return 1.0;
  double sum = 0.0;
  for (const Spring& s : system.springs) sum += s.stiffness * s.rest;
  if (sum > 0.0) return sum / static_cast<double>(system.springs.size());
  for (const Spring& s : system.springs) sum += s.stiffness * (system.positions[s.a] - system.positions[s.b]).norm();
  return sum > 0.0 ? sum / static_cast<double>(system.springs.size()) : 1.0;
}

double relative_residual(const SpringSystem& system, const std::vector<Vec3>& positions) {
  const std::vector<Vec3> forces = spring_forces(system, positions);
  double largest = 0.0;
  for (std::size_t i = 0; i < forces.size(); ++i)
    if (!system.fixed[i]) {
      const double f = forces[i].norm();
      if (f > largest || std::isnan(f)) largest = f;  // NaN sticks
    }
  return largest / residual_force_scale(system);
}

double thesis_damping_estimate(double mean_rest_length, double mass) {
  const double k6 = 2.0 + 4.0 * mean_rest_length;
  return std::sqrt(4.0 * k6 * 2.0 * mass);
}

SpringSystem spring_system_from_thesis(const ThesisModel& model, double mass) {
  if (!(mass > 0.0)) throw OptionError("mass: must be > 0, got " + std::to_string(mass));
  SpringSystem system;
  system.positions = model.points;
  system.fixed.assign(model.points.size(), 0);
  for (std::size_t i = 0; i < model.surface.size() && i < model.points.size(); ++i)
    system.fixed[i] = model.surface[i] ? 1 : 0;
  system.mass.assign(model.points.size(), mass);
  system.springs.reserve(model.springs.size());
  const int n = static_cast<int>(model.points.size());
  for (std::size_t s = 0; s < model.springs.size(); ++s) {
    const auto& in = model.springs[s];
    if (in.a < 0 || in.b < 0 || in.a >= n || in.b >= n)
      throw InputError(ErrorCode::index_out_of_range,
                       "spring " + std::to_string(s) + " refers to a point outside 0.." + std::to_string(n - 1));
    if (in.a == in.b)
      throw InputError(ErrorCode::malformed,
                       "spring " + std::to_string(s) + " joins point " + std::to_string(in.a) + " to itself");
    if (!(in.stiffness > 0.0) || !std::isfinite(in.stiffness))
      throw InputError(ErrorCode::bad_number, "spring " + std::to_string(s) + " has stiffness " +
                                                  std::to_string(in.stiffness) + " (must be > 0)");
    Spring spring;
    spring.a = in.a;
    spring.b = in.b;
    spring.rest = (model.points[in.a] - model.points[in.b]).norm();
    spring.stiffness = in.stiffness;
    system.springs.push_back(spring);
  }
  return system;
}

ThesisModel with_positions(const ThesisModel& model, const std::vector<Vec3>& positions) {
  FASCICLE_CHECK(positions.size() == model.points.size(), "position count differs from model");
  ThesisModel out = model;
  out.points = positions;
  return out;
}

}  // namespace fascicle::springs
