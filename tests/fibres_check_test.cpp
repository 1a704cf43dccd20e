// The fibre quality check (fibres/fibre_check.h) and `fascicle check`, on synthetic cases whose
// figures follow from geometry: a straight square lattice of fibres in a box covers it with
// nearest-fibre distances distributed as the distance from a uniform point of a unit square to
// its centre (mean (sqrt 2 + ln(1 + sqrt 2)) / 6 = 0.38260, 95th percentile 0.59905 spacings).
#include "fibres/fibre_check.h"
#include "fibres/fibre_grid.h"
#include "geometry/errors.h"
#include "geometry/mesh_io.h"
#include "geometry/mesh_stats.h"
#include "geometry/primitives.h"
#include "morph/attachments.h"
#include "test_common.h"

#include <catch2/catch.hpp>
#include <nlohmann/json.hpp>

#include <cmath>
#include <fstream>
#include <random>
#include <sstream>

using namespace fascicle;
using fascicle::test::TempDir;
using test::read_text;

namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kSize = 10.0;  // box: x in [-kSize, kSize], y and z in [-kSize/2, kSize/2]

/// The box [-s, s] x [-s/2, s/2]^2 (a cube stretched along x), 2n quads per cube edge so that
/// the centres of an n x n lattice over the end faces are mesh vertices.
TriangleMesh long_box(int n) {
  TriangleMesh box = make_cube(kSize, 2 * n);
  for (Vec3& p : box.positions) p.x() *= 2.0;
  return box;
}

/// n x n straight fibres along x through the centres of the squares of side h = kSize / n,
/// from x = from to x = to, `points` points each, lattice indices r along y and s along z.
Polylines straight_lattice(int n, int points, double from = -kSize, double to = kSize) {
  const double h = kSize / n;
  std::vector<std::vector<Vec3>> lines;
  std::vector<int> r, s;
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      std::vector<Vec3> line;
      for (int k = 0; k < points; ++k) {
        const double t = static_cast<double>(k) / (points - 1);
        line.emplace_back(from + t * (to - from), -kSize / 2 + (i + 0.5) * h, -kSize / 2 + (j + 0.5) * h);
      }
      lines.push_back(std::move(line));
      r.push_back(i);
      s.push_back(j);
    }
  return lattice_fibres(std::move(lines), r, s);
}

/// Automatic areas of the box; the fibres are reversed when the origin is at +x.
Attachments areas_for(const TriangleMesh& box, Polylines& fibres) {
  Attachments areas = automatic_attachments(box);
  if (areas.origin.centroid().x() > 0)
    for (auto& line : fibres.lines) std::reverse(line.begin(), line.end());
  return areas;
}

bool has_failed(const CheckReport& report, const std::string& name) {
  return std::find(report.failed.begin(), report.failed.end(), name) != report.failed.end();
}

int run(const std::string& args, const std::string& out = "/dev/null") {
  return fascicle::test::run_command(fascicle::test::program() + " " + args + " > " + out + " 2>/dev/null");
}

}  // namespace

TEST_CASE("straight lattice fibres in a box pass with the figures geometry predicts", "[fibres][check]") {
  for (int n : {1, 6}) {
    CAPTURE(n);
    const TriangleMesh box = long_box(n);
    Polylines fibres = straight_lattice(n, 11);
    const Attachments areas = areas_for(box, fibres);
    const CheckReport report = check_fibres(fibres, box, areas);
    CHECK(report.fibres == n * n);
    CHECK(report.points == n * n * 11);
    CHECK(report.inside_fraction == 1.0);
    CHECK(report.outside == 0);
    CHECK(report.lattice);
    CHECK(report.cells == (n - 1) * (n - 1) * 10);
    CHECK(report.inverted_cells == 0);
    // V = 2 s^3, F = n^2, L = 2 s: ideal spacing s / n, the lattice spacing.
    CHECK(report.coverage.volume == Approx(2 * kSize * kSize * kSize).epsilon(1e-12));
    CHECK(report.coverage.ideal_spacing == Approx(kSize / n).epsilon(1e-12));
    CHECK(report.coverage.samples == 20000);
    CHECK(report.coverage.mean == Approx(0.38260).margin(0.01));
    CHECK(report.coverage.p95 == Approx(0.59905).margin(0.01));
    CHECK(report.coverage.max <= std::sqrt(0.5) + 1e-9);
    CHECK(report.attachment.muscle_length == Approx(2 * kSize).epsilon(1e-12));
    CHECK(report.attachment.origin_max < 1e-9);
    CHECK(report.attachment.insertion_max < 1e-9);
    CHECK(report.length.mean == Approx(2 * kSize).epsilon(1e-12));
    CHECK(report.length.cv == Approx(0.0).margin(1e-9));
    CHECK(report.max_turning_angle_deg == Approx(0.0).margin(1e-6));
    // Straight segments in a box never leave it; the ends lie on the end faces (within the end
    // tolerance), which does not make the end segments cross.
    CHECK(report.segments == n * n * 10);
    CHECK(report.crossing_segments == 0);
    CHECK(report.segment_inside_fraction == 1.0);
    CHECK(report.max_segment_excursion == 0.0);
    CHECK(report.pass);
    CHECK(report.failed.empty());
    CHECK(failed_criteria(report, report.thresholds) == report.failed);
    // The same figures judged again under stricter thresholds fail those criteria, in order.
    CheckOptions strict = report.thresholds;
    strict.max_coverage_p95 = 0.5 * report.coverage.p95;
    strict.min_end_coverage = 1.01;
    CHECK(failed_criteria(report, strict) == std::vector<std::string>{"coverage", "ends"});
  }
}

