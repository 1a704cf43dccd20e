// Headless OpenGL through EGL (see gl_context.h) and the GL helpers shared by the solvers.

#include "shaders/gl_context.h"

#include "shaders/shader_sources.h"

#include <GL/glew.h>
#include <EGL/egl.h>
#include <EGL/eglext.h>

#include <dlfcn.h>
#include <link.h>

#include <algorithm>
#include <cstdio>
#include <cstring>
#include <map>
#include <mutex>
#include <set>

#ifndef EGL_PLATFORM_SURFACELESS_MESA
#define EGL_PLATFORM_SURFACELESS_MESA 0x31DD
#endif

namespace fascicle::shaders {

namespace {

struct EglDeviceApi {
  PFNEGLQUERYDEVICESEXTPROC query_devices = nullptr;
  PFNEGLQUERYDEVICESTRINGEXTPROC query_device_string = nullptr;
  PFNEGLGETPLATFORMDISPLAYEXTPROC get_platform_display = nullptr;
};

bool has_extension(const char* list, const char* name) {
  if (!list) return false;
  const std::size_t n = std::strlen(name);
  for (const char* p = list; (p = std::strstr(p, name)) != nullptr; p += n)
    if ((p == list || p[-1] == ' ') && (p[n] == ' ' || p[n] == '\0')) return true;
  return false;
}

const char* client_extensions() { return eglQueryString(EGL_NO_DISPLAY, EGL_EXTENSIONS); }

EglDeviceApi device_api() {
  EglDeviceApi api;
  const char* ext = client_extensions();
  if (has_extension(ext, "EGL_EXT_device_enumeration") || has_extension(ext, "EGL_EXT_device_base")) {
    api.query_devices = reinterpret_cast<PFNEGLQUERYDEVICESEXTPROC>(eglGetProcAddress("eglQueryDevicesEXT"));
    api.query_device_string =
        reinterpret_cast<PFNEGLQUERYDEVICESTRINGEXTPROC>(eglGetProcAddress("eglQueryDeviceStringEXT"));
  }
  if (has_extension(ext, "EGL_EXT_platform_base"))
    api.get_platform_display =
        reinterpret_cast<PFNEGLGETPLATFORMDISPLAYEXTPROC>(eglGetProcAddress("eglGetPlatformDisplayEXT"));
  return api;
}

std::vector<EGLDeviceEXT> query_devices(const EglDeviceApi& api) {
  if (!api.query_devices) return {};
  EGLint count = 0;
  if (!api.query_devices(0, nullptr, &count) || count <= 0) return {};
  std::vector<EGLDeviceEXT> devices(count);
  if (!api.query_devices(count, devices.data(), &count)) return {};
  devices.resize(count);
  return devices;
}

// Displays are shared per platform: terminate one only when its last context goes.
std::mutex display_mutex;
std::map<EGLDisplay, int> display_users;

std::string egl_error_name(EGLint e) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "0x%04X", static_cast<unsigned>(e));
  return buf;
}

std::string one_line(std::string text) {
  while (!text.empty() && (text.back() == '\n' || text.back() == ' ' || text.back() == '\0')) text.pop_back();
  for (char& c : text)
    if (c == '\n' || c == '\r') c = '|';
  return text;
}

// Names of the shared objects loaded in this process now (dl_iterate_phdr; the main program has
// an empty name and is left out).
std::set<std::string> loaded_objects() {
  std::set<std::string> names;
  dl_iterate_phdr(
      [](dl_phdr_info* info, std::size_t, void* data) {
        if (info->dlpi_name && info->dlpi_name[0] != '\0')
          static_cast<std::set<std::string>*>(data)->insert(info->dlpi_name);
        return 0;
      },
      &names);
  return names;
}

std::mutex pinned_mutex;
std::vector<std::string> pinned;  // what pin_new_objects has pinned, in order

