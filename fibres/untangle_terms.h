#pragma once
/// \file untangle_terms.h
/// Private to fibres/untangle.cpp: the untangling energy's tetrahedron terms (Garanzha et al.
/// 2021, fibres/untangle.h) several tetrahedra at a time in vectors, one tetrahedron a lane:
/// AVX2 (4 lanes) or AVX-512 (8). Each lane makes the same IEEE operations in the same order as
/// the scalar code of Energy::evaluate (which Eigen's 3 x 3 products, determinant and squared
/// norm fix), without FMA, so the terms and gradients are the scalar code's to the bit: the
/// untangling gives the same result with either width or none, on every processor
/// (tests/fibres_untangle_test.cpp compares them).

#include <cstdint>

namespace fascicle::detail {

/// `lanes` (4 or 8, as untangle_simd_lanes() gives) tetrahedra, lane l = tetrahedron l.
/// Vertex v of tetrahedron l is the point at positions[corners[v][l] + 0..2] (corners: `lanes`
/// consecutive indices per vertex, 3 times the point's index; gathered straight into the vector
/// registers); r[k]: entry k of the reference inverses (column-major), `lanes` consecutive
/// values; weight and eps_floor likewise (the tetrahedron's eps is max(eps, eps_floor)).
/// Writes term[0..lanes) = weight ((1 - lambda) shape + lambda volume) and, where `grad` is not
/// null, grad[k][0..lanes): entry k (column-major) of the terms' gradients by the edge vectors.
void untangle_terms_simd(int lanes, const double* positions, const int* const corners[4], const double* const r[9],
                         const double* weight, const double* eps_floor, double eps, double lambda, double* term,
                         double* const* grad);

/// Lanes of the vector terms to use now: 8 (AVX-512), 4 (AVX2) or 0 (the scalar code only).
int untangle_simd_lanes();
/// Whether the processor has AVX2 / AVX-512F.
bool untangle_terms_avx2_supported();
bool untangle_terms_avx512_supported();
/// Test hook: out[l] = the bits magic - bits(c[l]) / 3 (unsigned 64-bit division) for l < lanes,
/// computed by that width's vector code (the estimate of c^(-1/3) the terms start from); the
/// width must be supported.
void untangle_third_bits_simd(int lanes, const double* c, std::uint64_t magic, std::uint64_t* out);
/// The switches tests use to compare: set_untangle_simd(false): the scalar code only;
/// set_untangle_avx512(false): AVX2 where AVX-512 is there too.
void set_untangle_simd(bool enabled);
void set_untangle_avx512(bool enabled);

}  // namespace fascicle::detail
