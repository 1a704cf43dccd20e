// Broken meshes at scale: random combinations of the defect injector's sixteen defects applied to
// every muscle of the shared corpus, each broken mesh then run through the pipeline's stages as
// separate `fascicle` processes, as a user runs them. Every run must end in a verified result or
// a clean refusal (a documented exit code, one line on stderr, no output file); never a crash, a
// hang or a partial file, and the input file is never touched.
//
// `make test` runs one fixed seed per muscle; `make stress SEEDS=N` runs N seeds per muscle
// (FASCICLE_STRESS_SEEDS=N, FASCICLE_STRESS_JOBS=J processes at a time, default 2).
// FASCICLE_STRESS_STRIDE=K takes every K-th muscle only (default 1: all): the sanitized run
// (scripts/run-sanitized-tests.sh) uses it, where one case takes minutes instead of seconds.
// Stages: stress_stages() below: repair, then decompose of the repaired mesh.

#include "geometry/errors.h"
#include "geometry/inject_defects.h"
#include "geometry/mesh_io.h"
#include "repair/repair.h"
#include "test_common.h"

#include <catch2/catch.hpp>
#include <nlohmann/json.hpp>

#include <atomic>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <map>
#include <mutex>
#include <set>
#include <sstream>
#include <thread>
#include <tuple>

using namespace fascicle;
using test::read_text;
namespace fs = std::filesystem;

