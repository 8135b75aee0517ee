#!/usr/bin/env bash
# No IMAGE message lost at 1920x1080, 30 frames/s, raw BGR (6.2 MB a frame,
# about 95 UDP fragments each): ld-play publishes 90 frames in a private
# network namespace with the project's LCM URL (recv_buf_size=8388608), and
# an independent subscriber (ld-dump --live) must receive every sequence
# number exactly once. Prints the receive buffer the kernel allows in the
# namespace (net.core.rmem_max; LCM asks for 8 MiB and gets at most that).
set -euo pipefail
BIN=$1; ROOT=$2
T=$(mktemp -d); trap 'rm -rf "$T"' EXIT
FRAMES=90
"$BIN/ld-synth" sequence --out "$T/seq" --frames 10 --fps 30 --landmarks 3 --seed 5 \
  --resolution 1920x1080 --format mjpeg --log "$T/hd.lcmlog" --no-png >/dev/null

"$ROOT/scripts/netns-run.sh" bash -c '
  set -euo pipefail
  BIN=$1; T=$2; FRAMES=$3; ROOT=$4
  echo "net.core.rmem_max in the namespace: $(cat /proc/sys/net/core/rmem_max)"
  # (the receiver ahead of other work on the machine, where it may be: a
  # stall of 40 ms fills the 8 MiB buffer, 1.3 frames; a build beside the
  # suite lost 5 frames. Without the right to raise it, as it is.)
  NICE=(); if nice -n -10 true 2>/dev/null; then NICE=(nice -n -10); fi
  "${NICE[@]}" "$BIN/ld-dump" --live -c IMAGE > "$T/recv.jsonl" 2> "$T/dump.err" &
  dump=$!
  source "$ROOT/tests/lcm_sockets.sh"
  lcm_sockets 1   # subscribed (ld-dump takes 0.2-1 s), and LCM'"'"'s self test over
  "$BIN/ld-play" "$T/hd.lcmlog" --format bgr --fps 30 --frames "$FRAMES"
  sleep 1
  kill -INT $dump; wait $dump || true
' loss "$BIN" "$T" $FRAMES "$ROOT"

cat "$T/dump.err"
jq -r 'select(.width == 1920 and .height == 1080 and .pixelformat == "BGR") | .seq' "$T/recv.jsonl" |
  sort -n > "$T/seqs"
received=$(sort -u "$T/seqs" | wc -l)
echo "received $received of $FRAMES 1920x1080 BGR frames ($(wc -l < "$T/seqs") messages)"
if ! seq 0 $((FRAMES - 1)) | diff - "$T/seqs" > "$T/diff"; then
  echo "lost frames: $(grep -c '^<' "$T/diff" || true)"
  echo "hint: net.core.rmem_max on the host is $(cat /proc/sys/net/core/rmem_max); raise it to 8388608" \
       "before the namespace is made (see README: recv_buf_size and rmem_max)"
  exit 1
fi
echo "1 passed, 0 failed"
