#pragma once
/// \file compute_backend.h
/// Where a settle runs: the CPU solvers of this module, or a GPU through OpenGL (shaders/, when
/// the build has it). Callers ask make_compute_backend() for one by name and settle through it;
/// only the factory knows whether this build has the GPU backends.
#include "springs/settle.h"

#include <cstddef>
#include <memory>
#include <string>

namespace fascicle::springs {

/// What make_compute_backend() is asked for.
struct ComputeRequest {
  /// "cpu", "gl" (compute shaders), "gl-gs" (the thesis's geometry-shader scatter) or "auto"
  /// (default cpu). auto: a GPU only for a Verlet settle of many points on a hardware device.
  std::string name = "cpu";
  SolverKind solver = SolverKind::static_equilibrium;  ///< the solver to be run (auto and the GPU's checks)
  std::size_t points = 0;                   ///< points of the system to be settled (auto)
  int device = -1;                          ///< EGL device index for the GPU (default -1: the first that works)
  int check_interval = 32;                  ///< GPU: iterations between residual checks, >= 1 (default 32)
  /// GPU: finish a solve that float32 stops short of the tolerance on the CPU in double (default true).
  bool polish = true;
};

/// The device a backend runs on, for reports (empty strings and false for the CPU).
struct ComputeDevice {
  std::string renderer;    ///< GL_RENDERER
  std::string gl_version;  ///< GL_VERSION
  std::string platform;    ///< the EGL platform the context was made on
  bool hardware = false;   ///< false for a software renderer (llvmpipe)
};

/// What a GPU settle adds to its SettleReport (see shaders::GpuSettleReport).
struct GpuSettleFigures {
  double readback_seconds = 0.0;  ///< final readback
  std::size_t gpu_bytes = 0;      ///< buffers and textures
  bool stalled = false;           ///< stopped because the float32 residual no longer fell
  double gpu_residual = 0.0;      ///< relative residual where the GPU stopped (before any polish)
  bool polished = false;          ///< the CPU finished the solve in double
  int polish_iterations = 0;      ///< its iterations
  double polish_seconds = 0.0;    ///< its wall time
};

/// A compute backend, made once and used for any number of settles (a GPU keeps its context).
class ComputeBackend {
 public:
  virtual ~ComputeBackend() = default;
  /// "cpu", "gl" or "gl-gs".
  virtual std::string name() const = 0;
  /// One line: why this backend (the request, or what auto found).
  virtual std::string reason() const = 0;
  /// Whether auto chose a GPU backend and fell back to the CPU because no OpenGL context could be
  /// made (callers warn about it).
  virtual bool fell_back() const { return false; }
  /// The device, for reports.
  virtual ComputeDevice device() const = 0;
  /// Settles `system` in place as springs::settle() does; `gpu`, when given, receives a GPU
  /// settle's own figures (left as it is by the CPU). Throws as settle(), and Error(gpu) for GPU
  /// failures.
  virtual SettleReport settle(SpringSystem& system, const SettleOptions& options, const LatticeShape* shape = nullptr,
                              GpuSettleFigures* gpu = nullptr) = 0;
};

/// Whether this build has the GPU backends (OpenGL, EGL and GLEW were found when it was built).
bool gpu_backends_built();

/// The backend of `request`. auto falls back to the CPU (saying why in reason()) when the build
/// has no GPU backend, the settle is small or no OpenGL context can be made. Throws OptionError
/// for an unknown name, Error(gpu) when "gl" or "gl-gs" is asked for and the build has none or no
/// context can be made.
std::unique_ptr<ComputeBackend> make_compute_backend(const ComputeRequest& request);

}  // namespace fascicle::springs
