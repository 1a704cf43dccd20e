// The decomposition: pole frames on the sphere, template placement on the muscle, the whole
// pipeline on a synthetic muscle, bad options and bad landmarks (library and command line).
#include "fibres/decompose.h"
#include "fibres/fibre_grid.h"
#include "fibres/pole_frame.h"
#include "fibres/template_placement.h"
#include "geometry/errors.h"
#include "geometry/mesh_io.h"
#include "geometry/mesh_stats.h"
#include "geometry/primitives.h"
#include "geometry/sample_muscle.h"
#include "morph/sphere_locator.h"
#include "morph/sphere_map.h"
#include "tests/test_common.h"

#include <catch2/catch.hpp>
#include <nlohmann/json.hpp>

#include <filesystem>
#include <fstream>
#include <numeric>
#include <random>
#include <sstream>

#include <unistd.h>

using namespace fascicle;

namespace {

Vec3 random_unit(std::mt19937& rng) {
  std::normal_distribution<double> n;
  return Vec3(n(rng), n(rng), n(rng)).normalized();
}

// A capsule along z from -5 to 5 with radius 1.5: a long, round muscle (make_capsule lies along
// x; the cyclic permutation of the axes is a rotation, so the orientation stays outward).
TriangleMesh capsule() {
  TriangleMesh mesh = make_capsule(10.0, 1.5, 24);
  for (Vec3& p : mesh.positions) p = Vec3(p.y(), p.z(), p.x());
  return mesh;
}

// A muscle, its sphere map and locator, its automatic areas and an nr x ns x resolution lattice:
// what the placement tests place (by default the capsule and 8 x 8 x 12).
struct PlacementSetup {
  TriangleMesh mesh;
  SphereMap map;
  SphereLocator locator;
  Attachments areas;
  springs::Lattice lattice;
  explicit PlacementSetup(TriangleMesh m = capsule(), int nr = 8, int ns = 8, int resolution = 12)
      : mesh(std::move(m)),
        map(map_to_sphere(mesh)),
        locator(map.positions, mesh.triangles),
        areas(automatic_attachments(mesh)),
        lattice(springs::build_lattice([&] {
          springs::LatticeOptions lo;
          lo.nr = nr;
          lo.ns = ns;
          lo.resolution = resolution;
          return lo;
        }())) {}
  /// The template placed with `options`, on these areas or on `other` areas.
  Placement place(const PlacementOptions& options = {}, const Attachments* other = nullptr) const {
    return place_template(mesh, map.positions, locator, other ? *other : areas, lattice, options);
  }
};

}  // namespace

TEST_CASE("a pole frame sends origin and insertion to the poles and back", "[fibres][pole]") {
  std::mt19937 rng(7);
  for (int trial = 0; trial < 50; ++trial) {
    const Vec3 o = random_unit(rng), i = random_unit(rng);
    const PoleFrame frame(o, i, 0.3 + trial * 0.05);
    CHECK((frame.to_pole(o) - Vec3(0, 0, 1)).norm() < 1e-9);
    CHECK((frame.to_pole(i) - Vec3(0, 0, -1)).norm() < 1e-7);
    for (int k = 0; k < 20; ++k) {
      const Vec3 p = random_unit(rng);
      CHECK((frame.from_pole(frame.to_pole(p)) - p).norm() < 1e-8);
      // Orientation-preserving: a small positive triangle stays positive.
      const Vec3 t1 = (p + 1e-3 * random_unit(rng)).normalized(), t2 = (p + 1e-3 * random_unit(rng)).normalized();
      const double before = p.cross(t1).dot(t2);
      const double after = frame.to_pole(p).cross(frame.to_pole(t1)).dot(frame.to_pole(t2));
      if (std::abs(before) > 1e-12) CHECK((before > 0) == (after > 0));
    }
  }
  CHECK_THROWS_AS(PoleFrame(Vec3(0, 0, 1), Vec3(0, 0, 2)), std::invalid_argument);
}

TEST_CASE("template surface points land on the muscle, faces in their areas", "[fibres][placement]") {
  const PlacementSetup setup;
  REQUIRE(setup.map.report.quality.bijective());
  const TriangleMesh& mesh = setup.mesh;
  const Attachments& areas = setup.areas;
  const springs::Lattice& lattice = setup.lattice;
  const Placement placement = setup.place();
  const double length = muscle_length(mesh);
  CHECK(length == Approx(10.0).epsilon(0.01));
  double longest_edge = 0.0;
  for (const Triangle& t : mesh.triangles)
    for (int c = 0; c < 3; ++c)
      longest_edge = std::max(longest_edge, (mesh.positions[t[c]] - mesh.positions[t[(c + 1) % 3]]).norm());
  const int plane = lattice.nx * lattice.ny;
  std::vector<double> ring_z(static_cast<std::size_t>(lattice.nz), 0.0);
  std::vector<int> ring_n(static_cast<std::size_t>(lattice.nz), 0);
  for (int q = 0; q < lattice.point_count(); ++q) {
    const SurfacePoint& p = placement.points[static_cast<std::size_t>(q)];
    if (!lattice.system.fixed[static_cast<std::size_t>(q)]) {
      CHECK(p.face == -1);
      continue;
    }
    REQUIRE(p.face >= 0);
    const int k = q / plane;
    ring_z[static_cast<std::size_t>(k)] += p.position.z();
    ring_n[static_cast<std::size_t>(k)] += 1;
    // Origin face within the region of the origin area (upper end), insertion at the lower.
    // (inner face points: the fibre ends; the rim lies on the region's border)
    const int i = q % lattice.nx, j = (q / lattice.nx) % lattice.ny;
    const bool inner = i > 0 && j > 0 && i + 1 < lattice.nx && j + 1 < lattice.ny;
    const AttachmentArea* area = k == 0 ? &areas.origin : (k == lattice.nz - 1 ? &areas.insertion : nullptr);
    if (area && inner) {
      double nearest = 1e300;
      for (const SurfacePoint& a : area->points) nearest = std::min(nearest, (a.position - p.position).norm());
      // The region: vertices within region_radius of an area point; a face point may lie in a
      // triangle reaching one edge beyond it.
      CHECK(nearest <= PlacementOptions{}.region_radius * length + longest_edge);
    }
  }
  // Rings follow the muscle from the origin (top) to the insertion (bottom), in order.
  for (int k = 1; k < lattice.nz; ++k)
    CHECK(ring_z[static_cast<std::size_t>(k)] / ring_n[static_cast<std::size_t>(k)] <
          ring_z[static_cast<std::size_t>(k - 1)] / ring_n[static_cast<std::size_t>(k - 1)]);
  CHECK(placement.report.located ==
        static_cast<long>(std::count(lattice.system.fixed.begin(), lattice.system.fixed.end(), 1)));
}

