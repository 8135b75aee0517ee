#!/usr/bin/env bash
# ld-run --netns started in a private network namespace of the caller's
# (loopback alone up) runs the set in that namespace, so the caller's own
# programs there hear it: a namespace of ld-run's own inside it hid the set
# from them (an integrator's audit: its consumer heard nothing). And
# ld-dump's -c takes one pattern: the log file after it is a log.
# usage: run_netns_test.sh BIN_DIR
set -euo pipefail
BIN=$(cd "$1" && pwd)
T=$(mktemp -d); trap 'rm -rf "$T"' EXIT
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
grep -q "(private network namespace)" "$T/run.out" || fail "no private namespace said: $(cat "$T/run.out")"
heard=$(grep -c '"type":"landmark_list_t"' "$T/heard.jsonl" || true)
[ "$heard" -ge 25 ] || fail "the caller's ld-dump heard $heard of 30 tracked lists: $(head -c 300 "$T/heard.jsonl") $(cat "$T/dump.err")"
echo "the caller's program heard $heard of 30 tracked lists"

# ld-dump -c PATTERN LOG: the log is a log, not a second pattern
"$BIN/ld-dump" -c IMAGE "$T/in.lcmlog" >"$T/dump.out" || fail "ld-dump -c IMAGE LOG: exit $?"
[ "$(grep -c '"channel":"IMAGE"' "$T/dump.out")" -eq 30 ] || fail "ld-dump -c IMAGE LOG: $(head -c 300 "$T/dump.out")"
echo "run_netns_test: ok"
