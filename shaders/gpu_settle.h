#pragma once
/// \file gpu_settle.h
/// The spring settle on the GPU through OpenGL (Zeleny 2011, ch. 3.2 and 6.2.2; after Georgii and
/// Westermann 2005, "Mass-spring systems on the GPU"). The same damped Verlet iteration as the
/// CPU solver (springs/settle.h, formula 3.8, same masses, damping and time step from
/// SettleOptions), in float32:
///
/// - `gl`: OpenGL 4.3 compute shaders over shader storage buffers, gather formulation (each
///   point sums its own springs: no atomics, deterministic). A structured-lattice kernel with
///   implicit neighbour offsets (model-6 and model-26, shaders/verlet_lattice.comp) and a
///   compressed-row kernel for any spring list (shaders/verlet_csr.comp); the choice follows
///   SettleOptions::backend (the CPU data path option) as on the CPU. Positions stay on the GPU;
///   the residual is a reduction on the GPU every GpuSettleOptions::check_interval iterations
///   (a few bytes come back); one readback at the end. `gl` also runs the static solver's
///   `momentum` method (springs/settle.h: accelerated gradient on the same kernels, unit masses,
///   the CPU's step 1 / L, Nesterov's momentum with gradient restarts); its restart test needs
///   the sum of F . v over the lattice after every step, a reduction on the GPU whose few bytes
///   come back each step.
/// - `gl-gs`: the thesis's own method: one GL_POINTS vertex per spring, the vertex shader
///   computes the force once, a geometry shader emits it at both end points' texels with
///   opposite signs, additive blending (GL_ONE, GL_ONE) accumulates it in an RGBA32F force
///   texture; a full-screen pass integrates into three rotating position textures. Readback
///   with glReadPixels, directly or through a pixel buffer object.
///
/// Positions live on the GPU relative to the centre of their bounding box, so that float32
/// rounding scales with the lattice's extent, not with its distance from the origin.
///
/// Divergence stops the settle with the CPU solver's SolverError (naming the likely cause and the
/// option to change): every SettleOptions::energy_interval iterations the total energy is
/// reduced on the GPU and read back (a few kilobytes); NaN/Inf, or more than
/// energy_growth_bound times the initial energy, is divergence, as is a NaN/Inf force at a
/// residual check.

#include "shaders/gl_context.h"
#include "springs/settle.h"

#include <memory>
#include <string>
#include <vector>

