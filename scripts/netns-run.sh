#!/usr/bin/env bash
# Runs a command in a private network namespace whose loopback carries LCM's
# multicast, so nothing it sends can leave this machine:
#   scripts/netns-run.sh CMD [ARGS...]    (installed as ld-netns-run)
# Root uses `unshare -n`; other users get a user namespace too (`unshare -rn`).
set -euo pipefail
if [ "${LD_IN_NETNS:-}" = 1 ]; then
  exec "$@"
fi
flags=-n
[ "$(id -u)" -eq 0 ] || flags=-rn
# (a loopback or route that cannot be set stops here: the command ran
# without multicast, and LCM failed far from the cause)
exec unshare $flags env LD_IN_NETNS=1 bash -c '
  set -e
  command -v ip >/dev/null || { echo "netns-run: needs ip (the iproute2 package)" >&2; exit 127; }
  ip link set lo up
  ip route add 224.0.0.0/4 dev lo
  exec "$@"' netns-run "$@"
