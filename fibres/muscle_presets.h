#pragma once
/// \file muscle_presets.h
/// Presets by anatomical name (`fascicle decompose --muscle NAME`): the template a muscle's fibre
/// arrangement calls for and its pennation, so that a user with a named muscle gets a sensible
/// architecture without knowing the templates. A preset holds anatomical facts only:
/// - the template from the fibre arrangement anatomy describes: fusiform and strap muscles
///   `parallel`; fan-shaped (convergent) muscles `fanned`; fibres that run from an aponeurosis or
///   a bony line along the muscle to the tendon on its other side `unipennate`; fibres on both
///   sides of a central tendon `bipennate`;
/// - the pennation: the cadaver mean of Ward et al. 2009, "Are current measurements of lower
///   extremity muscle architecture accurate?", Clin Orthop Relat Res 467:1074-1082 (21 cadavers).
/// Nothing in a preset is chosen from the fibre length it produces.
#include "springs/fibre_template.h"

#include <string>
#include <vector>

namespace fascicle {

/// One muscle's preset.
struct MusclePreset {
  std::string name;            ///< snake_case anatomical name, as in Ward et al. 2009
  springs::TemplateKind kind;  ///< template of its fibre arrangement
  double pennation_deg;        ///< Ward et al. 2009's mean pennation, degrees
  std::string arrangement;     ///< the arrangement in words, for reports and --help
};

/// Every preset, by name.
const std::vector<MusclePreset>& muscle_presets();

/// The preset called `name`. Throws OptionError naming the value and listing the names.
const MusclePreset& muscle_preset(const std::string& name);

}  // namespace fascicle
