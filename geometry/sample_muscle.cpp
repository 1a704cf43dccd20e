#include "geometry/sample_muscle.h"

#include "geometry/errors.h"
#include "geometry/primitives.h"

#include <cmath>
#include <cstdio>
#include <string>

namespace fascicle {

namespace {

constexpr double kPi = 3.14159265358979323846;

[[noreturn]] void bad(const char* field, double value, const char* rule) {
  char buffer[64];
  std::snprintf(buffer, sizeof(buffer), "%.17g", value);
  throw OptionError(std::string("sample ") + field + " = " + buffer + " is invalid: " + rule);
}

}  // namespace

void SampleOptions::validate() const {
  auto positive = [](const char* field, double v) {
    if (!(std::isfinite(v) && v > 0)) bad(field, v, "must be finite and positive");
  };
  positive("length", length);
  positive("belly_radius", belly_radius);
  positive("tendon_radius", tendon_radius);
  if (!(tendon_radius < belly_radius)) bad("tendon_radius", tendon_radius, "must be below belly_radius");
  if (!(2 * belly_radius < length)) bad("belly_radius", belly_radius, "must be below half the length");
  if (!(ellipticity > 0 && ellipticity <= 1)) bad("ellipticity", ellipticity, "must be in (0, 1]");
  if (!(std::isfinite(axis_bend) && std::abs(axis_bend) <= 0.25 * length))
    bad("axis_bend", axis_bend, "must be finite and at most length / 4 in size");
  if (rings < 3 || rings > 10000) bad("rings", rings, "must be in [3, 10000]");
  if (segments < 3 || segments > 10000) bad("segments", segments, "must be in [3, 10000]");
  if (holes < 0 || holes > 100) bad("holes", holes, "must be in [0, 100]");
  if (hole_faces < 1 || hole_faces > 10000) bad("hole_faces", hole_faces, "must be in [1, 10000]");
  if (flipped_faces < 1 || flipped_faces > 10000) bad("flipped_faces", flipped_faces, "must be in [1, 10000]");
  if (!(duplicate_fraction >= 0 && duplicate_fraction <= 1))
    bad("duplicate_fraction", duplicate_fraction, "must be in [0, 1]");
}

TriangleMesh make_fusiform_muscle(const SampleOptions& options) {
  options.validate();
  const double L = options.length, h = options.axis_bend;
  // Axis c(s) = (L (s - 1/2), 0, 4 h s (1 - s)): a parabola through both tips, bowed by h.
  auto axis = [&](double s) { return Vec3(L * (s - 0.5), 0.0, 4.0 * h * s * (1.0 - s)); };
  auto tangent = [&](double s) { return Vec3(L, 0.0, 4.0 * h * (1.0 - 2.0 * s)).normalized(); };
  auto radius = [&](double s) {
    const double sine = std::sin(kPi * s);
    double r = options.tendon_radius + (options.belly_radius - options.tendon_radius) * sine * sine;
    // Round the tips: a quarter circle of the tendon radius over the last tendon_radius of length.
    const double d = std::min(s, 1.0 - s) * L / options.tendon_radius;
    if (d < 1.0) r *= std::sqrt(std::max(0.0, 1.0 - (1.0 - d) * (1.0 - d)));
    return r;
  };
  std::vector<std::vector<Vec3>> rings;
  rings.reserve(static_cast<std::size_t>(options.rings));
  const Vec3 side(0.0, 1.0, 0.0);  // perpendicular to the axis everywhere (the axis bends in xz)
  for (int i = 1; i <= options.rings; ++i) {
    const double s = 0.5 * (1.0 - std::cos(kPi * i / (options.rings + 1)));
    const Vec3 c = axis(s), t = tangent(s);
    const Vec3 up = t.cross(side);  // in the bending plane, normal to the axis
    const double r = radius(s);
    std::vector<Vec3> ring(static_cast<std::size_t>(options.segments));
    for (int j = 0; j < options.segments; ++j) {
      const double a = 2.0 * kPi * j / options.segments;
      ring[static_cast<std::size_t>(j)] = c + r * (std::cos(a) * up + options.ellipticity * std::sin(a) * side);
    }
    rings.push_back(std::move(ring));
  }
  return make_closed_tube(rings, axis(0.0), axis(1.0));
}

PolygonSoup make_sample(const SampleOptions& options, DefectLog* log) {
  PolygonSoup soup = to_soup(make_fusiform_muscle(options));
  if (!options.defects) return soup;
  const std::uint64_t seed = options.seed;
  if (options.holes > 0) {
    DefectParams p;
    p.count = options.holes;
    p.patch_faces = options.hole_faces;
    soup = inject(soup, DefectKind::holes, derive_seed(seed, 1), p, log);
  }
  DefectParams flip;
  flip.patch_faces = options.flipped_faces;
  soup = inject(soup, DefectKind::flipped_patch, derive_seed(seed, 2), flip, log);
  soup = inject(soup, DefectKind::pinched_vertex, derive_seed(seed, 3), DefectParams{}, log);
  soup = inject(soup, DefectKind::stray_component, derive_seed(seed, 4), DefectParams{}, log);
  if (options.duplicate_fraction > 0) {
    DefectParams dup;
    dup.fraction = options.duplicate_fraction;
    soup = inject(soup, DefectKind::duplicate_vertices, derive_seed(seed, 5), dup, log);
  }
  return soup;
}

}  // namespace fascicle