TEST_CASE("rings placed by meridian follow the muscle evenly", "[fibres][placement]") {
  // A capsule's sphere map has levels that run a little obliquely, so level rings tilt (each
  // spans up to 1.2 of the capsule's height at a step of 1.03); each point of a meridian ring
  // sits at its own meridian's share of the length, so those rings lie flatter: in order from the
  // origin to the insertion, each spanning at most half a step and less than the level rings'
  // largest span, steps within 25 % of their mean away from the caps.
  const PlacementSetup setup;
  REQUIRE(setup.map.report.quality.bijective());
  const springs::Lattice& lattice = setup.lattice;
  const int plane = lattice.nx * lattice.ny;
  struct Rings {
    std::vector<double> mean, span;
  };
  const auto rings = [&](bool meridian) {
    PlacementOptions options;
    options.meridian_rings = meridian;
    const Placement placement = setup.place(options);
    CHECK(placement.report.located ==
          static_cast<long>(std::count(lattice.system.fixed.begin(), lattice.system.fixed.end(), 1)));
    const auto nz = static_cast<std::size_t>(lattice.nz);
    std::vector<double> low(nz, 1e300), high(nz, -1e300);
    Rings out{std::vector<double>(nz, 0.0), std::vector<double>(nz, 0.0)};
    std::vector<int> count(nz, 0);
    for (int q = 0; q < lattice.point_count(); ++q) {
      if (!lattice.system.fixed[static_cast<std::size_t>(q)]) continue;
      const auto k = static_cast<std::size_t>(q / plane);
      REQUIRE(placement.points[static_cast<std::size_t>(q)].face >= 0);
      const double z = placement.points[static_cast<std::size_t>(q)].position.z();
      low[k] = std::min(low[k], z);
      high[k] = std::max(high[k], z);
      out.mean[k] += z;
      ++count[k];
    }
    for (std::size_t k = 0; k < nz; ++k) {
      out.mean[k] /= count[k];
      out.span[k] = high[k] - low[k];
    }
    return out;
  };
  const Rings level = rings(false), meridian = rings(true);
  std::vector<double> steps;
  for (std::size_t k = 1; k < meridian.mean.size(); ++k) {
    CHECK(meridian.mean[k] < meridian.mean[k - 1]);
    if (k >= 2 && k + 2 < meridian.mean.size()) steps.push_back(meridian.mean[k - 1] - meridian.mean[k]);
  }
  const double average = std::accumulate(steps.begin(), steps.end(), 0.0) / static_cast<double>(steps.size());
  for (double step : steps) CHECK(std::abs(step - average) <= 0.25 * average);
  const std::size_t last = meridian.span.size() - 1;
  const double level_largest = *std::max_element(level.span.begin() + 1, level.span.begin() + static_cast<long>(last));
  const double meridian_largest =
      *std::max_element(meridian.span.begin() + 1, meridian.span.begin() + static_cast<long>(last));
  CHECK(meridian_largest <= 0.5 * average);
  CHECK(meridian_largest < level_largest);
}

TEST_CASE("rings close up where the muscle turns, the first and last ring stay", "[fibres][placement]") {
  // An elbow: a capsule 30 long, radius 1.5, straight for its first and last third and turned
  // through 90 degrees along its middle third. With rings by length alone the middle third gets
  // about a third of the ring steps; with bend_step 10 degrees its turn asks for more, so the
  // rings' centre line turns by less at its sharpest inner ring, while the faces and the first
  // and last lateral ring stay exactly where they were.
  TriangleMesh mesh = make_capsule(30.0, 1.5, 24);
  const double a = 10.0, b = 20.0, radius = (b - a) / (0.5 * 3.14159265358979323846);
  for (Vec3& p : mesh.positions) {
    // make_capsule lies along x from -15 to 15: along z from 0 to 30, then the bend in xz.
    const double z = p.x() + 15.0, x = p.y(), y = p.z();
    if (z <= a) {
      p = Vec3(x, y, z);
    } else if (z <= b) {
      const double phi = (z - a) / radius;
      p = Vec3(radius - (radius - x) * std::cos(phi), y, a + (radius - x) * std::sin(phi));
    } else {
      p = Vec3(radius + (z - b), y, a + radius - x);
    }
  }
  REQUIRE(signed_volume(mesh) > 0.0);
  const PlacementSetup setup(mesh, 6, 6, 15);
  REQUIRE(setup.map.report.quality.bijective());
  const springs::Lattice& lattice = setup.lattice;
  const int plane = lattice.nx * lattice.ny;
  const auto ring_centres = [&](const Placement& placement) {
    std::vector<Vec3> centre(static_cast<std::size_t>(lattice.nz), Vec3::Zero());
    std::vector<int> count(static_cast<std::size_t>(lattice.nz), 0);
    for (int q = 0; q < lattice.point_count(); ++q) {
      if (!lattice.system.fixed[static_cast<std::size_t>(q)]) continue;
      centre[static_cast<std::size_t>(q / plane)] += placement.points[static_cast<std::size_t>(q)].position;
      ++count[static_cast<std::size_t>(q / plane)];
    }
    for (std::size_t k = 0; k < centre.size(); ++k) centre[k] /= count[k];
    return centre;
  };
  // The sharpest turn at a ring whose two neighbours move too (the first and last lateral ring
  // stay, and so do the faces next to them).
  const auto sharpest = [](const std::vector<Vec3>& c) {
    double most = 0.0;
    for (std::size_t k = 3; k + 3 < c.size(); ++k) {
      const Vec3 u = c[k] - c[k - 1], v = c[k + 1] - c[k];
      most = std::max(most, std::atan2(u.cross(v).norm(), u.dot(v)) * 180.0 / 3.14159265358979323846);
    }
    return most;
  };
  PlacementOptions options;
  options.bend_step_deg = 0.0;
  const Placement plain = setup.place(options);
  options.bend_step_deg = 10.0;
  const Placement bent = setup.place(options);
  CHECK(plain.report.bend_share == 0.0);
  CHECK(bent.report.bend_share > 0.05);
  CHECK(bent.report.centre_turn_deg > 80.0);
  const std::vector<Vec3> before = ring_centres(plain), after = ring_centres(bent);
  CAPTURE(sharpest(before), sharpest(after));
  CHECK(sharpest(after) < 0.85 * sharpest(before));
  for (int q = 0; q < lattice.point_count(); ++q) {
    const int k = q / plane;
    if (lattice.system.fixed[static_cast<std::size_t>(q)] && (k <= 1 || k >= lattice.nz - 2))
      CHECK(bent.points[static_cast<std::size_t>(q)].position == plain.points[static_cast<std::size_t>(q)].position);
  }
  // Rings inside the bend (the middle third, between its two straight ends): more with it.
  const auto in_bend = [&](const std::vector<Vec3>& c) {
    int n = 0;
    for (const Vec3& p : c) n += p.z() > a + 0.5 && p.x() < radius - 0.5 ? 1 : 0;
    return n;
  };
  CHECK(in_bend(after) > in_bend(before));
  options.bend_step_deg = -1.0;
  CHECK_THROWS_AS(setup.place(options), OptionError);
}

TEST_CASE("a result with a long layer is decomposed once more with meridian rings", "[fibres][decompose]") {
  // Any layer ratio above 1 asks for the meridian try; 0 never does.
  const TriangleMesh mesh = capsule();
  DecomposeOptions options;
  options.tries.even_layers_ratio = 1.0;
  const Decomposition d = decompose_repaired(mesh, Landmarks{}, options);
  const nlohmann::json& attempts = d.report.attempts;
  REQUIRE(attempts.size() == 2);
  CHECK(attempts[0]["change"] == "none");
  CHECK(attempts[0]["meridian_rings"] == false);
  CHECK(attempts[1]["change"] == "meridian_rings");
  CHECK(attempts[1]["failure_modes"] == nlohmann::json{"uneven_layers"});
  CHECK(attempts[1]["meridian_rings"] == true);
  CHECK(attempts[1]["layer_ratio"].get<double>() >= 1.0);
  // The kept one: the meridian try when it is better or passes with evener layers.
  if (d.report.kept_attempt == 1) CHECK(d.report.quality.steps.layer_ratio == attempts[1]["layer_ratio"].get<double>());
  CHECK(d.report.quality.pass);
  options.tries.even_layers_ratio = 0.0;
  CHECK(decompose_repaired(mesh, Landmarks{}, options).report.attempts.size() == 1);
  options.tries.even_layers_ratio = 1.0;
  options.tries.second_try = false;
  CHECK(decompose_repaired(mesh, Landmarks{}, options).report.attempts.size() == 1);
}

