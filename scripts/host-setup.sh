#!/usr/bin/env bash
# Host settings the stack needs, applied at run time (not persistent; for
# every boot install tools/systemd/99-landmark-rmem.conf in /etc/sysctl.d/):
#  - net.core.rmem_max >= 8 MiB, so that LCM's recv_buf_size=8388608 takes
#    effect and 1080p images are not dropped (see README, "LCM URL and large
#    images"). Network namespaces copy the host's value when they are made,
#    so this must happen before the demo and the tests make theirs.
# Idempotent; uses sudo when not root; when it cannot, it says so and goes on.
set -uo pipefail
WANT=8388608
have=$(cat /proc/sys/net/core/rmem_max 2>/dev/null || echo 0)
if [ "$have" -ge "$WANT" ]; then
  echo "host-setup: net.core.rmem_max is $have (>= $WANT)"
  exit 0
fi
SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo -n"; fi
if $SUDO sysctl -q -w net.core.rmem_max=$WANT >/dev/null 2>&1; then
  echo "host-setup: net.core.rmem_max raised from $have to $WANT"
else
  echo "host-setup: warning: cannot raise net.core.rmem_max from $have to $WANT" \
       "(needs root); large images may be dropped on the bus" >&2
fi
exit 0
