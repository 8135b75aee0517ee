#include "ld/camera.hpp"

#include <stdexcept>

namespace ld {

CameraModel CameraModel::defaultVga() { return pinhole({640, 480}, 600.0); }

CameraModel CameraModel::pinhole(cv::Size size, double focal_px) {
  CameraModel c;
  c.size = size;
  c.K = cv::Matx33d(focal_px, 0, (size.width - 1) / 2.0, 0, focal_px, (size.height - 1) / 2.0,
                    0, 0, 1);
  return c;
}

CameraModel CameraModel::load(const std::string& path) {
  cv::FileStorage fs;
  try {
    if (!fs.open(path, cv::FileStorage::READ))
      throw std::runtime_error("camera file " + path + ": cannot open or parse");
  } catch (const cv::Exception& e) {
    throw std::runtime_error("camera file " + path + ": cannot parse (" + e.err + ")");
  }
  CameraModel c;
  try {
    cv::Mat K;
    fs["camera_matrix"] >> K;
    if (K.empty()) throw std::runtime_error("camera file " + path + ": no camera_matrix");
    if (K.rows != 3 || K.cols != 3)
      throw std::runtime_error("camera file " + path + ": camera_matrix is not 3x3");
    K.convertTo(K, CV_64F);
    c.K = cv::Matx33d(K);
    if (!(c.K(0, 0) > 0) || !(c.K(1, 1) > 0))
      throw std::runtime_error("camera file " + path + ": focal lengths must be positive");
    fs["distortion_coefficients"] >> c.dist;
    if (!c.dist.empty()) {
      c.dist.convertTo(c.dist, CV_64F);
      c.dist = c.dist.reshape(1, 1);
      const int n = c.dist.cols;
      if (n != 4 && n != 5 && n != 8 && n != 12 && n != 14)
        throw std::runtime_error("camera file " + path +
                                 ": distortion_coefficients must have 4, 5, 8, 12 or 14 values");
    }
    int w = 0, h = 0;
    if (!fs["image_width"].empty()) fs["image_width"] >> w;
    if (!fs["image_height"].empty()) fs["image_height"] >> h;
    if (w <= 0 || h <= 0)
      throw std::runtime_error("camera file " + path + ": image_width/image_height missing");
    c.size = {w, h};
  } catch (const cv::Exception& e) {
    throw std::runtime_error("camera file " + path + ": malformed (" + e.err + ")");
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

bool CameraModel::hasDistortion() const {
  return !dist.empty() && cv::countNonZero(dist != 0) > 0;
}

}  // namespace ld
