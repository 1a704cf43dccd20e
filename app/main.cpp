// The fascicle command line: dispatches to the subcommands and maps every failure to a
// one-line message on stderr and a distinct exit code (geometry/errors.h).

#include "app/commands.h"
#include "geometry/errors.h"
#include "geometry/subprocess.h"

#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>

#include <csignal>
#include <cstdio>
#include <algorithm>
#include <cctype>
#include <cstring>
#include <string>
#include <vector>
#include <exception>
#include <new>
#include <unistd.h>

namespace {

// Levenshtein distance, for the nearest option to a mistyped one.
std::size_t edit_distance(const std::string& a, const std::string& b) {
  std::vector<std::size_t> row(b.size() + 1);
  for (std::size_t j = 0; j <= b.size(); ++j) row[j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i) {
    std::size_t diagonal = row[0];
    row[0] = i;
    for (std::size_t j = 1; j <= b.size(); ++j) {
      const std::size_t up = row[j];
      row[j] = std::min({row[j] + 1, row[j - 1] + 1, diagonal + (a[i - 1] == b[j - 1] ? 0 : 1)});
      diagonal = up;
    }
  }
  return row[b.size()];
}

// The deepest subcommand the command line reached.
const CLI::App* active_command(const CLI::App& app) {
  const CLI::App* current = &app;
  for (;;) {
    const auto parsed = current->get_subcommands();
    if (parsed.empty()) return current;
    current = parsed.front();
  }
}

// The long option names of `command` and its parents.
std::vector<std::string> option_names(const CLI::App* command) {
  std::vector<std::string> names;
  for (const CLI::App* c = command; c != nullptr; c = c->get_parent())
    for (const CLI::Option* o : c->get_options())
      for (const std::string& l : o->get_lnames()) names.push_back("--" + l);
  return names;
}

// "did you mean --fibres?" for each unknown --option the error names, when one is close.
std::string suggestions(const CLI::App& app, const std::string& message) {
  const std::vector<std::string> names = option_names(active_command(app));
  std::string out;
  std::size_t at = 0;
  while ((at = message.find("--", at)) != std::string::npos) {
    std::size_t end = at;
    while (end < message.size() &&
           (std::isalnum(static_cast<unsigned char>(message[end])) || message[end] == '-' || message[end] == '_'))
      ++end;
    const std::string given = message.substr(at, end - at);
    at = end;
    std::string best;
    std::size_t best_distance = 4;
    for (const std::string& name : names) {
      const std::size_t d = edit_distance(given, name);
      if (d < best_distance) best_distance = d, best = name;
    }
    if (!best.empty() && best != given) out += (out.empty() ? "" : "; ") + std::string("did you mean ") + best + "?";
  }
  return out;
}

// An option error names the field of an options struct ("end_fraction: ..." or
// "CheckOptions::max_turning_angle_deg must ..."); where the active command has the option
// that sets it, the message names that instead ("--end-fraction: ...").
std::string with_option_names(const CLI::App& app, const std::string& message) {
  const std::vector<std::string> names = option_names(active_command(app));
  static const std::vector<std::pair<std::string, std::string>> renamed = {
      {"--max-turning-angle-deg", "--max-turning-angle"},
      {"--coverage-samples", "--samples"},
      {"--untangle-cells", "--untangle"},
      {"--corner-twist-deg", "--corner-twist"}};
  const auto word = [](char c) { return std::isalnum(static_cast<unsigned char>(c)) || c == '_'; };
  std::string out;
  std::size_t at = 0;
  while (at < message.size()) {
    if (!word(message[at])) {
      out += message[at++];
      continue;
    }
    std::size_t end = at;
    while (end < message.size() && word(message[end])) ++end;
    std::string token = message.substr(at, end - at);
    // "Struct::field": the field alone.
    if (end + 1 < message.size() && message.compare(end, 2, "::") == 0) {
      std::size_t field_end = end + 2;
      while (field_end < message.size() && word(message[field_end])) ++field_end;
      token = message.substr(end + 2, field_end - end - 2);
      end = field_end;
    }
    std::string flag = "--";
    for (char c : token) flag += c == '_' ? '-' : c;
    for (const auto& [from, to] : renamed)
      if (flag == from) flag = to;
    // A field is a snake_case word, or any word followed by a colon ("fibres: must be ...").
    const bool field = token.find('_') != std::string::npos || (end < message.size() && message[end] == ':');
    const bool option = field && std::find(names.begin(), names.end(), flag) != names.end();
    out += option ? flag : message.substr(at, end - at);
    at = end;
  }
  return out;
}

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

  // --help-all: the help of a command with its advanced options too.
  std::vector<std::string> arguments(argv, argv + argc);
  for (std::string& a : arguments)
    if (a == "--help-all") {
      a = "--help";
      fascicle::app::set_show_all_options(true);
    }
  std::vector<char*> pointers;
  for (std::string& a : arguments) pointers.push_back(a.data());
  argc = static_cast<int>(pointers.size());
  argv = pointers.data();

  CLI::App app{"fascicle: muscle fibres from messy muscle surfaces (CT/MRI)"};
  // Global options (-q, -v, --time-limit) are taken after the subcommand too.
  app.fallthrough();
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
    if (code != 0) {
      const std::string hint = suggestions(app, e.what());
      if (!hint.empty()) std::fprintf(stderr, "%s\n", hint.c_str());
    }
    return code == 0 ? 0 : fascicle::exit_code(fascicle::ErrorCode::usage);
  } catch (const fascicle::OptionError& e) {
    std::fprintf(stderr, "fascicle: error: %s\n", with_option_names(app, e.what()).c_str());
    return fascicle::exit_code(e.code());
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
