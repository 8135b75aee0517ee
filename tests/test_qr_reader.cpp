// The QR reader rectifies a landmark from its corners and decodes its payload
// with zbar; damaged, missing or degenerate input gives no payload.
#include <gtest/gtest.h>

#include <type_traits>

#include <climits>
#include <cmath>
#include <cstdio>
#include <random>
#include <sstream>

#include <opencv2/imgproc.hpp>
#include <lcm/lcm-cpp.hpp>
#include <qrencode.h>

#include "ld/artwork.hpp"
#include "ld/image_convert.hpp"
#include "ld/message_decode.hpp"
#include "ld/message_publisher.hpp"
#include "ld/landmark_layout.hpp"
#include "ld/qr_reader.hpp"
#include "ld/qr_track_reader.hpp"
#include "../qr_reader/src/qr_function_patterns.hpp"
#include "../qr_reader/src/qr_pixel_model.hpp"
#include "qr_modules.hpp"

namespace {

struct Scene {
  cv::Mat image;
  std::array<cv::Point2f, 4> corners;
};

// The artwork warped by a homography onto a grey wall (or onto `onto`); corners exact.
Scene warped(const cv::Mat& sheet, const std::array<cv::Point2f, 4>& sheet_corners_in_image,
             const cv::Mat& onto = cv::Mat()) {
  const float s = static_cast<float>(sheet.cols);
  const std::vector<cv::Point2f> src{{0, 0}, {s, 0}, {s, s}, {0, s}};
  std::vector<cv::Point2f> dst(sheet_corners_in_image.begin(), sheet_corners_in_image.end());
  // sheet pixel coordinates are [0, s) with centres at +0.5: shift to OpenCV's convention
  const cv::Matx33d to_centres(1, 0, -0.5, 0, 1, -0.5, 0, 0, 1);
  const cv::Matx33d H = to_centres * cv::Matx33d(cv::getPerspectiveTransform(src, dst));
  Scene sc;
  sc.image = onto.empty() ? cv::Mat(480, 640, CV_8UC3, cv::Scalar(120, 130, 140)) : onto.clone();
  cv::warpPerspective(sheet, sc.image, H, sc.image.size(), cv::INTER_AREA, cv::BORDER_TRANSPARENT);
  for (size_t i = 0; i < 4; ++i) {
    const auto& c = ld::layout::kCornersU[i];
    const cv::Vec3d p = H * cv::Vec3d(c[0] * s / 9.0, c[1] * s / 9.0, 1.0);
    sc.corners[i] = {static_cast<float>(p[0] / p[2]), static_cast<float>(p[1] / p[2])};
  }
  return sc;
}

// A tracked landmark at `corners` (TL, TR, BR, BL), detected in its frame.
ld::landmark_t tracked(int64_t id, int32_t age, const std::array<cv::Point2f, 4>& corners) {
  ld::landmark_t lm{};
  lm.track_id = id;
  lm.age = age;
  lm.visible = true;
  for (size_t i = 0; i < 4; ++i) {
    lm.corners[i][0] = corners[i].x;
    lm.corners[i][1] = corners[i].y;
  }
  return lm;
}

ld::landmark_list_t trackedList(int64_t utime, int64_t seq, std::vector<ld::landmark_t> landmarks) {
  ld::landmark_list_t list{};
  list.utime = utime;
  list.seq = seq;
  list.width = 640;
  list.height = 480;
  list.backend = "tracker";
  list.landmarks = std::move(landmarks);
  list.nlandmarks = static_cast<int32_t>(list.landmarks.size());
  return list;
}

std::optional<std::string> codeOf(const ld::qr_code_list_t& out, int64_t id) {
  for (const auto& c : out.codes)
    if (c.track_id == id) return c.payload;
  return std::nullopt;
}

// A large landmark whose QR cannot be read (its middle painted over, 20 ms
// a try) and a readable one beside it.
struct TwoTracks {
  std::array<cv::Point2f, 4> damaged{{{20, 60}, {340, 60}, {340, 380}, {20, 380}}};
  std::array<cv::Point2f, 4> readable{{{400, 140}, {600, 140}, {600, 340}, {400, 340}}};
  cv::Mat image;
  TwoTracks() {
    cv::Mat sheet = ld::artwork::renderLandmark("damaged", 900);
    cv::rectangle(sheet, cv::Rect(250, 250, 400, 200), cv::Scalar(255, 255, 255), cv::FILLED);
    image = warped(ld::artwork::renderLandmark("room-214/door", 900), readable,
                   warped(sheet, damaged).image)
                .image;
  }
};

}  // namespace

TEST(QrReader, DecodesFrontalAndObliqueViews) {
  ld::QrReader reader;
  const std::vector<std::string> payloads{"room-214/door", "\xc3\xa9t\xc3\xa9 \xe6\x9d\xb1",
                                          std::string(100, 'Z')};
  for (const auto& p : payloads) {
    const cv::Mat sheet = ld::artwork::renderLandmark(p, 900);
    const Scene front = warped(sheet, {{{170, 90}, {470, 90}, {470, 390}, {170, 390}}});
    auto r = reader.decode(front.image, front.corners);
    ASSERT_TRUE(r.has_value()) << p;
    EXPECT_EQ(r->payload, p);
    const Scene oblique = warped(sheet, {{{200, 120}, {400, 80}, {410, 420}, {190, 360}}});
    r = reader.decode(oblique.image, oblique.corners);
    ASSERT_TRUE(r.has_value()) << p;
    EXPECT_EQ(r->payload, p);
    EXPECT_EQ(reader.lastView().rows, reader.lastView().cols);
  }
}

TEST(QrReader, UpsideDownUsesTheCornerOrder) {
  ld::QrReader reader;
  const cv::Mat sheet = ld::artwork::renderLandmark("upside-down", 900);
  // TL of the sheet at the bottom right of the image.
  const Scene sc = warped(sheet, {{{470, 390}, {170, 390}, {170, 90}, {470, 90}}});
  const auto r = reader.decode(sc.image, sc.corners);
  ASSERT_TRUE(r.has_value());
  EXPECT_EQ(r->payload, "upside-down");
}

// About 1.3 camera pixels per module, blurred: zbar finds no finder pattern
// in the view, the module-by-module reading of the sheet frame does.
TEST(QrReader, ReadsModuleByModuleWhereModulesAreUnderTwoPixels) {
  ld::QrReader reader;
  const std::string payload = "salle-107 \xc3\xa9t\xc3\xa9 caf\xc3\xa9";  // version 2: 25 modules
  ASSERT_EQ(ld::artwork::encodeQr(payload).size, 25);
  const cv::Mat sheet = ld::artwork::renderLandmark(payload, 900);
  // sheet side 80 px: QR square 36 px for 27 modules (code + quiet zone)
  Scene sc = warped(sheet, {{{300, 200}, {380, 204}, {378, 282}, {298, 280}}});
  cv::GaussianBlur(sc.image, sc.image, {0, 0}, 0.4);
  const auto r = reader.decode(sc.image, sc.corners);
  ASSERT_TRUE(r.has_value());
  EXPECT_EQ(r->payload, payload);
  EXPECT_GE(r->attempt, 6) << "decoded by attempt " << r->attempt;  // the grid, after the views failed
}