TEST_CASE("narrow edge cells bring the outer fibres nearer the surface", "[fibres][decompose]") {
  // With the ring spaced like the fibres the outermost fibres lie a whole spacing under the
  // surface; with edge cells of 0.5, half a spacing: the volume is covered more closely.
  const TriangleMesh mesh = capsule();
  DecomposeOptions options;
  const Decomposition even = decompose_repaired(mesh, Landmarks{}, options);
  options.edge_cell = 0.5;
  const Decomposition narrow = decompose_repaired(mesh, Landmarks{}, options);
  REQUIRE(even.report.quality.pass);
  REQUIRE(narrow.report.quality.pass);
  REQUIRE(narrow.report.attempts.size() == 1);  // passed on the first try
  CHECK(narrow.report.attempts[0]["edge_cell"] == 0.5);
  CHECK(even.report.attempts[0]["edge_cell"] == 1.0);
  CHECK(narrow.report.quality.coverage.p95 < 0.9 * even.report.quality.coverage.p95);
  // The fibres' mean distance from the capsule's axis grows (radius 1.5; the axis is z).
  const auto mean_radius = [](const Decomposition& d) {
    double sum = 0.0;
    long n = 0;
    for (const auto& line : d.fibres.lines)
      for (std::size_t k = 3; k + 3 < line.size(); ++k) sum += std::hypot(line[k].x(), line[k].y()), ++n;
    return sum / static_cast<double>(n);
  };
  CHECK(mean_radius(narrow) > mean_radius(even));

  DecomposeOptions bad;
  bad.edge_cell = 0.0;
  CHECK_THROWS_WITH(bad.validate(), Catch::Contains("edge_cell"));
  bad.edge_cell = 1.2;
  CHECK_THROWS_WITH(bad.validate(), Catch::Contains("edge_cell"));
}

TEST_CASE("a capsule decomposes into fibres inside it, ending on their areas", "[fibres][decompose]") {
  const TriangleMesh mesh = capsule();
  DecomposeOptions options;
  const Decomposition d = decompose_repaired(mesh, Landmarks{}, options);
  REQUIRE(d.fibres.lines.size() == 100);
  for (const auto& line : d.fibres.lines) REQUIRE(line.size() == 15);
  const FibreGrid grid = fibre_grid(d.fibres);
  CHECK(grid.nr * grid.ns == 100);
  const CheckReport& q = d.report.quality;
  CHECK(q.inside_fraction == 1.0);
  CHECK(q.attachment.origin_max <= 0.02);
  CHECK(q.attachment.insertion_max <= 0.02);
  CHECK(q.coverage.p95 <= 2.0);
  // Fibres run from the origin (upper end) to the insertion.
  for (const auto& line : d.fibres.lines) CHECK(line.front().z() > line.back().z());
  const nlohmann::json j = d.report.to_json();
  for (const char* key : {"sphere", "placement", "lattice", "settle", "containment", "quality", "seconds"})
    CHECK(j.contains(key));
}

TEST_CASE("the untangling's segment attempt holds the segments that cut a bend inside", "[fibres][decompose]") {
  // The bent tube of the next case: the chords next to its inner wall leave it by more than the
  // check allows until the segment attempt holds them in.
  const TriangleMesh mesh = make_bent_tube(10.0, 2.0, 150.0 * 3.14159265358979323846 / 180.0, 32);
  DecomposeOptions options;
  options.resolution = 8;
  options.contain_segments = false;  // the attempt alone
  options.smoothing.steps = 0;
  options.contact_segments = false;
  options.tries.second_try = false;  // one try: the segments left out would call the deep-faces try
  const Decomposition loose = decompose_repaired(mesh, Landmarks{}, options);
  REQUIRE(loose.report.status == "ok");
  REQUIRE(loose.report.quality.crossing_segments > 0);
  CHECK_FALSE(loose.report.untangle.value("segments_kept", false));
  options.contact_segments = true;
  const Decomposition held = decompose_repaired(mesh, Landmarks{}, options);
  REQUIRE(held.report.status == "ok");
  const nlohmann::json& u = held.report.untangle;
  CHECK(u.at("segments_kept").get<bool>());
  CHECK(u.at("crossing_before").get<long>() == loose.report.quality.crossing_segments);
  CHECK(u.at("crossing_after").get<long>() == held.report.quality.crossing_segments);
  CHECK(held.report.quality.crossing_segments < loose.report.quality.crossing_segments);
  CHECK(held.report.quality.max_segment_excursion < loose.report.quality.max_segment_excursion);
  CHECK(held.report.quality.inverted_cells == 0);
  CHECK(held.report.quality.inside_fraction == 1.0);
}

TEST_CASE("segments that cut a bend are moved back inside, and the check counts what is left", "[fibres][decompose]") {
  // A tube bent through 150 degrees with 8 points per fibre: about 21 degrees of arc per
  // segment, so the chords of the fibres next to the inner wall cut it (13 segments; with 6
  // points the fibres fail the coverage criterion and the retries keep another attempt).
  const TriangleMesh mesh = make_bent_tube(10.0, 2.0, 150.0 * 3.14159265358979323846 / 180.0, 32);
  DecomposeOptions options;
  options.resolution = 8;
  options.contain_segments = false;
  options.smoothing.steps = 0;       // step 11 alone: the smoothing after it would move the fibres again,
  options.contact_segments = false;  // and the untangling's segment attempt before it
  options.tries.second_try = false;  // one try: the segments left out would call the deep-faces try
  const Decomposition left = decompose_repaired(mesh, Landmarks{}, options);
  REQUIRE(left.report.status == "ok");
  CHECK_FALSE(left.report.containment.contains("segments"));
  const long crossing = left.report.quality.touching_segments;
  CHECK(crossing > 0);
  options.contain_segments = true;
  const Decomposition contained = decompose_repaired(mesh, Landmarks{}, options);
  REQUIRE(contained.report.status == "ok");
  const nlohmann::json& segments = contained.report.containment.at("segments");
  CHECK(segments.at("crossing_before").get<long>() == crossing);
  CHECK(segments.at("moved").get<long>() > 0);
  // The operation's count and the check's agree (the same rule, the same end tolerance).
  CHECK(segments.at("crossing_after").get<long>() == contained.report.quality.touching_segments);
  CHECK(contained.report.quality.touching_segments < crossing);
  CHECK(contained.report.quality.inside_fraction == 1.0);
  CHECK(contained.report.quality.inverted_cells <= left.report.quality.inverted_cells);
  CHECK(contained.report.quality.max_segment_excursion <= left.report.quality.max_segment_excursion);
  CHECK(segments.at("reverted").get<bool>() == false);

  // The moves do not guard the coverage: with a coverage threshold between the two results'
  // figures the moved fibres fail, the unmoved ones pass and are kept.
  const double unmoved = left.report.quality.coverage.p95, moved = contained.report.quality.coverage.p95;
  CAPTURE(unmoved, moved);
  REQUIRE(moved > unmoved);  // moving fibres off the inner wall leaves it a little thinner
  options.check.max_coverage_p95 = 0.5 * (unmoved + moved);
  const Decomposition strict = decompose_repaired(mesh, Landmarks{}, options);
  CHECK(strict.report.status == "ok");
  CHECK(strict.report.containment.at("segments").at("reverted").get<bool>());
  CHECK(strict.report.containment.at("segments").at("crossing_after").get<long>() == crossing);
  CHECK(strict.fibres.lines == left.fibres.lines);
}

