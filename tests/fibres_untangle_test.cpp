// Barrier untangling of tetrahedral cells (fibres/untangle.h).
#include "fibres/fibre_grid.h"
#include "fibres/untangle.h"
#include "fibres/untangle_lattice.h"
#include "fibres/untangle_terms.h"
#include "geometry/errors.h"

#include <catch2/catch.hpp>
#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <map>
#include <random>
#include <set>
#include <tbb/global_control.h>

using namespace fascicle;

namespace {

// An n x n x n grid of the unit cube, boundary fixed, each cell split into the six Kuhn
// tetrahedra of the quality check (kuhn_tetrahedra()), reference = the cell.
struct Grid {
  int n = 0;
  std::vector<Vec3> positions;
  std::vector<char> fixed;
  std::vector<UntangleTet> tets;
  int index(int i, int j, int k) const { return i + n * (j + n * k); }
};

Grid make_grid(int n) {
  Grid g;
  g.n = n;
  const double h = 1.0 / (n - 1);
  for (int k = 0; k < n; ++k)
    for (int j = 0; j < n; ++j)
      for (int i = 0; i < n; ++i) {
        g.positions.emplace_back(i * h, j * h, k * h);
        g.fixed.push_back(i == 0 || j == 0 || k == 0 || i == n - 1 || j == n - 1 || k == n - 1 ? 1 : 0);
      }
  for (int k = 0; k + 1 < n; ++k)
    for (int j = 0; j + 1 < n; ++j)
      for (int i = 0; i + 1 < n; ++i)
        for (const std::array<int, 4>& local : kuhn_tetrahedra()) {
          UntangleTet tet;
          for (int v = 0; v < 4; ++v) {
            const int c = local[static_cast<std::size_t>(v)];
            tet.v[static_cast<std::size_t>(v)] = g.index(i + (c & 1), j + ((c >> 1) & 1), k + ((c >> 2) & 1));
          }
          Eigen::Matrix3d s;
          for (int col = 0; col < 3; ++col)
            s.col(col) = g.positions[static_cast<std::size_t>(tet.v[static_cast<std::size_t>(col) + 1])] -
                         g.positions[static_cast<std::size_t>(tet.v[0])];
          REQUIRE(s.determinant() > 0.0);
          tet.reference_inverse = s.inverse();
          g.tets.push_back(tet);
        }
  return g;
}

long inverted(const std::vector<Vec3>& x, const std::vector<UntangleTet>& tets) {
  long count = 0;
  for (double d : tet_jacobian_dets(x, tets)) count += d > 0.0 ? 0 : 1;
  return count;
}

}  // namespace

TEST_CASE("untangle: the regular grid is at rest and is left alone", "[fibres][untangle]") {
  Grid g = make_grid(5);
  const std::vector<Vec3> before = g.positions;
  const UntangleReport r = untangle(g.positions, g.fixed, g.tets);
  CHECK(r.inverted_before == 0);
  CHECK(r.inverted_after == 0);
  CHECK(r.iterations == 0);
  CHECK(g.positions == before);
  for (double d : tet_jacobian_dets(g.positions, g.tets)) CHECK(d == Approx(1.0));
}

TEST_CASE("untangle: a point pushed through its neighbours is brought back, fixed points untouched",
          "[fibres][untangle]") {
  Grid g = make_grid(6);
  const std::vector<Vec3> before = g.positions;
  // Fold: two interior points swapped along x, a third pushed past its neighbour in z.
  std::swap(g.positions[static_cast<std::size_t>(g.index(2, 2, 2))],
            g.positions[static_cast<std::size_t>(g.index(3, 2, 2))]);
  g.positions[static_cast<std::size_t>(g.index(2, 3, 3))].z() += 0.35;
  REQUIRE(inverted(g.positions, g.tets) > 0);
  const UntangleReport r = untangle(g.positions, g.fixed, g.tets);
  CHECK(r.inverted_before > 0);
  CHECK(r.untangled());
  CHECK(r.min_det_after > UntangleOptions{}.min_det);
  CHECK(inverted(g.positions, g.tets) == 0);
  for (std::size_t q = 0; q < g.positions.size(); ++q)
    if (g.fixed[q]) CHECK(g.positions[q] == before[q]);  // bitwise
  for (const Vec3& p : g.positions) CHECK(p.allFinite());
}

TEST_CASE("untangle: random interior tangles of a grid are unfolded", "[fibres][untangle]") {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> jitter(-0.3, 0.3);
  for (int trial = 0; trial < 5; ++trial) {
    Grid g = make_grid(7);
    for (std::size_t q = 0; q < g.positions.size(); ++q)
      if (!g.fixed[q]) g.positions[q] += Vec3(jitter(rng), jitter(rng), jitter(rng));
    REQUIRE(inverted(g.positions, g.tets) > 0);
    const UntangleReport r = untangle(g.positions, g.fixed, g.tets);
    INFO("trial " << trial << ": " << r.to_json().dump());
    CHECK(r.untangled());
    CHECK(inverted(g.positions, g.tets) == 0);
  }
}

TEST_CASE("untangle: an impossible problem is reported, not hidden", "[fibres][untangle]") {
  Grid g = make_grid(4);
  // A fixed corner-edge point moved across its neighbour: the tetrahedron (2,0,0) (3,0,0)
  // (3,1,0) (3,1,1) has four fixed points and turns over; nothing can unfold it.
  g.positions[static_cast<std::size_t>(g.index(3, 1, 0))].y() = -0.5;
  const UntangleReport r = untangle(g.positions, g.fixed, g.tets);
  CHECK(r.inverted_before > 0);
  CHECK_FALSE(r.untangled());
  CHECK(r.inverted_after > 0);
  for (const Vec3& p : g.positions) CHECK(p.allFinite());
}

