// fascicle bench NAME: the bench programs of bench/.

#include "app/commands.h"
#include "bench/bench_commands.h"

namespace fascicle::app {

void add_bench_command(CLI::App& app) {
  CLI::App* bench = app.add_subcommand("bench", "Measure speed and memory (see docs/BENCHMARKS.md)");
  bench->require_subcommand(1);
  fascicle::bench::add_repair_bench(*bench);
  fascicle::bench::add_springs_bench(*bench);
  fascicle::bench::add_sphere_bench(*bench);
  fascicle::bench::add_gpu_bench(*bench);
  fascicle::bench::add_decompose_bench(*bench);
}

}  // namespace fascicle::app