TEST_CASE("a segment between two inside points that cuts a bend leaves the muscle", "[fibres][check]") {
  // A half ring: tube radius 2 round an arc of radius 10. A fibre along the axis with points
  // 1 degree apart stays inside; with three points (0, 90, 180 degrees, 0.01 rad in from the
  // caps) each chord cuts the inner wall: its middle is 10 cos(theta / 2) from the centre, theta
  // the chord's angle, inside the inner wall at radius 8 by about 0.894.
  const double R = 10.0, r = 2.0;
  const TriangleMesh tube = make_bent_tube(R, r, kPi, 64);
  auto arc = [&](int points) {
    std::vector<Vec3> line;
    for (int k = 0; k < points; ++k) {
      const double a = 0.01 + (kPi - 0.02) * k / (points - 1);
      line.emplace_back(R * std::cos(a), R * std::sin(a), 0.0);
    }
    return line;
  };
  Polylines fibres;
  fibres.lines = {arc(181), arc(3)};
  const Attachments areas = automatic_attachments(tube);
  CheckReport report = check_fibres(fibres, tube, areas);
  CHECK(report.inside_fraction == 1.0);  // every point is inside
  CHECK(report.segments == 180 + 2);
  CHECK(report.crossing_segments == 2);
  CHECK(report.segment_inside_fraction == Approx(1.0 - 2.0 / 182).epsilon(1e-12));
  REQUIRE(report.crossing_examples.size() == 2);
  for (int k = 0; k < 2; ++k) {
    CHECK(report.crossing_examples[static_cast<std::size_t>(k)].fibre == 1);
    CHECK(report.crossing_examples[static_cast<std::size_t>(k)].segment == k);
  }
  const double chord_middle = R * std::cos((kPi / 2 - 0.01) / 2);
  CHECK(report.max_segment_excursion == Approx((R - r) - chord_middle).margin(0.02));
  CHECK(report.max_segment_excursion_relative ==
        Approx(report.max_segment_excursion / report.attachment.muscle_length).epsilon(1e-12));
  CHECK(report.touching_segments == 2);
  CHECK(report.max_segment_excursion_diagonal ==
        Approx(report.max_segment_excursion / bounding_box(tube.positions).diagonal()).epsilon(1e-12));
  CHECK(has_failed(report, "segments"));  // judged by default: none may leave
  CHECK(report.to_table().find("crossing_segs") != std::string::npos);
  CHECK(report.to_table().find("crossing: fibre 1 between points 0 and 1") != std::string::npos);
  CHECK(report.summary().find("segments out 2 (<= 0 beyond 0.5 %) FAIL") != std::string::npos);

  CheckOptions judged;
  judged.max_crossing_segments = 2;
  CHECK_FALSE(has_failed(check_fibres(fibres, tube, areas, judged), "segments"));
  judged.max_crossing_segments = -1;  // reported, not judged
  CHECK_FALSE(has_failed(check_fibres(fibres, tube, areas, judged), "segments"));
  // A tolerance beyond the excursion: the chords touch the surface but do not cross.
  judged.max_crossing_segments = 0;
  judged.segment_tolerance = 1.01 * report.max_segment_excursion_diagonal;
  const CheckReport tolerant = check_fibres(fibres, tube, areas, judged);
  CHECK(tolerant.touching_segments == 2);
  CHECK(tolerant.crossing_segments == 0);
  CHECK_FALSE(has_failed(tolerant, "segments"));

  // A point outside makes both its segments cross.
  Polylines dense;
  dense.lines = {arc(181)};
  dense.lines[0][90].z() = 3 * r;
  report = check_fibres(dense, tube, areas);
  CHECK(report.outside == 1);
  CHECK(report.crossing_segments == 2);
  CHECK(report.max_segment_excursion > 0.0);
}

