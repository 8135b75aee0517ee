// Headless EGL (see egl_context.hpp).
#include "egl_context.hpp"

#include "filters.hpp"

#include <EGL/egl.h>
#include <EGL/eglext.h>
#include <GLES3/gl3.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <functional>
#include <map>
#include <mutex>
#include <vector>

#ifdef LD_HAVE_GBM
#include <fcntl.h>
#include <gbm.h>
#include <unistd.h>
#endif

namespace ld::detail {
namespace {

bool hasExtension(const char* list, const char* name) {
  if (!list) return false;
  const size_t n = std::strlen(name);
  for (const char* p = list; (p = std::strstr(p, name)) != nullptr; p += n)
    if ((p == list || p[-1] == ' ') && (p[n] == ' ' || p[n] == '\0')) return true;
  return false;
}

std::string hex(EGLint e) {
  char b[16];
  std::snprintf(b, sizeof b, "0x%04x", static_cast<unsigned>(e));
  return b;
}

std::mutex g_mutex;
// Initialised displays by name, kept for the process's lifetime.
std::map<std::string, EGLDisplay>& displays() {
  static std::map<std::string, EGLDisplay> m;
  return m;
}

// One way to a display: its name and how to get it (EGL_NO_DISPLAY on failure).
struct Route {
  std::string name;
  std::function<EGLDisplay()> get;
};

std::vector<Route> routes(const std::string& only, std::string& why) {
  std::vector<Route> out;
  const char* client = eglQueryString(EGL_NO_DISPLAY, EGL_EXTENSIONS);
  if (!client) {
    why = "EGL has no client extensions (no EGL_EXT_client_extensions: too old an EGL for headless use)";
    return out;
  }
  auto get_platform_display =
      reinterpret_cast<PFNEGLGETPLATFORMDISPLAYEXTPROC>(eglGetProcAddress("eglGetPlatformDisplayEXT"));
  if (!hasExtension(client, "EGL_EXT_platform_base") || !get_platform_display) {
    why = "EGL lacks EGL_EXT_platform_base";
    return out;
  }
  const bool all = only.empty();
  // 1. devices, hardware first
  if ((all || only == "device") && hasExtension(client, "EGL_EXT_platform_device")) {
    auto query_devices = reinterpret_cast<PFNEGLQUERYDEVICESEXTPROC>(eglGetProcAddress("eglQueryDevicesEXT"));
    auto query_string =
        reinterpret_cast<PFNEGLQUERYDEVICESTRINGEXTPROC>(eglGetProcAddress("eglQueryDeviceStringEXT"));
    EGLDeviceEXT devices[16];
    EGLint n = 0;
    if (query_devices && query_devices(16, devices, &n)) {
      std::vector<std::pair<bool, int>> order;  // (software, index)
      for (int i = 0; i < n; ++i) {
        const char* ext = query_string ? query_string(devices[i], EGL_EXTENSIONS) : nullptr;
        order.push_back({hasExtension(ext, "EGL_MESA_device_software"), i});
      }
      std::stable_sort(order.begin(), order.end());
      for (const auto& [software, i] : order) {
        std::string name = "device " + std::to_string(i);
        const char* ext = query_string ? query_string(devices[i], EGL_EXTENSIONS) : nullptr;
#ifdef EGL_DRM_DEVICE_FILE_EXT
        if (!software && hasExtension(ext, "EGL_EXT_device_drm"))
          if (const char* node = query_string(devices[i], EGL_DRM_DEVICE_FILE_EXT)) name += std::string(" ") + node;
#endif
        (void)ext;
        if (software) name += " (software)";
        EGLDeviceEXT dev = devices[i];
        out.push_back({name, [=] { return get_platform_display(EGL_PLATFORM_DEVICE_EXT, dev, nullptr); }});
      }
    }
  }
  // 2. Mesa's surfaceless platform
  if ((all || only == "surfaceless") && hasExtension(client, "EGL_MESA_platform_surfaceless"))
    out.push_back({"surfaceless", [=] {
                     return get_platform_display(EGL_PLATFORM_SURFACELESS_MESA, EGL_DEFAULT_DISPLAY, nullptr);
                   }});
#ifdef LD_HAVE_GBM
  // 3. GBM on a render node
  if ((all || only == "gbm") &&
      (hasExtension(client, "EGL_KHR_platform_gbm") || hasExtension(client, "EGL_MESA_platform_gbm")))
    for (int node = 128; node < 136; ++node) {
      const std::string path = "/dev/dri/renderD" + std::to_string(node);
      if (access(path.c_str(), R_OK | W_OK) != 0) continue;
      out.push_back({"gbm " + path, [=]() -> EGLDisplay {
                       const int fd = open(path.c_str(), O_RDWR | O_CLOEXEC);
                       if (fd < 0) return EGL_NO_DISPLAY;
                       gbm_device* gbm = gbm_create_device(fd);  // kept for the process's lifetime
                       if (!gbm) {
                         close(fd);
                         return EGL_NO_DISPLAY;
                       }
                       return get_platform_display(EGL_PLATFORM_GBM_KHR, gbm, nullptr);
                     }});
    }
#endif
  if (out.empty()) {
    why = only.empty() ? "EGL offers no headless platform (device, surfaceless or GBM)"
                       : "EGL platform '" + only + "' (LD_EGL_PLATFORM) is not available";
  }
  return out;
}

}  // namespace

std::unique_ptr<EglContext> EglContext::create(std::string& why) {
  why.clear();
  if (envFlag("LD_EGL_FORCE_FAIL")) {
    why = "EGL display disabled by LD_EGL_FORCE_FAIL";
    return nullptr;
  }
  const char* only_env = std::getenv("LD_EGL_PLATFORM");
  const std::string only = only_env ? only_env : "";
  if (!only.empty() && only != "device" && only != "surfaceless" && only != "gbm") {
    why = "LD_EGL_PLATFORM='" + only + "' is none of device, surfaceless, gbm";
    return nullptr;
  }
  std::lock_guard<std::mutex> lock(g_mutex);
  std::string list_why;
  const std::vector<Route> rs = routes(only, list_why);
  if (rs.empty()) {
    why = list_why;
    return nullptr;
  }
  std::string tried;
  auto fail = [&](const std::string& route, const std::string& what) {
    tried += (tried.empty() ? "" : "; ") + route + ": " + what;
  };
  for (const Route& r : rs) {
    EGLDisplay dpy = EGL_NO_DISPLAY;
    if (auto it = displays().find(r.name); it != displays().end()) {
      dpy = it->second;
    } else {
      dpy = r.get();
      if (dpy == EGL_NO_DISPLAY) {
        fail(r.name, "no display (" + hex(eglGetError()) + ")");
        continue;
      }
      EGLint major = 0, minor = 0;
      if (!eglInitialize(dpy, &major, &minor)) {
        fail(r.name, "eglInitialize failed (" + hex(eglGetError()) + ")");
        continue;
      }
      displays()[r.name] = dpy;
    }
    if (!eglBindAPI(EGL_OPENGL_ES_API)) {
      fail(r.name, "no OpenGL ES API");
      continue;
    }
    const char* ext = eglQueryString(dpy, EGL_EXTENSIONS);
    const bool no_config = hasExtension(ext, "EGL_KHR_no_config_context");
    const bool surfaceless = hasExtension(ext, "EGL_KHR_surfaceless_context");
    EGLConfig config = EGL_NO_CONFIG_KHR;
    if (!no_config || !surfaceless) {
      const EGLint want[] = {EGL_RENDERABLE_TYPE, EGL_OPENGL_ES3_BIT, EGL_SURFACE_TYPE, EGL_PBUFFER_BIT,
                             EGL_NONE};
      EGLint n = 0;
      if (!eglChooseConfig(dpy, want, &config, 1, &n) || n < 1) {
        fail(r.name, "no OpenGL ES 3 pbuffer config");
        continue;
      }
    }
    EGLContext ctx = EGL_NO_CONTEXT;
    for (int minor : {1, 0}) {
      const EGLint attrs[] = {EGL_CONTEXT_MAJOR_VERSION, 3, EGL_CONTEXT_MINOR_VERSION, minor, EGL_NONE};
      ctx = eglCreateContext(dpy, config, EGL_NO_CONTEXT, attrs);
      if (ctx != EGL_NO_CONTEXT) break;
    }
    if (ctx == EGL_NO_CONTEXT) {
      fail(r.name, "no OpenGL ES 3.0 context (" + hex(eglGetError()) + ")");
      continue;
    }
    EGLSurface surface = EGL_NO_SURFACE;
    if (!surfaceless) {
      const EGLint attrs[] = {EGL_WIDTH, 1, EGL_HEIGHT, 1, EGL_NONE};
      surface = eglCreatePbufferSurface(dpy, config, attrs);
      if (surface == EGL_NO_SURFACE) {
        eglDestroyContext(dpy, ctx);
        fail(r.name, "no pbuffer surface (" + hex(eglGetError()) + ")");
        continue;
      }
    }
    if (!eglMakeCurrent(dpy, surface, surface, ctx)) {
      fail(r.name, "eglMakeCurrent failed (" + hex(eglGetError()) + ")");
      if (surface != EGL_NO_SURFACE) eglDestroySurface(dpy, surface);
      eglDestroyContext(dpy, ctx);
      continue;
    }
    std::unique_ptr<EglContext> c(new EglContext);
    c->display_ = dpy;
    c->context_ = ctx;
    c->surface_ = surface;
    c->info_.platform = r.name;
    auto str = [](GLenum e) {
      const auto* s = reinterpret_cast<const char*>(glGetString(e));
      return std::string(s ? s : "?");
    };
    c->info_.vendor = str(GL_VENDOR);
    c->info_.renderer = str(GL_RENDERER);
    c->info_.version = str(GL_VERSION);
    GLint major = 0, minor = 0;
    glGetIntegerv(GL_MAJOR_VERSION, &major);
    glGetIntegerv(GL_MINOR_VERSION, &minor);
    c->info_.major = major;
    c->info_.minor = minor;
    for (const char* sw : {"llvmpipe", "softpipe", "SwiftShader", "Software Rasterizer", "swrast"})
      c->info_.software = c->info_.software || c->info_.renderer.find(sw) != std::string::npos;
    c->info_.software = c->info_.software || r.name.find("(software)") != std::string::npos;
    if (major < 3) {
      fail(r.name, "OpenGL ES " + std::to_string(major) + "." + std::to_string(minor) + " is below 3.0");
      continue;  // the destructor releases it
    }
    return c;
  }
  why = "no headless EGL context: " + tried;
  return nullptr;
}

EglContext::~EglContext() {
  if (!context_) return;
  if (eglGetCurrentContext() == context_) eglMakeCurrent(display_, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
  if (surface_) eglDestroySurface(display_, surface_);
  eglDestroyContext(display_, context_);
}

void EglContext::release() {
  if (eglGetCurrentContext() == context_) eglMakeCurrent(display_, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
}

bool EglContext::makeCurrent() {
  if (eglGetCurrentContext() == context_) return true;
  return eglMakeCurrent(display_, surface_, surface_, context_) == EGL_TRUE;
}

}  // namespace ld::detail