TEST_CASE("untangle: uncounted tetrahedra do not stop it, anchors pull", "[fibres][untangle]") {
  Grid g = make_grid(5);
  const int q = g.index(2, 2, 2);
  const Vec3 start = g.positions[static_cast<std::size_t>(q)];
  const Vec3 target = start + Vec3(0.05, 0.0, 0.0);
  UntangleOptions pull;
  pull.keep_best = false;  // the pull only worsens the worst cell: with keep_best it is undone (below)
  const UntangleReport r = untangle(g.positions, g.fixed, g.tets, pull, {{q, target, 1e4}});
  CHECK(r.untangled());
  // Pulled most of the way to the anchor, against the cells' pull back.
  CHECK((g.positions[static_cast<std::size_t>(q)] - target).norm() < 0.5 * (start - target).norm());

  Grid h = make_grid(4);
  h.positions[static_cast<std::size_t>(h.index(3, 1, 0))].y() = -0.5;  // impossible, as above
  for (UntangleTet& t : h.tets) t.counted = false;
  const UntangleReport u = untangle(h.positions, h.fixed, h.tets);
  CHECK(u.counted == 0);
  CHECK(u.untangled());  // nothing counted, nothing to do
  CHECK(u.uncounted_inverted_after > 0);
}

TEST_CASE("untangle: ball and plane pins pull only where they should", "[fibres][untangle]") {
  // One point of an unfolded grid, pinned 0.05 along x from where it is, with each kind of pin.
  auto moved = [](UntangleAnchor anchor) {
    Grid g = make_grid(5);
    const int q = g.index(2, 2, 2);
    const Vec3 start = g.positions[static_cast<std::size_t>(q)];
    anchor.point = q;
    anchor.target = start + Vec3(0.05, 0.0, 0.0);
    anchor.weight = 1e4;
    UntangleOptions pull;
    pull.keep_best = false;  // see the test above
    const UntangleReport r = untangle(g.positions, g.fixed, g.tets, pull, {anchor});
    CHECK(r.untangled());
    return Vec3(g.positions[static_cast<std::size_t>(q)] - start);
  };
  UntangleAnchor spring;
  const Vec3 by_spring = moved(spring);
  CHECK(by_spring.x() > 0.025);
  // A ball round the target that holds the point already: no pull.
  UntangleAnchor ball;
  ball.radius = 0.06;
  CHECK(moved(ball).norm() < 1e-6);
  // A smaller ball: pulled to its rim at most (0.05 - 0.04 = 0.01 along x).
  ball.radius = 0.04;
  const Vec3 by_ball = moved(ball);
  CHECK(by_ball.x() > 0.002);
  CHECK(by_ball.x() < 0.0101);
  // A half-space whose outward normal is -x: the point lies outside it (x below the target's) and
  // is pushed along x only; with the normal +x it is inside: no pull.
  UntangleAnchor half;
  half.normal = Vec3(-1.0, 0.0, 0.0);
  const Vec3 by_half = moved(half);
  CHECK(by_half.x() > 0.025);
  CHECK(std::abs(by_half.y()) < 0.1 * by_half.x());  // along the normal (the cells pull a little across)
  half.normal = Vec3(1.0, 0.0, 0.0);
  CHECK(moved(half).norm() < 1e-6);
  // A two-sided plane pulls from either side.
  half.one_sided = false;
  CHECK(moved(half).x() > 0.025);
  // A plane with the normal along y holds the point where it is (it lies on the plane's x offset
  // only): no pull along x.
  UntangleAnchor across;
  across.normal = Vec3(0.0, 1.0, 0.0);
  across.one_sided = false;
  CHECK(moved(across).norm() < 1e-6);
}

TEST_CASE("untangle: with nothing inverted, soft pins alone pull (the containment rounds)", "[fibres][untangle]") {
  // The containment rounds of the lattice untangling: no tetrahedron inverted, only anchors pull.
  Grid g = make_grid(5);
  const int q = g.index(2, 2, 2);
  const Vec3 start = g.positions[static_cast<std::size_t>(q)];
  const Vec3 target = start + Vec3(0.05, 0.0, 0.0);
  UntangleOptions pull;
  pull.keep_best = false;
  const UntangleReport r = untangle(g.positions, g.fixed, g.tets, pull, {{q, target, 1e4}});
  INFO(r.to_json().dump());
  CHECK(inverted(g.positions, g.tets) == 0);
  CHECK(r.stages >= 1);
  CHECK(r.iterations > 0);
  CHECK(r.untangled());
  CHECK(r.reverted == 0);
  CHECK((g.positions[static_cast<std::size_t>(q)] - target).norm() / (start - target).norm() < 0.5);

  // With keep_best (the default) the same pull is undone: it folds nothing, unfolds nothing and
  // brings no containment point inside, and only lowers the smallest det J (the polish after it,
  // which runs from the state kept, is off here).
  Grid h = make_grid(5);
  const std::vector<Vec3> entry = h.positions;
  UntangleOptions keep;
  keep.polish_iterations = 0;
  const UntangleReport k = untangle(h.positions, h.fixed, h.tets, keep, {{q, target, 1e4}});
  INFO(k.to_json().dump());
  CHECK(k.iterations > 0);
  CHECK(k.reverted == 1);
  CHECK(h.positions == entry);  // bitwise
  CHECK(k.min_det_after == k.min_det_before);
}

