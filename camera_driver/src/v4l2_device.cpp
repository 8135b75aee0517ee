#include "ld/v4l2_device.hpp"

#include <fcntl.h>
#include <sys/ioctl.h>
#include <sys/mman.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdlib>
#include <ctime>
#include <filesystem>

namespace ld {

int SystemV4l2Io::open(const char* path, int flags) { return ::open(path, flags); }

int SystemV4l2Io::close(int fd) { return ::close(fd); }

int SystemV4l2Io::ioctl(int fd, unsigned long request, void* arg) {
  return ::ioctl(fd, request, arg);
}

void* SystemV4l2Io::mmap(void* addr, size_t length, int prot, int flags, int fd, off_t offset) {
  return ::mmap(addr, length, prot, flags, fd, offset);
}

int SystemV4l2Io::munmap(void* addr, size_t length) { return ::munmap(addr, length); }

int SystemV4l2Io::poll(pollfd* fds, nfds_t nfds, int timeout_ms) {
  return ::poll(fds, nfds, timeout_ms);
}

std::vector<std::string> SystemV4l2Io::deviceNodes() {
  namespace fs = std::filesystem;
  std::vector<std::pair<long, std::string>> found;
  std::error_code ec;
  for (fs::directory_iterator it("/dev", ec), end; !ec && it != end; it.increment(ec)) {
    const std::string name = it->path().filename().string();
    if (name.size() <= 5 || name.compare(0, 5, "video") != 0) continue;
    if (!std::all_of(name.begin() + 5, name.end(), [](char c) { return c >= '0' && c <= '9'; }))
      continue;
    found.emplace_back(std::strtol(name.c_str() + 5, nullptr, 10), it->path().string());
  }
  std::sort(found.begin(), found.end());
  std::vector<std::string> out;
  for (auto& f : found) out.push_back(std::move(f.second));
  return out;
}

namespace {
int64_t nowUs(clockid_t id) {
  timespec ts{};
  clock_gettime(id, &ts);
  return static_cast<int64_t>(ts.tv_sec) * 1000000 + ts.tv_nsec / 1000;
}
}  // namespace

int64_t SystemClock::monotonicUs() { return nowUs(CLOCK_MONOTONIC); }

int64_t SystemClock::realtimeUs() { return nowUs(CLOCK_REALTIME); }

void SystemClock::sleepUs(int64_t us) {
  if (us <= 0) return;
  timespec ts{static_cast<time_t>(us / 1000000), static_cast<long>((us % 1000000) * 1000)};
  while (nanosleep(&ts, &ts) != 0 && errno == EINTR) {
  }
}

Clock& systemClock() {
  static SystemClock clock;
  return clock;
}

}  // namespace ld