TEST_CASE("a large lattice's harmonic start is solved by multigrid to the direct solve's result",
          "[fibres][decompose]") {
  // 400 fibres x 20 points: 22 x 22 x 20 = 9680 lattice points, two multigrid levels.
  const TriangleMesh mesh = capsule();
  DecomposeOptions direct;
  direct.fibres = 400;
  direct.resolution = 20;
  direct.harmonic_direct_points = 1'000'000;
  // The fibres compare to round-off only where the untangling has little to do (it stops at a
  // tolerance, so it carries round-off differences of its start up to that): the capsule's settle
  // with one cast factor for the whole face folds a few cells, with one per azimuth more.
  direct.cast_by_azimuth = false;
  DecomposeOptions multigrid = direct;
  multigrid.harmonic_direct_points = 0;
  const Decomposition a = decompose_repaired(mesh, Landmarks{}, direct);
  const Decomposition b = decompose_repaired(mesh, Landmarks{}, multigrid);
  const nlohmann::json& ha = a.report.settle["harmonic"];
  const nlohmann::json& hb = b.report.settle["harmonic"];
  CHECK(ha["backend"] == "ldlt");
  CHECK(hb["backend"].get<std::string>().rfind("multigrid-", 0) == 0);
  CHECK(hb["backend"] != "multigrid-1");  // V-cycles over at least two levels, not one direct solve
  CHECK(hb["factor_seconds"] == 0.0);     // no factorization made for it
  CHECK(hb["converged"] == true);
  CHECK(hb["residual"].get<double>() <= 1e-12);
  CHECK(ha["residual"].get<double>() <= 1e-12);
  CHECK(a.report.quality.pass);
  CHECK(b.report.quality.pass);
  REQUIRE(a.fibres.lines.size() == b.fibres.lines.size());
  double largest = 0.0;
  for (std::size_t f = 0; f < a.fibres.lines.size(); ++f) {
    REQUIRE(a.fibres.lines[f].size() == b.fibres.lines[f].size());
    for (std::size_t i = 0; i < a.fibres.lines[f].size(); ++i)
      largest = std::max(largest, (a.fibres.lines[f][i] - b.fibres.lines[f][i]).norm());
  }
  INFO("largest difference of a fibre point: " << largest);
  CHECK(largest <= 1e-9 * a.report.quality.length.mean);
  DecomposeOptions negative;
  negative.harmonic_direct_points = -1;
  CHECK_THROWS_AS(negative.validate(), OptionError);
}

TEST_CASE("fibre ends placed on a share of the automatic areas are checked against the whole areas",
          "[fibres][decompose]") {
  const TriangleMesh mesh = capsule();
  DecomposeOptions options;
  options.placement_end_share = 0.2;
  const Decomposition d = decompose_repaired(mesh, Landmarks{}, options);
  CHECK(d.report.attachments["placement_end_share"] == 0.2);
  const Attachments whole = automatic_attachments(mesh, options.attachments);
  AttachmentOptions halved = options.attachments;
  halved.end_fraction *= 0.2;
  const Attachments placed = automatic_attachments(mesh, halved);
  REQUIRE(placed.origin.points.size() < whole.origin.points.size());
  // The report's quality is what `fascicle check` computes with the same end fraction.
  const CheckReport against_whole = check_fibres(d.fibres, mesh, whole, options.check);
  const CheckReport against_placed = check_fibres(d.fibres, mesh, placed, options.check);
  CHECK(d.report.quality.attachment.origin_max == against_whole.attachment.origin_max);
  CHECK(d.report.quality.attachment.insertion_max == against_whole.attachment.insertion_max);
  // The smaller areas lie inside the whole ones: the ends are no farther from the whole areas.
  CHECK(against_whole.attachment.origin_max <= against_placed.attachment.origin_max);
  CHECK(against_whole.attachment.insertion_max <= against_placed.attachment.insertion_max);
  // Measured against the whole areas, placed on the smaller ones.
  CHECK(d.report.quality.attachment.origin_points == static_cast<long>(whole.origin.points.size()));
  CHECK(d.report.quality.attachment.insertion_points == static_cast<long>(whole.insertion.points.size()));
  CHECK(d.report.attachments["origin"]["points"] == placed.origin.points.size());
  CHECK(d.report.attachments["insertion"]["points"] == placed.insertion.points.size());
  CHECK(d.report.quality.inside_fraction == 1.0);
}

TEST_CASE("a flat muscle is covered to its thin edges", "[fibres][decompose]") {
  // The capsule flattened to a 5 : 1 cross-section (semi-axes 3 and 0.6), like a strap or
  // a fan. With the middle of a lattice side on each thin edge (corner_twist_deg 0, a round
  // muscle's first try's) the settled lattice stays away from the edges; with a lattice corner on
  // each (45 degrees, a flat muscle's first try's, and the second try's for a coverage gap) the
  // fibres reach them (docs/decompose.md, steps 4 and 9).
  TriangleMesh mesh = capsule();
  for (Vec3& p : mesh.positions) p = Vec3(2.0 * p.x(), 0.4 * p.y(), p.z());
  DecomposeOptions options;
  options.untangle.iterations = 2000;
  options.tries.second_try = false;
  options.placement.corner_twist_deg = 45.0;
  const Decomposition corner = decompose_repaired(mesh, Landmarks{}, options);
  options.placement.corner_twist_deg = 0.0;
  options.placement.flat_section_aspect = 0.0;  // the sides on the edges however flat
  const Decomposition side = decompose_repaired(mesh, Landmarks{}, options);
  const CheckReport& a = corner.report.quality;
  const CheckReport& b = side.report.quality;
  CAPTURE(a.coverage.p95, b.coverage.p95, a.coverage.far.fraction, b.coverage.far.fraction);
  CHECK(a.inside_fraction == 1.0);
  CHECK(std::max(a.attachment.origin_max, a.attachment.insertion_max) <= 0.02);
  CHECK(a.coverage.p95 <= 2.0);
  CHECK(a.coverage.far.fraction < 0.05);
  CHECK(b.coverage.p95 > a.coverage.p95);
  // With both tries and the sides on the edges, the first's coverage gap calls the second with
  // the corners there, which is the run above with them there.
  CHECK(b.coverage.p95 > 2.0);
  options.tries.second_try = true;
  const Decomposition both = decompose_repaired(mesh, Landmarks{}, options);
  const nlohmann::json attempts = both.report.to_json()["attempts"];
  INFO(attempts.dump());
  REQUIRE(attempts.size() == 2);
  CHECK(attempts[1]["change"] == "corners_on_edges");
  CHECK(both.report.kept_attempt == 1);
  CHECK(both.report.quality.coverage.p95 == a.coverage.p95);
  // With the default options the cross-sections (aspect 5) are flat: the first try has the
  // corners on the edges, and it is that run too.
  DecomposeOptions defaults;
  defaults.untangle.iterations = 2000;
  const Decomposition flat = decompose_repaired(mesh, Landmarks{}, defaults);
  const nlohmann::json report = flat.report.to_json();
  INFO(report["cross_section"].dump());
  CHECK(report["cross_section"]["flat"] == true);
  CHECK(report["cross_section"]["median_aspect"].get<double>() == Approx(5.0).epsilon(0.05));
  REQUIRE(report["attempts"].size() == 1);
  CHECK(report["attempts"][0]["corner_twist_deg"] == 45.0);
  CHECK(flat.report.quality.coverage.p95 == a.coverage.p95);
}

