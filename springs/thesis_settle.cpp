// Target files, lattice recognition and fibre output for `fascicle settle`.

#include "springs/thesis_settle.h"

#include "geometry/errors.h"
#include "springs/solvers_internal.h"

#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>

namespace fascicle::springs {
namespace {

[[noreturn]] void fail(ErrorCode code, const std::string& path, long line, const std::string& what) {
  throw InputError(code, path + ":" + std::to_string(line) + ": " + what);
}

double parse_double(const std::string& token, const std::string& path, long line) {
  errno = 0;
  char* end = nullptr;
  const double v = std::strtod(token.c_str(), &end);
  if (end == token.c_str() || *end != '\0' || errno == ERANGE || !std::isfinite(v))
    fail(ErrorCode::bad_number, path, line, "'" + token + "' is not a finite number");
  return v;
}

}  // namespace

std::vector<Target> read_targets(const std::string& path, const ReadOptions& options) {
  std::ifstream in(path);
  if (!in) throw InputError(ErrorCode::file_missing, path + ": cannot open the target file");
  std::vector<Target> targets;
  std::string text;
  long line = 0;
  while (std::getline(in, text)) {
    ++line;
    const auto hash = text.find('#');
    if (hash != std::string::npos) text.erase(hash);
    std::istringstream fields(text);
    std::vector<std::string> tokens;
    for (std::string token; fields >> token;) tokens.push_back(token);
    if (tokens.empty()) continue;
    if (tokens.size() != 4)
      fail(ErrorCode::malformed, path, line,
           "expected 'index x y z', found " + std::to_string(tokens.size()) + " fields");
    if (targets.size() >= options.max_elements)
      fail(ErrorCode::too_large, path, line, "more than " + std::to_string(options.max_elements) + " targets");
    errno = 0;
    char* end = nullptr;
    const long long index = std::strtoll(tokens[0].c_str(), &end, 10);
    if (end == tokens[0].c_str() || *end != '\0' || errno == ERANGE || index < 0 || index > 2147483647LL)
      fail(ErrorCode::bad_number, path, line, "'" + tokens[0] + "' is not a point index");
    Target t;
    t.index = static_cast<int>(index);
    for (int c = 0; c < 3; ++c) t.position[c] = parse_double(tokens[1 + c], path, line);
    targets.push_back(t);
  }
  if (targets.empty()) throw InputError(ErrorCode::file_empty, path + ": no target in the file");
  return targets;
}

void apply_targets(SpringSystem& system, const std::vector<Target>& targets, const std::string& source) {
  std::vector<char> seen(system.positions.size(), 0);
  for (std::size_t n = 0; n < targets.size(); ++n) {
    const Target& t = targets[n];
    const std::string where = source + ": target " + std::to_string(n + 1) + " (point " + std::to_string(t.index) + ")";
    if (t.index < 0 || static_cast<std::size_t>(t.index) >= system.positions.size())
      throw InputError(ErrorCode::index_out_of_range,
                       where + ": the model has " + std::to_string(system.positions.size()) + " points");
    if (!system.fixed[t.index])
      throw InputError(ErrorCode::malformed, where + ": only surface points ('m') can be moved to targets");
    if (seen[t.index]) throw InputError(ErrorCode::malformed, where + ": the point is named twice");
    seen[t.index] = 1;
    system.positions[t.index] = t.position;
  }
}

std::optional<LatticeShape> detect_lattice(const ThesisModel& model, const SpringSystem& springs,
                                           std::optional<SpringModel> wanted) {
  const long n = static_cast<long>(model.points.size());
  const long f = static_cast<long>(model.fibres.size());
  if (f < 1 || n % f != 0 || n / f < 2) return std::nullopt;
  const long nz = n / f;
  for (long i = 0; i < f; ++i)
    if (model.fibres[i][0] != i || model.fibres[i][1] != i + f * (nz - 1)) return std::nullopt;
  std::vector<SpringModel> models;
  if (wanted)
    models.push_back(*wanted);
  else
    models = {SpringModel::model6, SpringModel::model26};
  SettleOptions probe;
  probe.tolerance = 0.0;
  for (SpringModel m : models) {
    // The spring count pins the model; try every split nx x ny = F.
    for (long nx = 1; nx <= f; ++nx) {
      if (f % nx != 0) continue;
      LatticeShape shape{static_cast<int>(nx), static_cast<int>(f / nx), static_cast<int>(nz), m};
      long expected = 0;
      for (const auto& o : half_offsets(m))
        expected += std::max(0L, shape.nx - std::labs(o[0])) * std::max(0L, shape.ny - std::labs(o[1])) *
                    std::max(0L, shape.nz - std::labs(o[2]));
      if (expected != static_cast<long>(springs.springs.size())) continue;
      if (detail::make_structured_verlet(springs, probe, shape)) return shape;
    }
  }
  return std::nullopt;
}

Polylines model_fibres(const ThesisModel& model, const std::vector<Vec3>& positions,
                       const std::optional<LatticeShape>& shape) {
  Polylines out;
  const long stride = static_cast<long>(model.fibres.size());
  for (const auto& fibre : model.fibres) {
    std::vector<Vec3> line;
    if (shape) {
      for (long p = fibre[0]; p <= fibre[1]; p += stride) line.push_back(positions[p]);
    } else {
      line = {positions[fibre[0]], positions[fibre[1]]};
    }
    out.lines.push_back(std::move(line));
  }
  return out;
}

}  // namespace fascicle::springs