TEST_CASE("a fibre point outside the muscle fails the inside criterion", "[fibres][check]") {
  const TriangleMesh box = long_box(4);
  Polylines fibres = straight_lattice(4, 11);
  const Attachments areas = areas_for(box, fibres);
  fibres.lines[5][4].y() = kSize;  // pokes out through the side y = s/2
  const CheckReport report = check_fibres(fibres, box, areas);
  CHECK(report.outside == 1);
  CHECK(report.inside_fraction == Approx(1.0 - 1.0 / (16 * 11)).epsilon(1e-12));
  REQUIRE(report.outside_examples.size() == 1);
  CHECK(report.outside_examples[0].fibre == 5);
  CHECK(report.outside_examples[0].point == 4);
  CHECK(report.outside_examples[0].distance == Approx(kSize / 2).epsilon(1e-9));
  CHECK_FALSE(report.pass);
  CHECK(has_failed(report, "inside"));

  // An interior point exactly on the surface is not strictly inside.
  Polylines on_surface = straight_lattice(4, 11);
  areas_for(box, on_surface);
  on_surface.lines[0][5].y() = -kSize / 2;
  CHECK(check_fibres(on_surface, box, areas).outside == 1);
}

TEST_CASE("the grid-accelerated inside test agrees with the exact test point by point", "[fibres][check]") {
  // Random points in and around a sphere, many of them in grid cells near the surface.
  const TriangleMesh sphere = make_icosphere(3, 10.0);
  const SurfaceQuery query(sphere);
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-10.5, 10.5);
  Polylines fibres;
  long expected_outside = 0;
  for (int f = 0; f < 400; ++f) {
    std::vector<Vec3> line;
    for (int k = 0; k < 6; ++k) {
      line.emplace_back(u(rng), u(rng), u(rng));
      if (query.side(line.back()) != Side::inside) ++expected_outside;
    }
    fibres.lines.push_back(std::move(line));
  }
  Attachments areas = automatic_attachments(sphere);
  CheckOptions options;
  options.end_tolerance = 0.0;  // end points judged like the others
  options.coverage_samples = 1000;
  options.outside_listed = 100000;
  const CheckReport report = check_fibres(fibres, sphere, query, areas, options);
  REQUIRE(expected_outside > 100);
  CHECK(report.outside == expected_outside);
  for (const OutsidePoint& o : report.outside_examples) {
    CHECK(query.side(fibres.lines[static_cast<std::size_t>(o.fibre)][static_cast<std::size_t>(o.point)]) !=
          Side::inside);
    CHECK(o.distance == Approx(query.closest_point(o.position).distance));
  }
}

TEST_CASE("fibre ends may lie on or just outside the surface within the end tolerance", "[fibres][check]") {
  const TriangleMesh box = long_box(2);
  const double diagonal = bounding_box(box.positions).diagonal();
  Polylines fibres = straight_lattice(2, 5);
  const Attachments areas = areas_for(box, fibres);
  CHECK(check_fibres(fibres, box, areas).outside == 0);  // ends exactly on the end faces
  const double sign = fibres.lines[0].front().x() < 0 ? -1.0 : 1.0;
  fibres.lines[0].front().x() += sign * 0.5e-4 * diagonal;  // outside, within 1e-4 of the diagonal
  CHECK(check_fibres(fibres, box, areas).outside == 0);
  fibres.lines[0].front().x() += sign * 1e-4 * diagonal;  // now 1.5e-4 out
  const CheckReport report = check_fibres(fibres, box, areas);
  CHECK(report.outside == 1);
  CHECK(report.outside_examples.at(0).point == 0);
  CheckOptions wide;
  wide.end_tolerance = 2e-4;
  CHECK(check_fibres(fibres, box, areas, wide).outside == 0);
}

TEST_CASE("a folded lattice has inverted cells and a mirrored one has none", "[fibres][check]") {
  const TriangleMesh box = long_box(4);
  Polylines fibres = straight_lattice(4, 11);
  const Attachments areas = areas_for(box, fibres);
  // Mirror the lattice (r -> 3 - r): the whole frame flips, no cell is folded relative to it.
  Polylines mirrored = fibres;
  for (double& r : mirrored.cell_data[0].values) r = 3 - r;
  const CheckReport mirror_report = check_fibres(mirrored, box, areas);
  CHECK(mirror_report.cells == 3 * 3 * 10);
  CHECK(mirror_report.inverted_cells == 0);
  CHECK(mirror_report.inverted_examples.empty());

  // Fibres (1,1) and (2,1) swap places for points 3..5: they cross, and the cells between them
  // and their neighbours fold.
  const int a = 1 + 4 * 1, b = 2 + 4 * 1;
  for (int k = 3; k <= 5; ++k) std::swap(fibres.lines[a][k], fibres.lines[b][k]);
  const CheckReport report = check_fibres(fibres, box, areas);
  CHECK(report.inverted_cells > 0);
  CHECK(report.inverted_cells <= 3 * 3 * 4);  // only cells touching points 3..5 (k = 2..5)
  REQUIRE_FALSE(report.inverted_examples.empty());
  CHECK(static_cast<long>(report.inverted_examples.size()) == std::min<long>(report.inverted_cells, 10));
  for (const auto& c : report.inverted_examples) {
    CHECK(c[0] <= 2);  // a cell next to fibre (1,1) or (2,1)
    CHECK(c[1] <= 1);
    CHECK((c[2] >= 2 && c[2] <= 5));
  }
  CHECK(report.inside_fraction == 1.0);
  CHECK(has_failed(report, "inverted_cells"));
  CHECK_FALSE(report.pass);

  // A collapsed cell (two neighbouring fibres on top of each other) is flat: inverted too.
  Polylines collapsed = straight_lattice(4, 11);
  areas_for(box, collapsed);
  collapsed.lines[0] = collapsed.lines[1];
  CHECK(check_fibres(collapsed, box, areas).inverted_cells >= 10);
}

