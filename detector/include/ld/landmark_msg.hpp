// Conversions between detections and the LCM messages that carry them.
#pragma once

#include <string>

#include "ld/detector.hpp"
#include "ld/landmark_list_t.hpp"
#include "ld/landmark_t.hpp"

namespace ld {

/// A landmark as a message (track fields left untracked: track_id = -1).
landmark_t toMessage(const Landmark& lm);
Landmark fromMessage(const landmark_t& msg);

/// Fills `out` with the landmarks and stage timings of one frame. `out`'s
/// vectors are reused, so a caller that keeps `out` does not allocate.
void toListMessage(const Detection& det, int64_t utime, int64_t seq, int width, int height,
                   const std::string& backend, int64_t frames_skipped, landmark_list_t& out);

}  // namespace ld
