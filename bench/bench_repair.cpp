// fascicle bench repair: repairs every mesh of the corpus, each in its own child process (the
// same `fascicle repair` a user runs, with a time limit), and tabulates time and result.

#include "bench/bench_commands.h"

#include <nlohmann/json.hpp>

#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <memory>

namespace fascicle::bench {

namespace fs = std::filesystem;

namespace {

struct RepairBenchArgs {
  std::string data = FASCICLE_DATA_DIR;
  std::string sets = "muscles,broken,extra";
  std::string json;
  double time_limit = 120.0;
};

std::string self_path() {
  std::error_code ec;
  const fs::path p = fs::read_symlink("/proc/self/exe", ec);
  return ec ? std::string("fascicle") : p.string();
}

std::string quote(const std::string& s) {
  std::string q = "'";
  for (char c : s) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}

void run_repair_bench(const RepairBenchArgs& args) {
  std::vector<fs::path> files;
  std::string sets = args.sets + ",";
  for (std::size_t pos; (pos = sets.find(',')) != std::string::npos; sets.erase(0, pos + 1)) {
    const std::string set = sets.substr(0, pos);
    if (set.empty()) continue;
    const fs::path dir = fs::path(args.data) / set;
    if (!fs::is_directory(dir)) throw std::runtime_error("corpus folder " + dir.string() + " not found");
    for (const auto& e : fs::recursive_directory_iterator(dir)) {
      if (!e.is_regular_file()) continue;
      std::string ext = e.path().extension().string();
      std::transform(ext.begin(), ext.end(), ext.begin(), ::tolower);
      if (ext == ".off" || ext == ".obj" || ext == ".stl" || ext == ".ply" || ext == ".vtk") files.push_back(e.path());
    }
  }
  std::sort(files.begin(), files.end());
  const fs::path tmp = fs::temp_directory_path() / ("fascicle-bench-repair-" + std::to_string(::getpid()));
  fs::create_directories(tmp);
  const std::string exe = self_path();

  nlohmann::json records = nlohmann::json::array();
  std::printf("%-62s %8s %8s %-10s %8s %8s %9s %5s\n", "mesh", "faces_in", "faces_out", "status", "seconds", "cpu_s",
              "hausdorff", "exit");
  for (const fs::path& file : files) {
    const fs::path out = tmp / "out.off", report = tmp / "report.json";
    fs::remove(out);
    fs::remove(report);
    const std::string cmd = quote(exe) + " --quiet --time-limit " + std::to_string(args.time_limit) + " repair " +
                            quote(file.string()) + " -o " + quote(out.string()) + " --report " +
                            quote(report.string()) + " 2>" + quote((tmp / "stderr.txt").string());
    // CPU time of the child (and its wrap workers) from the children's resource usage: less
    // sensitive than wall time to other load on the machine.
    auto children_cpu = [] {
      rusage u{};
      ::getrusage(RUSAGE_CHILDREN, &u);
      return static_cast<double>(u.ru_utime.tv_sec + u.ru_stime.tv_sec) +
             1e-6 * static_cast<double>(u.ru_utime.tv_usec + u.ru_stime.tv_usec);
    };
    const double cpu0 = children_cpu();
    const auto t0 = std::chrono::steady_clock::now();
    const int status = std::system(cmd.c_str());
    const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    const double cpu = children_cpu() - cpu0;
    const int code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
    nlohmann::json rec = {{"mesh", fs::relative(file, args.data).string()},
                          {"exit_code", code},
                          {"wall_seconds", wall},
                          {"cpu_seconds", cpu}};
    nlohmann::json rep;
    if (fs::exists(report)) {
      std::ifstream in(report);
      rep = nlohmann::json::parse(in, nullptr, false);
    }
    if (rep.is_object()) {
      rec["status"] = rep.value("status", "?");
      if (rep.contains("input")) rec["faces_in"] = rep["input"]["faces"];
      if (rep.contains("output")) rec["faces_out"] = rep["output"]["faces"];
      if (rep.contains("seconds")) rec["seconds"] = rep["seconds"];
      if (rep.contains("hausdorff")) rec["hausdorff"] = rep["hausdorff"];
      if (rep.contains("hausdorff_whole_input")) rec["hausdorff_whole_input"] = rep["hausdorff_whole_input"];
      if (rep.contains("fallback")) rec["fallback"] = rep["fallback"];
      if (rep.contains("kept_area_share")) rec["kept_area_share"] = rep["kept_area_share"];
      if (rep.contains("error")) rec["error"] = rep["error"];
    } else {
      rec["status"] = code == 17 ? "time_limit" : "no_report";
    }
    std::printf("%-62s %8s %8s %-10s %8.3f %8.3f %9s %5d\n", rec["mesh"].get<std::string>().substr(0, 62).c_str(),
                rec.contains("faces_in") ? rec["faces_in"].dump().c_str() : "-",
                rec.contains("faces_out") ? rec["faces_out"].dump().c_str() : "-",
                rec["status"].get<std::string>().c_str(), rec.value("seconds", wall), cpu,
                rec.contains("hausdorff") ? std::to_string(rec["hausdorff"].get<double>()).substr(0, 8).c_str() : "-",
                code);
    std::fflush(stdout);
    records.push_back(rec);
  }
  fs::remove_all(tmp);
  if (!args.json.empty()) {
    std::ofstream out(args.json);
    out << records.dump(2) << '\n';
  }
}

}  // namespace

void add_repair_bench(CLI::App& bench) {
  auto args = std::make_shared<RepairBenchArgs>();
  CLI::App* cmd = bench.add_subcommand("repair", "Repair every corpus mesh (one child process each) and tabulate");
  cmd->add_option("--data", args->data, "Corpus folder")->capture_default_str();
  cmd->add_option("--sets", args->sets, "Comma-separated subfolders of the corpus")->capture_default_str();
  cmd->add_option("--json", args->json, "Write the records as JSON");
  cmd->add_option("--time-limit", args->time_limit, "Seconds per mesh")->capture_default_str();
  cmd->callback([args] { run_repair_bench(*args); });
}

}  // namespace fascicle::bench
