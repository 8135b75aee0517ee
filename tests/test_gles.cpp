// The GLES backend (detector/src/gles_filters.cpp, egl_context.cpp) against
// the CPU backend, on Mesa's llvmpipe where no GPU is present: headless
// context creation, label maps and edge maps, landmarks, the fallback to the
// CPU when no EGL display can be made, and bad input.
#include <gtest/gtest.h>

#include <memory>
#include <thread>

#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <random>
#include <sstream>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "../detector/src/egl_context.hpp"
#include "../detector/src/filters.hpp"
#include "ld/detector.hpp"
#include "ld/synth.hpp"

namespace {

const ld::CameraModel kCam = ld::CameraModel::defaultVga();

// Sets an environment variable for the scope.
class ScopedEnv {
 public:
  ScopedEnv(const char* name, const char* value) : name_(name) {
    if (const char* old = std::getenv(name)) old_ = old, had_ = true;
    setenv(name, value, 1);
  }
  ~ScopedEnv() {
    if (had_) setenv(name_, old_.c_str(), 1);
    else unsetenv(name_);
  }

 private:
  const char* name_;
  std::string old_;
  bool had_ = false;
};

std::unique_ptr<ld::detail::Filters> gles(bool allow_compute = true) {
  std::string why;
  auto f = ld::detail::makeGlesFilters(why, allow_compute);
  EXPECT_TRUE(f) << why;
  return f;
}

// Synthetic scenes with one or two landmarks of 15 cm at 0.8-2 m, any roll,
// yaw within +-50 degrees, over cluttered backgrounds with distractors.
std::vector<ld::synth::Frame> scenes(int n, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> U(0, 1);
  std::vector<ld::synth::Frame> out;
  for (int i = 0; i < n; ++i) {
    std::vector<ld::synth::LandmarkPlacement> lms;
    const int k = 1 + i % 2;
    for (int j = 0; j < k; ++j)
      lms.push_back(ld::synth::placeLandmark(kCam, 0.8 + 1.2 * U(rng), (U(rng) - 0.5) * 100, (U(rng) - 0.5) * 20,
                                             U(rng) * 360, k == 1 ? (U(rng) - 0.5) * 0.6 : (j ? 0.45 : -0.45),
                                             (U(rng) - 0.5) * 0.6, 0.15, "lm", j));
    out.push_back(ld::synth::render(ld::synth::randomConditions(kCam, lms, rng())));
  }
  return out;
}

// One landmark of 15 cm at 1 m, seen a little from the side (the fallback tests' frame).
ld::synth::Frame oneLandmark() {
  return ld::synth::render(ld::synth::randomConditions(
      kCam, {ld::synth::placeLandmark(kCam, 1.0, 15, 5, 30, 0.1, -0.1, 0.15)}, 17));
}

// A frame wider than any GPU's texture size limit: the GLES backend fails on it mid-run.
cv::Mat beyondTextureLimit() { return cv::Mat(3, 70000, CV_8UC3, cv::Scalar(200, 40, 30)); }

// The fraction of the edge pixels of `a` with an edge pixel of `b` within one pixel.
double agreement(const cv::Mat& a, const cv::Mat& b) {
  cv::Mat grown;
  cv::dilate(b, grown, cv::Mat::ones(3, 3, CV_8U));
  const int n = cv::countNonZero(a);
  return n ? static_cast<double>(cv::countNonZero(a & grown)) / n : 1.0;
}

// Every landmark of `a` in `b` with all four centres within `tol` px, and as many.
void expectSameLandmarks(const ld::Detection& a, const ld::Detection& b, double tol, const std::string& what) {
  ASSERT_EQ(a.landmarks.size(), b.landmarks.size()) << what;
  for (const auto& la : a.landmarks) {
    double best = 1e9;
    for (const auto& lb : b.landmarks) {
      double worst = 0;
      const cv::Point2f pa[4] = {la.fip_tl, la.fip_tr, la.fip_bl, la.ap};
      const cv::Point2f pb[4] = {lb.fip_tl, lb.fip_tr, lb.fip_bl, lb.ap};
      for (int i = 0; i < 4; ++i) worst = std::max(worst, cv::norm(pa[i] - pb[i]));
      best = std::min(best, worst);
    }
    EXPECT_LE(best, tol) << what;
  }
}

}  // namespace

TEST(GlesContext, HeadlessOnThisMachine) {
  ASSERT_TRUE(ld::detail::glesBuilt());
  std::string why;
  auto ctx = ld::detail::EglContext::create(why);
  ASSERT_TRUE(ctx) << why;
  const auto& info = ctx->info();
  std::printf("EGL %s: %s, %s\n", info.platform.c_str(), info.renderer.c_str(), info.version.c_str());
  EXPECT_GE(info.major * 10 + info.minor, 30);
  EXPECT_FALSE(info.renderer.empty());
  EXPECT_TRUE(ctx->makeCurrent());
  // A second context on the same display, and the first still works after it.
  auto second = ld::detail::EglContext::create(why);
  ASSERT_TRUE(second) << why;
  second.reset();
  EXPECT_TRUE(ctx->makeCurrent());
}

