#!/usr/bin/env bash
# Fault test: a malformed message right behind each good one, before the
# process got to the good one (over real LCM multicast in a private network
# namespace). ld-detector and ld-tracker keep the newest message only; a bad
# one must not take a good one's place: every good frame comes out, and
# every bad message is said and counted.
set -euo pipefail
BIN=$1; ROOT=$2
T=$(mktemp -d); trap 'rm -rf "$T"' EXIT
FRAMES=20
"$BIN/ld-synth" sequence --out "$T/seq" --frames $FRAMES --fps 10 --landmarks 2 --seed 12 --size 0.3 \
  --format yuyv --log "$T/in.lcmlog" --no-png >/dev/null

"$ROOT/scripts/netns-run.sh" bash -c '
  set -euo pipefail
  BIN=$1; T=$2; ROOT=$3
  URL="udpm://239.255.76.67:7667?ttl=0&recv_buf_size=8388608"
  source "$ROOT/tests/lcm_sockets.sh"
  # the detector: images, each followed by a malformed message
  "$BIN/ld-detector" --lcm-url "$URL" 2> "$T/detector.err" & det=$!
  lcm-logger --lcm-url="$URL" -c LANDMARKS -f "$T/lm.lcmlog" >/dev/null 2>&1 & logger=$!
  lcm_sockets 2
  "$BIN/ld-publish-garbage" --lcm-url "$URL" --channel IMAGE --interleave "$T/in.lcmlog" --interval-ms 100
  sleep 1
  kill -INT $det; wait $det
  kill -INT $logger; wait $logger || true
  # the tracker: the lists the detector made, each followed by a malformed message
  "$BIN/ld-tracker" --lcm-url "$URL" 2> "$T/tracker.err" & trk=$!
  lcm-logger --lcm-url="$URL" -c LANDMARKS_TRACKED -f "$T/tr.lcmlog" >/dev/null 2>&1 & logger=$!
  lcm_sockets 2
  "$BIN/ld-publish-garbage" --lcm-url "$URL" --channel LANDMARKS --interleave "$T/lm.lcmlog" --interval-ms 50
  sleep 1
  kill -INT $trk; wait $trk
  kill -INT $logger; wait $logger || true
' test "$BIN" "$T" "$ROOT"

echo "--- ld-detector"; cat "$T/detector.err"
echo "--- ld-tracker"; cat "$T/tracker.err"
"$BIN/ld-dump" "$T/in.lcmlog" | jq -c .utime | sort > "$T/in.utimes"
"$BIN/ld-dump" "$T/lm.lcmlog" -c LANDMARKS | jq -c .utime | sort > "$T/lm.utimes"
"$BIN/ld-dump" "$T/tr.lcmlog" -c LANDMARKS_TRACKED | jq -c .utime | sort > "$T/tr.utimes"
echo "$FRAMES frames: $(wc -l < "$T/lm.utimes") lists from the detector, $(wc -l < "$T/tr.utimes") from the tracker"
diff "$T/in.utimes" "$T/lm.utimes"   # every good frame detected
diff "$T/in.utimes" "$T/tr.utimes"   # every good list tracked
# every malformed message said (10 lines, then every 100th) and counted
grep -q "stopped after $FRAMES frames (0 skipped, $FRAMES bad, 0 missing)" "$T/detector.err"
grep -q "stopped after $FRAMES frames (0 skipped, $FRAMES bad," "$T/tracker.err"
[ "$(grep -c "ld-detector: dropped frame: " "$T/detector.err")" = 10 ]
[ "$(grep -c "ld-tracker: dropped message: " "$T/tracker.err")" = 10 ]
echo "1 passed, 0 failed"
