// ld-view: draws the tracked landmarks (track ids, payloads, pose axes) on
// the frames they were found in, matched by utime and seq. Reads the live
// bus (IMAGE, LANDMARKS_TRACKED, LANDMARK_CODES) or LCM logs, and shows the
// result in a window or writes PNGs / a video.
#include <atomic>
#include <cerrno>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <deque>
#include <filesystem>
#include <iostream>
#include <limits>
#include <map>
#include <set>
#include <optional>
#include <regex>

#include <CLI/CLI.hpp>
#include <lcm/lcm-cpp.hpp>
#include <opencv2/calib3d.hpp>
#include <opencv2/core/utils/logger.hpp>
#include <opencv2/highgui.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>
#include <fcntl.h>
#include <poll.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include "ld/cli.hpp"
#include "ld/camera.hpp"
#include "ld/file_checks.hpp"
#include "ld/image_convert.hpp"
#include "ld/landmark_json.hpp"
#include "ld/landmark_msg.hpp"
#include "ld/lcm_log_reader.hpp"
#include "ld/lcm_url.hpp"
#include "ld/message_decode.hpp"
#include "ld/qr_code_list_t.hpp"

namespace {

std::atomic<bool> g_stop{false};
void onSignal(int) { g_stop = true; }

using Key = std::pair<int64_t, int64_t>;  // (utime, seq)

// The calibration that draws the pose axes on frames of one size: scaled
// to it, as ld-detect and ld-detector scale it (axes drawn with a 1280x960
// calibration on 640x480 frames missed the landmark), or none where the
// frames have another aspect ratio (another crop of the sensor), said once.
class AxesCamera {
 public:
  explicit AxesCamera(ld::CameraModel model) : model_(std::move(model)) {}
  const ld::CameraModel* forFrame(cv::Size frame) {
    if (frame != size_) {
      size_ = frame;
      fits_ = model_.fits(frame);
      if (fits_) {
        scaled_ = model_.scaledTo(frame);
      } else if (!misfit_said_) {
        std::cerr << "ld-view: note: no pose axes: " << model_.misfit(frame) << "\n";
        misfit_said_ = true;
      }
    }
    return fits_ ? &scaled_ : nullptr;
  }