// Each headless platform EGL offers here gives a context on its own.
TEST(GlesContext, EachPlatform) {
  int made = 0;
  for (const char* platform : {"device", "surfaceless", "gbm"}) {
    ScopedEnv env("LD_EGL_PLATFORM", platform);
    std::string why;
    auto ctx = ld::detail::EglContext::create(why);
    std::printf("%s: %s\n", platform, ctx ? ctx->info().platform.c_str() : why.c_str());
    if (ctx) {
      ++made;
      EXPECT_EQ(ctx->info().platform.rfind(platform, 0), 0u);
    } else {
      EXPECT_FALSE(why.empty());
    }
  }
  EXPECT_GE(made, 1);
  ScopedEnv env("LD_EGL_PLATFORM", "wayland");
  std::string why;
  EXPECT_FALSE(ld::detail::EglContext::create(why));
  EXPECT_NE(why.find("LD_EGL_PLATFORM"), std::string::npos) << why;
}

// The fast front end's label images are the CPU's, pixel for pixel: on
// scenes, on random colours (every branch of the rule), and at widths that
// are not a multiple of four.
TEST(GlesParity, LabelMapsIdentical) {
  auto g = gles();
  ASSERT_TRUE(g);
  auto c = ld::detail::makeCpuFilters();
  const auto s = ld::detail::FilterSettings::from({});
  std::vector<cv::Mat> images;
  for (auto& f : scenes(3, 11)) images.push_back(f.bgr);
  cv::RNG rng(5);
  for (cv::Size size : {cv::Size(640, 480), cv::Size(37, 23), cv::Size(3, 3), cv::Size(1001, 7)}) {
    cv::Mat noise(size, CV_8UC3);
    rng.fill(noise, cv::RNG::UNIFORM, 0, 256);
    images.push_back(noise);
  }
  for (const cv::Mat& img : images) {
    std::vector<ld::StageTime> st;
    ld::detail::StageTimer timer(st);
    cv::Mat lc, lg;
    const cv::Mat *fc = nullptr, *fg = nullptr;
    c->labelMap(img, s, lc, fc, timer);
    g->labelMap(img, s, lg, fg, timer);
    ASSERT_EQ(lg.size(), img.size());
    EXPECT_EQ(cv::countNonZero(lc != lg), 0) << img.size();
    EXPECT_GT(cv::countNonZero(lc == ld::detail::kBlue), 0);
    EXPECT_GT(cv::countNonZero(lc == ld::detail::kRed), 0);
    EXPECT_EQ(fg, &img);
  }
}

// With a blur, the fast front end's blurred image and labels are the CPU's
// (the GPU's blur is OpenCV's fixed point; a pixel off by one at most).
TEST(GlesParity, BlurredLabelMapsAgree) {
  auto g = gles();
  ASSERT_TRUE(g);
  auto c = ld::detail::makeCpuFilters();
  ld::DetectorParams p;
  p.blur_kernel = 5;
  p.blur_sigma = 1.2;
  const auto s = ld::detail::FilterSettings::from(p);
  for (auto& f : scenes(2, 12)) {
    std::vector<ld::StageTime> st;
    ld::detail::StageTimer timer(st);
    cv::Mat lc, lg;
    const cv::Mat *fc = nullptr, *fg = nullptr;
    c->labelMap(f.bgr, s, lc, fc, timer);
    g->labelMap(f.bgr, s, lg, fg, timer);
    ASSERT_TRUE(fc && fg);
    ASSERT_EQ(fg->type(), CV_8UC3);
    EXPECT_LE(cv::norm(*fc, *fg, cv::NORM_INF), 1.0);
    EXPECT_LE(cv::countNonZero(lc != lg), static_cast<int>(0.001 * lc.total()));
  }
}

// The paper front end's edge maps, on the fragment-shader path and on the
// compute-shader path: at least 98 % of each map's edge pixels have one of
// the other's within one pixel (in fact all but a few are the same pixels).
class GlesEdges : public testing::TestWithParam<const char*> {};

