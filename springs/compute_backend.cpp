#include "springs/compute_backend.h"

#include "geometry/errors.h"

#ifdef FASCICLE_HAVE_SHADERS
#include "shaders/gl_context.h"
#include "shaders/gpu_settle.h"
#endif

#include <utility>

// This file is built into its own library, fascicle_compute (CMakeLists.txt at the top), after
// shaders/: it is the one place that knows whether the build has the GPU backends.

namespace fascicle::springs {

namespace {

class CpuBackend final : public ComputeBackend {
 public:
  explicit CpuBackend(std::string reason, bool fell_back = false)
      : reason_(std::move(reason)), fell_back_(fell_back) {}
  std::string name() const override { return "cpu"; }
  std::string reason() const override { return reason_; }
  bool fell_back() const override { return fell_back_; }
  ComputeDevice device() const override { return {}; }
  SettleReport settle(SpringSystem& system, const SettleOptions& options, const LatticeShape* shape,
                      GpuSettleFigures*) override {
    return springs::settle(system, options, shape);
  }

 private:
  std::string reason_;
  bool fell_back_ = false;
};

#ifdef FASCICLE_HAVE_SHADERS
class GlBackend final : public ComputeBackend {
 public:
  GlBackend(const ComputeRequest& request, std::string name, std::string reason)
      : name_(std::move(name)), reason_(std::move(reason)) {
    shaders::GlContextOptions context_options;
    context_options.device = request.device;
    context_ = std::make_unique<shaders::GlContext>(context_options);
    options_.backend = shaders::parse_gpu_backend(name_);
    options_.check_interval = request.check_interval;
    options_.polish = request.polish;
    options_.validate();
  }
  std::string name() const override { return name_; }
  std::string reason() const override { return reason_; }
  ComputeDevice device() const override {
    return {context_->renderer(), context_->version(), context_->platform(), context_->hardware()};
  }
  SettleReport settle(SpringSystem& system, const SettleOptions& options, const LatticeShape* shape,
                      GpuSettleFigures* gpu) override {
    const shaders::GpuSettleReport r = shaders::settle_gpu(*context_, system, options, options_, shape);
    if (gpu)
      *gpu = {r.readback_seconds, r.gpu_bytes,      r.stalled,       r.gpu_residual,
              r.polished,         r.polish_iterations, r.polish_seconds};
    return r;
  }

 private:
  std::string name_, reason_;
  std::unique_ptr<shaders::GlContext> context_;
  shaders::GpuSettleOptions options_;
};
#endif

}  // namespace

#ifdef FASCICLE_HAVE_SHADERS
bool gpu_backends_built() { return true; }

std::unique_ptr<ComputeBackend> make_compute_backend(const ComputeRequest& request) {
  const bool large = request.solver == SolverKind::verlet && request.points >= shaders::kAutoGpuMinPoints;
  const bool hardware = request.name == "auto" && large && shaders::hardware_gl_device_available();
  const shaders::BackendChoice choice = shaders::choose_backend(request.name, request.solver, request.points, hardware);
  if (choice.backend == "cpu") return std::make_unique<CpuBackend>(choice.reason);
  try {
    return std::make_unique<GlBackend>(request, choice.backend, choice.reason);
  } catch (const shaders::GpuError&) {
    // auto promised nothing: without a context the CPU settles, and the reason says why.
    if (request.name != "auto") throw;
    return std::make_unique<CpuBackend>(choice.reason + "; no OpenGL context, fell back to cpu", true);
  }
}
#else
bool gpu_backends_built() { return false; }

std::unique_ptr<ComputeBackend> make_compute_backend(const ComputeRequest& request) {
  if (request.name == "gl" || request.name == "gl-gs")
    throw Error(ErrorCode::gpu, "backend: " + request.name +
                                    " is not in this build (OpenGL, EGL or GLEW was not found when it was built); "
                                    "use --backend cpu");
  if (request.name != "cpu" && request.name != "auto")
    throw OptionError("backend: unknown backend '" + request.name + "' (valid: cpu, gl, gl-gs, auto)");
  return std::make_unique<CpuBackend>(request.name == "cpu" ? "requested (--backend cpu)"
                                                            : "auto: this build has no OpenGL backend");
}
#endif

}  // namespace fascicle::springs
