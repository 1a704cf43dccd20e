// fascicle batch INPUT_DIR|LIST.txt -o OUT_DIR [--jobs N] [decompose options]: decomposes many
// muscles, one `fascicle decompose` process per muscle (a crash, a hang or a failure of one muscle
// cannot take the batch down), writes one report per muscle and a summary CSV, continues past
// failures, skips muscles already done (resumable: every output is written atomically, so a batch
// killed mid-run leaves only complete files), and draws a progress bar on a terminal.

#include "app/commands.h"
#include "geometry/atomic_file.h"
#include "geometry/errors.h"
#include "geometry/subprocess.h"

#include <nlohmann/json.hpp>
#include <spdlog/spdlog.h>

#include <unistd.h>
#include <sys/wait.h>

#include <csignal>
#include <cmath>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <limits>
#include <memory>
#include <mutex>
#include <sstream>
#include <cstdint>
#include <thread>

namespace fascicle::app {

namespace {

namespace fs = std::filesystem;

struct BatchArgs {
  std::string input, output, format = "vtk", landmarks = "none";
  int jobs = 1;
  double time_limit = 600.0;
  bool force = false, keep_failed = false, retry_failed = false;
  std::vector<std::string> forwarded;  // decompose options, passed through
};

struct Muscle {
  std::string input, name;        // name: path relative to the input folder, no extension
  std::string origin, insertion;  // landmark files, when used
};

struct Outcome {
  std::string status = "not run", error;  ///< "not run", "running", "ok", "failed"
  int exit_code = -1;
  double seconds = 0.0;
  double inside_fraction = std::numeric_limits<double>::quiet_NaN(), coverage_p95 = inside_fraction,
         attachment = inside_fraction, segment_excursion = inside_fraction, layer_ratio = inside_fraction;
  long inverted_cells = -1, crossing_segments = -1;
  double fibre_length_m = std::numeric_limits<double>::quiet_NaN(), pennation_deg = fibre_length_m,
         pcsa_cm2 = fibre_length_m, max_force_n = fibre_length_m;
  bool skipped = false;
};

bool is_mesh(const fs::path& p) {
  std::string ext = p.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return ext == ".off" || ext == ".obj" || ext == ".stl" || ext == ".ply" || ext == ".vtk";
}

// Landmarks beside a mesh: the longest P such that the mesh's file name starts with P and both
// P.origin.xyz and P.insertion.xyz exist in its folder.
void find_landmarks(Muscle& m) {
  const fs::path mesh(m.input);
  std::string best;
  for (const auto& entry : fs::directory_iterator(mesh.parent_path().empty() ? fs::path(".") : mesh.parent_path())) {
    const std::string file = entry.path().filename().string();
    const std::string suffix = ".origin.xyz";
    if (file.size() <= suffix.size() || file.compare(file.size() - suffix.size(), suffix.size(), suffix) != 0) continue;
    const std::string prefix = file.substr(0, file.size() - suffix.size());
    if (mesh.filename().string().rfind(prefix, 0) != 0 || prefix.size() <= best.size()) continue;
    if (!fs::exists(entry.path().parent_path() / (prefix + ".insertion.xyz"))) continue;
    best = prefix;
  }
  if (best.empty()) return;
  m.origin = (mesh.parent_path() / (best + ".origin.xyz")).string();
  m.insertion = (mesh.parent_path() / (best + ".insertion.xyz")).string();
}

std::vector<Muscle> list_muscles(const BatchArgs& args) {
  std::vector<Muscle> muscles;
  const fs::path input(args.input);
  if (!fs::exists(input)) throw InputError(ErrorCode::file_missing, args.input + ": no such file or folder");
  if (fs::is_directory(input)) {
    for (const auto& entry : fs::recursive_directory_iterator(input)) {
      if (!entry.is_regular_file() || !is_mesh(entry.path())) continue;
      fs::path rel = fs::relative(entry.path(), input);
      muscles.push_back({entry.path().string(), (rel.parent_path() / rel.stem()).string(), "", ""});
    }
  } else if (is_mesh(input)) {
    // One mesh: a batch of one (the unit a cluster task runs).
    muscles.push_back({input.string(), input.stem().string(), "", ""});
  } else {
    std::ifstream in(input);
    if (!in) throw InputError(ErrorCode::file_missing, args.input + ": cannot be opened");
    std::string line;
    int number = 0;
    while (std::getline(in, line)) {
      ++number;
      const auto first = line.find_first_not_of(" \t\r");
      if (first == std::string::npos || line[first] == '#') continue;
      const auto last = line.find_last_not_of(" \t\r");
      fs::path p = line.substr(first, last - first + 1);
      if (p.is_relative()) p = input.parent_path() / p;
      if (!fs::exists(p))
        throw InputError(ErrorCode::file_missing,
                         args.input + ":" + std::to_string(number) + ": " + p.string() + ": no such file");
      muscles.push_back({p.string(), p.stem().string(), "", ""});
    }
  }
  std::sort(muscles.begin(), muscles.end(), [](const Muscle& a, const Muscle& b) { return a.name < b.name; });
  for (std::size_t i = 1; i < muscles.size(); ++i)
    if (muscles[i].name == muscles[i - 1].name)
      throw InputError(ErrorCode::malformed,
                       args.input + ": two muscles would share the output name " + muscles[i].name);
  if (muscles.empty())
    throw InputError(ErrorCode::file_empty, args.input + ": no mesh files (off, obj, stl, ply, vtk)");
  if (args.landmarks == "beside")
    for (Muscle& m : muscles) find_landmarks(m);
  return muscles;
}

// Runs `argv` with stdout/stderr to `log`, waits; returns the exit code (128 + signal), -1 when
// it cannot be started or waited for. The batch runs this from several threads at once, so the
// child is started with posix_spawn, not fork (geometry/subprocess.h). A killed batch takes its
// decompose processes with it (die_with_parent; their outputs are atomic: a killed one leaves at
// most a temporary file, removed when the batch is resumed).
int run_process(const std::vector<std::string>& argv, const std::string& log) {
  SpawnOptions spawn;
  spawn.argv = argv;
  spawn.log_file = log;
  pid_t pid = -1;
  try {
    pid = spawn_process(spawn);
  } catch (const Error& e) {
    spdlog::error("batch: {}", e.what());
    return -1;
  }
  const int status = wait_process(pid);
  if (status == -1) return -1;
  return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
}

void read_outcome(const std::string& report_path, Outcome& o) {
  std::ifstream in(report_path);
  if (!in) return;
  try {
    const nlohmann::json r = nlohmann::json::parse(in);
    o.status = r.value("status", "failed");
    if (r.contains("error")) o.error = r["error"].get<std::string>();
    if (r.contains("quality")) {
      const auto& q = r["quality"];
      o.inside_fraction = q.value("inside_fraction", o.inside_fraction);
      o.inverted_cells = q.value("inverted_cells", -1L);
      if (q.contains("coverage")) o.coverage_p95 = q["coverage"].value("p95", o.coverage_p95);
      if (q.contains("attachment"))
        o.attachment = std::max(q["attachment"].value("origin_max", 0.0), q["attachment"].value("insertion_max", 0.0));
      o.crossing_segments = q.value("crossing_segments", -1L);
      o.segment_excursion = q.value("max_segment_excursion_relative", o.segment_excursion);
      if (q.contains("steps")) o.layer_ratio = q["steps"].value("layer_ratio", o.layer_ratio);
    }
    if (r.contains("seconds") && r["seconds"].is_object()) o.seconds = r["seconds"].value("total", o.seconds);
    if (r.contains("architecture") && r["architecture"].is_object()) {
      const auto& a = r["architecture"];
      if (a.contains("fibre_length_m")) o.fibre_length_m = a["fibre_length_m"].value("mean", o.fibre_length_m);
      if (a.contains("pennation_deg")) o.pennation_deg = a["pennation_deg"].value("mean", o.pennation_deg);
      o.pcsa_cm2 = a.value("pcsa_cm2", o.pcsa_cm2);
      o.max_force_n = a.value("max_isometric_force_n", o.max_force_n);
    }
  } catch (const std::exception&) {
    o.status = "failed";
    o.error = "unreadable report";
  }
}

std::string csv_field(const std::string& s) {
  if (s.find_first_of(",\"\n") == std::string::npos) return s;
  std::string out = "\"";
  for (char c : s) out += c == '"' ? std::string("\"\"") : std::string(1, c == '\n' ? ' ' : c);
  return out + "\"";
}

void write_summary(const std::string& path, const std::vector<Muscle>& muscles, const std::vector<Outcome>& outcomes) {
  write_file_atomically(path, [&](std::ostream& out) {
    out << std::setprecision(std::numeric_limits<double>::max_digits10);
    out << "muscle,status,exit_code,seconds,inside_fraction,inverted_cells,coverage_p95,attachment,crossing_segments,"
           "segment_excursion,layer_ratio,fibre_length_m,pennation_deg,pcsa_cm2,max_isometric_force_n,error\n";
    for (std::size_t i = 0; i < muscles.size(); ++i) {
      const Outcome& o = outcomes[i];
      char seconds[32];
      std::snprintf(seconds, sizeof(seconds), "%.3f", o.seconds);
      out << csv_field(muscles[i].name) << ',' << o.status << ',' << o.exit_code << ',' << seconds << ','
          << o.inside_fraction << ',' << o.inverted_cells << ',' << o.coverage_p95 << ',' << o.attachment << ','
          << o.crossing_segments << ',' << o.segment_excursion << ',' << o.layer_ratio << ',' << o.fibre_length_m << ','
          << o.pennation_deg << ',' << o.pcsa_cm2 << ',' << o.max_force_n << ',' << csv_field(o.error) << '\n';
    }
  });
}

// FNV-1a, 64 bits: a fingerprint that is the same on every build and machine.
std::uint64_t fnv1a(const std::string& bytes, std::uint64_t hash = 1469598103934665603ULL) {
  for (unsigned char c : bytes) hash = (hash ^ c) * 1099511628211ULL;
  return hash;
}

std::string file_bytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream content;
  content << in.rdbuf();
  return content.str();
}

// What a muscle's result depends on: its input's bytes, its landmark files', the decompose
// options forwarded (a tuning file's content with them) and the fibre format. A report made
// from another request is redone.
std::string request_fingerprint(const Muscle& m, const BatchArgs& args) {
  std::uint64_t h = fnv1a(file_bytes(m.input));
  for (const std::string& path : {m.origin, m.insertion})
    h = fnv1a(path.empty() ? std::string("-") : file_bytes(path), h);
  for (std::size_t i = 0; i < args.forwarded.size(); ++i) {
    h = fnv1a(args.forwarded[i] + '\0', h);
    // A tuning file counts by its content: an edited file is another request.
    if (args.forwarded[i] == "--tuning" && i + 1 < args.forwarded.size())
      h = fnv1a(file_bytes(args.forwarded[i + 1]), h);
  }
  h = fnv1a("format=" + args.format, h);
  h = fnv1a(args.keep_failed ? "keep-failed" : "", h);
  char text[17];
  std::snprintf(text, sizeof(text), "%016llx", static_cast<unsigned long long>(h));
  return text;
}

// The batch's record in a muscle's report: the request's fingerprint, the process's exit code
// and seconds (read back for a muscle a resumed batch skips).
void record_batch(const std::string& report_path, const std::string& fingerprint, const Outcome& o) {
  nlohmann::json r;
  {
    std::ifstream in(report_path);
    try {
      if (in) r = nlohmann::json::parse(in);
    } catch (const std::exception&) { r = nlohmann::json::object(); }
  }
  if (!r.is_object()) r = nlohmann::json::object();
  if (!r.contains("status")) r["status"] = o.status;
  if (!r.contains("error") && !o.error.empty()) r["error"] = o.error;
  r["batch"] = {{"fingerprint", fingerprint}, {"exit_code", o.exit_code}, {"seconds", o.seconds}};
  write_file_atomically(report_path, [&](std::ostream& out) { out << std::setw(2) << r << '\n'; });
}

// The fingerprint and outcome a report's batch record holds ("" when it has none).
std::string recorded_fingerprint(const std::string& report_path, Outcome& o) {
  std::ifstream in(report_path);
  try {
    const nlohmann::json r = nlohmann::json::parse(in);
    if (!r.contains("batch")) return "";
    o.exit_code = r["batch"].value("exit_code", o.exit_code);
    o.seconds = r["batch"].value("seconds", o.seconds);
    return r["batch"].value("fingerprint", std::string());
  } catch (const std::exception&) { return ""; }
}

// The OpenSim muscle parameters of every muscle that passed, as the Thelen 2003 and Millard 2012
// muscle models name them: optimal fibre length (m), pennation angle at optimal length (rad),
// maximum isometric force (N), from the fibres as decomposed (their lengths taken as optimal).
void write_opensim(const std::string& path, const std::vector<Muscle>& muscles, const std::vector<Outcome>& outcomes) {
  write_file_atomically(path, [&](std::ostream& out) {
    out << std::setprecision(std::numeric_limits<double>::max_digits10);
    out << "muscle,optimal_fiber_length,pennation_angle_at_optimal,max_isometric_force\n";
    for (std::size_t i = 0; i < muscles.size(); ++i) {
      const Outcome& o = outcomes[i];
      if (o.status != "ok" || !std::isfinite(o.fibre_length_m)) continue;
      out << csv_field(muscles[i].name) << ',' << o.fibre_length_m << ','
          << o.pennation_deg * 3.14159265358979323846 / 180.0 << ',' << o.max_force_n << '\n';
    }
  });
}

std::string self_path() {
  std::error_code ec;
  const fs::path p = fs::read_symlink("/proc/self/exe", ec);
  if (ec) throw Error(ErrorCode::internal, "batch: cannot find the fascicle program (/proc/self/exe)");
  return p.string();
}

// True when process `pid` exists and is not a zombie (a killed process its parent has not reaped
// yet is gone for our purpose).
bool process_alive(pid_t pid) {
  if (::kill(pid, 0) != 0 && errno == ESRCH) return false;
  std::ifstream stat("/proc/" + std::to_string(pid) + "/stat");
  std::string line;
  if (!std::getline(stat, line)) return true;  // no /proc: trust kill()
  const auto close = line.rfind(')');
  return close == std::string::npos || close + 2 >= line.size() || line[close + 2] != 'Z';
}

// Temporary files of a killed run (".NAME.tmp.PID...", geometry/atomic_file.cpp) whose process is
// gone; removed so that a resumed batch leaves only complete outputs. Returns how many.
int remove_stale_temporaries(const std::string& folder) {
  int removed = 0;
  std::error_code ec;
  if (!fs::exists(folder, ec)) return 0;
  for (const auto& entry : fs::recursive_directory_iterator(folder, ec)) {
    const std::string name = entry.path().filename().string();
    const auto at = name.find(".tmp.");
    if (name.empty() || name[0] != '.' || at == std::string::npos || !entry.is_regular_file()) continue;
    const long pid = std::strtol(name.c_str() + at + 5, nullptr, 10);
    if (pid > 0 && process_alive(static_cast<pid_t>(pid))) continue;
    if (fs::remove(entry.path(), ec)) ++removed;
  }
  return removed;
}

void run_batch(const BatchArgs& args) {
  if (args.jobs < 1 || args.jobs > 256)
    throw OptionError("--jobs: must be in 1..256, got " + std::to_string(args.jobs));
  if (!(args.time_limit >= 0.0)) throw OptionError("--muscle-time-limit: must be >= 0");
  const std::vector<Muscle> muscles = list_muscles(args);
  fs::create_directories(args.output);
  const std::string program = self_path();
  // The options once, before any muscle: a bad value is one error, not a failed report per muscle.
  {
    std::vector<std::string> argv = {program,
                                     "-q",
                                     "decompose",
                                     muscles.front().input,
                                     "-o",
                                     (fs::path(args.output) / ("check." + args.format)).string(),
                                     "--check-options"};
    argv.insert(argv.end(), args.forwarded.begin(), args.forwarded.end());
    const std::string log = (fs::path(args.output) / ".options.log").string();
    const int code = run_process(argv, log);
    std::string message = file_bytes(log);
    std::error_code ec;
    fs::remove(log, ec);
    if (code != 0) {
      while (!message.empty() && (message.back() == '\n' || message.back() == '\r')) message.pop_back();
      const auto prefix = message.find("error: ");
      if (prefix != std::string::npos) message = message.substr(prefix + 7);
      throw Error(code > 0 && code < 128 ? static_cast<ErrorCode>(code) : ErrorCode::internal,
                  "batch: the decompose options are refused: " + message);
    }
  }
  if (const int stale = remove_stale_temporaries(args.output); stale > 0)
    spdlog::info("batch: removed {} temporary file(s) left by an interrupted run", stale);
  std::vector<Outcome> outcomes(muscles.size());
  std::atomic<std::size_t> next{0};
  std::atomic<int> done{0}, failed{0}, skipped{0}, redone{0};
  std::mutex mutex;
  const bool tty = isatty(2) != 0;
  const auto start = std::chrono::steady_clock::now();
  auto progress = [&](const std::string& last) {
    if (!tty) return;
    const int width = 30, d = done.load();
    const int filled = static_cast<int>(width * d / std::max<std::size_t>(1, muscles.size()));
    std::fprintf(stderr, "\r[%s%s] %d/%zu done, %d failed, %d skipped  %-40.40s", std::string(filled, '#').c_str(),
                 std::string(width - filled, '.').c_str(), d, muscles.size(), failed.load(), skipped.load(),
                 last.c_str());
    std::fflush(stderr);
  };
  const std::string summary = (fs::path(args.output) / "summary.csv").string();
  auto worker = [&]() {
    for (std::size_t i = next++; i < muscles.size(); i = next++) {
      const Muscle& m = muscles[i];
      Outcome& o = outcomes[i];
      const fs::path base = fs::path(args.output) / m.name;
      fs::create_directories(base.parent_path());
      const std::string fibres = base.string() + "." + args.format;
      const std::string report = base.string() + ".report.json";
      const std::string fingerprint = request_fingerprint(m, args);
      // A report of the same request is kept (failed ones too, unless --retry-failed); one made
      // from other options, another format or a changed input is redone.
      bool skip = false;
      if (!args.force && fs::exists(report)) {
        Outcome recorded;
        read_outcome(report, recorded);
        const std::string previous = recorded_fingerprint(report, recorded);
        if (previous == fingerprint && !(args.retry_failed && recorded.status != "ok")) {
          o = recorded;
          o.skipped = true;
          skip = true;
          ++skipped;
        } else if (previous != fingerprint) {
          ++redone;
        }
      }
      if (!skip) {
        {
          std::lock_guard<std::mutex> lock(mutex);
          o.status = "running";
          write_summary(summary, muscles, outcomes);
        }
        std::error_code ec;
        fs::remove(report, ec);  // a report of another request must not stand for this run
        fs::remove(fibres, ec);
        std::vector<std::string> argv = {program, "-q", "decompose", m.input, "-o", fibres, "--report", report};
        if (args.time_limit > 0.0) argv.insert(argv.begin() + 1, {"--time-limit", std::to_string(args.time_limit)});
        if (!m.origin.empty()) argv.insert(argv.end(), {"--origin", m.origin, "--insertion", m.insertion});
        if (args.keep_failed) argv.push_back("--keep-failed");
        argv.insert(argv.end(), args.forwarded.begin(), args.forwarded.end());
        const auto t0 = std::chrono::steady_clock::now();
        o.status = "not run";
        o.exit_code = run_process(argv, base.string() + ".log");
        o.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
        read_outcome(report, o);
        o.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
        if (o.exit_code == 0)
          o.status = "ok";
        else if (o.status == "ok" || o.status == "not run")
          o.status = "failed";
        if (o.error.empty() && o.exit_code != 0) {
          std::ifstream log(base.string() + ".log");
          std::string line, last;
          while (std::getline(log, line))
            if (!line.empty()) last = line;
          o.error = last.empty() ? "exit code " + std::to_string(o.exit_code) : last;
        }
        // The process died before it could write its report (a signal, the time limit) or wrote
        // one: either way the report records the request, the exit code and the time, so that a
        // resumed batch keeps it (--force or --retry-failed redo it).
        record_batch(report, fingerprint, o);
      }
      if (o.status != "ok") ++failed;
      ++done;
      std::lock_guard<std::mutex> lock(mutex);
      write_summary(summary, muscles, outcomes);
      progress(m.name);
    }
  };
  std::vector<std::thread> threads;
  for (int t = 0; t < args.jobs; ++t) threads.emplace_back(worker);
  for (std::thread& t : threads) t.join();
  if (tty) std::fprintf(stderr, "\n");
  write_opensim((fs::path(args.output) / "opensim.csv").string(), muscles, outcomes);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  spdlog::info(
      "batch: {} muscles, {} ok, {} failed, {} skipped (already done with these options){} in {:.1f} s; "
      "summary in {}",
      muscles.size(), muscles.size() - static_cast<std::size_t>(failed.load()), failed.load(), skipped.load(),
      redone.load() > 0 ? ", " + std::to_string(redone.load()) + " redone (their options, format or input changed)"
                        : std::string(),
      seconds, summary);
  if (failed.load() > 0) {
    // 19 when every failure is the quality check's; else the exit code of the first muscle that
    // failed otherwise (a repair that failed, a time limit, a crash).
    int code = exit_code(ErrorCode::quality);
    for (const Outcome& o : outcomes)
      if (o.status != "ok" && o.exit_code != exit_code(ErrorCode::quality)) {
        code = o.exit_code > 0 && o.exit_code < 128 ? o.exit_code : exit_code(ErrorCode::internal);
        break;
      }
    throw Error(static_cast<ErrorCode>(code), "batch: " + std::to_string(failed.load()) + " of " +
                                                  std::to_string(muscles.size()) + " muscles failed; see " + summary);
  }
}

}  // namespace

