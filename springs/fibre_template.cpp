// Fibre templates in the unit cube (Blemker & Delp 2005; Zeleny 2011 ch. 5.2). The formulas are
// documented in docs/templates.md; keep the two in step.

#include "springs/fibre_template.h"

#include "geometry/errors.h"

#include <algorithm>
#include <cmath>

namespace fascicle::springs {
namespace {

constexpr double kPi = 3.14159265358979323846;

double clamp01(double v) { return std::min(1.0, std::max(0.0, v)); }

// Curved: innermost and outermost arc radius.
constexpr double kCurvedInner = 0.1;
constexpr double kCurvedOuter = 0.5;
// Fanned: width of the square insertion area, centred on face z = 1.
constexpr double kFanWidth = 0.2;
// Rectus: fibres drop this much in z between the aponeurosis and the side.
constexpr double kRectusDrop = 0.25;

}  // namespace

const std::vector<TemplateKind>& all_template_kinds() {
  static const std::vector<TemplateKind> kinds = {
      TemplateKind::parallel, TemplateKind::pennate,    TemplateKind::curved,   TemplateKind::fanned,
      TemplateKind::rectus,   TemplateKind::unipennate, TemplateKind::bipennate};
  return kinds;
}

const char* template_name(TemplateKind kind) {
  switch (kind) {
    case TemplateKind::parallel: return "parallel";
    case TemplateKind::pennate: return "pennate";
    case TemplateKind::curved: return "curved";
    case TemplateKind::fanned: return "fanned";
    case TemplateKind::rectus: return "rectus";
    case TemplateKind::unipennate: return "unipennate";
    case TemplateKind::bipennate: return "bipennate";
  }
  return "unknown";
}

TemplateKind parse_template_kind(const std::string& name) {
  for (TemplateKind kind : all_template_kinds())
    if (name == template_name(kind)) return kind;
  throw OptionError("template: unknown kind '" + name +
                    "' (valid: parallel, pennate, curved, fanned, rectus, unipennate, bipennate)");
}

bool crosses_lattice(TemplateKind kind) { return kind == TemplateKind::unipennate || kind == TemplateKind::bipennate; }

Vec3 pennate_point(TemplateKind kind, double advance, double r, double s, double t) {
  if (!crosses_lattice(kind)) return template_point(kind, r, s, t);
  r = clamp01(r);
  s = clamp01(s);
  t = clamp01(t);
  // A fibre runs from x = from to x = to (width w) and rises by a = advance w over it. Its start
  // z0 spans [-a + h, 1 - h], h = min(a, 1) / 2: the lines cover the square, each keeps at least
  // half the length in it of the family's longest after the cut to 0 <= z <= 1 (shorter ones
  // would run along the end faces, on the surface), and a steep family (a > 1) spreads across x.
  double from = 0.0, to = 1.0, rho = r;
  if (kind == TemplateKind::bipennate) {
    // Fibres with r < 1/2 leave side x = 0, the others side x = 1; both end on the sheet x = 1/2.
    from = r < 0.5 ? 0.0 : 1.0;
    to = 0.5;
    rho = r < 0.5 ? 2.0 * r : 2.0 * r - 1.0;
  }
  const double a = advance * std::abs(to - from), h = 0.5 * std::min(a, 1.0);
  const double z0 = -a + h + rho * (1.0 + a - 2.0 * h);
  const double lo = std::max(0.0, -z0 / a), hi = std::min(1.0, (1.0 - z0) / a);
  const double tau = lo + t * (hi - lo);
  return Vec3(from + (to - from) * tau, s, clamp01(z0 + a * tau));
}

Vec3 template_point(TemplateKind kind, double r, double s, double t) {
  r = clamp01(r);
  s = clamp01(s);
  t = clamp01(t);
  switch (kind) {
    case TemplateKind::parallel: return Vec3(r, s, t);
    case TemplateKind::pennate:
      // Origin x in [0, 1/2] on z = 0, insertion x in [1/2, 1] on z = 1: every fibre is the
      // same oblique segment shifted in x (pennation angle 26.6 degrees from z).
      return Vec3(0.5 * r + 0.5 * t, s, t);
    case TemplateKind::curved: {
      // Nested half-ellipses over the line x = 1/2 of face z = 0; r picks the radius.
      const double radius = kCurvedInner + (kCurvedOuter - kCurvedInner) * r;
      const double angle = kPi * (1.0 - t);
      return Vec3(0.5 + radius * std::cos(angle), s, 2.0 * radius * std::sin(angle));
    }
    case TemplateKind::fanned: {
      const double lo = 0.5 - 0.5 * kFanWidth;
      return Vec3((1.0 - t) * r + t * (lo + kFanWidth * r), (1.0 - t) * s + t * (lo + kFanWidth * s), t);
    }
    case TemplateKind::rectus: {
      // The aponeurosis is the plane x = 1/2, z in [1/4, 1]. Fibres with r < 1/2 leave its lower
      // half towards side x = 0, the others leave its upper half towards side x = 1, each falling
      // by kRectusDrop. No two lattice points coincide (mirror-image fibres would share their
      // start), at the price of a jump of the end point across r = 1/2.
      const double z_start = kRectusDrop + (1.0 - kRectusDrop) * r;
      const double side = r < 0.5 ? 0.0 : 1.0;
      return Vec3(0.5 + (side - 0.5) * t, s, z_start - kRectusDrop * t);
    }
    case TemplateKind::unipennate:
    case TemplateKind::bipennate: return pennate_point(kind, kDefaultAdvance, r, s, t);
  }
  return Vec3(r, s, t);
}

bool TemplateArea::contains(const Vec3& p, double tolerance) const {
  for (const Rect& rect : parts) {
    bool inside = true;
    for (int axis = 0; axis < 3; ++axis)
      if (p[axis] < rect.lo[axis] - tolerance || p[axis] > rect.hi[axis] + tolerance) inside = false;
    if (inside) return true;
  }
  return false;
}

TemplateArea origin_area(TemplateKind kind, double advance) {
  switch (kind) {
    case TemplateKind::parallel:
    case TemplateKind::fanned: return {{{Vec3(0, 0, 0), Vec3(1, 1, 0)}}};
    case TemplateKind::pennate: return {{{Vec3(0, 0, 0), Vec3(0.5, 1, 0)}}};
    case TemplateKind::curved: return {{{Vec3(0.5 - kCurvedOuter, 0, 0), Vec3(0.5 - kCurvedInner, 1, 0)}}};
    case TemplateKind::rectus: return {{{Vec3(0.5, 0, kRectusDrop), Vec3(0.5, 1, 1)}}};
    // Starts on the side face (z0 >= 0, z <= 1 - h) and, cut at z = 0, at x <= 1 - h / a.
    case TemplateKind::unipennate: {
      const double h = 0.5 * std::min(advance, 1.0);
      return {{{Vec3(0, 0, 0), Vec3(0, 1, 1 - h)}, {Vec3(0, 0, 0), Vec3(1 - h / advance, 1, 0)}}};
    }
    case TemplateKind::bipennate: {
      const double a = 0.5 * advance, h = 0.5 * std::min(a, 1.0), cut = 0.5 * (1 - h / a);
      return {{{Vec3(0, 0, 0), Vec3(0, 1, 1 - h)},
               {Vec3(1, 0, 0), Vec3(1, 1, 1 - h)},
               {Vec3(0, 0, 0), Vec3(cut, 1, 0)},
               {Vec3(1 - cut, 0, 0), Vec3(1, 1, 0)}}};
    }
  }
  return {};
}

TemplateArea insertion_area(TemplateKind kind, double advance) {
  switch (kind) {
    case TemplateKind::parallel: return {{{Vec3(0, 0, 1), Vec3(1, 1, 1)}}};
    case TemplateKind::fanned: {
      const double lo = 0.5 - 0.5 * kFanWidth, hi = 0.5 + 0.5 * kFanWidth;
      return {{{Vec3(lo, lo, 1), Vec3(hi, hi, 1)}}};
    }
    case TemplateKind::pennate: return {{{Vec3(0.5, 0, 1), Vec3(1, 1, 1)}}};
    case TemplateKind::curved: return {{{Vec3(0.5 + kCurvedInner, 0, 0), Vec3(0.5 + kCurvedOuter, 1, 0)}}};
    case TemplateKind::rectus:
      return {{{Vec3(0, 0, 0), Vec3(0, 1, 1 - kRectusDrop)}, {Vec3(1, 0, 0), Vec3(1, 1, 1 - kRectusDrop)}}};
    // Ends on the far face or sheet (z0 + a <= 1, z >= h) and, cut at z = 1, past x = h / a.
    case TemplateKind::unipennate: {
      const double h = 0.5 * std::min(advance, 1.0);
      return {{{Vec3(1, 0, h), Vec3(1, 1, 1)}, {Vec3(h / advance, 0, 1), Vec3(1, 1, 1)}}};
    }
    case TemplateKind::bipennate: {
      const double a = 0.5 * advance, h = 0.5 * std::min(a, 1.0), cut = 0.5 * h / a;
      return {{{Vec3(0.5, 0, h), Vec3(0.5, 1, 1)}, {Vec3(cut, 0, 1), Vec3(1 - cut, 1, 1)}}};
    }
  }
  return {};
}

}  // namespace fascicle::springs
