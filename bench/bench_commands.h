#pragma once
/// \file bench_commands.h
/// Bench programs, run as `fascicle bench NAME`. Each measures one stage on real data and prints a
/// table plus, with --json, a list of records. Timings live here, never in tests.

#include <CLI/CLI.hpp>

namespace fascicle::bench {

/// `fascicle bench repair [--data DIR] [--json FILE]`: repair time and result for every mesh of
/// the corpus (../shared/data/muscles and broken).
void add_repair_bench(CLI::App& bench);
void add_sphere_bench(CLI::App& bench);  // fascicle bench sphere (bench/bench_sphere.cpp)

/// `fascicle bench springs [--sizes ...] [--json FILE]`: the CPU spring solvers (docs/BENCHMARKS.md).
void add_springs_bench(CLI::App& bench);

/// `fascicle bench gpu [--sizes ...] [--json FILE]`: GPU spring solvers through OpenGL
/// (bench_gpu.cpp); an error in a build without OpenGL.
void add_gpu_bench(CLI::App& bench);
/// `fascicle bench decompose [--json FILE]`: decomposition speed by stage, every template on the
/// LHDL muscles with their landmarks, the corpus with repair (bench_decompose.cpp).
void add_decompose_bench(CLI::App& bench);

}  // namespace fascicle::bench