// A 100-byte URL-like payload with `id` in it.
std::string longPayload(int id) {
  std::string payload = "https://example.org/building-7/floor-2/corridor-B/landmark?id=" + std::to_string(id) + "&v=";
  while (payload.size() < 100) payload += static_cast<char>('a' + payload.size() % 26);
  return payload;
}

// A 100-byte payload at level M (version 6: 41 modules) at about 1.5 camera pixels per
// module with motion blur across it: a fixed sharpening of the module grid
// leaves too many modules wrong; the equaliser, its blur model fitted on the
// code's function patterns, reads it.
TEST(QrReader, EqualisesBlurredModules) {
  ld::QrReader reader;
  const std::string payload = longPayload(42);
  const auto qr = ld::artwork::encodeQr(payload, ld::artwork::QrEcc::M);
  ASSERT_EQ(qr.size, 41);
  const cv::Mat sheet = ld::artwork::renderLandmark(qr, 900);
  // sheet side 150 px: QR square 67 px for 43 modules (code + quiet zone)
  Scene sc = warped(sheet, {{{250, 160}, {400, 166}, {397, 314}, {247, 310}}});
  const cv::Mat motion = cv::getGaussianKernel(5, 1.0, CV_32F).t();  // along x
  cv::filter2D(sc.image, sc.image, -1, motion);
  const auto r = reader.decode(sc.image, sc.corners);
  ASSERT_TRUE(r.has_value());
  EXPECT_EQ(r->payload, payload);
  EXPECT_EQ(r->attempt, 6) << "decoded by attempt " << r->attempt;
}

// A 100-byte payload (version 5 at level L: 37 modules) at about 1.04 camera
// pixels per module, defocused: sampled at the modules' centres, too many
// modules are wrong for the code's error correction; fitted to the pixels through the
// camera's blur (the pixel model), the code reads.
Scene defocusedLongCode(const std::string& payload, double sigma) {
  const auto qr = ld::artwork::encodeQr(payload);
  EXPECT_EQ(qr.size, 37);
  const cv::Mat sheet = ld::artwork::renderLandmark(qr, 900);
  // sheet side about 91 px: QR square 40.5 px for 39 modules (code + quiet
  // zone); drawn 8 times finer and box-filtered down, as a sensor integrates
  // over its pixels (warpPerspective alone samples the artwork, aliased)
  // (the sheet's pixel i spans [i, i + 1) of its edge coordinates, which is
  // what `sheet_to_fine` maps; the fine image's pixel centres are at +0.5)
  const std::array<cv::Point2f, 4> corners{{{275, 195}, {365.9f, 198.6f}, {364.1f, 288.6f}, {273.2f, 285.9f}}};
  const cv::Rect region(240, 160, 160, 160);
  constexpr float kFine = 8;
  const float s = static_cast<float>(sheet.cols);
  std::vector<cv::Point2f> edge{{0, 0}, {s, 0}, {s, s}, {0, s}}, fine;
  for (const auto& c : corners) fine.push_back((c - cv::Point2f(region.tl()) + cv::Point2f(0.5f, 0.5f)) * kFine);
  const cv::Matx33d sheet_to_fine(cv::getPerspectiveTransform(edge, fine));
  // (warpPerspective maps pixel indices: the sheet's index i is its edge
  // coordinate i + 0.5, the fine image's edge coordinate e its index e - 0.5)
  const cv::Matx33d index_to_index =
      cv::Matx33d(1, 0, -0.5, 0, 1, -0.5, 0, 0, 1) * sheet_to_fine * cv::Matx33d(1, 0, 0.5, 0, 1, 0.5, 0, 0, 1);
  cv::Mat big(static_cast<int>(region.height * kFine), static_cast<int>(region.width * kFine), CV_8UC3,
              cv::Scalar(120, 130, 140));
  cv::warpPerspective(sheet, big, index_to_index, big.size(), cv::INTER_LINEAR, cv::BORDER_TRANSPARENT);
  Scene sc;
  sc.image = cv::Mat(480, 640, CV_8UC3, cv::Scalar(120, 130, 140));
  cv::resize(big, sc.image(region), region.size(), 0, 0, cv::INTER_AREA);
  for (size_t i = 0; i < 4; ++i) {
    const auto& c = ld::layout::kCornersU[i];
    const cv::Vec3d p = sheet_to_fine * cv::Vec3d(c[0] * s / 9.0, c[1] * s / 9.0, 1.0);
    // fine edge coordinates -> image pixel coordinates (centres at integers)
    sc.corners[i] = cv::Point2f(static_cast<float>(p[0] / p[2]), static_cast<float>(p[1] / p[2])) / kFine -
                    cv::Point2f(0.5f, 0.5f) + cv::Point2f(region.tl());
  }
  cv::GaussianBlur(sc.image, sc.image, {0, 0}, sigma);
  cv::Mat noise(sc.image.size(), CV_32FC3);
  cv::theRNG().state = 42;
  cv::randn(noise, 0, 2.0);
  cv::Mat f;
  sc.image.convertTo(f, CV_32FC3);
  f += noise;
  f.convertTo(sc.image, CV_8UC3);
  return sc;
}

TEST(QrReader, FitsModulesToThePixelsThroughTheBlur) {
  const std::string payload = longPayload(7);
  ld::QrReader reader;
  const Scene sc = defocusedLongCode(payload, 0.4);
  const auto r = reader.decode(sc.image, sc.corners);
  ASSERT_TRUE(r.has_value());
  EXPECT_EQ(r->payload, payload);
  EXPECT_EQ(r->attempt, 8) << "decoded by attempt " << r->attempt;
}

// The pixel model on its own: nearly every module of that code as printed, where the modules' centres sampled get many wrong; and nothing
// (no crash) for a grid off the image or an image of the wrong type.
TEST(QrPixelModel, EstimatesTheModulesOfABlurredCode) {
  const std::string payload = longPayload(7);
  const auto qr = ld::artwork::encodeQr(payload);
  const Scene sc = defocusedLongCode(payload, 0.4);
  cv::Mat gray;
  cv::cvtColor(sc.image, gray, cv::COLOR_BGR2GRAY);
  const int n = qr.size;
  const cv::Matx33d module_to_image = ld::layout::sheetToImage(sc.corners) * ld::detail::moduleToSheet(n);
  ld::detail::QrPixelModel model;
  std::vector<uint8_t> modules;
  ASSERT_TRUE(model.estimate(gray, module_to_image, n, modules));
  ASSERT_EQ(modules.size(), static_cast<size_t>(n * n));
  const auto [wrong, count] = ld::test::wrongDataModules(qr, modules);
  const std::vector<uint8_t> function = ld::test::functionModules(n);
  int wrong_sampled = 0;
  for (int r = 0; r < n; ++r)
    for (int c = 0; c < n; ++c) {
      if (function[static_cast<size_t>(r) * n + c]) continue;
      // the module's centre, thresholded halfway between the code's light and dark
      const cv::Vec3d p = module_to_image * cv::Vec3d(c + 0.5, r + 0.5, 1);
      cv::Mat px;
      cv::getRectSubPix(gray, {1, 1}, {static_cast<float>(p[0] / p[2]), static_cast<float>(p[1] / p[2])}, px);
      wrong_sampled += (px.at<uint8_t>(0, 0) < 128) != qr.dark(c, r);
    }
  std::printf("modules wrong (all but the function patterns): pixel model %d, centres sampled %d, of %d\n", wrong,
              wrong_sampled, count);
  EXPECT_LT(wrong, count / 50);
  EXPECT_GT(wrong_sampled, 4 * wrong);
  // a grid off the image, a colour image: nothing
  const cv::Matx33d away(1, 0, 5000, 0, 1, 5000, 0, 0, 1);
  EXPECT_FALSE(model.estimate(gray, away * module_to_image, n, modules));
  EXPECT_FALSE(model.estimate(sc.image, module_to_image, n, modules));
}