TEST_CASE("untangle: a run that ends with more folded cells than it met returns the best state it met",
          "[fibres][untangle]") {
  // An unfolded grid whose centre point a stiff anchor pulls through its neighbour along x: one
  // stage of the wide starting eps lets the cells fold. Without keep_best the run ends folded;
  // with it the run returns its entry state, bit for bit.
  auto run = [](bool keep_best, std::vector<Vec3>* entry) {
    Grid g = make_grid(5);
    if (entry) *entry = g.positions;
    const int q = g.index(2, 2, 2);
    const Vec3 target = g.positions[static_cast<std::size_t>(q)] + Vec3(0.6, 0.0, 0.0);
    UntangleOptions options;
    options.max_stages = 1;
    options.polish_iterations = 0;
    options.keep_best = keep_best;
    const UntangleReport r = untangle(g.positions, g.fixed, g.tets, options, {{q, target, 1e6}});
    return std::make_pair(r, g.positions);
  };
  const auto [plain, plain_positions] = run(false, nullptr);
  INFO("without: " << plain.to_json().dump());
  REQUIRE(plain.inverted_before == 0);
  CHECK(plain.inverted_after > 0);
  CHECK(plain.reverted == 0);
  std::vector<Vec3> entry;
  const auto [kept, kept_positions] = run(true, &entry);
  INFO("with: " << kept.to_json().dump());
  CHECK(kept.inverted_after == 0);
  CHECK(kept.reverted == 1);
  CHECK(kept_positions == entry);
  CHECK(kept.to_json().at("reverted") == 1);
}

TEST_CASE("untangle: problems smaller than, and not a multiple of, the block of the energy's terms",
          "[fibres][untangle]") {
  // One cell (6 tetrahedra) with one free corner pushed through the opposite face, and 2 x 2 x 2
  // cells less one tetrahedron (47): the energy's terms are computed in blocks of 8 tetrahedra.
  for (int drop : {0, 1}) {
    Grid g = make_grid(drop ? 3 : 2);
    std::fill(g.fixed.begin(), g.fixed.end(), 1);
    const std::size_t q = static_cast<std::size_t>(g.index(1, 1, 1));
    g.fixed[q] = 0;
    if (drop) g.tets.pop_back();
    const Vec3 home = g.positions[q];
    g.positions[q] = drop ? home + Vec3(0.8, 0.7, 0.75) : Vec3(-0.2, -0.1, -0.15);
    REQUIRE(inverted(g.positions, g.tets) > 0);
    const UntangleReport r = untangle(g.positions, g.fixed, g.tets);
    INFO("drop " << drop << ": " << r.to_json().dump());
    CHECK(r.untangled());
    CHECK(inverted(g.positions, g.tets) == 0);
  }
}

TEST_CASE("untangle: a floor of sigma lowers eps in fewer stages on a fold that is a small part of the energy",
          "[fibres][untangle]") {
  // One point pushed through several layers of a large grid: the fold is a few tetrahedra among
  // thousands, each stage lowers the energy by well under the paper's sigma floor of 0.1, and
  // with that floor (the default) eps falls slowly; a floor of 0.3 gets there in fewer stages.
  auto folded = [] {
    Grid g = make_grid(9);
    const std::size_t q = static_cast<std::size_t>(g.index(4, 4, 4));
    g.positions[q] += Vec3(0.2, 0.15, 0.1);
    g.fixed[q] = 1;  // held there, like a point pinned just inside the muscle
    return g;
  };
  Grid slow = folded(), fast = folded();
  REQUIRE(inverted(slow.positions, slow.tets) > 0);
  UntangleOptions paper, raised;
  raised.min_sigma = 0.3;
  const UntangleReport a = untangle(slow.positions, slow.fixed, slow.tets, paper);
  const UntangleReport b = untangle(fast.positions, fast.fixed, fast.tets, raised);
  INFO("paper floor: " << a.to_json().dump() << "\nfloor 0.3: " << b.to_json().dump());
  CHECK(UntangleOptions{}.min_sigma == 0.1);
  CHECK(a.untangled());
  CHECK(b.untangled());
  CHECK(inverted(fast.positions, fast.tets) == 0);
  CHECK(b.stages < a.stages);
  CHECK(b.iterations < a.iterations);
}

TEST_CASE("untangle: the energy's terms computed on several threads give the serial result, bit for bit",
          "[fibres][untangle]") {
  // 13^3 cells, 13 182 tetrahedra: above the size from which an evaluation runs in parallel.
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> jitter(-0.06, 0.06);
  Grid g = make_grid(14);
  for (std::size_t q = 0; q < g.positions.size(); ++q)
    if (!g.fixed[q]) g.positions[q] += Vec3(jitter(rng), jitter(rng), jitter(rng));
  REQUIRE(inverted(g.positions, g.tets) > 0);
  REQUIRE(g.tets.size() > 256u);
  std::vector<Vec3> one_thread = g.positions, threads = g.positions;
  UntangleReport serial, parallel;
  {
    tbb::global_control only_one(tbb::global_control::max_allowed_parallelism, 1);
    serial = untangle(one_thread, g.fixed, g.tets);
  }
  parallel = untangle(threads, g.fixed, g.tets);
  INFO("one thread: " << serial.to_json().dump() << "\nthreads: " << parallel.to_json().dump());
  CHECK(serial.untangled());
  CHECK(parallel.iterations == serial.iterations);
  CHECK(parallel.evaluations == serial.evaluations);
  CHECK(parallel.min_det_after == serial.min_det_after);  // bitwise
  CHECK(threads == one_thread);                           // bitwise
}

