#include "ld/supervisor.hpp"

#include <algorithm>
#include <cerrno>
#include <climits>
#include <cmath>
#include <csignal>
#include <cstdlib>
#include <cstring>
#include <thread>

#include <fcntl.h>
#include <linux/close_range.h>
#include <sys/syscall.h>
#include <sys/prctl.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

namespace ld {

double restartDelay(const RestartPolicy& policy, int consecutive_failures) {
  const int n = std::max(1, consecutive_failures);
  const double d = policy.initial_s * std::pow(2.0, std::min(n - 1, 30));
  return std::min(d, policy.max_s);
}

std::string describeWaitStatus(int status) {
  if (WIFEXITED(status)) return "exit " + std::to_string(WEXITSTATUS(status));
  if (WIFSIGNALED(status)) {
    const int s = WTERMSIG(status);
    const char* name = strsignal(s);
    return "signal " + std::to_string(s) + (name ? std::string(" (") + name + ")" : "");
  }
  return "status " + std::to_string(status);
}

namespace {

bool isExecutable(const std::string& path) {
  struct stat st{};
  return ::stat(path.c_str(), &st) == 0 && S_ISREG(st.st_mode) && ::access(path.c_str(), X_OK) == 0;
}

// Sets FD_CLOEXEC on every descriptor above stderr (between fork and exec:
// only async-signal-safe calls).
void markDescriptorsCloseOnExec() {
#if defined(SYS_close_range) && defined(CLOSE_RANGE_CLOEXEC)
  if (::syscall(SYS_close_range, 3U, ~0U, CLOSE_RANGE_CLOEXEC) == 0) return;
#endif
  long max = ::sysconf(_SC_OPEN_MAX);
  if (max < 0 || max > 65536) max = 65536;
  for (int fd = 3; fd < max; ++fd) ::fcntl(fd, F_SETFD, FD_CLOEXEC);
}

}  // namespace

std::string resolveProgram(const std::string& name, const std::string& self_dir) {
  if (name.empty() || name.find('/') != std::string::npos) return name;
  if (!self_dir.empty() && isExecutable(self_dir + "/" + name)) return self_dir + "/" + name;
  if (const char* path = std::getenv("PATH")) {
    std::string p = path;
    size_t start = 0;
    while (start <= p.size()) {
      const size_t end = std::min(p.find(':', start), p.size());
      const std::string dir = p.substr(start, end - start);
      if (!dir.empty() && isExecutable(dir + "/" + name)) return dir + "/" + name;
      start = end + 1;
    }
  }
  return name;
}

std::string selfDirectory() {
  char buf[PATH_MAX];
  const ssize_t n = ::readlink("/proc/self/exe", buf, sizeof buf - 1);
  if (n <= 0) return "";
  std::string path(buf, static_cast<size_t>(n));
  const size_t slash = path.rfind('/');
  return slash == std::string::npos ? "" : path.substr(0, slash);
}

Supervisor::Supervisor(RestartPolicy policy, LineSink sink, LineSink events)
    : policy_(policy), sink_(std::move(sink)), events_(std::move(events)) {}

Supervisor::~Supervisor() {
  for (auto& p : procs_) {
    if (p.pid > 0) {
      ::kill(p.pid, SIGKILL);
      ::waitpid(p.pid, nullptr, 0);
    }
    if (p.out_fd >= 0) ::close(p.out_fd);
  }
}

size_t Supervisor::add(ProcessSpec spec) {
  ProcessState s;
  s.spec = std::move(spec);
  procs_.push_back(std::move(s));
  return procs_.size() - 1;
}

bool Supervisor::start(size_t i) {
  ProcessState& p = procs_.at(i);
  const auto now = SteadyClock::now();
  // In a long crash loop, most starts are not told (RestartPolicy::loop_shown).
  const int hidden = beginRun(p);
  // A start that failed: retried with the backoff of a process that died at
  // once, as an exec that fails is. (A pipe or fork that failed, out of
  // descriptors or processes, was said once and never retried: the run
  // waited for that process for ever, and ended with 0 when stopped.)
  const auto failed = [&](const std::string& why) {
    ++p.starts;
    p.started = now;
    p.pid = -1;
    p.failed_to_start = true;
    ++p.consecutive_failures;
    const double d = restartDelay(policy_, p.consecutive_failures);
    p.restart_at = now + std::chrono::duration_cast<SteadyClock::duration>(std::chrono::duration<double>(d));
    p.last_exit = why;
    const bool was_quiet = p.quiet;
    p.quiet = false;
    // (told where shown, or where it failed otherwise than the loop before)
    if (countFailure(p, why, true) || !was_quiet) {
      event(p, "cannot start " + p.spec.argv.at(0) + ": " + why + "; retrying in " +
                   std::to_string(d).substr(0, 4) + " s" + loopNote(p, was_quiet ? p.not_shown - 1 : hidden));
      p.not_shown = 0;
    }
    return false;
  };
  int out[2], err[2];
  if (::pipe2(out, O_CLOEXEC) != 0) return failed(std::string("pipe: ") + std::strerror(errno));
  if (::pipe2(err, O_CLOEXEC) != 0) {  // exec errno travels here; closed by a successful exec
    const int e = errno;
    ::close(out[0]);
    ::close(out[1]);
    return failed(std::string("pipe: ") + std::strerror(e));
  }
  std::vector<char*> argv;
  for (auto& a : p.spec.argv) argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);
  const pid_t parent = ::getpid();
  const pid_t pid = ::fork();
  if (pid < 0) {
    const int e = errno;
    for (int fd : {out[0], out[1], err[0], err[1]}) ::close(fd);
    return failed(std::string("fork: ") + std::strerror(e));
  }
  if (pid == 0) {
    // Child: own process group (a terminal's Ctrl-C reaches only ld-run, which
    // stops the set in order), ended with the supervisor if it dies.
    ::setpgid(0, 0);
    ::prctl(PR_SET_PDEATHSIG, SIGTERM);
    if (::getppid() != parent) ::_exit(127);
    for (int s : {SIGINT, SIGTERM, SIGPIPE, SIGHUP, SIGCHLD}) ::signal(s, SIG_DFL);
    sigset_t none;
    sigemptyset(&none);
    ::sigprocmask(SIG_SETMASK, &none, nullptr);
    ::dup2(out[1], STDOUT_FILENO);
    ::dup2(out[1], STDERR_FILENO);
    // Nothing else of the supervisor's reaches the program (its LCM sockets
    // above all: they would make the child look subscribed).
    markDescriptorsCloseOnExec();
    ::execvp(argv[0], argv.data());
    const int e = errno;
    ssize_t w = ::write(err[1], &e, sizeof e);
    (void)w;
    ::_exit(127);
  }
  ::close(out[1]);
  ::close(err[1]);
  int child_errno = 0;
  ssize_t n;
  do {
    n = ::read(err[0], &child_errno, sizeof child_errno);
  } while (n < 0 && errno == EINTR);
  ::close(err[0]);
  if (n == static_cast<ssize_t>(sizeof child_errno)) {
    ::waitpid(pid, nullptr, 0);
    ::close(out[0]);
    return failed(std::string("exec failed: ") + std::strerror(child_errno));
  }
  ++p.starts;
  ++p.runs;
  p.started = now;
  ::fcntl(out[0], F_SETFL, ::fcntl(out[0], F_GETFL) | O_NONBLOCK);
  if (p.out_fd >= 0) ::close(p.out_fd);
  p.out_fd = out[0];
  p.partial.clear();
  p.pid = pid;
  p.failed_to_start = false;
  p.done = false;
  p.failed = false;
  if (!p.quiet)
    event(p, (p.starts > 1 ? "restarted, pid " : "started, pid ") + std::to_string(pid) +
                 (hidden > 0 ? " (" + std::to_string(p.alike_failures) + " quick failures in a row; the " +
                                   std::to_string(hidden) + " restarts before this one not shown)"
                             : ""));
  return true;
}

