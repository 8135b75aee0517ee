// The QR reader on ld-synth scenes, through the detector's corners, as the
// process set reads payloads: 15 cm landmarks at 0.3 to 1.0 m, yaw within
// +-40 degrees, any roll, random lighting and degradation, 640x480 f = 600 px.
#include <gtest/gtest.h>

#include <chrono>
#include <cstdio>
#include <random>
#include <set>

#include <opencv2/imgproc.hpp>

#include "ld/artwork.hpp"
#include "ld/detector.hpp"
#include "ld/eval.hpp"
#include "ld/landmark_layout.hpp"
#include "ld/qr_reader.hpp"
#include "ld/synth.hpp"
#include "../qr_reader/src/qr_pixel_model.hpp"
#include "qr_modules.hpp"

namespace {

bool validUtf8(const std::string& s) {
  for (size_t i = 0; i < s.size();) {
    const auto c = static_cast<unsigned char>(s[i]);
    const size_t n = c < 0x80 ? 1 : (c >> 5) == 6 ? 2 : (c >> 4) == 14 ? 3 : (c >> 3) == 30 ? 4 : 0;
    if (n == 0 || i + n > s.size()) return false;
    for (size_t k = 1; k < n; ++k)
      if ((static_cast<unsigned char>(s[i + k]) >> 6) != 2) return false;
    i += n;
  }
  return true;
}

// Sweep options reading the QR of 15 cm landmarks: `trials` per point, the
// payloads of payloadFor's kinds first_kind .. first_kind + kinds - 1 (0-2:
// 8-23 bytes, 3-4: 99-100 bytes).
ld::eval::SweepOptions readingOptions(int trials, uint64_t seed, int first_kind, int kinds) {
  ld::eval::SweepOptions o;
  o.side_m = 0.15;
  o.trials = trials;
  o.seed = seed;
  o.decode = true;
  o.payload = [=](int i) { return ld::eval::payloadFor(5 * i + first_kind + i % kinds); };
  return o;
}

}  // namespace

TEST(QrPayloads, DistinctAsciiAndUtf8UpTo100Bytes) {
  std::set<std::string> seen;
  bool ascii = false, utf8 = false, hundred = false;
  for (int i = 0; i < 1000; ++i) {
    const std::string p = ld::eval::payloadFor(i);
    EXPECT_LE(p.size(), 100u) << p;
    EXPECT_TRUE(validUtf8(p)) << i;
    EXPECT_TRUE(seen.insert(p).second) << p;
    bool has_multibyte = false;
    for (char c : p) has_multibyte |= static_cast<unsigned char>(c) >= 0x80;
    (has_multibyte ? utf8 : ascii) = true;
    hundred |= p.size() >= 95;
  }
  EXPECT_TRUE(ascii && utf8 && hundred);
}

// The conditions: 15 cm, 0.3 to 1.0 m, yaw within +-40 degrees, 95 %.
// The QR square is 4/9 of the sheet (6.7 cm): at 1 m that is 40 px, about 2
// px per module for payloads of up to ~25 bytes (versions 1-2) but about one
// pixel per module for 100 bytes (version 5, error correction L: 37 modules),
// which single frames seldom resolve; long payloads are asserted where they
// have 1.5 px per module or more (to 0.6 m, read module by module there).
// docs/benchmarks.md has the whole table (ld-eval qr).
ld::eval::Point sweep(const std::vector<double>& distances, int first_kind, int kinds, uint64_t seed) {
  const auto points = ld::eval::overDistance(readingOptions(25, seed, first_kind, kinds), distances, 40.0);
  for (const auto& p : points)
    std::printf("%.2f m: detected %d/%d, decoded %d/%d (%.0f %%)\n", p.distance_m, p.detected,
                p.trials, p.decoded, p.trials, 100 * p.decodeRate());
  const ld::eval::Point t = ld::eval::total(points);
  std::printf("all: decoded %d/%d = %.1f %%\n", t.decoded, t.trials, 100 * t.decodeRate());
  return t;
}

TEST(QrDecodeRate, Landmark15cmPayloadsUpTo23BytesFrom30cmTo1m) {
  const auto t = sweep({0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 1.0}, 0, 3, 2026);
  EXPECT_GE(t.decodeRate(), 0.95);
  EXPECT_EQ(t.wrong_payload, 0);  // a payload is exactly the printed one or none
}