TEST_CASE("untangle: the AVX2 and AVX-512 energy terms give the scalar code's result, bit for bit",
          "[fibres][untangle]") {
  // The vector paths (fibres/untangle_terms.h) must make every rounding of the scalar one: the
  // same positions, iterations and min det J to the bit. Reference cells from a jittered grid
  // (entries of every size in the reference inverses, not the cube's zeros and ones), weights and
  // eps floors that vary, 12^3 cells less one tetrahedron (not a multiple of the 4 lanes), and
  // points pushed through their neighbours.
  if (!detail::untangle_terms_avx2_supported()) {
    WARN("this processor has no AVX2: the vector path is not run here");
    return;
  }
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> jitter(-0.2, 0.2), unit(0.0, 1.0);
  Grid g = make_grid(13);
  const double h = 1.0 / 12.0;
  std::vector<Vec3> reference = g.positions;
  for (std::size_t q = 0; q < reference.size(); ++q)
    if (!g.fixed[q]) reference[q] += h * Vec3(jitter(rng), jitter(rng), jitter(rng));
  for (UntangleTet& tet : g.tets) {
    Eigen::Matrix3d s;
    for (int col = 0; col < 3; ++col)
      s.col(col) = reference[static_cast<std::size_t>(tet.v[static_cast<std::size_t>(col) + 1])] -
                   reference[static_cast<std::size_t>(tet.v[0])];
    REQUIRE(s.determinant() > 0.0);
    tet.reference_inverse = s.inverse();
    tet.weight = 0.5 + unit(rng);
    if (unit(rng) < 0.1) tet.eps_floor = 1e-3 * unit(rng);
  }
  g.tets.pop_back();
  g.positions = reference;
  for (int i = 0; i < 12; ++i) {
    const std::size_t q = static_cast<std::size_t>(
        g.index(1 + static_cast<int>(rng() % 11), 1 + static_cast<int>(rng() % 11), 1 + static_cast<int>(rng() % 11)));
    g.positions[q] += 1.5 * h * Vec3(jitter(rng), jitter(rng), jitter(rng)) / 0.2;
  }
  REQUIRE(inverted(g.positions, g.tets) > 0);
  REQUIRE(g.tets.size() % 4 != 0);
  std::vector<Vec3> scalar = g.positions;
  detail::set_untangle_simd(false);
  const UntangleReport a = untangle(scalar, g.fixed, g.tets);
  detail::set_untangle_simd(true);
  CHECK(a.iterations > 30);
  CHECK(scalar != g.positions);  // it moved
  for (bool avx512 : {false, true}) {
    if (avx512 && !detail::untangle_terms_avx512_supported()) {
      WARN("this processor has no AVX-512: the 8-lane path is not run here");
      continue;
    }
    detail::set_untangle_avx512(avx512);
    REQUIRE(detail::untangle_simd_lanes() == (avx512 ? 8 : 4));
    std::vector<Vec3> vector = g.positions;
    const UntangleReport b = untangle(vector, g.fixed, g.tets);
    INFO("scalar: " << a.to_json().dump() << "\n" << (avx512 ? "AVX-512: " : "AVX2: ") << b.to_json().dump());
    CHECK(b.iterations == a.iterations);
    CHECK(b.evaluations == a.evaluations);
    CHECK(b.min_det_after == a.min_det_after);  // bitwise
    CHECK(vector == scalar);                    // bitwise
  }
  detail::set_untangle_avx512(true);
}

TEST_CASE("untangle: the vector estimate of c^(-1/3) divides the bits by 3 exactly", "[fibres][untangle]") {
  // The vector code divides each lane's 64 bits by 3 in 32-bit halves (fibres/untangle_terms.h);
  // four Newton steps later a wrong quotient can still round to the right result, so the
  // untangling's bitwise comparison above need not see it: the quotient itself is checked here,
  // on random bit patterns and on halves next to multiples of 3 and to 2^32.
  std::mt19937_64 rng(11);
  std::vector<std::uint64_t> bits;
  for (int i = 0; i < 200000; ++i) bits.push_back(rng());
  for (std::uint64_t hi : {0ull, 1ull, 2ull, 3ull, 4ull, 5ull, 0x3FEFFFFFull, 0x7FFFFFFEull, 0x7FFFFFFFull,
                           0xFFFFFFFDull, 0xFFFFFFFEull, 0xFFFFFFFFull})
    for (std::uint64_t lo = 0; lo < 8; ++lo) {
      bits.push_back((hi << 32) | lo);
      bits.push_back((hi << 32) | (0xFFFFFFFFull - lo));
    }
  for (double c : {1e-200, 1e-10, 0.3, 1.0, 3.0, 1e10, 1e200}) {
    std::uint64_t b;
    std::memcpy(&b, &c, sizeof b);
    bits.push_back(b);
  }
  while (bits.size() % 8 != 0) bits.push_back(rng());
  const std::uint64_t magic = 0x553ef0ff289dd796ull;
  for (int lanes : {4, 8}) {
    if (!(lanes == 4 ? detail::untangle_terms_avx2_supported() : detail::untangle_terms_avx512_supported())) {
      WARN("this processor lacks the " << lanes << "-lane vector path: not run here");
      continue;
    }
    long wrong = 0;
    for (std::size_t i = 0; i < bits.size(); i += static_cast<std::size_t>(lanes)) {
      double c[8];
      std::memcpy(c, bits.data() + i, sizeof(double) * static_cast<std::size_t>(lanes));
      std::uint64_t out[8];
      detail::untangle_third_bits_simd(lanes, c, magic, out);
      for (int l = 0; l < lanes; ++l) wrong += out[l] == magic - bits[i + static_cast<std::size_t>(l)] / 3 ? 0 : 1;
    }
    INFO(lanes << " lanes");
    CHECK(wrong == 0);
  }
}

TEST_CASE("untangle: bad options and bad input", "[fibres][untangle]") {
  Grid g = make_grid(3);
  UntangleOptions o;
  o.lambda = 0.0;
  CHECK_THROWS_AS(untangle(g.positions, g.fixed, g.tets, o), OptionError);
  o = {};
  o.history = 0;
  CHECK_THROWS_AS(o.validate(), OptionError);
  o = {};
  o.min_det = -1.0;
  CHECK_THROWS_AS(o.validate(), OptionError);
  for (double sigma : {0.0, 1.0, std::nan("")}) {
    o = {};
    o.min_sigma = sigma;
    CHECK_THROWS_AS(o.validate(), OptionError);
  }
  LatticeUntangleOptions lattice_options;
  lattice_options.contact_stall_rounds = -1;
  CHECK_THROWS_AS(lattice_options.validate(), OptionError);
  lattice_options.contact_stall_rounds = 0;  // never stop for that: allowed
  CHECK_NOTHROW(lattice_options.validate());
  lattice_options.containment_margin = 1.0;
  CHECK_THROWS_AS(lattice_options.validate(), OptionError);
  lattice_options.containment_margin = 0.15;
  lattice_options.containment_band = 0.0;
  CHECK_THROWS_AS(lattice_options.validate(), OptionError);
  lattice_options.containment_band = 3.0;
  CHECK_NOTHROW(lattice_options.validate());
  std::vector<UntangleTet> bad = g.tets;
  bad[0].v[2] = 1000;
  CHECK_THROWS_AS(untangle(g.positions, g.fixed, bad), Error);
  std::vector<Vec3> nan = g.positions;
  nan[13].x() = std::nan("");
  CHECK_THROWS_AS(untangle(nan, g.fixed, g.tets), Error);
  CHECK_THROWS_AS(untangle(g.positions, g.fixed, g.tets, {}, {{0, Vec3::Zero(), -1.0}}), Error);
}

