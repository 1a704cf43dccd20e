// The pennate presets on the Visible Human muscles they are for: every run passes decompose's
// check and the whole fibre check (no segment out, turning at most 45 degrees, ends spread over
// the aponeuroses), at the preset's pennation. A sample of two in the unit tier, all of them in
// the corpus tier.
#include "tests/decompose_run.h"
#include "tests/test_common.h"

#include <catch2/catch.hpp>
#include <nlohmann/json.hpp>

#include <filesystem>
#include <string>
#include <utility>
#include <vector>

using namespace fascicle;

namespace {

// Visible Human files with a unipennate or bipennate preset (fibres/muscle_presets.h).
const std::vector<std::pair<std::string, std::string>>& pennate_muscles() {
  static const std::vector<std::pair<std::string, std::string>> muscles = {
      {"extra/visible-human/VHM_Left_Muscle_Soleus_smooth.stl", "soleus"},
      {"muscles/visible-human/VHF_Left/VHF_Left_Muscle_BicepsFemorisLong_smooth.stl", "biceps_femoris_long_head"},
      {"extra/visible-human/VHM_Left_Muscle_TibialisAnterior_smooth.stl", "tibialis_anterior"},
      {"muscles/visible-human/VHF_Left/VHF_Left_Muscle_AdductorMagnus_smooth.stl", "adductor_magnus"},
      {"muscles/visible-human/VHF_Left/VHF_Left_Muscle_PsoasMajor_smooth.stl", "psoas"},
      {"muscles/visible-human/VHF_Left/VHF_Left_Muscle_RectusFemoris_smooth.stl", "rectus_femoris"},
      {"muscles/visible-human/VHF_Left/VHF_Left_Muscle_Semimembranosus_smooth.stl", "semimembranosus"},
      {"muscles/visible-human/VHF_Left/VHF_Left_Muscle_VastusIntermedius_smooth.stl", "vastus_intermedius"},
      {"muscles/visible-human/VHF_Left/VHF_Left_Muscle_VastusLateralis_smooth.stl", "vastus_lateralis"},
      {"muscles/visible-human/VHF_Left/VHF_Left_Muscle_VastusMedialis_smooth.stl", "vastus_medialis"},
      {"muscles/visible-human/VHF_Right/VHF_Right_Muscle_BicepsFemorisShortHead_smooth.stl",
       "biceps_femoris_short_head"},
      {"muscles/visible-human/VHM_Left/VHM_Left_Muscle_AdductorMagnus_smooth.stl", "adductor_magnus"},
      {"muscles/visible-human/VHM_Left/VHM_Left_Muscle_BicepsFemorisLongus_smooth.stl", "biceps_femoris_long_head"},
      {"muscles/visible-human/VHM_Left/VHM_Left_Muscle_PsoasMajor_smooth.stl", "psoas"},
      {"muscles/visible-human/VHM_Left/VHM_Left_Muscle_RectusFemoris_smooth.stl", "rectus_femoris"},
      {"muscles/visible-human/VHM_Left/VHM_Left_Muscle_Semimembranosus_smooth.stl", "semimembranosus"},
      {"muscles/visible-human/VHM_Left/VHM_Left_Muscle_VastusIntermedius_smooth.stl", "vastus_intermedius"},
      {"muscles/visible-human/VHM_Left/VHM_Left_Muscle_VastusLateralis_smooth.stl", "vastus_lateralis"},
      {"muscles/visible-human/VHM_Left/VHM_Left_Muscle_VastusMedialis_smooth.stl", "vastus_medialis"},
  };
  return muscles;
}

void check_pennate(const std::string& file, const std::string& preset) {
  const std::string path = test::data_dir() + "/" + file;
  REQUIRE(std::filesystem::exists(path));
  test::TempDir dir;
  const nlohmann::json r = test::decompose_report(path, dir.path().string(), "--muscle " + preset);
  INFO(file << " with --muscle " << preset);
  const auto& q = r["quality"];
  CHECK(r["status"] == "ok");
  CHECK(q["inside_fraction"].get<double>() == 1.0);
  CHECK(q["crossing_segments"].get<long>() == 0);
  CHECK(q["turning"]["max_deg"].get<double>() <= 45.0);
  CHECK(q["ends"]["origin"]["share"].get<double>() >= 0.25);
  CHECK(q["ends"]["insertion"]["share"].get<double>() >= 0.25);
  CHECK(q["coverage"]["p95"].get<double>() <= 2.0);
  REQUIRE(r["pennate"].is_object());
  CHECK(r["pennate"]["map"]["inverted_cells"] == 0);
  CHECK(r["architecture"]["pennation_deg"]["mean"].get<double>() ==
        Approx(r["muscle"]["pennation_deg"].get<double>()).margin(1.5));
}

}  // namespace

TEST_CASE("pennate presets pass the whole check on two Visible Human muscles", "[fibres][corpus][pennate]") {
  FASCICLE_REQUIRE_DATA();
  for (std::size_t i = 0; i < 2; ++i) check_pennate(pennate_muscles()[i].first, pennate_muscles()[i].second);
}

TEST_CASE("pennate presets pass the whole check on every Visible Human muscle they are for",
          "[fibres][corpus][pennate][slow]") {
  FASCICLE_REQUIRE_DATA();
  for (const auto& [file, preset] : pennate_muscles()) check_pennate(file, preset);
}