TEST(QrDecodeRate, Landmark15cmPayloadsUpTo100BytesFrom30To60cm) {
  const auto t = sweep({0.3, 0.35, 0.4, 0.45, 0.5, 0.55, 0.6}, 0, 5, 2027);
  EXPECT_GE(t.decodeRate(), 0.95);
  EXPECT_EQ(t.wrong_payload, 0);
}

// ld-qr-reader's stack of an undecoded track's frames: 100-byte codes at
// 1.05 to 1.15 m (a pixel per module or less), the same landmark in 8 frames
// a fraction of a pixel apart, each with its own sensor noise and JPEG, read
// at the detector's corners, in 16 poses. Single frames seldom resolve the
// modules (here 16 of 128, and in 5 of the 16 poses; of the first 8 poses'
// frames 7 of 64 since the fit's pull towards undecided was cut, 4 before; at 1.0
// to 1.1 m, since the reader fits the modules to the pixels, 23 of 64, 21
// with the old pull); their mean in the sheet's frame mostly does.
TEST(QrStack, AveragedFramesReadWhatSingleFramesMiss) {
  const ld::CameraModel cam = ld::CameraModel::defaultVga();
  ld::Detector detector;
  ld::QrReader reader;
  ld::QrReader stack_reader(ld::QrStack::readerParams());  // as ld-qr-reader decodes its stacks
  std::mt19937_64 rng(77);
  std::uniform_real_distribution<double> U(-1, 1);
  int single = 0, singles = 0, stacked = 0, wrong = 0, only_stacked = 0;
  const int kPoses = 16, kFrames = 8;
  for (int pose = 0; pose < kPoses; ++pose) {
    std::string payload = ld::eval::payloadFor(5 * pose + 4);  // the 99-100-byte kind
    const double distance = 1.05 + 0.05 * (pose % 3), yaw = 30 * U(rng), roll = 180 * U(rng);
    int pose_single = 0;
    const double nx = 0.3 * U(rng), ny = 0.3 * U(rng);
    ld::QrStack stack;
    for (int f = 0; f < kFrames; ++f) {
      ld::synth::SceneSpec spec;
      spec.camera = cam;
      // a fraction of a pixel apart (2 / 640 of nx is one pixel)
      spec.landmarks = {ld::synth::placeLandmark(cam, distance, yaw, 0, roll, nx + 0.002 * U(rng),
                                                 ny + 0.002 * U(rng), 0.15, payload)};
      spec.seed = 100 + pose;
      spec.noise_seed = 1000 * pose + f + 1;
      spec.degradation = {0.5, 0.0, 0.0, 4.0, 80};
      const ld::synth::Frame frame = ld::synth::render(spec);
      const auto& d = detector.detect(frame.bgr);
      if (d.landmarks.size() != 1) continue;
      ++singles;
      if (auto r = reader.decode(frame.bgr, d.landmarks[0].corners)) {
        single += r->payload == payload;
        pose_single += r->payload == payload;
        wrong += r->payload != payload;
      }
      stack.add(frame.bgr, d.landmarks[0].corners);
    }
    if (auto r = stack.decode(stack_reader)) {
      stacked += r->payload == payload;
      only_stacked += r->payload == payload && pose_single == 0;
      wrong += r->payload != payload;
    }
    std::printf("pose %d (%.2f m, yaw %.0f): %d frames in the stack, %d read alone\n", pose, distance, yaw, stack.frames(), pose_single);
  }
  std::printf("single frames decoded %d/%d, stacks decoded %d/%d (%d where no frame alone read)\n", single, singles, stacked, kPoses, only_stacked);
  EXPECT_EQ(wrong, 0);
  EXPECT_GE(singles, kPoses * kFrames * 9 / 10);      // the detector finds the landmark ...
  EXPECT_LE(single, singles / 5);                     // ... but single frames seldom read it
  EXPECT_GE(stacked, kPoses * 3 / 8);                 // (measured: 16 / 128 frames, 9 / 16 stacks,
  EXPECT_GE(only_stacked, 3);                         //  4 of them where no frame alone read)
}