#include "morph/signed_distance_grid.h"
#include "morph/surface_query.h"
#include "tests/morph_test_shapes.h"

TEST_CASE("untangle: containment in the energy brings a lattice pushed partly outside a surface back inside, unfolded",
          "[fibres][untangle][containment]") {
  // A 6 x 6 x 6 grid of the unit cube with its end layers (z = 0, z = 1) fixed, one interior point
  // pushed through its neighbours (a fold); the closed surface is the box [0.05, 0.95]^2 x
  // [-0.5, 1.5]: the lattice's sides stick out of it by 0.05. The untangling alone unfolds the cell
  // and leaves the side points where their cells' shapes want them, outside; with the containment
  // energy every free point ends inside the surface (the exact test), no tetrahedron folded.
  TriangleMesh box = test::subdivided_cube(4);
  for (Vec3& p : box.positions) p = Vec3(0.5 + 0.45 * p.x(), 0.5 + 0.45 * p.y(), 0.5 + p.z());
  SurfaceQuery query(box);
  auto make = [] {
    Grid g = make_grid(6);
    for (int k = 0; k < g.n; ++k)
      for (int j = 0; j < g.n; ++j)
        for (int i = 0; i < g.n; ++i)
          g.fixed[static_cast<std::size_t>(g.index(i, j, k))] = k == 0 || k == g.n - 1 ? 1 : 0;
    g.positions[static_cast<std::size_t>(g.index(2, 2, 2))].z() += 0.35;
    g.positions[static_cast<std::size_t>(g.index(3, 2, 3))].x() -= 0.3;
    return g;
  };
  auto outside = [&](const Grid& g) {
    long n = 0;
    for (std::size_t q = 0; q < g.positions.size(); ++q) n += !g.fixed[q] && !query.inside(g.positions[q]) ? 1 : 0;
    return n;
  };
  Grid plain = make();
  REQUIRE(inverted(plain.positions, plain.tets) > 0);
  REQUIRE(outside(plain) > 0);
  const UntangleReport without = untangle(plain.positions, plain.fixed, plain.tets);
  INFO("without: " << without.to_json().dump());
  CHECK(without.untangled());
  CHECK(outside(plain) > 0);  // unfolded, but the sides stay out

  Grid g = make();
  SignedDistanceGrid field(query, Vec3::Constant(-0.3), Vec3::Constant(1.3), 0.02);
  UntangleContainment containment;
  containment.signed_distance = [&field](const Vec3& p, Vec3* gradient) { return field(p, gradient); };
  for (std::size_t q = 0; q < g.positions.size(); ++q)
    if (!g.fixed[q]) containment.points.push_back({static_cast<int>(q), 30.0 / (0.2 * 0.2), 0.02});
  const UntangleReport with = untangle(g.positions, g.fixed, g.tets, UntangleOptions{}, {}, containment);
  INFO("with: " << with.to_json().dump());
  CHECK(with.outside_before > 0);
  CHECK(with.outside_after == 0);
  CHECK(with.untangled());
  CHECK(inverted(g.positions, g.tets) == 0);
  CHECK(outside(g) == 0);
  for (std::size_t q = 0; q < g.positions.size(); ++q)
    if (!g.fixed[q]) CHECK(field.exact(g.positions[q]) < 0.0);

  // Deterministic: the same result, bit for bit, on one thread.
  Grid one = make();
  {
    tbb::global_control single(tbb::global_control::max_allowed_parallelism, 1);
    SignedDistanceGrid field1(query, Vec3::Constant(-0.3), Vec3::Constant(1.3), 0.02);
    UntangleContainment c1 = containment;
    c1.signed_distance = [&field1](const Vec3& p, Vec3* gradient) { return field1(p, gradient); };
    untangle(one.positions, one.fixed, one.tets, UntangleOptions{}, {}, c1);
  }
  CHECK(one.positions == g.positions);
}

TEST_CASE("signed distance grid: close to the sphere's distance, gradient along the radius, exact outside its box",
          "[fibres][untangle][containment]") {
  const TriangleMesh sphere = test::icosphere(4);
  SurfaceQuery query(sphere);
  SignedDistanceGrid field(query, Vec3::Constant(-1.5), Vec3::Constant(1.5), 0.05);
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-1.4, 1.4);
  for (int t = 0; t < 200; ++t) {
    const Vec3 p(u(rng), u(rng), u(rng));
    if (p.norm() < 0.3) continue;
    Vec3 gradient;
    const double d = field(p, &gradient);
    CHECK(d == Approx(p.norm() - 1.0).margin(0.01));  // the icosphere's chords: ~0.003 under the sphere
    if (std::abs(p.norm() - 1.0) > 0.02) CHECK((d < 0.0) == (p.norm() < 1.0));
    if (std::abs(p.norm() - 1.0) > 0.1) CHECK(gradient.dot(p.normalized()) > 0.95);
  }
  // Outside the box: the exact value.
  CHECK(field(Vec3(3.0, 0.0, 0.0)) == Approx(2.0).margin(1e-9));
  CHECK(field.nodes_computed() > 0);
  CHECK_THROWS_AS(SignedDistanceGrid(query, Vec3::Zero(), Vec3::Zero(), 0.1), Error);
}

#include "fibres/decompose_mesh.h"
#include "geometry/mesh_io.h"
#include "tests/test_common.h"

