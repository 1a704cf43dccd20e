// Pennate fibres drawn through the settled lattice (fibres/pennate_fibres.h) and the presets by
// anatomical name (fibres/muscle_presets.h): on a flat capsule whose thickness is known, the
// fibres cross its thin direction at the requested pennation and are as long as its thickness
// gives; the presets hold Ward et al. 2009's pennations.
#include "fibres/decompose.h"
#include "fibres/muscle_presets.h"
#include "geometry/errors.h"
#include "geometry/primitives.h"
#include "tests/test_common.h"

#include <catch2/catch.hpp>
#include <nlohmann/json.hpp>

#include <cmath>
#include <fstream>
#include <map>
#include <sstream>

using namespace fascicle;

namespace {

constexpr double kPi = 3.14159265358979323846;

// A capsule 120 long along z (the principal axis: the automatic areas are its ends), radius 20,
// flattened to 8 in x: a lens-like cross-section 40 wide (y) and 16 thick (x).
TriangleMesh flat_capsule() {
  TriangleMesh mesh = make_capsule(120.0, 20.0, 32);
  for (Vec3& p : mesh.positions) p = Vec3(0.4 * p.y(), p.z(), p.x());
  return mesh;
}

constexpr double kThickness = 16.0;

}  // namespace

TEST_CASE("pennate templates: fibres rise by the advance and start on the origin area", "[fibres][pennate]") {
  using springs::TemplateKind;
  for (TemplateKind kind : {TemplateKind::unipennate, TemplateKind::bipennate}) {
    INFO(springs::template_name(kind));
    CHECK(springs::crosses_lattice(kind));
    for (double advance : {0.1, 0.5, 2.0, 10.0}) {
      const springs::TemplateArea origin = springs::origin_area(kind, advance),
                                  insertion = springs::insertion_area(kind, advance);
      for (int b = 0; b <= 4; ++b) {
        // Each is at least half as long as the family's longest (in each half for bipennate).
        double longest = 0.0;
        for (int a = 0; a <= 40; ++a)
          longest = std::max(longest, (springs::pennate_point(kind, advance, a / 40.0, b / 4.0, 1.0) -
                                       springs::pennate_point(kind, advance, a / 40.0, b / 4.0, 0.0))
                                          .norm());
        for (int a = 0; a <= 40; ++a)
          CHECK((springs::pennate_point(kind, advance, a / 40.0, b / 4.0, 1.0) -
                 springs::pennate_point(kind, advance, a / 40.0, b / 4.0, 0.0))
                    .norm() >= 0.5 * longest - 1e-9);
      }
      for (int a = 0; a <= 10; ++a)
        for (int b = 0; b <= 4; ++b) {
          const double r = a / 10.0, s = b / 4.0;
          const Vec3 start = springs::pennate_point(kind, advance, r, s, 0.0);
          const Vec3 end = springs::pennate_point(kind, advance, r, s, 1.0);
          CHECK(origin.contains(start));
          CHECK(insertion.contains(end));
          CHECK_FALSE(origin.contains(end));
          // A straight segment in the plane y = s, rising by `advance` per unit of x.
          CHECK(start.y() == Approx(s));
          CHECK(end.y() == Approx(s));
          CHECK(std::abs(end.z() - start.z()) == Approx(advance * std::abs(end.x() - start.x())).margin(1e-12));
          const Vec3 middle = springs::pennate_point(kind, advance, r, s, 0.5);
          CHECK((middle - 0.5 * (start + end)).norm() == Approx(0.0).margin(1e-12));
        }
    }
  }
  CHECK_FALSE(springs::crosses_lattice(springs::TemplateKind::pennate));
  // Other kinds: pennate_point is template_point.
  CHECK((springs::pennate_point(springs::TemplateKind::fanned, 0.3, 0.2, 0.4, 0.6) -
         springs::template_point(springs::TemplateKind::fanned, 0.2, 0.4, 0.6))
            .norm() == 0.0);
}