// The printed code's error correction: auto takes level L's symbol for 100
// bytes (version 5, 37 modules) where level M needs version 6 (41 modules),
// so its modules are 10 % larger and read from further away; short payloads
// keep their symbol at a higher level. Same scenes, 0.8-1.0 m.
TEST(QrDecodeRate, AutoErrorCorrectionReadsLongPayloadsFurther) {
  ld::eval::SweepOptions o = readingOptions(40, 41, 3, 2);
  int read[2] = {0, 0};
  for (int k = 0; k < 2; ++k) {
    o.ecc = k == 0 ? ld::artwork::QrEcc::Auto : ld::artwork::QrEcc::M;
    for (double d : {0.8, 0.9, 1.0}) {
      const auto p = ld::eval::measure(o, d, 0, 30);
      EXPECT_EQ(p.wrong_payload, 0);
      read[k] += p.decoded;
    }
  }
  std::printf("100 bytes at 0.8-1.0 m: auto (L) %d/120, M %d/120\n", read[0], read[1]);
  EXPECT_GE(read[0], read[1] + 5);  // (measured: 75 against 66; the same symbols would tie)
}

// 100-byte codes at 0.9 and 1 m (about a pixel a module): read from single
// frames by fitting the modules to the pixels (the pixel model; before it,
// 39 and 11 % of 100 frames a point, since it 54 and 35 %).
TEST(QrDecodeRate, FarLongPayloadsReadFromTheirPixels) {
  const ld::eval::SweepOptions o = readingOptions(40, 53, 3, 2);
  int read = 0, trials = 0;
  for (double d : {0.9, 1.0}) {
    const auto p = ld::eval::measure(o, d, 0, 40);
    EXPECT_EQ(p.wrong_payload, 0);
    std::printf("%.1f m, 100 bytes: %d/%d\n", d, p.decoded, p.trials);
    read += p.decoded;
    trials += p.trials;
  }
  EXPECT_GE(read, 32);  // (measured: 25 + 16 of 80; 19 + 4 before the pixel model)
}

// ld-eval qr --stack: each trial read over several frames as ld-qr-reader
// reads an undecoded track. 100-byte codes at 1.2 m, 40 trials (at 1.15 m,
// since the reader fits single frames' modules to the pixels, single frames
// read 9 of 40 and the 8 frames 11; at 0.95 m before the pixel model, 20
// trials, 3 and 8): the 8 frames read more than single frames, and the
// stack reads codes itself: the frames' mean, or the vote of their fits
// (measured: single frames 3 of 40, the 8 frames 20, the stack 20; before
// the vote 12, the mean 4).
TEST(QrDecodeRate, OverSeveralFramesAsTheProcessReads) {
  ld::eval::SweepOptions o = readingOptions(40, 31, 3, 2);
  o.stack_frames = 8;
  const auto p = ld::eval::measure(o, 1.2, 0, 30);
  std::printf("1.2 m, 100 bytes: single frames %d/%d, over 8 frames %d/%d (the stack: %d)\n", p.decoded,
              p.trials, p.decoded_stacked, p.trials, p.decoded_stack);
  EXPECT_EQ(p.wrong_payload, 0);
  EXPECT_GE(p.decoded_stacked, p.decoded + 10);
  EXPECT_GE(p.decoded_stack, 10);  // the stack itself reads, not only one of the 8 frames alone
}