TEST_CASE("fibres without lattice arrays are checked without cells", "[fibres][check]") {
  const TriangleMesh box = long_box(3);
  Polylines fibres = straight_lattice(3, 7);
  const Attachments areas = areas_for(box, fibres);
  fibres.cell_data.clear();
  const CheckReport report = check_fibres(fibres, box, areas);
  CHECK_FALSE(report.lattice);
  CHECK(report.cells == 0);
  CHECK(report.inverted_cells == 0);
  CHECK(report.pass);
}

TEST_CASE("fibres ending far from their areas fail the attachment criterion", "[fibres][check]") {
  const TriangleMesh box = long_box(3);
  // From x = -s/2 to x = s: the -x ends stop a quarter of the length short of the -x end.
  Polylines fibres = straight_lattice(3, 11, -kSize / 2, kSize);
  Attachments areas = automatic_attachments(box);
  const bool origin_at_minus_x = areas.origin.centroid().x() < 0;
  if (!origin_at_minus_x)
    for (auto& line : fibres.lines) std::reverse(line.begin(), line.end());
  const CheckReport report = check_fibres(fibres, box, areas);
  const double short_end = origin_at_minus_x ? report.attachment.origin_max : report.attachment.insertion_max;
  const double full_end = origin_at_minus_x ? report.attachment.insertion_max : report.attachment.origin_max;
  // The nearest area point is at least 0.3 s away (the areas reach 0.2 s in from the end face).
  CHECK(short_end > 0.3 * kSize / (2 * kSize));
  CHECK(full_end < 1e-9);
  CHECK(report.inside_fraction == 1.0);
  CHECK(has_failed(report, "attachment"));
  CHECK_FALSE(report.pass);

  // Reversed fibres (insertion to origin) fail too: each end is at the wrong area.
  Polylines reversed = straight_lattice(3, 11);
  if (origin_at_minus_x)
    for (auto& line : reversed.lines) std::reverse(line.begin(), line.end());
  const CheckReport wrong_way = check_fibres(reversed, box, areas);
  CHECK(wrong_way.attachment.origin_max > 0.5);
  CHECK(has_failed(wrong_way, "attachment"));
}

TEST_CASE("fibres bunched in one corner fail the coverage criterion", "[fibres][check]") {
  const TriangleMesh box = long_box(4);
  Polylines fibres = straight_lattice(4, 11);
  const Attachments areas = areas_for(box, fibres);
  // Squeeze the lattice into the quarter y, z < 0 (r, s and the ends keep their order).
  for (auto& line : fibres.lines)
    for (Vec3& p : line) {
      p.y() = -kSize / 2 + 0.25 * (p.y() + kSize / 2);
      p.z() = -kSize / 2 + 0.25 * (p.z() + kSize / 2);
    }
  const CheckReport report = check_fibres(fibres, box, areas);
  CHECK(report.inverted_cells == 0);
  CHECK(report.inside_fraction == 1.0);
  CHECK(report.coverage.p95 > 2.0);
  CHECK(has_failed(report, "coverage"));
}

