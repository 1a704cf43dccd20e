#pragma once
/// \file gl_context.h
/// A headless OpenGL context through EGL, for servers without a display: the first hardware
/// device found by EGL_EXT_device_enumeration / EGL_EXT_platform_device (or the device named by
/// GlContextOptions::device), else Mesa's surfaceless platform (EGL_MESA_platform_surfaceless:
/// llvmpipe, software). An OpenGL 4.3+ core context without any surface
/// (EGL_KHR_surfaceless_context); GLEW loads the functions. Plus the small GL helpers the
/// solvers share: program compilation with the driver's log in the error.

#include "geometry/errors.h"

#include <cstddef>
#include <memory>
#include <string>
#include <vector>

namespace fascicle::shaders {

/// An OpenGL or EGL failure: no usable device or context, a shader that does not compile or
/// link (the message carries the driver's log), a buffer above the device's limits, GL errors.
class GpuError : public Error {
 public:
  explicit GpuError(const std::string& message) : Error(ErrorCode::gpu, message) {}
};

/// One EGL device as enumerated by EGL_EXT_device_enumeration.
struct GlDeviceInfo {
  int index = 0;           ///< position in eglQueryDevicesEXT's list (what --gl-device names)
  bool software = false;   ///< EGL_MESA_device_software (llvmpipe): not a hardware GPU
  std::string extensions;  ///< the device's EGL extension string
  std::string drm_file;    ///< EGL_DRM_DEVICE_FILE_EXT when the device has one, else ""
};

/// Lists the EGL devices (empty when EGL_EXT_device_enumeration is missing). Never throws.
std::vector<GlDeviceInfo> list_gl_devices();

/// True when some EGL device is not a software renderer. Never throws.
bool hardware_gl_device_available();

/// Options of GlContext.
struct GlContextOptions {
  int device = -1;             ///< EGL device index (list_gl_devices); -1 = first hardware device, else the
                               ///< surfaceless software platform (default -1)
  bool allow_software = true;  ///< accept a software renderer when no hardware device works
                               ///< (default true: every test machine has only llvmpipe)
  int major = 4, minor = 3;    ///< least OpenGL core version, >= 4.3 (compute shaders; default 4.3)
  /// Throws OptionError naming the bad field.
  void validate() const;
};

/// A current, headless OpenGL core context on the calling thread. Build once, use from the
/// thread that built it; destroyed (and released) with the object. Non-copyable.
class GlContext {
 public:
  /// Creates the context (see the file comment). Throws GpuError when no EGL display, no
  /// OpenGL 4.3 core context or a missing GL function; OptionError for bad options or a
  /// --gl-device index that does not exist.
  explicit GlContext(const GlContextOptions& options = {});
  ~GlContext();
  GlContext(const GlContext&) = delete;
  GlContext& operator=(const GlContext&) = delete;

  /// GL_RENDERER, e.g. "llvmpipe (LLVM 15.0.6, 256 bits)".
  const std::string& renderer() const { return renderer_; }
  /// GL_VERSION, e.g. "4.5 (Core Profile) Mesa 22.3.6".
  const std::string& version() const { return version_; }
  /// GL_VENDOR.
  const std::string& vendor() const { return vendor_; }
  /// How the display was opened: "device N" or "surfaceless".
  const std::string& platform() const { return platform_; }
  /// False for a software renderer (llvmpipe, softpipe, swrast).
  bool hardware() const { return hardware_; }
  /// Makes this context current on the calling thread again. Throws GpuError.
  void make_current() const;

 private:
  struct State;
  std::unique_ptr<State> state_;
  std::string renderer_, version_, vendor_, platform_;
  bool hardware_ = false;
};

/// The shared objects that creating a GlContext loaded (the EGL vendor library's driver, e.g.
/// Mesa's dri/swrast_dri.so) and that are kept loaded until the process exits: without that the
/// last context's eglTerminate unloads the driver, the next context loads it again, and
/// LeakSanitizer reports the driver's still-referenced allocations as leaks from an unknown
/// module (docs/RELIABILITY.md). Full paths, in the order they were pinned.
std::vector<std::string> pinned_gl_libraries();

/// True when a shared object with this path is loaded in the process now.
bool library_loaded(const std::string& path);

/// Compiles and links a program from embedded GLSL files (shader_sources.h); the stage is taken
/// from each name's extension (.comp, .vert, .geom, .frag). `defines` is inserted after the
/// #version line. Returns the program name. Throws GpuError naming the file with the driver's
/// log on a compile or link failure, or for an unknown file.
unsigned compile_program(const std::vector<std::string>& files, const std::string& defines = "");

/// Compiles and links a program from source texts (name, source) - the same as compile_program
/// for sources that are not embedded (tests). Throws GpuError with the driver's log.
unsigned compile_program_sources(const std::vector<std::pair<std::string, std::string>>& sources,
                                 const std::string& defines = "");

/// Gives the buffer object `buffer` a shader-storage data store of `bytes` bytes (at least 16),
/// filled from `data` when not null: immutable storage (glBufferStorage with
/// GL_DYNAMIC_STORAGE_BIT, OpenGL 4.4 or ARB_buffer_storage), which lets the driver keep it in
/// the device's own memory, else glBufferData with GL_DYNAMIC_DRAW. Call once per buffer
/// object (an immutable store cannot be specified again). Leaves the buffer bound to
/// GL_SHADER_STORAGE_BUFFER. Throws GpuError naming `what` on a GL error (out of memory).
void allocate_storage_buffer(unsigned buffer, std::size_t bytes, const void* data, const char* what);
/// Throws GpuError naming `where` when glGetError reports an error (out of memory included).
void check_gl(const char* where);

}  // namespace fascicle::shaders
