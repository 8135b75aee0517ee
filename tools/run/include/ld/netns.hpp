// A private network namespace for LCM: loopback up and multicast routed to
// it, so that nothing the process set sends can leave the machine.
#pragma once

#include <cstdint>
#include <string>

namespace ld {

/// Moves the calling process (and the children it starts afterwards) into a
/// new network namespace, brings `lo` up and routes 224.0.0.0/4 to it (as
/// `ip link set lo up; ip route add 224.0.0.0/4 dev lo`). Root uses
/// unshare(CLONE_NEWNET); other users get a user namespace too. Call it
/// before any thread is started. Sets LD_IN_NETNS=1 for the children.
/// Throws std::runtime_error naming the step that failed.
void enterPrivateNetns();

/// True when the process is already in a private network namespace (one its
/// caller made: loopback alone up, and either another namespace than pid
/// 1's, or, where pid 1's is hidden, one whose multicast the caller routed
/// to `lo` already) and could route 224.0.0.0/4 to `lo` there: `ld-run
/// --netns` then runs the set in it, so that the caller's own programs in
/// that namespace hear the bus (a second namespace of ld-run's own hid the
/// set from them). Sets LD_IN_NETNS=1 for the children then. False, and
/// nothing changed, otherwise.
bool useThisPrivateNetns();

/// True when the process is in a network namespace other than pid 1's (or
/// one that cannot be told from it, inside a user namespace) where no
/// interface but loopback is up (made as DESIGN.md says, `unshare -n` then
/// `ip link set lo up`: nothing sent can leave the machine), or when
/// LD_IN_NETNS=1 says the caller made one (a namespace joined to another by
/// a veth pair, as the two-host test's).
bool inPrivateNetns();
/// True when some interface is up and every one up is loopback.
bool onlyLoopbackUp();
/// True when LD_IN_NETNS=1: a namespace enterPrivateNetns or
/// scripts/netns-run.sh made, or one a caller vouches for.
bool netnsVouchedFor();

/// net.core.rmem_max of the current network namespace (bytes), -1 if unreadable.
int64_t rmemMax();

/// The UDP port of an "udpm://group:port?..." URL (LCM's default 7667 when
/// the URL has none), or -1 for other providers.
int lcmUdpPort(const std::string& url);

/// True when process `pid` has a UDP socket bound to `port` in this network
/// namespace (for LCM: it has subscribed and joined the group).
bool hasUdpSocketOnPort(int pid, int port);

/// The bytes waiting in the receive queues of process `pid`'s UDP sockets
/// bound to `port` in this network namespace (what it has not read yet);
/// -1 when it has none there or they cannot be told.
int64_t udpBacklogOnPort(int pid, int port);

}  // namespace ld
