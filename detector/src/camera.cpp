#include "ld/camera.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <limits>
#include <stdexcept>
#include <tuple>
#include <vector>

#include <opencv2/calib3d.hpp>

#include "ld/config_file.hpp"

namespace ld {
namespace {

// Reads a matrix of at most max_elements values. OpenCV allocates the
// declared rows x cols before it reads the data, so the declared size is
// checked first: a file saying cols: 2147483647 would otherwise ask for tens
// of gigabytes (found by tests/fuzz/fuzz_camera).
cv::Mat readMatrix(const cv::FileNode& node, int max_elements, const std::string& path,
                   const char* name) {
  if (node.empty()) return {};
  // (a list or a number: OpenCV's reader said only "malformed (isMap())")
  if (!node.isMap())
    throw std::runtime_error("camera file " + path + ": " + name + " is " +
                             (node.isSeq() ? "a list" : node.isString() ? "a text" : "a number") +
                             ", not a matrix (rows, cols and data, as OpenCV's calibration writes it)");
  {
    const cv::FileNode rows = node["rows"], cols = node["cols"];
    if (!rows.isInt() || !cols.isInt())
      throw std::runtime_error("camera file " + path + ": " + name + " has no integer rows and cols");
    const int r = static_cast<int>(rows), c = static_cast<int>(cols);
    if (r < 0 || c < 0 || static_cast<int64_t>(r) * c > max_elements)
      throw std::runtime_error("camera file " + path + ": " + name + " is " + std::to_string(r) +
                               "x" + std::to_string(c) + ", more than " +
                               std::to_string(max_elements) + " values");
    const cv::FileNode data = node["data"];
    if (!data.isSeq())
      throw std::runtime_error("camera file " + path + ": " + name + " has no data list");
    if (static_cast<int64_t>(data.size()) != static_cast<int64_t>(r) * c)
      throw std::runtime_error("camera file " + path + ": " + name + " has " + std::to_string(data.size()) +
                               " values, not " + std::to_string(r) + "x" + std::to_string(c));
    if (node["dt"].empty()) {
      // ROS camera_info (camera_calibration's files): rows, cols and data,
      // without OpenCV's element type.
      if (r * c == 0) return {};
      cv::Mat m(r, c, CV_64F);
      int i = 0;
      for (const cv::FileNode& v : data) {
        if (!v.isReal() && !v.isInt())
          throw std::runtime_error("camera file " + path + ": " + name + " has a value that is not a number");
        m.at<double>(i++) = static_cast<double>(v);
      }
      return m;
    }
  }
  cv::Mat m;
  node >> m;
  return m;
}

// The first of `names` the file has (calibration tools name the same thing
// differently), and which one it was.
cv::FileNode firstOf(const cv::FileStorage& fs, std::initializer_list<const char*> names, const char*& found) {
  for (const char* n : names) {
    const cv::FileNode node = fs[n];
    if (!node.empty()) {
      found = n;
      return node;
    }
  }
  found = *names.begin();
  return {};
}

}  // namespace

CameraModel CameraModel::defaultVga() { return pinhole({640, 480}, 600.0); }

CameraModel CameraModel::pinhole(cv::Size size, double focal_px) {
  if (!(focal_px > 0) || !std::isfinite(focal_px))
    throw std::invalid_argument("CameraModel::pinhole: the focal length must be a finite number of pixels > 0");
  if (size.width < 0 || size.height < 0 || size.width > kMaxImageSide || size.height > kMaxImageSide)
    throw std::invalid_argument("CameraModel::pinhole: the image size must be 0 to " + std::to_string(kMaxImageSide) +
                                " px a side");
  CameraModel c;
  c.size = size;
  c.K = cv::Matx33d(focal_px, 0, (size.width - 1) / 2.0, 0, focal_px, (size.height - 1) / 2.0,
                    0, 0, 1);
  return c;
}

CameraModel CameraModel::load(const std::string& path) {
  // (integers beyond 32 bits refused where this reads numbers, not under
  // other keys: a camera's serial number, say)
  const cv::FileStorage fs = openConfigFile(path, "camera file", [](const std::string& key) {
    for (const char* k : {"image_width", "image_height", "cameraResolution", "camera_matrix", "cameraMatrix",
                          "distortion_coefficients", "dist_coeffs", "rows", "cols", "data", "dt"})
      if (key == k) return true;
    return false;
  });
  CameraModel c;
  try {
    // OpenCV's calibration sample and ROS camera_info: camera_matrix,
    // distortion_coefficients, image_width, image_height; OpenCV's
    // interactive calibration app: cameraMatrix, dist_coeffs,
    // cameraResolution [w, h].
    const char* k_name = nullptr;
    const cv::FileNode k_node = firstOf(fs, {"camera_matrix", "cameraMatrix"}, k_name);
    cv::Mat K = readMatrix(k_node, 9, path, k_name);
    if (K.empty()) throw std::runtime_error("camera file " + path + ": no camera_matrix (or cameraMatrix)");
    if (K.rows != 3 || K.cols != 3)
      throw std::runtime_error("camera file " + path + ": " + k_name + " is not 3x3");
    K.convertTo(K, CV_64F);
    c.K = cv::Matx33d(K);
    if (!cv::checkRange(K))
      throw std::runtime_error("camera file " + path + ": " + k_name + " has a value that is not finite");
    if (!(c.K(0, 0) > 0) || !(c.K(1, 1) > 0))
      throw std::runtime_error("camera file " + path + ": focal lengths must be positive");
    // ROS names its distortion model; only OpenCV's (plumb_bob, rational_polynomial) is this one.
    const cv::FileNode model = fs["distortion_model"];
    if (!model.empty()) {
      const std::string m = model.isString() ? configString(model) : std::string("that is not a name");
      if (m != "plumb_bob" && m != "rational_polynomial")
        throw std::runtime_error("camera file " + path + ": distortion_model " + m +
                                 " is not supported (plumb_bob or rational_polynomial: OpenCV's pinhole model)");
    }
    const char* d_name = nullptr;
    const cv::FileNode d_node = firstOf(fs, {"distortion_coefficients", "dist_coeffs"}, d_name);
    c.dist = readMatrix(d_node, 14, path, d_name);
    if (!c.dist.empty()) {
      c.dist.convertTo(c.dist, CV_64F);
      c.dist = c.dist.reshape(1, 1);
      const int n = c.dist.cols;
      if (n != 4 && n != 5 && n != 8 && n != 12 && n != 14)
        throw std::runtime_error("camera file " + path + ": " + d_name + " must have 4, 5, 8, 12 or 14 values");
      if (!cv::checkRange(c.dist))
        throw std::runtime_error("camera file " + path + ": " + d_name + " has a value that is not finite");
    }
    // The image size: whole pixels, as the frames' (a quoted "640" read as
    // 2147483647, and 1e10 or -640 as missing, before)
    const auto side = [&](const cv::FileNode& n, const std::string& key) {
      if (n.empty())  // (one of the two given without the other)
        throw std::runtime_error("camera file " + path + ": " + key + " is missing (image_width and image_height "
                                 "go together)");
      const double v = n.isInt() ? static_cast<double>(static_cast<int>(n)) : n.isReal() ? static_cast<double>(n) : -1;
      if (!(v >= 1 && v <= kMaxImageSide) || v != std::floor(v))  // (640.0 is 640)
        throw std::runtime_error("camera file " + path + ": " + key + " must be a whole number of pixels, 1 to " +
                                 std::to_string(kMaxImageSide));
      return static_cast<int>(v);
    };
    int w = 0, h = 0;
    const cv::FileNode res = fs["cameraResolution"];
    if (!fs["image_width"].empty() || !fs["image_height"].empty()) {
      w = side(fs["image_width"], "image_width");
      h = side(fs["image_height"], "image_height");
    } else if (!res.empty()) {
      if (!res.isSeq() || res.size() != 2)
        throw std::runtime_error("camera file " + path + ": cameraResolution must be [width, height]");
      w = side(res[0], "cameraResolution's width");
      h = side(res[1], "cameraResolution's height");
    } else {
      throw std::runtime_error("camera file " + path + ": image_width/image_height (or cameraResolution) missing");
    }
    c.size = {w, h};
    // a camera matrix: [fx s cx; 0 fy cy; 0 0 1], its principal point in the image
    if (c.K(1, 0) != 0 || c.K(2, 0) != 0 || c.K(2, 1) != 0 || c.K(2, 2) != 1)
      throw std::runtime_error("camera file " + path + ": " + k_name + " is not of the form [fx s cx; 0 fy cy; 0 0 1]");
    // (OpenCV's undistortion and solvePnP read fx, fy, cx and cy alone: a
    // skew was taken and left out of every pose without a word)
    if (std::abs(c.K(0, 1)) > 1e-3 * c.K(0, 0)) {
      char text[200];
      std::snprintf(text, sizeof text, "%s has a skew of %g px: OpenCV's camera model, which the pose uses, has "
                    "none (its calibration writes 0)", k_name, c.K(0, 1));
      throw std::runtime_error("camera file " + path + ": " + text);
    }
    if (!(c.K(0, 2) >= -1 && c.K(0, 2) <= w) || !(c.K(1, 2) >= -1 && c.K(1, 2) <= h))
      throw std::runtime_error("camera file " + path + ": principal point (" +
                               std::to_string(c.K(0, 2)) + ", " + std::to_string(c.K(1, 2)) +
                               ") is outside the " + std::to_string(w) + "x" + std::to_string(h) +
                               " image");
    // Focal lengths a lens can have for this image: from a fisheye's (a
    // fiftieth of the image's side) to a long telephoto's (a thousand sides).
    const double longest = std::max(w, h);
    for (const double f : {c.K(0, 0), c.K(1, 1)})
      if (f < 0.02 * longest || f > 1000 * longest) {
        char text[160];
        std::snprintf(text, sizeof text, "focal length %g px is not one a %dx%d camera has (%g to %g px)", f, w, h,
                      0.02 * longest, 1000 * longest);
        throw std::runtime_error("camera file " + path + ": " + text);
      }
    if (const std::string why = c.distortionProblem(); !why.empty())
      throw std::runtime_error("camera file " + path + ": " + d_name + ": " + why);
  } catch (const cv::Exception& e) {
    throw std::runtime_error("camera file " + path + ": malformed (" + e.err + ")");
  } catch (const std::runtime_error&) {
    throw;
  } catch (const std::exception& e) {
    throw std::runtime_error("camera file " + path + ": malformed (" + e.what() + ")");
  }
  return c;
}

std::string CameraModel::distortionProblem() const {
  if (dist.empty() || cv::countNonZero(dist) == 0 || size.width <= 0 || size.height <= 0) return "";
  // Along rays from the optical axis in 32 directions, ideal (undistorted)
  // points are distorted into the image until they are half-way from its
  // centre to its corners. Any lens's model carries them outward there
  // without turning back, and puts that half-way point between a quarter
  // and twice as far from the centre as the ray would be without distortion
  // (a strong wide-angle lens: about 0.9; a fisheye's half-way point 67
  // degrees off the axis: 0.5). Coefficients mistyped, or of another camera,
  // fold the image over or stretch it, or squeeze it into a sliver of the
  // view. (Nearer the corners
  // a real calibration's polynomial may fold where no calibration target
  // was: no test there. Nor is taking the image's points back with
  // cv::undistortPoints and out again one: its fixed-point iteration does
  // not converge for a wide-angle lens's strong barrel distortion.)
  const cv::Point2d c(K(0, 2), K(1, 2));
  const double f = std::sqrt(K(0, 0) * K(1, 1));
  const double half_way = 0.25 * std::hypot(size.width, size.height);
  constexpr int kDirections = 32, kSteps = 4000;
  constexpr double kStep = 0.005, kMinFactor = 0.25, kMaxFactor = 2;  // (ideal radius up to 20 focal lengths)
  std::vector<cv::Point3d> ray(kSteps);
  std::vector<cv::Point2d> img;
  char text[240];
  for (int d = 0; d < kDirections; ++d) {
    const double a = 2 * CV_PI * d / kDirections;
    for (int i = 0; i < kSteps; ++i) ray[i] = {(i + 1) * kStep * std::cos(a), (i + 1) * kStep * std::sin(a), 1.0};
    cv::projectPoints(ray, cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0), cv::Mat(K), dist, img);
    double last = 0, ideal = 0;
    int i = 0;
    for (; i < kSteps; ++i) {
      const double r = std::isfinite(img[i].x) && std::isfinite(img[i].y) ? cv::norm(img[i] - c)
                                                                          : std::numeric_limits<double>::infinity();
      if (r < last - 1e-6) {
        std::snprintf(text, sizeof text,
                      "the distortion folds the %dx%d image over near its centre (towards (%.0f, %.0f) it turns "
                      "back %.0f px from it): coefficients mistyped, or of another camera",
                      size.width, size.height, img[i].x, img[i].y, r);
        return text;
      }
      if (r >= half_way) {
        // where the ray reaches half-way (between this step and the last),
        // against where it would without distortion
        const double t = (half_way - last) / (r - last);
        ideal = (i + t) * kStep * f;
        break;
      }
      last = r;
    }
    const double factor = half_way / ideal;
    if (i == kSteps || !(factor <= kMaxFactor && factor >= kMinFactor)) {
      std::snprintf(text, sizeof text,
                    "the distortion puts the points half-way to the corners of the %dx%d image at %.3g times "
                    "their undistorted distance from its centre (direction %.0f deg): coefficients mistyped, or of "
                    "another camera",
                    size.width, size.height, factor, a * 180 / CV_PI);
      return text;
    }
  }
  return "";
}