TEST_CASE("untangle in the decomposition: a real muscle whose settle folds cells comes out unfolded",
          "[fibres][untangle][data]") {
  FASCICLE_REQUIRE_DATA();
  // VHM left rectus femoris: the settle leaves a few cells folded, which the untangling opens.
  const PolygonSoup soup =
      read_polygon_soup(test::data_dir() + "/muscles/visible-human/VHM_Left/VHM_Left_Muscle_RectusFemoris_smooth.stl");
  DecomposeOptions options;
  options.tries.second_try = false;  // this case is about the untangling of one placement
  options.placement.corner_twist_deg = 45.0;  // the placement this case was found with
  options.untangle_cells = false;
  const Decomposition folded = decompose(soup, {}, options);
  REQUIRE(folded.report.quality.inverted_cells > 0);
  options.untangle_cells = true;
  const Decomposition unfolded = decompose(soup, {}, options);
  const nlohmann::json u = unfolded.report.to_json()["untangle"];
  INFO(u.dump());
  CHECK(u["inverted_left"].get<long>() == 0);
  CHECK(unfolded.report.quality.inverted_cells == 0);
  CHECK(unfolded.report.quality.inside_fraction == 1.0);
  CHECK(unfolded.report.quality.attachment.origin_max <= 0.02);
  CHECK(unfolded.report.quality.attachment.insertion_max <= 0.02);
}

#include "fibres/untangle_lattice.h"
#include "springs/lattice.h"

TEST_CASE("kuhn split: six positive tetrahedra around the diagonal that fill the cell", "[fibres][untangle]") {
  const auto& kuhn = kuhn_tetrahedra();
  auto corner = [](int c) { return Vec3(c & 1, (c >> 1) & 1, (c >> 2) & 1); };
  double total = 0.0;
  std::set<std::array<int, 4>> distinct;
  for (const std::array<int, 4>& t : kuhn) {
    CHECK(t[0] == 0);
    CHECK(std::count(t.begin(), t.end(), 7) == 1);
    const Vec3 a = corner(t[1]) - corner(t[0]), b = corner(t[2]) - corner(t[0]), c = corner(t[3]) - corner(t[0]);
    const double volume = a.dot(b.cross(c)) / 6.0;
    CHECK(volume == Approx(1.0 / 6.0));
    total += volume;
    std::array<int, 4> sorted = t;
    std::sort(sorted.begin(), sorted.end());
    distinct.insert(sorted);
  }
  CHECK(distinct.size() == 6);
  CHECK(total == Approx(1.0));  // positive and summing to the cube: they tile it
}

TEST_CASE("lattice spacing: across the fibres only the springs within a layer count", "[fibres][untangle]") {
  // A 4 x 4 x 3 template lattice stretched 10 times along t: springs across the fibres 1/3 long,
  // along them 5; an anchor point after the lattice's keeps the mean over all its springs.
  for (springs::SpringModel model : {springs::SpringModel::model6, springs::SpringModel::model26}) {
    springs::LatticeOptions o;
    o.nr = 4;
    o.ns = 4;
    o.resolution = 3;
    o.model = model;
    springs::Lattice lattice = springs::build_lattice(o);
    springs::SpringSystem& system = lattice.system;
    for (Vec3& p : system.positions) p.z() *= 10.0;
    system.positions.push_back(system.positions[0] + Vec3(0.0, 0.0, -2.0));
    system.fixed.push_back(1);
    system.mass.push_back(1.0);
    springs::Spring anchor;
    anchor.a = 0;
    anchor.b = static_cast<int>(system.positions.size()) - 1;
    system.springs.push_back(anchor);
    const std::vector<double> local = lattice_local_spacing(system);
    const std::vector<double> across = lattice_across_spacing(lattice, system);
    REQUIRE(across.size() == system.positions.size());
    const int centre = lattice.index(1, 1, 1);
    if (model == springs::SpringModel::model6) {
      // Four springs of 1/3 across, two of 5 along.
      CHECK(across[static_cast<std::size_t>(centre)] == Approx(1.0 / 3.0));
      CHECK(local[static_cast<std::size_t>(centre)] == Approx((4.0 / 3.0 + 10.0) / 6.0));
      // The corner (0, 0, 0): two across, one along, one anchor spring of 2 (left out across).
      CHECK(across[0] == Approx(1.0 / 3.0));
      CHECK(local[0] == Approx((2.0 / 3.0 + 5.0 + 2.0) / 4.0));
    } else {
      // Within the layer: four of 1/3 and four diagonals of sqrt(2)/3.
      CHECK(across[static_cast<std::size_t>(centre)] == Approx((4.0 + 4.0 * std::sqrt(2.0)) / 3.0 / 8.0));
    }
    CHECK(across.back() == local.back());  // the anchor point
    for (std::size_t q = 0; q + 1 < across.size(); ++q) CHECK(across[q] < local[q]);
  }
}

TEST_CASE("lattice cell tetrahedra: the template lattice and its mirror image are unfolded, a swap folds it",
          "[fibres][untangle]") {
  springs::LatticeOptions o;
  o.nr = 5;
  o.ns = 6;
  o.resolution = 7;
  const springs::Lattice lattice = springs::build_lattice(o);
  std::vector<Vec3> x = lattice.system.positions;
  const std::vector<UntangleTet> tets = lattice_cell_tets(lattice, x);
  CHECK(tets.size() == 6u * 4u * 5u * 6u);
  long counted = 0;
  for (const UntangleTet& t : tets) counted += t.counted ? 1 : 0;
  CHECK(counted == 6 * 2 * 3 * 6);  // the cells between interior lines
  for (double d : tet_jacobian_dets(x, tets)) CHECK(d == Approx(1.0));
  CHECK(inverted_tets(x, tets) == 0);
  std::vector<Vec3> mirrored = x;
  for (Vec3& p : mirrored) p.x() = -p.x();
  CHECK(inverted_tets(mirrored, lattice_cell_tets(lattice, mirrored)) == 0);
  std::swap(x[static_cast<std::size_t>(lattice.index(2, 2, 3))], x[static_cast<std::size_t>(lattice.index(3, 2, 3))]);
  CHECK(inverted_tets(x, tets) > 0);
}