 private:
  ld::CameraModel model_, scaled_;
  cv::Size size_;
  bool fits_ = false, misfit_said_ = false;
};

struct Options {
  std::string out_dir, video;
  bool window = false;
  double fps = 30;
  mutable std::optional<AxesCamera> camera;  // (its scaled calibration kept for the frames' size)
  double axis_m = 0.1;
};

// Messages that are not what their channel carries: one line each, naming
// it (the first ten, then every hundredth, as every process says it), and
// counted.
struct Dropped {
  int64_t count = 0;
  void operator()(const std::string& what, const std::string& why) {
    if (ld::printBadLine(++count)) std::cerr << "ld-view: " << what << ": " << why << " " << ld::badSoFar(count) << "\n";
  }
};

// Where the annotated frames go: PNG files, a video, a window.
class Sink {
 public:
  explicit Sink(const Options& o) : o_(o) {}
  bool put(const cv::Mat& img, int64_t seq) {
    if (!o_.out_dir.empty()) {
      // DIR/SEQ.png; a name already written in this run (seq starting again:
      // a restarted camera, a second log) gets the next free -N, so no frame
      // is written over another
      // (a file of this run is one written since it started: no list of
      // names kept, which would grow with every frame of a live run)
      char name[32];
      std::snprintf(name, sizeof name, "%06lld", static_cast<long long>(seq < 0 ? count_ : seq));
      std::string path = o_.out_dir + "/" + name + ".png";
      for (int k = 2; writtenThisRun(path); ++k) path = o_.out_dir + "/" + name + "-" + std::to_string(k) + ".png";
      errno = 0;
      if (!cv::imwrite(path, img)) {
        // (the system's reason where the encoder's write left one: a full disk)
        std::cerr << "ld-view: cannot write " << path << (errno ? std::string(": ") + std::strerror(errno) : "")
                  << "\n";
        failed_ = true;
        return false;
      }
    }
    if (!o_.video.empty()) {
      if (!writer_.isOpened()) {
        writer_.open(o_.video, cv::VideoWriter::fourcc('M', 'J', 'P', 'G'), o_.fps, img.size());
        if (!writer_.isOpened()) {
          std::cerr << "ld-view: cannot open video " << o_.video << " (MJPG)\n";
          failed_ = true;
          return false;
        }
        size_ = img.size();
      }
      ++video_frames_;
      if (img.size() == size_) {
        writer_.write(img);
      } else {
        // (a video has one frame size: another size is scaled to it, said once)
        if (!resize_said_)
          std::cerr << "ld-view: note: " << img.cols << "x" << img.rows << " frames are scaled to the video's "
                    << size_.width << "x" << size_.height << "\n";
        resize_said_ = true;
        cv::resize(img, resized_, size_, 0, 0, cv::INTER_AREA);
        writer_.write(resized_);
      }
    }
    if (o_.window) {
      cv::imshow("ld-view", img);
      const int k = cv::waitKey(1);
      if (k == 'q' || k == 27) g_stop = true;
    }
    ++count_;
    return true;
  }
  int64_t count() const { return count_; }
  /// A frame could not be written (the run ends with status 1).
  bool failed() const { return failed_; }
  /// Closes the video and counts the frames its file holds: OpenCV's
  /// writer says nothing of a write that failed (a full disk left a video
  /// of 11 frames, no index, and "30 frames written", status 0). False, said,
  /// when it holds fewer than were written.
  bool finish() {
    if (!writer_.isOpened()) return true;
    writer_.release();
    // (counted in the file: OpenCV's own reader counts the first GiB's
    // frames alone, and FFmpeg's the frames a cut video's header announced)
    const int64_t held = std::max<int64_t>(0, ld::aviVideoFrames(o_.video));
    if (held >= video_frames_) return true;
    std::cerr << "ld-view: --video " << o_.video << " holds " << held << " of the " << video_frames_
              << " frames written (" << (held == 0 ? "it cannot be read back" : "cut short") << ": is the disk full?)\n";
    failed_ = true;
    return false;
  }

