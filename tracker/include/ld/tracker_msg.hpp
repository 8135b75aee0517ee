// The tracker on LCM messages: LANDMARKS (ld.landmark_list_t from the
// detector) in, LANDMARKS_TRACKED (the same type, track fields filled) out.
#pragma once

#include <vector>

#include "ld/landmark_list_t.hpp"
#include "ld/tracker.hpp"

namespace ld {

/// The detections of a landmark list (its track fields are ignored). `out`
/// is reused.
void landmarksFromList(const landmark_list_t& in, std::vector<Landmark>& out);

/// The tracked list of one frame: the input's utime, seq, width and height;
/// its stage timings followed by ("track", track_ms); backend "tracker";
/// frames_skipped the tracker's own count; one landmark per reported track
/// (track_id, age, frames_since_seen, time_since_seen_us, visible), in track
/// creation order. `out`'s vectors are reused.
void toTrackedListMessage(const std::vector<Track>& tracks, const landmark_list_t& in,
                          double track_ms, int64_t frames_skipped, landmark_list_t& out);

}  // namespace ld