TEST_CASE("untangle in the decomposition: points fixed just inside at the end do not fold cells",
          "[fibres][untangle][data]") {
  FASCICLE_REQUIRE_DATA();
  // LHDL right gluteus medius: the untangling leaves points outside that must be fixed just
  // inside; pins fixed after the untangling can fold cells, so the cells around them are
  // untangled again with the pins fixed (LatticeUntangleOptions::pin_rounds).
  const PolygonSoup soup =
      read_polygon_soup(test::data_dir() + "/muscles/lhdl/LHDL_R_M082_GluteusMedius_smooth.334.vtk");
  DecomposeOptions options;
  options.placement.corner_twist_deg = 0.0;  // the placement this case was found with (the
                                             // twist of 45 degrees needs no pins here), however
  options.placement.flat_section_aspect = 0.0;  // flat its cross-sections
  options.tries.second_try = false;          // this case is about the untangling of one placement
  options.cast_rim = false;                  // the face rims as when the case was found (cast, they
                                             // leave nothing outside to pin here)
  options.untangle.sliding_contact = false;  // the containment pins as when the case was found
                                             // (sliding, they bring every point in here)
  options.untangle.contact_rounds = 6;       // the rounds as when the case was found (16, the
                                             // default, bring every point in)
  const Decomposition d = decompose(soup, {}, options);
  const nlohmann::json u = d.report.to_json()["untangle"];
  INFO(u.dump());
  REQUIRE(u["pinned"].get<long>() > 0);  // the case this test is about
  CHECK(u["inverted_left"].get<long>() == 0);
  CHECK(d.report.quality.inverted_cells == 0);
  CHECK(d.report.quality.inside_fraction == 1.0);
  CHECK(d.report.quality.attachment.origin_max <= 0.02);
  CHECK(d.report.quality.attachment.insertion_max <= 0.02);
}

TEST_CASE("untangle in the decomposition: containment rounds that make progress are not stopped by the stall rule",
          "[fibres][untangle][data]") {
  FASCICLE_REQUIRE_DATA();
  // LHDL right gluteus maximus: with the face rims cast no two containment rounds in a row fail
  // to leave fewer points outside, so the stall rule (contact_stall_rounds 2; off by default)
  // must not fire: the same rounds, the same result.
  const PolygonSoup soup =
      read_polygon_soup(test::data_dir() + "/muscles/lhdl/LHDL_R_M081_GluteusMaximus_smooth.312.vtk");
  DecomposeOptions options;
  options.tries.second_try = false;                     // this case is about the untangling of one placement
  options.placement.corner_twist_deg = 45.0;            // the placement this case was found with
  options.contact_segments = false;                     // (nor the segment attempt: points outside only)
  REQUIRE(options.untangle.contact_stall_rounds == 0);  // the default: every containment round
  const Decomposition all_rounds = decompose(soup, {}, options);
  options.untangle.contact_stall_rounds = 2;
  const Decomposition stalled = decompose(soup, {}, options);
  const nlohmann::json a = stalled.report.to_json()["untangle"], b = all_rounds.report.to_json()["untangle"];
  INFO("stall 2: " << a.dump() << "\nstall 0: " << b.dump());
  // Of the containment rounds after the first of a phase, never two in a row leave no fewer
  // points outside than the round before (what the stall rule with 2 would stop on).
  int previous = -1, stalled_rounds = 0;
  for (const nlohmann::json& run : b["runs"]) {
    if (!run.contains("round")) continue;
    const int outside = run["outside"].get<int>();
    if (run["round"].get<int>() == 0) stalled_rounds = 0;
    else if (previous > 0) stalled_rounds = outside < previous ? 0 : stalled_rounds + 1;
    REQUIRE(stalled_rounds < 2);
    previous = outside;
  }
  CHECK(a["stops"].value("outside_stalled", 0) == 0);
  CHECK(b["stops"].value("outside_stalled", 0) == 0);
  // The run that ended an attempt's rounds says why, and the reasons add up to the count.
  int marked = 0, counted = 0;
  for (const nlohmann::json& run : a["runs"])
    if (run.contains("stop")) {
      ++marked;
      CHECK(a["stops"].contains(run["stop"].get<std::string>()));
    }
  for (const auto& item : a["stops"].items()) counted += item.value().get<int>();
  CHECK(marked == counted);
  CHECK(a["iterations"].get<long>() == b["iterations"].get<long>());
  long summed = 0;
  for (const nlohmann::json& run : a["runs"]) summed += run.value("iterations", 0L);
  CHECK(a["iterations"].get<long>() == summed);
  CHECK(stalled.fibres.lines == all_rounds.fibres.lines);
  for (const Decomposition* d : {&stalled, &all_rounds}) {
    const CheckReport& q = d->report.quality;
    CHECK(q.inverted_cells == 0);
    CHECK(q.inside_fraction == 1.0);
    CHECK(q.attachment.origin_max <= 0.02);
    CHECK(q.attachment.insertion_max <= 0.02);
    CHECK(q.coverage.p95 <= 2.0);
  }
}