TEST_CASE("far samples are counted where they lie along the muscle and in depth", "[fibres][check]") {
  // Fibres only over the origin half of the box: the insertion half is thin from the middle on.
  // n = 4, L = kSize: ideal spacing sqrt(2 kSize^3 / (16 kSize)) = 3.54, so a sample is far
  // beyond 7.07 from every fibre: none in the origin half (at most 1.77 off a fibre) nor in the
  // tenth next to the middle, all in the tenth at the insertion end (at least 8 from the ends).
  const TriangleMesh box = long_box(4);
  const Attachments areas = automatic_attachments(box);
  const double origin_x = areas.origin.centroid().x() > 0 ? kSize : -kSize;
  const Polylines fibres = straight_lattice(4, 11, origin_x, 0.0);
  const CheckReport report = check_fibres(fibres, box, areas);
  const FarSamples& far = report.coverage.far;
  CHECK(far.threshold == 2.0);
  int along = 0, along_far = 0, depth = 0, depth_far = 0;
  for (int b = 0; b < FarSamples::kAlongBins; ++b) {
    along += far.along_samples[static_cast<std::size_t>(b)];
    along_far += far.along_far[static_cast<std::size_t>(b)];
    CHECK(far.along_samples[static_cast<std::size_t>(b)] > 1000);  // about 2000 a tenth
  }
  for (int b = 0; b < FarSamples::kDepthBins; ++b) {
    depth += far.depth_samples[static_cast<std::size_t>(b)];
    depth_far += far.depth_far[static_cast<std::size_t>(b)];
  }
  CHECK(along == report.coverage.samples);
  CHECK(depth == report.coverage.samples);
  CHECK(along_far == depth_far);
  CHECK(far.fraction == Approx(static_cast<double>(along_far) / report.coverage.samples).epsilon(1e-12));
  for (int b = 0; b <= 5; ++b) CHECK(far.along_far[static_cast<std::size_t>(b)] == 0);
  CHECK(far.along_far[9] == far.along_samples[9]);
  CHECK(far.fraction == Approx(0.15).margin(0.01));  // the insertion end beyond x = 7.07 of 20
  // Depth below the surface: the box is 10 wide, so no sample lies deeper than 5 = 1.41 spacings.
  CHECK(far.depth_measured);  // the coverage criterion fails: the depth is measured
  CHECK(far.depth_samples[0] > 0);
  CHECK(far.depth_samples[1] > 0);
  CHECK(far.depth_samples[2] == 0);
  CHECK(far.depth_samples[3] == 0);
  const nlohmann::json j = report.to_json().at("coverage").at("far");
  CHECK(j.at("fraction").get<double>() == far.fraction);
  CHECK(j.at("along_far").at(9).get<int>() == far.along_far[9]);
  CHECK(j.at("depth_samples").size() == 4);
  CHECK(report.to_table().find("far samples (> 2 spacings)") != std::string::npos);
}

TEST_CASE("the far samples' depth is measured only where the coverage criterion fails", "[fibres][check]") {
  const TriangleMesh box = long_box(4);
  Polylines fibres = straight_lattice(4, 11);
  const CheckReport report = check_fibres(fibres, box, areas_for(box, fibres));
  REQUIRE(report.coverage.p95 <= report.thresholds.max_coverage_p95);
  const FarSamples& far = report.coverage.far;
  CHECK_FALSE(far.depth_measured);
  int along = 0, depth = 0;
  for (int b = 0; b < FarSamples::kAlongBins; ++b) along += far.along_samples[static_cast<std::size_t>(b)];
  for (int b = 0; b < FarSamples::kDepthBins; ++b) depth += far.depth_samples[static_cast<std::size_t>(b)];
  CHECK(along == report.coverage.samples);  // the breakdown along the muscle is always there
  CHECK(depth == 0);
  CHECK_FALSE(report.to_json().at("coverage").at("far").at("depth_measured").get<bool>());
  CHECK(report.to_table().find("by depth") == std::string::npos);
}

TEST_CASE("lengths and the largest turning angle", "[fibres][check]") {
  const TriangleMesh box = long_box(1);
  Polylines fibres;
  fibres.lines = {{Vec3(-kSize, 0, 0), Vec3(0, 0, 0), Vec3(0, 2, 0), Vec3(0, 2, 0), Vec3(kSize, 2, 0)},
                  {Vec3(-kSize, 1, 1), Vec3(kSize, 1, 1)}};
  Attachments areas = automatic_attachments(box);
  const CheckReport report = check_fibres(fibres, box, areas);
  CHECK(report.length.min == Approx(2 * kSize));
  CHECK(report.length.max == Approx(2 * kSize + 2));
  CHECK(report.length.mean == Approx(2 * kSize + 1));
  CHECK(report.length.cv == Approx(1.0 / (2 * kSize + 1)));
  // The repeated point has no direction; the corners turn by 90 degrees.
  CHECK(report.max_turning_angle_deg == Approx(90.0).epsilon(1e-12));
}