 private:
  bool writtenThisRun(const std::string& path) const {
    std::error_code ec;
    const auto t = std::filesystem::last_write_time(path, ec);
    return !ec && t >= started_;
  }
  const Options& o_;
  // (a second before the start: file times may be coarser than the clock)
  const std::filesystem::file_time_type started_ =
      std::filesystem::file_time_type::clock::now() - std::chrono::seconds(1);
  cv::VideoWriter writer_;
  cv::Size size_;
  cv::Mat resized_;
  bool resize_said_ = false, failed_ = false;
  int64_t count_ = 0, video_frames_ = 0;
};

// Draws one frame: every visible track with its id and payload (LANDMARK.md's
// overlay: outline, centres, TL marked), coasting tracks as a thin grey
// outline at their predicted place, pose axes when the pose is known and a
// calibration was given.
void annotate(cv::Mat& bgr, const ld::landmark_list_t& list, const std::map<int64_t, std::string>& payloads,
              const Options& o) {
  const int thick = std::max(1, bgr.cols / 640);
  std::vector<ld::Landmark> visible;
  size_t out_of_view = 0;  // coasting tracks predicted past the frame's edges
  for (const auto& m : list.landmarks) {
    ld::Landmark lm = ld::fromMessage(m);
    // The label drawLandmarks writes by the TL corner: "#id payload".
    const auto p = payloads.find(m.track_id);
    lm.payload = "#" + std::to_string(m.track_id) + (p != payloads.end() ? " " + p->second : "");
    if (!m.visible) {
      std::vector<cv::Point> quad;
      for (const auto& c : lm.corners) quad.emplace_back(cvRound(c.x), cvRound(c.y));
      // (one predicted past the edges is counted in the header: its label,
      // kept inside the frame, was drawn over the header's corner)
      if ((cv::boundingRect(quad) & cv::Rect(0, 0, bgr.cols, bgr.rows)).empty()) {
        ++out_of_view;
        continue;
      }
      cv::polylines(bgr, quad, true, cv::Scalar(160, 160, 160), 1, cv::LINE_AA);
      ld::drawLabel(bgr, *lm.payload + " (coasting)", lm.corners[0] + cv::Point2f(0, -6.0f * thick),
                    cv::Scalar(160, 160, 160), thick);
    } else {
      visible.push_back(lm);
    }
    const ld::CameraModel* camera = m.visible && m.pose_valid && o.camera ? o.camera->forFrame(bgr.size()) : nullptr;
    if (camera) {
      const cv::Vec3d rvec(m.rvec[0], m.rvec[1], m.rvec[2]), t(m.t[0], m.t[1], m.t[2]);
      cv::drawFrameAxes(bgr, cv::Mat(camera->K), camera->dist.empty() ? cv::Mat() : camera->dist, rvec, t,
                        static_cast<float>(o.axis_m), thick);
    }
  }
  ld::drawLandmarks(bgr, visible);
  char head[160];
  std::snprintf(head, sizeof head, "seq %lld  %zu tracked, %zu visible%s", static_cast<long long>(list.seq),
                list.landmarks.size(), visible.size(),
                out_of_view ? cv::format(", %zu coasting out of view", out_of_view).c_str() : "");
  cv::putText(bgr, head, cv::Point(8, 20 * thick), cv::FONT_HERSHEY_SIMPLEX, 0.55 * thick,
              cv::Scalar(0, 0, 0), 3 * thick, cv::LINE_AA);
  cv::putText(bgr, head, cv::Point(8, 20 * thick), cv::FONT_HERSHEY_SIMPLEX, 0.55 * thick,
              cv::Scalar(255, 255, 255), thick, cv::LINE_AA);
}

// --- logs: tracked lists and codes first, then every image in log order ---
int viewLogs(const std::vector<std::string>& logs, const std::string& image_ch, const std::string& tracked_ch,
             const std::string& codes_ch, bool all_frames, const ld::LogSpan& span, const Options& o) {
  std::map<Key, ld::landmark_list_t> lists;
  std::map<Key, ld::qr_code_list_t> codes;
  Dropped dropped;
  std::string why;
  int64_t lists_again = 0;  // (lists for a frame already listed: two runs' logs)
  ld::ChannelCounts log_channels;  // (named where a channel asked for has nothing)
  for (const auto& path : logs) {
    ld::LcmLogReader log(path);
    if (!log.good()) {
      std::cerr << "ld-view: cannot read log " << path << "\n";
      return 2;
    }
    while (log.next()) {
      ++log_channels[log.channel];
      if (log.channel == tracked_ch) {
        ld::landmark_list_t l;
        if (ld::decodeMessage(log.data.data(), log.data.size(), l, &why)) {
          auto [it, added] = lists.try_emplace(Key{l.utime, l.seq});
          lists_again += !added;
          it->second = std::move(l);
        } else {
          dropped(path + ": dropped message on " + log.channel, why);
        }
      } else if (log.channel == codes_ch) {
        ld::qr_code_list_t c;
        if (ld::decodeMessage(log.data.data(), log.data.size(), c, &why)) codes[{c.utime, c.seq}] = std::move(c);
        else dropped(path + ": dropped message on " + log.channel, why);
      }
    }
    if (!log.problem().empty())  // a cut log: what it holds is drawn
      std::cerr << "ld-view: warning: " << path << ": " << log.problem() << "\n";
  }
  Sink sink(o);
  std::map<int64_t, std::string> payloads;  // what was known up to the frame drawn
  ld::image_t img;
  cv::Mat bgr;
  int64_t images = 0, events = 0;
  std::set<Key> imaged;  // (the listed frames whose image came)
  int64_t outside = 0;  // images outside --from/--to
  double images_from_s = std::numeric_limits<double>::infinity(), images_to_s = -images_from_s;
  for (const auto& path : logs) {
    ld::LcmLogReader log(path);
    int64_t first = -1;
    while (!g_stop && log.next()) {
      ++events;
      if (first < 0) first = log.timestamp;
      if (log.channel != image_ch) continue;
      const double at_s = static_cast<double>(log.timestamp - first) / 1e6;
      images_from_s = std::min(images_from_s, at_s);
      images_to_s = std::max(images_to_s, at_s);
      if (!span.holds(first, log.timestamp)) {
        ++outside;
        continue;
      }
      if (!ld::decodeMessage(log.data.data(), log.data.size(), img, &why)) {
        dropped(path + ": dropped message on " + log.channel, why);
        continue;
      }
      try {  // (a message that is no image is bad, not an image, whatever was wrong with it)
        ld::checkImage(img);
      } catch (const ld::ImageFormatError& e) {
        dropped(path + ": dropped message on " + log.channel, e.what());
        continue;
      }
      ++images;
      const Key key{img.utime, ld::imageSeq(img).value_or(-1)};
      const auto l = lists.find(key);
      if (l == lists.end() && !all_frames) continue;
      if (l != lists.end()) imaged.insert(key);
      const auto c = codes.find(key);
      if (c != codes.end()) ld::takeCodes(c->second, payloads);
      try {
        ld::imageToBgr(img, bgr);
      } catch (const std::exception& e) {
        --images;  // (its JPEG data damaged: bad, not an image)
        dropped(path + ": dropped message on " + log.channel, e.what());
        continue;
      }
      if (l != lists.end()) annotate(bgr, l->second, payloads, o);
      if (!sink.put(bgr, key.second)) return 1;
    }
  }
  const bool video_whole = sink.finish();
  // (drawn, not written, where the video holds fewer: the line said "60
  // frames written" under the one that said it held 6)
  std::fprintf(stderr, "ld-view: %lld images, %zu tracked lists, %lld frames %s%s\n",
               static_cast<long long>(images), lists.size(), static_cast<long long>(sink.count()),
               video_whole ? "written" : "drawn (the video holds fewer: above)",
               dropped.count ? (", " + std::to_string(dropped.count) + " bad").c_str() : "");
  // (two runs' lists for the same frames: only the last log's were drawn,
  // without a word; and lists whose image no log holds, a cut image log's)
  if (lists_again > 0)
    std::fprintf(stderr,
                 "ld-view: note: %lld tracked lists came again for frames already listed (two runs' logs, or a "
                 "recording that also holds a replayed run's?): each frame is drawn with the last one\n",
                 static_cast<long long>(lists_again));
  if (!g_stop && images > 0 && imaged.size() < lists.size() && !span.limited())
    std::fprintf(stderr, "ld-view: note: %zu of the %zu tracked lists have no image in the logs: not drawn\n",
                 lists.size() - imaged.size(), lists.size());
  if (events == 0) std::fprintf(stderr, "ld-view: the logs hold no message: nothing to draw\n");
  else if (images == 0 && outside > 0 && !g_stop)
    std::fprintf(stderr,
                 "ld-view: no image %s after its log's first message (the images lie %.3f to %.3f s after "
                 "their log's first)\n",
                 span.text().c_str(), images_from_s, images_to_s);
  else if (images == 0 && !g_stop)
    std::fprintf(stderr, "ld-view: no images on %s in the logs (their channels: %s): frames are drawn on their "
                         "images (give the image log too: --log images.lcmlog --log run.lcmlog, or --image CHANNEL)\n",
                 image_ch.c_str(), ld::describeChannels(log_channels).c_str());
  if (sink.count() == 0 && images > 0 && imaged.empty() && !all_frames)
    std::fprintf(stderr, "ld-view: %s; --all draws every image\n",
                 lists.empty() ? ("no tracked lists on " + tracked_ch + " (the logs' channels: " +
                                  ld::describeChannels(log_channels) + ")")
                                     .c_str()
                               : "no tracked list has an image's utime and seq (logs of different runs?)");
  return sink.count() > 0 && video_whole ? 0 : 1;
}

// --- live bus: recent images kept; after each drain of the bus, the tracked
// lists that came drawn in turn on their images, at most kMaxBehind of them
// (a viewer slower than the camera drops the oldest, counting them, rather
// than falling ever further behind) ---
class Live {
 public:
  Live(const Options& o, std::string image_ch) : sink_(o), o_(o), image_ch_(std::move(image_ch)) {}
  void onImage(const lcm::ReceiveBuffer* rb, const std::string& channel) {
    queues[0].fit(rb->data_size);
    // The last kRecentFrames frames; the one that drops out lends its
    // buffer to the next (no copy, no allocation once they are all there).
    if (!decoded(rb, spare_, channel)) return;
    const Key key{spare_.utime, ld::imageSeq(spare_).value_or(-1)};
    recent_.emplace_back(key, std::move(spare_));
    if (recent_.size() > kRecentFrames) {
      spare_ = std::move(recent_.front().second);
      recent_.pop_front();
    }
  }
  void onCodes(const lcm::ReceiveBuffer* rb, const std::string& channel) {
    queues[2].fit(rb->data_size);
    ld::qr_code_list_t c;
    if (!decoded(rb, c, channel)) return;
    ld::takeCodes(c, payloads_);
  }
  void onTracked(const lcm::ReceiveBuffer* rb, const std::string& channel) {
    queues[1].fit(rb->data_size);
    if (!decoded(rb, list_, channel)) return;
    pending_.push_back(std::move(list_));
    if (pending_.size() > kMaxBehind) {
      pending_.pop_front();
      ++skipped_;
    }
  }
  /// The tracked lists not drawn yet, each on its image (when it is among
  /// the recent ones), oldest first.
  void drawPending() {
    while (!pending_.empty() && !g_stop) {
      list_ = std::move(pending_.front());
      pending_.pop_front();
      drawList();
    }
  }