// The QR reader's pixel model, stage by stage, on ld-synth frames of
// 100-byte codes at 0.9-1 m (about a pixel per module) through the
// detector's corners: the data modules it gets wrong against the printed
// ones, with every stage and with one left out. The least-squares start
// and the pair flips each get fewer wrong; with the corners a third of a
// pixel off, moving the grid onto the pixels does.
TEST(QrPixelModel, EachStageGetsFewerModulesWrongOnSynthFrames) {
  const ld::CameraModel cam = ld::CameraModel::defaultVga();
  ld::Detector detector;
  std::mt19937_64 rng(31);
  std::uniform_real_distribution<double> U(-1, 1);
  ld::detail::QrPixelModelStages no_ls, no_pairs, no_align;
  no_ls.least_squares_iterations = 0;
  no_pairs.pair_flips = false;
  no_align.align_steps = 0;
  ld::detail::QrPixelModel all, without_ls(no_ls), without_pairs(no_pairs), without_align(no_align);
  // wrong: all, without the least squares, without pairs; off: all, without alignment (grid shifted)
  int wrong[5] = {}, frames = 0, data_modules = 0;
  double moved_back = 0;
  for (int i = 0; i < 24; ++i) {
    const std::string payload = ld::eval::payloadFor(5 * i + 3 + i % 2);  // the 99-100-byte kinds
    ld::synth::SceneSpec spec;
    spec.camera = cam;
    spec.landmarks = {ld::synth::placeLandmark(cam, 0.9 + 0.1 * (i % 2), 30 * U(rng), 0, 180 * U(rng), 0.3 * U(rng),
                                               0.3 * U(rng), 0.15, payload)};
    spec.seed = 500 + i;
    spec.noise_seed = 600 + i;
    spec.degradation = {0.5, 0.0, 0.0, 4.0, 80};
    const ld::synth::Frame frame = ld::synth::render(spec);
    const auto& d = detector.detect(frame.bgr);
    if (d.landmarks.size() != 1) continue;
    const auto qr = ld::artwork::encodeQr(payload);
    const int n = qr.size;
    cv::Mat gray;
    cv::cvtColor(frame.bgr, gray, cv::COLOR_BGR2GRAY);
    const cv::Matx33d grid = ld::layout::sheetToImage(d.landmarks[0].corners) * ld::detail::moduleToSheet(n);
    const double dx = U(rng) > 0 ? 0.3 : -0.3, dy = U(rng) > 0 ? 0.2 : -0.2;
    const cv::Matx33d off = cv::Matx33d(1, 0, dx, 0, 1, dy, 0, 0, 1) * grid;
    auto wrongModules = [&](ld::detail::QrPixelModel& model, const cv::Matx33d& g) {
      std::vector<uint8_t> modules;
      return model.estimate(gray, g, n, modules) ? ld::test::wrongDataModules(qr, modules).wrong : -1;
    };
    const int w[5] = {wrongModules(all, grid), wrongModules(without_ls, grid), wrongModules(without_pairs, grid),
                      wrongModules(all, off), wrongModules(without_align, off)};
    if (*std::min_element(w, w + 5) < 0) continue;
    // how far the aligned grid's middle is from where the shifted one put it
    const cv::Vec3d a = all.grid() * cv::Vec3d(n / 2.0, n / 2.0, 1), b = off * cv::Vec3d(n / 2.0, n / 2.0, 1);
    moved_back += std::hypot(a[0] / a[2] - b[0] / b[2], a[1] / a[2] - b[1] / b[2]);
    for (int k = 0; k < 5; ++k) wrong[k] += w[k];
    ++frames;
    data_modules += ld::test::wrongDataModules(qr, {}).count;  // (an empty estimate: the count alone)
  }
  std::printf("%d frames, %d data modules: wrong with every stage %d, without the least-squares start %d, "
              "without pair flips %d; corners 0.36 px off: every stage %d, without alignment %d "
              "(the grid moved %.2f px on average)\n",
              frames, data_modules, wrong[0], wrong[1], wrong[2], wrong[3], wrong[4], moved_back / std::max(frames, 1));
  ASSERT_GE(frames, 20);
  EXPECT_LT(wrong[0], data_modules / 10);
  EXPECT_LT(wrong[0] * 10, wrong[1] * 9);
  EXPECT_LT(wrong[0] * 10, wrong[2] * 9);
  EXPECT_LT(wrong[3] * 10, wrong[4] * 9);
}

// A bar over the sheet's [x0, x1] x [y0, y1] (units u) in the image of a
// landmark at `corners`, shaded across from gray `lo` to `hi`: a finger or a
// pen with its lit and its shadowed side.
void shadedBar(cv::Mat& image, const std::array<cv::Point2f, 4>& corners, double x0, double x1, double y0, double y1,
               double lo, double hi) {
  ld::test::paintOnSheet(image, corners, x0, x1, y0, y1, [&](double u, double) {
    const double g = lo + (hi - lo) * (u - x0) / (x1 - x0);
    return cv::Vec3b(cv::saturate_cast<uint8_t>(0.85 * g), cv::saturate_cast<uint8_t>(0.95 * g),
                     cv::saturate_cast<uint8_t>(g));
  });
}

