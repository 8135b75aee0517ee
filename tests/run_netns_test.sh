#!/usr/bin/env bash
# ld-run --netns started in a private network namespace of the caller's
# (loopback alone up) runs the set in that namespace, so the caller's own
# programs there hear it: a namespace of ld-run's own inside it hid the set
# from them (an integrator's audit: its consumer heard nothing). And
# ld-dump's -c takes one pattern: the log file after it is a log.
# usage: run_netns_test.sh BIN_DIR
set -euo pipefail
BIN=$(cd "$1" && pwd)
source "$(dirname "$0")/ld_run_lib.sh"  # (T, removed at exit)
fail() { echo "FAIL: $*" >&2; exit 1; }

"$BIN/ld-synth" sequence --out "$T/seq" --frames 30 --fps 30 --landmarks 1 --seed 3 --size 0.3 \
  --format mjpeg --log "$T/in.lcmlog" --no-png >/dev/null
flags=-n
[ "$(id -u)" -eq 0 ] || flags=-rn
rc=0
timeout 120 unshare $flags env -u LD_IN_NETNS bash -c '
  set -u
  ip link set lo up && ip route add 224.0.0.0/4 dev lo || exit 90
  "$1/ld-dump" --live -c LANDMARKS_TRACKED >"$2/heard.jsonl" 2>"$2/dump.err" &
  dump=$!
  sleep 1
  rc=0
  "$1/ld-run" --netns --replay "$2/in.lcmlog" --exit-when-replay-done --status-interval 0 >"$2/run.out" 2>&1 || rc=$?
  sleep 0.5
  kill -INT $dump
  wait $dump || true
  exit $rc' _ "$BIN" "$T" || rc=$?
[ $rc -eq 0 ] || fail "ld-run in the caller's namespace: exit $rc: $(tail -5 "$T/run.out")"
grep -q "(private network namespace, the caller's)" "$T/run.out" || fail "the caller's namespace not said: $(cat "$T/run.out")"
heard=$(grep -c '"type":"landmark_list_t"' "$T/heard.jsonl" || true)
[ "$heard" -ge 25 ] || fail "the caller's ld-dump heard $heard of 30 tracked lists: $(head -c 300 "$T/heard.jsonl") $(cat "$T/dump.err")"
echo "the caller's program heard $heard of 30 tracked lists"

# without the caller's route to lo, where pid 1's namespace is hidden (a
# user namespace of its own, or a container's pid 1), ld-run cannot tell the
# caller's namespace from a host's, and makes its own, saying so
if ! stat -L /proc/1/ns/net >/dev/null 2>&1; then
  timeout 60 unshare $flags env -u LD_IN_NETNS bash -c 'ip link set lo up
    "$1/ld-run" --netns --replay "$2/in.lcmlog" --exit-when-replay-done --status-interval 0 >"$2/own.out" 2>&1' _ "$BIN" "$T" ||
    fail "ld-run without the caller's route: $(tail -3 "$T/own.out")"
  grep -q "(private network namespace, ld-run's own)" "$T/own.out" || fail "its own namespace not said: $(cat "$T/own.out")"
fi

# ld-dump -c PATTERN LOG: the log is a log, not a second pattern
"$BIN/ld-dump" -c IMAGE "$T/in.lcmlog" >"$T/dump.out" || fail "ld-dump -c IMAGE LOG: exit $?"
[ "$(grep -c '"channel":"IMAGE"' "$T/dump.out")" -eq 30 ] || fail "ld-dump -c IMAGE LOG: $(head -c 300 "$T/dump.out")"
echo "run_netns_test: ok"
