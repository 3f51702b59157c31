// GpuContext: EGL without a display. Devices through EGL_EXT_platform_device (hardware first),
// then Mesa's surfaceless platform. libepoxy resolves every EGL and GL entry point.
#include <epoxy/egl.h>
#include <epoxy/gl.h>

#include <cstring>
#include <map>
#include <mutex>
#include <string>
#include <vector>

#include "plantview/render.h"

namespace plantview {

namespace {

std::string egl_error_name(EGLint code) {
  switch (code) {
    case EGL_SUCCESS: return "EGL_SUCCESS";
    case EGL_NOT_INITIALIZED: return "EGL_NOT_INITIALIZED";
    case EGL_BAD_ACCESS: return "EGL_BAD_ACCESS";
    case EGL_BAD_ALLOC: return "EGL_BAD_ALLOC";
    case EGL_BAD_ATTRIBUTE: return "EGL_BAD_ATTRIBUTE";
    case EGL_BAD_CONFIG: return "EGL_BAD_CONFIG";
    case EGL_BAD_CONTEXT: return "EGL_BAD_CONTEXT";
    case EGL_BAD_DISPLAY: return "EGL_BAD_DISPLAY";
    case EGL_BAD_MATCH: return "EGL_BAD_MATCH";
    case EGL_BAD_PARAMETER: return "EGL_BAD_PARAMETER";
    default: return "EGL error 0x" + [&] {
      char buf[16];
      std::snprintf(buf, sizeof buf, "%x", unsigned(code));
      return std::string(buf);
    }();
  }
}

bool has_extension(const char* list, const char* name) {
  if (!list) return false;
  const size_t n = std::strlen(name);
  for (const char* p = list; (p = std::strstr(p, name)) != nullptr; p += n) {
    if ((p == list || p[-1] == ' ') && (p[n] == ' ' || p[n] == '\0')) return true;
  }
  return false;
}

// eglInitialize is not counted (EGL 1.5): one eglTerminate ends every context of the display,
// also those current on other threads. The GpuContexts of one device share its display (several
// render threads), so it is initialised and terminated under this lock, and terminated when
// the last of its contexts is released.
std::mutex display_users_mutex;
std::map<EGLDisplay, int> display_users;  // guarded by display_users_mutex

// A display with a current GL 4.5 core context, or an error. Owns what it made.
struct Attempt {
  EGLDisplay display = EGL_NO_DISPLAY;
  EGLContext context = EGL_NO_CONTEXT;
  std::string error;