// QrLook on the sweep's conditions (0.3 to 1 m, yaw within +-40 degrees,
// random lighting, blur, noise and JPEG): a read landmark's look against a
// later frame of the same landmark (moved 3 % of the image and 8 degrees,
// drawn with other conditions) and against the landmark of a payload one
// character apart at that pose. In a third of the poses a finger or a pen,
// shaded across (its dark side turns light modules dark, its lit side dark
// ones light: a review's finger was taken for another code), covers part of
// the code in the later frames, in another third a hot spot washes it out:
// those are not another code. (Measured over
// these 300 poses: 167 looks taken of 280 codes read, never Other for the
// same landmark, never Same for another code; where nothing covers the
// code, Same 42 and Other 43 of 55. Over 1500 poses of these conditions
// without cover: 778 looks, Same 582, Other 588, never wrong, before the
// modules were levelled locally.)
TEST(QrLook, TellsAnotherCodeFromTheSameOnSynthFrames) {
  const ld::CameraModel cam = ld::CameraModel::defaultVga();
  ld::Detector detector;
  ld::QrReader reader;
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> U(-1, 1);
  int read = 0, looks = 0, compared[2] = {0, 0};
  int verdicts[2][3] = {};  // [same landmark, another code][Unsure, Same, Other]
  int plain_same = 0, plain_other = 0, plain[2] = {0, 0};  // nothing over the code
  const int kPoses = 300;
  for (int i = 0; i < kPoses; ++i) {
    const std::string a = ld::eval::payloadFor(i);
    std::string b = a;  // (one character apart, where the last is ASCII)
    b.back() = b.back() == 'x' ? 'y' : static_cast<unsigned char>(b.back()) < 0x80 ? 'x' : b.back();
    if (b == a) b = ld::eval::payloadFor(i + 5);
    const double distance = 0.3 + 0.1 * (i % 8), yaw = 40 * U(rng), roll = 180 * U(rng);
    const double nx = 0.3 * U(rng), ny = 0.3 * U(rng);
    auto frame = [&](const std::string& payload, double dnx, double dyaw, uint64_t seed) {
      return ld::synth::render(ld::synth::randomConditions(
          cam, {ld::synth::placeLandmark(cam, distance, yaw + dyaw, 0, roll, nx + dnx, ny, 0.15, payload)}, seed));
    };
    const auto f1 = frame(a, 0, 0, 1000 + i);
    const auto d1 = detector.detect(f1.bgr);
    if (d1.landmarks.size() != 1) continue;
    const auto r = reader.decode(f1.bgr, d1.landmarks[0].corners);
    if (!r || r->payload != a) continue;
    ++read;
    ld::QrLook look;
    if (!look.capture(f1.bgr, d1.landmarks[0].corners)) continue;
    ++looks;
    EXPECT_EQ(look.modules() % 4, 1);
    for (int k = 0; k < 2; ++k) {
      auto f2 = frame(k == 0 ? a : b, 0.03, 8, 2000 + i);
      const auto d2 = detector.detect(f2.bgr);
      if (d2.landmarks.size() != 1) continue;
      const auto& c = d2.landmarks[0].corners;
      const cv::Point2f centre = (c[0] + c[1] + c[2] + c[3]) * 0.25f;
      const float side = static_cast<float>(cv::norm(c[1] - c[0]));
      if (i % 3 == 0) {  // a finger (1 unit wide) or a pen (0.4), shaded across
        const bool pen = i % 2;
        shadedBar(f2.bgr, c, pen ? 5.2 : 5.0, pen ? 5.6 : 6.0, 4.3, 6.7, pen ? 30 : 60, pen ? 230 : 200);
      } else if (i % 3 == 1) {  // a hot spot
        cv::Mat spot(f2.bgr.size(), CV_32F, cv::Scalar(0));
        cv::circle(spot, centre, static_cast<int>(side * 0.2f), cv::Scalar(200), cv::FILLED);
        cv::GaussianBlur(spot, spot, {0, 0}, side * 0.1);
        cv::Mat spot3, f;
        cv::merge(std::vector<cv::Mat>{spot, spot, spot}, spot3);
        f2.bgr.convertTo(f, CV_32FC3);
        f += spot3;
        f.convertTo(f2.bgr, CV_8UC3);  // (saturating)
      }
      const auto v = look.compare(f2.bgr, c);
      ++compared[k];
      ++verdicts[k][static_cast<int>(v)];
      if (k == 0) {
        EXPECT_NE(v, ld::QrLook::Verdict::Other) << "pose " << i << ", " << distance << " m: " << a;
      } else {
        EXPECT_NE(v, ld::QrLook::Verdict::Same) << "pose " << i << ", " << distance << " m: " << b;
      }
      if (i % 3 == 2) {
        ++plain[k];
        (k == 0 ? plain_same : plain_other) += v == (k == 0 ? ld::QrLook::Verdict::Same : ld::QrLook::Verdict::Other);
      }
    }
  }
  std::printf("%d read, %d looks taken; the same landmark: %d compared, %d same, %d unsure, %d other; another "
              "code: %d compared, %d other, %d unsure, %d same (nothing over the code: same %d of %d, other %d of %d)\n",
              read, looks, compared[0], verdicts[0][1], verdicts[0][0], verdicts[0][2], compared[1], verdicts[1][2],
              verdicts[1][0], verdicts[1][1], plain_same, plain[0], plain_other, plain[1]);
  EXPECT_GE(looks, read / 3);
  EXPECT_GE(plain_same, plain[0] * 6 / 10);
  EXPECT_GE(plain_other, plain[1] * 6 / 10);
}