// Moving the grid onto the pixels: the same code, a little sharper, with
// the corners a third of a pixel off (0.3 px right, 0.24 px up). The
// affine step's least squares come out with scale and rotation as large as
// the shift, a move of more than half a pixel, and are refused; the shift
// alone is right, and two steps of it bring the grid within 0.1 px. Without
// the alignment (or with the affine step alone) 153 modules are wrong.
TEST(QrPixelModel, MovesAGridAThirdOfAPixelOffOntoThePixels) {
  const std::string payload = longPayload(7);
  const auto qr = ld::artwork::encodeQr(payload);
  const int n = qr.size;
  const Scene sc = defocusedLongCode(payload, 0.5);
  cv::Mat gray;
  cv::cvtColor(sc.image, gray, cv::COLOR_BGR2GRAY);
  const cv::Matx33d truth = ld::layout::sheetToImage(sc.corners) * ld::detail::moduleToSheet(n);
  const cv::Matx33d off = cv::Matx33d(1, 0, 0.3, 0, 1, -0.24, 0, 0, 1) * truth;
  auto run = [&](ld::detail::QrPixelModelStages stages, double& grid_error) {
    ld::detail::QrPixelModel model(stages);
    std::vector<uint8_t> modules;
    EXPECT_TRUE(model.estimate(gray, off, n, modules));
    const int wrong = ld::test::wrongDataModules(qr, modules).wrong;
    grid_error = 0;  // the worst of the code's corners
    for (auto [x, y] : {std::pair{0, 0}, {n, 0}, {n, n}, {0, n}}) {
      const cv::Vec3d a = model.grid() * cv::Vec3d(x, y, 1), b = truth * cv::Vec3d(x, y, 1);
      grid_error = std::max(grid_error, std::hypot(a[0] / a[2] - b[0] / b[2], a[1] / a[2] - b[1] / b[2]));
    }
    return wrong;
  };
  double aligned_error = 0, unaligned_error = 0;
  ld::detail::QrPixelModelStages none;
  none.align_steps = 0;
  const int aligned = run({}, aligned_error), unaligned = run(none, unaligned_error);
  std::printf("modules wrong: aligned %d (grid %.3f px off), not aligned %d (%.3f px)\n", aligned, aligned_error,
              unaligned, unaligned_error);
  EXPECT_LT(aligned_error, 0.1);
  EXPECT_NEAR(unaligned_error, 0.384, 0.001);
  EXPECT_LT(aligned, 20);
  EXPECT_GT(unaligned, 5 * aligned + 50);
}

// A track's stack holds one landmark: frames of another (a tracker that
// swapped two tracks' ids), a pattern side or more away from where the track
// was in the last frame seen, restart it, so the mean is never a blend of two
// codes; the same landmark moving between frames stays in it.
// Movable, not copyable: a copy shared the stack's buffers, the frames added
// to one changing the other's mean (an API audit); a stack of no frames is
// refused (0 and -3 were taken).
static_assert(!std::is_copy_constructible_v<ld::QrStack> && !std::is_copy_assignable_v<ld::QrStack>);
static_assert(std::is_move_constructible_v<ld::QrStack> && std::is_move_assignable_v<ld::QrStack>);
TEST(QrStack, RefusesNoFrames) {
  for (int n : {0, -3}) {
    try {
      ld::QrStack s(n);
      ADD_FAILURE() << n << " frames taken";
    } catch (const std::invalid_argument& e) {
      EXPECT_EQ(std::string(e.what()), "QrStack: max_frames must be 1 or more, not " + std::to_string(n));
    }
  }
  EXPECT_NO_THROW(ld::QrStack(1));
}

TEST(QrStack, AnotherLandmarkRestartsTheStack) {
  const cv::Mat a = ld::artwork::renderLandmark("room-101/door", 450);
  const cv::Mat b = ld::artwork::renderLandmark("lift-B/floor-2", 450);
  // 120 px sheets, side by side 200 px apart; A also nudged by 0.2 of its side
  const auto at = [](float x, float y) {
    return std::array<cv::Point2f, 4>{{{x, y}, {x + 120, y}, {x + 120, y + 120}, {x, y + 120}}};
  };
  ld::QrReader reader;
  ld::QrStack stack;
  for (float dx : {0.0f, 12.0f, 24.0f}) {
    const Scene sa = warped(a, at(100 + dx, 180));
    ASSERT_TRUE(stack.add(sa.image, sa.corners));
  }
  EXPECT_EQ(stack.frames(), 3);
  const Scene sb = warped(b, at(320, 180));
  ASSERT_TRUE(stack.add(sb.image, sb.corners));
  EXPECT_EQ(stack.frames(), 1);  // restarted on the other landmark
  const auto r = stack.decode(reader);
  ASSERT_TRUE(r.has_value());
  EXPECT_EQ(r->payload, "lift-B/floor-2");

  // A camera turning: the landmark crosses the image by 1.5 sheets between
  // tries, followed in the frames between (ld-qr-reader follows every frame
  // of the track): the stack keeps its frames. A swap seen in a followed
  // frame restarts it.
  ld::QrStack turning;
  for (int k = 0; k < 3; ++k) {
    const float x = 60.0f + 180.0f * k;
    for (float step = -150.0f; step < 0; step += 30.0f) turning.follow(at(x + step, 180));
    const Scene sa = warped(a, at(x, 180));
    ASSERT_TRUE(turning.add(sa.image, sa.corners));
  }
  EXPECT_EQ(turning.frames(), 3);
  EXPECT_TRUE(turning.follow(at(60, 180)));  // the other landmark, a sheet and a half back
  EXPECT_FALSE(turning.follow(at(70, 180)));  // (nothing left to drop)
  const Scene sa = warped(a, at(60, 180));
  ASSERT_TRUE(turning.add(sa.image, sa.corners));
  EXPECT_EQ(turning.frames(), 1);
}

