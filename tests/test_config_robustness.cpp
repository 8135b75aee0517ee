// The configuration readers on the malformed files tests/fuzz found (kept as
// corpus entries regress-*): each is refused with one line naming the file
// and the problem, and a camera that loads never makes the detector report
// a non-finite position.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <fstream>
#include <sstream>

#include "ld/camera.hpp"
#include "ld/detector.hpp"
#include "fuzz/synth_frame.hpp"
#include "ld/tracker.hpp"

namespace {

const std::string kCorpus = std::string(LD_SOURCE_DIR) + "/tests/fuzz/corpus/";

std::string loadError(const std::string& file) {
  try {
    ld::CameraModel::load(kCorpus + "fuzz_camera/" + file);
  } catch (const std::runtime_error& e) {
    return e.what();
  }
  return "";
}

std::string writeTemp(const std::string& name, const std::string& text) {
  const std::string path = ::testing::TempDir() + name;
  std::ofstream(path, std::ios::binary) << text;
  return path;
}

TEST(CameraFile, MalformedFilesFoundByFuzzingAreRefusedWithAReason) {
  EXPECT_EQ(loadError("vga.yml"), "");
  EXPECT_EQ(loadError("wide8.xml"), "");
  // cols: a huge number (as libFuzzer mutated it, not even an integer);
  // OpenCV allocated rows x cols before reading
  EXPECT_NE(loadError("regress-huge-cols.xml").find("camera_matrix has no integer rows and cols"),
            std::string::npos);
  // no "dt": OpenCV's reader threw std::length_error, not cv::Exception
  EXPECT_NE(loadError("regress-no-dt.yml").find("camera file "), std::string::npos);
  // a NUL byte in an XML attribute: OpenCV 4.6's parser dereferenced a null pointer
  EXPECT_NE(loadError("regress-nul-in-xml-attribute.xml").find("NUL byte"), std::string::npos);
  // "<?xml version=" and nothing after it: OpenCV 4.6's XML parser dereferenced a null pointer
  EXPECT_NE(loadError("regress-xml-attribute-at-eof.xml").find("XML attribute without a quoted value"),
            std::string::npos)
      << loadError("regress-xml-attribute-at-eof.xml");
  // "---" with text after it, another "---" later: OpenCV 4.6's YAML parser loops forever
  EXPECT_NE(loadError("regress-yaml-hang.yml").find("line 2: \"---\" must stand on a line of its own"),
            std::string::npos)
      << loadError("regress-yaml-hang.yml");
  // cx = 6.4e8
  EXPECT_NE(loadError("regress-far-principal-point.yml").find("principal point"), std::string::npos);
}

TEST(CameraFile, NonFiniteAndNonCameraMatricesAreRefused) {
  const std::string head = "%YAML:1.0\n---\nimage_width: 640\nimage_height: 480\n"
                           "camera_matrix: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n";
  auto load = [&](const std::string& data) {
    try {
      ld::CameraModel::load(writeTemp("cam.yml", head + "   data: [ " + data + " ]\n"));
    } catch (const std::runtime_error& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  EXPECT_EQ(load("600., 0., 319.5, 0., 600., 239.5, 0., 0., 1."), "");
  EXPECT_NE(load("600., 0., .Inf, 0., 600., 239.5, 0., 0., 1.").find("not finite"), std::string::npos);
  EXPECT_NE(load("600., 0., 319.5, 0., 600., 239.5, 0., 1., 1.").find("of the form"), std::string::npos);
  // a skew, which OpenCV's model (and so the pose) leaves out: refused; a
  // trace of one, as a calibration's rounding leaves, is not
  EXPECT_NE(load("600., 5000., 319.5, 0., 600., 239.5, 0., 0., 1.").find("camera_matrix has a skew of 5000 px"),
            std::string::npos);
  EXPECT_EQ(load("600., 1e-9, 319.5, 0., 600., 239.5, 0., 0., 1."), "");
  std::string huge = head;
  huge.replace(huge.find("cols: 3"), 7, "cols: 2147483647");
  try {
    ld::CameraModel::load(writeTemp("cam.yml", huge + "   data: [ 1. ]\n"));
    FAIL() << "loaded";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("3x2147483647, more than 9 values"), std::string::npos)
        << e.what();
  }
}

// A matrix written as a list or a number is refused naming the key and
// what a matrix is (OpenCV's reader said only "malformed (isMap())").
TEST(CameraFile, AMatrixThatIsAListOrANumberIsNamed) {
  const auto load = [](const std::string& text) {
    try {
      ld::CameraModel::load(writeTemp("flat.yml", "%YAML:1.0\n---\nimage_width: 640\nimage_height: 480\n" + text));
    } catch (const std::runtime_error& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  const std::string matrix = "(rows, cols and data, as OpenCV's calibration writes it)";
  EXPECT_NE(load("camera_matrix: [600, 0, 320, 0, 600, 240, 0, 0, 1]\n")
                .find("camera_matrix is a list, not a matrix " + matrix),
            std::string::npos);
  EXPECT_NE(load("camera_matrix: 5\n").find("camera_matrix is a number, not a matrix"), std::string::npos);
  EXPECT_NE(load("camera_matrix: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n"
                 "   data: [600., 0., 319.5, 0., 600., 239.5, 0., 0., 1.]\ndistortion_coefficients: [0.1, 0, 0, 0]\n")
                .find("distortion_coefficients is a list, not a matrix"),
            std::string::npos);
}

// Values no camera has are refused by name, where they loaded before and
// took poses (or landmarks) away without a word; real lenses' calibrations,
// strong wide-angle barrel distortion included, load.
TEST(CameraFile, ValuesNoCameraHasAreRefused) {
  const auto file = [](const std::string& size, double f, const std::string& dist) {
    std::ostringstream focal;
    focal << f;  // (1e-300 as written)
    return size +
           "camera_matrix: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n   data: [ " + focal.str() +
           ", 0., 319.5, 0., " + focal.str() + ", 239.5, 0., 0., 1. ]\n" +
           "distortion_coefficients: !!opencv-matrix\n   rows: 1\n   cols: 5\n   dt: d\n   data: [ " + dist + " ]\n";
  };
  const std::string vga = "%YAML:1.0\n---\nimage_width: 640\nimage_height: 480\n";
  auto load = [&](const std::string& text) {
    try {
      ld::CameraModel::load(writeTemp("cam.yml", text));
    } catch (const std::runtime_error& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  // lenses: a webcam's, a strong wide-angle's (its polynomial folds near the
  // corners, beyond the calibration's targets), a fisheye-like one's
  EXPECT_EQ(load(file(vga, 600, "0.1, -0.2, 0., 0., 0.1")), "");
  EXPECT_EQ(load(file(vga, 400, "-0.35, 0.15, 0., 0., -0.03")), "");
  EXPECT_EQ(load(file(vga, 250, "-0.3, 0.09, 0., 0., -0.012")), "");
  // an editor's byte order mark is no part of the first key
  EXPECT_EQ(load("\xEF\xBB\xBF" + file(vga, 600, "0., 0., 0., 0., 0.")), "");
  // coefficients mistyped: they fold the image over or squeeze it
  for (const char* dist : {"1e6, 0., 0., 0., 0.", "0., 0., 5., 5., 0.", "0., 0., 0., 0., 1e12"})
    EXPECT_NE(load(file(vga, 600, dist)).find("coefficients mistyped, or of another camera"), std::string::npos)
        << dist << ": " << load(file(vga, 600, dist));
  EXPECT_NE(load(file(vga, 1e-300, "0., 0., 0., 0., 0.")).find("focal length 1e-300 px is not one a 640x480 camera has"),
            std::string::npos);
  EXPECT_NE(load(file(vga, 1e300, "0., 0., 0., 0., 0.")).find("is not one a 640x480 camera has (12.8 to 640000 px)"),
            std::string::npos);
  // the image size: whole pixels, as written (a quoted "640" was read as
  // 2147483647; 1e10 and -640 were "missing"; 4294967936 wrapped to 640)
  const std::string zero = "0., 0., 0., 0., 0.";
  EXPECT_NE(load(file("image_width: \"640\"\nimage_height: 480\n", 600, zero))
                .find("image_width must be a whole number of pixels, 1 to 16384"),
            std::string::npos);
  EXPECT_NE(load(file("image_width: 1e10\nimage_height: 480\n", 600, zero)).find("image_width must be a whole number"),
            std::string::npos);
  // one without the other: said missing (it was "must be a whole number")
  EXPECT_NE(load(file("image_height: 480\n", 600, zero)).find("image_width is missing (image_width and image_height go together)"),
            std::string::npos);
  EXPECT_NE(load(file("image_width: 640\nimage_height: -480\n", 600, zero)).find("image_height must be a whole number"),
            std::string::npos);
  EXPECT_NE(load(file("image_width: 4294967936\nimage_height: 480\n", 600, zero))
                .find("line 1: the integer 4294967936 is out of range (-2147483648 to 2147483647)"),
            std::string::npos)
      << load(file("image_width: 4294967936\nimage_height: 480\n", 600, zero));
  // a leading 0: OpenCV reads octal, so 0640 was 416 px
  EXPECT_NE(load(file("image_width: 0640\nimage_height: 480\n", 600, zero))
                .find("line 1: the integer 0640 has a leading 0, and OpenCV reads it as octal (416): write it without"),
            std::string::npos)
      << load(file("image_width: 0640\nimage_height: 480\n", 600, zero));
  // under keys it does not read, a long number is no matter (a camera's serial)
  EXPECT_EQ(load("camera_name: 4103284471\nserial: 12345678901 # lot\n" + file(vga.substr(14), 600, zero).substr(0) ), "")
      << load("camera_name: 4103284471\nserial: 12345678901 # lot\n" + file(vga.substr(14), 600, zero));
  // a camera_matrix of OpenCV's kind with too few values: counted, not OpenCV's assertion
  std::string short_k = file(vga, 600, zero);
  short_k.replace(short_k.find(", 0., 0., 1. ]"), 14, " ]");
  EXPECT_NE(load(short_k).find("camera_matrix has 6 values, not 3x3"), std::string::npos) << load(short_k);
}

// A user's existing calibration loads whichever tool wrote it: ROS's
// camera_calibration (camera_info YAML: plain YAML, matrices as rows, cols
// and data without OpenCV's type) and OpenCV's interactive calibration app
// (cameraMatrix, dist_coeffs, cameraResolution), as well as OpenCV's
// calibration sample (the tests above).
TEST(CameraFile, RosAndInteractiveCalibrationFilesLoad) {
  const std::string ros =
      "image_width: 640\n"
      "image_height: 480\n"
      "camera_name: head_camera\n"
      "camera_matrix:\n"
      "  rows: 3\n"
      "  cols: 3\n"
      "  data: [438.783367, 0.000000, 305.593336, 0.000000, 437.302876, 243.738352, 0.000000, 0.000000, 1.000000]\n"
      "distortion_model: plumb_bob\n"
      "distortion_coefficients:\n"
      "  rows: 1\n"
      "  cols: 5\n"
      "  data: [-0.361976, 0.110510, 0.001014, 0.000505, 0.000000]\n"
      "rectification_matrix:\n"
      "  rows: 3\n"
      "  cols: 3\n"
      "  data: [1, 0, 0, 0, 1, 0, 0, 0, 1]\n"
      "projection_matrix:\n"
      "  rows: 3\n"
      "  cols: 4\n"
      "  data: [300.0, 0, 306.0, 0, 0, 380.0, 241.0, 0, 0, 0, 1, 0]\n";
  const ld::CameraModel r = ld::CameraModel::load(writeTemp("ost.yaml", ros));
  EXPECT_EQ(r.size, cv::Size(640, 480));
  EXPECT_DOUBLE_EQ(r.K(0, 0), 438.783367);
  EXPECT_DOUBLE_EQ(r.K(1, 2), 243.738352);
  ASSERT_EQ(r.dist.total(), 5u);
  EXPECT_DOUBLE_EQ(r.dist.at<double>(0), -0.361976);
  EXPECT_DOUBLE_EQ(r.dist.at<double>(3), 0.000505);

  // A rectified camera: no coefficients at all.
  std::string rectified = ros;
  rectified.replace(rectified.find("  cols: 5\n  data: [-0.361976, 0.110510, 0.001014, 0.000505, 0.000000]"),
                    std::string("  cols: 5\n  data: [-0.361976, 0.110510, 0.001014, 0.000505, 0.000000]").size(),
                    "  cols: 0\n  data: []");
  EXPECT_TRUE(ld::CameraModel::load(writeTemp("rect.yaml", rectified)).dist.empty());

  auto loadError = [](const std::string& text) {
    try {
      ld::CameraModel::load(writeTemp("bad.yaml", text));
    } catch (const std::runtime_error& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  std::string fisheye = ros;
  fisheye.replace(fisheye.find("plumb_bob"), 9, "equidistant");
  EXPECT_NE(loadError(fisheye).find("distortion_model equidistant is not supported"), std::string::npos)
      << loadError(fisheye);
  std::string short_data = ros;
  short_data.replace(short_data.find(", 0.000000, 0.000000, 1.000000]"), 31, "]");
  EXPECT_NE(loadError(short_data).find("camera_matrix has 6 values, not 3x3"), std::string::npos)
      << loadError(short_data);
  std::string text_value = ros;
  text_value.replace(text_value.find("438.783367"), 10, "fx");
  EXPECT_NE(loadError(text_value).find("camera_matrix has a value that is not a number"), std::string::npos)
      << loadError(text_value);

  // What opencv_interactive-calibration writes (its saveCurrentCameraParameters keys).
  for (const char* ext : {"xml", "yml"}) {
    const std::string path = ::testing::TempDir() + "cameraParameters." + ext;
    {
      cv::FileStorage fs(path, cv::FileStorage::WRITE);
      fs << "calibrationDate" << "Wed Dec  2 03:00:00 2026";
      fs << "framesCount" << 20;
      fs << "cameraResolution" << cv::Size(1280, 720);
      fs << "cameraMatrix" << cv::Mat(cv::Matx33d(910, 0, 640.5, 0, 905, 361.25, 0, 0, 1));
      fs << "cameraMatrix_std_dev" << cv::Mat(cv::Matx41d(1, 1, 0.5, 0.5));
      fs << "dist_coeffs" << cv::Mat(cv::Matx<double, 1, 5>(0.1, -0.2, 0, 0, 0.05));
      fs << "avg_reprojection_error" << 0.31;
    }
    const ld::CameraModel c = ld::CameraModel::load(path);
    EXPECT_EQ(c.size, cv::Size(1280, 720)) << ext;
    EXPECT_DOUBLE_EQ(c.K(0, 0), 910) << ext;
    EXPECT_DOUBLE_EQ(c.K(1, 2), 361.25) << ext;
    ASSERT_EQ(c.dist.total(), 5u) << ext;
    EXPECT_DOUBLE_EQ(c.dist.at<double>(1), -0.2) << ext;
  }
}

// p2 = 20 (tangential distortion): the distortion model does not invert
// over the frame; the detector used to report NaN corners. Such a file is
// refused on loading now; a camera given in code is still no danger.
TEST(CameraFile, DivergingDistortionGivesNoNonFiniteLandmark) {
  EXPECT_NE(loadError("regress-tangential-20.yml").find("coefficients mistyped, or of another camera"),
            std::string::npos)
      << loadError("regress-tangential-20.yml");
  ld::CameraModel cam = ld::CameraModel::pinhole({640, 480}, 600);
  cam.dist = (cv::Mat_<double>(1, 5) << 0, 0, 0, 20, 0);
  const cv::Mat& frame = ld::fuzz::landmarkFrame();
  ld::Detector plain;
  ASSERT_EQ(plain.detect(frame).landmarks.size(), 1u);  // the frame has a landmark
  ld::Detector detector;
  detector.setCamera(cam, 0.15);
  for (const auto& lm : detector.detect(frame).landmarks)
    for (const auto& c : lm.corners) EXPECT_TRUE(std::isfinite(c.x) && std::isfinite(c.y));
}

TEST(ParamsFile, DashesInCommentsAreFine) {
  const std::string path =
      writeTemp("t.yml", "# ---- tracker ----\nmax_distance: 3  # --- wider ---\n");
  EXPECT_EQ(ld::TrackerParams::load(path).max_distance, 3);
}

TEST(ParamsFile, BinaryFilesAreRefusedBeforeOpenCvParsesThem) {
  const std::string path = writeTemp("p.yml", std::string("%YAML:1.0\nmax_distance: 3\0\n", 28));
  try {
    ld::TrackerParams::load(path);
    FAIL() << "loaded";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("NUL byte at offset 25"), std::string::npos) << e.what();
  }
  try {
    ld::DetectorParams::load(path);
    FAIL() << "loaded";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("detector params " + path + ": contains a NUL byte"),
              std::string::npos)
        << e.what();
  }
}

ld::Landmark squareAt(float x, float y) {
  ld::Landmark lm;
  lm.fip_tl = {x, y};
  lm.fip_tr = {x + 20, y};
  lm.fip_bl = {x, y + 20};
  lm.ap = {x + 20, y + 20};
  lm.corners = {{{x - 5, y - 5}, {x + 25, y - 5}, {x + 25, y + 25}, {x - 5, y + 25}}};
  return lm;
}

// Found by tests/fuzz/fuzz_messages: utimes come from the bus, and the
// difference of two of them overflowed int64_t (undefined behaviour).
TEST(TrackerTimes, AnyTwoUtimesWork) {
  ld::TrackerParams p;
  p.max_lifetime_s = 1e300;  // "forever" (used to overflow the lifetime in microseconds)
  ld::Tracker tracker(p);
  tracker.update({squareAt(50, 50)}, 0);
  const auto& tracks = tracker.update({}, 8000000000000000000);
  ASSERT_EQ(tracks.size(), 1u);  // still coasting: its lifetime is not over
  EXPECT_FALSE(tracks[0].visible);
  EXPECT_EQ(tracks[0].time_since_seen_us, 8000000000000000000);
  // more than INT64_MAX microseconds apart: the track ends, nothing overflows
  ld::Tracker extremes(p);
  extremes.update({squareAt(50, 50)}, INT64_MIN + 5);
  EXPECT_TRUE(extremes.update({}, INT64_MAX).empty());
  ASSERT_EQ(extremes.update({squareAt(50, 50)}, INT64_MAX).size(), 1u);
}

}  // namespace
