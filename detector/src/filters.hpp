// The front end's per-pixel filters (stages 1-3 of include/ld/detector.hpp):
// what the CPU and GLES backends differ in. Everything after them (regions,
// colour, geometry, corners, pose) is the same code for both backends
// (detector.cpp, stages.cpp).
//
// Not a public interface; tests include it by its path.
#pragma once

#include <chrono>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "ld/detector.hpp"
#include "stages.hpp"

namespace ld::detail {

/// A tiny named-stage timer: stamp(name) records the time since the previous stamp.
class StageTimer {
 public:
  using Clock = std::chrono::steady_clock;
  explicit StageTimer(std::vector<StageTime>& out) : out_(out), start_(Clock::now()), last_(start_) {}
  void stamp(const char* name) {
    const auto now = Clock::now();
    out_.push_back({name, std::chrono::duration<double, std::milli>(now - last_).count()});
    last_ = now;
  }
  double totalMs() const { return std::chrono::duration<double, std::milli>(Clock::now() - start_).count(); }

 private:
  std::vector<StageTime>& out_;
  Clock::time_point start_, last_;
};

/// The filter parameters, resolved from DetectorParams.
struct FilterSettings {
  int blur_kernel = 0;   ///< odd; <= 1: no blur
  double blur_sigma = 0; ///< 0: from the kernel (OpenCV's rule)
  MaskThresholds mask;   ///< fast front end
  double saturation_threshold = 0.45;  ///< paper front end: saturation image cut to zero below
  double canny_low = 50, canny_high = 150;

  static FilterSettings from(const DetectorParams& p);
};

/// Whether the environment variable `name` is set, to anything but "" or "0"
/// (the backends' switches for tests: LD_EGL_FORCE_FAIL, LD_GLES_AUTO_SOFTWARE).
inline bool envFlag(const char* name) {
  const char* v = std::getenv(name);
  return v && *v && std::strcmp(v, "0") != 0;
}

/// Thrown by a backend whose device failed while working on a frame (a lost
/// context, a GL error, a frame over its texture limit): the detector then
/// switches to the CPU backend for good.
struct BackendFailure : std::runtime_error {
  using std::runtime_error::runtime_error;
};
/// A frame the GPU backend does not take (beyond its texture size limit, or
/// its memory: kMaxGlesPixels): that frame runs on the CPU, the backend stays.
struct FrameTooLarge : BackendFailure {
  using BackendFailure::BackendFailure;
};
/// The largest frame the GLES backend takes, in pixels (4096 x 4096: its
/// textures take about 45 bytes a pixel, 750 MB there; 8000x6000 took 2.2 GB).
constexpr int64_t kMaxGlesPixels = int64_t{4096} * 4096;

class Filters {
 public:
  virtual ~Filters() = default;
  /// "cpu" or "gles".
  virtual const char* name() const = 0;
  /// One line on what runs for a front end (the GPU, the EGL platform, the
  /// shader path).
  virtual std::string info(bool paper_front_end) const = 0;

  /// Fast front end, stages 1-2: the label image (CV_8UC1, kNone / kBlue /
  /// kRed per pixel, as saturationMask) of an 8-bit BGR image, after the blur
  /// when s.blur_kernel > 1. `filtered` is set to the image the labels were
  /// computed on (bgr itself, or the blurred image held by the backend),
  /// whose pixels the regions' sums are taken over. Stamps its stages.
  virtual void labelMap(const cv::Mat& bgr, const FilterSettings& s, cv::Mat& labels, const cv::Mat*& filtered,
                        StageTimer& timer) = 0;

  /// Paper front end, stages 1-3: the Canny edge map (CV_8UC1, 0 or 255) of
  /// the HSV saturation (cut to zero below the threshold) of the blurred
  /// image. Stamps its stages.
  virtual void edgeMap(const cv::Mat& bgr, const FilterSettings& s, cv::Mat& edges, StageTimer& timer) = 0;

  /// False while the backend is still trying its own ways of doing a front
  /// end's filters on the first frames (the GLES paper front end's shader
  /// paths), so its times are not yet its settled ones.
  virtual bool settled(bool /*paper_front_end*/) const { return true; }

  /// Leaves the calling thread free of the backend (the GLES backend's EGL
  /// context is no longer current there), so that another thread may run
  /// the next frame: EGL refuses a context current in another thread.
  virtual void releaseThread() {}
};

/// The CPU backend (OpenCV and the vectorised pass of stages.cpp).
std::unique_ptr<Filters> makeCpuFilters();

/// The GLES backend: a headless EGL context of its own and the shaders. On
/// failure returns nullptr and says why in `why` (no EGL display, no
/// OpenGL ES 3.0 context, a shader that does not compile, a self-test that
/// disagrees with the CPU, a build without GLES; with `hardware_only`, a
/// software rasterizer such as llvmpipe). `allow_compute` false keeps to the
/// fragment-shader path even where OpenGL ES 3.1 compute shaders exist.
std::unique_ptr<Filters> makeGlesFilters(std::string& why, bool allow_compute = true, bool hardware_only = false);

/// Whether this build has the GLES backend at all.
bool glesBuilt();

/// The last step of Canny on the CPU: from a map of non-maximum-suppressed
/// gradient pixels (0: none, 1: above the low threshold, 2: above the high
/// one), the edges (255) are the strong pixels and the weak ones
/// 8-connected to them. `stack` is scratch kept between frames.
void hysteresis(const cv::Mat& nms, cv::Mat& edges, std::vector<int>& stack);

/// Resets the process-wide "warned once" flag of the backend fallback (tests).
void resetBackendWarning();

}  // namespace ld::detail