void Supervisor::drainOutput(ProcessState& p, bool eof) {
  if (p.out_fd < 0) return;
  char buf[4096];
  for (;;) {
    const ssize_t n = ::read(p.out_fd, buf, sizeof buf);
    if (n > 0) {
      p.partial.append(buf, static_cast<size_t>(n));
      size_t nl;
      while ((nl = p.partial.find('\n')) != std::string::npos) {
        childLine(p, p.partial.substr(0, nl));
        p.partial.erase(0, nl + 1);
      }
      if (p.partial.size() > 8192) {  // a very long line: pass it on in pieces
        childLine(p, p.partial);
        p.partial.clear();
      }
      continue;
    }
    if (n < 0 && errno == EINTR) continue;
    if (n == 0 || eof) {  // EOF (every writer gone), or the child is gone: stop reading
      if (n == 0 || (n < 0 && errno != EAGAIN)) {
        if (!p.partial.empty()) childLine(p, p.partial);
        p.partial.clear();
        ::close(p.out_fd);
        p.out_fd = -1;
      }
    }
    return;
  }
}

void Supervisor::onExit(ProcessState& p, int status, SteadyClock::time_point now) {
  drainOutput(p, true);
  p.pid = -1;
  p.last_exit = describeWaitStatus(status);
  // A quiet run's lines are shown where it ends the loop: stopped, finished
  // or refused for good.
  const char* const held_why = "its output since a start not shown (a crash loop's):";
  if (stopping_) {
    endQuiet(p, held_why);
    return;
  }
  if (p.spec.role == ProcessRole::Source && WIFEXITED(status) && WEXITSTATUS(status) == 0) {
    endQuiet(p, held_why);
    p.done = true;
    event(p, "finished (exit 0)");
    return;
  }
  if (WIFEXITED(status) && WEXITSTATUS(status) == 2 && policy_.usage_error_is_final) {
    endQuiet(p, held_why);
    p.failed = true;
    event(p, "failed (exit 2); not restarted");
    return;
  }
  const double ran = std::chrono::duration<double>(now - p.started).count();
  const bool quick = ran < policy_.stable_after_s;
  p.consecutive_failures = quick ? p.consecutive_failures + 1 : 1;
  const int hidden = p.not_shown;
  // (a run not shown that ended otherwise than the loop before it, a new
  // error's, is told with its lines: it was held back for minutes)
  if (countFailure(p, p.last_exit, quick) && p.quiet)
    endQuiet(p, "ended otherwise than the failures before it (its start not shown, nor the " +
                    std::to_string(hidden - 1) + " before it); its output:",
             true);
  const bool was_quiet = p.quiet;
  p.quiet = false;
  p.held.clear();
  p.held_tail.clear();
  p.held_dropped = 0;
  const double d = restartDelay(policy_, p.consecutive_failures);
  p.restart_at = now + std::chrono::duration_cast<SteadyClock::duration>(std::chrono::duration<double>(d));
  char buf[96];
  std::snprintf(buf, sizeof buf, "; restarting in %.2f s", d);
  if (!was_quiet) event(p, "died (" + p.last_exit + ")" + buf + loopNote(p, 0));
}

