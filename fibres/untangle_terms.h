#pragma once
/// \file untangle_terms.h
/// Private to fibres/untangle.cpp: the untangling energy's tetrahedron terms (Garanzha et al.
/// 2021, fibres/untangle.h) four tetrahedra at a time in AVX2 vectors, one tetrahedron a lane.
/// Each lane makes the same IEEE operations in the same order as the scalar code of
/// Energy::evaluate (which Eigen's 3 x 3 products, determinant and squared norm fix), and AVX2
/// without FMA rounds each one alike, so the terms and gradients are the scalar code's to the
/// bit: the untangling gives the same result with or without it, on every processor
/// (tests/fibres_untangle_test.cpp compares them).

namespace fascicle::detail {

/// Four tetrahedra, lane l = tetrahedron l. p[3 v + c][l]: coordinate c of vertex v; r[k]:
/// entry k of the four reference inverses (column-major), four consecutive values; weight and
/// eps_floor likewise (the tetrahedron's eps is max(eps, eps_floor)). Writes term[0..3] =
/// weight ((1 - lambda) shape + lambda volume) and, where `grad` is not null, grad[k][0..3]:
/// entry k (column-major) of the terms' gradients by the edge vectors. Call only where
/// untangle_terms_avx2_supported().
void untangle_terms_avx2(const double p[12][4], const double* const r[9], const double* weight, const double* eps_floor,
                         double eps, double lambda, double* term, double* const* grad);

/// Whether the processor runs untangle_terms_avx2 (AVX2), and the switch tests use to compare
/// (set_untangle_simd(false): the scalar code only).
bool untangle_terms_avx2_supported();
void set_untangle_simd(bool enabled);
bool untangle_simd_active();

}  // namespace fascicle::detail