namespace {

// Largest over smallest distance between neighbouring surface points round the middle ring of
// the placed lattice.
double ring_spacing_ratio(const springs::Lattice& lattice, const Placement& placement) {
  const int k = lattice.nz / 2;
  std::vector<Vec3> ring;
  auto at = [&](int i, int j) { return placement.points[static_cast<std::size_t>(lattice.index(i, j, k))].position; };
  for (int i = 0; i + 1 < lattice.nx; ++i) ring.push_back(at(i, 0));
  for (int j = 0; j + 1 < lattice.ny; ++j) ring.push_back(at(lattice.nx - 1, j));
  for (int i = lattice.nx - 1; i > 0; --i) ring.push_back(at(i, lattice.ny - 1));
  for (int j = lattice.ny - 1; j > 0; --j) ring.push_back(at(0, j));
  double lo = 1e300, hi = 0.0;
  for (std::size_t n = 0; n < ring.size(); ++n) {
    const double d = (ring[(n + 1) % ring.size()] - ring[n]).norm();
    lo = std::min(lo, d);
    hi = std::max(hi, d);
  }
  return hi / lo;
}

}  // namespace

TEST_CASE("a landmark strip down the side is centred towards the muscle's end", "[fibres][placement]") {
  // The capsule (z from -5 to 5 over its caps, the cylinder from -3.5 to 3.5). The origin
  // landmarks run down its side from the middle (z = 0) over the top cap to its tip, as the LHDL
  // gluteus medius's do (from 0.5 to 1 of the length); the
  // insertion is a disk on the bottom cap. Centred in the middle of its region (the automatic
  // areas' rule, landmark_centre_keep = 1) the origin face sits halfway down the strip; by
  // default it moves to the far end of the strip, near the top.
  const PlacementSetup setup;
  REQUIRE(setup.map.report.quality.bijective());
  const TriangleMesh& mesh = setup.mesh;
  const springs::Lattice& lattice = setup.lattice;
  std::vector<Vec3> origin, insertion;
  for (double z = 0.0; z < 3.5; z += 0.1) origin.emplace_back(1.5, 0.0, z);
  for (double a = 0.0; a <= 90.0; a += 4.0) {
    const double r = a * 3.14159265358979323846 / 180.0;
    origin.emplace_back(1.5 * std::cos(r), 0.0, 3.5 + 1.5 * std::sin(r));
  }
  for (double x = -0.4; x <= 0.41; x += 0.1)
    for (double y = -0.4; y <= 0.41; y += 0.1) insertion.emplace_back(x, y, -5.0);
  const Attachments areas = landmark_attachments(mesh, origin, "side.xyz", insertion, "bottom.xyz");
  PlacementOptions middle;
  middle.landmark_centre_keep = 1.0;
  const PlacementOptions towards_end;
  REQUIRE(towards_end.landmark_centre_keep < 1.0);
  const Placement before = setup.place(middle, &areas);
  const Placement after = setup.place(towards_end, &areas);
  const auto face_z = [&](const Placement& placement) {
    double z = 0.0;
    int count = 0;
    for (int j = 0; j < lattice.ny; ++j)
      for (int i = 0; i < lattice.nx; ++i) {
        z += placement.points[static_cast<std::size_t>(lattice.index(i, j, 0))].position.z();
        ++count;
      }
    return z / count;
  };
  CAPTURE(before.report.origin_centre.transpose(), after.report.origin_centre.transpose(), face_z(before),
          face_z(after));
  CHECK(before.report.origin_centre.z() < 3.0);
  CHECK(after.report.origin_centre.z() > 4.0);
  // The origin face's points follow it up the muscle, past the end of the cylinder.
  CHECK(face_z(before) < 3.0);
  CHECK(face_z(after) > 3.5);
  // Each centre is a vertex of its region: within the region radius of an area point.
  const double radius = towards_end.region_radius * muscle_length(mesh);
  const auto nearest = [](const AttachmentArea& area, const Vec3& p) {
    double d = 1e300;
    for (const SurfacePoint& s : area.points) d = std::min(d, (s.position - p).norm());
    return d;
  };
  CHECK(nearest(areas.origin, after.report.origin_centre) <= radius);
  CHECK(nearest(areas.insertion, after.report.insertion_centre) <= radius);

  // Automatic areas keep the rule of the deepest vertex: the option changes nothing there.
  const Placement a = setup.place(middle);
  const Placement b = setup.place(towards_end);
  REQUIRE(a.points.size() == b.points.size());
  for (std::size_t q = 0; q < a.points.size(); ++q) CHECK(a.points[q].position == b.points[q].position);

  PlacementOptions bad;
  bad.landmark_centre_keep = 0.0;
  CHECK_THROWS_WITH(bad.validate(), Catch::Contains("landmark_centre_keep"));
  bad.landmark_centre_keep = 1.5;
  CHECK_THROWS_WITH(bad.validate(), Catch::Contains("landmark_centre_keep"));
}

TEST_CASE("the lattice's rings are spread evenly round a flat cross-section", "[fibres][placement]") {
  // The flat capsule of the case above (semi-axes 3 and 0.6). By the sphere map's azimuths the
  // lattice corners crowd into the thin edges (their sides subtend the least angle there, and
  // the map compresses the edges); by even shares of the perimeter they do not.
  TriangleMesh mesh = capsule();
  for (Vec3& p : mesh.positions) p = Vec3(2.0 * p.x(), 0.4 * p.y(), p.z());
  const PlacementSetup setup(mesh, 12, 12, 15);
  REQUIRE(setup.map.report.quality.bijective());
  const springs::Lattice& lattice = setup.lattice;
  PlacementOptions even;
  even.even_perimeter = true;
  PlacementOptions by_azimuth;
  by_azimuth.even_perimeter = false;
  const double even_ratio =
      ring_spacing_ratio(lattice, setup.place(even));
  const double azimuth_ratio =
      ring_spacing_ratio(lattice, setup.place(by_azimuth));
  CAPTURE(even_ratio, azimuth_ratio);
  CHECK(even_ratio < 0.7 * azimuth_ratio);
  CHECK(even_ratio < 3.0);
}