namespace {
// Whether the start after `failures` quick failures in a row is told.
bool loopShows(const RestartPolicy& policy, int failures) {
  return failures < policy.loop_shown || (policy.loop_every > 0 && failures % policy.loop_every == 0);
}

// "10", "0.5": a number of seconds as a line shows it.
std::string seconds(double s) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%g", s);
  return buf;
}
}  // namespace

int Supervisor::beginRun(ProcessState& p) {
  p.quiet = !loopShows(policy_, p.alike_failures);
  if (p.quiet) {
    ++p.not_shown;
    return 0;
  }
  const int hidden = p.not_shown;
  p.not_shown = 0;
  return hidden;
}

bool Supervisor::countFailure(ProcessState& p, const std::string& kind, bool quick) {
  if (!quick) {  // (a run that lasted ended any loop before it)
    p.alike_failures = 0;
    p.failure_kind.clear();
    return false;
  }
  if (p.alike_failures > 0 && kind == p.failure_kind) {
    ++p.alike_failures;
    return false;
  }
  const bool otherwise = p.alike_failures > 0;
  p.alike_failures = 1;
  p.failure_kind = kind;
  return otherwise;
}

std::string Supervisor::loopNote(const ProcessState& p, int hidden) const {
  const int k = p.alike_failures;
  std::string note;
  if (hidden > 0) note = "; the " + std::to_string(hidden) + " restarts before this one not shown";
  if (!loopShows(policy_, k)) {
    if (k == policy_.loop_shown) {
      note += "; from now on only every " + std::to_string(policy_.loop_every) +
              "th restart is shown, with its output, until a run lasts " + seconds(policy_.stable_after_s) +
              " s or ends otherwise";
    } else if (policy_.loop_every > 0) {
      note += "; the next restart shown is the one after failure " +
              std::to_string((k / policy_.loop_every + 1) * policy_.loop_every);
    }
  }
  if (note.empty()) return "";
  if (k == 1) return " (otherwise than the failures before it" + note + ")";
  return " (" + std::to_string(k) + " quick failures in a row" + note + ")";
}

void Supervisor::childLine(ProcessState& p, const std::string& line) {
  if (!p.quiet) {
    sink_(p.spec.name, line);
  } else if (p.held.size() < kHeldLines) {
    p.held.push_back(line);
  } else {  // (the last lines too: an error is most often the last)
    p.held_tail.push_back(line);
    if (p.held_tail.size() > kHeldLines) {
      p.held_tail.pop_front();
      ++p.held_dropped;
    }
  }
}