void CameraModel::save(const std::string& path) const {
  cv::FileStorage fs(path, cv::FileStorage::WRITE);
  if (!fs.isOpened()) throw std::runtime_error("camera file " + path + ": cannot write");
  fs << "image_width" << size.width << "image_height" << size.height;
  fs << "camera_matrix" << cv::Mat(K);
  fs << "distortion_coefficients" << (dist.empty() ? cv::Mat::zeros(1, 5, CV_64F) : dist);
}

CameraModel CameraModel::scaledTo(cv::Size new_size) const {
  CameraModel c = *this;
  if (size.width <= 0 || size.height <= 0) return c;
  const double sx = static_cast<double>(new_size.width) / size.width;
  const double sy = static_cast<double>(new_size.height) / size.height;
  c.K(0, 0) *= sx;
  c.K(1, 1) *= sy;
  c.K(0, 2) = (K(0, 2) + 0.5) * sx - 0.5;
  c.K(1, 2) = (K(1, 2) + 0.5) * sy - 0.5;
  c.size = new_size;
  return c;
}

bool CameraModel::fits(cv::Size frame) const {
  if (size.width <= 0 || size.height <= 0) return true;
  if (frame.width <= 0 || frame.height <= 0) return false;
  const double sx = static_cast<double>(frame.width) / size.width;
  const double sy = static_cast<double>(frame.height) / size.height;
  return std::abs(sx - sy) <= 0.01 * std::max(sx, sy);
}