// The stack's vote over frames' pixel-model fits: five fits of a 100-byte
// code, each with its own 8 % of the data modules wrong (frames seen at
// other sub-pixel positions, with their own noise), none of which reads
// alone, read as most of them read each module; two fits are no vote, and
// a restart of the stack (another landmark) drops them.
TEST(QrStack, VotesTheFramesFittedModules) {
  const std::string payload = longPayload(3);
  const ld::artwork::QrCode qr = ld::artwork::encodeQr(payload);
  const int n = qr.size;
  const std::vector<uint8_t> function = ld::test::functionModules(n);
  // the frames the stack averages show no code: its mean reads nothing
  cv::Mat blank = ld::artwork::renderLandmark("x", 900);
  cv::rectangle(blank, cv::Rect(250, 250, 400, 400), cv::Scalar(255, 255, 255), cv::FILLED);
  const Scene frame = warped(blank, {{{170, 90}, {470, 90}, {470, 390}, {170, 390}}});
  ld::QrReader reader;
  ld::QrStack stack;
  cv::RNG rng(11);
  int read_alone = 0, wrong = 0;
  std::optional<ld::QrResult> r;
  for (int f = 0; f < 5; ++f) {
    std::vector<uint8_t> fit = qr.modules;
    for (size_t i = 0; i < fit.size(); ++i)
      if (!function[i] && rng.uniform(0.0, 1.0) < 0.08) fit[i] ^= 1, ++wrong;
    read_alone += reader.decodeModules(n, fit).has_value();
    ASSERT_TRUE(stack.add(frame.image, frame.corners));
    stack.addModules(n, fit);
    r = stack.decode(reader);
    if (f < 2) {
      EXPECT_FALSE(r.has_value()) << f + 1 << " fits";
    }
  }
  std::printf("%d-module code, %d data modules wrong in 5 fits; read alone %d of 5\n", n, wrong, read_alone);
  EXPECT_EQ(read_alone, 0);
  ASSERT_TRUE(r.has_value());
  EXPECT_EQ(r->payload, payload);
  EXPECT_EQ(r->attempt, 9);
  // another landmark a sheet away: the stack and its vote start again
  ASSERT_TRUE(stack.follow({{{600, 90}, {900, 90}, {900, 390}, {600, 390}}}));
  ASSERT_TRUE(stack.add(frame.image, frame.corners));
  EXPECT_FALSE(stack.decode(reader).has_value());
  // a fit of the wrong size for its modules is not taken
  EXPECT_FALSE(reader.decodeModules(n, std::vector<uint8_t>(10, 0)).has_value());

  // Fits that read alone: two are no vote, the third makes one.
  ld::QrStack votes;
  const auto fitted = [&](ld::QrStack& st, const std::vector<uint8_t>& fit) {
    EXPECT_TRUE(st.add(frame.image, frame.corners));
    st.addModules(n, fit);
    return st.decode(reader);
  };
  EXPECT_FALSE(fitted(votes, qr.modules).has_value());
  EXPECT_FALSE(fitted(votes, qr.modules).has_value()) << "two fits";
  auto three = fitted(votes, qr.modules);
  ASSERT_TRUE(three.has_value());
  EXPECT_EQ(three->payload, payload);
  // After a restart (clear(), or a QR of another size in add()), only the
  // new landmark's fits vote: three of another code of the same size.
  const std::string other = longPayload(4);
  const ld::artwork::QrCode qr2 = ld::artwork::encodeQr(other);
  ASSERT_EQ(qr2.size, n);
  for (bool by_size : {false, true}) {
    ld::QrStack st;
    for (int k = 0; k < 5; ++k) fitted(st, qr.modules);
    if (by_size) {
      const Scene smaller = warped(blank, {{{170, 90}, {370, 90}, {370, 290}, {170, 290}}});
      ASSERT_TRUE(st.add(smaller.image, smaller.corners));  // two thirds the size: restarted
      st.addModules(n, qr2.modules);
    } else {
      st.clear();
      fitted(st, qr2.modules);
    }
    EXPECT_FALSE(st.decode(reader).has_value()) << "one fit after the restart, by_size " << by_size;
    // (the next frames as the first after a size change: the same size again restarts nothing)
    const Scene& at = by_size ? warped(blank, {{{170, 90}, {370, 90}, {370, 290}, {170, 290}}}) : frame;
    std::optional<ld::QrResult> after;
    for (int k = 0; k < 2; ++k) {
      ASSERT_TRUE(st.add(at.image, at.corners));
      st.addModules(n, qr2.modules);
      after = st.decode(reader);
    }
    ASSERT_TRUE(after.has_value()) << "by_size " << by_size;
    EXPECT_EQ(after->payload, other) << "by_size " << by_size;
  }
  // A tie goes to the latest fit: two fits with the same 8 % of the data
  // modules wrong and two right, in either order.
  std::vector<uint8_t> bad = qr.modules;
  for (size_t i = 0; i < bad.size(); ++i)
    if (!function[i] && rng.uniform(0.0, 1.0) < 0.08) bad[i] ^= 1;
  ASSERT_FALSE(reader.decodeModules(n, bad).has_value());
  for (bool right_last : {true, false}) {
    ld::QrStack st;
    std::optional<ld::QrResult> tied;
    for (int k = 0; k < 4; ++k) tied = fitted(st, (k < 2) == right_last ? bad : qr.modules);
    EXPECT_EQ(tied.has_value(), right_last) << "the right fits " << (right_last ? "last" : "first");
  }
}

TEST(QrReader, DamagedOrMissingQrGivesNothing) {
  ld::QrReader reader;
  cv::Mat sheet = ld::artwork::renderLandmark("damaged", 900);
  cv::rectangle(sheet, cv::Rect(250, 250, 400, 200), cv::Scalar(255, 255, 255), cv::FILLED);
  Scene sc = warped(sheet, {{{170, 90}, {470, 90}, {470, 390}, {170, 390}}});
  EXPECT_FALSE(reader.decode(sc.image, sc.corners).has_value());

  cv::Mat blank = ld::artwork::renderLandmark("x", 900);
  cv::rectangle(blank, cv::Rect(250, 250, 400, 400), cv::Scalar(255, 255, 255), cv::FILLED);
  sc = warped(blank, {{{170, 90}, {470, 90}, {470, 390}, {170, 390}}});
  EXPECT_FALSE(reader.decode(sc.image, sc.corners).has_value());
}

// Parameters out of their range are refused, named (min_side_px over
// max_side_px broke std::clamp's precondition, INT_MAX sides asked for
// exabytes, a NaN upsample was taken).
TEST(QrReader, ParametersOutOfRangeAreRefused) {
  const auto refused = [](void (*set)(ld::QrReaderParams&), const std::string& says) {
    ld::QrReaderParams bad;
    set(bad);
    try {
      ld::QrReader reader(bad);
      ADD_FAILURE() << "taken: " << says;
    } catch (const std::invalid_argument& e) {
      EXPECT_EQ(std::string(e.what()), "QrReaderParams: " + says);
    }
  };
  refused([](ld::QrReaderParams& q) { q.min_side_px = 600; }, "min_side_px 600 is over max_side_px 480");
  refused([](ld::QrReaderParams& q) { q.max_side_px = 8; }, "max_side_px must be 16 to 4096, not 8");
  refused([](ld::QrReaderParams& q) { q.min_side_px = q.max_side_px = INT_MAX; },
          "min_side_px must be 16 to 4096, not 2147483647");
  refused([](ld::QrReaderParams& q) { q.upsample = std::nan(""); }, "upsample must be 0.25 to 16, not nan");
  refused([](ld::QrReaderParams& q) { q.margin_u = -0.1; }, "margin_u must be 0 to 1, not -0.1");
  ld::QrReaderParams edge;
  edge.min_side_px = edge.max_side_px = 480;
  EXPECT_NO_THROW(ld::QrReader{edge});
}