TEST_P(GlesEdges, EdgeMapsAgree) {
  const bool compute = std::string(GetParam()) == "compute";
  ScopedEnv env("LD_GLES_COMPUTE", compute ? "1" : "0");
  auto g = gles();
  ASSERT_TRUE(g);
  std::printf("%s\n", g->info(true).c_str());
  EXPECT_EQ(g->info(true).find("paper front end on compute shaders") != std::string::npos, compute) << g->info(true);
  auto c = ld::detail::makeCpuFilters();
  const auto frames = scenes(3, 13);
  for (const ld::DetectorParams& p : {ld::DetectorParams::paper(), [] {
         ld::DetectorParams q = ld::DetectorParams::paper();
         q.blur_kernel = 0;  // Sobel, suppression and thresholds alone
         return q;
       }()}) {
    const auto s = ld::detail::FilterSettings::from(p);
    for (auto& f : frames) {
      std::vector<ld::StageTime> st;
      ld::detail::StageTimer timer(st);
      cv::Mat ec, eg;
      c->edgeMap(f.bgr, s, ec, timer);
      g->edgeMap(f.bgr, s, eg, timer);
      ASSERT_EQ(eg.size(), ec.size());
      ASSERT_EQ(eg.type(), CV_8UC1);
      const double cg = agreement(ec, eg), gc = agreement(eg, ec);
      const int differ = cv::countNonZero(ec != eg);
      std::printf("blur %d: %d CPU edge pixels, %.4f / %.4f within 1 px, %d differ\n", s.blur_kernel,
                  cv::countNonZero(ec), cg, gc, differ);
      EXPECT_GT(cv::countNonZero(ec), 1000);
      EXPECT_GE(cg, 0.98);
      EXPECT_GE(gc, 0.98);
      // The same integer arithmetic (OpenCV's fixed-point blur included): all but a few pixels alike.
      EXPECT_LE(differ, static_cast<int>(0.001 * cv::countNonZero(ec)) + 5);
    }
  }
}

// Odd sizes (partial tiles and texels, rows of one or two groups) and noise
// (edges everywhere, borders included): the same edge maps.
TEST_P(GlesEdges, OddSizesAndNoise) {
  const bool compute = std::string(GetParam()) == "compute";
  ScopedEnv env("LD_GLES_COMPUTE", compute ? "1" : "0");
  auto g = gles();
  ASSERT_TRUE(g);
  auto c = ld::detail::makeCpuFilters();
  cv::RNG rng(21);
  for (cv::Size size : {cv::Size(37, 23), cv::Size(1001, 7), cv::Size(5, 5), cv::Size(3, 3), cv::Size(17, 300),
                        cv::Size(640, 480)})
    for (int blur : {31, 21, 13, 11, 9, 7, 5, 3, 0}) {  // (7 to 31 came out otherwise before: OpenCV's rounding)
      cv::Mat img(size, CV_8UC3);
      rng.fill(img, cv::RNG::UNIFORM, 0, 256);
      cv::rectangle(img, {1, 1}, {size.width / 2, size.height / 2}, {200, 40, 30}, cv::FILLED);
      ld::DetectorParams p = ld::DetectorParams::paper();
      p.blur_kernel = blur;
      p.blur_sigma = blur == 5 ? 1.2 : p.blur_sigma;
      const auto s = ld::detail::FilterSettings::from(p);
      std::vector<ld::StageTime> st;
      ld::detail::StageTimer timer(st);
      cv::Mat ec, eg;
      c->edgeMap(img, s, ec, timer);
      g->edgeMap(img, s, eg, timer);
      ASSERT_EQ(eg.size(), size);
      EXPECT_EQ(cv::countNonZero(ec != eg), 0) << size << " blur " << blur;
    }
}

INSTANTIATE_TEST_SUITE_P(Paths, GlesEdges, testing::Values("fragment", "compute"));

// Both front ends: the same landmarks, centres within 0.5 px (the paper
// front end's first frames try both shader paths, then keep the faster).
TEST(GlesParity, SameLandmarks) {
  const auto frames = scenes(10, 14);  // the paper front end measures its two shader paths on 10
  for (const char* fe : {"fast", "paper"}) {
    ld::DetectorParams p = std::string(fe) == "paper" ? ld::DetectorParams::paper() : ld::DetectorParams{};
    ld::Detector cpu(p);
    p.backend = "gles";
    ld::Detector gpu(p);
    ASSERT_STREQ(gpu.backend(), "gles");
    int found = 0;
    for (size_t i = 0; i < frames.size(); ++i) {
      const ld::Detection a = cpu.detect(frames[i].bgr);
      const ld::Detection& b = gpu.detect(frames[i].bgr);
      expectSameLandmarks(a, b, 0.5, std::string(fe) + " frame " + std::to_string(i));
      found += static_cast<int>(a.landmarks.size());
      EXPECT_GT(b.stageMs("upload"), 0.0);
      EXPECT_GT(b.stageMs("readback"), 0.0);
      EXPECT_EQ(a.stageMs("upload"), 0.0);
    }
    std::printf("%s: %d landmarks in %zu frames, the same on both backends; %s\n", fe, found, frames.size(),
                gpu.backendInfo().c_str());
    if (std::string(fe) == "paper") {  // the shader path is chosen by now
      EXPECT_EQ(gpu.backendInfo().find("the faster on the first frames"), std::string::npos) << gpu.backendInfo();
    }
    EXPECT_GE(found, static_cast<int>(frames.size()) / 2) << fe;
  }
}

