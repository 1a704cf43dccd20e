#pragma once
/// \file template_plot.h
/// A picture of a fibre template as SVG text: an oblique (cabinet) projection of the unit cube,
/// a grid of fibres t -> template_point(kind, r, s, t), the origin area (red) and the insertion
/// area (green). Used for docs/templates.md until the renderer exists.

#include "springs/fibre_template.h"

#include <string>

namespace fascicle::springs {

/// SVG document (size `pixels` x `pixels`) of `kind` with fibres_r x fibres_s fibres, each drawn
/// through `samples` points (>= 2). Throws OptionError for counts below 2 (fibres 1 is allowed).
std::string template_svg(TemplateKind kind, int fibres_r = 6, int fibres_s = 3, int samples = 40, int pixels = 360);

}  // namespace fascicle::springs
