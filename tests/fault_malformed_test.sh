#!/usr/bin/env bash
# Fault test: malformed messages injected on every channel of the running set
# (ld-detector, ld-tracker, ld-qr-reader over real LCM multicast in a private
# network namespace). Each process must report each bad message on its
# channels in one line, count them all (the counts in its exit line), and go
# on: the frames played after the garbage all come out on LANDMARKS and
# LANDMARKS_TRACKED, with QR payloads on LANDMARK_CODES.
set -euo pipefail
BIN=$1; ROOT=$2
T=$(mktemp -d); trap 'rm -rf "$T"' EXIT
FRAMES=20
for phase in 1 2; do
  "$BIN/ld-synth" sequence --out "$T/seq$phase" --frames $FRAMES --fps 10 --landmarks 2 --seed 11 --size 0.3 \
    --start-utime $((1700000000000000 + phase * 100000000)) --format yuyv \
    --log "$T/in$phase.lcmlog" --no-png >/dev/null
done

"$ROOT/scripts/netns-run.sh" bash -c '
  set -euo pipefail
  BIN=$1; T=$2; ROOT=$3
  URL="udpm://239.255.76.67:7667?ttl=0&recv_buf_size=8388608"
  source "$ROOT/tests/lcm_sockets.sh"
  "$BIN/ld-detector" --lcm-url "$URL" 2> "$T/detector.err" & det=$!
  "$BIN/ld-tracker" --lcm-url "$URL" 2> "$T/tracker.err" & trk=$!
  "$BIN/ld-qr-reader" --lcm-url "$URL" 2> "$T/qr.err" & qr=$!
  lcm_sockets 3
  lcm-logplayer --lcm-url="$URL" "$T/in1.lcmlog"   # the set works
  sleep 0.5
  for ch in IMAGE LANDMARKS LANDMARKS_TRACKED LANDMARK_CODES; do
    "$BIN/ld-publish-garbage" --lcm-url "$URL" --channel $ch --interval-ms 200 >> "$T/garbage.out"
  done
  sleep 0.5
  lcm-logger --lcm-url="$URL" -c "LANDMARKS.*|LANDMARK_CODES" -f "$T/out.lcmlog" >/dev/null 2>&1 &
  logger=$!
  lcm_sockets 4
  lcm-logplayer --lcm-url="$URL" "$T/in2.lcmlog"   # and still works after the garbage
  sleep 1.5
  for p in $det $trk $qr; do kill -0 $p; done      # all still running
  kill -INT $det $trk $qr
  wait $det; wait $trk; wait $qr                   # and exit cleanly (status 0)
  kill -INT $logger; wait $logger || true
' test "$BIN" "$T" "$ROOT"

echo "--- ld-detector"; cat "$T/detector.err"
echo "--- ld-tracker"; cat "$T/tracker.err"
echo "--- ld-qr-reader"; cat "$T/qr.err"

# N malformed messages per channel (ld-publish-garbage): every one counted by
# each subscriber, each of the first 10 reported in its own line.
cat "$T/garbage.out"
N=$(sed -n "s/^published \([0-9]*\) malformed messages on IMAGE$/\1/p" "$T/garbage.out")
[ "$N" -ge 9 ] && [ "$N" -le 10 ]   # the line counts below assume one channel fits in 10 lines
bad() { sed -n "s/.*stopped after .* \([0-9][0-9]*\) bad.*/\1/p" "$1"; }
[ "$(bad "$T/detector.err")" = "$N" ]                                 # IMAGE
[ "$(bad "$T/tracker.err")" = "$N" ]                                  # LANDMARKS
[ "$(bad "$T/qr.err")" = "$((2 * N))" ]                               # IMAGE and LANDMARKS_TRACKED
[ "$(grep -c "ld-detector: dropped frame: .*(.* bad so far)" "$T/detector.err")" = "$N" ]
[ "$(grep -c "ld-tracker: dropped message: message on LANDMARKS is " "$T/tracker.err")" = "$N" ]
[ "$(grep -c "ld-qr-reader: dropped message on IMAGE: " "$T/qr.err")" = "$N" ]
# (each channel's lines thinned out on their own: a flood of bad images
# left room for just one bad list's line)
[ "$(grep -c "ld-qr-reader: dropped message on LANDMARKS_TRACKED: .*(.* bad on LANDMARKS_TRACKED so far" "$T/qr.err")" = "$N" ]
grep -q "nstages 2147483647 does not fit" "$T/tracker.err"
grep -q "string backend has length 0" "$T/tracker.err"
grep -q "MJPEG frame 30000x30000 is larger than" "$T/detector.err"

# After the garbage: every frame of the second run through detector and tracker, codes read.
"$BIN/ld-dump" "$T/in2.lcmlog" | jq -c .utime | sort > "$T/in.utimes"
"$BIN/ld-dump" "$T/out.lcmlog" -c LANDMARKS > "$T/lm.jsonl"
"$BIN/ld-dump" "$T/out.lcmlog" -c LANDMARKS_TRACKED > "$T/tr.jsonl"
"$BIN/ld-dump" "$T/out.lcmlog" -c LANDMARK_CODES > "$T/codes.jsonl"
jq -c .utime "$T/lm.jsonl" | sort > "$T/lm.utimes"
jq -c .utime "$T/tr.jsonl" | sort > "$T/tr.utimes"
diff "$T/in.utimes" "$T/lm.utimes"
diff "$T/in.utimes" "$T/tr.utimes"
with=$(jq -c 'select(.landmarks | length > 0)' "$T/lm.jsonl" | wc -l)
coded=$(jq -c 'select((.codes | length) > 0)' "$T/codes.jsonl" | wc -l)
payloads=$(jq -r '.codes[].payload' "$T/codes.jsonl" | sort -u | tr '\n' ' ')
echo "after the garbage: $FRAMES frames in, $(wc -l < "$T/lm.utimes") LANDMARKS ($with with landmarks)," \
     "$(wc -l < "$T/tr.utimes") LANDMARKS_TRACKED, $coded LANDMARK_CODES with codes: $payloads"
[ "$with" -ge $((FRAMES * 2 / 3)) ]
[ "$coded" -ge $((FRAMES / 2)) ]
echo "1 passed, 0 failed"