// With a camera (a pose per landmark, and the sheet alignment that runs by
// default then, on the CPU after either backend's filters): the same
// landmarks and the same poses on both backends.
TEST(GlesParity, SamePosesWithACamera) {
  const auto frames = scenes(6, 23);
  ld::DetectorParams p;
  ld::Detector cpu(p);
  p.backend = "gles";
  ld::Detector gpu(p);
  ASSERT_STREQ(gpu.backend(), "gles");
  cpu.setCamera(kCam, 0.15);
  gpu.setCamera(kCam, 0.15);
  int posed = 0;
  double corner_diff = 0, distance_diff = 0;
  for (size_t i = 0; i < frames.size(); ++i) {
    const ld::Detection a = cpu.detect(frames[i].bgr);
    const ld::Detection& b = gpu.detect(frames[i].bgr);
    expectSameLandmarks(a, b, 0.5, "frame " + std::to_string(i));
    for (const auto& la : a.landmarks)
      for (const auto& lb : b.landmarks) {
        if (cv::norm(la.fip_tl - lb.fip_tl) > 0.5) continue;
        ASSERT_TRUE(la.pose && lb.pose) << "frame " << i;
        for (int k = 0; k < 4; ++k) corner_diff = std::max(corner_diff, cv::norm(la.corners[k] - lb.corners[k]));
        distance_diff = std::max(distance_diff, std::abs(la.pose->distance / lb.pose->distance - 1));
        ++posed;
      }
  }
  std::printf("%d landmarks with a pose on both backends: corners at most %.4f px apart, distances %.4f %%\n", posed,
              corner_diff, 100 * distance_diff);
  EXPECT_GE(posed, static_cast<int>(frames.size()) / 2);
  // (the alignment moves corners by 0.1-0.2 px: a backend that skipped it would be that far off)
  EXPECT_LT(corner_diff, 0.05);
  EXPECT_LT(distance_diff, 0.0005);
}

// "auto" with a GPU (here any renderer, LD_GLES_AUTO_SOFTWARE) times the
// GPU's filters against the CPU's on the first frames, in blocks, then keeps
// the one its own medians say is faster (or, with LD_GLES_AUTO_FORCE, the
// one forced, so that both outcomes run on any machine). The landmarks are
// the CPU detector's on every frame, before, during and after the choice;
// backend() names what ran each frame (the GPU's frames have an upload
// stage, the CPU's none). The fast front end also with a blur: its filtered
// image is then the backend's own, and must outlive the choice.
TEST(GlesAuto, TimesBothThenKeepsTheFasterWithTheSameLandmarks) {
  ScopedEnv soft("LD_GLES_AUTO_SOFTWARE", "1");
  const auto frames = scenes(6, 16);
  struct Case {
    const char* fe;
    int blur;
    const char* force;
  };
  // ("GPU": no value it takes, ignored with a warning; it kept the GPU without a word)
  for (const Case& k : {Case{"fast", 0, ""}, Case{"paper", 0, ""}, Case{"fast", 5, "gles"}, Case{"fast", 5, "cpu"},
                        Case{"paper", 0, "gles"}, Case{"fast", 0, "GPU"}}) {
    const bool forced = std::string(k.force) == "gles" || std::string(k.force) == "cpu";
    ScopedEnv force("LD_GLES_AUTO_FORCE", k.force);
    ld::DetectorParams p = std::string(k.fe) == "paper" ? ld::DetectorParams::paper() : ld::DetectorParams{};
    if (k.blur) p.blur_kernel = k.blur;
    ld::Detector cpu(p);
    p.backend = "auto";
    const bool unknown_force = *k.force && !forced;
    if (unknown_force) testing::internal::CaptureStderr();  // (said as the detector is made)
    ld::Detector a(p);
    const std::string name = std::string(k.fe) + (k.blur ? " blur" : "") + (*k.force ? " forced " : "") + k.force;
    ASSERT_STREQ(a.backend(), "gles") << a.backendInfo();
    EXPECT_TRUE(a.choosingBackend()) << name;
    EXPECT_NE(a.backendInfo().find("timing it against the CPU"), std::string::npos) << a.backendInfo();
    std::map<std::string, int> ran_during, ran_after;
    const int n = 50;  // the paper front end: 10 frames for its shader path, then 24 for the choice
    for (int i = 0; i < n; ++i) {
      const auto& f = frames[static_cast<size_t>(i) % frames.size()];
      const bool choosing = a.choosingBackend();
      const ld::Detection c = cpu.detect(f.bgr);
      const ld::Detection& d = a.detect(f.bgr);
      const std::string what = name + " frame " + std::to_string(i);
      expectSameLandmarks(c, d, 0.5, what);
      const std::string b = a.backend();
      EXPECT_EQ(d.stageMs("upload") > 0, b == "gles") << what << ": " << b;
      (choosing ? ran_during : ran_after)[b]++;
    }
    if (unknown_force) {  // (said once a process: this is the suite's one such case)
      const std::string said = testing::internal::GetCapturedStderr();
      EXPECT_NE(said.find("warning: LD_GLES_AUTO_FORCE=" + std::string(k.force) + " is neither gles nor cpu: ignored"),
                std::string::npos)
          << name << ": " << said;
    }
    EXPECT_FALSE(a.choosingBackend()) << name;
    EXPECT_GT(ran_during["cpu"], 0) << name;
    EXPECT_GT(ran_during["gles"], 0) << name;
    ASSERT_EQ(ran_after.size(), 1u) << name << ": the backend still changes after the choice";
    EXPECT_GE(ran_after.begin()->second, 10) << name;
    const std::string chosen = ran_after.begin()->first;
    const std::string info = a.backendInfo();
    std::printf("%s: %s -> %s\n", name.c_str(), info.c_str(), chosen.c_str());
    EXPECT_EQ(info.find("timing it"), std::string::npos) << info;
    EXPECT_NE(info.find(chosen == "cpu" ? "auto chose the CPU" : "auto chose the GPU"), std::string::npos) << info;
    if (forced) {
      EXPECT_EQ(chosen, k.force) << info;
      EXPECT_NE(info.find("LD_GLES_AUTO_FORCE"), std::string::npos) << info;
    } else {  // the choice agrees with the medians it reports
      EXPECT_EQ(info.find("LD_GLES_AUTO_FORCE"), std::string::npos) << info;
      const size_t took = info.find("took "), against = info.find("against ");
      ASSERT_NE(took, std::string::npos) << info;
      ASSERT_NE(against, std::string::npos) << info;
      const double gpu_ms = std::stod(info.substr(took + 5)), cpu_ms = std::stod(info.substr(against + 8));
      EXPECT_EQ(chosen, cpu_ms <= gpu_ms ? "cpu" : "gles") << info;
    }
  }
}