TEST_CASE("a decomposition is tried at most twice, the second time for a named failure mode", "[fibres][decompose]") {
  // The failure modes of a check (fibres/try_policy.h), each from its criterion.
  TryPolicy policy;
  CheckReport passed;
  passed.pass = true;
  CHECK(failure_modes(passed, policy).empty());
  CheckReport folded;
  folded.failed = {"inverted_cells", "coverage"};
  CHECK(failure_modes(folded, policy) == std::vector<std::string>{"folds", "coverage"});
  CheckReport uneven = passed;
  uneven.steps.layer_ratio = 3.0;
  CHECK(failure_modes(uneven, policy) == std::vector<std::string>{"uneven_layers"});
  policy.even_layers_ratio = 0.0;
  CHECK(failure_modes(uneven, policy).empty());
  CheckReport attachment;
  attachment.failed = {"attachment"};  // no second try addresses it
  CHECK(failure_modes(attachment, TryPolicy{}).empty());
  // The second try's options: meridian rings for folds and uneven layers; for a coverage gap the
  // lattice's corners on the thin edges, and where they are there already narrow edge cells;
  // nothing where the first had them already.
  DecomposeOptions options;
  REQUIRE(options.placement.corner_twist_deg == 0.0);
  const SecondTry both = second_try(options, {"folds", "coverage"});
  CHECK(both.change == "meridian_rings+corners_on_edges");
  CHECK(both.options.placement.meridian_rings);
  CHECK(both.options.placement.corner_twist_deg == 45.0);
  CHECK(both.options.edge_cell == options.edge_cell);
  CHECK_NOTHROW(both.options.validate());
  CHECK(second_try(options, {"uneven_layers"}).change == "meridian_rings");
  CHECK(second_try(options, {"uneven_layers"}).options.edge_cell == options.edge_cell);
  CHECK(second_try(options, {"coverage"}).change == "corners_on_edges");
  CHECK_FALSE(second_try(options, {"coverage"}).options.placement.meridian_rings);
  const SecondTry narrow_cells = second_try(both.options, {"folds", "coverage"});
  CHECK(narrow_cells.change == "narrow_edge_cells");
  CHECK(narrow_cells.options.edge_cell == 0.5);
  CHECK(narrow_cells.options.placement.corner_twist_deg == 45.0);
  DecomposeOptions turned = options;
  turned.placement.corner_twist_deg = -135.0;  // corners on the edges too (the square's symmetry)
  CHECK(second_try(turned, {"coverage"}).change == "narrow_edge_cells");
  CHECK(second_try(narrow_cells.options, {"folds", "coverage"}).change.empty());
  DecomposeOptions by_area = options;
  by_area.placement.band_by_length = false;  // meridian rings need rings by length
  CHECK(second_try(by_area, {"folds"}).change.empty());
  // The whole check's modes, for a first try that passes decompose's check: deep faces; nothing
  // where the first had them already, nor for a sharp joint inside the fibres.
  CheckReport whole = passed;
  whole.origin_ends.share = 0.1;
  whole.insertion_ends.share = 0.5;
  whole.turning.max_deg = 60.0;
  whole.turning.max_at_end = true;
  whole.crossing_segments = 2;
  CHECK(whole_check_modes(whole) == std::vector<std::string>{"gathered_ends", "hooked_ends", "segments_out"});
  whole.turning.max_at_end = false;
  CHECK(whole_check_modes(whole) == std::vector<std::string>{"gathered_ends", "sharp_joints", "segments_out"});
  whole.origin_ends.share = 0.3;
  whole.turning.max_deg = 20.0;
  CHECK(whole_check_modes(whole) == std::vector<std::string>{"segments_out"});
  whole.crossing_segments = 0;
  CHECK(whole_check_modes(whole).empty());
  const SecondTry deep = second_try(options, {"gathered_ends"});
  CHECK(deep.change == "deep_faces");
  CHECK(deep.options.placement.max_face_depth == 1.0);
  CHECK_NOTHROW(deep.options.validate());
  CHECK(second_try(deep.options, {"hooked_ends"}).change.empty());
  CHECK(second_try(options, {"hooked_ends"}).change == "deep_faces");
  CHECK(second_try(options, {"sharp_joints"}).change.empty());
  // On landmark strips gathered ends alone call no second try; a hooked end still does.
  CHECK(second_try(options, {"gathered_ends"}, true).change.empty());
  CHECK(second_try(options, {"gathered_ends", "sharp_joints"}, true).change.empty());
  CHECK(second_try(options, {"gathered_ends", "hooked_ends"}, true).change == "deep_faces");
  CHECK(second_try(options, {"segments_out"}, true).change == "deep_faces");

  // A capsule passes at once: no second try.
  const TriangleMesh mesh = capsule();
  const Decomposition once = decompose_repaired(mesh, Landmarks{}, options);
  REQUIRE(once.report.quality.pass);
  CHECK(once.report.attempts.size() == 1);
  CHECK(once.report.to_json()["attempts"].size() == 1);
  // A coverage limit no lattice meets: the second try with the corners on the edges, both fail,
  // the report says which it kept (the better one) and why the second ran.
  options.check.max_coverage_p95 = 1e-6;
  const Decomposition twice = decompose_repaired(mesh, Landmarks{}, options);
  CHECK_FALSE(twice.report.quality.pass);
  const nlohmann::json attempts = twice.report.to_json()["attempts"];
  INFO(attempts.dump());
  REQUIRE(attempts.size() == 2);
  CHECK(attempts[0]["change"] == "none");
  CHECK(attempts[0]["status"] == "failed");
  CHECK(attempts[0]["edge_cell"] == 1.0);
  CHECK(attempts[0]["corner_twist_deg"] == 0.0);
  CHECK(attempts[1]["change"] == "corners_on_edges");
  CHECK(attempts[1]["failure_modes"] == nlohmann::json{"coverage"});
  CHECK(attempts[1]["corner_twist_deg"] == 45.0);
  CHECK(attempts[1]["edge_cell"] == 1.0);
  CHECK(attempts[1]["status"] == "failed");
  const int kept = twice.report.kept_attempt;
  REQUIRE((kept == 0 || kept == 1));
  CHECK(attempts[kept]["coverage_p95"].get<double>() == twice.report.quality.coverage.p95);
  CHECK(attempts[kept]["coverage_p95"].get<double>() <= attempts[1 - kept]["coverage_p95"].get<double>());
  CHECK(twice.report.placement.is_object());
  // A failure mode with nothing left to change: one try, and the report says so.
  DecomposeOptions narrow = options;
  narrow.placement.corner_twist_deg = 45.0;
  narrow.edge_cell = 0.5;
  const Decomposition no_change = decompose_repaired(mesh, Landmarks{}, narrow);
  REQUIRE(no_change.report.attempts.size() == 1);
  CHECK(no_change.report.attempts[0]["second_try"].get<std::string>().find("coverage") != std::string::npos);
  options.tries.second_try = false;
  const Decomposition one = decompose_repaired(mesh, Landmarks{}, options);
  CHECK(one.report.attempts.size() == 1);
  CHECK(one.report.quality.coverage.p95 == Approx(once.report.quality.coverage.p95));
}

TEST_CASE("the ranking of results", "[fibres][decompose]") {
  CheckReport pass, fail_one, fail_one_folded, fail_two;
  pass.pass = true;
  fail_one.failed = {"coverage"};
  fail_one.inverted_cells = 0;
  fail_one_folded.failed = {"inverted_cells"};
  fail_one_folded.inverted_cells = 12;
  fail_two.failed = {"coverage", "inverted_cells"};
  fail_two.inverted_cells = 3;
  CHECK(better_result(pass, fail_one));
  CHECK_FALSE(better_result(fail_one, pass));
  CHECK(better_result(fail_one_folded, fail_two));
  CHECK(better_result(fail_one, fail_one_folded));
  CHECK_FALSE(better_result(fail_one, fail_one));  // equals: the first is kept
}