namespace {

int env_int(const char* name, int fallback) {
  const char* value = std::getenv(name);
  if (value == nullptr || *value == '\0') return fallback;
  return std::max(1, std::atoi(value));
}

/// One stage of the pipeline as the stress test runs it.
struct Stage {
  std::string name;
  /// Extension of the stage's output file.
  std::string output_ext;
  /// Command-line arguments after `fascicle --quiet --time-limit T`, given input, output, report.
  std::function<std::string(const std::string&, const std::string&, const std::string&)> arguments;
  /// Exit codes that are clean refusals of this stage (besides time_limit, always allowed).
  std::set<int> refusals;
  /// Checks a successful run's output and report; returns "" when both are right, else why not.
  std::function<std::string(const std::string&, const std::string&)> verify;
};

std::string quoted(const std::string& s) { return "'" + s + "'"; }

/// The stages every broken mesh goes through, in order; each takes the previous one's output.
std::vector<Stage> stress_stages() {
  std::vector<Stage> stages;
  stages.push_back(Stage{
      "repair",
      "off",
      [](const std::string& in, const std::string& out, const std::string& report) {
        // A short wrap budget keeps the fixed seeds of `make test` quick; the time limit above
        // still bounds every run.
        return "repair " + quoted(in) + " -o " + quoted(out) + " --report " + quoted(report) + " --wrap-seconds 15";
      },
      {exit_code(ErrorCode::bad_number), exit_code(ErrorCode::repair_failed), exit_code(ErrorCode::topology)},
      [](const std::string& out, const std::string& report) -> std::string {
        nlohmann::json j;
        try {
          j = nlohmann::json::parse(read_text(report));
        } catch (const std::exception& e) { return std::string("report is not JSON: ") + e.what(); }
        const std::string status = j.value("status", "");
        if (status != "repaired" && status != "unchanged" && status != "wrapped")
          return "report status '" + status + "'";
        if (j["output"]["genus"] != 0 || j["output"]["components"] != 1) return "report census is not genus 0";
        try {
          const PolygonSoup soup = read_polygon_soup(out);
          const std::string verdict = verify_genus0(soup_triangles(soup));
          if (!verdict.empty()) return "output fails verification: " + verdict;
        } catch (const Error& e) { return std::string("output does not read back: ") + e.what(); }
        return "";
      }});
  stages.push_back(
      Stage{"decompose",
            "vtk",
            [](const std::string& in, const std::string& out, const std::string& report) {
              return "decompose " + quoted(in) + " -o " + quoted(out) + " --report " + quoted(report);
            },
            // Refusals: a sphere map that is not a bijection (solver), or fibres that fail the check
            // (quality: then no fibre file is written).
            {exit_code(ErrorCode::solver_diverged), exit_code(ErrorCode::quality), exit_code(ErrorCode::topology)},
            [](const std::string& out, const std::string& report) -> std::string {
              nlohmann::json j;
              try {
                j = nlohmann::json::parse(read_text(report));
              } catch (const std::exception& e) { return std::string("report is not JSON: ") + e.what(); }
              if (j.value("status", "") != "ok") return "report status '" + j.value("status", "") + "'";
              if (j["quality"]["inside_fraction"] != 1.0) return "a fibre point is outside";
              try {
                const Polylines fibres = read_polylines(out);
                if (fibres.lines.size() != 100) return "fibre count " + std::to_string(fibres.lines.size());
                for (const auto& line : fibres.lines)
                  for (const Vec3& p : line)
                    if (!p.allFinite()) return "a fibre point is not finite";
              } catch (const Error& e) { return std::string("fibres do not read back: ") + e.what(); }
              return "";
            }});
  return stages;
}

/// Welds exactly equal points (STL stores three per facet), so that the injector sees the
/// muscle's connectivity.
PolygonSoup weld_exact(const PolygonSoup& soup) {
  PolygonSoup out;
  std::map<std::tuple<double, double, double>, int> index;
  std::vector<int> remap(soup.points.size());
  for (std::size_t i = 0; i < soup.points.size(); ++i) {
    const Vec3& p = soup.points[i];
    const auto [it, inserted] =
        index.emplace(std::make_tuple(p.x(), p.y(), p.z()), static_cast<int>(out.points.size()));
    if (inserted) out.points.push_back(p);
    remap[i] = it->second;
  }
  for (const auto& polygon : soup.polygons) {
    std::vector<int> q;
    for (int i : polygon) q.push_back(remap[static_cast<std::size_t>(i)]);
    out.polygons.push_back(std::move(q));
  }
  return out;
}

/// Writes a soup as OFF text by hand: the writers refuse non-finite coordinates, and the stress
/// test must also hand NaN to the readers.
void write_off_text(const std::string& path, const PolygonSoup& soup) {
  std::ofstream out(path);
  out.precision(std::numeric_limits<double>::max_digits10);
  out << "OFF\n" << soup.points.size() << " " << soup.polygons.size() << " 0\n";
  for (const Vec3& p : soup.points) {
    for (int c = 0; c < 3; ++c) {
      if (std::isnan(p[c]))
        out << "nan";
      else
        out << p[c];
      out << (c < 2 ? ' ' : '\n');
    }
  }
  for (const auto& polygon : soup.polygons) {
    out << polygon.size();
    for (int i : polygon) out << ' ' << i;
    out << '\n';
  }
}

/// One broken input: which muscle, which seed, what was done to it.
struct Case {
  std::string muscle;
  std::uint64_t seed = 0;
  std::string input;        ///< the broken mesh file
  std::string description;  ///< defects applied
  std::string skipped;      ///< why no broken mesh could be made ("" when one was)
};

/// What one stage run did.
struct Run {
  std::string stage;
  int code = 0;
  std::string stderr_text;
  std::string failure;  ///< "" when the run met every promise
};

/// Makes the broken input of one case: 2 to 4 random kinds from inject_random_combination (the
/// fifteen kinds other than NaN), then, by seed, nothing more, a 1e-6 or 1e6 scale, or NaN
/// coordinates; written in a format chosen by the seed (OFF text when NaN is present).
void make_case(Case& c, const PolygonSoup& muscle, const std::string& dir) {
  const std::uint64_t seed = c.seed;
  DefectLog log;
  PolygonSoup broken;
  try {
    broken = inject_random_combination(muscle, seed, 2 + static_cast<int>(seed % 3), &log);
    const int extra = static_cast<int>(derive_seed(seed, 99) % 4);
    if (extra == 1 || extra == 2) {
      DefectParams params;
      params.scale_factor = extra == 1 ? 1e-6 : 1e6;
      broken = inject(broken, DefectKind::scale, derive_seed(seed, 100), params, &log);
    } else if (extra == 3) {
      broken = inject(broken, DefectKind::nan_coordinates, derive_seed(seed, 100), {}, &log);
    }
  } catch (const Error& e) {
    c.skipped = std::string("injector: ") + e.what();
    return;
  }
  std::ostringstream what;
  for (const auto& r : log.records) what << defect_name(r.kind) << "(" << r.count << ") ";
  c.description = what.str();
  bool finite = true;
  for (const Vec3& p : broken.points) finite = finite && p.allFinite();
  static const char* formats[] = {"off", "obj", "ply", "stl", "vtk"};
  std::string ext = finite ? formats[derive_seed(seed, 101) % 5] : "off";
  c.input = dir + "/broken." + ext;
  if (finite) {
    try {
      write_triangle_mesh(c.input, soup_triangles(broken));
    } catch (const IoError&) {
      // STL's float32 merges the corners of a mesh scaled down far from the origin (the writer
      // refuses it): the same mesh goes in as OFF.
      ext = "off";
      c.input = dir + "/broken." + ext;
      write_triangle_mesh(c.input, soup_triangles(broken));
      c.description += "(refused as .stl) ";
    }
  } else {
    write_off_text(c.input, broken);
  }
  c.description += "as ." + ext;
}

struct Stamp {
  std::uintmax_t size;
  fs::file_time_type time;
  bool operator==(const Stamp& o) const { return size == o.size && time == o.time; }
};
Stamp stamp(const std::string& path) { return {fs::file_size(path), fs::last_write_time(path)}; }

/// Runs the stages on one case's input in `dir`; stops at the first refusal.
std::vector<Run> run_stages(const Case& c, const std::string& dir, int time_limit) {
  std::vector<Run> runs;
  std::string input = c.input;
  int step = 0;
  for (const Stage& stage : stress_stages()) {
    Run run;
    run.stage = stage.name;
    const std::string prefix = dir + "/" + std::to_string(step++) + "-" + stage.name;
    const std::string out = prefix + "." + stage.output_ext, report = prefix + ".json", err = prefix + ".stderr";
    const Stamp before = stamp(input);
    run.code = test::run_command(quoted(test::program()) + " --quiet --time-limit " + std::to_string(time_limit) + " " +
                                 stage.arguments(input, out, report) + " > /dev/null 2> " + quoted(err));
    run.stderr_text = read_text(err);
    std::string& why = run.failure;
    if (!(stamp(input) == before)) why = "the input file changed";
    for (const auto& entry : fs::directory_iterator(dir))
      if (entry.path().filename().string().find(".tmp") != std::string::npos)
        why = "temporary file left behind: " + entry.path().string();
    if (why.empty() && run.code == 0) {
      if (!fs::exists(out))
        why = "exit 0 without an output file";
      else
        why = stage.verify(out, report);
    } else if (why.empty()) {
      const bool clean_code = stage.refusals.count(run.code) != 0 || run.code == exit_code(ErrorCode::time_limit);
      const bool one_line = run.stderr_text.rfind("fascicle: error: ", 0) == 0 &&
                            std::count(run.stderr_text.begin(), run.stderr_text.end(), '\n') == 1;
      if (!clean_code)
        why = "exit code " + std::to_string(run.code) + " is not a clean refusal of " + stage.name;
      else if (!one_line)
        why = "stderr is not one 'fascicle: error:' line";
      else if (fs::exists(out))
        why = "refused but an output file exists";
    }
    runs.push_back(run);
    if (run.code != 0 || !run.failure.empty()) break;
    input = out;
  }
  return runs;
}

}  // namespace