// LD_GLES_AUTO_FORCE=gles where "auto" finds no GPU (here the software
// renderer alone, which auto does not take): the CPU runs, and the one
// warning says the variable is ignored (it was dropped without a word). (A
// value it does not take is said as the detector is made, GPU or none:
// GlesAuto.TimesBothThenKeepsTheFasterWithTheSameLandmarks.)
TEST(GlesAuto, ForceWithoutAGpuIsSaidToBeIgnored) {
  ld::DetectorParams p;
  p.backend = "auto";
  {
    ScopedEnv force("LD_GLES_AUTO_FORCE", "gles");
    ld::detail::resetBackendWarning();
    testing::internal::CaptureStderr();
    ld::Detector a(p);
    const std::string said = testing::internal::GetCapturedStderr();
    if (std::string(a.backend()) == "gles") GTEST_SKIP() << "a GPU here: " << a.backendInfo();
    EXPECT_NE(said.find("running the CPU backend; LD_GLES_AUTO_FORCE=gles is ignored: auto has no GPU to keep"),
              std::string::npos)
        << said;
    EXPECT_EQ(std::count(said.begin(), said.end(), '\n'), 1) << said;
  }
}

// The GPU failing while "auto" is still timing it: the CPU for good, one
// warning, no choice left pending or reported, the same landmarks after.
TEST(GlesAuto, GpuFailureDuringTheChoice) {
  ScopedEnv soft("LD_GLES_AUTO_SOFTWARE", "1");
  ScopedEnv fail("LD_GLES_FAIL_AT_FRAME", "2");  // (the GPU's second frame)
  ld::detail::resetBackendWarning();
  ld::DetectorParams p;
  p.backend = "auto";
  ld::Detector d(p);
  const auto f = oneLandmark();
  const size_t n = d.detect(f.bgr).landmarks.size();
  ASSERT_GT(n, 0u);
  ASSERT_STREQ(d.backend(), "gles");  // (the first block runs on the GPU)
  ASSERT_TRUE(d.choosingBackend());
  testing::internal::CaptureStderr();
  EXPECT_EQ(d.detect(f.bgr).landmarks.size(), n);  // (done again on the CPU)
  const std::string err = testing::internal::GetCapturedStderr();
  EXPECT_STREQ(d.backend(), "cpu");
  EXPECT_FALSE(d.choosingBackend());
  EXPECT_EQ(std::count(err.begin(), err.end(), '\n'), 1) << err;
  for (int i = 0; i < 30; ++i) {
    const ld::Detection& det = d.detect(f.bgr);
    EXPECT_EQ(det.landmarks.size(), n) << i;
    EXPECT_EQ(det.stageMs("upload"), 0.0) << i;
    EXPECT_STREQ(d.backend(), "cpu") << i;
  }
  const std::string info = d.backendInfo();
  EXPECT_NE(info.find("failure forced by LD_GLES_FAIL_AT_FRAME"), std::string::npos) << info;
  EXPECT_EQ(info.find("auto chose"), std::string::npos) << info;
  EXPECT_EQ(info.find("timing"), std::string::npos) << info;
  ld::detail::resetBackendWarning();
}