TEST(QrReader, DegenerateInputDoesNotCrash) {
  ld::QrReader reader;
  const cv::Mat img(480, 640, CV_8UC3, cv::Scalar(200, 200, 200));
  EXPECT_FALSE(reader.decode(img, {{{10, 10}, {10, 10}, {10, 10}, {10, 10}}}).has_value());
  EXPECT_FALSE(reader.decode(img, {{{-1e6f, 0}, {1e6f, 0}, {1e6f, 1e6f}, {0, 1e6f}}}).has_value());
  const float nan = std::numeric_limits<float>::quiet_NaN();
  EXPECT_FALSE(reader.decode(img, {{{nan, 0}, {1, 0}, {1, 1}, {0, 1}}}).has_value());
  EXPECT_FALSE(reader.decode(cv::Mat(), {{{0, 0}, {100, 0}, {100, 100}, {0, 100}}}).has_value());
  const cv::Mat gray(1, 1, CV_8UC1, cv::Scalar(0));
  EXPECT_FALSE(reader.decode(gray, {{{0, 0}, {100, 0}, {100, 100}, {0, 100}}}).has_value());
  // An early return makes no view: lastView() is not the previous call's.
  const cv::Mat sheet = ld::artwork::renderLandmark("view", 900);
  const Scene sc = warped(sheet, {{{170, 90}, {470, 90}, {470, 390}, {170, 390}}});
  ASSERT_TRUE(reader.decode(sc.image, sc.corners).has_value());
  EXPECT_FALSE(reader.lastView().empty());
  EXPECT_FALSE(reader.decode(img, {{{nan, 0}, {1, 0}, {1, 1}, {0, 1}}}).has_value());
  EXPECT_TRUE(reader.lastView().empty());
  // A 16-bit or float image is the caller's mistake, said (it read nothing).
  for (int type : {CV_16UC1, CV_16UC3, CV_32FC3}) {
    try {
      reader.decode(cv::Mat(480, 640, type, cv::Scalar(0)), sc.corners);
      ADD_FAILURE() << "a " << cv::typeToString(type) << " image was taken";
    } catch (const std::invalid_argument& e) {
      EXPECT_EQ(std::string(e.what()), "QrReader::decode: a " + cv::typeToString(type) +
                                           " image: it reads 8-bit BGR, BGRA or gray (CV_8UC3, CV_8UC4, CV_8UC1)");
    }
    // and a stack's frames (a 16-bit one was left out without a word; a
    // two-channel one was stacked, and its decode threw later)
    ld::QrStack stack;
    EXPECT_THROW(stack.add(cv::Mat(480, 640, type, cv::Scalar(0)), sc.corners), std::invalid_argument);
  }
  ld::QrStack stack;
  EXPECT_THROW(stack.add(cv::Mat(480, 640, CV_8UC2, cv::Scalar(0)), sc.corners), std::invalid_argument);
}

// The modules the grid reader redraws ideal are those every code has, in
// every version it reads (1-15): libqrencode's symbols agree module for module.
TEST(QrReader, FunctionPatternsAreThoseOfEveryCode) {
  for (int version = 1; version <= 15; ++version) {
    const std::string payload = "room-" + std::to_string(version);
    QRcode* code = QRcode_encodeData(static_cast<int>(payload.size()),
                                     reinterpret_cast<const unsigned char*>(payload.data()), version, QR_ECLEVEL_M);
    ASSERT_NE(code, nullptr);
    ASSERT_EQ(code->width, 17 + 4 * version);
    const int n = code->width;
    int count = 0, wrong = 0;
    ld::detail::forEachFunctionModule(n, [&](int r, int c, bool dark) {
      ASSERT_TRUE(r >= 0 && c >= 0 && r < n && c < n);
      ++count;
      wrong += ((code->data[r * n + c] & 1) != 0) != dark;
    });
    EXPECT_EQ(wrong, 0) << "version " << version;
    // finders and separators, timing rows, alignment patterns, the dark module
    const int k = version < 2 ? 0 : version / 7 + 2, alignments = version < 2 ? 0 : k * k - 3;
    EXPECT_EQ(count, 3 * 64 + 2 * (n - 16) + 25 * alignments + 1) << "version " << version;
    QRcode_free(code);
  }
}