 private:
  void drawList() {
    for (auto it = recent_.rbegin(); it != recent_.rend(); ++it) {
      if (it->first != Key{list_.utime, list_.seq}) continue;
      try {
        ld::imageToBgr(it->second, bgr_);
      } catch (const std::exception& e) {
        dropped_("dropped image on " + image_ch_, e.what());
        return;
      }
      annotate(bgr_, list_, payloads_, o_);
      if (!sink_.put(bgr_, list_.seq)) g_stop = true;
      return;
    }
  }
 public:
  int64_t frames() const { return sink_.count(); }
  int64_t skipped() const { return skipped_; }
  int64_t bad() const { return dropped_.count; }
  bool failed() const { return sink_.failed(); }
  bool finish() { return sink_.finish(); }
  // Image, tracks and codes: while a frame is drawn and written, what comes
  // waits in a queue held to a byte budget, not LCM's 30 messages, which
  // dropped the newer ones without a word (ld::QueueFit); the next drain
  // takes it all, and only the newest list is drawn.
  ld::QueueFit queues[3];

 private:
  template <class T>
  bool decoded(const lcm::ReceiveBuffer* rb, T& msg, const std::string& channel) {
    std::string why;
    if (ld::decodeMessage(rb->data, rb->data_size, msg, &why)) return true;
    dropped_("dropped message on " + channel, why);
    return false;
  }
  Dropped dropped_;
  Sink sink_;
  const Options& o_;
  std::string image_ch_;
  static constexpr size_t kRecentFrames = 60;
  ld::image_t spare_;
  ld::landmark_list_t list_;
  // Tracked lists not drawn yet; beyond kMaxBehind (a quarter of a second at
  // 30 fps) the oldest is dropped, counted in skipped_.
  static constexpr size_t kMaxBehind = 8;
  std::deque<ld::landmark_list_t> pending_;
  int64_t skipped_ = 0;
  cv::Mat bgr_;
  std::deque<std::pair<Key, ld::image_t>> recent_;
  std::map<int64_t, std::string> payloads_;
};

// Whether a window can be opened here, found out in a child process: the
// Qt highgui aborts the whole process when its display does not answer
// (DISPLAY=:99 with no server there). Empty when it can; otherwise why (the
// child's first line on stderr, or how it ended). Call before any thread
// exists.
std::string probeWindow() {
  std::signal(SIGCHLD, SIG_DFL);  // so that the child can be waited for (an ignored SIGCHLD is inherited)
  int err[2];
  if (::pipe2(err, O_CLOEXEC) != 0) return std::string("pipe: ") + std::strerror(errno);
  const pid_t pid = ::fork();
  if (pid < 0) return std::string("fork: ") + std::strerror(errno);
  if (pid == 0) {
    const rlimit no_core{0, 0};
    ::setrlimit(RLIMIT_CORE, &no_core);  // an abort here is an answer, not a crash to keep
    ::dup2(err[1], STDERR_FILENO);
    const int null = ::open("/dev/null", O_WRONLY);
    if (null >= 0) ::dup2(null, STDOUT_FILENO);
    try {
      cv::namedWindow("ld-view");
    } catch (const std::exception& e) {
      std::fprintf(stderr, "%s\n", e.what());
      ::_exit(1);
    }
    ::_exit(0);
  }
  ::close(err[1]);
  // Its stderr until it ends (not until the pipe closes: a helper Qt started
  // may hold it), at most 10 s.
  std::string text;
  char buf[4096];
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(10);
  pollfd pfd{err[0], POLLIN, 0};
  int ws = 0;
  bool ended = false;
  while (true) {
    if (!ended) ended = ::waitpid(pid, &ws, WNOHANG) == pid;
    const int r = ::poll(&pfd, 1, ended ? 0 : 20);
    if (r > 0) {
      const ssize_t n = ::read(err[0], buf, sizeof buf);
      if (n > 0) {
        if (text.size() < 65536) text.append(buf, static_cast<size_t>(n));
        if (std::chrono::steady_clock::now() <= deadline) continue;  // more may be waiting
      }
      if (!ended) pfd.fd = -1;  // closed: only the child's end is left to wait for
    }
    if (ended || std::chrono::steady_clock::now() > deadline) break;
  }
  ::close(err[0]);
  if (!ended) {
    ::kill(pid, SIGKILL);
    while (::waitpid(pid, &ws, 0) < 0 && errno == EINTR) {
    }
    return "no answer in 10 s";
  }
  if (WIFEXITED(ws) && WEXITSTATUS(ws) == 0) return "";
  std::string first;  // the first line that says something
  size_t at = 0;
  while (first.empty() && at < text.size()) {
    size_t end = text.find('\n', at);
    if (end == std::string::npos) end = text.size();
    first = text.substr(at, end - at);
    first.erase(0, first.find_first_not_of(" \t\r"));
    first.erase(first.find_last_not_of(" \t\r") + 1);
    at = end + 1;
  }
  const std::string how = WIFSIGNALED(ws) ? "killed by " + std::string(strsignal(WTERMSIG(ws)))
                                          : "exit status " + std::to_string(WEXITSTATUS(ws));
  return first.empty() ? how : first;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"ld-view: tracked landmarks drawn on their frames, live or from LCM logs."};
  std::vector<std::string> logs;
  std::string url = ld::defaultLcmUrl(), image_ch = "IMAGE", tracked_ch = "LANDMARKS_TRACKED",
              codes_ch = "LANDMARK_CODES", camera_file;
  bool all_frames = false, force_window = false;
  bool out_made = false;  // (--out's folder made by this run)
  Options o;
  app.add_option("--log", logs, "read these LCM logs instead of the bus (images, tracks and codes "
                                "may be in different logs; repeatable)");
  app.add_option("--out,-o", o.out_dir, "write annotated frames as DIR/SEQ.png");
  app.add_option("--video", o.video, "write annotated frames to this video (MJPG in AVI: its name ends in .avi)");
  app.add_flag("--window", force_window, "show a window (default when a display exists and no --out/--video)");
  app.add_option("--fps", o.fps, "frame rate of --video (0.1 to 1000)")->check(ld::cli::Between(0.1, 1000))->capture_default_str();
  app.add_option("--camera", camera_file, "camera calibration (OpenCV YAML/XML, ROS camera_info, opencv_interactive-calibration): draws pose axes");
  app.add_option("--axis-length", o.axis_m, "pose axis length, metres")->check(ld::cli::Positive)->capture_default_str();
  app.add_flag("--all", all_frames, "logs: also frames without tracked landmarks");
  ld::LogSpan span;
  app.add_option("--from", span.from_s, "logs: only images logged this many seconds or more after their log's first message")
      ->check(ld::cli::NonNegative);
  app.add_option("--to", span.to_s, "logs: only images logged at most this many seconds after their log's first message")
      ->check(ld::cli::NonNegative);
  app.add_option("--lcm-url", url, "LCM URL (live)")->capture_default_str();
  app.add_option("--image", image_ch, "image channel")->capture_default_str();
  app.add_option("--tracks", tracked_ch, "tracked landmarks channel")->capture_default_str();
  app.add_option("--codes", codes_ch, "QR codes channel")->capture_default_str();
  LD_CLI_PARSE(app, argc, argv);
  cv::utils::logging::setLogLevel(cv::utils::logging::LOG_LEVEL_SILENT);  // our own one-line errors

