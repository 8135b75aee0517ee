#include "ld/qr_track_reader.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>

#include "ld/image_convert.hpp"
#include "ld/message_publisher.hpp"

namespace ld {

namespace {

// A tracked landmark's pattern corners (TL, TR, BR, BL) as the reader takes them.
std::array<cv::Point2f, 4> cornersOf(const landmark_t& lm) {
  std::array<cv::Point2f, 4> corners;
  for (size_t i = 0; i < 4; ++i) corners[i] = {lm.corners[i][0], lm.corners[i][1]};
  return corners;
}

// Whether a track's corners can be a landmark in a w x h image (0: size not
// known): finite, enclosing at least 4x4 px, none further out than the
// image's own size beyond its sides. Others (a foreign publisher's NaNs, a
// pattern collapsed to a point, corners at 1e30) are never due: each took a
// decode of the frame's few, before a readable track's turn.
bool readableCorners(const landmark_t& lm, int w, int h) {
  double area2 = 0;
  for (int i = 0; i < 4; ++i) {
    const float x = lm.corners[i][0], y = lm.corners[i][1];
    if (!std::isfinite(x) || !std::isfinite(y)) return false;
    if (w > 0 && h > 0 && (x < -w || x > 2.0 * w || y < -h || y > 2.0 * h)) return false;
    const int j = (i + 1) % 4;
    area2 += double{x} * lm.corners[j][1] - double{lm.corners[j][0]} * y;
  }
  return std::abs(area2) / 2 >= 16;
}

}  // namespace

bool QrTrackReader::lookAtReadTracks(const image_t& image, const landmark_list_t& list) {
  const double every_us = params_.look_interval_s * 1e6;
  bool converted = false;
  for (const auto& lm : list.landmarks) {
    if (!lm.visible || lm.track_id < 0) continue;
    const auto it = looks_.find(lm.track_id);  // (read tracks have one, empty or not)
    if (it == looks_.end()) continue;
    Look& look = it->second;
    if (look.look.empty() && look.reads >= kLookReads) continue;
    // (an older frame, matched late, is looked at too: what it shows is as
    // good; a track without a look is looked at every kLookLessEvery
    // intervals: one read only far may never show its modules sharply)
    const double wait_us = look.look.empty() ? kLookLessEvery * every_us : every_us;
    if (look.checked != INT64_MIN && list.utime >= look.checked &&
        static_cast<double>(list.utime) - static_cast<double>(look.checked) < wait_us)
      continue;
    if (!readableCorners(lm, image.width, image.height)) continue;
    if (!converted) {
      imageToBgr(image, bgr_);  // (throws before anything changes)
      converted = true;
    }
    look.checked = list.utime;
    if (look.look.empty()) {
      // Read from a frame that did not show its modules sharply (far,
      // blurred): where this one does, it is read again now, and the read
      // takes the look (a look taken without a read could be another code's).
      if (spare_look_.capture(bgr_, cornersOf(lm))) book_.readAgain(lm.track_id);
      continue;
    }
    if (look.look.compare(bgr_, cornersOf(lm)) != QrLook::Verdict::Other) {
      look.others = 0;
      continue;
    }
    // Another code: the payload is withheld (step 4) and the track read
    // again now. A read of another payload replaces it (step 3); a read of
    // the same one, or a later look that sees its code, says something over
    // the code fooled the look (a striped sleeve, a barcode sticker: a
    // review); no read for kOtherLooks looks in a row, and the payload
    // cannot be vouched for: it is forgotten until the code reads again.
    if (++look.others < kOtherLooks) {
      book_.readAgain(lm.track_id);
      continue;
    }
    look = Look{};
    const auto forgotten = book_.forget(lm.track_id);
    ++changed_;
    if (forgotten && verbose_)
      log_ << "ld-qr-reader: track " << lm.track_id << " shows another code than \"" << *forgotten << "\" in "
           << kOtherLooks << " looks in a row and does not read: it is forgotten until it reads (ids moved?)\n";
  }
  return converted;
}

QrTrackReader::QrTrackReader(const QrTrackReaderParams& params, std::ostream& log, bool verbose)
    : params_(params), log_(log), verbose_(verbose), book_(params.schedule) {}

void QrTrackReader::process(const image_t& image, const landmark_list_t& list, qr_code_list_t& out) {
  // 1. THE FRAME'S TRACKS
  ids_.clear();
  ages_.clear();
  for (const auto& lm : list.landmarks) {
    // (an id listed twice, by a publisher other than the tracker: due once)
    if (lm.visible && lm.track_id >= 0 && readableCorners(lm, image.width, image.height) &&
        std::find(ids_.begin(), ids_.end(), lm.track_id) == ids_.end())
      ids_.push_back(lm.track_id);
    if (lm.track_id >= 0) ages_.emplace_back(lm.track_id, lm.age);
  }
  // (a tracker that restarted numbers its tracks from 1 again: what was
  // read under the old ids belongs to other landmarks)
  if (book_.noteAges(ages_)) {
    stacks_.clear();
    log_ << "ld-qr-reader: track ids started again (a track is younger than it can be: the tracker "
            "restarted); the payloads read so far are forgotten\n";
  }
  // (a read track whose landmark jumped is another landmark now: the
  // tracker moved its id over; what was read is forgotten and read again)
  for (const auto& lm : list.landmarks) {
    if (lm.track_id < 0) continue;
    const std::array<cv::Point2f, 4> c = cornersOf(lm);
    double side = 0;
    for (size_t i = 0; i < 4; ++i) side += cv::norm(c[(i + 1) % 4] - c[i]) / 4;
    const cv::Point2f centre = (c[0] + c[1] + c[2] + c[3]) * 0.25f;
    const auto forgotten = book_.follow(lm.track_id, lm.age, lm.visible, centre.x, centre.y, side);
    if (forgotten && verbose_)
      log_ << "ld-qr-reader: track " << lm.track_id << " jumped by more than its landmark's size: \"" << *forgotten
           << "\" is forgotten and the track read again (ids moved?)\n";
    // (off its path by more than half that: looked at in this frame, not at
    // the next look's time, in case a neighbour within its size has the id)
    if (book_.strayed(lm.track_id))
      if (const auto look = looks_.find(lm.track_id); look != looks_.end()) look->second.checked = INT64_MIN;
  }
  // (a read track whose landmark shows another code is another landmark
  // within the tracker's gate: forgotten and read again, as a jump)
  for (auto it = looks_.begin(); it != looks_.end();) it = book_.payload(it->first) ? std::next(it) : looks_.erase(it);
  bool converted = params_.look_interval_s > 0 && lookAtReadTracks(image, list);
  if (still_.note(list.utime))
    log_ << "ld-qr-reader: 10 frames in a row with utime " << list.utime
         << ": retries and re-reads count time from it, so a track not read at once is not tried again "
            "while it stands still (does the publisher stamp its frames?)\n";

  // 2. SCHEDULE, AND THE STACKS OF TRACKS GONE OR READ
  const std::vector<int64_t> todo = book_.schedule(ids_, list.utime);
  for (auto it = stacks_.begin(); it != stacks_.end();) {
    const landmark_t* listed = nullptr;  // visible or coasting
    for (const auto& lm : list.landmarks)
      if (lm.track_id == it->first) listed = &lm;
    if (!listed || book_.payload(it->first)) {
      it = stacks_.erase(it);
      continue;
    }
    // where the track is in every frame: a jump is another landmark
    if (it->second.follow(cornersOf(*listed)) && verbose_)
      log_ << "ld-qr-reader: track " << it->first
           << " jumped by more than its landmark's side: its stacked frames start again (ids swapped?)\n";
    ++it;
  }
  if (!todo.empty() && !converted) imageToBgr(image, bgr_);  // (throws before out is touched)

  // 3. DECODE the due tracks in the schedule's order (undecoded first, least
  // recently tried first), while the frame's budget lasts: the ones left
  // stay due and lead the next frame's schedule. (In the list's order, the
  // first unreadable track took the budget every frame.)
  out.codes.clear();
  out.withheld_track_ids.clear();
  DecodeBudget budget(params_.decode_budget_ms);
  tried_ms_.clear();
  const int stack_frames = params_.stack_frames;
  for (const int64_t id : todo) {
    const auto lm = std::find_if(list.landmarks.begin(), list.landmarks.end(), [&](const landmark_t& l) {
      return l.track_id == id && l.visible && readableCorners(l, image.width, image.height);
    });
    if (lm == list.landmarks.end() || !budget.allows(std::chrono::steady_clock::now())) continue;
    const std::array<cv::Point2f, 4> corners = cornersOf(*lm);
    const auto t0 = std::chrono::steady_clock::now();
    auto r = reader_.decode(bgr_, corners);
    bool from_stack = false;
    if (!r && stack_frames > 0 && !book_.payload(id) && (stacks_.count(id) || stacks_.size() < kMaxStacks)) {
      QrStack& stack = stacks_.try_emplace(id, stack_frames).first->second;
      if (stack.add(bgr_, corners)) {
        stack.addFit(reader_);
        if (stack.frames() >= std::min(kMinStackFrames, stack_frames))
          from_stack = static_cast<bool>(r = stack.decode(stack_reader_));
      }
    }
    tried_ms_.emplace_back(id, std::chrono::duration<float, std::milli>(std::chrono::steady_clock::now() - t0).count());
    const auto* known = book_.payload(id);
    const bool is_new = r && (!known || known->payload != r->payload);
    bool said = false;  // (the change said already)
    decoded_stacked_ += is_new && from_stack;
    if (r && params_.look_interval_s > 0) {
      // the look of the code just read: this frame's, where it shows the
      // modules sharply; else the last one's, where it read the same
      Look& look = looks_[id];
      if (known && known->payload != r->payload) {
        if (look.others > 0) {  // (read again for a look that saw another code)
          ++changed_;
          said = verbose_;
          if (verbose_)
            log_ << "ld-qr-reader: track " << id << " shows another code than \"" << known->payload << "\": it reads \""
                 << r->payload << "\" now (ids moved?)\n";
        }
        look = Look{};
      }
      look.others = 0;
      // (a look kept: a frame with something over the code may read, and
      // its look would be the cover's)
      if (look.look.empty()) {
        if (spare_look_.capture(bgr_, corners)) std::swap(look.look, spare_look_);
        else if (known) ++look.reads;  // (a re-read for a look that took none)
      }
      look.checked = list.utime;
    } else if (known && params_.look_interval_s > 0) {
      const auto it = looks_.find(id);
      if (it != looks_.end() && it->second.look.empty()) ++it->second.reads;
    }
    book_.record(id, list.utime, list.seq, r ? std::optional<std::string>(r->payload) : std::nullopt);
    if (is_new) {
      ++decoded_;  // (its stack goes with the next frame's pruning)
      if (verbose_ && !said)
        log_ << "ld-qr-reader: track " << id << " reads \"" << r->payload << "\""
             << (from_stack ? " (from its stacked frames)" : "") << "\n";
    }
  }

  // 4. THE PAYLOADS KNOWN for the frame's tracks (but those whose last look
  // saw another code, not read since: withheld until a look sees theirs,
  // and listed as withheld)
  for (const auto& lm : list.landmarks) {
    if (lm.track_id < 0) continue;
    if (const auto* k = book_.payload(lm.track_id)) {
      if (const auto l = looks_.find(lm.track_id); l != looks_.end() && l->second.others > 0) {
        out.withheld_track_ids.push_back(lm.track_id);
        continue;
      }
      qr_code_t c{};
      c.track_id = lm.track_id;
      c.payload = ld::lcmString(k->payload);  // (a NUL byte: U+FFFD)
      c.utime = k->utime;
      c.seq = k->seq;
      for (int i = 0; i < 4; ++i)
        for (int j = 0; j < 2; ++j) c.corners[i][j] = lm.corners[i][j];
      const auto t = std::find_if(tried_ms_.begin(), tried_ms_.end(), [&](const auto& p) { return p.first == lm.track_id; });
      c.decode_ms = t == tried_ms_.end() ? 0.0f : t->second;
      out.codes.push_back(std::move(c));
    }
  }
  out.utime = list.utime;
  out.seq = list.seq;
  out.ncodes = static_cast<int32_t>(out.codes.size());
  out.nwithheld = static_cast<int32_t>(out.withheld_track_ids.size());
}

}  // namespace ld
