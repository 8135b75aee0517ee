// ld-soak: drives the process set (ld-detector, ld-tracker, ld-qr-reader)
// with synthetic camera frames for a chosen time and reports, over time, each
// process's memory (VmRSS) and open file descriptors, and the messages on
// each link: what was published, received, deliberately skipped (the
// processes' own frames_skipped counts) and lost. Ends with a verdict: memory
// flat, fds flat, nothing lost but the deliberate skips.
//
// LCM stays inside a private network namespace: run it as
//   scripts/netns-run.sh build/bin/ld-soak --duration 600
#include <fcntl.h>
#include <signal.h>
#include <sys/prctl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <regex>
#include <string>
#include <thread>
#include <vector>

#include <CLI/CLI.hpp>
#include <lcm/lcm-cpp.hpp>

#include "ld/cli.hpp"
#include "ld/image_convert.hpp"
#include "ld/lcm_url.hpp"
#include "ld/message_decode.hpp"
#include "ld/netns.hpp"
#include "ld/supervisor.hpp"
#include "ld/synth.hpp"

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

namespace {

struct Options {
  double duration_s = 60;
  double fps = 30;
  int width = 1920, height = 1080;
  int landmarks = 4;
  int loop_frames = 30;
  std::string format = "mjpeg";
  double sample_s = 5;
  double warmup_s = 20;
  std::string bin_dir;
  std::string log_dir;
  std::string csv;
  double max_growth_mb = 8;  // allowed RSS growth after the warm-up, per process
};

// One process of the set, started with its stderr in a file.
struct Child {
  std::string name;
  pid_t pid = -1;
  std::string err_path;
  bool reaped = false;  // ended during the run (its status was taken then)
};

// SIGINT / SIGTERM (Ctrl-C, timeout, systemd): the run stops publishing and
// ends as usual, the set stopped and the verdict printed.
std::atomic<bool> g_stop{false};
void onSignal(int) { g_stop = true; }

Child spawn(const std::string& bin_dir, const std::string& name, const std::string& url,
            const std::string& log_dir) {
  Child c{name, -1, log_dir + "/" + name + ".err"};
  const std::string exe = bin_dir + "/" + name;
  const pid_t parent = getpid();
  const pid_t pid = fork();
  if (pid < 0) throw std::runtime_error("fork failed");
  if (pid == 0) {
    prctl(PR_SET_PDEATHSIG, SIGTERM);  // (ld-soak killed outright: the set goes too)
    if (getppid() != parent) _exit(1);  // (it died before the line above)
    const int fd = open(c.err_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    if (fd >= 0) {
      dup2(fd, 2);
      close(fd);
    }
    // (none of ld-soak's own files: --csv's was counted in each process's fds)
    for (int other = 3, last = static_cast<int>(sysconf(_SC_OPEN_MAX)); other < std::min(last, 4096); ++other)
      close(other);
    execl(exe.c_str(), name.c_str(), "--lcm-url", url.c_str(), static_cast<char*>(nullptr));
    std::perror(exe.c_str());
    _exit(127);
  }
  c.pid = pid;
  return c;
}

struct ProcSample {
  double rss_mb = 0;
  int fds = 0;
  bool alive = false;
};

ProcSample sampleProcess(pid_t pid) {
  ProcSample s;
  std::ifstream status("/proc/" + std::to_string(pid) + "/status");
  std::string line;
  while (std::getline(status, line))
    if (line.rfind("VmRSS:", 0) == 0) {
      s.rss_mb = std::stod(line.substr(6)) / 1024.0;
      s.alive = true;
    }
  std::error_code ec;
  for (auto it = fs::directory_iterator("/proc/" + std::to_string(pid) + "/fd", ec);
       !ec && it != fs::directory_iterator(); it.increment(ec))
    ++s.fds;
  return s;
}

// What ld-soak hears back on the output channels.
struct Outputs {
  int64_t landmarks = 0, tracked = 0, codes = 0;
  int64_t detector_skipped = 0;  // the detector's own count, latest
  int64_t landmarks_with_detections = 0, codes_entries = 0, bad = 0;
  ld::landmark_list_t list;
  ld::qr_code_list_t code_list;

  ld::QueueFit queues[3];  // landmarks, tracked, codes (ld::QueueFit)
  void onLandmarks(const lcm::ReceiveBuffer* rb, const std::string&) {
    queues[0].fit(rb->data_size);
    if (!ld::decodeMessage(rb->data, rb->data_size, list)) return void(++bad);
    ++landmarks;
    detector_skipped = list.frames_skipped;
    if (!list.landmarks.empty()) ++landmarks_with_detections;
  }
  void onTracked(const lcm::ReceiveBuffer* rb, const std::string&) {
    queues[1].fit(rb->data_size);
    if (!ld::decodeMessage(rb->data, rb->data_size, list)) return void(++bad);
    ++tracked;
  }
  void onCodes(const lcm::ReceiveBuffer* rb, const std::string&) {
    queues[2].fit(rb->data_size);
    if (!ld::decodeMessage(rb->data, rb->data_size, code_list)) return void(++bad);
    ++codes;
    codes_entries += code_list.ncodes;
  }
  // LCM's self test of each process that starts (see the wait for the set)
  int64_t self_tests = 0;
  std::chrono::steady_clock::time_point last_self_test{};
  void onSelfTest(const lcm::ReceiveBuffer*, const std::string&) {
    ++self_tests;
    last_self_test = std::chrono::steady_clock::now();
  }
};

// The frames of the loop: the landmarks drift a little from frame to frame
// (the tracker follows them) over an office background, with fresh sensor
// noise in each frame.
std::vector<ld::image_t> renderLoop(const Options& o) {
  const ld::CameraModel camera = ld::CameraModel::pinhole({o.width, o.height}, 0.75 * o.width);
  std::vector<ld::synth::LandmarkPlacement> base;
  for (int k = 0; k < o.landmarks; ++k) {
    const double nx = o.landmarks == 1 ? 0.0 : -0.65 + 1.3 * k / (o.landmarks - 1);
    const double ny = (k % 2 ? 0.35 : -0.3);
    base.push_back(ld::synth::placeLandmark(camera, 1.4 + 0.5 * (k % 3), -25.0 + 17.0 * k, 0, 8.0 * k,
                                            nx, ny, 0.2, "soak-" + std::to_string(k), k));
  }
  const int32_t format = ld::pixelFormatFromName(o.format);
  std::vector<ld::image_t> frames;
  for (int i = 0; i < o.loop_frames; ++i) {
    ld::synth::SceneSpec spec;
    spec.camera = camera;
    spec.background = ld::synth::Background::Office;
    spec.distractors = 6;
    spec.seed = 5;
    spec.noise_seed = 1000 + static_cast<uint64_t>(i);
    spec.degradation.noise_sigma = 2.0;
    const double phase = 2 * 3.14159265358979 * i / o.loop_frames;  // the loop closes smoothly
    for (auto lm : base) {
      lm.tvec[0] += 0.04 * std::sin(phase + lm.id);
      lm.tvec[1] += 0.02 * std::cos(phase + lm.id);
      spec.landmarks.push_back(lm);
    }
    const ld::synth::Frame f = ld::synth::render(spec);
    frames.push_back(ld::matToImage(f.bgr, format, 0, 0, 85));
  }
  return frames;
}

// The counts of a process's "stopped after ..." line, by their labels (the
// lines gain counts over time; their order is no contract):
//   ld-detector: stopped after P frames (S skipped, B bad, M missing)
//   ld-tracker: stopped after P frames (S skipped, B bad, N landmarks not tracked, L late, R repeated), T tracks
//   ld-qr-reader: stopped after P frames, R tracks read (K from stacked frames), C changed (...), S skipped, L late, U unmatched, B bad
// Empty when the line, or one of `labels`, is missing.
std::map<std::string, int64_t> exitCounts(const std::string& err_path, const std::string& program,
                                          const std::vector<std::string>& labels) {
  std::ifstream f(err_path);
  std::string line, last;
  while (std::getline(f, line))
    if (line.rfind(program + ": stopped after", 0) == 0) last = line;
  std::map<std::string, int64_t> counts;
  std::smatch m;
  if (!std::regex_search(last, m, std::regex("stopped after ([0-9]+) frames"))) return {};
  counts["frames"] = std::stoll(m[1].str());
  for (const auto& label : labels) {
    if (!std::regex_search(last, m, std::regex("([0-9]+) " + label + "\\b"))) return {};
    counts[label] = std::stoll(m[1].str());
  }
  return counts;
}

double secondsSince(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

}  // namespace

int main(int argc, char** argv) {
  Options o;
  CLI::App app{"ld-soak: the process set under a long camera load; memory, fds and messages lost "
               "over time (run it in a private network namespace: scripts/netns-run.sh)."};
  app.add_option("-d,--duration", o.duration_s, "seconds of load (1 to 1e6)")
      ->capture_default_str()->check(ld::cli::Between(1, 1e6));
  app.add_option("--fps", o.fps, "frames per second (0.1 to 1000)")
      ->capture_default_str()->check(ld::cli::Between(0.1, 1000));
  app.add_option("--width", o.width, "frame width")->capture_default_str()->check(ld::cli::Between(32, 8192));
  app.add_option("--height", o.height, "frame height")->capture_default_str()->check(ld::cli::Between(32, 8192));
  app.add_option("-k,--landmarks", o.landmarks, "landmarks in view (1 to 10)")
      ->capture_default_str()->check(ld::cli::Between(1, 10));
  app.add_option("--loop-frames", o.loop_frames, "distinct frames rendered, published in a loop (1 to 300)")
      ->capture_default_str()->check(ld::cli::Between(1, 300));
  app.add_option("--format", o.format, "pixel format published: mjpeg, yuyv, bgr, gray, ...")
      ->capture_default_str()->check(ld::cli::Parses("FORMAT", ld::pixelFormatFromName));
  app.add_option("--sample-interval", o.sample_s, "seconds between samples")
      ->capture_default_str()->check(ld::cli::Between(0.1, 3600));
  app.add_option("--warmup", o.warmup_s, "seconds before the memory baseline is taken (less than --duration)")
      ->capture_default_str()->check(ld::cli::NonNegative);
  app.add_option("--max-growth-mb", o.max_growth_mb,
                 "largest RSS growth after the warm-up that still counts as flat")
      ->capture_default_str()->check(ld::cli::NonNegative);
  app.add_option("--bin", o.bin_dir, "folder of ld-detector, ld-tracker, ld-qr-reader (default: ld-soak's)");
  app.add_option("--log-dir", o.log_dir, "where the processes' stderr goes (default: a temporary folder)");
  app.add_option("--csv", o.csv, "also write the samples to this CSV file");
  LD_CLI_PARSE(app, argc, argv);

  if (!ld::inPrivateNetns()) {
    std::cerr << "ld-soak: run me in a private network namespace, so that LCM stays on this "
                 "machine: scripts/netns-run.sh " << argv[0] << " ...\n";
    return 2;
  }
  std::signal(SIGINT, onSignal);  // (from here on: a stop while rendering ends with the verdict too)
  std::signal(SIGTERM, onSignal);
  if (o.warmup_s >= o.duration_s) {
    std::cerr << "ld-soak: --warmup (" << o.warmup_s << " s) must be shorter than --duration ("
              << o.duration_s << " s): memory is compared from the first sample after the warm-up "
                 "to the last\n";
    return 2;
  }
  // (what the frames' conversion would refuse after rendering them all)
  if (const int32_t f = ld::pixelFormatFromName(o.format);  // (checked by the option)
      (f == ld::image_t::PIXEL_FORMAT_YUYV || f == ld::image_t::PIXEL_FORMAT_UYVY) && o.width % 2 != 0) {
    std::cerr << "ld-soak: --format " << o.format << " needs an even width, not " << o.width << "\n";
    return 2;
  }
  if (o.bin_dir.empty()) o.bin_dir = ld::selfDirectory();
  if (o.log_dir.empty()) {
    std::string tmpl = (fs::temp_directory_path() / "ld-soak-XXXXXX").string();
    if (!mkdtemp(tmpl.data())) {
      std::perror("ld-soak: mkdtemp");
      return 2;
    }
    o.log_dir = tmpl;
  }
  std::error_code ec;
  fs::create_directories(o.log_dir, ec);
  if (ec || access(o.log_dir.c_str(), W_OK) != 0) {
    std::cerr << "ld-soak: cannot write the process logs in " << o.log_dir << "\n";
    return 2;
  }
  for (const char* name : {"ld-detector", "ld-tracker", "ld-qr-reader"})
    if (access((o.bin_dir + "/" + name).c_str(), X_OK) != 0) {
      std::cerr << "ld-soak: no " << name << " to run in " << o.bin_dir << " (--bin)\n";
      return 2;
    }
  std::ofstream csv;
  if (!o.csv.empty()) {
    csv.open(o.csv);
    if (!csv) {
      std::cerr << "ld-soak: cannot write " << o.csv << " (--csv)\n";
      return 2;
    }
  }

  std::cout << "ld-soak: rendering " << o.loop_frames << " frames of " << o.width << "x" << o.height
            << " with " << o.landmarks << " landmarks (" << o.format << ")..." << std::flush;
  std::vector<ld::image_t> frames;
  try {
    frames = renderLoop(o);
  } catch (const std::exception& e) {
    std::cerr << "\nld-soak: " << e.what() << "\n";
    return 2;
  }
  if (g_stop) {
    std::printf("\nverdict: FAIL (stopped by a signal before the run)\n");
    return 1;
  }
  size_t bytes = 0;
  for (const auto& f : frames) bytes += f.data.size();
  std::cout << " " << bytes / frames.size() / 1024 << " KiB per frame\n";

  const std::string url = ld::defaultLcmUrl();
  if (!ld::lcmUrlUsable(url, "ld-soak")) return 2;
  lcm::LCM lcm(url);
  if (const int status = ld::lcmOpenStatus(lcm, url, "ld-soak")) return status;
  Outputs out;
  out.queues[0] = ld::QueueFit(lcm.subscribe("LANDMARKS", &Outputs::onLandmarks, &out));
  out.queues[1] = ld::QueueFit(lcm.subscribe("LANDMARKS_TRACKED", &Outputs::onTracked, &out));
  out.queues[2] = ld::QueueFit(lcm.subscribe("LANDMARK_CODES", &Outputs::onCodes, &out));
  lcm.subscribe("LCM_SELF_TEST", &Outputs::onSelfTest, &out);

  std::vector<Child> set;
  for (const char* name : {"ld-detector", "ld-tracker", "ld-qr-reader"})
    set.push_back(spawn(o.bin_dir, name, url, o.log_dir));
  // Subscriptions in place: each process has its socket on LCM's port (0.2-1.7
  // s after its start, later on a loaded machine, where a fixed second lost
  // the first frames and failed the run), then LCM's self test is over: LCM
  // drops what else arrives while it repeats its test every 100 ms until
  // its own message comes back (a fixed half second after the sockets lost
  // the first 8-15 frames on a loaded machine). As ld-run waits.
  const int port = ld::lcmUdpPort(url);
  const auto ready_by = Clock::now() + std::chrono::seconds(30);
  const auto started = [&] {
    return std::all_of(set.begin(), set.end(), [&](const Child& c) { return ld::hasUdpSocketOnPort(c.pid, port); });
  };
  while (port > 0 && !g_stop && Clock::now() < ready_by &&
         !(started() && out.self_tests >= static_cast<int64_t>(set.size()) &&
           Clock::now() - out.last_self_test > std::chrono::milliseconds(150)))
    lcm.handleTimeout(20);
  if (port > 0 && Clock::now() >= ready_by)
    std::cerr << "ld-soak: not every process listens after 30 s; starting anyway\n";

  if (csv.is_open()) {
    csv << "t_s,published,landmarks,tracked,codes,detector_skipped";
    for (const auto& c : set) csv << "," << c.name << "_rss_mb," << c.name << "_fds";
    csv << "\n";
  }
  std::printf("%7s %9s %9s %9s %9s %8s", "t (s)", "IMAGE", "LANDMARKS", "TRACKED", "CODES", "skipped");
  for (const auto& c : set) std::printf(" | %-12s %4s", (c.name.substr(3) + " MB").c_str(), "fds");
  std::printf("\n");

  struct Row {
    double t;
    std::vector<ProcSample> procs;
  };
  std::vector<Row> rows;
  auto sample = [&](double t, int64_t published) {
    Row r{t, {}};
    for (const auto& c : set) r.procs.push_back(sampleProcess(c.pid));
    std::printf("%7.1f %9lld %9lld %9lld %9lld %8lld", t, static_cast<long long>(published),
                static_cast<long long>(out.landmarks), static_cast<long long>(out.tracked),
                static_cast<long long>(out.codes), static_cast<long long>(out.detector_skipped));
    for (const auto& p : r.procs) std::printf(" | %12.1f %4d", p.rss_mb, p.fds);
    std::printf("\n");
    std::fflush(stdout);
    if (csv.is_open()) {
      csv << t << "," << published << "," << out.landmarks << "," << out.tracked << "," << out.codes
          << "," << out.detector_skipped;
      for (const auto& p : r.procs) csv << "," << p.rss_mb << "," << p.fds;
      csv << "\n";
    }
    rows.push_back(std::move(r));
  };

  // Publish at the frame rate; between frames, take what comes back.
  const auto period = std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(1.0 / o.fps));
  // Frames at the rate for the duration; where ld-soak cannot keep the rate
  // (a size or format too large for this machine), publishing still ends at
  // the duration and `total` counts what went out.
  const int64_t planned = std::max<int64_t>(1, std::llround(o.duration_s * o.fps));
  int64_t total = 0;
  const auto t0 = Clock::now();
  const int64_t utime0 = std::chrono::duration_cast<std::chrono::microseconds>(
                             std::chrono::system_clock::now().time_since_epoch()).count();
  std::vector<uint8_t> buf;
  double next_sample = 0;
  int64_t late = 0;
  bool died = false;
  for (int64_t i = 0; i < planned && !died && !g_stop; ++i) {
    const auto due = t0 + i * period;
    if ((i > 0 && secondsSince(t0) >= o.duration_s) || g_stop) break;
    while (Clock::now() < due && !g_stop) {
      const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(due - Clock::now()).count();
      lcm.handleTimeout(static_cast<int>(std::max<int64_t>(left, 0)));
    }
    if (Clock::now() - due > period) ++late;  // ld-soak itself could not keep the rate
    ld::image_t& msg = frames[static_cast<size_t>(i % static_cast<int64_t>(frames.size()))];
    msg.utime = utime0 + std::llround(i * 1e6 / o.fps);
    ld::setImageSeq(msg, i);
    buf.resize(static_cast<size_t>(msg.getEncodedSize()));
    msg.encode(buf.data(), 0, static_cast<int>(buf.size()));
    lcm.publish("IMAGE", buf.data(), static_cast<unsigned>(buf.size()));
    total = i + 1;
    if (secondsSince(t0) >= next_sample) {
      sample(secondsSince(t0), i + 1);
      next_sample += o.sample_s;
      for (auto& c : set)
        if (waitpid(c.pid, nullptr, WNOHANG) == c.pid) {
          std::cerr << "ld-soak: " << c.name << " exited during the run (see " << c.err_path << ")\n";
          c.reaped = died = true;
        }
    }
  }
  const double publish_s = secondsSince(t0);
  // let the set finish the last frames
  const auto drain_until = Clock::now() + std::chrono::seconds(2);
  while (Clock::now() < drain_until) lcm.handleTimeout(100);
  // (stopped by a signal, a Ctrl-C reached the set too: a sample now would
  // be of processes that have ended, RSS 0; the figures are those up to
  // the stop)
  if (!g_stop) sample(secondsSince(t0), total);

  for (auto& c : set)
    if (!c.reaped) kill(c.pid, SIGINT);
  bool clean_exit = !died;
  for (auto& c : set) {
    if (c.reaped) continue;  // (said above; not a clean exit)
    int status = 0;
    waitpid(c.pid, &status, 0);
    if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) {
      clean_exit = false;
      std::cerr << "ld-soak: " << c.name << " did not exit cleanly (see " << c.err_path << ")\n";
    }
  }

