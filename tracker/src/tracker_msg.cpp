#include "ld/tracker_msg.hpp"

#include <algorithm>

#include "ld/landmark_msg.hpp"

namespace ld {

void landmarksFromList(const landmark_list_t& in, std::vector<Landmark>& out) {
  const size_t n = std::min(in.landmarks.size(), static_cast<size_t>(std::max(in.nlandmarks, 0)));
  out.resize(n);
  for (size_t i = 0; i < n; ++i) out[i] = fromMessage(in.landmarks[i]);
}

void toTrackedListMessage(const std::vector<Track>& tracks, const landmark_list_t& in,
                          double track_ms, int64_t frames_skipped, landmark_list_t& out) {
  out.utime = in.utime;
  out.seq = in.seq;
  out.width = in.width;
  out.height = in.height;
  out.backend = "tracker";
  out.frames_skipped = frames_skipped;
  const size_t n_in = std::min({in.stage_names.size(), in.stage_ms.size(),
                                static_cast<size_t>(std::max(in.nstages, 0))});
  out.stage_names.resize(n_in + 1);
  out.stage_ms.resize(n_in + 1);
  for (size_t i = 0; i < n_in; ++i) {
    out.stage_names[i] = in.stage_names[i];
    out.stage_ms[i] = in.stage_ms[i];
  }
  out.stage_names[n_in] = "track";
  out.stage_ms[n_in] = static_cast<float>(track_ms);
  out.nstages = static_cast<int32_t>(n_in + 1);

  out.nlandmarks = static_cast<int32_t>(tracks.size());
  out.landmarks.resize(tracks.size());
  for (size_t i = 0; i < tracks.size(); ++i) {
    const Track& t = tracks[i];
    landmark_t& m = out.landmarks[i];
    m = toMessage(t.landmark);
    m.track_id = t.id;
    m.age = t.age;
    m.frames_since_seen = t.frames_since_seen;
    m.time_since_seen_us = t.time_since_seen_us;
    m.visible = t.visible;
  }
}

}  // namespace ld
