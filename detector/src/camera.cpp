#include "ld/camera.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <stdexcept>

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
  if (node.isMap()) {
    const cv::FileNode rows = node["rows"], cols = node["cols"];
    if (!rows.isInt() || !cols.isInt())
      throw std::runtime_error("camera file " + path + ": " + name + " has no integer rows and cols");
    const int r = static_cast<int>(rows), c = static_cast<int>(cols);
    if (r < 0 || c < 0 || static_cast<int64_t>(r) * c > max_elements)
      throw std::runtime_error("camera file " + path + ": " + name + " is " + std::to_string(r) +
                               "x" + std::to_string(c) + ", more than " +
                               std::to_string(max_elements) + " values");
    if (node["dt"].empty()) {
      // ROS camera_info (camera_calibration's files): rows, cols and data,
      // without OpenCV's element type.
      const cv::FileNode data = node["data"];
      if (!data.isSeq())
        throw std::runtime_error("camera file " + path + ": " + name + " has no data list");
      if (static_cast<int64_t>(data.size()) != static_cast<int64_t>(r) * c)
        throw std::runtime_error("camera file " + path + ": " + name + " has " + std::to_string(data.size()) +
                                 " values, not " + std::to_string(r) + "x" + std::to_string(c));
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
  CameraModel c;
  c.size = size;
  c.K = cv::Matx33d(focal_px, 0, (size.width - 1) / 2.0, 0, focal_px, (size.height - 1) / 2.0,
                    0, 0, 1);
  return c;
}

CameraModel CameraModel::load(const std::string& path) {
  const cv::FileStorage fs = openConfigFile(path, "camera file");
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
    int w = 0, h = 0;
    if (!fs["image_width"].empty()) fs["image_width"] >> w;
    if (!fs["image_height"].empty()) fs["image_height"] >> h;
    const cv::FileNode res = fs["cameraResolution"];
    if (w <= 0 && h <= 0 && res.isSeq() && res.size() == 2 && res[0].isInt() && res[1].isInt())
      w = static_cast<int>(res[0]), h = static_cast<int>(res[1]);
    if (w <= 0 || h <= 0)
      throw std::runtime_error("camera file " + path + ": image_width/image_height (or cameraResolution) missing");
    c.size = {w, h};
    // a camera matrix: [fx s cx; 0 fy cy; 0 0 1], its principal point in the image
    if (c.K(1, 0) != 0 || c.K(2, 0) != 0 || c.K(2, 1) != 0 || c.K(2, 2) != 1)
      throw std::runtime_error("camera file " + path + ": " + k_name + " is not of the form [fx s cx; 0 fy cy; 0 0 1]");
    if (!(c.K(0, 2) >= -1 && c.K(0, 2) <= w) || !(c.K(1, 2) >= -1 && c.K(1, 2) <= h))
      throw std::runtime_error("camera file " + path + ": principal point (" +
                               std::to_string(c.K(0, 2)) + ", " + std::to_string(c.K(1, 2)) +
                               ") is outside the " + std::to_string(w) + "x" + std::to_string(h) +
                               " image");
  } catch (const cv::Exception& e) {
    throw std::runtime_error("camera file " + path + ": malformed (" + e.err + ")");
  } catch (const std::runtime_error&) {
    throw;
  } catch (const std::exception& e) {
    throw std::runtime_error("camera file " + path + ": malformed (" + e.what() + ")");
  }
  return c;
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

bool CameraModel::hasDistortion() const {
  return !dist.empty() && cv::countNonZero(dist != 0) > 0;
}

}  // namespace ld