// No EGL display: "auto" runs the CPU with one warning per process, "gles"
// throws a clear error, and detection goes on.
TEST(GlesFallback, ForcedEglFailure) {
  ScopedEnv env("LD_EGL_FORCE_FAIL", "1");
  ld::detail::resetBackendWarning();
  ld::DetectorParams p;
  p.backend = "auto";
  testing::internal::CaptureStderr();
  ld::Detector a(p), b(p);
  const std::string err = testing::internal::GetCapturedStderr();
  EXPECT_STREQ(a.backend(), "cpu");
  EXPECT_STREQ(b.backend(), "cpu");
  EXPECT_NE(a.backendInfo().find("LD_EGL_FORCE_FAIL"), std::string::npos) << a.backendInfo();
  size_t lines = 0;
  for (char ch : err) lines += ch == '\n';
  EXPECT_EQ(lines, 1u) << err;
  EXPECT_NE(err.find("warning"), std::string::npos) << err;
  EXPECT_NE(err.find("CPU"), std::string::npos) << err;
  const auto frames = scenes(1, 15);
  EXPECT_FALSE(a.detect(frames[0].bgr).landmarks.empty());

  p.backend = "gles";
  try {
    ld::Detector g(p);
    ADD_FAILURE() << "backend gles without EGL did not throw";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("GLES backend unavailable"), std::string::npos) << e.what();
  }
  ld::detail::resetBackendWarning();
}

// Without the forced failure, "auto" takes the GPU where there is one,
// silently; where there is only a software renderer (llvmpipe, as in CI) it
// runs the CPU, which is faster, with the one warning.
TEST(GlesFallback, AutoTakesAGpuNotASoftwareRenderer) {
  std::string why;
  auto ctx = ld::detail::EglContext::create(why);
  ASSERT_TRUE(ctx) << why;
  const bool software = ctx->info().software;
  std::printf("renderer %s: %s\n", ctx->info().renderer.c_str(), software ? "software" : "GPU");
  ctx.reset();
  ld::detail::resetBackendWarning();
  ld::DetectorParams p;
  p.backend = "auto";
  testing::internal::CaptureStderr();
  ld::Detector d(p);
  const std::string err = testing::internal::GetCapturedStderr();
  if (software) {
    EXPECT_STREQ(d.backend(), "cpu");
    EXPECT_EQ(std::count(err.begin(), err.end(), '\n'), 1) << err;
    EXPECT_NE(err.find("software renderer"), std::string::npos) << err;
  } else {
    EXPECT_EQ(err, "");
    EXPECT_STREQ(d.backend(), "gles");
    EXPECT_EQ(d.backendInfo().rfind("gles: ", 0), 0u) << d.backendInfo();
  }
  ld::detail::resetBackendWarning();
}

// The backend is a parameter like the others: saved, loaded, validated.
TEST(GlesParams, BackendInParameterFiles) {
  const auto path = std::filesystem::temp_directory_path() / ("test_gles_params_" + std::to_string(getpid()) + ".yaml");
  ld::DetectorParams p;
  p.backend = "auto";
  p.save(path.string());
  EXPECT_EQ(ld::DetectorParams::load(path.string()).backend, "auto");
  std::filesystem::remove(path);
  p.backend = "metal";
  try {
    p.validate();
    ADD_FAILURE() << "backend metal accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("backend"), std::string::npos) << e.what();
  }
  EXPECT_THROW(ld::Detector{p}, std::invalid_argument);
}

// A GPU that fails mid-run (here: forced on its second frame) is dropped
// for the CPU with one warning; detection goes on, that frame included.
TEST(GlesFallback, FailureMidRunSwitchesToCpu) {
  ScopedEnv fail("LD_GLES_FAIL_AT_FRAME", "2");
  ld::detail::resetBackendWarning();
  ld::DetectorParams p;
  p.backend = "gles";
  ld::Detector d(p);
  const auto f = oneLandmark();
  const size_t n = d.detect(f.bgr).landmarks.size();
  ASSERT_GT(n, 0u);
  ASSERT_STREQ(d.backend(), "gles");
  testing::internal::CaptureStderr();
  EXPECT_EQ(d.detect(f.bgr).landmarks.size(), n);
  EXPECT_EQ(d.detect(f.bgr).landmarks.size(), n);
  const std::string err = testing::internal::GetCapturedStderr();
  EXPECT_STREQ(d.backend(), "cpu");
  EXPECT_EQ(std::count(err.begin(), err.end(), '\n'), 1) << err;
  EXPECT_NE(err.find("GLES backend failed"), std::string::npos) << err;
  EXPECT_NE(d.backendInfo().find("LD_GLES_FAIL_AT_FRAME"), std::string::npos) << d.backendInfo();
  ld::detail::resetBackendWarning();
}