// QrLook under a hot spot of glare (ld-synth's glare, peak 0.5 to 1 of white,
// over or beside the code, its radius 8-20 % of the image width): where the
// spot lifts part of the code towards white, one dark and one light level
// for the whole code class that part all light, and hardly a look was taken
// before the modules were levelled locally (3 of 91 codes read). Corners as the
// truth's, 0.3 px off at most (a detector's); the later frame is the same
// landmark or the code one character apart, 4 degrees further round, under
// the same spot. (Measured over these 120 poses: 92 read, 43 looks taken;
// the same landmark Same 34, Unsure 9, another code Other
// 33, Unsure 10; never wrong.)
TEST(QrLook, TakesLooksUnderAHotSpot) {
  const ld::CameraModel cam = ld::CameraModel::defaultVga();
  ld::QrReader reader;
  std::mt19937_64 rng(7);
  std::mt19937_64 jitter(8);  // (the corners' error: the poses do not depend on what was read)
  std::uniform_real_distribution<double> U(-1, 1), P(0, 1);
  int read = 0, looks = 0, verdicts[2][3] = {};  // [same landmark, another code][Unsure, Same, Other]
  for (int i = 0; i < 120; ++i) {
    const std::string a = ld::eval::payloadFor(i);
    std::string b = a;
    b.back() = b.back() == 'x' ? 'y' : static_cast<unsigned char>(b.back()) < 0x80 ? 'x' : b.back();
    if (b == a) b = ld::eval::payloadFor(i + 5);
    const double distance = 0.3 + 0.1 * (i % 8), yaw = 40 * U(rng), roll = 180 * U(rng);
    const double nx = 0.3 * U(rng), ny = 0.3 * U(rng);
    ld::synth::Lighting glare;
    glare.glare = 0.5 + 0.5 * P(rng);
    glare.glare_radius = 0.08 + 0.12 * P(rng);
    glare.glare_centre = {0.5 + 0.5 * nx + 0.08 * U(rng), 0.5 + 0.5 * ny + 0.08 * U(rng)};
    auto frame = [&](const std::string& payload, double dyaw, uint64_t seed) {
      auto spec = ld::synth::randomConditions(
          cam, {ld::synth::placeLandmark(cam, distance, yaw + dyaw, 0, roll, nx, ny, 0.15, payload)}, seed);
      spec.lighting.glare = glare.glare;
      spec.lighting.glare_radius = glare.glare_radius;
      spec.lighting.glare_centre = glare.glare_centre;
      return ld::synth::render(spec);
    };
    auto corners = [&](const ld::synth::Frame& f) {
      std::array<cv::Point2f, 4> c;
      for (int k = 0; k < 4; ++k)
        c[k] = cv::Point2f(static_cast<float>(f.truth[0].corners[k].x + 0.3 * U(jitter)),
                           static_cast<float>(f.truth[0].corners[k].y + 0.3 * U(jitter)));
      return c;
    };
    const auto f1 = frame(a, 0, 1000 + i);
    const auto c1 = corners(f1);
    const auto r = reader.decode(f1.bgr, c1);
    if (!r || r->payload != a) continue;
    ++read;
    ld::QrLook look;
    if (!look.capture(f1.bgr, c1)) continue;
    ++looks;
    for (int k = 0; k < 2; ++k) {
      const auto f2 = frame(k == 0 ? a : b, 4, 2000 + i);
      const auto v = look.compare(f2.bgr, corners(f2));
      ++verdicts[k][static_cast<int>(v)];
      EXPECT_NE(v, k == 0 ? ld::QrLook::Verdict::Other : ld::QrLook::Verdict::Same)
          << "pose " << i << ", " << distance << " m, glare " << glare.glare << ": " << (k == 0 ? a : b);
    }
  }
  std::printf("under a hot spot: %d read, %d looks taken; the same landmark: %d same, %d unsure, %d other; another "
              "code: %d other, %d unsure, %d same\n",
              read, looks, verdicts[0][1], verdicts[0][0], verdicts[0][2], verdicts[1][2], verdicts[1][0],
              verdicts[1][1]);
  EXPECT_GE(read, 60);
  EXPECT_GE(looks, read / 3);
  EXPECT_GE(verdicts[0][1], looks * 6 / 10);
  EXPECT_GE(verdicts[1][2], looks * 6 / 10);
}
