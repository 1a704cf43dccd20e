// Fibre ends next to a narrow tendon end (decompose step 6, `cast_faces` in fibres/decompose.cpp):
// the rim of each attachment face is cast with its fibre ends. The placement's depth rule can
// shrink a face to a few percent of its region (as on the VHF psoas used here); a rim left there
// lies inside the cast fibre ends and the cells between them fold, which the untangling with the
// ends held cannot open.
#include "tests/decompose_run.h"
#include "tests/test_common.h"

#include <catch2/catch.hpp>

using namespace fascicle;

using test::decompose_report;

TEST_CASE("a psoas's narrow ends: face rims cast with the fibre ends leave no folded cell",
          "[fibres][decompose][corpus][slow]") {
  FASCICLE_REQUIRE_DATA();
  const std::string muscle = test::data_dir() + "/muscles/visible-human/VHF_Left/VHF_Left_Muscle_PsoasMajor_smooth.stl";
  test::TempDir with_dir, without_dir;
  // The corners on the thin edges: the placement this case was found with.
  const nlohmann::json with = decompose_report(muscle, with_dir.path().string(), "--corner-twist 45");
  // Without the rims cast, with the surface ring held in the untangling: the free-ring attempt
  // would open these folds too, so the ring is held here to show what the cast rims do.
  const nlohmann::json without =
      decompose_report(muscle, without_dir.path().string(),
                       "--corner-twist 45 --cast-rim false --untangle-free-ring false");
  INFO(with["settle"]["cast_faces"].dump());
  // Both faces are shrunk by the depth rule, far below their regions.
  CHECK(with["placement"]["face_scale"][0].get<double>() < 0.2);
  CHECK(with["placement"]["face_scale"][1].get<double>() < 0.2);
  // Every cast round casts both rims; without them the end layers fold.
  for (const auto& round : with["settle"]["cast_faces"])
    for (const auto& face : round) {
      CHECK(face["cast"] == true);
      CHECK(face["rim"] == true);
    }
  for (const auto& round : without["settle"]["cast_faces"])
    for (const auto& face : round) CHECK(face["rim"] == false);
  CHECK(without["quality"]["inverted_cells"].get<long>() > 0);
  CHECK(with["quality"]["inverted_cells"].get<long>() == 0);
  CHECK(with["status"] == "ok");
  CHECK(with["quality"]["inside_fraction"].get<double>() == 1.0);
  CHECK(with["quality"]["coverage"]["p95"].get<double>() <= 2.0);
}