std::string CameraModel::misfit(cv::Size frame) const {
  if (fits(frame)) return "";
  return "the camera calibration is for " + std::to_string(size.width) + "x" + std::to_string(size.height) +
         " images and this frame is " + std::to_string(frame.width) + "x" + std::to_string(frame.height) +
         ", another aspect ratio (another crop of the sensor, whose intrinsics do not scale): no pose; "
         "calibrate the camera at this resolution";
}

std::string CameraModel::turned(int quarter_turns_cw, bool mirrored, CameraModel& out) const {
  // OpenCV's coefficients: k1 k2 p1 p2 [k3 [k4 k5 k6 [s1 s2 s3 s4 [tx ty]]]]
  std::vector<double> d;
  if (!dist.empty()) dist.reshape(1, 1).convertTo(d, CV_64F);
  if (d.size() > 12 && (d[12] != 0 || d[13] != 0))
    return "its distortion has a tilted sensor's terms, which do not turn with the image";
  if (size.width <= 0 || size.height <= 0) return "its image size is not known, and the principal point turns about it";
  const int k = ((quarter_turns_cw % 4) + 4) % 4;
  if (k % 2 && K(0, 1) != 0) return "its camera matrix has skew, which does not turn a quarter with the image";
  CameraModel c = *this;
  // mirrored, u' = W-1-u: x' = -x, y' = y
  if (mirrored) {
    c.K(0, 2) = size.width - 1 - c.K(0, 2);
    c.K(0, 1) = -c.K(0, 1);
    if (d.size() >= 4) d[3] = -d[3];                     // p2
    if (d.size() >= 12) d[8] = -d[8], d[9] = -d[9];  // s1, s2
  }
  // a quarter clockwise, u' = H-1-v, v' = u: x' = -y, y' = x
  for (int i = 0; i < k; ++i) {
    const double fx = c.K(0, 0), fy = c.K(1, 1), cx = c.K(0, 2), cy = c.K(1, 2);
    c.K(0, 0) = fy;
    c.K(1, 1) = fx;
    c.K(0, 2) = c.size.height - 1 - cy;
    c.K(1, 2) = cx;
    c.size = cv::Size(c.size.height, c.size.width);
    if (d.size() >= 4) std::tie(d[2], d[3]) = std::make_tuple(d[3], -d[2]);  // p1' = p2, p2' = -p1
    if (d.size() >= 12)
      std::tie(d[8], d[9], d[10], d[11]) = std::make_tuple(-d[10], -d[11], d[8], d[9]);
  }
  if (!dist.empty()) c.dist = cv::Mat(d, true).reshape(1, dist.rows == 1 ? 1 : static_cast<int>(d.size()));
  out = c;
  return "";
}

bool CameraModel::hasDistortion() const {
  return !dist.empty() && cv::countNonZero(dist != 0) > 0;
}

}  // namespace ld
