#include "ld/qr_tracks.hpp"

#include <algorithm>
#include <cmath>

namespace ld {

void FrameMatcher::addImage(const Key& key, const uint8_t* data, size_t size) {
  // Images from behind the last frame taken, each newer than the one before:
  // the camera's clock stepped back. ld-tracker publishes no list for the
  // first kStepBackFrames - 1 of them, so the lists alone would count the
  // run again from its first list.
  if (taken_any_ && key.utime < last_taken_.utime) images_behind_.note(key.utime, 1);
  else if (taken_any_ && key.utime > last_taken_.utime) images_behind_.frames = 0;
  Entry e{key, {}};
  if (!spare_.empty()) {
    e.bytes = std::move(spare_.back());
    spare_.pop_back();
  }
  e.bytes.assign(data, data + size);
  images_.push_back(std::move(e));
  while (images_.size() > max_images_) {
    spare_.push_back(std::move(images_.front().bytes));
    images_.pop_front();
  }
  match();
}

void FrameMatcher::addList(const Key& key, const uint8_t* data, size_t size) {
  Entry e{key, {}};
  if (!spare_.empty()) {
    e.bytes = std::move(spare_.back());
    spare_.pop_back();
  }
  e.bytes.assign(data, data + size);
  lists_.push_back(std::move(e));
  while (lists_.size() > max_lists_) {
    spare_.push_back(std::move(lists_.front().bytes));
    lists_.pop_front();
    ++unmatched_dropped_;
  }
  match();
}

void FrameMatcher::match() {
  for (auto l = lists_.begin(); l != lists_.end();) {
    auto im = std::find_if(images_.rbegin(), images_.rend(),
                           [&](const Entry& e) { return e.key == l->key; });
    if (im == images_.rend()) {
      ++l;
      continue;
    }
    Pair p;
    p.key = l->key;
    p.list = std::move(l->bytes);
    if (!spare_.empty()) {
      p.image = std::move(spare_.back());
      spare_.pop_back();
    }
    p.image.assign(im->bytes.begin(), im->bytes.end());  // the image may serve another list
    ready_.push_back(std::move(p));
    ++matched_;
    l = lists_.erase(l);
  }
  // Lists much older than the oldest image held can never be matched.
  if (!images_.empty()) {
    const int64_t oldest = images_.front().key.utime;
    while (!lists_.empty() && lists_.front().key.utime < oldest &&
           images_.size() == max_images_) {
      spare_.push_back(std::move(lists_.front().bytes));
      lists_.pop_front();
      ++unmatched_dropped_;
    }
  }
}

bool FrameMatcher::takeNewest(Pair& out) {
  if (ready_.empty()) return false;
  // Late: older than the last frame taken by up to kLateUs, or that frame
  // again. Frames whose utime stands still are told apart by their seqs: up
  // to kLateSeqs back is late, further back is the publisher starting again
  // (without that, a replay's seqs from 0 were all dropped until they passed
  // the last one); without seqs they are taken.
  const auto late = [&](const Key& k) {
    if (!taken_any_) return false;
    if (k.utime == last_taken_.utime)
      return k.seq >= 0 && last_taken_.seq >= 0 && k.seq <= last_taken_.seq && last_taken_.seq - k.seq <= kLateSeqs;
    // (the difference as unsigned: any two utimes may come, as in Tracker::update)
    return k.utime < last_taken_.utime &&
           static_cast<uint64_t>(last_taken_.utime) - static_cast<uint64_t>(k.utime) <= static_cast<uint64_t>(kLateUs);
  };
  auto newest = ready_.end(), newest_late = ready_.end();
  int64_t late_now = 0;
  for (auto p = ready_.begin(); p != ready_.end(); ++p) {
    if (late(p->key)) {
      ++late_now;
      if (newest_late == ready_.end() || newest_late->key.utime < p->key.utime) newest_late = p;
    } else if (newest == ready_.end() || newest->key.utime < p->key.utime ||
               (newest->key.utime == p->key.utime && newest->key.seq < p->key.seq)) {
      newest = p;
    }
  }
  // Late frames in a row, each newer than the ones before: time stepped back
  // (as Tracker::update takes it), the kStepBackFrames-th taken.
  if (newest == ready_.end() && newest_late != ready_.end() && newest_late->key.utime < last_taken_.utime) {
    pairs_behind_.note(newest_late->key.utime, static_cast<int>(late_now));
    if (pairs_behind_.frames >= kStepBackFrames || images_behind_.frames >= kStepBackFrames) {
      newest = newest_late;
      --late_now;
      pairs_behind_.frames = 0;
    }
  } else if (newest != ready_.end()) {
    pairs_behind_.frames = 0;
  }
  late_ += late_now;
  const bool found = newest != ready_.end();
  if (found) {
    if (!out.image.empty()) spare_.push_back(std::move(out.image));
    if (!out.list.empty()) spare_.push_back(std::move(out.list));
    out = std::move(*newest);
    skipped_ += static_cast<int64_t>(ready_.size()) - 1 - late_now;
    taken_any_ = true;
    last_taken_ = out.key;
  }
  for (auto& p : ready_) {
    if (!p.image.empty()) spare_.push_back(std::move(p.image));
    if (!p.list.empty()) spare_.push_back(std::move(p.list));
  }
  ready_.clear();
  if (spare_.size() > max_images_ + max_lists_) spare_.resize(max_images_ + max_lists_);
  return found;
}

bool QrTrackBook::noteAges(const std::vector<std::pair<int64_t, int32_t>>& ages) {
  if (!restarts_.note(ages)) return false;
  tracks_.clear();
  return true;
}

std::vector<int64_t> QrTrackBook::schedule(const std::vector<int64_t>& track_ids, int64_t utime) {
  // (saturating: an interval of 1e300 s is never, where the cast's
  // overflow made it every frame)
  const auto us = [](double s) { return s * 1e6 >= 9e18 ? INT64_MAX : static_cast<int64_t>(s * 1e6); };
  std::vector<std::pair<int64_t, int64_t>> due;  // (priority, id): lower first
  ++frames_;
  for (int64_t id : track_ids) {
    Track& t = tracks_[id];
    t.last_seen = utime;
    t.last_frame = frames_;
    const int64_t since = t.last_try == INT64_MIN ? INT64_MAX : utime - t.last_try;
    if (!t.known) {
      if (since >= us(params_.retry_interval_s)) due.emplace_back(t.last_try, id);
    } else if (since >= us(params_.recheck_interval_s)) {
      // Re-checks come after every undecoded track (one asked for now,
      // readAgain, first among them).
      due.emplace_back(INT64_MAX / 2 + std::clamp<int64_t>(t.last_try / 2, 0, INT64_MAX / 4), id);
    }
  }
  std::stable_sort(due.begin(), due.end(),
                   [](const auto& a, const auto& b) { return a.first < b.first; });
  std::vector<int64_t> out;
  for (const auto& d : due) {
    if (static_cast<int>(out.size()) >= params_.max_decodes_per_frame) break;
    out.push_back(d.second);
  }
  // Forget tracks unseen for long, and beyond kMaxTracks those named
  // longest ago (now and then, a tenth of the bound at a time), never one
  // of this frame.
  int64_t named_before = INT64_MIN;  // forgotten: named in this schedule call or before
  if (tracks_.size() > kMaxTracks + kMaxTracks / 10) {
    std::vector<int64_t> frames;
    frames.reserve(tracks_.size());
    for (const auto& [id, t] : tracks_) frames.push_back(t.last_frame);
    const size_t drop = tracks_.size() - kMaxTracks;
    std::nth_element(frames.begin(), frames.begin() + static_cast<std::ptrdiff_t>(drop - 1), frames.end());
    named_before = std::min(frames[drop - 1], frames_ - 1);
  }
  for (auto it = tracks_.begin(); it != tracks_.end();) {
    if (utime - it->second.last_seen > us(params_.forget_after_s) || it->second.last_frame <= named_before) {
      restarts_.forget(it->first);
      it = tracks_.erase(it);
    } else {
      ++it;
    }
  }
  return out;
}

std::optional<std::string> QrTrackBook::follow(int64_t track_id, int32_t age, bool visible, double cx, double cy,
                                               double size) {
  const auto it = tracks_.find(track_id);
  if (it == tracks_.end()) return std::nullopt;
  Track& t = it->second;
  t.strayed = false;  // (this frame's alone)
  if (!visible) {  // (its place is the tracker's guess; that it coasts is news)
    if (t.placed && age > t.age) t.coasted = true;
    return std::nullopt;
  }
  if (!std::isfinite(cx) || !std::isfinite(cy) || !(size > 0) || !std::isfinite(size)) return std::nullopt;
  if (t.placed && age <= t.age) return std::nullopt;  // (an older frame, matched late: no news)
  const double frames = t.placed ? static_cast<double>(age) - t.age : 1.0;
  const double px = t.cx + t.vx * frames, py = t.cy + t.vy * frames;  // where its motion leads
  const double mean_size = 0.5 * (size + t.size);
  bool jumped = false;
  if (t.placed && t.known) {
    double off = 0, jump = 0;  // (how far from its path, and how far is a jump)
    if (!t.coasted) {
      off = std::hypot(cx - px, cy - py);
      jump = frames * mean_size;
    } else {
      // Seen coasting, it was found again by the tracker's gate, which a
      // neighbour may be in: it must be within 1.5 sizes of its path from
      // its last place to where its motion leads (the robot may have
      // stopped anywhere on it), however long it coasted. (Closer, the
      // velocity's error over many frames coasted reads as a jump.)
      const double dx = px - t.cx, dy = py - t.cy, len2 = dx * dx + dy * dy;
      const double u = len2 > 0 ? std::clamp(((cx - t.cx) * dx + (cy - t.cy) * dy) / len2, 0.0, 1.0) : 0.0;
      off = std::hypot(cx - (t.cx + u * dx), cy - (t.cy + u * dy));
      jump = 1.5 * mean_size;
    }
    jumped = off > jump;
    t.strayed = !jumped && off > 0.5 * jump;
  }
  t.coasted = false;
  if (t.placed && !jumped) {
    t.vx = (cx - t.cx) / frames;
    t.vy = (cy - t.cy) / frames;
  } else {
    t.vx = t.vy = 0;  // (a new landmark under the id: its motion is not known yet)
  }
  t.placed = true;
  t.cx = cx;
  t.cy = cy;
  t.size = size;
  t.age = age;
  if (!jumped) return std::nullopt;
  return forget(track_id);
}

bool QrTrackBook::strayed(int64_t track_id) const {
  const auto it = tracks_.find(track_id);
  return it != tracks_.end() && it->second.strayed;
}

void QrTrackBook::readAgain(int64_t track_id) {
  const auto it = tracks_.find(track_id);
  if (it != tracks_.end()) it->second.last_try = INT64_MIN;
}

std::optional<std::string> QrTrackBook::forget(int64_t track_id) {
  const auto it = tracks_.find(track_id);
  if (it == tracks_.end() || !it->second.known) return std::nullopt;
  std::optional<std::string> forgotten = std::move(it->second.known->payload);
  it->second.known.reset();
  it->second.last_try = INT64_MIN;  // (first in the next schedule)
  return forgotten;
}

void QrTrackBook::record(int64_t track_id, int64_t utime, int64_t seq,
                         const std::optional<std::string>& payload) {
  Track& t = tracks_[track_id];
  t.last_try = utime;
  t.last_seen = std::max(t.last_seen, utime);
  // A failed re-check keeps what was read before: the QR may just be blurred now.
  if (payload) t.known = Known{*payload, utime, seq};
}

const QrTrackBook::Known* QrTrackBook::payload(int64_t track_id) const {
  const auto it = tracks_.find(track_id);
  return it == tracks_.end() || !it->second.known ? nullptr : &*it->second.known;
}

}  // namespace ld