  void release() {
    if (display != EGL_NO_DISPLAY) {
      eglMakeCurrent(display, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
      if (context != EGL_NO_CONTEXT) eglDestroyContext(display, context);
      std::lock_guard lock(display_users_mutex);
      if (--display_users[display] == 0) {
        display_users.erase(display);
        eglTerminate(display);
      }
    }
    display = EGL_NO_DISPLAY;
    context = EGL_NO_CONTEXT;
  }

  bool open(EGLenum platform, void* native, const std::string& what) {
    display = eglGetPlatformDisplayEXT(platform, native, nullptr);
    if (display == EGL_NO_DISPLAY) {
      error = what + ": no display (" + egl_error_name(eglGetError()) + ")";
      return false;
    }
    EGLint major = 0, minor = 0;
    {
      std::lock_guard lock(display_users_mutex);
      if (!eglInitialize(display, &major, &minor)) {
        error = what + ": eglInitialize failed (" + egl_error_name(eglGetError()) + ")";
        display = EGL_NO_DISPLAY;
        return false;
      }
      ++display_users[display];
    }
    const char* extensions = eglQueryString(display, EGL_EXTENSIONS);
    if (!eglBindAPI(EGL_OPENGL_API)) {
      error = what + ": no desktop OpenGL (" + egl_error_name(eglGetError()) + ")";
      release();
      return false;
    }
    // Rendering goes to framebuffer objects, so no surface is needed: no config at all where
    // the display allows it, else any config that can render OpenGL.
    EGLConfig config = nullptr;
    if (!has_extension(extensions, "EGL_KHR_no_config_context") &&
        !has_extension(extensions, "EGL_MESA_configless_context")) {
      const EGLint config_attributes[] = {EGL_RENDERABLE_TYPE, EGL_OPENGL_BIT, EGL_NONE};
      EGLint count = 0;
      if (!eglChooseConfig(display, config_attributes, &config, 1, &count) || count < 1) {
        error = what + ": no OpenGL config";
        release();
        return false;
      }
    }
    if (!has_extension(extensions, "EGL_KHR_surfaceless_context")) {
      error = what + ": EGL_KHR_surfaceless_context is missing";
      release();
      return false;
    }
    const EGLint context_attributes[] = {EGL_CONTEXT_MAJOR_VERSION, 4,
                                         EGL_CONTEXT_MINOR_VERSION, 5,
                                         EGL_CONTEXT_OPENGL_PROFILE_MASK,
                                         EGL_CONTEXT_OPENGL_CORE_PROFILE_BIT,
                                         EGL_NONE};
    context = eglCreateContext(display, config, EGL_NO_CONTEXT, context_attributes);
    if (context == EGL_NO_CONTEXT) {
      error = what + ": no OpenGL 4.5 core context (" + egl_error_name(eglGetError()) + ")";
      release();
      return false;
    }
    if (!eglMakeCurrent(display, EGL_NO_SURFACE, EGL_NO_SURFACE, context)) {
      error = what + ": eglMakeCurrent failed (" + egl_error_name(eglGetError()) + ")";
      release();
      return false;
    }
    return true;
  }
};

// What EGL says a device is: its DRM node, its CUDA device (NVIDIA's driver where the machine
// has no DRM nodes, as in containers) or "software".
std::string device_name(EGLDeviceEXT device) {
  const char* extensions = eglQueryDeviceStringEXT(device, EGL_EXTENSIONS);
  if (has_extension(extensions, "EGL_EXT_device_drm")) {
    const char* node = eglQueryDeviceStringEXT(device, EGL_DRM_DEVICE_FILE_EXT);
    if (node) return node;
  }
  if (has_extension(extensions, "EGL_NV_device_cuda")) {
    EGLAttrib cuda = -1;
    if (eglQueryDeviceAttribEXT(device, EGL_CUDA_DEVICE_NV, &cuda))
      return "CUDA device " + std::to_string(cuda);
  }
  if (has_extension(extensions, "EGL_MESA_device_software")) return "software";
  return "unnamed";
}

// The devices of EGL_EXT_platform_device, where EGL offers it.
std::vector<EGLDeviceEXT> platform_devices(const char* client_extensions) {
  std::vector<EGLDeviceEXT> devices;
  if (!has_extension(client_extensions, "EGL_EXT_platform_device") ||
      !has_extension(client_extensions, "EGL_EXT_device_enumeration"))
    return devices;
  EGLint count = 0;
  if (eglQueryDevicesEXT(0, nullptr, &count) && count > 0) {
    devices.resize(size_t(count));
    if (!eglQueryDevicesEXT(count, devices.data(), &count)) count = 0;
    devices.resize(size_t(count));
  }
  return devices;
}

std::string device_what(const std::vector<EGLDeviceEXT>& devices, size_t i) {
  return "EGL device " + std::to_string(i) + " (" + device_name(devices[i]) + ")";
}

bool is_software(EGLDeviceEXT device) {
  return has_extension(eglQueryDeviceStringEXT(device, EGL_EXTENSIONS),
                       "EGL_MESA_device_software");
}

std::string gl_description() {
  const auto str = [](GLenum name) {
    const auto* s = reinterpret_cast<const char*>(glGetString(name));
    return std::string(s ? s : "?");
  };
  return str(GL_RENDERER) + " (" + str(GL_VENDOR) + "), OpenGL " + str(GL_VERSION);
}

}  // namespace

struct GpuContext::State {
  Attempt attempt;
  std::string description;
  ~State() { attempt.release(); }
};

GpuContext::GpuContext(std::unique_ptr<State> state) : state_(std::move(state)) {}
GpuContext::~GpuContext() = default;
const std::string& GpuContext::description() const { return state_->description; }

bool GpuContext::make_current(std::string& error) {
  if (!eglMakeCurrent(state_->attempt.display, EGL_NO_SURFACE, EGL_NO_SURFACE,
                      state_->attempt.context)) {
    error = "GPU context: eglMakeCurrent failed (" + egl_error_name(eglGetError()) + ")";
    return false;
  }
  return true;
}

std::unique_ptr<GpuContext> GpuContext::create(int device_index, std::string& error) {
  const char* client_extensions = eglQueryString(EGL_NO_DISPLAY, EGL_EXTENSIONS);
  if (!client_extensions) {
    error = "EGL: no client extensions (is libEGL from Mesa or a GPU driver installed?)";
    return nullptr;
  }
  auto state = std::make_unique<State>();
  std::vector<std::string> failures;
  const std::vector<EGLDeviceEXT> devices = platform_devices(client_extensions);

  if (device_index >= 0) {
    if (size_t(device_index) >= devices.size()) {
      error = "EGL: no device " + std::to_string(device_index) + " (" +
              std::to_string(devices.size()) + " found through EGL_EXT_platform_device)";
      return nullptr;
    }
    const std::string what = device_what(devices, size_t(device_index));
    if (!state->attempt.open(EGL_PLATFORM_DEVICE_EXT, devices[size_t(device_index)], what)) {
      error = state->attempt.error;
      return nullptr;
    }
    state->description = what + ": " + gl_description();
    return std::unique_ptr<GpuContext>(new GpuContext(std::move(state)));
  }

  // Hardware devices first, then software ones, then the surfaceless platform.
  for (int pass = 0; pass < 2; ++pass) {
    for (size_t i = 0; i < devices.size(); ++i) {
      if (is_software(devices[i]) != (pass == 1)) continue;
      const std::string what = device_what(devices, i);
      if (state->attempt.open(EGL_PLATFORM_DEVICE_EXT, devices[i], what)) {
        state->description = what + ": " + gl_description();
        return std::unique_ptr<GpuContext>(new GpuContext(std::move(state)));
      }
      failures.push_back(state->attempt.error);
    }
  }
  if (has_extension(client_extensions, "EGL_MESA_platform_surfaceless")) {
    if (state->attempt.open(EGL_PLATFORM_SURFACELESS_MESA, EGL_DEFAULT_DISPLAY,
                            "Mesa surfaceless")) {
      state->description = "Mesa surfaceless: " + gl_description();
      return std::unique_ptr<GpuContext>(new GpuContext(std::move(state)));
    }
    failures.push_back(state->attempt.error);
  } else {
    failures.push_back("EGL_MESA_platform_surfaceless is not offered");
  }
  error = "EGL: no OpenGL 4.5 core context could be created";
  for (const auto& f : failures) error += "; " + f;
  return nullptr;
}

std::vector<GpuDeviceInfo> GpuContext::list_devices() {
  std::vector<GpuDeviceInfo> list;
  const char* client_extensions = eglQueryString(EGL_NO_DISPLAY, EGL_EXTENSIONS);
  if (!client_extensions) return list;
  const std::vector<EGLDeviceEXT> devices = platform_devices(client_extensions);
  // The context current on this thread, if any, is current again afterwards.
  const EGLDisplay display = eglGetCurrentDisplay();
  const EGLContext context = eglGetCurrentContext();
  const EGLSurface draw = eglGetCurrentSurface(EGL_DRAW), read = eglGetCurrentSurface(EGL_READ);
  for (size_t i = 0; i < devices.size(); ++i) {
    GpuDeviceInfo& info = list.emplace_back();
    info.index = int(i);
    info.name = device_name(devices[i]);
    info.software = is_software(devices[i]);
    const std::string what = device_what(devices, i);
    Attempt attempt;
    info.usable = attempt.open(EGL_PLATFORM_DEVICE_EXT, devices[i], what);
    info.description = info.usable ? what + ": " + gl_description() : attempt.error;
    attempt.release();
  }
  if (context != EGL_NO_CONTEXT) eglMakeCurrent(display, draw, read, context);
  return list;
}

}  // namespace plantview