  // The processes' own counts, from their exit lines.
  auto det = exitCounts(set[0].err_path, "ld-detector", {"skipped", "bad"});
  auto trk = exitCounts(set[1].err_path, "ld-tracker", {"skipped", "bad"});
  auto qr = exitCounts(set[2].err_path, "ld-qr-reader", {"tracks read", "skipped", "late", "unmatched", "bad"});
  if (det.empty() || trk.empty() || qr.empty()) {
    std::cerr << "ld-soak: missing exit lines in " << o.log_dir << "\n";
    std::printf("verdict: FAIL (a process did not finish its run: see %s)\n", o.log_dir.c_str());
    return 1;
  }
  const int64_t det_in = det["frames"] + det["skipped"] + det["bad"];
  const int64_t trk_in = trk["frames"] + trk["skipped"] + trk["bad"];
  const int64_t lost_image = total - det_in;              // IMAGE frames ld-detector never saw
  const int64_t lost_landmarks = det["frames"] - trk_in;  // LANDMARKS lists ld-tracker never saw
  const int64_t lost_to_soak =
      (det["frames"] - out.landmarks) + (trk["frames"] - out.tracked) + (qr["frames"] - out.codes);

  std::printf("\nframes published: %lld in %.1f s (%.1f fps; %lld published late), %dx%d %s, %d landmarks\n",
              static_cast<long long>(total), publish_s, total / publish_s, static_cast<long long>(late),
              o.width, o.height, o.format.c_str(), o.landmarks);
  if (total < planned && !g_stop)
    std::printf("ld-soak could not keep %g fps: %lld of %lld frames went out in the %g s\n", o.fps,
                static_cast<long long>(total), static_cast<long long>(planned), o.duration_s);
  std::printf("IMAGE -> ld-detector:       %lld received = %lld processed + %lld skipped (deliberate) + "
              "%lld bad; lost %lld\n",
              static_cast<long long>(det_in), static_cast<long long>(det["frames"]),
              static_cast<long long>(det["skipped"]), static_cast<long long>(det["bad"]),
              static_cast<long long>(lost_image));
  std::printf("LANDMARKS -> ld-tracker:    %lld published, %lld received = %lld processed + %lld skipped "
              "(deliberate) + %lld bad; lost %lld\n",
              static_cast<long long>(det["frames"]), static_cast<long long>(trk_in),
              static_cast<long long>(trk["frames"]), static_cast<long long>(trk["skipped"]),
              static_cast<long long>(trk["bad"]),
              static_cast<long long>(lost_landmarks));
  std::printf("ld-qr-reader:               %lld frames joined, %lld tracks read, %lld skipped (deliberate), "
              "%lld late, %lld unmatched, %lld bad\n",
              static_cast<long long>(qr["frames"]), static_cast<long long>(qr["tracks read"]),
              static_cast<long long>(qr["skipped"]), static_cast<long long>(qr["late"]),
              static_cast<long long>(qr["unmatched"]), static_cast<long long>(qr["bad"]));
  std::printf("outputs -> ld-soak:         LANDMARKS %lld of %lld (%lld with landmarks), LANDMARKS_TRACKED "
              "%lld of %lld, LANDMARK_CODES %lld of %lld (%lld codes); lost %lld\n",
              static_cast<long long>(out.landmarks), static_cast<long long>(det["frames"]),
              static_cast<long long>(out.landmarks_with_detections), static_cast<long long>(out.tracked),
              static_cast<long long>(trk["frames"]), static_cast<long long>(out.codes),
              static_cast<long long>(qr["frames"]), static_cast<long long>(out.codes_entries),
              static_cast<long long>(lost_to_soak));

