#pragma once
/// \file fibre_template.h
/// Fibre templates: parametric families of muscle fibres in the unit cube [0,1]^3, after
/// Blemker & Delp 2005, "Three-dimensional representation of complex muscle architectures and
/// geometries" (Ann. Biomed. Eng. 33(5)), who map fibres of a unit-cube template into a muscle,
/// and the thesis's use of them (Zeleny 2011, ch. 5.2; ../shared/docs/METHOD.md).
///
/// A template point is addressed by (r, s, t) in [0,1]^3: r and s choose the fibre, t runs along
/// it from the origin area (t = 0) to the insertion area (t = 1). Every family maps [0,1]^3 into
/// the unit cube, is continuous in t and (except `rectus` across r = 1/2) in r and s, and its
/// fibres do not cross. The formulas are written out in docs/templates.md.

#include "geometry/mesh.h"

#include <string>
#include <vector>

namespace fascicle::springs {

/// The five template families.
enum class TemplateKind {
  parallel,  ///< fibres straight from face z = 0 to face z = 1 (sartorius)
  pennate,   ///< areas on opposite faces, offset in x, so fibres run obliquely (vastus medialis)
  curved,    ///< both areas on face z = 0, fibres arc through the volume (iliacus)
  fanned,    ///< broad origin on z = 0 converging to a narrow insertion on z = 1 (gluteus)
  rectus,    ///< bipennate: from a central aponeurosis x = 1/2 obliquely to both sides x = 0, 1
};

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

/// The origin area of a template: every template_point(kind, r, s, 0) lies in it.
TemplateArea origin_area(TemplateKind kind);

/// The insertion area of a template: every template_point(kind, r, s, 1) lies in it.
TemplateArea insertion_area(TemplateKind kind);

}  // namespace fascicle::springs