// Marks every object loaded since `before` as never unloaded (dlopen with RTLD_NOLOAD |
// RTLD_NODELETE promotes the flag on a resident object; the extra reference is dropped again).
// The EGL vendor library loads its driver (Mesa: dri/swrast_dri.so, which holds LLVM) at
// eglInitialize and unloads it at the last eglTerminate; pinned, the next context does not
// load and relocate the driver again, and LeakSanitizer still sees the driver's static data as
// roots at exit instead of reporting what only the driver refers to as leaked.
void pin_new_objects(const std::set<std::string>& before) {
  std::lock_guard<std::mutex> lock(pinned_mutex);
  for (const std::string& name : loaded_objects()) {
    if (before.count(name) || std::find(pinned.begin(), pinned.end(), name) != pinned.end()) continue;
    if (void* handle = dlopen(name.c_str(), RTLD_LAZY | RTLD_NOLOAD | RTLD_NODELETE)) {
      dlclose(handle);
      pinned.push_back(name);
    }
  }
}

bool software_renderer_name(const std::string& renderer) {
  for (const char* s : {"llvmpipe", "softpipe", "swrast", "SWR", "Software Rasterizer", "lavapipe"})
    if (renderer.find(s) != std::string::npos) return true;
  return false;
}

}  // namespace

