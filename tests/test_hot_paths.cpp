// Hot paths allocate nothing per frame once warmed up (the design's rule). The
// detector is counted at malloc itself, not at operator new: OpenCV takes its
// buffers from malloc and posix_memalign. (ld::Tracker is counted in
// test_tracker; ld::MessagePublisher's kept buffer in test_messages.)
#include <gtest/gtest.h>

#include <atomic>
#include <cerrno>
#include <cstdlib>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "ld/adaptive.hpp"
#include "ld/detector.hpp"
#include "ld/landmark_layout.hpp"
#include "../qr_reader/src/qr_pixel_model.hpp"
#include "ld/synth.hpp"

// The sanitizers replace malloc themselves: no count under them.
#if defined(__SANITIZE_ADDRESS__)
#define LD_COUNT_MALLOC 0
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define LD_COUNT_MALLOC 0
#endif
#endif
#ifndef LD_COUNT_MALLOC
#define LD_COUNT_MALLOC 1
#endif

namespace {
std::atomic<bool> g_counting{false};
std::atomic<long> g_allocations{0};
}  // namespace

#if LD_COUNT_MALLOC
// glibc's own entry points, which a program may wrap (free needs no wrapper).
extern "C" {
void* __libc_malloc(size_t);
void* __libc_calloc(size_t, size_t);
void* __libc_realloc(void*, size_t);
void* __libc_memalign(size_t, size_t);

void* malloc(size_t n) {
  if (g_counting) ++g_allocations;
  return __libc_malloc(n);
}
void* calloc(size_t n, size_t size) {
  if (g_counting) ++g_allocations;
  return __libc_calloc(n, size);
}
void* realloc(void* p, size_t n) {
  if (g_counting) ++g_allocations;
  return __libc_realloc(p, n);
}
void* memalign(size_t alignment, size_t n) {
  if (g_counting) ++g_allocations;
  return __libc_memalign(alignment, n);
}
void* aligned_alloc(size_t alignment, size_t n) {
  if (g_counting) ++g_allocations;
  return __libc_memalign(alignment, n);
}
int posix_memalign(void** p, size_t alignment, size_t n) {
  if (g_counting) ++g_allocations;
  *p = __libc_memalign(alignment, n);
  return *p ? 0 : ENOMEM;
}
}
#endif

namespace {

struct Frame {
  cv::Mat bgr;
  bool glare_corrected = false;  // Detector::setGlareCorrected
};

// Frames of a drive past five landmarks under four lightings: as rendered
// (the main look), warm tungsten light and dim light (the faint look's white
// balance), and glare on the wall; and the glare frames as ld-detector
// --adaptive gives them to the detector, a strong veil taken out (the veil
// look's tint).
std::vector<Frame> frames() {
  ld::synth::SequenceOptions o;
  o.out_dir.clear();
  o.write_png = false;
  o.frames = 20;
  o.landmarks = 5;
  o.seed = 4;
  ld::synth::Sequence seq(o);
  std::vector<Frame> out;
  ld::LightingAdapter adapter;
  for (int light = 0; light < 5; ++light)
    for (int i = 0; i < seq.frames(); ++i) {
      ld::synth::SceneSpec scene = seq.scene(i);
      if (light == 1) scene.lighting.colour_temp_k = 2200, scene.lighting.gain = 0.6;
      if (light == 2) scene.lighting.gain = 0.25;
      if (light >= 3) scene.lighting.glare = 0.6, scene.lighting.glare_radius = 0.3;
      Frame f{ld::synth::render(scene).bgr};
      if (light == 4) {
        adapter.reset();  // (each frame on its own, as ld-eval's trials)
        f.bgr = adapter.correct(f.bgr).clone();
        f.glare_corrected = adapter.strongVeil();
      }
      out.push_back(f);
    }
  return out;
}

}  // namespace