TEST_CASE("the smooth criterion: the largest turn, where it is, and the joints over 30 and 45 degrees",
          "[fibres][check]") {
  const TriangleMesh box = long_box(3);
  Polylines fibres = straight_lattice(3, 11);
  const Attachments areas = areas_for(box, fibres);
  CHECK(check_fibres(fibres, box, areas).turning.joints == 9 * 9);
  // Fibre 4, point 5 moved sideways by half a step: joints 4 and 6 turn by atan(1/2) = 26.57
  // degrees, joint 5 by twice that.
  auto& line = fibres.lines[4];
  const double step = (line[1] - line[0]).norm();
  line[5].y() += 0.5 * step;
  CheckReport report = check_fibres(fibres, box, areas);
  CHECK(report.turning.max_deg == Approx(2.0 * std::atan(0.5) * 180.0 / kPi).epsilon(1e-9));
  CHECK(report.turning.fibre == 4);
  CHECK(report.turning.joint == 5);
  CHECK(report.turning.over_30 == 1);
  CHECK(report.turning.over_45 == 1);
  CHECK(report.turning.end_joints_over_45 == 0);
  CHECK_FALSE(report.turning.max_at_end);
  CHECK(has_failed(report, "smooth"));
  CheckOptions loose;
  loose.max_turning_angle_deg = 60.0;
  CHECK_FALSE(has_failed(check_fibres(fibres, box, areas, loose), "smooth"));
  // A hook at the end: the second point off to the side turns the first joint.
  Polylines hooked = straight_lattice(3, 11);
  const Attachments hooked_areas = areas_for(box, hooked);
  hooked.lines[0][1].z() += 2.0 * step;
  report = check_fibres(hooked, box, hooked_areas);
  CHECK(report.turning.fibre == 0);
  CHECK(report.turning.joint == 1);
  CHECK(report.turning.end_joints_over_45 >= 1);
  CHECK(report.turning.max_at_end);
  CHECK(report.to_json()["turning"]["max_at_end"] == true);
}

TEST_CASE("the ends criterion: ends spread over their areas pass, ends gathered into a point fail", "[fibres][check]") {
  const TriangleMesh box = long_box(6);
  Polylines spread = straight_lattice(6, 11);
  const Attachments areas = areas_for(box, spread);
  const CheckReport good = check_fibres(spread, box, areas);
  CHECK(good.origin_ends.share > 0.9);
  CHECK(good.insertion_ends.share > 0.9);
  CHECK(good.origin_ends.samples > 2500);
  // The area is the end band: the end face (10 x 10) and a tenth of the length of the sides.
  CHECK(good.origin_ends.area == Approx(100.0 + 4 * 10.0 * 2.0).epsilon(0.1));
  CHECK(good.origin_ends.spacing == Approx(std::sqrt(good.origin_ends.area / 36.0)).epsilon(1e-12));
  CHECK_FALSE(has_failed(good, "ends"));
  // Every fibre's insertion end moved to the centre of the end face.
  Polylines gathered = spread;
  for (auto& line : gathered.lines) line.back() = Vec3(line.back().x(), 0.0, 0.0);
  const CheckReport bad = check_fibres(gathered, box, areas);
  // A disk of one ideal spacing round the centre: pi / F of the area.
  CHECK(bad.insertion_ends.share == Approx(kPi / 36.0).epsilon(0.2));
  CHECK(bad.origin_ends.share == Approx(good.origin_ends.share).epsilon(1e-12));
  CHECK(has_failed(bad, "ends"));
  CheckOptions loose;
  loose.min_end_coverage = 0.05;
  CHECK_FALSE(has_failed(check_fibres(gathered, box, areas, loose), "ends"));
}

TEST_CASE("point spacing along the fibres: per fibre and per layer", "[fibres][check]") {
  // Three fibres of five points along x: steps 2, 2, 2, 6 (the last layer three times the
  // others), 3, 3, 3, 3 (even) and 1, 1, 1, 9.
  const auto fibre = [](double y, std::vector<double> steps) {
    std::vector<Vec3> line{Vec3(-6, y, 0)};
    for (double s : steps) line.push_back(line.back() + Vec3(s, 0, 0));
    return line;
  };
  Polylines fibres;
  fibres.lines = {fibre(0, {2, 2, 2, 6}), fibre(1, {3, 3, 3, 3}), fibre(2, {1, 1, 1, 9})};
  StepFigures steps = step_figures(fibres);
  CHECK(steps.mean == Approx(36.0 / 12.0));
  // Longest over mean: 6 / 3 = 2, 1, 9 / 3 = 3.
  CHECK(steps.max_ratio == Approx(3.0));
  CHECK(steps.median_ratio == Approx(2.0));
  CHECK(steps.worst_fibre == 2);
  CHECK(steps.worst_segment == 3);
  REQUIRE(steps.layers.size() == 4);
  CHECK(steps.layers[0] == Approx(2.0));
  CHECK(steps.layers[3] == Approx(6.0));
  CHECK(steps.layer_ratio == Approx(3.0));  // 6 over the median of 2, 2, 2, 6
  // Fibres of different point counts have no layers.
  fibres.lines.push_back({Vec3(-6, 3, 0), Vec3(6, 3, 0)});
  steps = step_figures(fibres);
  CHECK(steps.layers.empty());
  CHECK(steps.layer_ratio == 0.0);
  CHECK(steps.max_ratio == Approx(3.0));
  // In the report, its JSON and its table.
  const TriangleMesh box = long_box(1);
  const CheckReport report = check_fibres(fibres, box, automatic_attachments(box));
  CHECK(report.steps.max_ratio == steps.max_ratio);
  const nlohmann::json j = report.to_json();
  CHECK(j.at("steps").at("median_ratio").get<double>() == report.steps.median_ratio);
  CHECK(j.at("steps").at("worst_fibre").get<int>() == 2);
  CHECK(report.to_table().find("(fibre 2 between points 3 and 4)") != std::string::npos);
  // Evenly spaced lattice fibres: every ratio 1.
  Polylines even = straight_lattice(3, 7);
  steps = step_figures(even);
  CHECK(steps.max_ratio == Approx(1.0));
  CHECK(steps.layer_ratio == Approx(1.0));
}