void add_batch_command(CLI::App& app) {
  auto args = std::make_shared<BatchArgs>();
  CLI::App* cmd = app.add_subcommand(
      "batch", "Decompose every muscle of a folder (recursively) or a list file, one process per muscle; resumable");
  cmd->add_option("input", args->input, "Folder of meshes (searched recursively) or a text file with one mesh per line")
      ->required();
  cmd->add_option("-o,--output", args->output, "Output folder: fibres, report and log per muscle, summary.csv")
      ->required();
  cmd->add_option("--jobs", args->jobs, "Muscles decomposed at once")->capture_default_str();
  cmd->add_option("--format", args->format, "Fibre file format: vtk, vtp, vtu, obj, csv")
      ->check(CLI::IsMember({"vtk", "vtp", "vtu", "obj", "csv"}))
      ->capture_default_str();
  cmd->add_option("--landmarks", args->landmarks,
                  "none (automatic areas) or beside (P.origin.xyz and P.insertion.xyz next to a mesh whose name starts "
                  "with P)")
      ->check(CLI::IsMember({"none", "beside"}))
      ->capture_default_str();
  cmd->add_option("--muscle-time-limit", args->time_limit, "Seconds per muscle before it is stopped (0: none)")
      ->capture_default_str();
  cmd->add_flag("--force", args->force, "Redo muscles that already have a report");
  cmd->add_flag("--keep-failed", args->keep_failed, "Write fibres even for muscles that fail the check");
  cmd->add_flag("--retry-failed", args->retry_failed, "Redo muscles whose report says they failed");
  // Every decompose option, passed through unchanged: one table, decompose's own.
  CLI::App mirror;
  add_decompose_command(mirror);
  const CLI::App* decompose = mirror.get_subcommand("decompose");
  for (const CLI::Option* option : decompose->get_options()) {
    const std::string name = option->get_name();
    if (option->get_positional() || name == "--help" || name == "-h,--help" || name == "--output" ||
        name == "-o,--output" || name == "--report" || name == "--write-repaired" || name == "--origin" ||
        name == "--insertion" || name == "--keep-failed" || name == "--check-options" || name == "--architecture" ||
        name == "--fe-mesh")
      continue;
    const std::string flag = option->get_lnames().empty() ? name : "--" + option->get_lnames().front();
    auto seen = std::make_shared<bool>(false);
    cmd->add_option(flag, option->get_description())
        ->expected(option->get_expected_min(), option->get_expected_max())
        ->each([args, flag, seen](const std::string& v) {
          if (!*seen) args->forwarded.push_back(flag);
          *seen = true;
          args->forwarded.push_back(v);
        })
        ->group("Decompose options (passed to every muscle's decompose)");
  }
  cmd->callback([args] { run_batch(*args); });
}

}  // namespace fascicle::app
