// Every corpus muscle through `fascicle batch` (one decompose process per muscle, default
// options): what the decomposition guarantees on real data, so that a change that breaks it is
// caught. Hard rules (every point inside, ends on their areas, at most two tries) hold for every
// muscle; the criteria sensitive to round-off (passes, inverted cells, coverage) have floors
// that leave room for one muscle. The figures per muscle: `fascicle bench decompose` (docs/BENCHMARKS.md).
#include "tests/test_common.h"

#include <catch2/catch.hpp>
#include <nlohmann/json.hpp>

#include <algorithm>
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
  int reports = 0, passed = 0, unfolded = 0, covered = 0, widened = 0, meridian_tries = 0, whole = 0;
  int flat_muscles = 0, second_tries = 0;
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
      // Refused before any fibre is made: none expected, the sphere map being bijective on
      // every corpus muscle (checked below: `refused` must stay empty).
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
      if (area["end_pieces"].get<int>() == 1)
        CHECK(area["end_fraction"].get<double>() == Approx(0.1 * share));
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
    // The whole check's criteria (fibres/fibre_check.h, default thresholds) on the same figures.
    whole += r["status"] == "ok" && q["crossing_segments"].get<long>() == 0 &&
             q["turning"]["max_deg"].get<double>() <= 45.0 && q["ends"]["origin"]["share"].get<double>() >= 0.25 &&
             q["ends"]["insertion"]["share"].get<double>() >= 0.25;
    // Steps 11 and 12 (segments moved back inside, sharp joints smoothed): the count after the
    // last is the check's where every fibre point is inside (the check also counts a segment
    // with a point outside); when either is reverted (the check's fallbacks), step 11's count is.
    REQUIRE(r["containment"].contains("segments"));
    const nlohmann::json& smoothing = r["containment"]["smoothing"];
    const nlohmann::json& last = smoothing.is_object() && !smoothing.value("reverted", false) &&
                                         !r["containment"]["segments"]["reverted"].get<bool>()
                                     ? smoothing
                                     : r["containment"]["segments"];
    if (q["inside_fraction"].get<double>() == 1.0) CHECK(last["crossing_after"] == q["touching_segments"]);
    crossing += q["touching_segments"].get<long>();
    crossing_before += r["containment"]["segments"]["crossing_before"].get<long>();
    // At most two tries (fibres/try_policy.h): a second only for the first's failure modes,
    // named in its entry, and with the change that addresses them; the kept try's figures are
    // the report's.
    const auto& attempts = r["attempts"];
    REQUIRE(attempts.size() >= 1);
    REQUIRE(attempts.size() <= 2);
    CHECK(attempts[0]["change"] == "none");
    // A flat muscle (cross-sections at least twice as broad as thick) starts with the corners on
    // its thin edges, a round one with the sides there.
    const nlohmann::json& section = r["cross_section"];
    const bool flat = section["flat"].get<bool>();
    CHECK(flat == (section["median_aspect"].get<double>() >= 2.0));
    CHECK(attempts[0]["corner_twist_deg"] == (flat ? 45.0 : 0.0));
    flat_muscles += flat;
    second_tries += attempts.size() == 2;
    const bool meridian = attempts.size() == 2 && attempts[1]["meridian_rings"] == true;
    if (attempts.size() == 2) {
      const auto& modes = attempts[1]["failure_modes"];
      REQUIRE(!modes.empty());
      const auto shows = [&](const char* mode) { return std::find(modes.begin(), modes.end(), mode) != modes.end(); };
      CHECK(meridian == (shows("folds") || shows("uneven_layers")));
      // Automatic areas: a coverage gap puts the corners on the thin edges where the first try
      // had its sides there (a round muscle's), and narrows the edge cells where it had its
      // corners there (a flat one's); nothing else does either.
      if (flat) {
        CHECK(attempts[1]["corner_twist_deg"] == 45.0);
        CHECK((attempts[1]["edge_cell"] == 0.5) == shows("coverage"));
      } else {
        CHECK((attempts[1]["corner_twist_deg"] == 45.0) == shows("coverage"));
        CHECK(attempts[1]["edge_cell"] == attempts[0]["edge_cell"]);
      }
      if (shows("uneven_layers")) CHECK(attempts[0]["layer_ratio"].get<double>() > 2.5);
    }
    if (meridian) {
      ++meridian_tries;
      // The meridian rings space the layers evenly.
      CHECK(attempts[1]["layer_ratio"].get<double>() < 2.0);
    } else if (r["kept_attempt"].get<int>() == 0) {
      // A first try kept with layers over the policy's ratio would have called the meridian try;
      // a kept deep-faces or corners try is held to the ceiling below (the opendihu tracer's
      // deep-faces try, kept for passing the whole check, has a layer of about 2.8 times the median).
      CHECK(q["steps"]["layer_ratio"].get<double>() <= 2.5);
    }
    if (entry.path().filename() == "LHDL_R_M090_Psoas_smooth.415.report.json") CHECK(meridian);
    largest_layer_ratio = std::max(largest_layer_ratio, q["steps"]["layer_ratio"].get<double>());
    const auto& kept = attempts[r["kept_attempt"].get<std::size_t>()];
    CHECK(kept["inverted_cells"] == q["inverted_cells"]);
  }
  CHECK(reports == 47);
  CHECK(refused.empty());
  // Widened ends: at least two corpus muscles have two heads at an automatic end (the opendihu
  // left biceps among them); room for the opendihu wraps, which can depend on the machine's load.
  CHECK(widened >= 2);
  // Segments that leave the muscle between their points: step 11 must cut them (crossing <
  // crossing_before, below) and the total stay under a ceiling with room for round-off in the
  // retries and the untangling.
  CHECK(crossing <= 900);
  // Layers of fibre segments: the meridian try fires for at least the LHDL psoas (whose tendon
  // hooks) and few others, and no kept result has a layer far longer than its median one; room
  // for muscles whose meridian tries round-off makes fail, keeping the level rings' ratio.
  // Both kinds of cross-section are in the corpus; a flat muscle's corners placed from the start
  // leave few second tries (room for the whole check's, which swing with round-off).
  CHECK(flat_muscles >= 10);
  CHECK(flat_muscles <= reports - 10);
  CHECK(second_tries <= 10);
  CHECK(meridian_tries >= 1);
  CHECK(meridian_tries <= 3);
  CHECK(largest_layer_ratio <= 4.5);
  CHECK(crossing < crossing_before);
  // Floors, not the goal (every muscle): one muscle's room, since the untangling's attempts are
  // sensitive to round-off and swing by tens of cells between neighbouring settings.
  CHECK(passed >= 46);
  CHECK(unfolded >= 46);
  CHECK(covered >= 46);
  // The whole check: the goal is every muscle; the floor is today's count less one muscle's room.
  CHECK(whole >= 43);
  CHECK(inverted <= 40);
}
