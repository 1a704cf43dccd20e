#pragma once
// One `fascicle decompose` run of a corpus muscle for the tests that read its report: the fibres
// kept when the check fails (--keep-failed) and the first try only (--second-try false), so that a
// test sees the attempt its feature changes. Include after catch2 and tests/test_common.h.
#include "tests/test_common.h"

#include <catch2/catch.hpp>
#include <nlohmann/json.hpp>

#include <fstream>
#include <string>

namespace fascicle::test {

/// Decomposes `muscle` into `out_dir`/m.vtk with the extra options `extra` and returns its report
/// (`out_dir`/m.json). Checks the exit code is 0 (passed) or 19 (written, quality check failed).
inline nlohmann::json decompose_report(const std::string& muscle, const std::string& out_dir,
                                       const std::string& extra) {
  const std::string report = out_dir + "/m.json";
  const int code = run_command(program() + " -q decompose " + muscle + " -o " + out_dir + "/m.vtk --report " + report +
                               " --keep-failed --second-try false " + extra + " 2>/dev/null");
  INFO(muscle << " " << extra);
  CHECK((code == 0 || code == 19));
  std::ifstream in(report);
  REQUIRE(in.good());
  return nlohmann::json::parse(in);
}

}  // namespace fascicle::test
