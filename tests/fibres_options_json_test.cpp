// Every setting of a decomposition as JSON and back (fibres/decompose_options_json.h): the report's
// "options" and the --tuning file.

#include "fibres/decompose_options_json.h"
#include "geometry/errors.h"

#include <catch2/catch.hpp>

#include <string>

using namespace fascicle;

namespace {

// Every leaf of `j`, as "a.b.c" paths with their values.
void leaves(const nlohmann::json& j, const std::string& path, std::vector<std::pair<std::string, nlohmann::json>>& out) {
  for (const auto& item : j.items()) {
    const std::string key = path.empty() ? item.key() : path + "." + item.key();
    if (item.value().is_object())
      leaves(item.value(), key, out);
    else
      out.emplace_back(key, item.value());
  }
}

// `j` with the leaf at `path` set to `value`.
nlohmann::json with_leaf(nlohmann::json j, const std::string& path, const nlohmann::json& value) {
  nlohmann::json* at = &j;
  std::size_t begin = 0;
  for (std::size_t dot; (dot = path.find('.', begin)) != std::string::npos; begin = dot + 1)
    at = &(*at)[path.substr(begin, dot - begin)];
  (*at)[path.substr(begin)] = value;
  return j;
}

// Another valid value of the same kind as `v`.
nlohmann::json changed(const std::string& path, const nlohmann::json& v) {
  if (v.is_boolean()) return !v.get<bool>();
  if (path == "model") return v == 6 ? 26 : 6;
  if (v.is_number_integer()) return v.get<long long>() + 1;
  if (v.is_number()) return v.get<double>() * 0.5 + 0.125;
  if (path == "template") return v == "parallel" ? "fanned" : "parallel";
  if (path == "rest") return v == "zero" ? "tension" : "zero";
  if (path == "backend") return v == "cpu" ? "gl" : "cpu";
  if (path == "sphere.method") return v == "tutte" ? "relax" : "tutte";
  if (path == "sphere.start") return v == "tube" ? "progressive" : "tube";
  if (path == "settle.solver") return v == "verlet" ? "static" : "verlet";
  if (path == "settle.backend") return v == "general" ? "structured" : "general";
  if (path == "settle.damping_mode") return v == "value" ? "critical" : "value";
  if (path == "settle.static_method") return v == "newton" ? "multigrid" : "newton";
  if (path == "settle.acceleration") return v == "none" ? "anderson" : "none";
  FAIL("no other value known for " << path);
  return v;
}

}  // namespace

TEST_CASE("every setting goes to JSON and each one comes back from it", "[fibres][options]") {
  const DecomposeOptions defaults;
  const nlohmann::json j = decompose_options_json(defaults);
  CHECK(j.at("fibres") == 100);
  CHECK(j.at("template") == "parallel");
  CHECK(j.at("model") == 6);
  CHECK(j.at("settle").at("solver") == "static");
  CHECK(j.at("placement").at("max_face_depth") == 0.1);
  CHECK(j.at("check").at("max_crossing_segments") == -1);  // decompose's own check (default_check())
  CHECK(decompose_options_json(apply_tuning(defaults, j)) == j);
  CHECK(decompose_options_json(apply_tuning(defaults, nlohmann::json::object())) == j);
  // Each leaf set alone comes back changed, and nothing else does.
  std::vector<std::pair<std::string, nlohmann::json>> all;
  leaves(j, "", all);
  CHECK(all.size() > 140);
  for (const auto& [path, value] : all) {
    CAPTURE(path);
    const nlohmann::json expected = with_leaf(j, path, changed(path, value));
    CHECK(decompose_options_json(apply_tuning(defaults, expected)) == expected);
  }
}

TEST_CASE("a tuning file's unknown keys and wrong values are option errors naming them", "[fibres][options]") {
  const DecomposeOptions defaults;
  const auto error = [&](const nlohmann::json& tuning) {
    try {
      (void)apply_tuning(defaults, tuning);
    } catch (const OptionError& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  CHECK(error({{"placement", {{"max_face_deph", 0.5}}}}).find("placement.max_face_deph is not a setting") !=
        std::string::npos);
  CHECK(error({{"fibre", 10}}).find("fibre is not a setting") != std::string::npos);
  CHECK(error({{"fibres", 10.5}}).find("fibres must be an integer") != std::string::npos);
  CHECK(error({{"fibres", "10"}}).find("fibres must be an integer") != std::string::npos);
  CHECK(error({{"fibres", 1LL << 40}}).find("fibres is out of range") != std::string::npos);
  CHECK(error({{"sphere", {{"seed", -1}}}}).find("sphere.seed is out of range") != std::string::npos);
  CHECK(error({{"template", "fan"}}).find("template must be one of parallel,") != std::string::npos);
  CHECK(error({{"model", 7}}).find("model must be 6 or 26") != std::string::npos);
  CHECK(error({{"align_ends", 1}}).find("align_ends must be true or false") != std::string::npos);
  CHECK(error({{"settle", 3}}).find("settle must be an object") != std::string::npos);
  CHECK(error(nlohmann::json::array()).find("must be an object") != std::string::npos);
  // Values in range are the validation's business, after the tuning.
  const DecomposeOptions zero = apply_tuning(defaults, {{"fibres", 0}});
  CHECK(zero.fibres == 0);
  CHECK_THROWS_AS(zero.validate(), OptionError);
}

TEST_CASE("with a tuning file, the settings the command line changed win", "[fibres][options]") {
  const DecomposeOptions reference;
  DecomposeOptions given = reference;
  given.fibres = 64;                    // changed on the command line
  given.placement.max_face_depth = 0.3;
  const nlohmann::json tuning = {{"fibres", 144}, {"resolution", 19}, {"placement", {{"meridian_rings", true}}}};
  const DecomposeOptions out = tune_options(reference, given, tuning);
  CHECK(out.fibres == 64);
  CHECK(out.resolution == 19);
  CHECK(out.placement.max_face_depth == 0.3);
  CHECK(out.placement.meridian_rings);
  CHECK(out.placement.band_by_length == reference.placement.band_by_length);
  CHECK_THROWS_AS(tune_options(reference, given, {{"fibers", 1}}), OptionError);
}