TEST_CASE("a lattice's handedness follows its layers' turn along the fibres", "[fibres][decompose]") {
  springs::LatticeOptions lo;
  lo.nr = 6;
  lo.ns = 5;
  lo.resolution = 7;
  const springs::Lattice lattice = springs::build_lattice(lo);
  springs::SpringSystem system = lattice.system;
  const int hand = lattice_handedness(system, lattice);
  CHECK(hand != 0);
  // A mirror image turns the other way; a rotation does not.
  for (Vec3& p : system.positions) p.x() = -p.x();
  CHECK(lattice_handedness(system, lattice) == -hand);
  for (Vec3& p : system.positions) p = Vec3(p.y(), -p.x(), p.z());  // the mirror image turned: still a mirror
  CHECK(lattice_handedness(system, lattice) == -hand);
  system.positions = lattice.system.positions;
  for (Vec3& p : system.positions) p = Vec3(-p.y(), p.x(), p.z());
  CHECK(lattice_handedness(system, lattice) == hand);
  springs::LatticeOptions thin = lo;
  thin.resolution = 2;
  const springs::Lattice two = springs::build_lattice(thin);
  CHECK(lattice_handedness(two.system, two) == 0);
}

TEST_CASE("decompose refuses bad options and coinciding areas", "[fibres][decompose]") {
  const TriangleMesh mesh = capsule();
  DecomposeOptions zero;
  zero.fibres = 0;
  CHECK_THROWS_AS(decompose_repaired(mesh, {}, zero), OptionError);
  DecomposeOptions one;
  one.resolution = 1;
  CHECK_THROWS_AS(decompose_repaired(mesh, {}, one), OptionError);
  // Each of fibres and resolution in range, their product (1e9 lattice points) not: the
  // lattice's own check, which DecomposeOptions::validate runs.
  DecomposeOptions product;
  product.fibres = 1'000'000;
  product.resolution = 1'000;
  CHECK_THROWS_WITH(product.validate(), Catch::Contains("fibres x resolution"));
  DecomposeOptions many;
  many.fibres = 1'000'001;
  CHECK_THROWS_WITH(many.validate(), Catch::Contains("fibres: at most 1000000"));
  DecomposeOptions backend;
  backend.backend = "quantum";
  CHECK_THROWS_AS(decompose_repaired(mesh, {}, backend), OptionError);
  CHECK_THROWS_AS(parse_rest_shape("loose"), OptionError);
  DecomposeOptions twist;
  twist.placement.corner_twist_deg = 200.0;
  CHECK_THROWS_WITH(twist.validate(), Catch::Contains("corner_twist_deg"));
  DecomposeOptions share;
  share.placement_end_share = 0.0;
  CHECK_THROWS_WITH(share.validate(), Catch::Contains("placement_end_share"));
  share.placement_end_share = 1.5;
  CHECK_THROWS_WITH(share.validate(), Catch::Contains("placement_end_share"));
  DecomposeOptions layers;
  layers.tries.even_layers_ratio = 0.5;
  CHECK_THROWS_WITH(layers.validate(), Catch::Contains("even_layers_ratio"));
  layers.tries.even_layers_ratio = 0.0;
  CHECK_NOTHROW(layers.validate());
  DecomposeOptions depth;
  depth.contact_depth = 1.0;  // a target on the next layer
  CHECK_THROWS_WITH(depth.validate(), Catch::Contains("contact_depth"));
  depth.contact_depth = 0.0;
  CHECK_THROWS_WITH(depth.validate(), Catch::Contains("contact_depth"));
  Landmarks same;
  same.origin = same.insertion = {Vec3(0, 0, 5.0), Vec3(0.1, 0, 5.0)};
  same.origin_source = same.insertion_source = "same.xyz";
  try {
    decompose_repaired(mesh, same, {});
    FAIL("coinciding areas accepted");
  } catch (const InputError& e) { CHECK(e.code() == ErrorCode::landmarks); }
}

TEST_CASE("fascicle decompose: one-line errors with their codes and no output", "[fibres][cli]") {
  test::TempDir dir;
  const std::string muscle = (dir.path() / "capsule.off").string();
  write_triangle_mesh(muscle, capsule());
  const std::string out = (dir.path() / "fibres.vtk").string();
  const std::string fascicle = test::program();
  CHECK(test::run_command(fascicle + " decompose " + muscle + " -o " + out + " --fibres 0 2>/dev/null") == 18);
  CHECK_FALSE(std::filesystem::exists(out));
  CHECK(test::run_command(fascicle + " decompose " + muscle + " -o " + out + " --resolution 1 2>/dev/null") == 18);
  CHECK_FALSE(std::filesystem::exists(out));
  CHECK(test::run_command(fascicle + " decompose " + muscle + " -o " + out + " --corner-twist 200 2>/dev/null") == 18);
  CHECK_FALSE(std::filesystem::exists(out));
  for (const char* bad : {" --connect-margin -0.1", " --max-end-fraction 0.6", " --max-end-fraction 0.05"}) {
    CHECK(test::run_command(fascicle + " decompose " + muscle + " -o " + out + bad + " 2>/dev/null") == 18);
    CHECK_FALSE(std::filesystem::exists(out));
  }
  CHECK(test::run_command(fascicle + " decompose " + (dir.path() / "missing.off").string() + " -o " + out +
                          " 2>/dev/null") == 3);
  CHECK_FALSE(std::filesystem::exists(out));
  // Far landmarks: the landmarks code, no output.
  const std::string far = (dir.path() / "far.xyz").string();
  std::ofstream(far) << "0 0 500\n";
  const std::string near = (dir.path() / "near.xyz").string();
  std::ofstream(near) << "0 0 0\n";
  CHECK(test::run_command(fascicle + " decompose " + muscle + " -o " + out + " --origin " + far + " --insertion " +
                          near + " 2>/dev/null") == 16);
  CHECK_FALSE(std::filesystem::exists(out));
  // A run writes the report; its exit code is 0 or the quality code (19), which then writes no
  // fibres unless --keep-failed.
  const std::string report = (dir.path() / "r.json").string();
  const int code = test::run_command(fascicle + " decompose " + muscle + " -o " + out + " --report " + report +
                                     " --keep-failed 2>/dev/null");
  CHECK((code == 0 || code == 19));
  CHECK(std::filesystem::exists(out));
  CHECK(std::filesystem::exists(report));
  const Polylines back = read_polylines(out);
  CHECK(back.lines.size() == 100);
  // The capsule's automatic ends are one piece each: the requested share, reported.
  std::ifstream in(report);
  const nlohmann::json r = nlohmann::json::parse(in);
  for (const char* end : {"origin", "insertion"}) {
    CHECK(r["attachments"][end]["end_pieces"] == 1);
    CHECK(r["attachments"][end]["end_fraction"].get<double>() == Approx(0.1));
  }
}

