#include "ld/netns.hpp"

#include <algorithm>
#include <cerrno>
#include <cstdlib>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <optional>
#include <map>
#include <set>
#include <sstream>
#include <stdexcept>

#include <arpa/inet.h>
#include <dirent.h>
#include <fcntl.h>
#include <ifaddrs.h>
#include <sys/stat.h>
#include <net/if.h>
#include <net/route.h>
#include <netinet/in.h>
#include <sched.h>
#include <sys/ioctl.h>
#include <sys/socket.h>
#include <unistd.h>

namespace ld {
namespace {

[[noreturn]] void fail(const std::string& what) {
  throw std::runtime_error(what + ": " + std::strerror(errno));
}

void writeFile(const std::string& path, const std::string& text) {
  const int fd = ::open(path.c_str(), O_WRONLY | O_CLOEXEC);
  if (fd < 0) fail("cannot open " + path);
  const ssize_t n = ::write(fd, text.data(), text.size());
  const int e = errno;
  ::close(fd);
  errno = e;
  if (n != static_cast<ssize_t>(text.size())) fail("cannot write " + path);
}

sockaddr_in ipv4(const char* text) {
  sockaddr_in a{};
  a.sin_family = AF_INET;
  ::inet_pton(AF_INET, text, &a.sin_addr);
  return a;
}

}  // namespace

bool onlyLoopbackUp() {
  ifaddrs* list = nullptr;
  if (::getifaddrs(&list) != 0) return false;
  bool loopback_only = true, any = false;
  for (const ifaddrs* a = list; a; a = a->ifa_next) {
    if (!(a->ifa_flags & IFF_UP)) continue;
    any = true;
    if (!(a->ifa_flags & IFF_LOOPBACK)) loopback_only = false;
  }
  ::freeifaddrs(list);
  return any && loopback_only;
}

bool netnsVouchedFor() {
  const char* v = std::getenv("LD_IN_NETNS");
  return v && std::string(v) == "1";
}

// Whether this process's network namespace is another than pid 1's; null
// when that cannot be told (pid 1's is hidden from a process in a user
// namespace of its own, as `unshare -rn` makes).
std::optional<bool> otherThanInitsNetns() {
  struct stat self {}, init {};
  if (::stat("/proc/self/ns/net", &self) != 0 || ::stat("/proc/1/ns/net", &init) != 0) return std::nullopt;
  return self.st_ino != init.st_ino || self.st_dev != init.st_dev;
}

// (loopback alone up in pid 1's own namespace is a host offline, whose live
// stack on lo a soak would feed: not private)
bool inPrivateNetns() { return netnsVouchedFor() || (otherThanInitsNetns().value_or(true) && onlyLoopbackUp()); }

namespace {
// `ip link set lo up; ip route add 224.0.0.0/4 dev lo` in the namespace the
// process is in (a route there already is fine).
void routeMulticastToLo() {
  const int s = ::socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC, 0);
  if (s < 0) fail("socket");
  ifreq ifr{};
  std::strncpy(ifr.ifr_name, "lo", IFNAMSIZ - 1);
  if (::ioctl(s, SIOCGIFFLAGS, &ifr) != 0) {
    ::close(s);
    fail("lo: SIOCGIFFLAGS");
  }
  ifr.ifr_flags = static_cast<short>(ifr.ifr_flags | IFF_UP | IFF_RUNNING);
  if (::ioctl(s, SIOCSIFFLAGS, &ifr) != 0) {
    ::close(s);
    fail("cannot bring lo up");
  }
  rtentry rt{};
  const sockaddr_in dst = ipv4("224.0.0.0"), mask = ipv4("240.0.0.0");
  std::memcpy(&rt.rt_dst, &dst, sizeof dst);
  std::memcpy(&rt.rt_genmask, &mask, sizeof mask);
  rt.rt_flags = RTF_UP;
  char dev[] = "lo";
  rt.rt_dev = dev;
  if (::ioctl(s, SIOCADDRT, &rt) != 0 && errno != EEXIST) {
    ::close(s);
    fail("cannot route 224.0.0.0/4 to lo");
  }
  ::close(s);
}
}  // namespace

void enterPrivateNetns() {
  const uid_t uid = ::getuid();
  const gid_t gid = ::getgid();
  if (uid == 0) {
    if (::unshare(CLONE_NEWNET) != 0) fail("unshare(CLONE_NEWNET)");
  } else {
    if (::unshare(CLONE_NEWUSER | CLONE_NEWNET) != 0) fail("unshare(CLONE_NEWUSER | CLONE_NEWNET)");
    writeFile("/proc/self/setgroups", "deny");
    writeFile("/proc/self/uid_map", "0 " + std::to_string(uid) + " 1");
    writeFile("/proc/self/gid_map", "0 " + std::to_string(gid) + " 1");
  }
  routeMulticastToLo();
  ::setenv("LD_IN_NETNS", "1", 1);
}

