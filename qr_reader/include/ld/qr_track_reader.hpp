#pragma once
// What ld-qr-reader does with each frame whose image and tracked landmarks
// joined: follows the read tracks (a jump, or another code in a look at
// their modules, is another landmark), schedules
// the due tracks, decodes them within the frame's time budget, averages an
// undecoded track's frames when single frames fail, and lists the payloads
// known for the frame's tracks. The process only wires LCM to it.
#include <cstdint>
#include <ostream>
#include <unordered_map>
#include <utility>
#include <vector>

#include <opencv2/core.hpp>

#include "ld/image_t.hpp"
#include "ld/landmark_list_t.hpp"
#include "ld/lcm_url.hpp"
#include "ld/qr_code_list_t.hpp"
#include "ld/qr_reader.hpp"
#include "ld/qr_tracks.hpp"

namespace ld {

struct QrTrackReaderParams {
  QrScheduleParams schedule;
  /// Milliseconds of decoding per frame: once spent, the frame's other due
  /// tracks wait for the next (the first decode always runs). See DecodeBudget.
  double decode_budget_ms = 30;
  /// Frames of an undecoded track averaged in the sheet's frame and read
  /// when single frames fail (QrStack); 0: off.
  int stack_frames = 8;
  /// Seconds between looks at a read track: its modules in the frame
  /// against those of the frame it was read from (QrLook). A landmark that
  /// shows another code is read again at once, its payload withheld from
  /// the codes until a look sees its code again: another payload read
  /// replaces it; none read in kOtherLooks looks in a row, it is forgotten
  /// until it reads. 0 (or less): off.
  double look_interval_s = 0.2;
};

class QrTrackReader {
 public:
  /// Notes (a tracker that restarted, frames whose utime stands still) go to
  /// `log`; with `verbose`, each payload read and each jump too.
  QrTrackReader(const QrTrackReaderParams& params, std::ostream& log, bool verbose = false);

  /// One joined frame: `image` and the tracked landmarks found in it. Fills
  /// `out` (utime and seq of the frame, one code per track of the list whose
  /// payload is known and not withheld: QrTrackReaderParams::look_interval_s). The image's pixels are converted only when a track
  /// is due or a look (QrTrackReaderParams::look_interval_s); throws
  /// ImageFormatError (out untouched) when they cannot be.
  void process(const image_t& image, const landmark_list_t& list, qr_code_list_t& out);

  int64_t tracksRead() const { return decoded_; }        ///< payloads newly read (another than known too)
  int64_t tracksReadStacked() const { return decoded_stacked_; }  ///< ... of which from stacked frames
  /// Read tracks whose landmark showed another code (QrLook): read again as
  /// another payload, or forgotten when they did not read.
  int64_t tracksChanged() const { return changed_; }
  const QrTrackBook& book() const { return book_; }

 private:
  static constexpr size_t kMaxStacks = 32;  // undecoded tracks stacked at once
  static constexpr int kMinStackFrames = 3;  // frames stacked before the stack is read
  QrTrackReaderParams params_;
  std::ostream& log_;
  bool verbose_;
  QrReader reader_;
  // its own buffers (the stacks' views have their own size), and the
  // stacks' parameters (QrStack::readerParams)
  QrReader stack_reader_{QrStack::readerParams()};
  QrTrackBook book_;
  StillTimeWatch still_;
  std::unordered_map<int64_t, QrStack> stacks_;
  struct Look {
    QrLook look;  // of the frame of the last read that showed the modules sharply
    int64_t checked = INT64_MIN;  // utime of the last look at it
    int reads = 0;   // re-reads that took no look (none yet)
    int others = 0;  // looks in a row that saw another code, with no read since
  };
  std::unordered_map<int64_t, Look> looks_;  // read tracks only
  // Re-reads a read track without a look gets when a frame shows its
  // modules sharply (their reads failed: regular re-reads from then on).
  static constexpr int kLookReads = 3;
  static constexpr int kLookLessEvery = 5;  // (look intervals between tries for a look)
  static constexpr int kOtherLooks = 5;  // looks in a row seeing another code, unread, forget it
  QrLook spare_look_;  // (whether a frame shows a track's modules sharply)
  // Looks at the read tracks due for one: true when the image's pixels were
  // converted (into bgr_) for it.
  bool lookAtReadTracks(const image_t& image, const landmark_list_t& list);
  cv::Mat bgr_;
  std::vector<int64_t> ids_;
  std::vector<std::pair<int64_t, int32_t>> ages_;  // (track id, age) of every track of the frame
  std::vector<std::pair<int64_t, float>> tried_ms_;  // this frame's decodes: (track id, ms)
  int64_t decoded_ = 0, decoded_stacked_ = 0, changed_ = 0;
};

}  // namespace ld
