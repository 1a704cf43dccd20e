#pragma once
/// \file fibre_template.h
/// Fibre templates: parametric families of muscle fibres in the unit cube [0,1]^3, after
/// Blemker & Delp 2005, "Three-dimensional representation of complex muscle architectures and
/// geometries" (Ann. Biomed. Eng. 33(5)), who map fibres of a unit-cube template into a muscle,
/// and the thesis's use of them (Zeleny 2011, ch. 5.2; ../shared/docs/METHOD.md).
///
/// A template point is addressed by (r, s, t) in [0,1]^3: r and s choose the fibre, t runs along
/// it from the origin area (t = 0) to the insertion area (t = 1). Every family maps [0,1]^3 into
/// the unit cube, is continuous in t and (except `rectus` and `bipennate` across r = 1/2) in r and
/// s, and its fibres do not cross. The formulas are written out in docs/templates.md.
///
/// Two families are pennate in the muscle (`unipennate`, `bipennate`): their fibres cross the cube
/// from an aponeurosis face along it (x = 0, or x = 0 and 1) to the opposite face (x = 1) or a
/// central sheet (x = 1/2), rising in z as they go, so that they are as long as the muscle is
/// thick, not as it is long. A decomposition settles the parallel lattice (the map of the cube
/// into the muscle) and draws these fibres through it (fibres/pennate_fibres.h).

#include "geometry/mesh.h"

#include <string>
#include <vector>

namespace fascicle::springs {

/// The seven template families.
enum class TemplateKind {
  parallel,    ///< fibres straight from face z = 0 to face z = 1 (sartorius)
  pennate,     ///< areas on opposite faces, offset in x, so fibres run obliquely (vastus medialis)
  curved,      ///< both areas on face z = 0, fibres arc through the volume (iliacus)
  fanned,      ///< broad origin on z = 0 converging to a narrow insertion on z = 1 (gluteus)
  rectus,      ///< bipennate: from a central aponeurosis x = 1/2 obliquely to both sides x = 0, 1
  unipennate,  ///< across the cube from aponeurosis x = 0 to x = 1, rising in z (soleus, vastus lateralis)
  bipennate,   ///< from both sides x = 0, 1 to a central sheet x = 1/2, rising in z (rectus femoris)
};

/// Whether a kind's fibres cross the cube between faces along it (unipennate, bipennate): its
/// lattice is the parallel one, and its fibres are drawn through the settled lattice.
bool crosses_lattice(TemplateKind kind);

/// The rise in z of a pennate fibre per unit of x that template_point() draws (default 0.5).
inline constexpr double kDefaultAdvance = 0.5;

/// Point of a crossing family (crosses_lattice(kind)) whose fibres rise by `advance` (> 0) in z
/// per unit of x: the fibre (r, s) lies in the plane y = s; r sets its start in z, so that the
/// fibres' lines cover the plane's square, each at least half as long in it as the family's
/// longest (z0 in [-a + h, 1 - h], a the rise over the crossing, h = min(a, 1) / 2); the
/// part of the line outside 0 <= z <= 1 is cut off, and t runs along what is left. For other
/// kinds, template_point(kind, r, s, t).
Vec3 pennate_point(TemplateKind kind, double advance, double r, double s, double t);

/// All kinds, in declaration order.
const std::vector<TemplateKind>& all_template_kinds();

/// The command-line name of a kind ("parallel", ...).
const char* template_name(TemplateKind kind);

/// Parses a kind name. Throws OptionError naming the value and listing the valid names.
TemplateKind parse_template_kind(const std::string& name);

/// Point of the template at parameters (r, s, t), each in [0,1] (values outside are clamped).
/// Returns a position in the unit cube (unitless template coordinates).
Vec3 template_point(TemplateKind kind, double r, double s, double t);

/// An attachment area: a union of axis-aligned rectangles, each flat in one axis (lo == hi there).
struct TemplateArea {
  struct Rect {
    Vec3 lo, hi;  ///< opposite corners, lo <= hi componentwise
  };
  std::vector<Rect> parts;
  /// True when `p` lies in one of the rectangles, to within `tolerance` (template units).
  bool contains(const Vec3& p, double tolerance = 1e-12) const;
};

/// The origin area of a template: every template_point(kind, r, s, 0) lies in it (for the crossing
/// families, every pennate_point(kind, advance, r, s, 0); advance > 0).
TemplateArea origin_area(TemplateKind kind, double advance = kDefaultAdvance);

/// The insertion area of a template: every template_point(kind, r, s, 1) lies in it (for the
/// crossing families, every pennate_point(kind, advance, r, s, 1); advance > 0).
TemplateArea insertion_area(TemplateKind kind, double advance = kDefaultAdvance);

}  // namespace fascicle::springs
