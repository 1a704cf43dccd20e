#include "fibres/decompose_options_json.h"

#include "geometry/errors.h"

#include <algorithm>
#include <cstdint>
#include <initializer_list>
#include <limits>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

namespace fascicle {

namespace {

using springs::Acceleration;
using springs::DampingMode;
using springs::SettleOptions;
using springs::SolverKind;
using springs::SpringModel;
using springs::StaticMethod;
using springs::TemplateKind;

// ---- enum names (the command line's) ----

template <class E>
using NameTable = std::vector<std::pair<E, const char*>>;

// The table of `all` named by the project's own name function, so that the names stay the
// command line's.
template <class E, class Name>
NameTable<E> table_of(std::initializer_list<E> all, Name name) {
  NameTable<E> out;
  for (E e : all) out.emplace_back(e, name(e));
  return out;
}

const NameTable<SphereMethod>& names(SphereMethod) {
  static const NameTable<SphereMethod> t =
      table_of({SphereMethod::tutte, SphereMethod::relax}, [](SphereMethod e) { return to_string(e); });
  return t;
}
const NameTable<SphereStart>& names(SphereStart) {
  static const NameTable<SphereStart> t = table_of(
      {SphereStart::automatic, SphereStart::tube, SphereStart::progressive, SphereStart::stereographic},
      [](SphereStart e) { return to_string(e); });
  return t;
}
const NameTable<TemplateKind>& names(TemplateKind) {
  static const NameTable<TemplateKind> t =
      table_of({TemplateKind::parallel, TemplateKind::pennate, TemplateKind::curved, TemplateKind::fanned,
                TemplateKind::rectus, TemplateKind::unipennate, TemplateKind::bipennate},
               springs::template_name);
  return t;
}
const NameTable<RestShape>& names(RestShape) {
  static const NameTable<RestShape> t =
      table_of({RestShape::zero, RestShape::tension, RestShape::template_}, rest_shape_name);
  return t;
}
const NameTable<SolverKind>& names(SolverKind) {
  static const NameTable<SolverKind> t =
      table_of({SolverKind::verlet, SolverKind::static_equilibrium}, springs::solver_name);
  return t;
}
const NameTable<springs::Backend>& names(springs::Backend) {
  static const NameTable<springs::Backend> t = table_of(
      {springs::Backend::automatic, springs::Backend::structured, springs::Backend::general}, springs::backend_name);
  return t;
}
// These three have no name function of their own.
const NameTable<DampingMode>& names(DampingMode) {
  static const NameTable<DampingMode> t = {
      {DampingMode::estimate, "estimate"}, {DampingMode::critical, "critical"}, {DampingMode::value, "value"}};
  return t;
}
const NameTable<StaticMethod>& names(StaticMethod) {
  static const NameTable<StaticMethod> t = {{StaticMethod::momentum, "momentum"},
                                            {StaticMethod::newton, "newton"},
                                            {StaticMethod::local_global, "local-global"},
                                            {StaticMethod::multigrid, "multigrid"}};
  return t;
}
const NameTable<Acceleration>& names(Acceleration) {
  static const NameTable<Acceleration> t = {{Acceleration::none, "none"}, {Acceleration::anderson, "anderson"}};
  return t;
}

// ---- the fields of each options struct, in declaration order ----

template <class V>
void fields(SphereMapOptions& o, V& v) {
  v("method", o.method);
  v("start", o.start);
  v("progressive_max_valence", o.progressive_max_valence);
  v("progressive_relax_rounds", o.progressive_relax_rounds);
  v("anisotropic", o.anisotropic);
  v("tube_elongation", o.tube_elongation);
  v("reweight_rounds", o.reweight_rounds);
  v("reweight_exponent", o.reweight_exponent);
  v("reweight_target", o.reweight_target);
  v("untangle_sweeps", o.untangle_sweeps);
  v("mobius_steps", o.mobius_steps);
  v("mobius_tolerance", o.mobius_tolerance);
  v("balance_sweeps", o.balance_sweeps);
  v("balance_tolerance", o.balance_tolerance);
  v("relax_threshold", o.relax_threshold);
  v("relax_max_iterations", o.relax_max_iterations);
  v("relax_restarts", o.relax_restarts);
  v("relax_threshold_lowerings", o.relax_threshold_lowerings);
  v("seed", o.seed);
}

template <class V>
void fields(AttachmentOptions& o, V& v) {
  v("max_landmark_distance", o.max_landmark_distance);
  v("end_fraction", o.end_fraction);
  v("connected_ends", o.connected_ends);
  v("max_end_fraction", o.max_end_fraction);
  v("connect_margin", o.connect_margin);
  v("max_point_spacing", o.max_point_spacing);
}

template <class V>
void fields(StripOptions& o, V& v) {
  v("join", o.join);
  v("max_gap", o.max_gap);
  v("step", o.step);
  v("max_points", o.max_points);
}

template <class V>
void fields(PlacementOptions& o, V& v) {
  v("region_radius", o.region_radius);
  v("region_margin", o.region_margin);
  v("azimuth_bins", o.azimuth_bins);
  v("min_band", o.min_band);
  v("max_face_depth", o.max_face_depth);
  v("face_shrink_rounds", o.face_shrink_rounds);
  v("band_by_length", o.band_by_length);
  v("bend_step_deg", o.bend_step_deg);
  v("meridian_rings", o.meridian_rings);
  v("corner_twist_deg", o.corner_twist_deg);
  v("edge_corner_twist_deg", o.edge_corner_twist_deg);
  v("flat_section_aspect", o.flat_section_aspect);
  v("even_perimeter", o.even_perimeter);
  v("landmark_centre_keep", o.landmark_centre_keep);
}

template <class V>
void fields(PennateOptions& o, V& v) {
  v("pennation_deg", o.pennation_deg);
  v("area_density", o.area_density);
  v("smoothing_steps", o.smoothing_steps);
  v("smoothing_weight", o.smoothing_weight);
}

template <class V>
void fields(SettleOptions& o, V& v) {
  v("solver", o.solver);
  v("tolerance", o.tolerance);
  v("max_iterations", o.max_iterations);
  v("backend", o.backend);
  v("portable_loop", o.portable_loop);
  v("mass", o.mass);
  v("damping_mode", o.damping_mode);
  v("damping", o.damping);
  v("dt", o.dt);
  v("energy_interval", o.energy_interval);
  v("energy_growth_bound", o.energy_growth_bound);
  v("record_energy", o.record_energy);
  v("static_method", o.static_method);
  v("acceleration", o.acceleration);
  v("anderson_window", o.anderson_window);
  v("multigrid_step", o.multigrid_step);
  v("multigrid_harmonic_start", o.multigrid_harmonic_start);
  v("multigrid_directional", o.multigrid_directional);
  v("multigrid_smoothing_steps", o.multigrid_smoothing_steps);
  v("coarse_start_points", o.coarse_start_points);
  v("coarse_start_tolerance", o.coarse_start_tolerance);
  v("coarse_start_perturbation", o.coarse_start_perturbation);
  v("multigrid_coarsest_points", o.multigrid_coarsest_points);
}

template <class V>
void fields(UntangleOptions& o, V& v) {
  v("lambda", o.lambda);
  v("history", o.history);
  v("stage_iterations", o.stage_iterations);
  v("max_stages", o.max_stages);
  v("stall_stages", o.stall_stages);
  v("min_sigma", o.min_sigma);
  v("polish_iterations", o.polish_iterations);
  v("min_det", o.min_det);
  v("keep_best", o.keep_best);
}

template <class V>
void fields(LatticeUntangleOptions& o, V& v) {
  v("solver", o.solver);
  v("iterations", o.iterations);
  v("end_anchor_weight", o.end_anchor_weight);
  v("end_shift", o.end_shift);
  v("free_ring", o.free_ring);
  v("ring_depth", o.ring_depth);
  v("ring_weight", o.ring_weight);
  v("end_area_margin", o.end_area_margin);
  v("contact_weight", o.contact_weight);
  v("sliding_contact", o.sliding_contact);
  v("pin_search", o.pin_search);
  v("contact_rounds", o.contact_rounds);
  v("contact_stall_rounds", o.contact_stall_rounds);
  v("fold_stall_needs_outside_stall", o.fold_stall_needs_outside_stall);
  v("pin_rounds", o.pin_rounds);
  v("contact_depth", o.contact_depth);
  v("containment_energy", o.containment_energy);
  v("containment_energy_everywhere", o.containment_energy_everywhere);
  v("containment_margin", o.containment_margin);
  v("containment_band", o.containment_band);
  v("across_spacing", o.across_spacing);
}

template <class V>
void fields(FibreSmoothingOptions& o, V& v) {
  v("steps", o.steps);
  v("weight", o.weight);
  v("max_turning_deg", o.max_turning_deg);
}

template <class V>
void fields(SegmentContainmentOptions& o, V& v) {
  v("sweeps", o.sweeps);
  v("margin", o.margin);
  v("samples", o.samples);
  v("steps", o.steps);
  v("max_shift", o.max_shift);
  v("patch_radius", o.patch_radius);
}

template <class V>
void fields(ArchitectureOptions& o, V& v) {
  v("metres_per_unit", o.metres_per_unit);
  v("specific_tension", o.specific_tension);
}

template <class V>
void fields(CheckOptions& o, V& v) {
  v("coverage_samples", o.coverage_samples);
  v("seed", o.seed);
  v("end_tolerance", o.end_tolerance);
  v("min_inside_fraction", o.min_inside_fraction);
  v("max_inverted_cells", o.max_inverted_cells);
  v("max_coverage_p95", o.max_coverage_p95);
  v("max_attachment", o.max_attachment);
  v("segment_tolerance", o.segment_tolerance);
  v("max_crossing_segments", o.max_crossing_segments);
  v("excursion_samples", o.excursion_samples);
  v("max_turning_angle_deg", o.max_turning_angle_deg);
  v("end_region_radius", o.end_region_radius);
  v("end_samples", o.end_samples);
  v("min_end_coverage", o.min_end_coverage);
  v("outside_listed", o.outside_listed);
}

template <class V>
void fields(TryPolicy& o, V& v) {
  v("second_try", o.second_try);
  v("even_layers_ratio", o.even_layers_ratio);
}

template <class V>
void fields(DecomposeOptions& o, V& v) {
  v("sphere", o.sphere);
  v("attachments", o.attachments);
  v("strip", o.strip);
  v("placement", o.placement);
  v("template", o.kind);
  v("pennate", o.pennate);
  v("fibres", o.fibres);
  v("resolution", o.resolution);
  v("model", o.model);
  v("rest", o.rest);
  v("harmonic_direct_points", o.harmonic_direct_points);
  v("map_faces", o.map_faces);
  v("settle", o.settle);
  v("backend", o.backend);
  v("cast_rounds", o.cast_rounds);
  v("cast_rim", o.cast_rim);
  v("cast_by_azimuth", o.cast_by_azimuth);
  v("soft_contact_rounds", o.soft_contact_rounds);
  v("contact_rounds", o.contact_rounds);
  v("contact_depth", o.contact_depth);
  v("untangle_cells", o.untangle_cells);
  v("untangle", o.untangle);
  v("contact_segments", o.contact_segments);
  v("smoothing", o.smoothing);
  v("contain_segments", o.contain_segments);
  v("segments", o.segments);
  v("align_ends", o.align_ends);
  v("architecture", o.architecture);
  v("check", o.check);
  v("placement_end_share", o.placement_end_share);
  v("edge_cell", o.edge_cell);
  v("tries", o.tries);
}

// Whether T is an options struct with fields() above.
struct Probe {
  template <class T>
  void operator()(const char*, T&) {}
};
template <class T, class = void>
struct HasFields : std::false_type {};
template <class T>
struct HasFields<T, std::void_t<decltype(fields(std::declval<T&>(), std::declval<Probe&>()))>> : std::true_type {};

// ---- to JSON ----

template <class T>
nlohmann::json encode(const T& value);

struct Writer {
  nlohmann::json& out;
  template <class T>
  void operator()(const char* key, T& value) {
    out[key] = encode(value);
  }
};

template <class T>
nlohmann::json encode(const T& value) {
  if constexpr (HasFields<T>::value) {
    nlohmann::json out = nlohmann::json::object();
    Writer writer{out};
    T copy = value;  // fields() takes a mutable struct; writing reads only
    fields(copy, writer);
    return out;
  } else if constexpr (std::is_same_v<T, SpringModel>) {
    return static_cast<int>(value);
  } else if constexpr (std::is_enum_v<T>) {
    for (const auto& [e, name] : names(T{}))
      if (e == value) return name;
    return static_cast<int>(value);  // not reached: every enumerator has a name
  } else {
    return value;  // bool, number, string
  }
}

// ---- from JSON ----

[[noreturn]] void bad(const std::string& path, const std::string& what) {
  throw OptionError("tuning: " + path + " " + what);
}

template <class T>
void decode(const nlohmann::json& j, T& value, const std::string& path);

struct Reader {
  const nlohmann::json& in;
  std::string path;
  std::vector<std::string> keys;  // the settings of this struct, to find keys that are none
  template <class T>
  void operator()(const char* key, T& value) {
    keys.emplace_back(key);
    const auto it = in.find(key);
    if (it != in.end()) decode(*it, value, path.empty() ? std::string(key) : path + "." + key);
  }
};

template <class T>
void decode(const nlohmann::json& j, T& value, const std::string& path) {
  if constexpr (HasFields<T>::value) {
    if (!j.is_object()) bad(path.empty() ? std::string("(the file)") : path, "must be an object of settings");
    Reader reader{j, path, {}};
    fields(value, reader);
    for (const auto& item : j.items())
      if (std::find(reader.keys.begin(), reader.keys.end(), item.key()) == reader.keys.end())
        bad(path.empty() ? item.key() : path + "." + item.key(), "is not a setting");
  } else if constexpr (std::is_same_v<T, SpringModel>) {
    if (!j.is_number_integer() || (j.get<long long>() != 6 && j.get<long long>() != 26))
      bad(path, "must be 6 or 26, got " + j.dump());
    value = static_cast<SpringModel>(j.get<int>());
  } else if constexpr (std::is_enum_v<T>) {
    std::string valid;
    for (const auto& [e, name] : names(T{})) {
      if (j.is_string() && j.get<std::string>() == name) {
        value = e;
        return;
      }
      valid += (valid.empty() ? "" : ", ") + std::string(name);
    }
    bad(path, "must be one of " + valid + ", got " + j.dump());
  } else if constexpr (std::is_same_v<T, bool>) {
    if (!j.is_boolean()) bad(path, "must be true or false, got " + j.dump());
    value = j.get<bool>();
  } else if constexpr (std::is_integral_v<T>) {
    if (!j.is_number_integer()) bad(path, "must be an integer, got " + j.dump());
    if (j.is_number_unsigned()) {
      const auto v = j.get<unsigned long long>();
      if (v > static_cast<unsigned long long>(std::numeric_limits<T>::max())) bad(path, "is too large: " + j.dump());
      value = static_cast<T>(v);
    } else {
      const auto v = j.get<long long>();
      if (v < static_cast<long long>(std::numeric_limits<T>::min()) ||
          (v > 0 && static_cast<unsigned long long>(v) > static_cast<unsigned long long>(std::numeric_limits<T>::max())))
        bad(path, "is out of range: " + j.dump());
      value = static_cast<T>(v);
    }
  } else if constexpr (std::is_floating_point_v<T>) {
    if (!j.is_number()) bad(path, "must be a number, got " + j.dump());
    value = j.get<T>();
  } else {
    static_assert(std::is_same_v<T, std::string>, "a setting of a type decode() does not know");
    if (!j.is_string()) bad(path, "must be a string, got " + j.dump());
    value = j.get<std::string>();
  }
}

// `into` with every leaf of `given` that differs from `reference` (same shapes).
void overlay_changes(nlohmann::json& into, const nlohmann::json& reference, const nlohmann::json& given) {
  for (const auto& item : given.items()) {
    const nlohmann::json& ref = reference.at(item.key());
    if (item.value().is_object())
      overlay_changes(into[item.key()], ref, item.value());
    else if (item.value() != ref)
      into[item.key()] = item.value();
  }
}

}  // namespace

nlohmann::json decompose_options_json(const DecomposeOptions& options) { return encode(options); }

DecomposeOptions apply_tuning(DecomposeOptions options, const nlohmann::json& tuning) {
  decode(tuning, options, "");
  return options;
}

DecomposeOptions tune_options(const DecomposeOptions& reference, const DecomposeOptions& given,
                              const nlohmann::json& tuning) {
  nlohmann::json tuned = decompose_options_json(apply_tuning(reference, tuning));
  overlay_changes(tuned, decompose_options_json(reference), decompose_options_json(given));
  return apply_tuning(given, tuned);  // every setting; `given`'s progress stays
}

}  // namespace fascicle
