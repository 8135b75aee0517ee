// LANDMARK.md's JSON for landmarks, and overlay drawing, shared by the tools.
#pragma once

#include <vector>

#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>

#include "ld/detector.hpp"

namespace ld {

/// {"fip_tl": [x, y], ..., "corners": [[x, y] x4], "payload": text|null,
///  "pose": {"t": [..], "rvec": [..], "distance": d}} (pose only when known).
nlohmann::ordered_json toJson(const Landmark& lm);

/// Draws landmarks (pattern outline, the four centres, TL marked, payload
/// and distance as text) onto a BGR image.
void drawLandmarks(cv::Mat& bgr, const std::vector<Landmark>& landmarks);

}  // namespace ld
