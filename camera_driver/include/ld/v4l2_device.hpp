// The system calls V4L2 capture needs, behind a small interface.
//
// V4l2Capture talks to a camera only through V4l2Io (open, close, ioctl,
// mmap, munmap, poll: the syscall signatures, errors reported as -1 or
// MAP_FAILED with errno set) and reads time only through Clock. In a process
// these are SystemV4l2Io and SystemClock; in tests, FakeV4l2Device and
// FakeClock (ld/fake_v4l2.hpp) stand in for a webcam and for time, so the
// capture loop, the format handling and the error paths run without a
// camera and without waiting for real seconds (the same split as Chromium's
// V4L2CaptureDevice / FakeV4L2Impl).
#pragma once

#include <poll.h>
#include <sys/types.h>

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace ld {

/// Thin wrappers of the V4L2 system calls. Each returns what the syscall
/// returns and sets errno the same way.
class V4l2Io {
 public:
  virtual ~V4l2Io() = default;
  virtual int open(const char* path, int flags) = 0;
  virtual int close(int fd) = 0;
  virtual int ioctl(int fd, unsigned long request, void* arg) = 0;
  virtual void* mmap(void* addr, size_t length, int prot, int flags, int fd, off_t offset) = 0;
  virtual int munmap(void* addr, size_t length) = 0;
  virtual int poll(pollfd* fds, nfds_t nfds, int timeout_ms) = 0;
  /// The V4L2 device nodes that exist now ("/dev/video0", "/dev/video1",
  /// ...), in numeric order; listDevices() enumerates these.
  virtual std::vector<std::string> deviceNodes() = 0;
};

/// The real system calls (<linux/videodev2.h> ioctls on /dev/video*).
class SystemV4l2Io final : public V4l2Io {
 public:
  int open(const char* path, int flags) override;
  int close(int fd) override;
  int ioctl(int fd, unsigned long request, void* arg) override;
  void* mmap(void* addr, size_t length, int prot, int flags, int fd, off_t offset) override;
  int munmap(void* addr, size_t length) override;
  int poll(pollfd* fds, nfds_t nfds, int timeout_ms) override;
  std::vector<std::string> deviceNodes() override;
};

/// The clocks capture reads, and sleeping (reconnect backoff).
class Clock {
 public:
  virtual ~Clock() = default;
  /// CLOCK_MONOTONIC in microseconds: the clock of V4L2 buffer timestamps.
  virtual int64_t monotonicUs() = 0;
  /// CLOCK_REALTIME in microseconds: wall-clock time, the clock of `utime`.
  virtual int64_t realtimeUs() = 0;
  /// Sleeps `us` microseconds (nothing when `us` <= 0).
  virtual void sleepUs(int64_t us) = 0;
};

/// clock_gettime and nanosleep.
class SystemClock final : public Clock {
 public:
  int64_t monotonicUs() override;
  int64_t realtimeUs() override;
  void sleepUs(int64_t us) override;
};

/// A process-wide SystemClock.
Clock& systemClock();

}  // namespace ld