TEST_CASE("a decomposition is the same to the bit on one thread and on two", "[fibres][untangle][data]") {
  FASCICLE_REQUIRE_DATA();
  // LHDL right gluteus maximus, default options: the sphere map's rounds and lift, the placement's
  // per-vertex loops, the general spring solves in two halves, the untangling (51 cells folded
  // before it; its first run above 2048 active tetrahedra, its containment rounds between 256
  // and 2048) and the check all run on threads, each summing in a fixed order.
  const PolygonSoup soup =
      read_polygon_soup(test::data_dir() + "/muscles/lhdl/LHDL_R_M081_GluteusMaximus_smooth.312.vtk");
  Decomposition one;
  {
    tbb::global_control only_one(tbb::global_control::max_allowed_parallelism, 1);
    one = decompose(soup, {}, DecomposeOptions{});
  }
  const Decomposition two = decompose(soup, {}, DecomposeOptions{});
  const nlohmann::json a = one.report.to_json(), b = two.report.to_json();
  INFO("one thread: " << a["untangle"].dump() << "\ntwo: " << b["untangle"].dump());
  REQUIRE(a["untangle"]["inverted_before"].get<long>() > 0);
  CHECK(a["untangle"]["iterations"] == b["untangle"]["iterations"]);
  CHECK(a["settle"]["solves"].size() == b["settle"]["solves"].size());
  for (std::size_t i = 0; i < a["settle"]["solves"].size() && i < b["settle"]["solves"].size(); ++i) {
    CHECK(a["settle"]["solves"][i]["iterations"] == b["settle"]["solves"][i]["iterations"]);
    CHECK(a["settle"]["solves"][i]["residual"] == b["settle"]["solves"][i]["residual"]);
  }
  CHECK(a["sphere"]["quality"]["area_log_mean"] == b["sphere"]["quality"]["area_log_mean"]);
  CHECK(one.fibres.lines == two.fibres.lines);  // bitwise
  CHECK(one.report.quality.coverage.p95 == two.report.quality.coverage.p95);
  CHECK(two.report.quality.pass);
}

TEST_CASE("untangle in the decomposition: the containment energy in the free-ring attempts leaves fewer folds",
          "[fibres][untangle][data][slow]") {
  FASCICLE_REQUIRE_DATA();
  // LHDL right psoas: with the surface ring free and without the containment energy, cells stay
  // folded (the pins at the end fold them); with the containment energy in the untangling's
  // energy (containment_energy) the free-ring attempts must leave fewer.
  const PolygonSoup soup = read_polygon_soup(test::data_dir() + "/muscles/lhdl/LHDL_R_M090_Psoas_smooth.415.vtk");
  DecomposeOptions options;
  options.tries.second_try = false;  // this case is about the untangling of one placement
  options.placement.corner_twist_deg = 45.0;  // the placement this case was found with
  // The areas as their bands' vertices (no points across the triangles), whose gaps shrink the
  // cast end faces: the case whose free-ring attempt leaves folds.
  options.attachments.max_point_spacing = 1.0;
  options.cast_by_azimuth = false;  // the cast as when the case was found (one factor for the face)
  REQUIRE_FALSE(options.untangle.containment_energy);
  // The folded tetrahedra after the free-ring attempts' pins (the fewest of the attempt and its
  // continuation with the ends held), and the untangling's report.
  const auto free_ring_folds = [&](bool energy, nlohmann::json& u, Decomposition& d) {
    options.untangle.containment_energy = energy;
    d = decompose(soup, {}, options);
    u = d.report.to_json()["untangle"];
    std::map<std::string, long> finished;
    std::string current;
    for (const nlohmann::json& run : u["runs"]) {
      if (run.contains("attempt")) current = run["attempt"].get<std::string>();
      if (run.contains("finished") && !current.empty()) finished[current] = run["finished"].get<long>();
    }
    REQUIRE(finished.count("free_ring"));
    return std::min(finished["free_ring"], finished.count("free_ring_then_held_ends")
                                               ? finished["free_ring_then_held_ends"]
                                               : std::numeric_limits<long>::max());
  };
  nlohmann::json without_u, u;
  Decomposition without_d, d;
  const long without = free_ring_folds(false, without_u, without_d);
  const long with = free_ring_folds(true, u, d);
  INFO(without_u["kept"].dump() << " " << u["kept"].dump() << " " << d.report.quality.inverted_cells);
  CHECK(without > 0);  // the free-ring attempts without the energy leave folds
  CHECK(with < without);
  CHECK(u["kept"].get<std::string>().rfind("free_ring", 0) == 0);
  CHECK(u["inverted_left"].get<long>() == with);
  CHECK(d.report.quality.inverted_cells < without_d.report.quality.inverted_cells);
  CHECK(d.report.quality.inside_fraction == 1.0);
  CHECK(d.report.quality.coverage.p95 <= 2.0);
  CHECK(d.report.quality.attachment.origin_max <= 0.02);
  CHECK(d.report.quality.attachment.insertion_max <= 0.02);
}

TEST_CASE("untangle in the decomposition: segment rounds that move no point end the segment attempt",
          "[fibres][untangle][data][slow]") {
  FASCICLE_REQUIRE_DATA();
  // LHDL right psoas: after the free-ring attempt about a hundred points stay outside and three
  // hundred on leaving segments; the segment attempt's pins reach the cells' barrier within a
  // few rounds, and a round that moves nothing ends it instead of running all contact rounds.
  const PolygonSoup soup = read_polygon_soup(test::data_dir() + "/muscles/lhdl/LHDL_R_M090_Psoas_smooth.415.vtk");
  DecomposeOptions options;
  options.tries.second_try = false;  // this case is about the untangling of one placement
  options.placement.corner_twist_deg = 45.0;  // the placement this case was found with
  const Decomposition d = decompose(soup, {}, options);
  const nlohmann::json u = d.report.to_json()["untangle"];
  REQUIRE(u["segments_needed"].get<bool>());
  // The segment attempt's rounds are the runs that count the points on leaving segments.
  int rounds = 0;
  std::string last_stop;
  for (const nlohmann::json& run : u["runs"])
    if (run.contains("leaving_points")) {
      ++rounds;
      last_stop = run.value("stop", "");
    }
  CHECK(rounds > 1);
  CHECK(rounds < options.untangle.contact_rounds);
  CHECK(last_stop == "unmoved");
  CHECK(u["stops"].value("unmoved", 0) == 1);
  CHECK(d.report.quality.inverted_cells == 0);
  CHECK(d.report.quality.inside_fraction == 1.0);
}
