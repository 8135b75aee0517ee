// ld-run's library: supervisor (restart with backoff, ordered stop, output
// lines), bus monitor (latency matching, skips, tracks, payloads), config.
#include <chrono>
#include <csignal>
#include <filesystem>
#include <fstream>
#include <random>
#include <thread>

#include <gtest/gtest.h>

#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <lcm/lcm-cpp.hpp>
#include "ld/bus_monitor.hpp"
#include "ld/hang_watch.hpp"
#include "ld/image_convert.hpp"
#include "ld/netns.hpp"
#include "ld/rss_series.hpp"
#include "ld/run_config.hpp"
#include "ld/supervisor.hpp"

namespace {

using namespace std::chrono_literals;

struct Lines {
  std::vector<std::pair<std::string, std::string>> all;
  ld::Supervisor::LineSink sink() {
    return [this](const std::string& n, const std::string& l) { all.emplace_back(n, l); };
  }
  bool has(const std::string& name, const std::string& text) const {
    for (const auto& [n, l] : all)
      if (n == name && l.find(text) != std::string::npos) return true;
    return false;
  }
};

// Polls the supervisor until pred() or the timeout.
template <typename Pred>
bool pollUntil(ld::Supervisor& sup, Pred pred, std::chrono::milliseconds timeout) {
  const auto end = std::chrono::steady_clock::now() + timeout;
  while (std::chrono::steady_clock::now() < end) {
    sup.poll(std::chrono::steady_clock::now());
    if (pred()) return true;
    std::this_thread::sleep_for(10ms);
  }
  return false;
}

TEST(Supervisor, RestartDelayDoublesUpToTheMaximum) {
  ld::RestartPolicy p{0.2, 1.0, 10};
  EXPECT_DOUBLE_EQ(ld::restartDelay(p, 1), 0.2);
  EXPECT_DOUBLE_EQ(ld::restartDelay(p, 2), 0.4);
  EXPECT_DOUBLE_EQ(ld::restartDelay(p, 3), 0.8);
  EXPECT_DOUBLE_EQ(ld::restartDelay(p, 4), 1.0);
  EXPECT_DOUBLE_EQ(ld::restartDelay(p, 100), 1.0);
}

TEST(Supervisor, DescribesWaitStatus) {
  EXPECT_EQ(ld::describeWaitStatus(3 << 8), "exit 3");
  EXPECT_EQ(ld::describeWaitStatus(SIGKILL).rfind("signal 9", 0), 0u);
}

TEST(Supervisor, KilledWorkerComesBackOthersKeepTheirPid) {
  Lines lines;
  ld::Supervisor sup({0.1, 1.0, 10}, lines.sink());
  const size_t a = sup.add({"a", {"sleep", "30"}, ld::ProcessRole::Worker});
  const size_t b = sup.add({"b", {"sleep", "30"}, ld::ProcessRole::Worker});
  ASSERT_TRUE(sup.start(a));
  ASSERT_TRUE(sup.start(b));
  const pid_t pa = sup.processes()[a].pid, pb = sup.processes()[b].pid;
  ASSERT_EQ(::kill(pa, SIGKILL), 0);
  ASSERT_TRUE(pollUntil(sup, [&] { return sup.processes()[a].pid > 0 && sup.processes()[a].pid != pa; }, 2000ms));
  EXPECT_EQ(sup.processes()[b].pid, pb);
  EXPECT_EQ(sup.processes()[a].starts, 2);
  EXPECT_EQ(sup.restarts(), 1);
  EXPECT_TRUE(lines.has("a", "died (signal 9"));
  EXPECT_TRUE(sup.stopAll(2.0));
  EXPECT_EQ(sup.processes()[a].pid, -1);
  EXPECT_EQ(sup.processes()[b].pid, -1);
  EXPECT_EQ(::kill(pb, 0), -1);
}

TEST(Supervisor, CrashLoopBacksOff) {
  Lines lines;
  ld::Supervisor sup({0.05, 0.4, 10}, lines.sink());
  const size_t i = sup.add({"crash", {"false"}, ld::ProcessRole::Worker});
  ASSERT_TRUE(sup.start(i));
  pollUntil(sup, [] { return false; }, 1000ms);
  // 0.05 + 0.1 + 0.2 + 0.4 + 0.4 ...: about 5 starts in a second, not dozens
  EXPECT_GE(sup.processes()[i].starts, 3);
  EXPECT_LE(sup.processes()[i].starts, 7);
  EXPECT_TRUE(lines.has("crash", "died (exit 1)"));
  sup.stopAll(1.0);
}

// A long crash loop (a camera unplugged for a day) is told in full for its
// first loop_shown failures, then only at every loop_every-th, each shown
// start with its own output and how many were left out.
TEST(Supervisor, LongCrashLoopIsToldOnlyNowAndThen) {
  Lines lines;
  ld::RestartPolicy policy{0.001, 0.001, 10};
  policy.loop_shown = 3;
  policy.loop_every = 5;
  ld::Supervisor sup(policy, lines.sink());
  const size_t i = sup.add({"crash", {"sh", "-c", "echo out of luck; exit 1"}, ld::ProcessRole::Worker});
  ASSERT_TRUE(sup.start(i));
  // (a death is reaped in one poll and restarted in a later one)
  ASSERT_TRUE(pollUntil(
      sup, [&] { return sup.processes()[i].pid < 0 && sup.processes()[i].consecutive_failures == 12; }, 10000ms));
  EXPECT_EQ(sup.processes()[i].starts, 12);
  EXPECT_EQ(sup.restarts(), 11);
  // runs after 0, 1, 2, 5 and 10 failures are shown: their output and their deaths
  auto count = [&](const std::string& text) {
    int n = 0;
    for (const auto& [name, l] : lines.all) n += name == "crash" && l.find(text) != std::string::npos;
    return n;
  };
  EXPECT_EQ(count("out of luck"), 5);
  EXPECT_EQ(count("died (exit 1)"), 5);
  EXPECT_EQ(count("restarted, pid"), 4);
  EXPECT_TRUE(lines.has("crash", "(3 quick failures in a row; from now on only every 5th restart is shown, "
                                 "with its output, until a run lasts 10 s or ends otherwise)"));
  EXPECT_TRUE(lines.has("crash", "(5 quick failures in a row; the 2 restarts before this one not shown)"));
  EXPECT_TRUE(lines.has("crash", "(6 quick failures in a row; the next restart shown is the one after failure 10)"));
  EXPECT_TRUE(lines.has("crash", "(10 quick failures in a row; the 4 restarts before this one not shown)"));
  EXPECT_TRUE(lines.has("crash", "(11 quick failures in a row; the next restart shown is the one after failure 15)"));
  sup.stopAll(1.0);
}

// A run of the loop that lasts stable_after_s ends it: told, with the lines
// it wrote while not shown; a run stopped while not shown shows its lines.
TEST(Supervisor, CrashLoopThatEndsShowsTheLastingRunsOutput) {
  const auto dir = std::filesystem::temp_directory_path() /
                   ("ld_sup_loop_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  const std::string counter = (dir / "n").string();
  // fails quickly 6 times (runs 0..5), then run 6 lasts
  const std::string script = "n=$(cat " + counter + " 2>/dev/null || echo 0); echo $((n+1)) > " + counter +
                             "; echo run $n; if [ $n -ge 6 ]; then echo lasting; exec sleep 30; fi; exit 1";
  Lines lines;
  ld::RestartPolicy policy{0.001, 0.001, 0.5};
  policy.loop_shown = 3;
  policy.loop_every = 5;
  ld::Supervisor sup(policy, lines.sink());
  const size_t i = sup.add({"cam", {"sh", "-c", script}, ld::ProcessRole::Worker});
  ASSERT_TRUE(sup.start(i));
  ASSERT_TRUE(pollUntil(sup, [&] { return lines.has("cam", "lasting"); }, 10000ms));
  EXPECT_EQ(sup.processes()[i].starts, 7);
  EXPECT_GT(sup.processes()[i].pid, 0);
  // runs 3, 4 and 6 were quiet; 5 was shown; 6's lines came once it lasted
  for (const char* shown : {"run 0", "run 1", "run 2", "run 5"}) EXPECT_TRUE(lines.has("cam", shown)) << shown;
  for (const char* hidden : {"run 3", "run 4"}) EXPECT_FALSE(lines.has("cam", hidden)) << hidden;
  size_t told = lines.all.size();
  for (size_t k = 0; k < lines.all.size(); ++k)
    if (lines.all[k].second.find("has run 0.5 s after 6 quick failures in a row: its restarts are shown again") !=
        std::string::npos)
      told = k;
  ASSERT_LT(told + 2, lines.all.size());
  EXPECT_EQ(lines.all[told + 1].second, "run 6");
  EXPECT_EQ(lines.all[told + 2].second, "lasting");
  sup.stopAll(1.0);

  // the same loop stopped while its run 6 is quiet: the run's lines are shown
  std::filesystem::remove(counter);
  Lines stopped;
  ld::RestartPolicy long_policy = policy;
  long_policy.stable_after_s = 60;
  ld::Supervisor sup2(long_policy, stopped.sink());
  const size_t j = sup2.add({"cam", {"sh", "-c", script}, ld::ProcessRole::Worker});
  ASSERT_TRUE(sup2.start(j));
  ASSERT_TRUE(pollUntil(sup2, [&] { return sup2.processes()[j].starts == 7; }, 10000ms));
  pollUntil(sup2, [] { return false; }, 200ms);  // (run 6 writes its lines, held)
  EXPECT_FALSE(stopped.has("cam", "lasting"));
  sup2.stopAll(1.0);
  EXPECT_TRUE(stopped.has("cam", "its output since a start not shown (a crash loop's):"));
  EXPECT_TRUE(stopped.has("cam", "run 6"));
  EXPECT_TRUE(stopped.has("cam", "lasting"));
  std::filesystem::remove_all(dir);
}

// A shell script whose run n (counted in a file under `dir`) runs `body`
// with $n set: each start of it a run of its own.
std::vector<std::string> countingScript(const std::filesystem::path& dir, const std::string& body) {
  std::filesystem::create_directories(dir);
  const std::string counter = (dir / "n").string();
  return {"sh", "-c",
          "n=$(cat " + counter + " 2>/dev/null || echo 0); echo $((n+1)) > " + counter + "; " + body};
}

int countLines(const Lines& lines, const std::string& text) {
  int n = 0;
  for (const auto& [name, l] : lines.all) n += l.find(text) != std::string::npos;
  return n;
}

std::filesystem::path scratchDir(const std::string& what) {
  const auto dir = std::filesystem::temp_directory_path() / ("ld_sup_" + what + "_" + std::to_string(::getpid()));
  std::filesystem::remove_all(dir);
  return dir;
}

// A loop that starts failing otherwise (a new error after the camera's
// "not found") is told at once, with the lines of that run: they waited for
// the 100th restart, minutes.
TEST(Supervisor, CrashLoopThatFailsOtherwiseIsToldAtOnce) {
  const auto dir = scratchDir("otherwise");
  Lines lines;
  ld::RestartPolicy policy{0.001, 0.001, 10};
  policy.loop_shown = 3;
  ld::Supervisor sup(policy, lines.sink());
  const size_t i = sup.add({"cam", countingScript(dir, "if [ $n -lt 6 ]; then echo not found; exit 1; fi; "
                                                       "echo new error $n; kill -SEGV $$"),
                            ld::ProcessRole::Worker});
  ASSERT_TRUE(sup.start(i));
  ASSERT_TRUE(pollUntil(sup, [&] { return sup.processes()[i].pid < 0 && sup.processes()[i].starts == 9; }, 10000ms));
  // runs 3-6 not shown; 6 failed otherwise: told with its lines; 7 and 8 shown
  EXPECT_EQ(countLines(lines, "not found"), 3);
  EXPECT_TRUE(lines.has("cam", "ended otherwise than the failures before it (its start not shown, nor the 3 before "
                               "it); its output:"));
  for (const char* shown : {"new error 6", "new error 7", "new error 8"}) EXPECT_TRUE(lines.has("cam", shown)) << shown;
  EXPECT_EQ(countLines(lines, "died (signal 11"), 3);
  sup.stopAll(1.0);
  std::filesystem::remove_all(dir);
}

// A loop after a run that lasted counts its quick failures alone: told in
// full for loop_shown of them (the run that lasted was counted as one).
TEST(Supervisor, CrashLoopAfterALastingRunCountsItsQuickFailures) {
  const auto dir = scratchDir("after_stable");
  Lines lines;
  ld::RestartPolicy policy{0.001, 0.001, 0.3};
  policy.loop_shown = 3;
  ld::Supervisor sup(policy, lines.sink());
  const size_t i = sup.add(
      {"cam", countingScript(dir, "echo run $n; if [ $n -eq 0 ]; then sleep 0.5; fi; exit 1"), ld::ProcessRole::Worker});
  ASSERT_TRUE(sup.start(i));
  ASSERT_TRUE(pollUntil(sup, [&] { return sup.processes()[i].pid < 0 && sup.processes()[i].starts == 5; }, 10000ms));
  for (const char* shown : {"run 0", "run 1", "run 2", "run 3"}) EXPECT_TRUE(lines.has("cam", shown)) << shown;
  EXPECT_FALSE(lines.has("cam", "run 4"));
  EXPECT_TRUE(lines.has("cam", "(3 quick failures in a row; from now on only every 100th restart is shown"));
  sup.stopAll(1.0);
  std::filesystem::remove_all(dir);
}

// A run not shown keeps its first and its last lines (its error is most
// often the last): shown when it is refused for good, and when it is killed
// as hung.
TEST(Supervisor, RunNotShownKeepsItsFirstAndLastLines) {
  const auto dir = scratchDir("held");
  Lines lines;
  ld::RestartPolicy policy{0.001, 0.001, 10};
  policy.loop_shown = 3;
  policy.usage_error_is_final = true;
  ld::Supervisor sup(policy, lines.sink());
  const size_t i = sup.add({"play", countingScript(dir, "if [ $n -lt 4 ]; then exit 1; fi; "
                                                        "k=1; while [ $k -le 250 ]; do echo line $k; k=$((k+1)); done; "
                                                        "echo error: --foo refused; exit 2"),
                            ld::ProcessRole::Source});
  ASSERT_TRUE(sup.start(i));
  ASSERT_TRUE(pollUntil(sup, [&] { return sup.failedProcess() != nullptr; }, 10000ms));
  EXPECT_TRUE(lines.has("play", "its output since a start not shown (a crash loop's):"));
  EXPECT_TRUE(lines.has("play", "line 100"));
  EXPECT_FALSE(lines.has("play", "line 101"));
  EXPECT_TRUE(lines.has("play", "(51 lines of that run not kept)"));
  EXPECT_FALSE(lines.has("play", "line 151"));
  EXPECT_TRUE(lines.has("play", "line 152"));
  EXPECT_TRUE(lines.has("play", "error: --foo refused"));
  EXPECT_TRUE(lines.has("play", "failed (exit 2); not restarted"));

  Lines hung;
  const auto dir2 = scratchDir("hung");
  ld::Supervisor sup2(policy, hung.sink());
  const size_t j = sup2.add(
      {"tracker", countingScript(dir2, "if [ $n -lt 3 ]; then exit 1; fi; echo stuck on something; exec sleep 30"),
       ld::ProcessRole::Worker});
  ASSERT_TRUE(sup2.start(j));
  ASSERT_TRUE(pollUntil(sup2, [&] { return sup2.processes()[j].starts == 4 && sup2.processes()[j].pid > 0; }, 10000ms));
  pollUntil(sup2, [] { return false; }, 200ms);  // (its line written, held)
  EXPECT_FALSE(hung.has("tracker", "stuck on something"));
  ASSERT_TRUE(sup2.killHung("tracker"));
  EXPECT_TRUE(hung.has("tracker", "its output since a start not shown (a crash loop's), killed as hung:"));
  EXPECT_TRUE(hung.has("tracker", "stuck on something"));
  sup2.stopAll(1.0);
  std::filesystem::remove_all(dir);
  std::filesystem::remove_all(dir2);
}

// Starts that fail (a program not there) loop as deaths do; a shown one says
// in one note what was left out before it and which is shown next.
TEST(Supervisor, FailedStartsLoopAsDeathsDo) {
  Lines lines;
  ld::RestartPolicy policy{0.001, 0.001, 10};
  policy.loop_shown = 3;
  policy.loop_every = 5;
  ld::Supervisor sup(policy, lines.sink());
  const size_t i = sup.add({"cam", {"/nonexistent/ld-camera"}, ld::ProcessRole::Worker});
  sup.start(i);
  ASSERT_TRUE(pollUntil(sup, [&] { return sup.processes()[i].starts >= 12; }, 10000ms));
  EXPECT_EQ(countLines(lines, "cannot start /nonexistent/ld-camera"), 5);  // after 0, 1, 2, 5 and 10 failures
  EXPECT_TRUE(lines.has("cam", "(6 quick failures in a row; the 2 restarts before this one not shown; the next "
                               "restart shown is the one after failure 10)"));
  sup.stopAll(1.0);
}

TEST(Supervisor, SourceThatFinishesIsDoneNotRestarted) {
  Lines lines;
  ld::Supervisor sup({0.05, 1, 10}, lines.sink());
  const size_t i = sup.add({"replay", {"sh", "-c", "echo one; echo two >&2"}, ld::ProcessRole::Source});
  ASSERT_TRUE(sup.start(i));
  ASSERT_TRUE(pollUntil(sup, [&] { return sup.sourcesDone(); }, 2000ms));
  pollUntil(sup, [] { return false; }, 200ms);
  EXPECT_EQ(sup.processes()[i].starts, 1);
  EXPECT_TRUE(lines.has("replay", "one"));
  EXPECT_TRUE(lines.has("replay", "two"));
  EXPECT_TRUE(lines.has("replay", "finished"));
}

// A usage error (exit 2), a source's or a worker's, is final only when the
// policy says so (ld-run sets it, live and replaying); otherwise it is
// restarted as any death.
TEST(Supervisor, UsageErrorIsFinalWhenThePolicySaysSo) {
  // (a source's refused file; a worker's refused option, as the detector's)
  for (const auto& [name, role] :
       {std::pair{"play", ld::ProcessRole::Source}, {"detector", ld::ProcessRole::Worker}})
    for (const bool final_error : {true, false}) {
      Lines lines;
      ld::RestartPolicy policy{0.05, 0.1, 10};
      policy.usage_error_is_final = final_error;
      ld::Supervisor sup(policy, lines.sink());
      const size_t i = sup.add({name, {"sh", "-c", "echo refused >&2; exit 2"}, role});
      ASSERT_TRUE(sup.start(i));
      pollUntil(sup, [] { return false; }, 400ms);
      if (final_error) {
        ASSERT_NE(sup.failedProcess(), nullptr) << name;
        EXPECT_EQ(sup.failedProcess()->spec.name, name);
        EXPECT_EQ(sup.processes()[i].starts, 1) << name;
        EXPECT_TRUE(lines.has(name, "failed (exit 2); not restarted")) << name;
      } else {
        EXPECT_EQ(sup.failedProcess(), nullptr) << name;
        EXPECT_GE(sup.processes()[i].starts, 2) << name;
        EXPECT_TRUE(lines.has(name, "died (exit 2); restarting")) << name;
      }
      EXPECT_FALSE(sup.sourcesDone()) << name;
      sup.stopAll(0.5);
    }
}

TEST(Supervisor, MissingProgramIsReportedAndRetried) {
  Lines lines;
  ld::Supervisor sup({0.05, 0.1, 10}, lines.sink());
  const size_t i = sup.add({"ghost", {"/nonexistent/ld-ghost"}, ld::ProcessRole::Worker});
  EXPECT_FALSE(sup.start(i));
  EXPECT_TRUE(lines.has("ghost", "cannot start /nonexistent/ld-ghost"));
  pollUntil(sup, [] { return false; }, 300ms);
  EXPECT_GE(sup.processes()[i].starts, 2);
  EXPECT_TRUE(sup.stopAll(0.5));
}

// A start whose pipe cannot be made (out of descriptors) is retried with
// the backoff, as a missing program is; it was said once and never
// retried, and ld-run waited for that process for ever. runs counts the
// starts that ran.
TEST(Supervisor, StartOutOfDescriptorsIsRetried) {
  Lines lines;
  ld::Supervisor sup({0.05, 0.1, 10}, lines.sink());
  const size_t i = sup.add({"starved", {"sh", "-c", "sleep 5"}, ld::ProcessRole::Worker});
  rlimit old{};
  ASSERT_EQ(::getrlimit(RLIMIT_NOFILE, &old), 0);
  // (the lowest free descriptor, then no room for a pipe beyond it)
  const int probe = ::dup(0);
  ASSERT_GE(probe, 0);
  ::close(probe);
  rlimit low = old;
  low.rlim_cur = static_cast<rlim_t>(probe);
  ASSERT_EQ(::setrlimit(RLIMIT_NOFILE, &low), 0);
  const bool started = sup.start(i);
  ASSERT_EQ(::setrlimit(RLIMIT_NOFILE, &old), 0);
  EXPECT_FALSE(started);
  EXPECT_TRUE(lines.has("starved", "cannot start sh: pipe: Too many open files; retrying in")) << lines.all.size();
  EXPECT_EQ(sup.processes()[i].runs, 0);
  ASSERT_TRUE(pollUntil(sup, [&] { return sup.processes()[i].runs == 1; }, 2000ms));  // (retried, and it runs)
  EXPECT_GE(sup.processes()[i].starts, 2);
  sup.stopAll(0.5);
}

TEST(Supervisor, StopsAProcessIgnoringSigtermWithSigkill) {
  Lines lines;
  ld::Supervisor sup({0.1, 1, 10}, lines.sink());
  const size_t i = sup.add({"stubborn", {"sh", "-c", "trap '' TERM; echo up; while :; do sleep 0.05; done"},
                            ld::ProcessRole::Worker});
  ASSERT_TRUE(sup.start(i));
  ASSERT_TRUE(pollUntil(sup, [&] { return lines.has("stubborn", "up"); }, 2000ms));
  EXPECT_FALSE(sup.stopAll(0.3));
  EXPECT_TRUE(lines.has("stubborn", "killed"));
  EXPECT_EQ(sup.processes()[i].pid, -1);
}

TEST(Supervisor, ChildInheritsOnlyStdio) {
  int fds[2];
  ASSERT_EQ(::pipe(fds), 0);  // not close-on-exec, as LCM's sockets are not
  Lines lines;
  ld::Supervisor sup({0.1, 1, 10}, lines.sink());
  const size_t i = sup.add({"fds", {"sh", "-c", "ls /proc/$$/fd"}, ld::ProcessRole::Source});
  ASSERT_TRUE(sup.start(i));
  ASSERT_TRUE(pollUntil(sup, [&] { return sup.sourcesDone(); }, 2000ms));
  pollUntil(sup, [] { return false; }, 100ms);
  EXPECT_TRUE(lines.has("fds", "2"));
  for (const auto& [n, l] : lines.all) {
    EXPECT_NE(l, std::to_string(fds[0]));
    EXPECT_NE(l, std::to_string(fds[1]));
  }
  ::close(fds[0]);
  ::close(fds[1]);
}

TEST(Netns, LcmUdpPort) {
  EXPECT_EQ(ld::lcmUdpPort("udpm://239.255.76.67:7667?ttl=0"), 7667);
  EXPECT_EQ(ld::lcmUdpPort("udpm://239.255.76.67:7700"), 7700);
  EXPECT_EQ(ld::lcmUdpPort("udpm://239.255.76.67"), 7667);
  EXPECT_EQ(ld::lcmUdpPort("memq://"), -1);
}

// A namespace made by hand as DESIGN.md says (`unshare -n`, then lo up) is
// a private one: ld-soak refused it, looking only for LD_IN_NETNS=1. One
// with another interface up is not (a veth pair's end, up).
TEST(Netns, OnlyLoopbackUpIsPrivate) {
  const pid_t pid = ::fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) {  // (one thread here: unshare takes it)
    int code = 0;
    try {
      ld::enterPrivateNetns();
      ::unsetenv("LD_IN_NETNS");  // (what it sets for its children: the namespace is to tell)
      if (!ld::onlyLoopbackUp() || !ld::inPrivateNetns()) code = 1;
      else if (std::system("ip link add ldt0 type veth peer name ldt1 2>/dev/null && ip link set ldt0 up") != 0)
        code = 4;
      else if (ld::onlyLoopbackUp() || ld::inPrivateNetns())
        code = 2;
    } catch (const std::exception&) {
      code = 3;
    }
    ::_exit(code);
  }
  int status = 0;
  ASSERT_EQ(::waitpid(pid, &status, 0), pid);
  ASSERT_TRUE(WIFEXITED(status));
  if (WEXITSTATUS(status) == 4) GTEST_SKIP() << "lo alone: private, as it should; no veth pair could be made";
  EXPECT_EQ(WEXITSTATUS(status), 0) << "1: lo alone up, not private; 2: a veth up too, private; 3: no namespace";
}

ld::landmark_t trackedLandmark(int64_t id, bool visible, const std::string& payload = "", int32_t age = 0) {
  ld::landmark_t m{};
  m.track_id = id;
  m.age = age;
  m.visible = visible;
  m.has_payload = !payload.empty();
  m.payload = payload;
  return m;
}

ld::landmark_list_t list(int64_t utime, int64_t seq, std::vector<ld::landmark_t> lms, int64_t skipped = 0) {
  ld::landmark_list_t l{};
  l.utime = utime;
  l.seq = seq;
  l.frames_skipped = skipped;
  l.landmarks = std::move(lms);
  l.nlandmarks = static_cast<int32_t>(l.landmarks.size());
  return l;
}

// Images the detector refuses are bad images, not images never tracked
// (ld-run counted them as images: 81 against the detector's 60 refused,
// explained nowhere); a good one's utime and seq are what it is matched by.
TEST(BusMonitor, CountsImagesTheDetectorRefusesAsBad) {
  lcm::LCM lcm("memq://");
  ASSERT_TRUE(lcm.good());
  ld::BusMonitor m;
  m.subscribe(lcm);
  const auto publish = [&](const ld::image_t& img) {
    std::vector<uint8_t> b(static_cast<size_t>(img.getEncodedSize()));
    img.encode(b.data(), 0, static_cast<int>(b.size()));
    lcm.publish("IMAGE", b.data(), static_cast<unsigned>(b.size()));
  };
  const ld::image_t good = ld::matToImage(cv::Mat(4, 6, CV_8UC3, cv::Scalar(1, 2, 3)),
                                          ld::image_t::PIXEL_FORMAT_BGR, 123456789, 42);
  ld::image_t short_data = good;  // (a row short of its size)
  short_data.data.resize(good.data.size() - 18);
  short_data.size = static_cast<int32_t>(short_data.data.size());
  ld::image_t unknown = good;
  unknown.pixelformat = 0x34363248;  // 'H264'
  ld::image_t odd_yuyv = ld::matToImage(cv::Mat(4, 6, CV_8UC3, cv::Scalar(1, 2, 3)),
                                        ld::image_t::PIXEL_FORMAT_YUYV, 5, 1);
  odd_yuyv.width = 5;
  odd_yuyv.row_stride = 10;
  odd_yuyv.data.resize(40);
  odd_yuyv.size = 40;
  ld::image_t not_jpeg = good;
  not_jpeg.pixelformat = ld::image_t::PIXEL_FORMAT_MJPEG;
  not_jpeg.row_stride = 0;
  for (const ld::image_t* img : std::vector<const ld::image_t*>{&short_data, &unknown, &odd_yuyv, &not_jpeg, &good})
    publish(*img);
  for (int i = 0; i < 5; ++i) ASSERT_GE(lcm.handleTimeout(100), 1);
  const auto s = m.summary();
  EXPECT_EQ(s["frames"]["images"], 1);
  EXPECT_EQ(s["frames"]["bad_images"], 4);
  // matched by utime and seq
  m.trackedSeen(list(123456789, 42, {}), 123456789 + 5000);
  EXPECT_EQ(m.summary()["frames"]["matched"], 1);
}

// Malformed messages on the landmark and code channels are counted as bad,
// and the monitor goes on: lcm-gen's decoder threw std::length_error on a
// string length of 0 (std::bad_alloc on a huge count), and ld-run, the
// parent of every process, went down with it (a fresh-eyes review).
TEST(BusMonitor, CountsMalformedListsAndCodesAsBadAndGoesOn) {
  lcm::LCM lcm("memq://");
  ASSERT_TRUE(lcm.good());
  ld::BusMonitor m;
  m.subscribe(lcm);
  const auto bytes = [](const auto& msg) {
    std::vector<uint8_t> b(static_cast<size_t>(msg.getEncodedSize()));
    msg.encode(b.data(), 0, static_cast<int>(b.size()));
    return b;
  };
  const auto put32 = [](std::vector<uint8_t>& b, size_t at, uint32_t v) {
    for (int i = 0; i < 4; ++i) b.at(at + static_cast<size_t>(i)) = static_cast<uint8_t>(v >> (24 - 8 * i));
  };
  std::vector<uint8_t> bad_list = bytes(list(1000, 0, {trackedLandmark(7, true)}));
  put32(bad_list, 8 + 8 + 8 + 4 + 4, 0);  // the backend string's length (hash, utime, seq, width, height)
  ld::qr_code_list_t codes{};
  ld::qr_code_t c{};
  c.track_id = 7;
  c.payload = "dock";
  codes.codes = {c};
  codes.ncodes = 1;
  std::vector<uint8_t> bad_codes = bytes(codes);
  put32(bad_codes, 8 + 8 + 8 + 4 + 8, 0);  // the payload's length (hash, utime, seq, ncodes, track_id)
  std::vector<uint8_t> huge_codes = bytes(codes);
  put32(huge_codes, 8 + 8 + 8, 0x7fffffff);  // ncodes
  for (const char* channel : {"LANDMARKS", "LANDMARKS_TRACKED"})
    lcm.publish(channel, bad_list.data(), static_cast<unsigned>(bad_list.size()));
  lcm.publish("LANDMARK_CODES", bad_codes.data(), static_cast<unsigned>(bad_codes.size()));
  lcm.publish("LANDMARK_CODES", huge_codes.data(), static_cast<unsigned>(huge_codes.size()));
  const std::vector<uint8_t> good = bytes(list(1000, 0, {trackedLandmark(7, true)}));
  lcm.publish("LANDMARKS_TRACKED", good.data(), static_cast<unsigned>(good.size()));
  for (int i = 0; i < 5; ++i) ASSERT_NO_THROW(ASSERT_GE(lcm.handleTimeout(100), 1));
  const auto s = m.summary();
  EXPECT_EQ(s["frames"]["bad_messages"], 4);
  EXPECT_EQ(s["frames"]["tracked"], 1);
  EXPECT_EQ(m.trackedFrames(), 1);
}

TEST(BusMonitor, MatchesFramesByUtimeAndSeqAndSummarises) {
  ld::BusMonitor m;
  // three frames of a replayed log (their utimes 9 s old) arriving 33 ms
  // apart; tracked 2 ms, 3 ms after their arrival and (frame 2) never
  m.imageSeen(1000, 0, 9'000'000);
  m.imageSeen(2000, 1, 9'033'000);
  m.imageSeen(3000, 2, 9'066'000);
  m.landmarksSeen(list(1000, 0, {}), 9'001'000);
  m.trackedSeen(list(1000, 0, {trackedLandmark(7, true), trackedLandmark(8, true)}), 9'002'000);
  m.trackedSeen(list(2000, 1, {trackedLandmark(7, true), trackedLandmark(8, false)}, 1), 9'036'000);
  m.trackedSeen(list(9999, 5, {}), 9'040'000);  // an image never seen: no latency
  ld::qr_code_list_t codes{};
  ld::qr_code_t c{};
  c.track_id = 7;
  c.payload = "dock";
  codes.utime = 1000;  // (the frame the codes message answers)
  codes.codes = {c};
  codes.ncodes = 1;
  m.codesSeen(codes, 9'037'000);

  const auto s = m.summary();
  EXPECT_EQ(s["frames"]["images"], 3);
  EXPECT_EQ(s["frames"]["tracked"], 3);
  EXPECT_EQ(s["frames"]["matched"], 2);
  EXPECT_EQ(s["frames"]["unmatched_images"], 1);
  EXPECT_EQ(s["frames"]["tracker_skipped"], 1);
  EXPECT_EQ(s["frames"]["qr_reader_skipped"], 2);  // (3 tracked frames, 1 codes message)
  EXPECT_EQ(s["latency_ms"]["count"], 2);
  EXPECT_EQ(s["latency_ms"]["from"], "arrival");  // (utimes 9 s before: a replay's)
  EXPECT_DOUBLE_EQ(s["latency_ms"]["p50"].get<double>(), 2.0);
  EXPECT_DOUBLE_EQ(s["latency_ms"]["max"].get<double>(), 3.0);
  EXPECT_TRUE(s["per_frame"][2]["latency_ms"].is_null());
  EXPECT_EQ(s["landmarks_per_frame"]["histogram"]["2"], 1);
  EXPECT_EQ(s["landmarks_per_frame"]["histogram"]["1"], 1);
  EXPECT_EQ(s["landmarks_per_frame"]["histogram"]["0"], 1);
  ASSERT_EQ(s["tracks"].size(), 2u);
  EXPECT_EQ(s["tracks"][0]["id"], 7);
  EXPECT_EQ(s["tracks"][0]["payload"], "dock");
  EXPECT_EQ(s["tracks"][0]["frames_visible"], 2);
  EXPECT_TRUE(s["tracks"][1]["payload"].is_null());
  EXPECT_EQ(s["tracks"][1]["frames_coasting"], 1);
  EXPECT_EQ(s["payloads_decoded"], 1);
}

// A recording holding the set's outputs played onto the running set: every
// list and codes message of a frame comes twice. Each frame is counted once
// (the report said 80 tracked of 40 images, and skips from the two
// publishers' counters mixed), and the repeats are counted apart.
TEST(BusMonitor, RepeatedFramesAreCountedOnce) {
  ld::BusMonitor m;
  for (int64_t k = 0; k < 3; ++k) m.imageSeen(1000 * (k + 1), k, 9'000'000 + 33'000 * k);
  for (int copy = 0; copy < 2; ++copy)
    for (int64_t k = 0; k < 3; ++k) {
      m.landmarksSeen(list(1000 * (k + 1), k, {}, copy == 0 ? 0 : 5), 9'100'000);
      m.trackedSeen(list(1000 * (k + 1), k, {trackedLandmark(7, true)}, copy == 0 ? 0 : 4), 9'100'000);
      ld::qr_code_list_t codes{};
      codes.utime = 1000 * (k + 1);
      codes.seq = k;
      m.codesSeen(codes, 9'100'000);
    }
  m.trackedSeen(list(0, -1, {}), 9'200'000);  // (unstamped: never a repeat)
  m.trackedSeen(list(0, -1, {}), 9'200'000);
  const auto s = m.summary();
  EXPECT_EQ(s["frames"]["tracked"], 5);
  EXPECT_EQ(s["frames"]["repeated_messages"], 9);
  EXPECT_EQ(s["frames"]["detector_skipped"], 0);
  EXPECT_EQ(s["frames"]["tracker_skipped"], 0);
  EXPECT_EQ(s["tracks"][0]["frames_visible"], 3);
  EXPECT_EQ(m.repeatedMessages(), 9);
  // The log replayed again (its images come again too): a pass of its own,
  // whose lists are counted (they were all dropped as repeats)
  for (int64_t k = 0; k < 3; ++k) {
    m.imageSeen(1000 * (k + 1), k, 10'000'000 + 33'000 * k);
    m.trackedSeen(list(1000 * (k + 1), k, {trackedLandmark(7, true)}), 10'010'000 + 33'000 * k);
  }
  EXPECT_EQ(m.summary()["frames"]["tracked"], 8);
  EXPECT_EQ(m.repeatedMessages(), 9);
}

// One id that carried two landmarks' payloads (the tracker gave it to
// another landmark, whose code was read too) lists both, each from the
// frame it came from; the summary showed the last over the whole track (an
// audit). Before any codes message, the QR reader's skips are not known.
TEST(BusMonitor, TrackWithTwoPayloadsListsBoth) {
  ld::BusMonitor m;
  for (int i = 0; i < 10; ++i) m.trackedSeen(list(1000 + i, i, {trackedLandmark(2, true)}), 1000 + i);
  EXPECT_TRUE(m.summary()["frames"]["qr_reader_skipped"].is_null());
  EXPECT_NE(m.statusLine(1010).find("qr - |"), std::string::npos);  // (no QR reader heard yet)
  // no image seen, so no frame timed: "-", not "p50 0.00 ms"
  EXPECT_NE(m.statusLine(1020).find("| e2e - |"), std::string::npos) << m.statusLine(1030);
  ld::qr_code_list_t codes{};
  ld::qr_code_t c{};
  c.track_id = 2;
  c.payload = "E1";
  c.seq = 1;
  c.utime = 1001;
  codes.utime = 1009;  // (the frame the codes message answers)
  codes.seq = 9;
  codes.codes = {c};
  codes.ncodes = 1;
  m.codesSeen(codes, 1011);
  m.trackedSeen(list(1011, 11, {trackedLandmark(2, true, "E1")}), 1011);
  c.payload = "E3";
  c.seq = 11;
  c.utime = 1011;
  codes.utime = 1011;
  codes.seq = 11;
  codes.codes = {c};
  m.codesSeen(codes, 1013);
  m.trackedSeen(list(1013, 13, {trackedLandmark(2, true, "E3")}), 1013);
  const auto s = m.summary();
  ASSERT_EQ(s["tracks"].size(), 1u);
  const auto& t = s["tracks"][0];
  EXPECT_EQ(t["payload"], "E3");
  EXPECT_EQ(t["payload_changes"], 1);
  ASSERT_EQ(t["payloads"].size(), 2u);
  EXPECT_EQ(t["payloads"][0]["payload"], "E1");
  EXPECT_EQ(t["payloads"][0]["from_seq"], 1);
  EXPECT_EQ(t["payloads"][1]["payload"], "E3");
  EXPECT_EQ(t["payloads"][1]["from_seq"], 11);
  EXPECT_EQ(s["frames"]["qr_reader_skipped"], 10);  // 12 tracked, 2 answered by a codes message
  // a track known through a code first (its list lost) starts at the code's frame
  c.track_id = 9;
  c.seq = 13;
  c.utime = 1013;
  codes.utime = 1013;  // (a codes message answers one frame once: a repeat is left out)
  codes.seq = 13;
  codes.codes = {c};
  m.codesSeen(codes, 1014);
  EXPECT_EQ(m.summary()["tracks"][1]["first_seq"], 13);
  // the status line counts the frames before the last answered (0-8; 13 may
  // still be decoding), the summary every one
  EXPECT_NE(m.statusLine(2000).find("qr 9 |"), std::string::npos) << m.statusLine(3000);
  // and older lists of it arriving after the code, in any order, start it
  // at the oldest, its frames still ending at the code's
  m.trackedSeen(list(1012, 12, {trackedLandmark(9, true, "")}), 1015);
  EXPECT_EQ(m.summary()["tracks"][1]["first_seq"], 12);
  EXPECT_EQ(m.summary()["tracks"][1]["last_seq"], 13);
  m.trackedSeen(list(1010, 10, {trackedLandmark(9, true, "")}), 1016);
  m.trackedSeen(list(1012, 12, {trackedLandmark(9, true, "")}), 1017);  // (a repeat: left out)
  EXPECT_EQ(m.summary()["tracks"][1]["first_seq"], 10);
  EXPECT_EQ(m.summary()["tracks"][1]["last_seq"], 13);
}

// An image whose utime is a time of the last second (ld-camera's capture
// time, ld-play's publication) is timed from it: the latency includes its
// transfer, which LCM does not time from the kernel for an image. A
// replayed image (an old utime) is timed from its arrival.
TEST(BusMonitor, TimesLiveImagesFromTheirUtime) {
  ld::BusMonitor m;
  m.imageSeen(5'000'000, 0, 5'004'000);  // captured, arrived 4 ms later
  m.trackedSeen(list(5'000'000, 0, {}), 5'010'000);
  EXPECT_EQ(m.summary()["latency_ms"]["from"], "capture");
  EXPECT_DOUBLE_EQ(m.summary()["latency_ms"]["max"].get<double>(), 10.0);
  m.imageSeen(1'000, 1, 5'100'000);  // a logged image replayed
  m.trackedSeen(list(1'000, 1, {}), 5'103'000);
  const auto s = m.summary();
  EXPECT_EQ(s["latency_ms"]["from"], "capture and arrival");
  EXPECT_DOUBLE_EQ(s["per_frame"][0]["latency_ms"].get<double>(), 10.0);
  EXPECT_DOUBLE_EQ(s["per_frame"][1]["latency_ms"].get<double>(), 3.0);
  // the edges: a utime exactly a second before its arrival is live, one
  // after it (another clock ahead) is not; no frame timed: from null
  ld::BusMonitor edge;
  EXPECT_TRUE(edge.summary()["latency_ms"]["from"].is_null());
  edge.imageSeen(10'000'000, 0, 10'000'000 + ld::BusMonitor::kLiveUtimeUs);
  edge.trackedSeen(list(10'000'000, 0, {}), 11'000'002);
  edge.imageSeen(20'000'000, 1, 19'999'999);
  edge.trackedSeen(list(20'000'000, 1, {}), 20'000'004);
  const auto e = edge.summary();
  EXPECT_DOUBLE_EQ(e["per_frame"][0]["latency_ms"].get<double>(), 1000.002);
  EXPECT_DOUBLE_EQ(e["per_frame"][1]["latency_ms"].get<double>(), 0.005);
}

// ld-run's replay source publishes a log's utimes: a log made a moment
// before its replay has utimes of the last second, which are still not
// capture times. (Timed from them, a replay started 0.4 s after ld-log-images
// made its log read a constant 400 ms.)
TEST(BusMonitor, TimesALogsImagesFromTheirArrivalHoweverRecent) {
  ld::BusMonitor m;
  m.setUtimesLogged(true);
  m.imageSeen(5'000'000, 0, 5'400'000);  // logged 0.4 s before its replay
  m.trackedSeen(list(5'000'000, 0, {}), 5'403'000);
  const auto s = m.summary();
  EXPECT_EQ(s["latency_ms"]["from"], "arrival");
  EXPECT_DOUBLE_EQ(s["per_frame"][0]["latency_ms"].get<double>(), 3.0);
}

// A tracker that restarts numbers its tracks from 1 again: the summary keeps
// the two runs' track 1 apart (they are different landmarks), and a payload
// read from a frame of the first run stays with the first run's track even
// when it comes after the restart.
TEST(BusMonitor, KeepsTheTracksOfATrackerRunApartFromTheNext) {
  ld::BusMonitor m;
  for (int i = 0; i < 20; ++i)
    m.trackedSeen(list(1000 + i, i, {trackedLandmark(1, true, "", i), trackedLandmark(2, true, "", i)}), 1000 + i);
  // the tracker restarts: its first tracks are 1 again, 0 frames old
  for (int i = 0; i < 5; ++i)
    m.trackedSeen(list(2000 + i, 100 + i, {trackedLandmark(1, true, "", i)}), 2000 + i);
  // the codes of a frame of the first run come after the restart (late),
  // then those of a frame of the second
  ld::qr_code_list_t codes{};
  ld::qr_code_t old_read{}, new_read{};
  old_read.track_id = 1;
  old_read.payload = "dock";
  old_read.utime = 1012;  // read in a frame of the first run
  old_read.seq = 12;
  codes.utime = 1015;
  codes.seq = 15;
  codes.codes = {old_read};
  codes.ncodes = 1;
  m.codesSeen(codes, 2008);
  new_read.track_id = 1;
  new_read.payload = "room-101";
  new_read.utime = 2003;
  new_read.seq = 103;
  codes.utime = 2004;
  codes.seq = 104;
  codes.codes = {new_read};
  m.codesSeen(codes, 2010);

  const auto s = m.summary();
  EXPECT_EQ(s["tracker_restarts"], 1);
  ASSERT_EQ(s["tracks"].size(), 3u);
  EXPECT_EQ(s["tracks"][0]["id"], 1);
  EXPECT_EQ(s["tracks"][0]["tracker_run"], 1);
  EXPECT_EQ(s["tracks"][0]["payload"], "dock");
  EXPECT_EQ(s["tracks"][0]["frames_visible"], 20);
  EXPECT_EQ(s["tracks"][0]["last_seq"], 19);
  EXPECT_EQ(s["tracks"][1]["id"], 2);
  EXPECT_EQ(s["tracks"][1]["tracker_run"], 1);
  EXPECT_EQ(s["tracks"][2]["id"], 1);
  EXPECT_EQ(s["tracks"][2]["tracker_run"], 2);
  EXPECT_EQ(s["tracks"][2]["payload"], "room-101");
  EXPECT_EQ(s["tracks"][2]["payload_changes"], 0);
  EXPECT_EQ(s["tracks"][2]["first_seq"], 100);
  EXPECT_EQ(s["tracks"][2]["frames_visible"], 5);
  EXPECT_EQ(s["payloads_decoded"], 2);
  EXPECT_EQ(s["per_frame"][19]["tracker_run"], 1);
  EXPECT_EQ(s["per_frame"][20]["tracker_run"], 2);
}

// A log replayed again after the tracker restarted: the second pass's frames
// have the first pass's times, and a code read in the second pass is of the
// run that tracked it (run 2), not of the run whose frames had that time
// first (it made two tracks that never were, and the real one unread).
TEST(BusMonitor, CodeOfAReplayedFrameGoesToTheRunThatTrackedIt) {
  ld::BusMonitor m;
  for (int i = 0; i < 10; ++i) {  // the first pass, tracker run 1
    m.imageSeen(1000 + i, i, 5000 + i);
    m.trackedSeen(list(1000 + i, i, {trackedLandmark(1, true, "", i)}), 5000 + i);
  }
  for (int i = 0; i < 5; ++i) {  // the tracker restarts: run 2
    m.imageSeen(1010 + i, 10 + i, 5010 + i);
    m.trackedSeen(list(1010 + i, 10 + i, {trackedLandmark(1, true, "", i)}), 5010 + i);
  }
  // the log is replayed again from its start; run 2 goes on (ids 3 and on)
  for (int i = 0; i < 5; ++i) {
    m.imageSeen(1000 + i, i, 6000 + i);
    m.trackedSeen(list(1000 + i, i, {trackedLandmark(3, true, "", i)}), 6000 + i);
  }
  ld::qr_code_list_t codes{};
  ld::qr_code_t read{};
  read.track_id = 3;
  read.payload = "room-101";
  read.utime = 1002;  // read in the second pass's frame 2
  read.seq = 2;
  codes.codes = {read};
  codes.ncodes = 1;
  codes.utime = 1004;
  codes.seq = 4;
  m.codesSeen(codes, 6010);
  const auto s = m.summary();
  EXPECT_EQ(s["tracker_restarts"], 1);
  ASSERT_EQ(s["tracks"].size(), 3u) << s["tracks"].dump();  // 1/1, 1/2, 3/2
  for (const auto& t : s["tracks"]) {
    if (t["id"] == 3) {
      EXPECT_EQ(t["tracker_run"], 2);
      EXPECT_EQ(t["payload"], "room-101");
      EXPECT_EQ(t["frames_visible"], 5);
    } else {
      EXPECT_EQ(t["id"], 1);
      EXPECT_TRUE(t["payload"].is_null()) << t.dump();
    }
  }
}

TEST(BusMonitor, SkipCountersSurviveAPublisherRestart) {
  ld::BusMonitor m;
  m.landmarksSeen(list(1, 1, {}, 5), 1);
  m.landmarksSeen(list(2, 2, {}, 7), 2);
  m.landmarksSeen(list(3, 3, {}, 1), 3);  // restarted: counts from 0 again
  EXPECT_EQ(m.summary()["frames"]["detector_skipped"], 8);
}

TEST(BusMonitor, Percentiles) {
  const auto p = ld::percentiles({5, 1, 4, 2, 3, 6, 7, 8, 9, 10});
  EXPECT_EQ(p.count, 10u);
  EXPECT_DOUBLE_EQ(p.p50, 5);
  EXPECT_DOUBLE_EQ(p.p90, 9);
  EXPECT_DOUBLE_EQ(p.p99, 10);
  EXPECT_DOUBLE_EQ(p.mean, 5.5);
  EXPECT_EQ(ld::percentiles({}).count, 0u);
}

// The whole run's latencies in fixed memory: the same percentiles as
// ld::percentiles of the values themselves, to the bit within +-65.536 ms
// (a replay's latency can read negative), to the millisecond above; the
// largest and the mean exact.
TEST(BusMonitor, LatencyHistogramGivesThePercentilesOfItsValues) {
  std::mt19937 rng(7);
  const auto binned = [](int64_t us) {  // what a 1-ms bin reads: its lower edge
    return us < 65'536 ? static_cast<double>(us) * 1e-3 : 65.536 + static_cast<double>((us - 65'536) / 1000);
  };
  for (const int n : {1, 2, 10, 999, 20000}) {
    ld::LatencyHistogram h;
    std::vector<double> exact_ms, binned_ms;
    for (int i = 0; i < n; ++i) {
      // mostly 0.5-30 ms, a few over 65.536 ms, a few below 0
      const int64_t us = i % 97 == 5   ? 65'536 + static_cast<int64_t>(rng() % 400'000)
                         : i % 89 == 3 ? -static_cast<int64_t>(rng() % 5'000)
                                       : 500 + static_cast<int64_t>(rng() % 29'500);
      h.add(us);
      exact_ms.push_back(static_cast<double>(us) * 1e-3);
      binned_ms.push_back(binned(us));
    }
    const auto want = ld::percentiles(binned_ms);
    const auto got = h.percentiles();
    EXPECT_EQ(got.count, static_cast<size_t>(n));
    EXPECT_DOUBLE_EQ(got.p50, want.p50) << n;
    EXPECT_DOUBLE_EQ(got.p90, want.p90) << n;
    EXPECT_DOUBLE_EQ(got.p99, want.p99) << n;
    EXPECT_DOUBLE_EQ(got.max, ld::percentiles(exact_ms).max) << n;
    EXPECT_NEAR(got.mean, ld::percentiles(exact_ms).mean, 1e-9) << n;
  }
  // on either side of the 1-ms bins' start, in order (a value just above
  // 65.536 ms read below those just under it: p99 under p90)
  ld::LatencyHistogram edge;
  for (int i = 0; i < 90; ++i) edge.add(65'000 + i);
  for (int i = 0; i < 10; ++i) edge.add(65'600);
  const auto e = edge.percentiles();
  EXPECT_LE(e.p50, e.p90);
  EXPECT_LE(e.p90, e.p99);
  EXPECT_DOUBLE_EQ(e.p99, 65.536);
  EXPECT_DOUBLE_EQ(e.p90, 65.089);
  // negative ones as they are
  ld::LatencyHistogram negative;
  for (const int64_t us : {-3'000, -2'000, -1'000, 5'000}) negative.add(us);
  EXPECT_DOUBLE_EQ(negative.percentiles().p50, -2.0);
  // beyond the ends: read as the largest, the smallest
  ld::LatencyHistogram far;
  far.add(-90'000'000);
  far.add(1'000);
  far.add(90'000'000);
  EXPECT_DOUBLE_EQ(far.percentiles().p99, 90'000.0);
  EXPECT_DOUBLE_EQ(far.percentiles().p50, 1.0);
  EXPECT_DOUBLE_EQ(ld::percentiles({-90'000.0, 1.0, 90'000.0}).p50, 1.0);
  ld::LatencyHistogram low;
  low.add(-90'000'000);
  low.add(1'000);
  EXPECT_DOUBLE_EQ(low.percentiles().p50, -90'000.0);
  EXPECT_EQ(ld::LatencyHistogram().percentiles().count, 0u);
}

// A run of hours: the summary lists the last kFramesKept frames and counts
// the earlier ones; every other figure counts every frame (a vector of every
// frame grew without end: about 130 bytes a frame, 16 MB an hour at 30
// frames/s, and several times that in the summary's JSON at the end).
TEST(BusMonitor, LongRunListsTheLastFramesAndCountsThemAll) {
  ld::BusMonitor m;
  const size_t kept = ld::BusMonitor::kFramesKept, total = kept + 500;
  std::vector<double> latencies;
  for (size_t i = 0; i < total; ++i) {
    const auto t = static_cast<int64_t>(i) * 33'333;
    const int64_t latency_us = 1'000 + static_cast<int64_t>(i % 101) * 13;
    m.imageSeen(t + 1, static_cast<int64_t>(i), t + 10'000'000);
    m.trackedSeen(list(t + 1, static_cast<int64_t>(i), {trackedLandmark(1, true, "", 0)}),
                  t + 10'000'000 + latency_us);
    latencies.push_back(static_cast<double>(latency_us) * 1e-3);
  }
  // the QR reader answers the last frame only: every earlier one skipped,
  // those no longer listed too
  ld::qr_code_list_t codes{};
  codes.utime = static_cast<int64_t>(total - 1) * 33'333 + 1;
  codes.seq = static_cast<int64_t>(total - 1);
  m.codesSeen(codes, static_cast<int64_t>(total) * 33'333 + 10'100'000);
  const auto s = m.summary();
  ASSERT_EQ(s["per_frame"].size(), kept);
  EXPECT_EQ(s["per_frame_left_out"], 500);
  EXPECT_EQ(s["per_frame"][0]["seq"], 500);
  EXPECT_EQ(s["per_frame"][kept - 1]["seq"], static_cast<int64_t>(total - 1));
  EXPECT_EQ(s["frames"]["tracked"], static_cast<int64_t>(total));
  EXPECT_EQ(s["frames"]["qr_reader_skipped"], static_cast<int64_t>(total - 1));
  const auto want = ld::percentiles(latencies);
  EXPECT_EQ(s["latency_ms"]["count"], static_cast<int64_t>(total));
  EXPECT_DOUBLE_EQ(s["latency_ms"]["p50"].get<double>(), std::round(want.p50 * 1000) / 1000);
  EXPECT_DOUBLE_EQ(s["latency_ms"]["p99"].get<double>(), std::round(want.p99 * 1000) / 1000);
  EXPECT_DOUBLE_EQ(s["latency_ms"]["max"].get<double>(), 2.3);
  EXPECT_EQ(s["landmarks_per_frame"]["histogram"]["1"], static_cast<int64_t>(total));
  EXPECT_EQ(m.latencyCount(), total);

  // A QR reader that answers every other frame all along: half skipped,
  // past the cap too (the frames the reader settles are counted from the
  // first, not from the first kept)
  ld::BusMonitor every_other;
  for (size_t i = 0; i < total; ++i) {
    const auto t = static_cast<int64_t>(i) * 33'333 + 1;
    every_other.trackedSeen(list(t, static_cast<int64_t>(i), {}), t + 10'000);
    if (i % 2 == 1) {
      ld::qr_code_list_t answer{};
      answer.utime = t;
      answer.seq = static_cast<int64_t>(i);
      every_other.codesSeen(answer, t + 20'000);
    }
  }
  EXPECT_EQ(every_other.summary()["frames"]["qr_reader_skipped"], static_cast<int64_t>(total / 2));
}

// A robot driving past landmarks for days makes tens of thousands of
// tracks: the summary lists the kTracksKept most recently seen and counts
// the others; the count of tracks read counts them all. (Every track was
// kept: about 170 bytes each, and its summary at the end peaked at 1.2 GB
// with 500,000.)
TEST(BusMonitor, LongRunListsTheLastTracksAndCountsThemAll) {
  ld::BusMonitor m;
  const int64_t total = static_cast<int64_t>(ld::BusMonitor::kTracksKept) * 12 / 10 + 7;
  for (int64_t i = 0; i < total; ++i) {
    // a new track every frame, every third read; and one seen all along
    m.trackedSeen(list(1000 + i, i,
                       {trackedLandmark(i, true, i % 3 == 0 ? "room-" + std::to_string(i) : ""),
                        trackedLandmark(1'000'000, true, "dock")}),
                  5000 + i);
  }
  const auto s = m.summary();
  const auto kept = static_cast<int64_t>(s["tracks"].size());
  EXPECT_LE(kept, static_cast<int64_t>(ld::BusMonitor::kTracksKept * 11 / 10) + 1);
  EXPECT_GE(kept, static_cast<int64_t>(ld::BusMonitor::kTracksKept));
  EXPECT_EQ(kept + s["tracks_left_out"].get<int64_t>(), total + 1);
  EXPECT_EQ(s["payloads_decoded"], (total + 2) / 3 + 1);
  bool dock = false, newest = false, oldest = false;
  for (const auto& t : s["tracks"]) {
    dock = dock || (t["id"] == 1'000'000 && t["frames_visible"] == total && t["payload"] == "dock");
    newest = newest || t["id"] == total - 1;
    oldest = oldest || t["id"] == 0;
  }
  EXPECT_TRUE(dock);
  EXPECT_TRUE(newest);
  EXPECT_FALSE(oldest);
  const std::string line = m.statusLine(10'000'000);
  EXPECT_NE(line.find("tracks " + std::to_string(total + 1) + ", " + std::to_string((total + 2) / 3 + 1) + " read"),
            std::string::npos)
      << line;
}

// A tracker restart long after the last run's track 1 was listed: told all
// the same (a watch that forgot tracks after 3000 lists, as ld-qr-reader's,
// missed it, and the old and the new track 1 merged into one with two
// payloads).
TEST(BusMonitor, TrackerRestartIsToldLongAfterItsIdsWereListed) {
  ld::BusMonitor m;
  int64_t seq = 0;
  for (int i = 0; i < 20; ++i, ++seq) m.trackedSeen(list(1000 + seq, seq, {trackedLandmark(1, true, "dock", i)}), 5000 + seq);
  for (int i = 0; i < 4000; ++i, ++seq) m.trackedSeen(list(1000 + seq, seq, {trackedLandmark(2, true, "", 20 + i)}), 5000 + seq);
  m.trackedSeen(list(1000 + seq, seq, {trackedLandmark(1, true, "room-7", 0)}), 5000 + seq);
  const auto s = m.summary();
  EXPECT_EQ(s["tracker_restarts"], 1);
  ASSERT_EQ(s["tracks"].size(), 3u) << s["tracks"].dump();
  for (const auto& t : s["tracks"]) EXPECT_EQ(t["payload_changes"], 0) << t.dump();
}

// ld-run's memory samples over days: at most kRssSamplesKept, evenly spread
// over the whole run, the largest and the last exact.
TEST(RssSeries, KeepsTheWholeCourseInAFixedNumberOfSamples) {
  ld::RssSeries r;
  const int looks = 3 * 86400;  // three days of a look a second
  for (int i = 0; i < looks; ++i) r.add(i, i == 1000 ? 900'000 : 50'000 + i / 1000);
  EXPECT_LE(r.samples.size(), ld::RssSeries::kRssSamplesKept);
  EXPECT_GE(r.samples.size(), ld::RssSeries::kRssSamplesKept / 2);
  EXPECT_EQ(r.max_kb, 900'000);
  EXPECT_EQ(r.last_kb, 50'000 + (looks - 1) / 1000);
  EXPECT_DOUBLE_EQ(r.samples.front().first, 0);
  EXPECT_GT(r.samples.back().first, looks - 300);  // (every 256th look by then)
  const double step = r.samples[1].first - r.samples[0].first;
  for (size_t i = 1; i < r.samples.size(); ++i)
    ASSERT_DOUBLE_EQ(r.samples[i].first - r.samples[i - 1].first, step) << i;
  // a short run keeps every look
  ld::RssSeries brief;
  for (int i = 0; i < 100; ++i) brief.add(i, 1);
  EXPECT_EQ(brief.samples.size(), 100u);
}

TEST(RunConfig, ReadsJsonAndBuildsTheProcessTable) {
  const auto cfg = ld::RunConfig::fromJson(nlohmann::json::parse(R"({
    "lcm_url": "udpm://239.255.76.67:7667?ttl=0",
    "source": {"type": "replay", "log": "x.lcmlog", "speed": 2},
    "detector": {"args": ["--params", "d.yaml"]},
    "qr_reader": {"enabled": false},
    "record": {"file": "out.lcmlog"}
  })"));
  const auto specs = ld::buildProcessSpecs(cfg, cfg.lcm_url, "");
  ASSERT_EQ(specs.size(), 4u);
  EXPECT_EQ(specs[0].name, "recorder");
  EXPECT_EQ(specs[0].role, ld::ProcessRole::Recorder);
  EXPECT_EQ(specs[1].name, "detector");
  EXPECT_EQ(specs[1].argv.back(), "d.yaml");
  EXPECT_EQ(specs[2].name, "tracker");
  EXPECT_EQ(specs[3].name, "replay");
  EXPECT_EQ(specs[3].role, ld::ProcessRole::Source);
  EXPECT_EQ(specs[3].argv.back(), "x.lcmlog");
  EXPECT_NE(std::find(specs[3].argv.begin(), specs[3].argv.end(), "--regexp=^IMAGE$"), specs[3].argv.end());
  // a log whose name starts with '-' goes as ./-...: lcm-logplayer took it
  // for its options, and the replay was restarted for ever
  for (const char* type : {"replay", "play"}) {
    auto dashed = ld::RunConfig::fromJson(nlohmann::json::parse(std::string(R"({"source": {"type": ")") + type +
                                                                 R"(", "log": "-r.lcmlog"}})"));
    const auto d = ld::buildProcessSpecs(dashed, "udpm://239.255.76.67:7667?ttl=0", "");
    const auto& argv = d.back().argv;
    EXPECT_NE(std::find(argv.begin(), argv.end(), "./-r.lcmlog"), argv.end()) << type;
    EXPECT_EQ(std::find(argv.begin(), argv.end(), "-r.lcmlog"), argv.end()) << type;
  }
  // (the recording too: lcm-logger took -o.lcmlog for its options)
  auto recorded = ld::RunConfig::fromJson(nlohmann::json::parse(
      R"({"source": {"type": "play", "log": "x.lcmlog"}, "record": {"file": "-o.lcmlog"}})"));
  const auto r = ld::buildProcessSpecs(recorded, "udpm://239.255.76.67:7667?ttl=0", "");
  EXPECT_EQ(r.front().name, "recorder");
  EXPECT_EQ(r.front().argv.back(), "./-o.lcmlog");
}

TEST(RunConfig, RejectsUnknownKeysAndBadValues) {
  EXPECT_THROW(ld::RunConfig::fromJson(nlohmann::json::parse(R"({"detectr": {}})")), std::runtime_error);
  EXPECT_THROW(ld::RunConfig::fromJson(nlohmann::json::parse(R"({"source": {"type": "tape"}})")),
               std::runtime_error);
  EXPECT_THROW(ld::RunConfig::fromJson(nlohmann::json::parse(R"({"tracker": {"args": "x"}})")),
               std::runtime_error);
  EXPECT_THROW(ld::RunConfig::fromJson(nlohmann::json::parse(R"({"restart": {"initial_s": 0}})")),
               std::runtime_error);
  EXPECT_THROW(ld::RunConfig::fromJson(nlohmann::json::parse(R"({"restart": {"hang_s": 0.5}})")),
               std::runtime_error);
  EXPECT_EQ(ld::RunConfig::fromJson(nlohmann::json::parse(R"({"restart": {"hang_s": 0}})")).restart.hang_s, 0);
  EXPECT_EQ(ld::RunConfig::fromJson(nlohmann::json::parse("{}")).restart.hang_s, 10);
  try {
    ld::RunConfig::fromJson(nlohmann::json::parse(R"({"channels": {"image": ""}})"));
    ADD_FAILURE() << "an empty channel name: no error";
  } catch (const std::runtime_error& e) {
    EXPECT_EQ(std::string(e.what()), "channels.image: a channel name, not \"\"");
  }
  const auto cfg = ld::RunConfig::fromJson(nlohmann::json::parse(R"({"source": {"type": "replay"}})"));
  EXPECT_THROW(ld::buildProcessSpecs(cfg, "udpm://", ""), std::runtime_error);  // no log
  // Channels the set would pass nothing on, without a word: a name LCM's
  // subscriptions read as another (CAM(1) takes CAM1), one channel for two
  // roles, patterns lcm-logger or lcm-logplayer cannot read (an empty
  // recording, status 0).
  const auto error = [](const char* text) {
    try {
      ld::RunConfig::fromJson(nlohmann::json::parse(text));
    } catch (const std::runtime_error& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  EXPECT_EQ(error(R"j({"channels": {"image": "CAM(1)"}})j"),
            "channels.image: CAM(1) is read by LCM's subscriptions as a regular expression that does not take the "
            "name itself: name it with letters, digits and _ - / . alone");
  EXPECT_EQ(error(R"j({"channels": {"landmarks": "L", "codes": "L"}})j"),
            "channels.codes: L is also channels.landmarks: another type of message on one channel");
  EXPECT_EQ(error(R"j({"channels": {"image": "LANDMARK_CODES"}})j"),
            "channels.codes: LANDMARK_CODES is also channels.image: another type of message on one channel");
  // (the detector's lists as the tracked ones, with the tracker left out: one type)
  EXPECT_EQ(error(R"j({"tracker": {"enabled": false}, "channels": {"tracked": "LANDMARKS"}})j"), "");
  EXPECT_EQ(error(R"j({"record": {"file": "r.lcmlog", "channels": "("}})j"),
            "record.channels: ( is no regular expression lcm-logger can read (missing terminating ))");
  EXPECT_EQ(error(R"j({"source": {"type": "replay", "log": "a.lcmlog", "channels": "IMAGE|["}})j"),
            "source.channels: IMAGE|[ is no regular expression lcm-logplayer can read (missing terminating ] for "
            "character class)");
  // (a trailing backslash escaped the $ the check added: taken, then refused by lcm-logplayer)
  EXPECT_EQ(error(R"j({"source": {"type": "replay", "log": "a.lcmlog", "channels": "IMAGE\\"}})j"),
            "source.channels: IMAGE\\ is no regular expression lcm-logplayer can read (\\ at end of pattern)");
  EXPECT_EQ(error(R"j({"channels": {"image": "CAM/front.left-1"}, "record": {"file": "r.lcmlog", "channels": "LANDMARK.*"}})j"), "");
  // a recording split into files (lcm-logger's --split-mb and --rotate)
  EXPECT_EQ(error(R"j({"record": {"file": "r.lcmlog", "split_mb": -1}})j"),
            "record: split_mb must be 0 (one file) or 0.001 to 1000000 MB");
  EXPECT_EQ(error(R"j({"record": {"file": "r.lcmlog", "split_mb": 10, "keep": 1}})j"), "record: keep must be 2 to 1000 files");
  EXPECT_EQ(error(R"j({"record": {"file": "r.lcmlog", "keep": 5}})j"),
            "record: keep is the number of files split_mb makes: give split_mb too");
  const auto split = ld::RunConfig::fromJson(nlohmann::json::parse(
      R"j({"source": {"type": "none"}, "record": {"file": "r.lcmlog", "split_mb": 50, "keep": 7}})j"));
  const auto specs = ld::buildProcessSpecs(split, "udpm://239.255.76.67:7667?ttl=0", "");
  const auto recorder = std::find_if(specs.begin(), specs.end(), [](const auto& p) { return p.name == "recorder"; });
  ASSERT_NE(recorder, specs.end());
  const std::vector<std::string> tail(recorder->argv.end() - 4, recorder->argv.end());
  EXPECT_EQ(tail, (std::vector<std::string>{"--rotate=7", "--split-mb=50", "-q", "r.lcmlog"}));
  const auto one = ld::buildProcessSpecs(
      ld::RunConfig::fromJson(nlohmann::json::parse(R"j({"source": {"type": "none"}, "record": {"file": "r.lcmlog"}})j")),
      "udpm://239.255.76.67:7667?ttl=0", "");
  EXPECT_EQ(std::count(one.front().argv.begin(), one.front().argv.end(), "-a"), 1);
}

// --play-format and source.format take what ld-play's --format takes (keep,
// or a pixel format of ld::pixelFormatFromName), so that ld-run refuses a
// bad one at once instead of restarting ld-play on it again and again.
TEST(RunConfig, PlayFormatIsOneLdPlayTakes) {
  for (const char* f : {"keep", "bgr", "YUYV", "mjpg", "gray", "rgba"}) EXPECT_NO_THROW(ld::checkPlayFormat(f)) << f;
  for (const char* f : {"foo", "", "Keep"}) EXPECT_THROW(ld::checkPlayFormat(f), std::runtime_error) << f;
  try {
    ld::checkPlayFormat("foo");
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("'foo'"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("keep"), std::string::npos) << e.what();
  }
  const auto cfg = ld::RunConfig::fromJson(
      nlohmann::json::parse(R"({"source": {"type": "play", "log": "x.lcmlog", "format": "uyvy"}})"));
  EXPECT_EQ(cfg.play_format, "uyvy");
  try {
    ld::RunConfig::fromJson(nlohmann::json::parse(R"({"source": {"type": "play", "log": "x", "format": "foo"}})"));
    ADD_FAILURE() << "source.format foo accepted";
  } catch (const std::runtime_error& e) {
    EXPECT_EQ(std::string(e.what()).rfind("source.format: unknown pixel format 'foo'", 0), 0u) << e.what();
  }
}

TEST(RunConfig, ExampleConfigLoads) {
  const auto cfg = ld::RunConfig::load(std::string(LD_SOURCE_DIR) + "/tools/run/ld-run.example.json");
  EXPECT_EQ(cfg.source, "camera");
  // no bus of its own: $LCM_DEFAULT_URL (/etc/default/landmark) decides
  EXPECT_EQ(cfg.lcm_url, "");
  EXPECT_FALSE(ld::buildProcessSpecs(cfg, "udpm://239.255.76.67:7667?ttl=0", "").empty());
}

// The YAML example says what the JSON one says: the same process table.
TEST(RunConfig, YamlExampleIsTheJsonExample) {
  const auto json = ld::RunConfig::load(std::string(LD_SOURCE_DIR) + "/tools/run/ld-run.example.json");
  const auto yaml = ld::RunConfig::load(std::string(LD_SOURCE_DIR) + "/tools/run/ld-run.example.yaml");
  const auto a = ld::buildProcessSpecs(json, "udpm://239.255.76.67:7667?ttl=0", "/opt/x");
  const auto b = ld::buildProcessSpecs(yaml, "udpm://239.255.76.67:7667?ttl=0", "/opt/x");
  ASSERT_EQ(a.size(), b.size());
  for (size_t i = 0; i < a.size(); ++i) {
    EXPECT_EQ(a[i].name, b[i].name);
    EXPECT_EQ(a[i].argv, b[i].argv) << a[i].name;
  }
  EXPECT_EQ(json.lcm_url, yaml.lcm_url);
  EXPECT_EQ(yaml.camera_args.back(), "30");  // a number in args stays as written
  EXPECT_DOUBLE_EQ(yaml.restart.initial_s, 0.2);
  EXPECT_DOUBLE_EQ(yaml.restart.max_s, 5);
}

TEST(RunConfig, YamlErrorsNameTheKeyOrTheLine) {
  auto loadError = [](const std::string& name, const std::string& text) {
    const std::string path = ::testing::TempDir() + name;
    std::ofstream(path) << text;
    try {
      ld::RunConfig::load(path);
    } catch (const std::runtime_error& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  EXPECT_EQ(loadError("empty.yaml", ""), "");  // every default
  EXPECT_EQ(loadError("ok.yml", "source: {type: replay, log: run.lcmlog, speed: 2}\ntracker: {enabled: false}\n"), "");
  EXPECT_NE(loadError("k.yaml", "detectr: {}\n").find("unknown key \"detectr\""), std::string::npos);
  EXPECT_NE(loadError("n.yaml", "source: {type: replay, speed: fast}\n").find("source.speed: expected a number, got \"fast\""),
            std::string::npos);
  EXPECT_NE(loadError("x.yaml", "source: {type: replay, speed: 0x10}\n").find("expected a number"), std::string::npos);
  EXPECT_NE(loadError("b.yaml", "tracker: {enabled: yes}\n").find("tracker.enabled: expected true or false, got \"yes\""),
            std::string::npos);
  // a quoted or tagged true is text, as YAML says
  EXPECT_NE(loadError("q.yaml", "tracker: {enabled: \"true\"}\n").find("expected true or false"), std::string::npos);
  EXPECT_NE(loadError("t.yaml", "tracker: {enabled: !!str true}\n").find("expected true or false"), std::string::npos);
  EXPECT_EQ(loadError("s.yaml", "source: {type: replay, log: !!str null}\n"), "");  // a log named "null"
  // args keep what was written; "args:" alone is none
  EXPECT_EQ(loadError("a.yaml", "tracker: {args: [--x, true, 30, 1e3]}\ndetector: {args: }\n"), "");
  EXPECT_NE(loadError("an.yaml", "tracker: {args: [--x, ~]}\n").find("tracker.args: expected text in the list, got null"),
            std::string::npos);
  // a key that is not text; aliases that would expand into millions of values
  EXPECT_NE(loadError("k2.yaml", "{[a, b]: 1}\n").find("k2.yaml: line 1: a key must be text"), std::string::npos);
  std::string bomb = "a: &a [x, x, x, x, x, x, x, x, x, x]\n";
  for (char c = 'b'; c <= 'i'; ++c)
    bomb += std::string(1, c) + ": &" + c + " [*" + static_cast<char>(c - 1) + ", *" + static_cast<char>(c - 1) +
            ", *" + static_cast<char>(c - 1) + ", *" + static_cast<char>(c - 1) + ", *" + static_cast<char>(c - 1) +
            ", *" + static_cast<char>(c - 1) + ", *" + static_cast<char>(c - 1) + ", *" + static_cast<char>(c - 1) +
            ", *" + static_cast<char>(c - 1) + ", *" + static_cast<char>(c - 1) + "]\n";
  EXPECT_NE(loadError("bomb.yaml", bomb).find("more than 100000 values"), std::string::npos) << loadError("bomb.yaml", bomb);
  // bytes that are not UTF-8 (found by fuzz_run_config: the error message's JSON dump threw)
  const std::string latin1 = "tracker:\n  args: [--x, \"a\xe4" "c\"]\n";
  EXPECT_NE(loadError("u.yaml", latin1).find("u.yaml: line 2: text that is not UTF-8"), std::string::npos)
      << loadError("u.yaml", latin1);
  const std::string bad = loadError("bad.yaml", "source:\n  type: [camera\n");
  EXPECT_NE(bad.find("bad.yaml: not valid YAML: line"), std::string::npos) << bad;
  // JSON too: a number beyond a double threw nlohmann's out_of_range, not a
  // parse error, past the reader (found by fuzz_run_config)
  const std::string overflow = loadError("big.json", "{\"source\": {\"speed\": 3e333}}");
  EXPECT_NE(overflow.find("big.json: not valid JSON"), std::string::npos) << overflow;
  // an image or a log given by mistake: said, not a parse error ending in a raw byte
  const std::string png = loadError("lm.json", std::string("\x89PNG\r\n\x1a\n\0\0\0\rIHDR", 16));
  EXPECT_NE(png.find("lm.json contains a NUL byte at offset 8 (not a text file)"), std::string::npos) << png;
  EXPECT_NE(loadError("w.json", std::string("\xFF\xFE{\0}\0", 6)).find("w.json is UTF-16 text: save it as UTF-8"),
            std::string::npos);
  const std::string latin = loadError("l1.json", "{\"source\": \xe4}");
  EXPECT_NE(latin.find("not valid JSON"), std::string::npos) << latin;
  EXPECT_NE(latin.find("\\xE4"), std::string::npos) << latin;
  EXPECT_EQ(latin.find('\xe4'), std::string::npos) << latin;
  try {
    ld::RunConfig::load("/nonexistent/robot.json");
    ADD_FAILURE();
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("cannot read config /nonexistent/robot.json: No such file or directory"), std::string::npos) << e.what();
  }
  // JSON stays strict: a number written as text is refused
  EXPECT_NE(loadError("str.json", "{\"source\": {\"speed\": \"2\"}}").find("source.speed: expected a number, got \"2\""),
            std::string::npos);
}

// A config path without an extension (ld-run@.service's /etc/landmark/<instance>)
// is the .yaml, .yml or .json of that name; two of them is an error.
// An option ld-run passes a program itself, given again in the config's args,
// is refused naming where it is set: the program refused it as given twice
// ("--in: At Most 1 required but received 2"), which the user never typed
// (an audit). Other options, and values that look alike, pass.
TEST(RunConfig, ArgsThatRepeatLdRunsOwnOptionsAreRefused) {
  for (const auto& [json, expected] : std::vector<std::pair<std::string, std::string>>{
           {R"({"detector": {"args": ["--in", "X"]}})",
            "detector's args give --in, which ld-run passes itself from the config's channels: set it there"},
           {R"({"tracker": {"args": ["--lcm-url=udpm://239.255.76.67:7667"]}})",
            "tracker's args give --lcm-url, which ld-run passes itself from the config's lcm_url (or --lcm-url)"},
           {R"({"qr_reader": {"args": ["-v", "--tracks", "T"]}})", "qr-reader's args give --tracks"},
           {R"({"qr_reader": {"args": ["--codes=C"]}})",  // (its other name, as ld-view's)
            "qr-reader's args give --codes (its --out), which ld-run passes itself from the config's channels"},
           {R"({"source": {"type": "replay", "log": "a.lcmlog", "args": ["--speed=3"]}})",
            "replay's args give --speed, which ld-run passes itself from the config's source's speed"},
           {R"({"source": {"type": "replay", "log": "a.lcmlog", "args": ["--lcm-url=udpm://239.255.76.67:7000"]}})",
            "replay's args give --lcm-url"},
           {R"({"source": {"type": "play", "log": "a.lcmlog", "args": ["--fps=5"]}})",
            "play's args give --fps, which ld-run passes itself from the config's source (fps, format, duration_s)"}}) {
    const auto cfg = ld::RunConfig::fromJson(nlohmann::json::parse(json));
    try {
      ld::buildProcessSpecs(cfg, "udpm://239.255.76.67:7667?ttl=0", "");
      ADD_FAILURE() << json << ": no error";
    } catch (const std::runtime_error& e) {
      EXPECT_NE(std::string(e.what()).find(expected), std::string::npos) << e.what();
    }
  }
  const auto ok = ld::RunConfig::fromJson(
      nlohmann::json::parse(R"({"detector": {"args": ["--params", "d.yaml", "--explain", "1", "--input-hint"]}})"));
  EXPECT_NO_THROW(ld::buildProcessSpecs(ok, "udpm://239.255.76.67:7667?ttl=0", ""));
}

TEST(RunConfig, PathWithoutExtensionFindsTheFile) {
  const std::string dir = ::testing::TempDir() + "ldrun-ext/";
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  std::ofstream(dir + "robot.yaml") << "source: {type: replay, log: a.lcmlog}\n";
  EXPECT_EQ(ld::RunConfig::load(dir + "robot").log, "a.lcmlog");
  std::ofstream(dir + "lab.json") << "{\"source\": {\"type\": \"none\"}}";
  EXPECT_EQ(ld::RunConfig::load(dir + "lab").source, "none");
  std::ofstream(dir + "robot.json") << "{}";
  try {
    ld::RunConfig::load(dir + "robot");
    FAIL() << "loaded one of two";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("robot.yaml and " + dir + "robot.json exist"), std::string::npos) << e.what();
  }
  try {
    ld::RunConfig::load(dir + "none");
    FAIL() << "loaded nothing";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("(nor " + dir + "none.yaml, .yml or .json)"), std::string::npos) << e.what();
  }
  std::filesystem::remove_all(dir);
  // a file that never ends (read for ever before): refused, naming it
  try {
    ld::RunConfig::load("/dev/zero");
    FAIL() << "loaded /dev/zero";
  } catch (const std::runtime_error& e) {
    EXPECT_EQ(std::string(e.what()), "config /dev/zero is larger than 16 MiB: not a configuration file");
  }
  // the file read is kept (ld-run refuses to write over it)
  std::ofstream(::testing::TempDir() + "ldrun-file.json") << "{}";
  EXPECT_EQ(ld::RunConfig::load(::testing::TempDir() + "ldrun-file.json").file, ::testing::TempDir() + "ldrun-file.json");
  std::remove((::testing::TempDir() + "ldrun-file.json").c_str());
}

}  // namespace

namespace {

// A bus of named channels and workers' processes that a test moves by hand.
struct FakeBus {
  std::map<std::string, int64_t> channels;
  std::map<std::string, ld::HangWatch::Process> procs;
  std::vector<ld::HangWatch::Event> check(ld::HangWatch& w, int64_t now_us) {
    return w.check(
        now_us, [&](const std::string& ch) { return channels[ch]; },
        [&](const std::string& n) { return procs.count(n) ? procs[n] : ld::HangWatch::Process{}; });
  }
};

}  // namespace

// A worker that publishes nothing for hang_s while each of its inputs keeps
// coming, and reads none of it (its socket's queue never empties nor
// shrinks), or whose main thread does not run, or is stopped, is hung: said once, its end said once too. One
// that reads on and publishes nothing (a detector dropping damaged frames,
// a tracker dropping repeats, a QR reader whose inputs never join) is not;
// nor one whose input stopped, one not running, or one restarted, which
// until it answers once is hung only stopped (a slow start).
TEST(HangWatch, SaysAWorkerSilentAndNotReadingOnce) {
  ld::HangWatch w(2.0);
  w.add("detector", {"IMAGE"}, "LANDMARKS");
  w.add("qr-reader", {"IMAGE", "LANDMARKS_TRACKED"}, "LANDMARK_CODES");
  FakeBus bus;
  bus.procs["detector"] = {1, 0, false};
  bus.procs["qr-reader"] = {1, 0, false};
  int64_t t = 1'000'000'000;
  std::vector<std::string> said;
  // detector: "works" (answers), "reads" (drains its socket), else its
  // backlog grows by an image a frame
  const auto step = [&](bool works, bool reads, int frames, bool tracker_works = true, bool qr_works = true) {
    for (int i = 0; i < frames; ++i, t += 100'000) {  // 10 frames a second
      ++bus.channels["IMAGE"];
      if (works) ++bus.channels["LANDMARKS"];
      if (tracker_works) ++bus.channels["LANDMARKS_TRACKED"];
      if (qr_works) ++bus.channels["LANDMARK_CODES"];
      bus.procs["detector"].backlog = works || reads ? 0 : bus.procs["detector"].backlog + 460800;
      for (const auto& e : bus.check(w, t)) said.push_back(e.name + (e.hung ? " hung: " : " again: ") + e.text);
    }
  };
  step(true, true, 30);
  EXPECT_TRUE(said.empty());
  step(false, true, 60);  // reads on, publishes nothing: no hang
  EXPECT_TRUE(said.empty());
  step(true, true, 1);
  step(false, false, 19);  // 1.9 s unread: not yet
  EXPECT_TRUE(said.empty());
  step(false, false, 30);  // ... 2 s: once, however long it lasts
  ASSERT_EQ(said.size(), 1u);
  EXPECT_EQ(said[0].substr(0, said[0].find(" for ")), "detector hung: published nothing on LANDMARKS");
  EXPECT_NE(said[0].find("while its input came (2"), std::string::npos) << said[0];
  EXPECT_NE(said[0].find(" bytes of it unread"), std::string::npos) << said[0];
  step(true, true, 1);
  ASSERT_EQ(said.size(), 2u);
  EXPECT_EQ(said[1].substr(0, said[1].find(", after")), "detector again: publishes on LANDMARKS again");
  // its input stopped (no image): silence is no hang
  said.clear();
  for (int i = 0; i < 50; ++i, t += 100'000)
    for (const auto& e : bus.check(w, t)) said.push_back(e.name);
  EXPECT_TRUE(said.empty());
  // not running for a while, then restarted: until it answers, only a
  // stopped process is hung (a start may take long)
  step(false, false, 15);
  bus.procs["detector"].starts = -1;
  step(false, false, 10);
  bus.procs["detector"] = {2, 0, false};
  step(false, false, 40);
  EXPECT_TRUE(said.empty());
  bus.procs["detector"].stopped = true;  // (stopped at every look for hang_s)
  step(false, false, 19);
  EXPECT_TRUE(said.empty());
  step(false, false, 2);
  ASSERT_EQ(said.size(), 1u);
  // silent, its main thread running on (and stopped at every other look
  // when `flickering`), after answering at a new start
  const auto silentRunning = [&](int starts, int frames, bool flickering) {
    bus.procs["detector"] = {starts, 0, false, 1000};
    step(true, true, 5);
    for (int i = 0; i < frames; ++i) {
      bus.procs["detector"].stopped = flickering && i % 2 == 0;
      bus.procs["detector"].runtime_ns += 5000;
      step(false, true, 1);
    }
  };
  // stopped at some looks only (strace stops it at each call, for a
  // moment), reading and running on: no hang
  said.clear();
  silentRunning(7, 60, true);
  EXPECT_TRUE(said.empty());
  // stopped after answering: hung after hang_s of silence
  said.clear();
  bus.procs["detector"] = {3, 0, false};
  step(true, true, 5);
  bus.procs["detector"].stopped = true;
  step(false, true, 19);
  EXPECT_TRUE(said.empty());
  step(false, true, 2);
  ASSERT_EQ(said.size(), 1u);
  // its main thread blocked (a deadlock: LCM's own thread reads the socket
  // on, the queue stays empty) after answering: hung after hang_s; one whose
  // main thread runs on is not
  said.clear();
  silentRunning(6, 40, false);
  EXPECT_TRUE(said.empty());
  step(false, true, 19);  // (runtime_ns as it was)
  EXPECT_TRUE(said.empty());
  step(false, true, 2);
  ASSERT_EQ(said.size(), 1u);
  EXPECT_NE(said[0].find(", its main thread not run since"), std::string::npos) << said[0];
  // the QR reader needs both its inputs: with the tracker silent (no lists
  // to answer) its silence is no hang; with lists coming, it is
  said.clear();
  bus.procs["detector"] = {4, 0, false};
  bus.procs["qr-reader"].backlog = 0;
  step(true, true, 10);
  bus.procs["qr-reader"].stopped = true;
  step(true, true, 50, false, false);
  EXPECT_TRUE(said.empty());
  step(true, true, 25, true, false);
  ASSERT_EQ(said.size(), 1u);
  EXPECT_EQ(said[0].substr(0, said[0].find(" for ")), "qr-reader hung: published nothing on LANDMARK_CODES");
  EXPECT_NE(said[0].find(" on IMAGE, 2"), std::string::npos) << said[0];
  // 0: never
  ld::HangWatch never(0);
  never.add("detector", {"IMAGE"}, "LANDMARKS");
  bus.procs["detector"] = {5, 1000, true};
  for (int i = 0; i < 100; ++i, t += 100'000) {
    ++bus.channels["IMAGE"];
    EXPECT_TRUE(bus.check(never, t).empty());
  }
}