void Supervisor::endQuiet(ProcessState& p, const std::string& why, bool tell) {
  if (!p.quiet) return;
  p.quiet = false;
  p.not_shown = 0;
  if (!why.empty() && (tell || !p.held.empty())) event(p, why);
  for (const auto& line : p.held) sink_(p.spec.name, line);
  if (p.held_dropped > 0) event(p, "(" + std::to_string(p.held_dropped) + " lines of that run not kept)");
  for (const auto& line : p.held_tail) sink_(p.spec.name, line);
  p.held.clear();
  p.held_tail.clear();
  p.held_dropped = 0;
}

void Supervisor::poll(SteadyClock::time_point now) {
  for (auto& p : procs_) drainOutput(p, false);
  // A quiet run that lasted ends the crash loop: shown again, held lines too.
  for (auto& p : procs_)
    if (p.quiet && p.pid > 0 && std::chrono::duration<double>(now - p.started).count() >= policy_.stable_after_s) {
      event(p, "has run " + seconds(policy_.stable_after_s) + " s after " + std::to_string(p.alike_failures) +
                   " quick failures in a row: its restarts are shown again" +
                   (p.held.empty() ? "" : "; this run's output:"));
      endQuiet(p, "");
    }
  for (;;) {
    int status = 0;
    const pid_t pid = ::waitpid(-1, &status, WNOHANG);
    if (pid <= 0) break;
    for (auto& p : procs_)
      if (p.pid == pid) onExit(p, status, now);
  }
  if (stopping_) return;
  for (size_t i = 0; i < procs_.size(); ++i) {
    ProcessState& p = procs_[i];
    if (p.pid < 0 && !p.done && !p.failed && p.starts > 0 && now >= p.restart_at) start(i);
  }
}

void Supervisor::appendPollFds(std::vector<pollfd>& fds) const {
  for (const auto& p : procs_)
    if (p.out_fd >= 0) fds.push_back({p.out_fd, POLLIN, 0});
}

bool Supervisor::stopGroup(ProcessRole role, double grace_s) {
  bool clean = true;
  for (auto& p : procs_)
    if (p.spec.role == role && p.pid > 0) ::kill(p.pid, SIGTERM);
  const auto deadline = SteadyClock::now() + std::chrono::duration_cast<SteadyClock::duration>(
                                                 std::chrono::duration<double>(grace_s));
  for (;;) {
    bool any = false;
    for (auto& p : procs_) {
      if (p.spec.role != role || p.pid <= 0) continue;
      int status = 0;
      const pid_t r = ::waitpid(p.pid, &status, WNOHANG);
      if (r == p.pid) {
        const bool ok = (WIFEXITED(status) && WEXITSTATUS(status) == 0) ||
                        (WIFSIGNALED(status) && WTERMSIG(status) == SIGTERM);
        if (!ok) clean = false;
        onExit(p, status, SteadyClock::now());
        event(p, "stopped (" + p.last_exit + ")");
      } else {
        drainOutput(p, false);
        any = true;
      }
    }
    if (!any) break;
    if (SteadyClock::now() >= deadline) {
      for (auto& p : procs_) {
        if (p.spec.role != role || p.pid <= 0) continue;
        ::kill(p.pid, SIGKILL);
        int status = 0;
        ::waitpid(p.pid, &status, 0);
        onExit(p, status, SteadyClock::now());
        event(p, "killed: did not stop within the grace period");
        clean = false;
      }
      break;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  return clean;
}

bool Supervisor::stopAll(double grace_s) {
  stopping_ = true;
  bool clean = stopGroup(ProcessRole::Source, grace_s);
  clean = stopGroup(ProcessRole::Worker, grace_s) && clean;
  clean = stopGroup(ProcessRole::Recorder, grace_s) && clean;
  for (auto& p : procs_) drainOutput(p, true);
  return clean;
}

bool Supervisor::killHung(const std::string& name) {
  for (auto& p : procs_)
    if (p.spec.name == name && p.pid > 0) {
      ++p.hangs;
      endQuiet(p, "its output since a start not shown (a crash loop's), killed as hung:");
      ::kill(p.pid, SIGKILL);  // (a stopped one too; reaped and restarted by poll)
      return true;
    }
  return false;
}

bool Supervisor::sourcesDone() const {
  bool any = false;
  for (const auto& p : procs_) {
    if (p.spec.role != ProcessRole::Source) continue;
    any = true;
    if (!p.done) return false;
  }
  return any;
}

const ProcessState* Supervisor::failedProcess() const {
  for (const auto& p : procs_)
    if (p.failed) return &p;
  return nullptr;
}

int Supervisor::restarts() const {
  int n = 0;
  for (const auto& p : procs_) n += std::max(0, p.starts - 1);
  return n;
}

}  // namespace ld