TEST(HotPaths, DetectorAllocatesNothingOnceWarmedUp) {
  if (!LD_COUNT_MALLOC) GTEST_SKIP() << "the sanitizers own malloc";
  const std::vector<Frame> scenes = frames();
  ld::Detector detector;  // the CPU backend (Mesa's and a GPU driver's own allocations are theirs)
  for (int pass = 0; pass < 2; ++pass)  // warm: every buffer at its largest for these frames
    for (const Frame& f : scenes) {
      detector.setGlareCorrected(f.glare_corrected);
      detector.detect(f.bgr);
    }
  long allocations = 0;
  size_t landmarks = 0;
  int frames_with = 0, veiled = 0;
  for (const Frame& f : scenes) {
    detector.setGlareCorrected(f.glare_corrected);
    veiled += f.glare_corrected;
    g_allocations = 0;
    g_counting = true;
    const ld::Detection& d = detector.detect(f.bgr);
    g_counting = false;
    allocations += g_allocations;
    frames_with += g_allocations > 0;
    landmarks += d.landmarks.size();
  }
  EXPECT_EQ(allocations, 0) << "in " << frames_with << " of " << scenes.size() << " frames";
  EXPECT_GE(landmarks, scenes.size());  // (the frames hold landmarks, and they were found)
  EXPECT_GE(veiled, 10);                // (and the veil look ran)
}

// The QR reader's pixel model (its own code: the reader around it calls
// OpenCV's warps and zbar, which allocate): far landmarks' codes (100-byte
// payloads at 0.8-1.2 m, modules of about 1 px) fitted to the pixels, then
// fitted again once every buffer is at its largest.
TEST(HotPaths, QrPixelModelAllocatesNothingOnceWarmedUp) {
  if (!LD_COUNT_MALLOC) GTEST_SKIP() << "the sanitizers own malloc";
  const ld::CameraModel cam = ld::CameraModel::defaultVga();
  struct Code {
    cv::Mat gray;
    cv::Matx33d module_to_image;
  };
  std::vector<Code> codes;
  const std::string payload(100, 'Q');  // version 5 at level L: 37 modules
  constexpr int n = 37;
  for (int k = 0; k < 5; ++k) {
    ld::synth::SceneSpec spec;
    spec.camera = cam;
    spec.landmarks = {ld::synth::placeLandmark(cam, 0.8 + 0.1 * k, 20.0 - 10 * k, 5, 30.0 * k, 0, 0, 0.15, payload)};
    spec.seed = 10 + static_cast<uint64_t>(k);
    const ld::synth::Frame frame = ld::synth::render(spec);
    std::array<cv::Point2f, 4> corners;
    for (size_t i = 0; i < 4; ++i) corners[i] = cv::Point2f(frame.truth[0].corners[i]);
    Code c;
    cv::cvtColor(frame.bgr, c.gray, cv::COLOR_BGR2GRAY);
    c.module_to_image = ld::layout::sheetToImage(corners) * ld::detail::moduleToSheet(n);
    codes.push_back(c);
  }
  ld::detail::QrPixelModel model;
  std::vector<uint8_t> modules;
  int fitted = 0;
  for (int pass = 0; pass < 2; ++pass)
    for (const Code& c : codes) fitted += model.estimate(c.gray, c.module_to_image, n, modules);
  EXPECT_EQ(fitted, 2 * static_cast<int>(codes.size()));
  long allocations = 0;
  for (const Code& c : codes) {
    g_allocations = 0;
    g_counting = true;
    model.estimate(c.gray, c.module_to_image, n, modules);
    g_counting = false;
    allocations += g_allocations;
  }
  EXPECT_EQ(allocations, 0);
}

// The count itself works: a frame's worth of cv::Mat is counted.
TEST(HotPaths, TheCountSeesOpenCvBuffers) {
  if (!LD_COUNT_MALLOC) GTEST_SKIP() << "the sanitizers own malloc";
  g_allocations = 0;
  g_counting = true;
  {
    cv::Mat m(480, 640, CV_8UC3);
    m.setTo(cv::Scalar::all(1));
  }
  g_counting = false;
  EXPECT_GE(g_allocations.load(), 1);
}