// Whether a route in this namespace's main table sends LCM's default group
// out through `lo` (224.0.0.0/4 as DESIGN.md and scripts/netns-run.sh add
// it, or a narrower one). /proc/net/route prints each destination and mask
// as the bytes of the address read as a host integer, as s_addr holds them.
// (A multicast-type route or one in another table is not listed there: the
// caller's namespace is then not told from a host's, and ld-run makes one
// of its own.)
static bool multicastRoutedToLo() {
  const uint32_t group = ipv4("239.255.76.67").sin_addr.s_addr;
  std::ifstream f("/proc/net/route");
  std::string line;
  std::getline(f, line);  // header
  while (std::getline(f, line)) {
    std::istringstream in(line);
    std::string iface, dest, gateway, flags, refcnt, use, metric, mask;
    if (!(in >> iface >> dest >> gateway >> flags >> refcnt >> use >> metric >> mask) || iface != "lo") continue;
    const auto d = static_cast<uint32_t>(std::strtoul(dest.c_str(), nullptr, 16));
    const auto m = static_cast<uint32_t>(std::strtoul(mask.c_str(), nullptr, 16));
    if (m != 0 && (group & m) == d) return true;
  }
  return false;
}

bool useThisPrivateNetns() {
  // Loopback alone up, in a namespace known to be another than pid 1's (its
  // route to lo added when missing), or, where that cannot be told (pid 1's
  // hidden), one whose multicast the caller routed to lo already, as
  // scripts/netns-run.sh and DESIGN.md do: nothing is added then to a
  // namespace that may be a host's, offline with loopback alone up.
  if (!onlyLoopbackUp()) return false;
  const std::optional<bool> other = otherThanInitsNetns();
  if (other.has_value() ? !*other : !multicastRoutedToLo()) return false;
  try {
    routeMulticastToLo();
  } catch (const std::exception&) {
    return false;  // (no right to route here: a namespace of its own then)
  }
  ::setenv("LD_IN_NETNS", "1", 1);
  return true;
}

int64_t rmemMax() {
  std::ifstream f("/proc/sys/net/core/rmem_max");
  int64_t v = -1;
  if (!(f >> v)) return -1;
  return v;
}

int lcmUdpPort(const std::string& url) {
  const std::string prefix = "udpm://";
  if (url.rfind(prefix, 0) != 0) return url.empty() ? 7667 : -1;
  const size_t end = url.find('?');
  const std::string addr = url.substr(prefix.size(), end == std::string::npos ? std::string::npos
                                                                               : end - prefix.size());
  const size_t colon = addr.rfind(':');
  if (colon == std::string::npos) return 7667;
  try {
    return std::stoi(addr.substr(colon + 1));
  } catch (const std::exception&) {
    return -1;
  }
}

namespace {
// The UDP sockets bound to `port` in this namespace: inode -> bytes in the
// receive queue (/proc/net/udp's "tx_queue:rx_queue", hexadecimal).
std::map<unsigned long, int64_t> udpSocketsOnPort(int port) {
  std::map<unsigned long, int64_t> sockets;
  for (const char* table : {"/proc/net/udp", "/proc/net/udp6"}) {
    std::ifstream f(table);
    std::string line;
    std::getline(f, line);  // header
    while (std::getline(f, line)) {
      std::istringstream in(line);
      std::string sl, local, remote, st, queues, tr, retr;
      unsigned long uid = 0, timeout = 0, inode = 0;
      if (!(in >> sl >> local >> remote >> st >> queues >> tr >> retr >> uid >> timeout >> inode))
        continue;
      const size_t colon = local.rfind(':'), qcolon = queues.find(':');
      if (colon == std::string::npos || qcolon == std::string::npos) continue;
      if (std::stoi(local.substr(colon + 1), nullptr, 16) == port)
        sockets[inode] = static_cast<int64_t>(std::stoull(queues.substr(qcolon + 1), nullptr, 16));
    }
  }
  return sockets;
}

// The socket inodes among process `pid`'s open files.
std::set<unsigned long> socketInodesOf(int pid) {
  std::set<unsigned long> inodes;
  const std::string dir = "/proc/" + std::to_string(pid) + "/fd";
  DIR* d = ::opendir(dir.c_str());
  if (!d) return inodes;
  while (const dirent* e = ::readdir(d)) {
    char target[64];
    const std::string link = dir + "/" + e->d_name;
    const ssize_t n = ::readlink(link.c_str(), target, sizeof target - 1);
    if (n <= 0) continue;
    target[n] = 0;
    unsigned long inode = 0;
    if (std::sscanf(target, "socket:[%lu]", &inode) == 1) inodes.insert(inode);
  }
  ::closedir(d);
  return inodes;
}
}  // namespace

bool hasUdpSocketOnPort(int pid, int port) { return udpBacklogOnPort(pid, port) >= 0; }

int64_t udpBacklogOnPort(int pid, int port) {
  const auto sockets = udpSocketsOnPort(port);
  if (sockets.empty()) return -1;
  int64_t backlog = -1;
  for (const unsigned long inode : socketInodesOf(pid))
    if (const auto it = sockets.find(inode); it != sockets.end()) backlog = std::max<int64_t>(backlog, 0) + it->second;
  return backlog;
}

}  // namespace ld