TEST_CASE("fascicle batch: one report per muscle, a summary, past failures, resumable", "[fibres][cli][batch]") {
  test::TempDir dir;
  const std::filesystem::path in = dir.path() / "in";
  std::filesystem::create_directories(in / "sub");
  write_triangle_mesh((in / "capsule.off").string(), capsule());
  std::ofstream((in / "sub" / "broken.off").string()) << "not a mesh\n";
  const std::filesystem::path out = dir.path() / "out";
  const std::string cmd =
      test::program() + " -q batch " + in.string() + " -o " + out.string() + " --jobs 2 --keep-failed";
  // The broken mesh fails, the batch goes on and says so with the broken mesh's code.
  CHECK(test::run_command(cmd + " 2>/dev/null") == 5);
  CHECK(std::filesystem::exists(out / "capsule.vtk"));
  CHECK(std::filesystem::exists(out / "capsule.report.json"));
  CHECK(std::filesystem::exists(out / "sub" / "broken.report.json"));
  CHECK_FALSE(std::filesystem::exists(out / "sub" / "broken.vtk"));
  std::ifstream summary((out / "summary.csv").string());
  std::string header, a, b, extra;
  std::getline(summary, header);
  std::getline(summary, a);
  std::getline(summary, b);
  CHECK(header ==
        "muscle,status,exit_code,seconds,inside_fraction,inverted_cells,coverage_p95,attachment,crossing_segments,"
        "segment_excursion,layer_ratio,fibre_length_m,pennation_deg,pcsa_cm2,max_isometric_force_n,error");
  CHECK(a.rfind("capsule,", 0) == 0);
  {
    // The segment figures of the report's quality section: a count and a fraction of the length.
    std::vector<std::string> fields;
    std::stringstream row(a);
    for (std::string field; std::getline(row, field, ',');) fields.push_back(field);
    REQUIRE(fields.size() >= 11);
    CHECK(std::stol(fields[8]) >= 0);
    CHECK(std::stod(fields[9]) >= 0.0);
    CHECK(std::stod(fields[10]) >= 1.0);  // the longest layer step over the median one
  }
  CHECK(b.rfind("sub/broken,failed,5,", 0) == 0);
  CHECK_FALSE(std::getline(summary, extra));
  // Resumable: a second run redoes nothing (the fibre file keeps its time stamp).
  const auto stamp = std::filesystem::last_write_time(out / "capsule.vtk");
  CHECK(test::run_command(cmd + " 2>/dev/null") == 5);
  CHECK(std::filesystem::last_write_time(out / "capsule.vtk") == stamp);
  // A list file works as input too; a missing entry is a one-line error (code 3).
  const std::string list = (dir.path() / "list.txt").string();
  std::ofstream(list) << "# muscles\n" << (in / "capsule.off").string() << "\n" << (in / "nope.off").string() << "\n";
  CHECK(test::run_command(test::program() + " -q batch " + list + " -o " + (dir.path() / "out2").string() +
                          " 2>/dev/null") == 3);
}

TEST_CASE("fascicle batch killed with SIGKILL leaves only complete outputs and resumes", "[fibres][cli][batch]") {
  test::TempDir dir;
  const std::filesystem::path in = dir.path() / "in";
  std::filesystem::create_directories(in);
  for (int i = 0; i < 8; ++i) write_triangle_mesh((in / ("m" + std::to_string(i) + ".off")).string(), capsule());
  const std::filesystem::path out = dir.path() / "out";
  const std::string cmd =
      test::program() + " -q batch " + in.string() + " -o " + out.string() + " --jobs 2 --keep-failed";
  // Start the batch, kill it hard part-way (wherever the kill lands, the checks below hold).
  const std::string pid_file = (dir.path() / "pid").string();
  REQUIRE(test::run_command(cmd + " > /dev/null 2>&1 & echo $! > " + pid_file) == 0);
  ::usleep(700 * 1000);
  std::string pid;
  std::ifstream(pid_file) >> pid;
  REQUIRE_FALSE(pid.empty());
  test::run_command("kill -9 " + pid + " 2>/dev/null");
  ::usleep(500 * 1000);  // its decompose processes die with it
  auto fibre_files = [&] {
    std::vector<std::filesystem::path> files;
    if (std::filesystem::exists(out))
      for (const auto& e : std::filesystem::directory_iterator(out))
        if (e.path().extension() == ".vtk") files.push_back(e.path());
    return files;
  };
  for (const auto& f : fibre_files()) CHECK(read_polylines(f.string()).lines.size() == 100);  // complete
  // Resume: the rest is done, what was done stays, no temporary file remains.
  const int code = test::run_command(cmd + " 2>/dev/null");
  CHECK((code == 0 || code == 19));
  CHECK(fibre_files().size() == 8);
  for (const auto& f : fibre_files()) CHECK(read_polylines(f.string()).lines.size() == 100);
  for (const auto& e : std::filesystem::recursive_directory_iterator(out)) {
    INFO(e.path().string());
    CHECK(e.path().filename().string().find(".tmp.") == std::string::npos);
  }
}

TEST_CASE("a surface finer than map_faces is mapped simplified, and the fibres fill the muscle itself",
          "[fibres][decompose]") {
  TriangleMesh mesh = make_capsule(10.0, 1.5, 64);
  for (Vec3& p : mesh.positions) p = Vec3(p.y(), p.z(), p.x());
  REQUIRE(mesh.triangles.size() > 4000);
  DecomposeOptions options;
  options.map_faces = 1000;
  const Decomposition d = decompose_repaired(mesh, Landmarks{}, options);
  CHECK(d.report.status == "ok");
  CHECK(d.report.quality.pass);
  const nlohmann::json& simplified = d.report.sphere.at("simplified");
  CHECK(simplified.at("faces_before").get<long>() == static_cast<long>(mesh.triangles.size()));
  CHECK(simplified.at("faces_after").get<long>() <= 1000);
  // Checked against the muscle given: every point inside it, the ends on its surface.
  CHECK(d.report.quality.inside_fraction == 1.0);
  CHECK(d.muscle.triangles.size() == mesh.triangles.size());
  // The same input gives the same fibres.
  const Decomposition again = decompose_repaired(mesh, Landmarks{}, options);
  CHECK(again.fibres.lines == d.fibres.lines);
  // At or under the limit nothing is simplified.
  options.map_faces = static_cast<long>(mesh.triangles.size());
  CHECK_FALSE(decompose_repaired(mesh, Landmarks{}, options).report.sphere.contains("simplified"));
  DecomposeOptions negative;
  negative.map_faces = 999;
  CHECK_THROWS_AS(negative.validate(), OptionError);
}

TEST_CASE("ends gathered on thin tendons call the deep-faces try, whose ends spread over the areas",
          "[fibres][decompose]") {
  // The sample muscle's automatic areas are mostly the sides of its thin tendons: cast along the
  // end axis, the first try's ends land on the tendons' tips.
  const TriangleMesh mesh = make_fusiform_muscle();
  const Decomposition d = decompose_repaired(mesh, Landmarks{}, DecomposeOptions{});
  REQUIRE(d.report.status == "ok");
  const nlohmann::json attempts = d.report.to_json()["attempts"];
  INFO(attempts.dump());
  REQUIRE(attempts.size() == 2);
  CHECK(attempts[0]["whole_check_failed"] == nlohmann::json{"ends"});
  CHECK(attempts[1]["change"] == "deep_faces");
  CHECK(attempts[1]["failure_modes"] == nlohmann::json{"gathered_ends"});
  CHECK(attempts[1]["max_face_depth"] == 1.0);
  // The second passes the whole check and is kept.
  CHECK(d.report.kept_attempt == 1);
  CHECK(failed_criteria(d.report.quality, CheckOptions{}).empty());
  // With one try only, the first result is returned.
  DecomposeOptions one;
  one.tries.second_try = false;
  const Decomposition first = decompose_repaired(mesh, Landmarks{}, one);
  CHECK(first.report.attempts.size() == 1);
  CHECK(failed_criteria(first.report.quality, CheckOptions{}) == std::vector<std::string>{"ends"});
}
