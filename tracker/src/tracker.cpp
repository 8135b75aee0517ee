#include "ld/tracker.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <stdexcept>

namespace ld {
namespace {

// A detection two pool landmarks could both be (a landmark that left the
// image where another one left before, a landmark found again next to a
// duplicate) goes to the one seen more recently, as in a matching cascade: a
// pair's margin inside its gate is divided by 1 + this times the seconds the
// pool landmark has been unseen.
constexpr double kStaleWeight = 1.0;

// A landmark followed with its own motion predicts itself well, and the
// frame's other landmarks say how far the robot's motion changed: a
// detection shifted from its prediction unlike the others' (the median of
// their shifts) by more than kSurpriseMin sizes, kSurpriseOwn times its
// detections' usual distance from their predictions and kSurpriseFrame
// times the farthest of the others from that median, is another landmark (a
// landmark missed for one frame gave its id to a newcomer 1.5-1.8 sizes
// away: a review). A jolt or a turn of the robot shifts every landmark
// alike, in pixels, near or far; a lone landmark is not judged (nothing to
// tell a jolt from another landmark: a second review, where a small one
// lost its id at every jolt or start of a turn).
constexpr double kSurpriseMin = 1.0, kSurpriseOwn = 4.0, kSurpriseFrame = 2.0;
// A frame is calm where the others' shifts from their predictions, and their
// scatter, are within this many sizes of the landmark judged.
constexpr double kCalm = 0.5;
// Weight of a frame in the running mean of a track's distance from its prediction.
constexpr double kMissDistanceWeight = 0.3;

// One frame more on a count (a track's age, hits, frames unseen), held at
// the largest int32_t: a landmark in view for 2^31 frames (828 days at 30
// frames/s) would otherwise wrap to a negative age.
void countUp(int32_t& n) {
  if (n < std::numeric_limits<int32_t>::max()) ++n;
}

// Microseconds from `then` to `now` (now >= then: update() restarts when time
// goes back), saturated: any two utimes may arrive, and their difference can
// exceed int64_t (found by tests/fuzz/fuzz_messages).
int64_t elapsedUs(int64_t now, int64_t then) {
  const uint64_t d = static_cast<uint64_t>(now) - static_cast<uint64_t>(then);
  return d > static_cast<uint64_t>(INT64_MAX) ? INT64_MAX : static_cast<int64_t>(d);
}

double dist(const cv::Point2d& a, const cv::Point2d& b) { return std::hypot(a.x - b.x, a.y - b.y); }

// The landmark moved so that its centre goes from `from` to `to` and scaled
// about its centre by `scale`.
cv::Point2f movePoint(const cv::Point2f& p, const cv::Point2d& from, const cv::Point2d& to,
                      double scale) {
  return {static_cast<float>(to.x + (p.x - from.x) * scale),
          static_cast<float>(to.y + (p.y - from.y) * scale)};
}

void moveLandmark(Landmark& lm, const cv::Point2d& from, const cv::Point2d& to, double scale) {
  lm.fip_tl = movePoint(lm.fip_tl, from, to, scale);
  lm.fip_tr = movePoint(lm.fip_tr, from, to, scale);
  lm.fip_bl = movePoint(lm.fip_bl, from, to, scale);
  lm.ap = movePoint(lm.ap, from, to, scale);
  for (auto& c : lm.corners) c = movePoint(c, from, to, scale);
}

}  // namespace

cv::Point2f landmarkCentre(const Landmark& lm) {
  return (lm.fip_tl + lm.fip_tr + lm.fip_bl + lm.ap) * 0.25f;
}

double landmarkSize(const Landmark& lm) {
  double sum = 0;
  for (size_t i = 0; i < 4; ++i) {
    const cv::Point2f d = lm.corners[(i + 1) % 4] - lm.corners[i];
    sum += std::hypot(static_cast<double>(d.x), static_cast<double>(d.y));
  }
  return sum / 4.0;
}

Tracker::Tracker(const TrackerParams& params) : params_(params) {
  params_.validate();
  pool_.reserve(64);
  out_.reserve(64);
}

void Tracker::reset() {
  stats_.tracks_dropped += static_cast<int64_t>(pool_.size());
  pool_.clear();
  out_.clear();
  has_time_ = false;
}

const std::vector<Track>& Tracker::update(const std::vector<Landmark>& detections, int64_t utime,
                                          cv::Size image) {
  if (has_time_ && utime < last_utime_) {
    // (frames from behind in a row, each newer than the one before, are time
    // stepped back, not messages held up: taken from the kStepBackFrames-th)
    behind_ = behind_ > 0 && utime > behind_utime_ ? behind_ + 1 : 1;
    behind_utime_ = utime;
    if (elapsedUs(last_utime_, utime) <= kLateFrameUs && behind_ < kStepBackFrames) {
      ++stats_.late_frames;
      out_.clear();
      return out_;
    }
    reset();
    ++stats_.resets;
  }
  behind_ = 0;
  has_time_ = true;
  last_utime_ = utime;
  ++stats_.frames;

  // 0. VALID DETECTIONS, with their centres and sizes.
  det_index_.clear();
  det_centre_.clear();
  det_size_.clear();
  for (size_t k = 0; k < detections.size(); ++k) {
    const Landmark& d = detections[k];
    const double size = finiteLandmark(d) ? landmarkSize(d) : 0.0;
    if (!(size >= 1.0) || !std::isfinite(size)) {
      ++stats_.rejected_detections;
      continue;
    }
    det_index_.push_back(static_cast<int>(k));
    det_centre_.push_back(landmarkCentre(d));
    det_size_.push_back(size);
  }

  // 1. EXPIRE: a landmark stays in the pool while unseen for less than its lifetime.
  // (clamped to 9e12 s, "forever": a larger lifetime would not fit in int64_t microseconds)
  const auto lifetime_us =
      static_cast<int64_t>(std::llround(std::min(params_.max_lifetime_s, 9e12) * 1e6));
  const auto expired = std::remove_if(pool_.begin(), pool_.end(), [&](const PoolEntry& e) {
    return elapsedUs(utime, e.last_seen_utime) >= lifetime_us;
  });
  stats_.tracks_dropped += pool_.end() - expired;
  pool_.erase(expired, pool_.end());
  // ... and no more than kMaxPool, the longest unseen going first (then the
  // oldest seen: a utime standing still makes every gap 0)
  // (the pool's order, that of the tracks reported, kept)
  if (pool_.size() > kMaxPool) {
    std::vector<std::pair<int32_t, int64_t>> keys;  // (-frames unseen, id): the first ones go
    keys.reserve(pool_.size());
    for (const PoolEntry& e : pool_) keys.emplace_back(-e.frames_since_seen, e.id);
    const size_t drop = pool_.size() - kMaxPool;
    std::nth_element(keys.begin(), keys.begin() + static_cast<std::ptrdiff_t>(drop - 1), keys.end());
    const auto last_dropped = keys[drop - 1];
    pool_.erase(std::remove_if(pool_.begin(), pool_.end(),
                               [&](const PoolEntry& e) {
                                 return std::pair<int32_t, int64_t>(-e.frames_since_seen, e.id) <= last_dropped;
                               }),
                pool_.end());
    stats_.tracks_dropped += static_cast<int64_t>(drop);
  }

  // 2. PREDICT every pool landmark to this frame's time.
  predict(utime);

  // 3. ASSIGN new landmarks to pool landmarks.
  assign(utime, image);

  // 4. UPDATE the pool: matched, coasting, new.
  common_vx_.clear();
  common_vy_.clear();
  const size_t n_old = pool_.size();
  for (size_t i = 0; i < n_old; ++i) {
    PoolEntry& e = pool_[i];
    countUp(e.age);
    e.restart_motion = false;
    if (e.detection >= 0) {
      const bool continuous = e.frames_since_seen == 0;
      updateMatched(e, detections[static_cast<size_t>(det_index_[static_cast<size_t>(e.detection)])],
                    e.detection, utime);
      if (continuous && e.motion == Motion::Measured) {
        common_vx_.push_back(e.velocity.x);
        common_vy_.push_back(e.velocity.y);
      }
    } else {
      countUp(e.frames_since_seen);
    }
  }
  // A tentative track (fewer than min_hits detections) ends at its first miss.
  if (params_.min_hits > 1) {
    const auto gone = std::remove_if(pool_.begin(), pool_.end(), [&](const PoolEntry& e) {
      return e.detection < 0 && e.hits < params_.min_hits;
    });
    stats_.tracks_dropped += pool_.end() - gone;
    pool_.erase(gone, pool_.end());
  }
  for (size_t j = 0; j < det_index_.size(); ++j) {
    if (det_matched_[j]) continue;
    pool_.emplace_back();
    PoolEntry& e = pool_.back();
    e.id = next_id_++;
    e.lm = detections[static_cast<size_t>(det_index_[j])];
    e.centre = det_centre_[j];
    e.size = det_size_[j];
    e.pred_centre = e.centre;
    e.pred_size = e.size;
    e.last_seen_utime = utime;
    e.hits = 1;
    e.detection = static_cast<int>(j);
    e.restart_motion = true;
    ++stats_.tracks_created;
  }
  // New tracks, tracks found again where they were last seen and tracks
  // still without a velocity of their own take the image motion common to
  // the tracks followed without a gap (on a robot, mostly its own motion):
  // the median of their velocities.
  if (params_.predict) {
    const bool has_common = !common_vx_.empty();
    cv::Point2d common;
    if (has_common) {
      const auto mid = static_cast<long>(common_vx_.size() / 2);
      std::nth_element(common_vx_.begin(), common_vx_.begin() + mid, common_vx_.end());
      std::nth_element(common_vy_.begin(), common_vy_.begin() + mid, common_vy_.end());
      common = {common_vx_[static_cast<size_t>(mid)], common_vy_[static_cast<size_t>(mid)]};
    }
    for (PoolEntry& e : pool_) {
      if (e.restart_motion) {
        e.velocity = common;
        e.size_rate = 0;
        e.miss_distance = 1.0;
        e.motion = has_common ? Motion::Borrowed : Motion::None;
      } else if (e.motion == Motion::None && has_common) {  // still without its own
        e.velocity = common;
        e.motion = Motion::Borrowed;
      }
    }
  }

  // 5. REPORT.
  report(utime);
  return out_;
}

void Tracker::predict(int64_t utime) {
  for (PoolEntry& e : pool_) {
    e.detection = -1;
    e.pred_centre = e.centre;
    e.pred_size = e.size;
    if (!params_.predict || e.motion == Motion::None) continue;
    const double dt = static_cast<double>(elapsedUs(utime, e.last_seen_utime)) * 1e-6;
    e.pred_centre = e.centre + e.velocity * dt;
    e.pred_size = std::clamp(e.size + e.size_rate * dt, 0.5 * e.size, 2.0 * e.size);
  }
}

void Tracker::assign(int64_t utime, cv::Size image) {
  const size_t n_pool = pool_.size(), n_det = det_index_.size();
  det_matched_.assign(n_det, 0);
  // a) Empty pool: every new landmark starts a track (step 4).
  // b) No new landmarks: every pool landmark ages (step 4).
  if (n_pool == 0 || n_det == 0) return;

  // c) Both non-empty: the assignment problem, pool landmarks as agents and
  // new landmarks as tasks. A pair inside its gate (widened for a coasting
  // landmark) gains its margin inside the plain gate (max_distance: the
  // widening lets a pair in, it does not make it better, or a stale landmark
  // would take a detection from one sitting on it), weighed down by the time
  // the pool landmark has been unseen; the assignment with the largest total
  // gain wins, leaving a pool landmark and a detection apart when no pairing
  // gains. (Fewest unmatched first, as a plain rectangular assignment does,
  // moved every id one landmark over along a row of landmarks when one left
  // the image as another came in: one pair more, each a poor one.)
  gain_.assign(n_pool * n_det, 0.0);
  double max_gain = 0;
  for (size_t i = 0; i < n_pool; ++i) {
    const PoolEntry& e = pool_[i];
    const double unseen_s = static_cast<double>(elapsedUs(utime, e.last_seen_utime)) * 1e-6;
    // Without a velocity (seen once, nothing to borrow from), the motion
    // during the missed frames is unknown: the distance is allowed for the
    // next frame too.
    const double frames_of_motion = e.motion == Motion::None && e.frames_since_seen > 0 ? 2 : 1;
    const double max_dist =
        params_.max_distance * frames_of_motion + params_.coast_distance_growth * unseen_s;
    // A coasting landmark may also be where it was last seen: the robot
    // stopped or turned back (a landmark that left the image comes back
    // where it left).
    const bool two_places = e.frames_since_seen > 0 && e.pred_centre != e.centre;
    // Predicted past a side of the image, it comes back through that side,
    // where it left it or moved along it as its motion went (a row tilted out
    // through the top as the robot rocked, while it panned on: a review
    // found the ids one landmark over when the row came back).
    const Sides gone = sidesLeftBy(e, image);
    const bool across = gone.top || gone.bottom, along = gone.left || gone.right;
    // (only one last seen at that side, within a size of it: a landmark
    // jolted for a frame in the middle of the image, predicted past a side
    // by the jolt's speed, took a detection there from its own new track)
    double to_side = -std::numeric_limits<double>::infinity();  // (a corner past it: positive)
    if (across != along)
      for (const cv::Point2f& c : e.lm.corners)
        to_side = std::max(to_side, gone.top ? -c.y : gone.bottom ? c.y - (image.height - 1.0)
                                   : gone.left ? -c.x : c.x - (image.width - 1.0));
    const bool third_place = two_places && across != along && to_side > -e.size;
    const cv::Point2d moved_along = across ? cv::Point2d(e.pred_centre.x, e.centre.y) : cv::Point2d(e.centre.x, e.pred_centre.y);
    for (size_t j = 0; j < n_det; ++j) {
      if (gone.any() && !gone.towards(det_centre_[j], image)) continue;
      auto [margin, plain] = gateMargins(e.pred_centre, e.pred_size, j, max_dist);
      if (two_places) {
        const auto [there, there_plain] = gateMargins(e.centre, e.size, j, max_dist);
        margin = std::max(margin, there);
        plain = std::max(plain, there_plain);
      }
      if (third_place) {
        const auto [there, there_plain] = gateMargins(moved_along, e.size, j, max_dist);
        margin = std::max(margin, there);
        plain = std::max(plain, there_plain);
      }
      if (!(margin >= 0)) continue;  // outside the gate (or not finite): no gain
      // (a pair in the gate but beyond the plain one still gains a little: it is allowed)
      const double g = (std::max(plain, 0.0) + 1e-3) / (1.0 + kStaleWeight * unseen_s);
      gain_[i * n_det + j] = g;
      max_gain = std::max(max_gain, g);
    }
  }
  if (max_gain <= 0) return;  // no pair inside its gate
  // Largest gain = least cost max_gain - gain over a full rectangular
  // assignment; its pairs without gain are no match. Solved again without
  // the pairs refuseSurprises() refuses, if any.
  cost_.resize(n_pool * n_det);
  for (int pass = 0; pass < 2; ++pass) {
    for (size_t k = 0; k < cost_.size(); ++k) cost_[k] = max_gain - gain_[k];
    hungarian_.solve(cost_.data(), static_cast<int>(n_pool), static_cast<int>(n_det), row_to_col_);
    if (pass == 1 || !refuseSurprises(utime)) break;
  }
  for (size_t i = 0; i < n_pool; ++i) {
    const int j = row_to_col_[i];
    if (j < 0 || !(gain_[i * n_det + static_cast<size_t>(j)] > 0)) continue;
    pool_[i].detection = j;
    det_matched_[static_cast<size_t>(j)] = 1;
    ++stats_.matches;
  }
}

bool Tracker::refuseSurprises(int64_t utime) {
  const size_t n_det = det_index_.size();
  // The pairs judged: a landmark detected in the frame before, as often as
  // before, with its own motion (the prediction of one unseen for longer is
  // less sure), and where its detection is from its prediction (pixels).
  judged_.clear();
  shift_.clear();
  for (size_t i = 0; i < pool_.size(); ++i) {
    const PoolEntry& e = pool_[i];
    const int j = row_to_col_[i];
    if (j < 0 || !(gain_[i * n_det + static_cast<size_t>(j)] > 0) || e.motion != Motion::Measured ||
        e.frames_since_seen > 0 ||
        static_cast<double>(elapsedUs(utime, e.last_seen_utime)) > 1.5 * static_cast<double>(e.seen_gap_us))
      continue;
    judged_.push_back(i);
    shift_.push_back(det_centre_[static_cast<size_t>(j)] - e.pred_centre);
  }
  // A lone landmark: nothing to tell a jolt of the robot from another landmark.
  const size_t n = judged_.size();
  if (n < 2) return false;
  const auto sq = [](const cv::Point2d& d) { return d.x * d.x + d.y * d.y; };
  // The median shift of a set, each way (a jolt or a turn of the robot
  // shifts every landmark alike), from others_x_ and others_y_.
  const auto median = [&] {
    const auto mid = static_cast<long>(others_x_.size() / 2);
    std::nth_element(others_x_.begin(), others_x_.begin() + mid, others_x_.end());
    std::nth_element(others_y_.begin(), others_y_.begin() + mid, others_y_.end());
    return cv::Point2d(others_x_[static_cast<size_t>(mid)], others_y_[static_cast<size_t>(mid)]);
  };
  // Each landmark is judged against the others: with a few, their median
  // and farthest from it without it; with more, the median of all (one
  // landmark moves it little) and the farthest but itself (200 landmarks
  // took 0.7 ms more a frame the first way).
  constexpr size_t kFew = 8;
  cv::Point2d all_common;
  double far1 = 0, far2 = 0;  // the two largest squared distances from all_common
  if (n > kFew) {
    others_x_.clear();
    others_y_.clear();
    for (const cv::Point2d& d : shift_) {
      others_x_.push_back(d.x);
      others_y_.push_back(d.y);
    }
    all_common = median();
    for (const cv::Point2d& d : shift_) {
      const double d2 = sq(d - all_common);
      if (d2 > far1) {
        far2 = far1;
        far1 = d2;
      } else {
        far2 = std::max(far2, d2);
      }
    }
  }
  bool refused = false;
  for (size_t a = 0; a < n; ++a) {
    cv::Point2d common = all_common;
    double spread2 = 0;  // (squared) how far the others are from that shift themselves
    if (n > kFew) {
      spread2 = sq(shift_[a] - common) >= far1 ? far2 : far1;
    } else {
      others_x_.clear();
      others_y_.clear();
      for (size_t b = 0; b < n; ++b)
        if (b != a) {
          others_x_.push_back(shift_[b].x);
          others_y_.push_back(shift_[b].y);
        }
      common = median();
      for (size_t b = 0; b < n; ++b)
        if (b != a) spread2 = std::max(spread2, sq(shift_[b] - common));
    }
    const size_t i = judged_[a];
    const PoolEntry& e = pool_[i];
    const int j = row_to_col_[i];
    const double half = 0.5 * (e.pred_size + det_size_[static_cast<size_t>(j)]), calm = kCalm * half;
    // Only in a frame the others say is calm (their predictions held): in a
    // jolt or the start of a turn, a wrong pair may be the others' and the
    // right one the odd one out (a row of equal landmarks jumping 2 sizes).
    if (sq(common) > calm * calm || spread2 > calm * calm) continue;
    const double bound = std::max({kSurpriseMin * half, kSurpriseOwn * e.miss_distance * half,
                                   kSurpriseFrame * std::sqrt(spread2)});
    if (sq(shift_[a] - common) > bound * bound) {
      gain_[i * n_det + static_cast<size_t>(j)] = 0;
      refused = true;
    }
  }
  return refused;
}

Tracker::Sides Tracker::sidesLeftBy(const PoolEntry& e, cv::Size image) const {
  Sides out;
  if (image.width <= 0 || image.height <= 0) return out;
  const double w = image.width - 1.0, h = image.height - 1.0, scale = e.pred_size / e.size;
  for (const cv::Point2f& c : e.lm.corners) {  // where the prediction puts them
    const cv::Point2d p = e.pred_centre + (cv::Point2d(c) - e.centre) * scale;
    out.left |= p.x < 0;
    out.right |= p.x > w;
    out.top |= p.y < 0;
    out.bottom |= p.y > h;
  }
  // Only a side it was last seen near (in that half): one predicted to
  // have crossed the image while unseen, its motion ended (the robot
  // stopped), is found where it was.
  out.left &= e.centre.x < 0.5 * w;
  out.right &= e.centre.x > 0.5 * w;
  out.top &= e.centre.y < 0.5 * h;
  out.bottom &= e.centre.y > 0.5 * h;
  return out;
}

bool Tracker::Sides::towards(const cv::Point2d& d, cv::Size image) const {
  const double mx = 0.5 * (image.width - 1.0), my = 0.5 * (image.height - 1.0);
  return (left && d.x < mx) || (right && d.x > mx) || (top && d.y < my) || (bottom && d.y > my);
}

std::pair<double, double> Tracker::gateMargins(const cv::Point2d& centre, double size, size_t j,
                                               double max_dist) const {
  const double s1 = det_size_[j];
  if (!(std::max(size, s1) <= params_.max_size_ratio * std::min(size, s1))) return {-1, -1};
  // (in landmark sizes, as the gates: a pixel of a large landmark's margin
  // is worth no more than one of a small one's, or a large stale landmark
  // took the detection of a smaller one predicted exactly)
  const double half = 0.5 * (size + s1), d = dist(centre, det_centre_[j]) / half;
  return {max_dist - d, params_.max_distance - d};
}

void Tracker::updateMatched(PoolEntry& e, const Landmark& det, int d, int64_t utime) {
  const cv::Point2d centre = det_centre_[static_cast<size_t>(d)];
  const double size = det_size_[static_cast<size_t>(d)];
  const double dt = static_cast<double>(elapsedUs(utime, e.last_seen_utime)) * 1e-6;
  if (e.frames_since_seen > 0 && dist(e.centre, centre) < dist(e.pred_centre, centre)) {
    // Found where it was last seen, not where its motion led: that motion
    // has ended (the robot stopped or turned back).
    e.restart_motion = true;
  } else if (dt > 0) {
    if (e.frames_since_seen == 0 && e.motion == Motion::Measured)
      e.miss_distance += kMissDistanceWeight * (dist(e.pred_centre, centre) / (0.5 * (e.pred_size + size)) - e.miss_distance);
    const cv::Point2d v = (centre - e.centre) / dt;
    const double sr = (size - e.size) / dt;
    const double a = e.motion == Motion::Measured ? params_.velocity_smoothing : 1.0;
    e.velocity = a * v + (1.0 - a) * e.velocity;
    e.size_rate = a * sr + (1.0 - a) * e.size_rate;
    e.motion = Motion::Measured;
  }
  // The detection replaces the track's landmark; a payload read once stays.
  if (det.payload || !e.lm.payload) {
    e.lm = det;
  } else {
    e.lm.fip_tl = det.fip_tl;
    e.lm.fip_tr = det.fip_tr;
    e.lm.fip_bl = det.fip_bl;
    e.lm.ap = det.ap;
    e.lm.corners = det.corners;
    e.lm.score = det.score;
    e.lm.pose = det.pose;
  }
  e.centre = centre;
  e.size = size;
  e.seen_gap_us = elapsedUs(utime, e.last_seen_utime);
  e.last_seen_utime = utime;
  e.frames_since_seen = 0;
  countUp(e.hits);
}

void Tracker::report(int64_t utime) {
  size_t n = 0;
  for (const PoolEntry& e : pool_) {
    const bool visible = e.detection >= 0;
    if (e.hits < params_.min_hits || (!visible && !params_.report_coasting)) continue;
    if (n == out_.size()) out_.emplace_back();
    Track& t = out_[n++];
    t.id = e.id;
    t.age = e.age;
    t.hits = e.hits;
    t.frames_since_seen = e.frames_since_seen;
    t.time_since_seen_us = elapsedUs(utime, e.last_seen_utime);
    t.visible = visible;
    t.detection_index = visible ? det_index_[static_cast<size_t>(e.detection)] : -1;
    t.landmark = e.lm;
    if (!visible) moveLandmark(t.landmark, e.centre, e.pred_centre, e.pred_size / e.size);
    t.velocity = cv::Point2f(e.velocity);
  }
  // The vector keeps its capacity.
  out_.erase(out_.begin() + static_cast<long>(n), out_.end());
}

}  // namespace ld