  // (an empty variable is no display)
  const auto envSet = [](const char* name) -> const char* {
    const char* v = std::getenv(name);
    return v && *v ? v : nullptr;
  };
  const char* x_display = envSet("DISPLAY");
  const char* wayland_display = envSet("WAYLAND_DISPLAY");
  const bool display = x_display || wayland_display;
  for (const auto& [option, name] : {std::pair<const char*, const std::string*>{"--image", &image_ch},
                                     {"--tracks", &tracked_ch},
                                     {"--codes", &codes_ch}}) {
    // (live, they are LCM subscriptions; in logs, names matched as they are)
    const std::string problem = logs.empty()    ? ld::inputChannelProblem({option, *name})
                                : name->empty() ? std::string(option) + " needs a channel name"
                                                : "";
    if (!problem.empty()) return ld::cli::usage(argv[0], problem);
  }
  if (all_frames && logs.empty())
    return ld::cli::usage(argv[0], "--all is for --log (live, every frame with a tracked list is drawn)");
  if (logs.empty() && span.limited())
    return ld::cli::usage(argv[0], "--from and --to are for --log (seconds after a log's first message)");
  if (const std::string problem = span.problem(); !problem.empty()) return ld::cli::usage(argv[0], problem);
  if (!logs.empty() && app.count("--lcm-url"))
    return ld::cli::usage(argv[0], "--lcm-url is for live viewing (--log reads its files)");
  if (!o.video.empty() && !ld::hasExtension(o.video, ".avi"))
    return ld::cli::usage(argv[0], "--video " + o.video + ": the video is MJPG in AVI, its name must end in .avi");
  o.window = force_window || (display && o.out_dir.empty() && o.video.empty());
  if (!o.window && o.out_dir.empty() && o.video.empty()) {
    return ld::cli::usage(argv[0], "no display: give --out DIR or --video FILE");
  }
  if (o.window) {
    const std::string why = probeWindow();
    if (!why.empty()) {
      const std::string where = x_display         ? std::string(" on display ") + x_display
                                : wayland_display ? std::string(" on Wayland display ") + wayland_display
                                                  : ": DISPLAY and WAYLAND_DISPLAY are unset";
      std::cerr << "ld-view: cannot open a window" << where << " (" << why << "); "
                << (o.out_dir.empty() && o.video.empty() ? "give --out DIR or --video FILE" : "drop --window")
                << "\n";
      return 2;
    }
  }
  if (!camera_file.empty()) {
    try {
      o.camera.emplace(ld::CameraModel::load(camera_file));
    } catch (const std::exception& e) {
      std::cerr << "ld-view: " << e.what() << "\n";
      return 2;
    }
  }
  // (the logs first: a refused run creates no folder)
  for (const auto& path : logs) {
    const ld::LcmLogCheck start = ld::checkLcmLogStart(path);
    if (start.start == ld::LcmLogStart::NotALog || start.start == ld::LcmLogStart::Unreadable) {
      std::cerr << "ld-view: log " << path << " " << start.problem << "\n";
      return 2;
    }
  }
  if (!o.out_dir.empty()) {  // created when missing, and written in
    // Not over frames already there: ld-synth's (its frames are named as
    // ld-view names its own, SEQ.png), or an earlier run's, were written
    // over without a word.
    std::error_code ec;
    int64_t frames = 0;
    std::string first;
    static const std::regex frame_name(R"(\d+(-\d+)?\.png)");
    for (std::filesystem::directory_iterator it(o.out_dir, ec), end; !ec && it != end; it.increment(ec)) {
      const std::string name = it->path().filename().string();
      if (!std::regex_match(name, frame_name)) continue;
      if (frames++ == 0 || name < first) first = name;
    }
    if (frames > 0) {
      std::cerr << "ld-view: --out " << o.out_dir << " holds " << frames << " frame" << (frames == 1 ? "" : "s")
                << " named as ld-view names its own (" << first << (frames > 1 ? ", ..." : "")
                << "): they would be written over; give an empty or new folder\n";
      return 2;
    }
    std::error_code exists_ec;
    out_made = !std::filesystem::exists(o.out_dir, exists_ec);
    const std::string problem = ld::prepareOutputFolder(o.out_dir);
    if (!problem.empty()) {
      std::cerr << "ld-view: --out " << o.out_dir << ": " << problem << "\n";
      return 2;
    }
  }
  if (!o.video.empty()) {
    // (not over one of its inputs: `--log run.avi --video run.avi` replaced
    // the recording with a one-frame video; nor over anything not a video)
    std::vector<ld::NamedFile> inputs{{"--camera", camera_file}};
    for (const auto& path : logs) inputs.push_back({"--log", path});
    if (const std::string clash = ld::outputsClash({{"--video", o.video}}, inputs); !clash.empty())
      return ld::cli::usage(argv[0], clash);
    const std::string problem = ld::prepareVideoOutputFile(o.video);  // creates missing folders, as --out does
    if (!problem.empty()) {
      std::cerr << "ld-view: --video " << o.video << ": " << problem << "\n";
      return 2;
    }
  }
  std::signal(SIGINT, onSignal);
  std::signal(SIGTERM, onSignal);
  // (a folder it made and wrote nothing in is removed: a run that drew
  // nothing left an empty folder behind)
  const auto tidy = [&](int status) {
    std::error_code ec;
    if (out_made && std::filesystem::is_empty(o.out_dir, ec) && !ec) std::filesystem::remove(o.out_dir, ec);
    return status;
  };
  if (!logs.empty()) return tidy(viewLogs(logs, image_ch, tracked_ch, codes_ch, all_frames, span, o));

  if (!ld::lcmUrlUsable(url, "ld-view")) return 2;
  lcm::LCM lcm(url);
  if (const int status = ld::lcmOpenStatus(lcm, url, "ld-view")) return status;
  Live live(o, image_ch);
  live.queues[0] = ld::QueueFit(lcm.subscribe(image_ch, &Live::onImage, &live));
  live.queues[1] = ld::QueueFit(lcm.subscribe(tracked_ch, &Live::onTracked, &live));
  live.queues[2] = ld::QueueFit(lcm.subscribe(codes_ch, &Live::onCodes, &live));
  while (!g_stop) {
    if (!ld::pumpLcm(lcm, 200, g_stop, "ld-view")) return tidy(1);
    live.drawPending();
  }
  live.finish();
  std::string more;
  if (live.skipped() > 0) more += ", " + std::to_string(live.skipped()) + " skipped (drawing was slower than the camera)";
  if (live.bad() > 0) more += ", " + std::to_string(live.bad()) + " bad";
  std::fprintf(stderr, "ld-view: %lld frames drawn%s\n", static_cast<long long>(live.frames()), more.c_str());
  return tidy(live.failed() ? 1 : 0);
}
