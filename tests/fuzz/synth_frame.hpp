// A small rendered frame with one landmark, for the fuzz targets that run
// the detector or the tracker with the configuration they read.
#pragma once

#include <opencv2/core.hpp>

#include "ld/synth.hpp"

namespace ld::fuzz {

/// 160x120, one frontal landmark about 37 px across on a plain wall.
inline const cv::Mat& landmarkFrame() {
  static const cv::Mat frame = [] {
    synth::SceneSpec spec;
    spec.camera = CameraModel::pinhole({160, 120}, 150.0);
    spec.background = synth::Background::Plain;
    spec.distractors = 0;
    spec.landmarks.push_back(synth::placeLandmark(spec.camera, 0.6, 10, 0, 5));
    return synth::render(spec).bgr;
  }();
  return frame;
}

}  // namespace ld::fuzz