// A frame the GPU does not take (beyond its texture size limit, or over its
// pixel budget) runs alone on the CPU, with one warning; the GPU stays for
// the frames after (one stray frame made it the CPU for good before).
TEST(GlesFallback, FrameTooLargeRunsAloneOnTheCpu) {
  ld::detail::resetBackendWarning();
  ld::DetectorParams p;
  p.backend = "gles";
  ld::Detector d(p);
  const auto f = oneLandmark();
  const size_t n = d.detect(f.bgr).landmarks.size();
  ASSERT_GT(n, 0u);
  testing::internal::CaptureStderr();
  EXPECT_TRUE(d.detect(beyondTextureLimit()).landmarks.empty());
  EXPECT_STREQ(d.backend(), "cpu");  // (that frame's)
  EXPECT_TRUE(d.detect(cv::Mat(4100, 4100, CV_8UC3, cv::Scalar(255, 255, 255))).landmarks.empty());
  EXPECT_EQ(d.detect(f.bgr).landmarks.size(), n);
  EXPECT_STREQ(d.backend(), "gles");
  const std::string err = testing::internal::GetCapturedStderr();
  EXPECT_EQ(std::count(err.begin(), err.end(), '\n'), 1) << err;
  EXPECT_NE(err.find("texture size limit"), std::string::npos) << err;
  EXPECT_NE(err.find("; frames that large run on the CPU backend"), std::string::npos) << err;
  ld::detail::resetBackendWarning();
}

namespace {

// Runs a shell command; its exit status, and its stderr in `err`.
int run(const std::string& cmd, std::string& err) {
  const auto tmp = std::filesystem::temp_directory_path() / ("test_gles_err_" + std::to_string(getpid()));
  const int rc = std::system((cmd + " 2> " + tmp.string()).c_str());
  std::ifstream in(tmp);
  std::stringstream ss;
  ss << in.rdbuf();
  err = ss.str();
  std::filesystem::remove(tmp);
  return WIFEXITED(rc) ? WEXITSTATUS(rc) : -1;
}

}  // namespace

// ld-detect --backend: gles and cpu find the same landmark; without EGL,
// auto warns once and goes on, gles stops with a clear error.
TEST(GlesCli, DetectBackendOption) {
  const auto dir = std::filesystem::temp_directory_path() / ("test_gles_" + std::to_string(getpid()));
  std::filesystem::create_directories(dir);
  const auto f = ld::synth::render(ld::synth::randomConditions(
      kCam, {ld::synth::placeLandmark(kCam, 1.2, -20, 0, 120, 0, 0, 0.15)}, 18));
  ASSERT_TRUE(cv::imwrite((dir / "frame.png").string(), f.bgr));
  const std::string detect = std::string(LD_BIN_DIR) + "/ld-detect " + (dir / "frame.png").string();
  std::string err;
  std::string out[2];
  for (int k = 0; k < 2; ++k) {
    const auto json = dir / ("out" + std::to_string(k) + ".jsonl");
    EXPECT_EQ(run(detect + " --backend " + (k ? "gles" : "cpu") + " -o " + json.string(), err), 0) << err;
    std::ifstream in(json);
    std::getline(in, out[k]);
    // detect_ms aside, the same line
    out[k] = out[k].substr(out[k].find("\"landmarks\""));
  }
  EXPECT_EQ(out[0], out[1]);
  EXPECT_NE(out[0].find("fip_tl"), std::string::npos) << out[0];

  EXPECT_EQ(run("LD_EGL_FORCE_FAIL=1 " + detect + " --backend auto -o /dev/null", err), 0) << err;
  EXPECT_EQ(std::count(err.begin(), err.end(), '\n'), 1) << err;
  EXPECT_NE(err.find("ld-detect: warning: GLES backend unavailable"), std::string::npos) << err;
  EXPECT_EQ(run("LD_EGL_FORCE_FAIL=1 " + detect + " --backend gles -o /dev/null", err), 2) << err;
  EXPECT_NE(err.find("GLES backend unavailable"), std::string::npos) << err;
  // ld-detector: status 1, not 2 (a GPU whose driver is not up yet at boot:
  // a supervisor starts it again, where 2 stopped the set for good)
  EXPECT_EQ(run("LD_EGL_FORCE_FAIL=1 " + std::string(LD_BIN_DIR) + "/ld-detector --backend gles", err), 1) << err;
  EXPECT_NE(err.find("ld-detector: GLES backend unavailable"), std::string::npos) << err;
  EXPECT_EQ(run(detect + " --backend metal -o /dev/null", err), 2) << err;  // a bad command line, one line
  EXPECT_NE(err.find("ld-detect: --backend: metal not in {cpu,gles,auto}"), std::string::npos) << err;
  std::filesystem::remove_all(dir);
}

