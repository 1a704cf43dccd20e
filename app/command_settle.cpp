// fascicle settle IN.txt -o OUT.txt|OUT.vtk: settles a mass-spring system in the thesis format
// (Zeleny 2011, appendix 2). Surface points ('m') are fixed; --targets first moves them to new
// positions, as the decomposition pins the template surface to the muscle; spring rest lengths
// are the distances in the input file; the interior then settles with the chosen solver.

#include "app/commands.h"
#include "app/report_file.h"
#include "geometry/atomic_file.h"
#include "geometry/errors.h"
#include "geometry/mesh_io.h"
#include "geometry/thesis_format.h"
#include "springs/compute_backend.h"
#include "springs/settle.h"
#include "springs/thesis_settle.h"

#include <nlohmann/json.hpp>
#include <spdlog/spdlog.h>

#include <cmath>
#include <memory>

namespace fascicle::app {

namespace {

struct SettleArgs {
  std::string input, output, report, targets;
  std::string solver = "verlet";
  std::string static_method = "momentum";
  std::string backend = "auto";  // compute backend: cpu, gl, gl-gs, auto
  std::string path = "auto";     // CPU/gl data path: auto, structured, general
  bool portable_loop = springs::SettleOptions{}.portable_loop;
  int gl_device = -1;
  int check_interval = 32;
  bool gpu_polish = true;
  std::string damping = "estimate";
  int model = 0;
  double tolerance = 1e-6;
  int max_iterations = 100000;
  double mass = 0.0;
  double density = 1.1;
  double dt = 0.0;
  int coarse_start_points = springs::SettleOptions{}.coarse_start_points;
  double coarse_start_perturbation = springs::SettleOptions{}.coarse_start_perturbation;
};

springs::SettleOptions settle_options(const SettleArgs& args) {
  springs::SettleOptions options;
  options.solver = springs::parse_solver_kind(args.solver);
  options.static_method = springs::parse_static_method(args.static_method);
  try {
    options.backend = springs::parse_backend(args.path);
  } catch (const OptionError&) {
    throw OptionError("path: unknown data path '" + args.path + "' (valid: auto, structured, general)");
  }
  options.tolerance = args.tolerance;
  options.max_iterations = args.max_iterations;
  options.mass = args.mass;
  options.dt = args.dt;
  options.coarse_start_points = args.coarse_start_points;
  options.coarse_start_perturbation = args.coarse_start_perturbation;
  options.portable_loop = args.portable_loop;
  if (args.damping == "estimate") {
    options.damping_mode = springs::DampingMode::estimate;
  } else if (args.damping == "critical") {
    options.damping_mode = springs::DampingMode::critical;
  } else {
    options.damping_mode = springs::DampingMode::value;
    char* end = nullptr;
    options.damping = std::strtod(args.damping.c_str(), &end);
    if (end == args.damping.c_str() || *end != '\0')
      throw OptionError("damping: '" + args.damping + "' is not a number, 'critical' or 'estimate'");
  }
  options.validate();
  return options;
}

// Default point mass: density x bounding-box volume / points (the thesis's 1.1 / 125 for a
// 5 x 5 x 5 lattice of the unit template).
double default_mass(const ThesisModel& model, double density) {
  if (!(density > 0.0) || !std::isfinite(density))
    throw OptionError("density: must be > 0, got " + std::to_string(density));
  Vec3 lo = Vec3::Constant(std::numeric_limits<double>::infinity()), hi = -lo;
  for (const Vec3& p : model.points) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  const double volume = (hi - lo).prod();
  const double mass = density * volume / static_cast<double>(model.points.size());
  if (!(mass > 0.0) || !std::isfinite(mass))
    throw OptionError("mass: the model is flat (zero bounding-box volume); give --mass");
  return mass;
}

void run_settle(const SettleArgs& args) {
  check_not_same_file(args.input, args.output);
  const std::string extension = lower_extension(args.output);
  if (extension != "txt" && extension != "vtk")
    throw InputError(ErrorCode::unknown_format,
                     args.output + ": output must be .txt (thesis format) or .vtk (fibre polylines)");
  const springs::SettleOptions options = settle_options(args);
  std::optional<springs::SpringModel> wanted;
  if (args.model != 0) wanted = springs::parse_spring_model(args.model);

  const ThesisModel model = read_thesis_model(args.input);
  if (model.points.empty()) throw InputError(ErrorCode::file_empty, args.input + ": the model has no point");
  if (model.springs.empty()) throw InputError(ErrorCode::malformed, args.input + ": the model has no spring");
  const double mass = args.mass > 0.0 ? args.mass : default_mass(model, args.density);
  springs::SpringSystem system = springs::spring_system_from_thesis(model, mass);
  const std::optional<springs::LatticeShape> shape = springs::detect_lattice(model, system, wanted);
  if (wanted && !shape && options.backend == springs::Backend::structured)
    throw OptionError("model: " + args.input + " is not a model-" + std::to_string(args.model) +
                      " lattice as written by fascicle; use --path general");
  if (!args.targets.empty()) springs::apply_targets(system, springs::read_targets(args.targets), args.targets);
  const springs::LatticeShape* shape_ptr = shape ? &*shape : nullptr;

  // Compute backend: the CPU solvers or the GPU through OpenGL (springs/compute_backend.h).
  springs::ComputeRequest request;
  request.name = args.backend;
  request.solver = options.solver;
  request.points = system.positions.size();
  request.device = args.gl_device;
  request.check_interval = args.check_interval;
  request.polish = args.gpu_polish;
  const std::unique_ptr<springs::ComputeBackend> backend = springs::make_compute_backend(request);
  const std::string compute = backend->name(), reason = backend->reason();
  if (backend->fell_back()) spdlog::warn("backend auto: no OpenGL context; using the CPU");
  spdlog::info("backend {}: {}", compute, reason);
  nlohmann::json gpu_info = nullptr;
  springs::SettleReport report;
  if (compute == "cpu") {
    report = backend->settle(system, options, shape_ptr);
  } else {
    const springs::ComputeDevice device = backend->device();
    spdlog::info("OpenGL: {} | {} | {}{}", device.renderer, device.gl_version, device.platform,
                 device.hardware ? "" : " (software renderer, no GPU)");
    springs::GpuSettleFigures gpu;
    report = backend->settle(system, options, shape_ptr, &gpu);
    if (gpu.polished)
      spdlog::info(
          "the residual stopped falling at {:.3g} on the GPU (float32 precision); the CPU polished in "
          "double: {} iterations to {:.3g}, {:.3f} s",
          gpu.gpu_residual, gpu.polish_iterations, report.residual, gpu.polish_seconds);
    else if (gpu.stalled)
      spdlog::warn(
          "the residual stopped falling at {:.3g} on the GPU (float32 precision); use --gpu-polish "
          "true (with iterations left of --max-iterations) or --backend cpu for a tolerance below it",
          report.residual);
    gpu_info = {{"renderer", device.renderer},
                {"gl_version", device.gl_version},
                {"hardware", device.hardware},
                {"platform", device.platform},
                {"readback_seconds", gpu.readback_seconds},
                {"gpu_bytes", gpu.gpu_bytes},
                {"check_interval", args.check_interval},
                {"stalled", gpu.stalled},
                {"gpu_residual", gpu.gpu_residual},
                {"polish", args.gpu_polish},
                {"polished", gpu.polished},
                {"polish_iterations", gpu.polish_iterations},
                {"polish_seconds", gpu.polish_seconds}};
  }
  spdlog::info("settled {} points ({} fixed, {} springs) with {} [{}]: {} iterations, residual {:.3g}{}, {:.3f} s",
               system.positions.size(), std::count(system.fixed.begin(), system.fixed.end(), 1), system.springs.size(),
               report.solver, report.backend, report.iterations, report.residual,
               report.converged ? "" : (options.tolerance > 0.0 ? " (NOT converged)" : ""), report.seconds);

  if (extension == "txt")
    write_thesis_model(args.output, springs::with_positions(model, system.positions));
  else
    write_polylines(args.output, springs::model_fibres(model, system.positions, shape));

  if (!args.report.empty()) {
    nlohmann::json j;
    j["input"] = args.input;
    j["output"] = args.output;
    j["targets"] = args.targets;
    j["points"] = system.positions.size();
    j["fixed_points"] = std::count(system.fixed.begin(), system.fixed.end(), 1);
    j["springs"] = system.springs.size();
    j["lattice"] = shape ? nlohmann::json{{"nx", shape->nx},
                                          {"ny", shape->ny},
                                          {"nz", shape->nz},
                                          {"model", static_cast<int>(shape->model)}}
                         : nlohmann::json(nullptr);
    j["solver"] = report.solver;
    j["backend"] = report.backend;
    j["compute_backend"] = compute;
    j["backend_reason"] = reason;
    j["path"] = args.path;
    j["gpu"] = gpu_info;
    j["tolerance"] = options.tolerance;
    j["max_iterations"] = options.max_iterations;
    j["iterations"] = report.iterations;
    j["inner_iterations"] = report.inner_iterations;
    j["converged"] = report.converged;
    j["residual"] = report.residual;
    j["residual_history"] = report.residual_history;
    j["seconds"] = report.seconds;
    j["setup_seconds"] = report.setup_seconds;
    j["start_levels"] = report.start_levels;
    j["start_iterations"] = report.start_iterations;
    j["mass"] = mass;
    if (options.solver == springs::SolverKind::verlet) {
      j["dt"] = report.dt;
      j["mean_damping"] = report.mean_damping;
      j["damping"] = args.damping;
    }
    write_json_report(args.report, j);
  }
}

}  // namespace

void add_settle_command(CLI::App& app) {
  auto args = std::make_shared<SettleArgs>();
  CLI::App* cmd =
      app.add_subcommand("settle", "Settle a mass-spring system in the thesis format (fixed surface, free interior)");
  cmd->add_option("input", args->input, "Input model, thesis text format (.txt)")->required();
  cmd->add_option("-o,--output", args->output, "Output: .txt (thesis format) or .vtk (fibre polylines)")->required();
  cmd->add_option("--report", args->report, "Write a JSON report here");
  cmd->add_option("--targets", args->targets, "Move fixed points first: lines 'index x y z'");
  cmd->add_option("--solver", args->solver, "verlet (thesis, formula 3.8) or static (equilibrium directly)")
      ->capture_default_str();
  cmd->add_option("--static-method", args->static_method,
                  "static solver: momentum, newton, local-global or multigrid (lattices only; other "
                  "systems run momentum)")
      ->capture_default_str();
  cmd->add_option("--coarse-start", args->coarse_start_points,
                  "static momentum on a lattice: start from the settled lattice of every other point, "
                  "recursively while a lattice has more than this many points (0: off)")
      ->capture_default_str();
  cmd->add_option("--coarse-start-perturbation", args->coarse_start_perturbation,
                  "coarse start, model-6 lattices only: offset each free point of an interpolated start by up to "
                  "half this share of the mean rest length (a fixed pseudo-random pattern; starts the buckling "
                  "of compressed lattices; 0: none)")
      ->capture_default_str();
  cmd->add_option("--backend", args->backend,
                  "Compute backend: cpu, gl (OpenGL compute shaders), gl-gs (the thesis's geometry-shader method) "
                  "or auto (a hardware GPU for large Verlet lattices, else cpu)")
      ->capture_default_str();
  cmd->add_option("--path", args->path, "Verlet data path: auto, structured (lattice), general (spring list)")
      ->capture_default_str();
  cmd->add_option("--portable-loop", args->portable_loop,
                  "Structured path: the portable spring loop, the same result on every processor (true), or the "
                  "fastest loop the processor has: AVX-512, AVX2 (false)")
      ->capture_default_str();
  cmd->add_option("--gl-device", args->gl_device,
                  "EGL device index for gl/gl-gs (-1: first hardware device, "
                  "else the software renderer)")
      ->capture_default_str();
  cmd->add_option("--gpu-check-interval", args->check_interval,
                  "gl/gl-gs: iterations between residual checks on the GPU")
      ->capture_default_str();
  cmd->add_option("--gpu-polish", args->gpu_polish,
                  "gl/gl-gs: when float32 stops short of the tolerance, finish on the CPU in double from the "
                  "GPU's positions (static momentum)")
      ->capture_default_str();
  cmd->add_option("--model", args->model, "Expect a model-6 or model-26 lattice (default: detect)");
  cmd->add_option("--tolerance", args->tolerance,
                  "Stop at this relative residual (max free-point force / mean spring force); 0 runs "
                  "exactly --max-iterations")
      ->capture_default_str();
  cmd->add_option("--max-iterations", args->max_iterations, "Iteration cap")->capture_default_str();
  cmd->add_option("--mass", args->mass, "Point mass (default: --density x bounding-box volume / points)");
  cmd->add_option("--density", args->density, "Mass per unit volume when --mass is not given")->capture_default_str();
  cmd->add_option("--damping", args->damping,
                  "Verlet damping c: a number, 'critical' (sqrt(4 k m) per point) or "
                  "'estimate' (thesis formula 7.2)")
      ->capture_default_str();
  cmd->add_option("--dt", args->dt, "Verlet time step (0: the largest stable step x 0.9)")->capture_default_str();
  cmd->callback([args] { run_settle(*args); });
}

}  // namespace fascicle::app
