// The fascicle command line: dispatches to the subcommands and maps every failure to a
// one-line message on stderr and a distinct exit code (geometry/errors.h).

#include "app/commands.h"
#include "geometry/errors.h"
#include "geometry/subprocess.h"

#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>

#include <csignal>
#include <cstdio>
#include <cstring>
#include <exception>
#include <new>
#include <unistd.h>

namespace {

void on_time_limit(int) {
  static const char msg[] = "fascicle: error: time limit reached (--time-limit); no output written\n";
  // Only async-signal-safe calls here. Outputs are renamed into place only when complete, so
  // stopping now leaves no partial file under the requested name.
  ssize_t ignored = ::write(2, msg, sizeof(msg) - 1);
  (void)ignored;
  std::_Exit(fascicle::exit_code(fascicle::ErrorCode::time_limit));
}

}  // namespace

int main(int argc, char** argv) {
  // Started by `fascicle batch`: end with it.
  fascicle::die_with_parent_if_asked();
  auto logger = spdlog::stderr_color_mt("fascicle");
  spdlog::set_default_logger(logger);
  spdlog::set_pattern("%^%l%$: %v");
  spdlog::set_level(spdlog::level::info);

  CLI::App app{"fascicle: muscle fibres from messy muscle surfaces (CT/MRI)"};
  app.set_version_flag("--version", "fascicle 0.1.0");
  app.require_subcommand(1);
  bool verbose = false, quiet = false;
  double time_limit = 0.0;
  app.add_flag("-v,--verbose", verbose, "Print every step's details");
  app.add_flag("-q,--quiet", quiet, "Print errors only");
  app.add_option("--time-limit", time_limit, "Stop with exit code 17 after this many seconds (0: none)")
      ->check(CLI::NonNegativeNumber);
  app.parse_complete_callback([&] {
    if (verbose) spdlog::set_level(spdlog::level::debug);
    if (quiet) spdlog::set_level(spdlog::level::err);
    if (time_limit > 0) {
      std::signal(SIGALRM, on_time_limit);
      ::alarm(static_cast<unsigned>(time_limit + 0.999));
    }
  });

  fascicle::app::add_sample_command(app);
  fascicle::app::add_repair_command(app);
  fascicle::app::add_convert_command(app);
  fascicle::app::add_bench_command(app);
  fascicle::app::add_settle_command(app);
  fascicle::app::add_sphere_command(app);
  fascicle::app::add_check_command(app);
  fascicle::app::add_decompose_command(app);
  fascicle::app::add_batch_command(app);
  fascicle::app::add_render_command(app);

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int code = app.exit(e);
    return code == 0 ? 0 : fascicle::exit_code(fascicle::ErrorCode::usage);
  } catch (const fascicle::Error& e) {
    std::fprintf(stderr, "fascicle: error: %s\n", e.what());
    return fascicle::exit_code(e.code());
  } catch (const std::bad_alloc&) {
    std::fprintf(stderr, "fascicle: error: out of memory\n");
    return fascicle::exit_code(fascicle::ErrorCode::too_large);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "fascicle: error: internal: %s\n", e.what());
    return fascicle::exit_code(fascicle::ErrorCode::internal);
  }
  return 0;
}