// Owns the EGL context; released also when GlContext's constructor throws after creating it.
struct GlContext::State {
  EGLDisplay display = EGL_NO_DISPLAY;
  EGLContext context = EGL_NO_CONTEXT;
  State() = default;
  State(const State&) = delete;
  State& operator=(const State&) = delete;
  ~State() {
    if (context == EGL_NO_CONTEXT) return;
    eglMakeCurrent(display, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
    eglDestroyContext(display, context);
    std::lock_guard<std::mutex> lock(display_mutex);
    if (--display_users[display] == 0) {
      display_users.erase(display);
      eglTerminate(display);
    }
  }
};

std::vector<GlDeviceInfo> list_gl_devices() {
  std::vector<GlDeviceInfo> out;
  const EglDeviceApi api = device_api();
  const std::vector<EGLDeviceEXT> devices = query_devices(api);
  for (std::size_t i = 0; i < devices.size(); ++i) {
    GlDeviceInfo info;
    info.index = static_cast<int>(i);
    const char* ext = api.query_device_string ? api.query_device_string(devices[i], EGL_EXTENSIONS) : nullptr;
    info.extensions = ext ? ext : "";
    info.software = has_extension(ext, "EGL_MESA_device_software");
    if (has_extension(ext, "EGL_EXT_device_drm")) {
      const char* file = api.query_device_string(devices[i], EGL_DRM_DEVICE_FILE_EXT);
      info.drm_file = file ? file : "";
    }
    out.push_back(info);
  }
  return out;
}

bool hardware_gl_device_available() {
  for (const GlDeviceInfo& d : list_gl_devices())
    if (!d.software) return true;
  return false;
}

void GlContextOptions::validate() const {
  if (device < -1) throw OptionError("gl_device: must be >= 0 (or -1 for automatic), got " + std::to_string(device));
  if (major < 4 || (major == 4 && minor < 3) || minor < 0)
    throw OptionError("gl_version: must be at least 4.3 (compute shaders), got " + std::to_string(major) + "." +
                      std::to_string(minor));
}

namespace {

// Tries to open `display` and create a current core context on it. Returns "" on success, else
// why not (the display is released again).
std::string try_context(EGLDisplay display, const GlContextOptions& options, EGLContext& context) {
  if (display == EGL_NO_DISPLAY) return "no EGL display";
  EGLint major = 0, minor = 0;
  if (!eglInitialize(display, &major, &minor)) return "eglInitialize failed (" + egl_error_name(eglGetError()) + ")";
  {
    std::lock_guard<std::mutex> lock(display_mutex);
    ++display_users[display];
  }
  auto release = [&](const std::string& why) {
    std::lock_guard<std::mutex> lock(display_mutex);
    if (--display_users[display] == 0) {
      display_users.erase(display);
      eglTerminate(display);
    }
    return why;
  };
  const char* ext = eglQueryString(display, EGL_EXTENSIONS);
  if (!has_extension(ext, "EGL_KHR_surfaceless_context"))
    return release("the display lacks EGL_KHR_surfaceless_context");
  if (!eglBindAPI(EGL_OPENGL_API)) return release("eglBindAPI(EGL_OPENGL_API) failed");
  EGLConfig config = nullptr;  // EGL_NO_CONFIG_KHR
  if (!has_extension(ext, "EGL_KHR_no_config_context") && !has_extension(ext, "EGL_MESA_configless_context")) {
    const EGLint attributes[] = {EGL_SURFACE_TYPE, 0, EGL_RENDERABLE_TYPE, EGL_OPENGL_BIT, EGL_NONE};
    EGLint found = 0;
    if (!eglChooseConfig(display, attributes, &config, 1, &found) || found < 1)
      return release("no EGL config renders OpenGL");
  }
  const EGLint context_attributes[] = {EGL_CONTEXT_MAJOR_VERSION,
                                       options.major,
                                       EGL_CONTEXT_MINOR_VERSION,
                                       options.minor,
                                       EGL_CONTEXT_OPENGL_PROFILE_MASK,
                                       EGL_CONTEXT_OPENGL_CORE_PROFILE_BIT,
                                       EGL_NONE};
  context = eglCreateContext(display, config, EGL_NO_CONTEXT, context_attributes);
  if (context == EGL_NO_CONTEXT)
    return release("no OpenGL " + std::to_string(options.major) + "." + std::to_string(options.minor) +
                   " core context (" + egl_error_name(eglGetError()) + ")");
  if (!eglMakeCurrent(display, EGL_NO_SURFACE, EGL_NO_SURFACE, context)) {
    eglDestroyContext(display, context);
    context = EGL_NO_CONTEXT;
    return release("eglMakeCurrent without a surface failed (" + egl_error_name(eglGetError()) + ")");
  }
  return "";
}

}  // namespace

GlContext::GlContext(const GlContextOptions& options) : state_(std::make_unique<State>()) {
  options.validate();
  const std::set<std::string> before = loaded_objects();
  const EglDeviceApi api = device_api();
  const std::vector<EGLDeviceEXT> devices = query_devices(api);
  const std::vector<GlDeviceInfo> infos = list_gl_devices();
  std::string log;
  auto attempt = [&](EGLDisplay display, const std::string& name) {
    EGLContext context = EGL_NO_CONTEXT;
    const std::string why = try_context(display, options, context);
    if (why.empty()) {
      state_->display = display;
      state_->context = context;
      platform_ = name;
      return true;
    }
    log += (log.empty() ? "" : "; ") + name + ": " + why;
    return false;
  };
  bool ok = false;
  if (options.device >= 0) {
    if (options.device >= static_cast<int>(devices.size()))
      throw OptionError("gl_device: device " + std::to_string(options.device) + " does not exist (" +
                        std::to_string(devices.size()) + " EGL devices)");
    if (!api.get_platform_display) throw GpuError("EGL: EGL_EXT_platform_base is missing; cannot open a device");
    ok = attempt(api.get_platform_display(EGL_PLATFORM_DEVICE_EXT, devices[options.device], nullptr),
                 "device " + std::to_string(options.device));
  } else {
    if (api.get_platform_display && has_extension(client_extensions(), "EGL_EXT_platform_device"))
      for (std::size_t i = 0; i < devices.size() && !ok; ++i)
        if (!infos[i].software)
          ok = attempt(api.get_platform_display(EGL_PLATFORM_DEVICE_EXT, devices[i], nullptr),
                       "device " + std::to_string(i));
    if (!ok && options.allow_software) {
      if (api.get_platform_display && has_extension(client_extensions(), "EGL_MESA_platform_surfaceless"))
        ok = attempt(api.get_platform_display(EGL_PLATFORM_SURFACELESS_MESA, EGL_DEFAULT_DISPLAY, nullptr),
                     "surfaceless");
      for (std::size_t i = 0; i < devices.size() && !ok; ++i)
        if (infos[i].software)
          ok = attempt(api.get_platform_display(EGL_PLATFORM_DEVICE_EXT, devices[i], nullptr),
                       "device " + std::to_string(i));
    }
  }
  if (!ok)
    throw GpuError("EGL: no headless OpenGL " + std::to_string(options.major) + "." + std::to_string(options.minor) +
                   " core context" +
                   (log.empty() ? std::string(" (no EGL device or surfaceless platform)") : " (" + log + ")"));
  pin_new_objects(before);

  glewExperimental = GL_TRUE;
  const GLenum glew = glewInit();
  // GLEW 2.2 built for GLX reports GLEW_ERROR_NO_GLX_DISPLAY under EGL after loading every core
  // function: accept it and check the functions the solvers call instead.
  if (glew != GLEW_OK && glew != GLEW_ERROR_NO_GLX_DISPLAY) {
    const std::string why = reinterpret_cast<const char*>(glewGetErrorString(glew));
    throw GpuError("GLEW: " + why);
  }
  const std::pair<const char*, const void*> needed[] = {
      {"glDispatchCompute", reinterpret_cast<const void*>(glDispatchCompute)},
      {"glMemoryBarrier", reinterpret_cast<const void*>(glMemoryBarrier)},
      {"glBindBufferBase", reinterpret_cast<const void*>(glBindBufferBase)},
      {"glBufferData", reinterpret_cast<const void*>(glBufferData)},
      {"glGetBufferSubData", reinterpret_cast<const void*>(glGetBufferSubData)},
      {"glMapBufferRange", reinterpret_cast<const void*>(glMapBufferRange)},
      {"glCreateShader", reinterpret_cast<const void*>(glCreateShader)},
      {"glGetProgramInfoLog", reinterpret_cast<const void*>(glGetProgramInfoLog)},
      {"glGenFramebuffers", reinterpret_cast<const void*>(glGenFramebuffers)},
      {"glVertexAttribIPointer", reinterpret_cast<const void*>(glVertexAttribIPointer)},
      {"glGenVertexArrays", reinterpret_cast<const void*>(glGenVertexArrays)},
      {"glFenceSync", reinterpret_cast<const void*>(glFenceSync)},
      {"glClientWaitSync", reinterpret_cast<const void*>(glClientWaitSync)},
      {"glClearBufferfv", reinterpret_cast<const void*>(glClearBufferfv)},
      {"glUniform1fv", reinterpret_cast<const void*>(glUniform1fv)},
  };
  for (const auto& [name, pointer] : needed)
    if (!pointer) throw GpuError(std::string("OpenGL: function ") + name + " did not load (GLEW)");
  auto text = [](GLenum what) {
    const GLubyte* s = glGetString(what);
    return s ? std::string(reinterpret_cast<const char*>(s)) : std::string("?");
  };
  renderer_ = text(GL_RENDERER);
  version_ = text(GL_VERSION);
  vendor_ = text(GL_VENDOR);
  hardware_ = !software_renderer_name(renderer_);
  if (!hardware_ && !options.allow_software)
    throw GpuError("OpenGL: only a software renderer is available (" + renderer_ + ")");
}

GlContext::~GlContext() = default;

std::vector<std::string> pinned_gl_libraries() {
  std::lock_guard<std::mutex> lock(pinned_mutex);
  return pinned;
}

bool library_loaded(const std::string& path) { return loaded_objects().count(path) > 0; }

void GlContext::make_current() const {
  if (!eglMakeCurrent(state_->display, EGL_NO_SURFACE, EGL_NO_SURFACE, state_->context))
    throw GpuError("EGL: eglMakeCurrent failed (" + egl_error_name(eglGetError()) + ")");
}

void allocate_storage_buffer(unsigned buffer, std::size_t bytes, const void* data, const char* what) {
  const GLsizeiptr size = static_cast<GLsizeiptr>(std::max<std::size_t>(bytes, 16));
  glBindBuffer(GL_SHADER_STORAGE_BUFFER, buffer);
  if (glBufferStorage)
    glBufferStorage(GL_SHADER_STORAGE_BUFFER, size, data, GL_DYNAMIC_STORAGE_BIT);
  else
    glBufferData(GL_SHADER_STORAGE_BUFFER, size, data, GL_DYNAMIC_DRAW);
  check_gl(what);
}

void check_gl(const char* where) {
  const GLenum e = glGetError();
  if (e == GL_NO_ERROR) return;
  while (glGetError() != GL_NO_ERROR) {}
  std::string what;
  switch (e) {
    case GL_OUT_OF_MEMORY: what = "out of GPU memory (GL_OUT_OF_MEMORY)"; break;
    case GL_INVALID_VALUE: what = "GL_INVALID_VALUE"; break;
    case GL_INVALID_OPERATION: what = "GL_INVALID_OPERATION"; break;
    case GL_INVALID_ENUM: what = "GL_INVALID_ENUM"; break;
    case GL_INVALID_FRAMEBUFFER_OPERATION: what = "GL_INVALID_FRAMEBUFFER_OPERATION"; break;
    default: what = "GL error " + egl_error_name(static_cast<EGLint>(e));
  }
  throw GpuError(std::string("OpenGL: ") + where + ": " + what);
}

unsigned compile_program_sources(const std::vector<std::pair<std::string, std::string>>& sources,
                                 const std::string& defines) {
  const GLuint program = glCreateProgram();
  std::vector<GLuint> shaders;
  auto cleanup = [&] {
    for (GLuint s : shaders) glDeleteShader(s);
    glDeleteProgram(program);
  };
  for (const auto& [name, text] : sources) {
    const std::string ext = name.substr(name.find_last_of('.') + 1);
    GLenum stage = 0;
    if (ext == "comp")
      stage = GL_COMPUTE_SHADER;
    else if (ext == "vert")
      stage = GL_VERTEX_SHADER;
    else if (ext == "geom")
      stage = GL_GEOMETRY_SHADER;
    else if (ext == "frag")
      stage = GL_FRAGMENT_SHADER;
    if (!stage) {
      cleanup();
      throw GpuError("shader " + name + ": unknown stage (use .comp, .vert, .geom or .frag)");
    }
    std::string code = text;
    if (!defines.empty()) {
      const std::size_t line_end = code.find('\n');
      code.insert(line_end == std::string::npos ? code.size() : line_end + 1, defines + "\n");
    }
    const GLuint shader = glCreateShader(stage);
    shaders.push_back(shader);
    const char* pointer = code.c_str();
    glShaderSource(shader, 1, &pointer, nullptr);
    glCompileShader(shader);
    GLint ok = 0;
    glGetShaderiv(shader, GL_COMPILE_STATUS, &ok);
    if (!ok) {
      GLint length = 0;
      glGetShaderiv(shader, GL_INFO_LOG_LENGTH, &length);
      std::string log(std::max(length, 1), '\0');
      glGetShaderInfoLog(shader, length, nullptr, log.data());
      cleanup();
      throw GpuError("shader " + name + " does not compile: " + one_line(log));
    }
    glAttachShader(program, shader);
  }
  glLinkProgram(program);
  GLint ok = 0;
  glGetProgramiv(program, GL_LINK_STATUS, &ok);
  if (!ok) {
    GLint length = 0;
    glGetProgramiv(program, GL_INFO_LOG_LENGTH, &length);
    std::string log(std::max(length, 1), '\0');
    glGetProgramInfoLog(program, length, nullptr, log.data());
    std::string names;
    for (const auto& s : sources) names += (names.empty() ? "" : "+") + s.first;
    cleanup();
    throw GpuError("shader program " + names + " does not link: " + one_line(log));
  }
  for (GLuint s : shaders) {
    glDetachShader(program, s);
    glDeleteShader(s);
  }
  return program;
}

unsigned compile_program(const std::vector<std::string>& files, const std::string& defines) {
  std::vector<std::pair<std::string, std::string>> sources;
  for (const std::string& name : files) {
    const char* text = embedded_shader(name);
    if (!text) throw GpuError("shader " + name + ": not embedded in this build (shaders/*.comp|vert|geom|frag)");
    sources.emplace_back(name, text);
  }
  return compile_program_sources(sources, defines);
}

}  // namespace fascicle::shaders
