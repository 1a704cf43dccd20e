// Every corpus muscle through `fascicle batch` (one decompose process per muscle, default
// options): what the decomposition guarantees today on real data, so that a change that breaks it
// is caught. The figures per muscle are in docs/BENCHMARKS.md ("Decompose"); the criteria the
// method does not meet yet on every muscle (inverted cells, coverage) have floors here.
#include "tests/test_common.h"

#include <catch2/catch.hpp>
#include <nlohmann/json.hpp>

#include <filesystem>
#include <fstream>
#include <set>

using namespace fascicle;

TEST_CASE("corpus muscles decompose with every fibre inside and ends on their areas", "[fibres][corpus][slow]") {
  FASCICLE_REQUIRE_DATA();
  test::TempDir dir;
  const std::string muscles = test::data_dir() + "/muscles";
  const int code = test::run_command(test::program() + " -q batch " + muscles + " -o " + dir.path().string() +
                                     " --jobs 2 --keep-failed 2>/dev/null");
  CHECK((code == 0 || code == 19));
  int reports = 0, passed = 0, unfolded = 0, covered = 0, widened = 0, meridian_tries = 0;
  double largest_layer_ratio = 0.0;
  long inverted = 0, crossing = 0, crossing_before = 0;
  std::set<std::string> refused;
  for (const auto& entry : std::filesystem::recursive_directory_iterator(dir.path())) {
    const std::string path = entry.path().string();
    if (path.size() < 12 || path.compare(path.size() - 12, 12, ".report.json") != 0) continue;
    ++reports;
    std::ifstream in(path);
    const nlohmann::json r = nlohmann::json::parse(in);
    INFO(path);
    if (!r.contains("quality")) {
      // Refused before any fibre is made: none since the sphere map is bijective on all 47
      // (issue 3); the LHDL psoas and the opendihu left biceps used to be refused here.
      CHECK(r.value("error_code", std::string()) == "solver_diverged");
      refused.insert(entry.path().filename().string());
      continue;
    }
    const auto& q = r["quality"];
    CHECK(q["fibres"].get<long>() == 100);
    // Automatic areas: an end whose band of 0.1 is one piece keeps 0.1; one of several pieces
    // (two heads) is widened until it is one, plus 0.02 (AttachmentOptions::connected_ends).
    for (const char* end : {"origin", "insertion"}) {
      const auto& area = r["attachments"][end];
      const double share = r["attachments"]["placement_end_share"].get<double>();
      REQUIRE(area.contains("end_pieces"));
      if (area["end_pieces"].get<int>() == 1) CHECK(area["end_fraction"].get<double>() == Approx(0.1 * share));
      else {
        CHECK(area["end_fraction"].get<double>() > 0.1 * share + 0.02 - 1e-9);
        CHECK(area["end_fraction"].get<double>() <= 0.3 + 1e-9);
        ++widened;
      }
    }
    // The opendihu left biceps brachii: two heads at the upper end, both inside its origin.
    if (entry.path().filename() == "left_biceps_brachii.report.json") {
      CHECK(r["attachments"]["origin"]["end_pieces"] == 2);
      CHECK(r["attachments"]["origin"]["end_fraction"].get<double>() > 0.12);
    }
    CHECK(q["inside_fraction"].get<double>() == 1.0);
    CHECK(q["attachment"]["origin_max"].get<double>() <= 0.02);
    CHECK(q["attachment"]["insertion_max"].get<double>() <= 0.02);
    passed += r["status"] == "ok";
    unfolded += q["inverted_cells"].get<long>() == 0;
    inverted += q["inverted_cells"].get<long>();
    covered += q["coverage"]["p95"].get<double>() <= 2.0;
    // Step 10 (segments moved back inside): its count after is the check's where every fibre
    // point is inside (the check also counts a segment with a point outside).
    REQUIRE(r["containment"].contains("segments"));
    if (q["inside_fraction"].get<double>() == 1.0)
      CHECK(r["containment"]["segments"]["crossing_after"] == q["touching_segments"]);
    crossing += q["touching_segments"].get<long>();
    crossing_before += r["containment"]["segments"]["crossing_before"].get<long>();
    // The retries: none after a pass; after a failure the second try (alternative placement)
    // and, unless that passes, the third (face rims left where the placement put them) run
    // unless the first result has more than retry_max_inverted_cells (50) inverted cells or its
    // folds outlasted the untangling with the surface ring free, and are then listed as skipped;
    // the kept attempt's figures are the report's.
    const auto& attempts = r["attempts"];
    REQUIRE(attempts.size() >= 1);
    CHECK(attempts[0]["change"] == "none");
    // After the ladder, the kept try once more with the rings placed by meridian when its longest
    // layer of segments is more than 2.5 times the median (DecomposeOptions::even_layers_ratio).
    // (the first try's options, then, unless that is kept and passes, the kept try's).
    std::size_t ladder = attempts.size();
    while (ladder > 1 && attempts[ladder - 1]["change"] == "meridian_rings") --ladder;
    const bool meridian = ladder < attempts.size();
    if (meridian) {
      CHECK(attempts.size() - ladder <= 2);
      ++meridian_tries;
      // The meridian rings space the layers evenly (LHDL psoas: 1.56 against 4.08 by level).
      for (std::size_t i = ladder; i < attempts.size(); ++i) {
        CHECK(attempts[i]["meridian_rings"] == true);
        CHECK(attempts[i]["layer_ratio"].get<double>() < 2.0);
      }
    } else {
      CHECK(q["steps"]["layer_ratio"].get<double>() <= 2.5);
    }
    if (entry.path().filename() == "LHDL_R_M090_Psoas_smooth.415.report.json") CHECK(meridian);
    largest_layer_ratio = std::max(largest_layer_ratio, q["steps"]["layer_ratio"].get<double>());
    if (attempts[0]["status"] == "ok") CHECK(ladder == 1);
    else {
      REQUIRE(ladder >= 2);
      CHECK(attempts[1]["change"] == "alternative_placement");
      const bool gated = attempts[0]["inverted_cells"].get<long>() > 50 ||
                         attempts[0]["free_ring_tried"].get<bool>();
      if (gated) CHECK(attempts[1]["status"] == "skipped");
      else CHECK(attempts[1]["status"] != "skipped");
      if (attempts[1]["status"] == "ok") CHECK(ladder == 2);
      else {
        REQUIRE(ladder >= 3);
        CHECK(attempts[2]["change"] == "rim_left");
        if (gated) CHECK(attempts[2]["status"] == "skipped");
        else CHECK(attempts[2]["status"] != "skipped");
        // Then, never skipped, the fibre ends placed on 0.8 of the automatic areas
        // (DecomposeOptions::end_share_retry).
        if (attempts[2]["status"] == "ok") CHECK(ladder == 3);
        else {
          REQUIRE(ladder == 4);
          CHECK(attempts[3]["change"] == "end_share");
          CHECK(attempts[3]["placement_end_share"] == 0.8);
          CHECK(attempts[3]["status"] != "skipped");
        }
      }
    }
    const auto& kept = attempts[r["kept_attempt"].get<std::size_t>()];
    CHECK(kept["inverted_cells"] == q["inverted_cells"]);
  }
  CHECK(reports == 47);
  CHECK(refused.empty());
  // Widened ends (seventeenth session, 2026-11-27: the opendihu left biceps, biceps tracer and
  // left triceps, LHDL iliacus, VHM left vastus intermedius; the wrap of the opendihu muscles can
  // depend on the machine's load, README).
  CHECK(widened >= 2);
  // Floors, not the goal (every muscle). Seventeenth session, 2026-11-27 (docs/BENCHMARKS.md,
  // "Decompose", "Seventeenth session"), automatic ends widened to one piece: 47 of 47 pass, 47
  // have no inverted cell, 47 have coverage p95 <= 2 (the highest: VHM left vastus intermedius
  // 1.978, LHDL psoas 1.977). The floors keep room for one muscle: the untangling's attempts are
  // sensitive to round-off, and the left biceps swung between 0 and 11 inverted cells with the
  // widening's margin (morph/attachments.h). Fifteenth session, 2026-11-27 (docs/BENCHMARKS.md,
  // "Decompose", "Fifteenth session"), with the end-share retry: 46 of 47 pass, 46 have no inverted
  // cell, 47 have coverage p95 <= 2, 14 inverted cells in all (the opendihu left biceps; the LHDL
  // psoas passes on its end-share retry). Tenth session, 2026-11-22 14:05-14:16 UTC (docs/BENCHMARKS.md,
  // "Decompose", "Fibre ends in the containment energy"), the free-ring attempts retried with the
  // containment energy where they leave folds (containment_retry): 45 of 47 pass, 45 have no
  // inverted cell, 47 have coverage p95 <= 2, 16 inverted cells in all (LHDL psoas 2, opendihu
  // left biceps 14; main: 33 and 123). The total's floor keeps room for round-off: these two
  // muscles' attempts swing by tens of cells between neighbouring settings.
  // Since 2026-11-22 (ninth session) the decomposition settles
  // with the portable spring loop on every processor (SettleOptions::portable_loop), so these
  // figures no longer follow the processor's vector instructions; measured then on an AVX2
  // processor (docs/BENCHMARKS.md, "Decompose", "Merged 2026-11-22, ninth session"): 45 of 47
  // pass, 45 have no inverted cell, 47 have coverage p95 <= 2, 156 inverted cells in all (LHDL psoas
  // 33, opendihu left biceps 123). The figures below were measured with the AVX-512 loop in the
  // settle, whose rounding differs. Measured on 2026-11-22 07:16-07:21 UTC (docs/BENCHMARKS.md,
  // "Decompose", "Folds next to hooked ends"; the untangling's free-ring attempt): 45 of 47 pass
  // every criterion, 45 have no inverted cell, 46 have coverage p95 <= 2 (the opendihu left biceps,
  // which fails with 77 inverted cells, has 2.19), 106 inverted cells in all (LHDL psoas 29, left
  // biceps 77; the biceps tracer passes). The untangling's attempts are sensitive to round-off,
  // so the total's floor has more room than the others'. Measured on 2026-11-22 00:53-01:06 UTC (docs/BENCHMARKS.md,
  // "Decompose", "Face rims cast with the fibre ends"): 44 of 47 pass every criterion, 44 have no
  // inverted cell, 47 have coverage p95 <= 2, 642 inverted cells in all (LHDL psoas 196, opendihu
  // biceps tracer 135, left biceps 311; the left biceps's first try varied between 199 and 313
  // inverted cells from run to run). Before the rims were cast (2026-11-21 22:06-22:08 UTC):
  // 40 of 47 pass every criterion, 41 have no inverted cell, 46 have coverage p95
  // <= 2, 771 inverted cells in all (ends cast so that they turn the lattice's way, a second try
  // with the alternative placement for a muscle that fails with at most 50 inverted cells; with
  // the second try for every failing muscle 713, 21:15 UTC, for 18 s more batch wall time); at
  // 19:38 the figures were 38, 38, 47 and 979, at 16:34 20, 30, 28. One below the ninth
  // session's figures (two for coverage) and the total about 25 % above its 156: libm's
  // processor-specific variants (glibc picks FMA versions of some functions at run time) may still
  // round differently elsewhere, and the untangling's attempts are sensitive to round-off.
  // Segments that leave the muscle between their points, twenty-first session, 2026-11-28
  // (docs/BENCHMARKS.md, "Decompose", "Twenty-first session"): 1316 of 65800 without step 10,
  // 516 with it; the ceiling keeps room for round-off (the retries and the untangling). Twenty-
  // second session: 665, the LHDL psoas's fibres now following the hook of its tendon by meridian
  // rings (102 -> 251 crossing segments, the deepest 6.84 % -> 3.22 % of its length).
  CHECK(crossing <= 900);
  // Layers of fibre segments (twenty-second session): by level rings the psoas's longest layer
  // was 4.08 times its median one; with the meridian try only the LHDL psoas is retried (kept:
  // 1.56) and the largest ratio left is 2.17 (opendihu left biceps). Room for muscles whose
  // meridian tries round-off makes fail: their ratio stays what the level rings gave.
  CHECK(meridian_tries >= 1);
  CHECK(meridian_tries <= 3);
  CHECK(largest_layer_ratio <= 4.5);
  CHECK(crossing < crossing_before);
  CHECK(passed >= 46);
  CHECK(unfolded >= 46);
  CHECK(covered >= 46);
  CHECK(inverted <= 40);
}