TEST_CASE("the check is deterministic for a seed and reports as JSON", "[fibres][check]") {
  const TriangleMesh box = long_box(3);
  Polylines fibres = straight_lattice(3, 7);
  const Attachments areas = areas_for(box, fibres);
  CheckOptions options;
  options.coverage_samples = 5000;
  const CheckReport a = check_fibres(fibres, box, areas, options);
  const CheckReport b = check_fibres(fibres, box, areas, options);
  CHECK(a.coverage.mean == b.coverage.mean);
  CHECK(a.coverage.p95 == b.coverage.p95);
  options.seed = 2;
  CHECK(check_fibres(fibres, box, areas, options).coverage.mean != a.coverage.mean);
  const nlohmann::json j = a.to_json();
  CHECK(j.at("inside_fraction").get<double>() == a.inside_fraction);
  CHECK(j.at("inverted_cells").get<long>() == a.inverted_cells);
  CHECK(j.at("coverage").at("p95").get<double>() == a.coverage.p95);
  CHECK(j.at("coverage").at("samples").get<int>() == 5000);
  CHECK(j.at("attachment").at("origin_max").get<double>() == a.attachment.origin_max);
  CHECK(j.at("length").at("cv").get<double>() == a.length.cv);
  CHECK(j.at("pass").get<bool>() == a.pass);
  CHECK(j.at("thresholds").at("max_coverage_p95").get<double>() == 2.0);
  const std::string table = a.to_table();
  CHECK(table.find("inside_fraction") != std::string::npos);
  CHECK(table.find("result: pass") != std::string::npos);
}

TEST_CASE("bad options and inputs are refused", "[fibres][check]") {
  const TriangleMesh box = long_box(1);
  Polylines fibres = straight_lattice(1, 3);
  const Attachments areas = areas_for(box, fibres);
  CheckOptions options;
  options.coverage_samples = 0;
  CHECK_THROWS_AS(check_fibres(fibres, box, areas, options), OptionError);
  options = {};
  options.min_inside_fraction = 1.5;
  CHECK_THROWS_AS(options.validate(), OptionError);
  options = {};
  options.end_tolerance = -1;
  CHECK_THROWS_AS(options.validate(), OptionError);
  options = {};
  options.max_attachment = 0;
  CHECK_THROWS_AS(options.validate(), OptionError);
  options = {};
  options.max_crossing_segments = -2;
  CHECK_THROWS_AS(options.validate(), OptionError);
  options = {};
  options.excursion_samples = 0;
  CHECK_THROWS_AS(options.validate(), OptionError);

  CHECK_THROWS_AS(check_fibres(Polylines{}, box, areas), InputError);
  Polylines single = fibres;
  single.lines[0].resize(1);
  CHECK_THROWS_AS(check_fibres(single, box, areas), InputError);
  Polylines nan = fibres;
  nan.lines[0][1].x() = std::nan("");
  CHECK_THROWS_AS(check_fibres(nan, box, areas), InputError);

  TriangleMesh inverted = box;
  for (Triangle& t : inverted.triangles) std::swap(t[1], t[2]);
  CHECK_THROWS_AS(check_fibres(fibres, inverted, areas), TopologyError);
  CHECK_THROWS_AS(check_fibres(fibres, TriangleMesh{}, areas), TopologyError);
  Attachments empty = areas;
  empty.insertion.points.clear();
  CHECK_THROWS_AS(check_fibres(fibres, box, empty), InputError);
}