TEST_CASE("unipennate and bipennate fibres cross the thin direction at the requested pennation", "[fibres][pennate]") {
  using springs::TemplateKind;
  const TriangleMesh mesh = flat_capsule();
  for (TemplateKind kind : {TemplateKind::unipennate, TemplateKind::bipennate}) {
    for (double pennation : {15.0, 30.0}) {
      INFO(springs::template_name(kind) << " at " << pennation << " degrees");
      DecomposeOptions options;
      options.kind = kind;
      options.pennate.pennation_deg = pennation;
      const Decomposition d = decompose_repaired(mesh, Landmarks{}, options);
      CHECK(d.report.status == "ok");
      CHECK(d.report.quality.inside_fraction == 1.0);
      CHECK(d.report.quality.crossing_segments == 0);
      CHECK(d.report.quality.max_turning_angle_deg <= 45.0);
      REQUIRE(d.report.pennate.is_object());
      CHECK(d.report.pennate["unreached_sheets"] == 0);
      // Each sheet's advance is solved to the pennation; the ends, continued to the surface,
      // move the chords a little.
      CHECK(d.report.architecture.pennation_deg.mean == Approx(pennation).margin(1.5));
      CHECK(std::abs(d.report.architecture.line_of_action.z()) > 0.99);
      // Fibres cross the thickness (x), not the width (y): a fibre across the thickness at the
      // pennation is at most thickness / sin(pennation) long (a half crossing for bipennate).
      const double crossing = kind == TemplateKind::unipennate ? kThickness : kThickness / 2.0;
      const double longest = crossing / std::sin(pennation * kPi / 180.0);
      // In the middle half of the width (away from the thin edges, where the surface turns) the
      // chords run across the thickness.
      double across_thickness = 0.0, across_width = 0.0, longest_chord = 0.0;
      for (const auto& line : d.fibres.lines) {
        const Vec3 chord = line.back() - line.front();
        longest_chord = std::max(longest_chord, chord.norm());
        if (std::abs(0.5 * (line.front() + line.back()).y()) > 10.0) continue;
        across_thickness += std::abs(chord.x());
        across_width += std::abs(chord.y());
      }
      INFO("across the thickness " << across_thickness << ", the width " << across_width << ", longest "
                                   << longest_chord << " of " << longest);
      CHECK(across_thickness > 2.0 * across_width);  // across the width instead: well under 1
      CHECK(longest_chord <= 1.4 * longest);         // across the width: 2.5 times as long
      CHECK(d.report.architecture.fibre_length_m.mean * 1e3 >= 0.4 * longest);
      // The check measured the ends against the areas the family spans, with their own patches.
      CHECK(d.report.quality.attachment.origin_max <= 0.02);
      CHECK(d.report.quality.origin_ends.share >= 0.25);
      CHECK(d.report.quality.insertion_ends.share >= 0.25);
    }
  }
}

TEST_CASE("pennate fibres: bad options are refused before the work", "[fibres][pennate]") {
  DecomposeOptions options;
  options.kind = springs::TemplateKind::unipennate;
  for (double bad : {0.0, 90.0, -5.0, std::nan("")}) {
    options.pennate.pennation_deg = bad;
    CHECK_THROWS_AS(options.validate(), OptionError);
  }
  options.pennate.pennation_deg = 20.0;
  options.pennate.area_density = 0;
  CHECK_THROWS_AS(options.validate(), OptionError);
}

TEST_CASE("muscle presets: names and templates", "[fibres][pennate]") {
  CHECK(muscle_preset("vastus_lateralis").kind == springs::TemplateKind::unipennate);
  CHECK(muscle_preset("rectus_femoris").kind == springs::TemplateKind::bipennate);
  CHECK(muscle_preset("sartorius").kind == springs::TemplateKind::parallel);
  CHECK(muscle_preset("psoas").kind == springs::TemplateKind::unipennate);
  try {
    muscle_preset("vastus_lateral");
    FAIL("an unknown name is refused");
  } catch (const OptionError& e) {
    CHECK(std::string(e.what()).find("vastus_lateralis") != std::string::npos);  // the names are listed
  }
}

TEST_CASE("muscle presets hold the pennations of ward2009.csv, one per row", "[fibres][pennate][corpus]") {
  const std::string table = std::string(FASCICLE_DATA_DIR) + "/architecture/ward2009.csv";
  std::ifstream in(table);
  if (!in) {
    WARN("skipped: " << table << " not found (the presets' pennations are compared with it)");
    return;
  }
  std::string line;
  std::getline(in, line);  // header: muscle,fibre_length_cm,fibre_length_sd_cm,pennation_deg,...
  int rows = 0;
  while (std::getline(in, line)) {
    std::stringstream fields(line);
    std::string name, length, length_sd, pennation;
    std::getline(fields, name, ',');
    std::getline(fields, length, ',');
    std::getline(fields, length_sd, ',');
    std::getline(fields, pennation, ',');
    INFO(name);
    CHECK(muscle_preset(name).pennation_deg == Approx(std::stod(pennation)));
    ++rows;
  }
  CHECK(rows == static_cast<int>(muscle_presets().size()));
}