// Two GLES detectors used in turn on one thread (each has its own context,
// made current as needed) give what each gives alone.
TEST(GlesInput, TwoDetectorsInTurn) {
  ld::DetectorParams fast, paper = ld::DetectorParams::paper();
  fast.backend = paper.backend = "gles";
  ld::Detector a(fast), b(paper), cpu_a, cpu_b(ld::DetectorParams::paper());
  for (const auto& f : scenes(3, 19)) {
    const ld::Detection wa = cpu_a.detect(f.bgr), wb = cpu_b.detect(f.bgr);
    const ld::Detection ga = a.detect(f.bgr);
    const ld::Detection& gb = b.detect(f.bgr);
    expectSameLandmarks(wa, ga, 1e-4, "fast");
    expectSameLandmarks(wb, gb, 1e-4, "paper");
  }
  EXPECT_STREQ(a.backend(), "gles");
  EXPECT_STREQ(b.backend(), "gles");
}

// A GLES Detector is used from one thread at a time, not always the same
// one: made in a thread that has ended, then run in this one, then in
// others in turn. Its EGL context stayed current in the thread of its last
// frame, EGL refused it to the next ("cannot make the EGL context current"),
// and the detector ran on the CPU from then on.
TEST(GlesInput, HandedFromThreadToThread) {
  std::unique_ptr<ld::Detector> d;
  std::thread([&] {
    ld::DetectorParams p;
    p.backend = "gles";
    d = std::make_unique<ld::Detector>(p);
  }).join();
  ASSERT_STREQ(d->backend(), "gles");
  ld::Detector cpu;
  const auto frames = scenes(4, 23);
  const auto check = [&](size_t i, const std::string& where) {
    const ld::Detection& g = d->detect(frames[i].bgr);
    EXPECT_GT(g.stageMs("upload"), 0.0) << where;  // (the GPU's stage ran)
    EXPECT_STREQ(d->backend(), "gles") << where;
    expectSameLandmarks(cpu.detect(frames[i].bgr), g, 1e-4, where);
  };
  check(0, "this thread");
  for (size_t i = 1; i < frames.size(); ++i) std::thread([&] { check(i, "thread " + std::to_string(i)); }).join();
  check(0, "this thread again");
  EXPECT_STREQ(d->backend(), "gles");
  std::thread([&] { d.reset(); }).join();  // (and freed in yet another)
}

// Empty, tiny, gray, four-channel and 16-bit images, and frames changing size,
// on both front ends: no crash, no landmarks where none can be.
TEST(GlesInput, BadAndOddImages) {
  for (const char* fe : {"fast", "paper"}) {
    ld::DetectorParams p = std::string(fe) == "paper" ? ld::DetectorParams::paper() : ld::DetectorParams{};
    p.backend = "gles";
    ld::Detector d(p);
    EXPECT_TRUE(d.detect(cv::Mat()).landmarks.empty());
    EXPECT_TRUE(d.detect(cv::Mat(1, 1, CV_8UC3, cv::Scalar(255, 0, 0))).landmarks.empty());
    EXPECT_TRUE(d.detect(cv::Mat(2, 2, CV_8UC3, cv::Scalar(255, 0, 0))).landmarks.empty());
    EXPECT_TRUE(d.detect(cv::Mat(3, 3, CV_8UC3, cv::Scalar(255, 0, 0))).landmarks.empty());
    EXPECT_TRUE(d.detect(cv::Mat(480, 640, CV_8UC1, cv::Scalar(128))).landmarks.empty());
    EXPECT_THROW(d.detect(cv::Mat(480, 640, CV_16UC3, cv::Scalar(0))), std::invalid_argument);  // (said, not none)
    // a 15 cm landmark at 1 m, a little turned: both front ends find it
    const auto f = ld::synth::render(ld::synth::randomConditions(
        kCam, {ld::synth::placeLandmark(kCam, 1.0, 15, 5, 30, 0.1, -0.1, 0.15)}, 16));
    cv::Mat bgra;
    cv::cvtColor(f.bgr, bgra, cv::COLOR_BGR2BGRA);
    const size_t n = d.detect(f.bgr).landmarks.size();
    EXPECT_GT(n, 0u) << fe;
    EXPECT_EQ(d.detect(bgra).landmarks.size(), n) << fe;
    // A view into a larger image (not continuous), then the full frame again.
    EXPECT_NO_THROW(d.detect(f.bgr(cv::Rect(3, 5, 317, 211))));
    EXPECT_EQ(d.detect(f.bgr).landmarks.size(), n) << fe;
    EXPECT_STREQ(d.backend(), "gles");
  }
}