// ld-qr-reader's frame step: once a frame's decoding budget is spent, the
// tracks left wait, and lead the next frame. An unreadable track listed
// first does not take the budget every frame (it did when the tracks were
// decoded in the list's order).
TEST(QrTrackReader, BudgetSpentGoesToTheTracksLeftNextFrame) {
  const TwoTracks scene;
  const ld::image_t image = ld::matToImage(scene.image, ld::image_t::PIXEL_FORMAT_BGR, 0);
  ld::QrTrackReaderParams params;
  params.decode_budget_ms = 1e-9;  // one decode a frame
  params.stack_frames = 0;
  params.schedule.retry_interval_s = 0.01;
  std::ostringstream log;
  ld::QrTrackReader reader(params, log);
  ld::qr_code_list_t out;
  std::optional<std::string> read;
  for (int f = 0; f < 2 && !read; ++f) {
    const auto list = trackedList(1'000'000 + f * 33'000, f,
                                  {tracked(1, f + 1, scene.damaged), tracked(2, f + 1, scene.readable)});
    reader.process(image, list, out);
    EXPECT_EQ(out.utime, list.utime);
    EXPECT_EQ(out.seq, list.seq);
    EXPECT_FALSE(codeOf(out, 1).has_value());
    read = codeOf(out, 2);
  }
  ASSERT_TRUE(read.has_value()) << "the readable track waited behind the unreadable one";
  EXPECT_EQ(*read, "room-214/door");
  EXPECT_EQ(out.ncodes, 1);
  EXPECT_EQ(reader.tracksRead(), 1);

  // Known now: listed every frame from the book, without being decoded again.
  const auto later = trackedList(1'100'000, 3, {tracked(1, 4, scene.damaged), tracked(2, 4, scene.readable)});
  reader.process(image, later, out);
  ASSERT_EQ(codeOf(out, 2), std::optional<std::string>("room-214/door"));
  EXPECT_LT(out.codes[0].seq, later.seq);  // the frame it was read from
  EXPECT_EQ(out.codes[0].utime, 1'000'000 + out.codes[0].seq * 33'000);
  EXPECT_TRUE(log.str().empty()) << log.str();
}

// The tracker moved the read track's id onto the other landmark (its own
// went away): the payload is not published for it, and it is read again.
TEST(QrTrackReader, ReadTrackThatJumpsLosesItsPayload) {
  const TwoTracks scene;
  const ld::image_t image = ld::matToImage(scene.image, ld::image_t::PIXEL_FORMAT_BGR, 0);
  std::ostringstream log;
  ld::QrTrackReader reader({}, log, true);
  ld::qr_code_list_t out;
  int64_t t = 1'000'000;
  for (int f = 0; f < 3; ++f, t += 33'000) reader.process(image, trackedList(t, f, {tracked(2, f + 1, scene.readable)}), out);
  ASSERT_EQ(codeOf(out, 2), std::optional<std::string>("room-214/door"));
  EXPECT_NE(log.str().find("track 2 reads \"room-214/door\""), std::string::npos) << log.str();
  reader.process(image, trackedList(t, 3, {tracked(2, 4, scene.damaged)}), out);
  EXPECT_FALSE(codeOf(out, 2).has_value());
  EXPECT_EQ(out.ncodes, 0);
  EXPECT_NE(log.str().find("track 2 jumped"), std::string::npos) << log.str();
}

// A code's look (QrLook): the same code in another view is the same, a code
// one character apart at the same place is another, a view too blurred or
// too small says nothing, and input that is no view gives nothing and no crash.
TEST(QrLook, TellsTheSameCodeFromAnotherOneCharacterApart) {
  const std::array<cv::Point2f, 4> front{{{170, 90}, {470, 90}, {470, 390}, {170, 390}}};
  const std::array<cv::Point2f, 4> oblique{{{200, 120}, {400, 80}, {410, 420}, {190, 360}}};
  for (const std::string& p : {std::string("room-101"), longPayload(1)}) {
    const std::string q = p.substr(0, p.size() - 1) + (p.back() == '2' ? '3' : '2');
    const Scene a = warped(ld::artwork::renderLandmark(p, 900), front);
    ld::QrLook look;
    EXPECT_TRUE(look.empty());
    EXPECT_EQ(look.compare(a.image, a.corners), ld::QrLook::Verdict::Unsure);  // (no look yet)
    ASSERT_TRUE(look.capture(a.image, a.corners)) << p;
    EXPECT_EQ(look.modules(), p.size() > 50 ? 37 : 21) << p;
    const Scene same = warped(ld::artwork::renderLandmark(p, 900), oblique);
    EXPECT_EQ(look.compare(same.image, same.corners), ld::QrLook::Verdict::Same) << p;
    const Scene other = warped(ld::artwork::renderLandmark(q, 900), oblique);
    EXPECT_EQ(look.compare(other.image, other.corners), ld::QrLook::Verdict::Other) << q;
    cv::Mat gray;
    cv::cvtColor(other.image, gray, cv::COLOR_BGR2GRAY);  // (any 8-bit image)
    EXPECT_EQ(look.compare(gray, other.corners), ld::QrLook::Verdict::Other) << q;
    cv::Mat blurred;
    cv::GaussianBlur(other.image, blurred, {0, 0}, 4);
    EXPECT_EQ(look.compare(blurred, other.corners), ld::QrLook::Verdict::Unsure) << q;
    // a third of the size: under 1.5 px a module for 37 modules, 2.3 for 21
    std::array<cv::Point2f, 4> small;
    for (size_t i = 0; i < 4; ++i) small[i] = front[i] * (1.0f / 3);
    const Scene far = warped(ld::artwork::renderLandmark(p, 900), small);
    ld::QrLook small_look;
    EXPECT_EQ(small_look.capture(far.image, far.corners), p.size() < 50) << p;
    EXPECT_EQ(look.compare(far.image, far.corners),
              p.size() < 50 ? ld::QrLook::Verdict::Same : ld::QrLook::Verdict::Unsure) << p;
  }
  const Scene a = warped(ld::artwork::renderLandmark("room-101", 900), front);
  ld::QrLook look;
  ASSERT_TRUE(look.capture(a.image, a.corners));
  const float nan = std::nanf("");
  for (const auto& c : {std::array<cv::Point2f, 4>{{{nan, 0}, {100, 0}, {100, 100}, {0, 100}}},
                        std::array<cv::Point2f, 4>{{{50, 50}, {50, 50}, {50, 50}, {50, 50}}},
                        std::array<cv::Point2f, 4>{{{-1e30f, -1e30f}, {1e30f, -1e30f}, {1e30f, 1e30f}, {-1e30f, 1e30f}}}}) {
    ld::QrLook l;
    EXPECT_FALSE(l.capture(a.image, c));
    EXPECT_TRUE(l.empty());
    EXPECT_NE(look.compare(a.image, c), ld::QrLook::Verdict::Other);
  }
  EXPECT_EQ(look.compare(cv::Mat(), a.corners), ld::QrLook::Verdict::Unsure);
  EXPECT_THROW(look.compare(cv::Mat(480, 640, CV_16UC1, cv::Scalar(0)), a.corners), std::invalid_argument);
  EXPECT_THROW(look.capture(cv::Mat(480, 640, CV_32FC3, cv::Scalar(0)), a.corners), std::invalid_argument);
  EXPECT_FALSE(look.capture(cv::Mat(), a.corners));
}

// The tracker kept a read track's id on another landmark at the same place
// (a scene cut; a landmark half the image wide leaving as its neighbour came
// in): the payload read under the id went with it until the next re-read,
// five seconds on. The look at its modules sees another code: the payload is
// forgotten and the track read again in the same frame. The looks come at
// their interval; 0 turns them off.
TEST(QrTrackReader, ReadTrackShowingAnotherCodeIsReadAgain) {
  const std::array<cv::Point2f, 4> sheet{{{170, 90}, {470, 90}, {470, 390}, {170, 390}}};
  const Scene one = warped(ld::artwork::renderLandmark("room-214/door", 900), sheet);
  const Scene two = warped(ld::artwork::renderLandmark("room-215/door", 900), sheet);
  const ld::image_t before = ld::matToImage(one.image, ld::image_t::PIXEL_FORMAT_BGR, 0);
  const ld::image_t after = ld::matToImage(two.image, ld::image_t::PIXEL_FORMAT_BGR, 0);
  const auto& at = one.corners;  // (the pattern's, as the detector gives them)
  for (const double interval : {0.2, 1.0, 0.0}) {
    ld::QrTrackReaderParams params;
    params.look_interval_s = interval;
    std::ostringstream log;
    ld::QrTrackReader reader(params, log, true);
    ld::qr_code_list_t out;
    reader.process(before, trackedList(1'000'000, 0, {tracked(2, 1, at)}), out);
    ASSERT_EQ(codeOf(out, 2), std::optional<std::string>("room-214/door"));
    // the cut, 0.3 s on, and 1.1 s on
    reader.process(after, trackedList(1'300'000, 9, {tracked(2, 10, at)}), out);
    EXPECT_EQ(codeOf(out, 2), std::optional<std::string>(interval == 0.2 ? "room-215/door" : "room-214/door"))
        << interval;
    reader.process(after, trackedList(2'100'000, 33, {tracked(2, 34, at)}), out);
    EXPECT_EQ(codeOf(out, 2), std::optional<std::string>(interval > 0 ? "room-215/door" : "room-214/door"))
        << interval;
    if (interval > 0) {
      EXPECT_EQ(out.codes[0].seq, interval == 0.2 ? 9 : 33);  // read from the frame of the look
      EXPECT_EQ(reader.tracksChanged(), 1);
      EXPECT_EQ(reader.tracksRead(), 2);
      EXPECT_NE(log.str().find("track 2 shows another code than \"room-214/door\""), std::string::npos) << log.str();
    } else {
      EXPECT_EQ(reader.tracksChanged(), 0);
    }
  }
}

// The tracker moved a read track's id to a neighbour less than a size away
// (every landmark shifted at once between two frames, as in a turn with
// frames dropped): short of a jump, the payload stayed on the neighbour
// until the next look, and two tracks published the same payload (a user
// audit: 2 frames; up to the look interval). A track detected more than half
// a jump off its path is looked at in that frame: the other code is seen and
// read at once. Half a jump or less, it waits for its look's time.
TEST(QrTrackReader, ReadTrackOffItsPathIsLookedAtAtOnce) {
  const std::array<cv::Point2f, 4> here{{{40, 90}, {340, 90}, {340, 390}, {40, 390}}};
  for (const float shift : {210.0f, 120.0f}) {  // 0.7 and 0.4 of the sheet's 300 px
    std::array<cv::Point2f, 4> there = here;
    for (auto& c : there) c.x += shift;
    const Scene one = warped(ld::artwork::renderLandmark("room-214/door", 900), here);
    const Scene two = warped(ld::artwork::renderLandmark("room-215/door", 900), there);
    const ld::image_t before = ld::matToImage(one.image, ld::image_t::PIXEL_FORMAT_BGR, 0);
    const ld::image_t after = ld::matToImage(two.image, ld::image_t::PIXEL_FORMAT_BGR, 0);
    std::ostringstream log;
    ld::QrTrackReader reader({}, log, true);
    ld::qr_code_list_t out;
    int64_t t = 1'000'000;
    for (int f = 0; f < 3; ++f, t += 33'000)
      reader.process(before, trackedList(t, f, {tracked(2, f + 1, one.corners)}), out);
    ASSERT_EQ(codeOf(out, 2), std::optional<std::string>("room-214/door"));
    reader.process(after, trackedList(t, 3, {tracked(2, 4, two.corners)}), out);
    EXPECT_EQ(codeOf(out, 2), std::optional<std::string>(shift > 150 ? "room-215/door" : "room-214/door"))
        << shift << "\n" << log.str();
    EXPECT_EQ(log.str().find("jumped"), std::string::npos) << log.str();  // (short of a jump)
  }
}

// A track read from a far frame (1.3 px a module) has no look; once a frame
// shows its modules sharply (the robot came closer), it is read again at
// once and the read takes the look, which then sees a cut at the next look.
// At most kLookReads such re-reads where they fail.
TEST(QrTrackReader, TrackReadFarIsReadAgainNearForItsLook) {
  const std::string p = "salle-107 \xc3\xa9t\xc3\xa9 caf\xc3\xa9", q = "salle-108 \xc3\xa9t\xc3\xa9 caf\xc3\xa9";
  Scene far = warped(ld::artwork::renderLandmark(p, 900), {{{300, 200}, {380, 204}, {378, 282}, {298, 280}}});
  cv::GaussianBlur(far.image, far.image, {0, 0}, 0.4);
  ld::QrLook none;
  ASSERT_FALSE(none.capture(far.image, far.corners));
  const std::array<cv::Point2f, 4> sheet{{{170, 90}, {470, 90}, {470, 390}, {170, 390}}};
  const Scene near = warped(ld::artwork::renderLandmark(p, 900), sheet);
  const Scene other = warped(ld::artwork::renderLandmark(q, 900), sheet);
  std::ostringstream log;
  ld::QrTrackReader reader({}, log, true);
  ld::qr_code_list_t out;
  int64_t t = 1'000'000, seq = 0;
  auto frame = [&](const Scene& sc, int64_t step_us) {
    t += step_us;
    reader.process(ld::matToImage(sc.image, ld::image_t::PIXEL_FORMAT_BGR, 0),
                   trackedList(t, seq, {tracked(5, static_cast<int32_t>(seq + 1), sc.corners)}), out);
    ++seq;
    return codeOf(out, 5);
  };
  ASSERT_EQ(frame(far, 0), std::optional<std::string>(p));
  // (a track without a look is looked at every 5 look intervals, 1 s)
  EXPECT_EQ(frame(near, 1'000'000), std::optional<std::string>(p));  // (a look due: read again, same payload)
  EXPECT_EQ(out.codes[0].seq, 1);  // read again from this frame
  EXPECT_EQ(frame(other, 300'000), std::optional<std::string>(q));  // the look sees the cut
  EXPECT_EQ(reader.tracksChanged(), 1);
  EXPECT_EQ(reader.tracksRead(), 2);
  EXPECT_NE(log.str().find("track 5 shows another code than"), std::string::npos) << log.str();

  // Sharp frames whose code does not read (its data modules scrambled, its
  // function patterns whole): three re-reads for a look, then only the
  // regular re-reads (every 5 s), the payload kept.
  ld::QrTrackReader again({}, log);
  ld::artwork::QrCode code = ld::artwork::encodeQr(p);
  const std::vector<uint8_t> function = ld::test::functionModules(code.size);
  std::mt19937 rng(3);
  for (size_t i = 0; i < code.modules.size(); ++i)
    if (!function[i] && i / code.size != 8 && i % code.size != 8) code.modules[i] = rng() & 1;
  const Scene scrambled = warped(ld::artwork::renderLandmark(code, 900), sheet);
  ASSERT_FALSE(ld::QrReader().decode(scrambled.image, scrambled.corners).has_value());
  ASSERT_TRUE(ld::QrLook().capture(scrambled.image, scrambled.corners));
  t = 1'000'000;
  int tried = 0;
  for (int f = 0; f < 5; ++f, t += 1'000'000) {  // (the regular re-read would come at 6 s)
    again.process(ld::matToImage((f == 0 ? far : scrambled).image, ld::image_t::PIXEL_FORMAT_BGR, 0),
                  trackedList(t, f, {tracked(6, f + 1, (f == 0 ? far : scrambled).corners)}), out);
    ASSERT_EQ(codeOf(out, 6), std::optional<std::string>(p)) << f;
    tried += f > 0 && out.codes[0].decode_ms > 0;
    if (f == 4) {
      EXPECT_EQ(out.codes[0].decode_ms, 0.0f);
    }
  }
  EXPECT_EQ(tried, 3);
}

// Stripes over a read code (a striped sleeve, a barcode sticker) turn its
// modules both ways, strewn, among others: the look sees another code (a
// review), and the code no longer reads. The payload is withheld and the
// track read again at once, and at each look; a look that sees its own code
// publishes it again (no read needed), and the 5th look in a row that sees
// another forgets it (the code under the id cannot be vouched for); read
// again once the stripes are gone.
TEST(QrTrackReader, StripesOverTheCodeWithholdItsPayloadAndForgetItAfterFiveLooks) {
  const std::array<cv::Point2f, 4> sheet{{{170, 90}, {470, 90}, {470, 390}, {170, 390}}};
  const std::string p = "room-214/door";
  const Scene clean = warped(ld::artwork::renderLandmark(p, 900), sheet);
  Scene covered = clean;
  covered.image = clean.image.clone();
  ld::test::paintOnSheet(covered.image, clean.corners, 4.5, 6.5, 4.5, 6.5, [](double u, double) {
    return std::fmod(u, 0.3) < 0.15 ? cv::Vec3b(40, 40, 40) : cv::Vec3b(220, 220, 220);
  });
  ld::QrLook look;
  ASSERT_TRUE(look.capture(clean.image, clean.corners));
  ASSERT_EQ(look.compare(covered.image, covered.corners), ld::QrLook::Verdict::Other);
  ASSERT_FALSE(ld::QrReader().decode(covered.image, covered.corners).has_value());
  std::ostringstream log;
  ld::QrTrackReader reader({}, log, true);
  ld::qr_code_list_t out;
  // frames 0.2 s apart, a look each: 0 read; 1-4 covered; 5 clean (its own
  // code: the count starts again); 6-10 covered (the 5th forgets); 11 clean
  int64_t t = 1'000'000;
  for (int f = 0; f < 12; ++f, t += 200'000) {
    const Scene& sc = f == 0 || f == 5 || f == 11 ? clean : covered;
    reader.process(ld::matToImage(sc.image, ld::image_t::PIXEL_FORMAT_BGR, 0),
                   trackedList(t, f, {tracked(7, f + 1, sc.corners)}), out);
    const bool published = f == 0 || f == 5 || f == 11;
    EXPECT_EQ(codeOf(out, 7), published ? std::optional<std::string>(p) : std::nullopt) << f;
    EXPECT_EQ(reader.book().payload(7) != nullptr, f < 10 || f == 11) << f;  // (withheld, not forgotten)
    // the message says which are withheld (a payload known, not published)
    const bool withheld = !published && f < 10;
    EXPECT_EQ(out.withheld_track_ids, withheld ? std::vector<int64_t>{7} : std::vector<int64_t>{}) << f;
    EXPECT_EQ(out.nwithheld, withheld ? 1 : 0) << f;
  }
  EXPECT_EQ(reader.tracksChanged(), 1);
  EXPECT_EQ(reader.tracksRead(), 2);  // (read again at frame 11)
  EXPECT_NE(log.str().find("track 7 shows another code than \"room-214/door\" in 5 looks in a row and does not read: it is "
                           "forgotten until it reads"),
            std::string::npos)
      << log.str();
}

// A payload with a NUL byte (QR byte mode takes any bytes): LCM's encoder
// ends a string at its NUL while the message's size counts every byte, so
// the codes message encoded short and was never published, for any of its
// tracks. The NUL is sent as U+FFFD; the reader itself keeps the bytes.
TEST(QrTrackReader, PayloadWithANulByteIsPublished) {
  const std::string payload("door\0" "214", 8);
  const std::array<cv::Point2f, 4> at{{{170, 90}, {470, 90}, {470, 390}, {170, 390}}};
  const Scene scene = warped(ld::artwork::renderLandmark(payload, 900), at);
  ld::QrReader plain;
  const auto read = plain.decode(scene.image, scene.corners);
  ASSERT_TRUE(read.has_value());
  ASSERT_EQ(read->payload, payload);
  std::ostringstream log;
  ld::QrTrackReader reader({}, log);
  ld::qr_code_list_t out;
  const ld::image_t image = ld::matToImage(scene.image, ld::image_t::PIXEL_FORMAT_BGR, 0);
  reader.process(image, trackedList(1'000'000, 0, {tracked(3, 1, at)}), out);
  ASSERT_EQ(codeOf(out, 3), std::optional<std::string>("door\xEF\xBF\xBD" "214"));
  lcm::LCM lcm("memq://");
  ASSERT_TRUE(lcm.good());
  ld::MessagePublisher publisher(lcm);
  EXPECT_EQ(publisher.publish("LANDMARK_CODES", out), 0);
  std::vector<uint8_t> bytes(static_cast<size_t>(out.getEncodedSize()));
  ASSERT_EQ(out.encode(bytes.data(), 0, static_cast<int>(bytes.size())), static_cast<int>(bytes.size()));
  ld::qr_code_list_t back;
  std::string why;
  ASSERT_TRUE(ld::decodeMessage(bytes.data(), bytes.size(), back, &why)) << why;
  ASSERT_EQ(back.ncodes, 1);
  EXPECT_EQ(back.codes[0].payload, "door\xEF\xBF\xBD" "214");
  EXPECT_EQ(ld::lcmString(std::string("\0\0", 2)), "\xEF\xBF\xBD\xEF\xBF\xBD");
}

// Tracks whose corners can be no landmark (NaN, collapsed to a point, out
// at 1e30: a publisher other than the tracker) are never due: the three of
// them took the frame's three decodes, every retry interval, and the
// readable track waited. An id listed twice is due once, and read where
// its corners can be read.
TEST(QrTrackReader, UnreadableCornersTakeNoDecode) {
  const TwoTracks scene;
  const ld::image_t image = ld::matToImage(scene.image, ld::image_t::PIXEL_FORMAT_BGR, 0);
  const float nan = std::nanf("");
  ld::QrTrackReaderParams params;
  params.stack_frames = 0;
  std::ostringstream log;
  ld::QrTrackReader reader(params, log);
  ld::qr_code_list_t out;
  const std::array<cv::Point2f, 4> point{{{50, 50}, {50, 50}, {50, 50}, {50, 50}}};
  const std::array<cv::Point2f, 4> huge{{{-1e30f, -1e30f}, {1e30f, -1e30f}, {1e30f, 1e30f}, {-1e30f, 1e30f}}};
  const std::array<cv::Point2f, 4> nans{{{nan, 0}, {100, 0}, {100, 100}, {0, 100}}};
  reader.process(image,
                 trackedList(1'000'000, 0,
                             {tracked(1, 1, nans), tracked(2, 1, point), tracked(3, 1, huge), tracked(3, 1, huge),
                              tracked(4, 1, point), tracked(4, 1, scene.readable)}),
                 out);
  EXPECT_EQ(codeOf(out, 4), std::optional<std::string>("room-214/door"));
  EXPECT_EQ(reader.book().size(), 1u);  // (the others never scheduled)
}

// The image's pixels are needed only for a due track; when they cannot be
// converted the frame is refused whole, and the reader goes on.
TEST(QrTrackReader, BadImageOnlyWhenATrackIsDue) {
  const TwoTracks scene;
  ld::image_t bad = ld::matToImage(scene.image, ld::image_t::PIXEL_FORMAT_BGR, 0);
  bad.size -= 7;
  bad.data.resize(static_cast<size_t>(bad.size));
  std::ostringstream log;
  ld::QrTrackReader reader({}, log);
  ld::qr_code_list_t out;
  out.ncodes = 5;
  EXPECT_THROW(reader.process(bad, trackedList(1'000'000, 0, {tracked(2, 1, scene.readable)}), out),
               ld::ImageFormatError);
  EXPECT_EQ(out.ncodes, 5);  // untouched
  EXPECT_NO_THROW(reader.process(bad, trackedList(1'033'000, 1, {}), out));
  EXPECT_EQ(out.ncodes, 0);
  const ld::image_t good = ld::matToImage(scene.image, ld::image_t::PIXEL_FORMAT_BGR, 0);
  reader.process(good, trackedList(1'066'000, 2, {tracked(2, 3, scene.readable)}), out);
  EXPECT_EQ(codeOf(out, 2), std::optional<std::string>("room-214/door"));
}
