// Presets by anatomical name: template from the fibre arrangement, pennation from Ward et al. 2009.

#include "fibres/muscle_presets.h"

#include "geometry/errors.h"

namespace fascicle {

const std::vector<MusclePreset>& muscle_presets() {
  using springs::TemplateKind;
  const char* along_femur = "from the pelvis to a line along the femur (linea aspera)";
  static const std::vector<MusclePreset> presets = {
      {"adductor_brevis", TemplateKind::unipennate, 6.1, along_femur},
      {"adductor_longus", TemplateKind::unipennate, 7.1, along_femur},
      {"adductor_magnus", TemplateKind::unipennate, 15.5, along_femur},
      {"biceps_femoris_long_head", TemplateKind::unipennate, 11.6, "between proximal and distal aponeuroses"},
      {"biceps_femoris_short_head", TemplateKind::unipennate, 12.3, "from the linea aspera to the distal tendon"},
      {"extensor_digitorum_longus", TemplateKind::unipennate, 10.8,
       "from the fibula and membrane to a tendon along it"},
      {"extensor_hallucis_longus", TemplateKind::unipennate, 9.4, "from the fibula and membrane to a tendon along it"},
      {"gastrocnemius_lateral", TemplateKind::unipennate, 12.0, "from the proximal aponeurosis to the distal one"},
      {"gastrocnemius_medial", TemplateKind::unipennate, 9.9, "from the proximal aponeurosis to the distal one"},
      {"gluteus_maximus", TemplateKind::parallel, 21.9, "quadrilateral, coarse parallel fascicles"},
      {"gluteus_medius", TemplateKind::fanned, 20.5, "fan-shaped, converging on the greater trochanter"},
      {"gracilis", TemplateKind::parallel, 8.2, "strap"},
      {"iliacus", TemplateKind::fanned, 14.3, "fan-shaped, converging on the psoas tendon"},
      {"peroneus_longus", TemplateKind::bipennate, 14.1, "on both sides of a central tendon"},
      // Fascicles from each lumbar level, of similar length, insert obliquely onto one tendon
      // (Bogduk, Pearcy and Hadfield 1992, Clin Biomech 7:109-119).
      {"psoas", TemplateKind::unipennate, 10.6, "from the lumbar vertebrae onto its tendon"},
      {"rectus_femoris", TemplateKind::bipennate, 13.9, "on both sides of a central aponeurosis"},
      {"sartorius", TemplateKind::parallel, 1.3, "strap"},
      {"semimembranosus", TemplateKind::unipennate, 15.1, "between proximal and distal aponeuroses"},
      {"semitendinosus", TemplateKind::parallel, 12.9, "fusiform, with a tendinous intersection"},
      {"soleus", TemplateKind::bipennate, 28.3, "on both sides of a central intramuscular tendon"},
      {"tibialis_anterior", TemplateKind::bipennate, 9.6, "on both sides of a central aponeurosis"},
      {"vastus_intermedius", TemplateKind::unipennate, 4.5, "from the femoral shaft to the deep aponeurosis"},
      {"vastus_lateralis", TemplateKind::unipennate, 18.4, "from the femur to the superficial aponeurosis"},
      {"vastus_medialis", TemplateKind::unipennate, 29.6, "from the femur to the superficial aponeurosis"},
  };
  return presets;
}

const MusclePreset& muscle_preset(const std::string& name) {
  std::string names;
  for (const MusclePreset& preset : muscle_presets()) {
    if (preset.name == name) return preset;
    names += (names.empty() ? "" : ", ") + preset.name;
  }
  throw OptionError("muscle: no preset for '" + name + "' (presets: " + names + ")");
}

}  // namespace fascicle