TEST_CASE("fascicle check prints a table or JSON and writes the report and exits 19 with --strict",
          "[fibres][check][cli]") {
  TempDir dir;
  const TriangleMesh box = long_box(3);
  Polylines good = straight_lattice(3, 9);
  const Attachments areas = areas_for(box, good);
  const std::string mesh = dir.file("box.off"), fibres = dir.file("fibres.vtk");
  write_triangle_mesh(mesh, box);
  write_polylines(fibres, good);

  const std::string out = dir.file("out.txt");
  REQUIRE(run("check " + fibres + " " + mesh, out) == 0);
  CHECK(read_text(out).find("result: pass") != std::string::npos);

  const std::string report = dir.file("r.json");
  REQUIRE(run("check " + fibres + " " + mesh + " --json --report " + report, out) == 0);
  const nlohmann::json printed = nlohmann::json::parse(read_text(out));
  const nlohmann::json written = nlohmann::json::parse(read_text(report));
  CHECK(printed == written);
  CHECK(printed.at("inside_fraction").get<double>() == 1.0);
  CHECK(printed.at("inverted_cells").get<long>() == 0);
  CHECK(printed.at("lattice").get<bool>());
  CHECK(printed.at("muscle_repaired").get<bool>() == false);
  CHECK(printed.at("pass").get<bool>());
  CHECK(printed.at("crossing_segments").get<long>() == 0);
  CHECK(printed.at("segments").get<long>() == 9 * 8);
  CHECK(printed.at("thresholds").at("max_crossing_segments").get<long>() == 0);
  CHECK(printed.at("turning").at("max_deg").get<double>() == Approx(0.0).margin(1e-9));
  CHECK(printed.at("ends").at("origin").at("share").get<double>() > 0.9);
  REQUIRE(run("check " + fibres + " " + mesh +
                  " --json --strict --max-crossing-segments -1 --max-turning-angle 10 "
                  "--min-end-coverage 0.5 --segment-tolerance 0.01",
              out) == 0);
  const nlohmann::json loose = nlohmann::json::parse(read_text(out)).at("thresholds");
  CHECK(loose.at("max_crossing_segments").get<long>() == -1);
  CHECK(loose.at("max_turning_angle_deg").get<double>() == 10.0);
  CHECK(loose.at("min_end_coverage").get<double>() == 0.5);
  CHECK(loose.at("segment_tolerance").get<double>() == 0.01);
  REQUIRE(run("check " + fibres + " " + mesh + " --summary", out) == 0);
  CHECK(read_text(out).rfind("pass: inside 1 (>= 1), inverted cells 0 (<= 0), coverage p95 ", 0) == 0);

  // Landmark files replace the automatic areas.
  const double origin_x = good.lines[0].front().x();
  std::ofstream(dir.file("o.xyz")) << origin_x << " 0 0\n" << origin_x << " 1 1\n";
  std::ofstream(dir.file("i.xyz")) << -origin_x << " 0 0\n";
  REQUIRE(run("check " + fibres + " " + mesh + " --json --origin " + dir.file("o.xyz") + " --insertion " +
                  dir.file("i.xyz"),
              out) == 0);
  const nlohmann::json landmarks = nlohmann::json::parse(read_text(out));
  CHECK(landmarks.at("areas").at("automatic").get<bool>() == false);
  CHECK(landmarks.at("inside_fraction").get<double>() == 1.0);

  // A failing set: exit 0 without --strict, 19 with it (the report is still written).
  Polylines bad = good;
  bad.lines[4][4].z() = 3 * kSize;
  const std::string bad_file = dir.file("bad.csv");
  write_polylines(bad_file, bad);
  CHECK(run("check " + bad_file + " " + mesh, out) == 0);
  CHECK(read_text(out).find("FAIL: inside") != std::string::npos);
  const std::string bad_report = dir.file("bad.json");
  CHECK(run("check " + bad_file + " " + mesh + " --strict --report " + bad_report) == 19);
  CHECK(nlohmann::json::parse(read_text(bad_report)).at("outside_points").get<long>() == 1);

  // Errors: missing files (3), unreadable fibres (10), half the landmarks (18).
  CHECK(run("check " + dir.file("missing.vtk") + " " + mesh) == 3);
  CHECK(run("check " + fibres + " " + dir.file("missing.off")) == 3);
  std::ofstream(dir.file("broken.csv")) << "fibre,r,s,point,x,y,z\n0,0,0,0,1,2\n";
  CHECK(run("check " + dir.file("broken.csv") + " " + mesh) == 10);
  CHECK(run("check " + fibres + " " + mesh + " --origin " + dir.file("o.xyz")) == 18);
}

TEST_CASE("fascicle check repairs a muscle that is not closed genus 0", "[fibres][check][cli]") {
  TempDir dir;
  const TriangleMesh box = long_box(3);
  Polylines fibres = straight_lattice(3, 9);
  areas_for(box, fibres);
  // Drop one triangle: an open mesh the inside test cannot use until repaired.
  TriangleMesh open = box;
  open.triangles.erase(open.triangles.begin() + 7);
  write_triangle_mesh(dir.file("open.off"), open);
  write_polylines(dir.file("f.vtp"), fibres);
  const std::string out = dir.file("out.json");
  REQUIRE(run("check " + dir.file("f.vtp") + " " + dir.file("open.off") + " --json", out) == 0);
  const nlohmann::json j = nlohmann::json::parse(read_text(out));
  CHECK(j.at("muscle_repaired").get<bool>());
  CHECK(j.at("inside_fraction").get<double>() == 1.0);
  CHECK(j.at("coverage").at("volume").get<double>() == Approx(2 * kSize * kSize * kSize).epsilon(1e-3));
}