namespace fascicle::shaders {

/// Which GPU method.
enum class GpuBackend {
  gl,     ///< compute shaders, gather (default)
  gl_gs,  ///< the thesis's geometry-shader scatter with additive blending
};

/// "gl" | "gl-gs". Throws OptionError naming the value.
GpuBackend parse_gpu_backend(const std::string& name);
/// "gl" | "gl-gs".
const char* gpu_backend_name(GpuBackend backend);

/// Options of the GPU settle (beside springs::SettleOptions).
struct GpuSettleOptions {
  GpuBackend backend = GpuBackend::gl;  ///< method (default gl)
  int check_interval = 32;              ///< iterations between residual checks on the GPU, >= 1 (default 32)
  bool pbo_readback = true;             ///< gl-gs: read the positions back through a pixel buffer object
                                        ///< (default true: the thesis measured it 25 % faster)
  int texture_width = 2048;             ///< gl-gs: texels per row of the point textures, 1..16384 (default 2048)
  int stall_checks = 16;                ///< stall suspected after this many checks with no new minimum below 0.99 of
                                        ///< the best, >= 1 (default 16: float32 bottoms out near 1e-5 relative)
  double stall_motion = 1e-4;           ///< stall confirmed only if no free point moved more than this share of
                                        ///< the rest length, >= 0 (default 1e-4: a swinging slow mode also stalls)
  bool polish = true;  ///< finish a stalled float32 solve on the CPU in double, momentum method (default
                       ///< true: far-stretched springs stop float32 short of the tolerance, changing folds)
  /// Throws OptionError naming the bad field.
  void validate() const;
};

/// A GPU solver object: buffers and programs built once, then run many times. Needs its context
/// current on the calling thread.
class GpuSpringSolver {
 public:
  virtual ~GpuSpringSolver() = default;
  /// Runs `iterations` Verlet steps on the GPU without reading anything back (static momentum:
  /// a few bytes per step, the restart test).
  virtual void run(int iterations) = 0;
  /// Relative residual at the current positions (largest spring-force magnitude at a free point /
  /// springs::residual_force_scale, the CPU's measure): one force evaluation and a reduction on
  /// the GPU. +Inf when a force is NaN or Inf.
  virtual double residual() = 0;
  /// Total energy at the current state, as the CPU Verlet solver measures it (kinetic
  /// 1/2 m |x - x_prev|^2 / dt^2 at free points plus 1/2 D (|l| - |l0|)^2 per spring): one pass
  /// and a reduction on the GPU (float32 per work group, summed in double). NaN when any term is
  /// NaN or Inf.
  virtual double energy() = 0;
  /// Current positions, #N (one readback).
  virtual std::vector<Vec3> positions() = 0;
  /// Waits until the GPU has finished every queued command (for timing).
  virtual void finish() = 0;
  /// "gl-structured", "gl-structured-uniform", "gl-general" or "gl-gs"; the static momentum
  /// solver prefixes "momentum-".
  virtual std::string backend() const = 0;
  /// Verlet time step and mean damping coefficient used.
  virtual double time_step() const = 0;
  virtual double mean_damping() const = 0;
  /// Bytes of GPU memory allocated for buffers and textures.
  virtual std::size_t gpu_bytes() const = 0;
};

/// Builds a GPU Verlet solver for `system` (validated) on `context`'s device. `shape`, when given
/// and the springs are exactly its model-6/26 neighbours with stiffness 1 / rest length, lets `gl`
/// take the structured kernel (SettleOptions::backend = general forces the spring list,
/// structured requires the lattice). SolverKind::static_equilibrium runs StaticMethod::momentum
/// on `gl` (the CPU's coefficients, float32). Throws OptionError (bad options, a static method
/// other than momentum or the static solver on gl-gs, structured without a lattice), GpuError
/// (context, shaders, memory limits).
std::unique_ptr<GpuSpringSolver> make_gpu_solver(const GlContext& context, const springs::SpringSystem& system,
                                                 const springs::SettleOptions& options,
                                                 const GpuSettleOptions& gpu_options,
                                                 const springs::LatticeShape* shape = nullptr);

/// Positions read back from a gl-gs solver either with glReadPixels into client memory
/// (`pbo` false) or through a pixel buffer object (`pbo` true), with the seconds the readback
/// took (table 7.3 of the thesis). For other solvers `pbo` is ignored (buffer readback).
struct Readback {
  std::vector<Vec3> positions;
  double seconds = 0.0;
};
Readback read_positions(GpuSpringSolver& solver, bool pbo);

/// What settle_gpu did: the CPU report's fields plus the GPU's.
struct GpuSettleReport : springs::SettleReport {
  std::string renderer;           ///< GL_RENDERER
  std::string gl_version;         ///< GL_VERSION
  bool hardware = false;          ///< false for a software renderer
  double readback_seconds = 0.0;  ///< final readback
  std::size_t gpu_bytes = 0;      ///< buffers and textures
  bool stalled = false;           ///< stopped because the residual no longer fell (stall_checks)
  // The CPU polish (GpuSettleOptions::polish). After one, residual and converged are the
  // polish's; iterations, seconds, setup_seconds, residual_history, solver and dt stay the GPU's.
  double gpu_residual = 0.0;    ///< relative residual where the GPU stopped (before any polish)
  bool polished = false;        ///< the CPU polish ran (it may take 0 iterations: the double
                                ///< residual at the GPU's positions can already be within tolerance)
  int polish_iterations = 0;    ///< its iterations
  double polish_seconds = 0.0;  ///< its wall time, set-up included
};

/// Settles `system` on the GPU: runs blocks of check_interval iterations, measures the residual
/// on the GPU after each (and the energy every energy_interval iterations, see above), stops at the tolerance or max_iterations (tolerance 0 runs exactly
/// max_iterations and checks once at the end) or when the residual stops falling in float32
/// (GpuSettleOptions::stall_checks; report.stalled), reads the positions back once and writes the
/// free points into system.positions (fixed points keep their exact input bits); after a stall the
/// CPU polishes them in double (GpuSettleOptions::polish), and residual and converged are then the
/// polish's. The residual history holds one value per GPU check. Throws as make_gpu_solver, SolverError on divergence.
GpuSettleReport settle_gpu(const GlContext& context, springs::SpringSystem& system,
                           const springs::SettleOptions& options, const GpuSettleOptions& gpu_options,
                           const springs::LatticeShape* shape = nullptr);

/// The compute backend a settle runs on, and why.
struct BackendChoice {
  std::string backend;  ///< "cpu" | "gl" | "gl-gs"
  std::string reason;   ///< one line for the log and the report
};

/// Points from which `auto` moves a Verlet settle to a hardware GPU: 8000 (20^3). Below it the
/// context and the per-check synchronisation cost more than the iterations save (measured with
/// `fascicle settle` on n^3 lattices, docs/BENCHMARKS.md); a slower host CPU moves it down, not up.
constexpr std::size_t kAutoGpuMinPoints = 8000;

/// Resolves `requested` ("cpu" | "gl" | "gl-gs" | "auto") for a settle of `points` points with
/// `solver`: auto takes `gl` only for the Verlet solver, at least `min_gpu_points` points and a
/// hardware device (`hardware_device`, e.g. hardware_gl_device_available(); only consulted
/// after the first two tests pass), else `cpu`; the reason names the deciding fact. `gl` may be
/// asked for the static solver (its momentum method, checked by make_gpu_solver). Throws
/// OptionError for an unknown name or gl-gs asked for the static solver.
BackendChoice choose_backend(const std::string& requested, springs::SolverKind solver, std::size_t points,
                             bool hardware_device, std::size_t min_gpu_points = kAutoGpuMinPoints);

}  // namespace fascicle::shaders