TEST_CASE("stress: random defect combinations on every corpus muscle end verified or cleanly refused",
          "[stress][corpus][reliability]") {
  FASCICLE_REQUIRE_DATA();
  const auto muscles = test::corpus_files("muscles", {"off", "obj", "stl", "ply", "vtk"});
  REQUIRE_FALSE(muscles.empty());
  const int seeds = env_int("FASCICLE_STRESS_SEEDS", 1);
  const int jobs = env_int("FASCICLE_STRESS_JOBS", 2);
  const int time_limit = env_int("FASCICLE_STRESS_TIME_LIMIT", 90);
  const int stride = env_int("FASCICLE_STRESS_STRIDE", 1);

  test::TempDir root;
  std::vector<Case> cases;
  std::vector<std::string> dirs;
  for (std::size_t m = 0; m < muscles.size(); m += static_cast<std::size_t>(stride)) {
    const PolygonSoup muscle = weld_exact(read_polygon_soup(muscles[m]));
    for (int k = 0; k < seeds; ++k) {
      Case c;
      c.muscle = muscles[m];
      c.seed = 1000u * static_cast<std::uint64_t>(k) + m + 1;  // fixed: the same runs every time
      const std::string dir = root.file(std::to_string(cases.size()));
      fs::create_directories(dir);
      make_case(c, muscle, dir);
      cases.push_back(c);
      dirs.push_back(dir);
    }
  }

  // The runs are independent processes; worker threads only collect results (Catch2's
  // assertions are not thread-safe), the checks below run on this thread.
  std::vector<std::vector<Run>> results(cases.size());
  std::atomic<std::size_t> next{0};
  std::vector<std::thread> workers;
  for (int w = 0; w < jobs; ++w)
    workers.emplace_back([&] {
      for (std::size_t i = next++; i < cases.size(); i = next++)
        if (cases[i].skipped.empty()) results[i] = run_stages(cases[i], dirs[i], time_limit);
    });
  for (auto& t : workers) t.join();

  std::map<std::string, int> outcomes;
  std::size_t skipped = 0;
  for (std::size_t i = 0; i < cases.size(); ++i) {
    const Case& c = cases[i];
    if (!c.skipped.empty()) {
      ++skipped;
      WARN(c.muscle << " seed " << c.seed << ": no broken mesh made (" << c.skipped << ")");
      continue;
    }
    for (const Run& run : results[i]) {
      INFO(c.muscle << " seed " << c.seed << ": " << c.description << "; " << run.stage << " exit " << run.code
                    << ", stderr: " << run.stderr_text);
      CHECK(run.failure == "");
      ++outcomes[run.stage + " exit " + std::to_string(run.code)];
    }
  }
  // Most muscles must be breakable, or the test tests little.
  CHECK(skipped * 4 <= cases.size());
  std::ostringstream summary;
  for (const auto& [what, n] : outcomes) summary << what << ": " << n << "; ";
  WARN("stress: " << cases.size() << " cases (" << skipped << " not injectable), " << summary.str());
}
