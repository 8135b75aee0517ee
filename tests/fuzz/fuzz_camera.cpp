// Fuzz target: the camera calibration reader, CameraModel::load
// (ld-detector --camera), in OpenCV's calibration file format.
//
// A file either loads or throws std::runtime_error naming the problem; a
// camera that loads must then work for pose: scaled to another frame size,
// given to a detector that finds a landmark and solves its pose (through the
// undistorted image when the file has distortion).
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <stdexcept>

#include "fuzz_file.hpp"
#include "ld/camera.hpp"
#include "ld/detector.hpp"
#include "synth_frame.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string path = ld::fuzz::writeInput(data, size, ".yml");
  ld::CameraModel camera;
  try {
    camera = ld::CameraModel::load(path);
  } catch (const std::runtime_error&) {
    return 0;
  }
  if (camera.size.width <= 0 || camera.size.height <= 0) std::abort();
  (void)camera.scaledTo({320, 240});
  (void)camera.hasDistortion();

  static ld::Detector detector;
  detector.setCamera(camera, 0.15);
  const ld::Detection& det = detector.detect(ld::fuzz::landmarkFrame());
  for (const auto& lm : det.landmarks) {
    for (const auto& c : lm.corners)
      if (!std::isfinite(c.x) || !std::isfinite(c.y)) std::abort();
    if (lm.pose && (!cv::checkRange(lm.pose->t) || !cv::checkRange(lm.pose->rvec) ||
                    !std::isfinite(lm.pose->distance)))
      std::abort();
  }
  return 0;
}
