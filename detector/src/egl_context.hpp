// A headless EGL context for OpenGL ES, without any window system.
//
// The display is chosen through EGL's platform extensions, in this order:
//  1. the device platform (EGL_EXT_platform_device; eglQueryDevicesEXT):
//     NVIDIA's driver and Mesa's devices, hardware devices before Mesa's
//     software one (EGL_MESA_device_software, llvmpipe);
//  2. Mesa's surfaceless platform (EGL_MESA_platform_surfaceless);
//  3. GBM on a DRM render node (/dev/dri/renderD128...; EGL_KHR_platform_gbm),
//     as on a Raspberry Pi's V3D.
// The first display that initialises and gives an OpenGL ES 3.1 (or else
// 3.0) context without a surface (or with a 1x1 pbuffer where the driver
// needs one) wins.
//
// Environment, read at each create():
//  - LD_EGL_FORCE_FAIL=1: fail as if no display could be made (tests of the
//    CPU fallback; a machine whose GPU misbehaves);
//  - LD_EGL_PLATFORM=device|surfaceless|gbm: try that platform only.
//
// Displays are initialised once per process and never terminated (EGL 1.5
// does not count eglInitialize calls: terminating one would break every other
// context on it); each EglContext has a context of its own.
//
// Not a public interface; tests include it by its path.
#pragma once

#include <memory>
#include <string>

namespace ld::detail {

struct EglInfo {
  std::string platform;  ///< "device", "surfaceless" or "gbm" (and which device or node)
  std::string vendor, renderer, version;  ///< GL_VENDOR, GL_RENDERER, GL_VERSION
  int major = 0, minor = 0;               ///< the context's OpenGL ES version
  /// A software rasterizer (Mesa's llvmpipe or softpipe, SwiftShader): the
  /// CPU emulating a GPU, slower than the CPU backend itself.
  bool software = false;
};

class EglContext {
 public:
  /// A context, current on the calling thread; nullptr with `why` on failure.
  static std::unique_ptr<EglContext> create(std::string& why);
  ~EglContext();
  EglContext(const EglContext&) = delete;
  EglContext& operator=(const EglContext&) = delete;

  /// Makes the context current on the calling thread (cheap when it already is).
  bool makeCurrent();
  /// Makes it current on no thread, when it is on the calling one (EGL
  /// refuses to make a context current that another thread holds).
  void release();
  const EglInfo& info() const { return info_; }

 private:
  EglContext() = default;
  void* display_ = nullptr;
  void* context_ = nullptr;
  void* surface_ = nullptr;
  EglInfo info_;
};

}  // namespace ld::detail
