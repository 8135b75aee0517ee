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

/// Writes a label with its bottom left at `at`, on a dark outline (green on
/// a landmark's white sheet and blue square read "WOm-103" for "room-103"),
/// moved inside the image where it would run off an edge.
void drawLabel(cv::Mat& bgr, const std::string& text, cv::Point2f at, const cv::Scalar& colour, int thick);

}  // namespace ld