  // Memory and fds: the first sample after the warm-up against the last.
  size_t base = 0;
  while (base + 1 < rows.size() && rows[base].t < o.warmup_s) ++base;
  bool mem_flat = true, fds_flat = true;
  const double minutes = std::max(1e-9, (rows.back().t - rows[base].t) / 60.0);
  for (size_t k = 0; k < set.size(); ++k) {
    double peak = 0;
    for (size_t r = base; r < rows.size(); ++r) peak = std::max(peak, rows[r].procs[k].rss_mb);
    const ProcSample& a = rows[base].procs[k];
    const ProcSample& b = rows.back().procs[k];
    const double growth = b.rss_mb - a.rss_mb;
    if (growth > o.max_growth_mb || !b.alive) mem_flat = false;
    if (a.fds != b.fds) fds_flat = false;
    std::printf("%-13s RSS %.1f MB at %.0f s -> %.1f MB at %.0f s (%+.1f MB, %+.2f MB/min, peak %.1f); fds %d -> %d\n",
                (set[k].name + ":").c_str(), a.rss_mb, rows[base].t, b.rss_mb, rows.back().t, growth,
                growth / minutes, peak, a.fds, b.fds);
  }
  const bool none_lost = lost_image == 0 && lost_landmarks == 0 && lost_to_soak == 0 && out.bad == 0;
  const bool pass = mem_flat && fds_flat && none_lost && clean_exit && !g_stop;
  if (g_stop) {
    // A stop is no verdict on the set: what held up to it, the messages in
    // flight at the stop (the set stopped with ld-soak) not counted as lost.
    std::printf("stopped by a signal after %.1f s of %g\n", publish_s, o.duration_s);
    std::printf("verdict: FAIL (stopped by a signal; up to then memory %s, fds %s; %lld message%s in flight at "
                "the stop)\n",
                mem_flat ? "flat" : "GROWS", fds_flat ? "flat" : "CHANGE",
                static_cast<long long>(lost_image + lost_landmarks + lost_to_soak),
                lost_image + lost_landmarks + lost_to_soak == 1 ? "" : "s");
    std::printf("process logs: %s\n", o.log_dir.c_str());
    return 1;
  }
  std::printf("verdict: %s (memory %s, fds %s, %s, %s)\n", pass ? "PASS" : "FAIL",
              mem_flat ? "flat" : "GROWS", fds_flat ? "flat" : "CHANGE",
              none_lost ? "no message lost" : "MESSAGES LOST",
              clean_exit ? "clean exits" : "A PROCESS FAILED");
  std::printf("process logs: %s\n", o.log_dir.c_str());
  return pass ? 0 : 1;
}
