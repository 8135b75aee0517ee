#!/usr/bin/env bash
# ld-view on logs and on the live bus. A short ld-synth sequence is run
# through the set by ld-run (in a private network namespace) while ld-view
# draws the live frames; then ld-view draws the same frames from the logs.
# Every tracked frame must come out annotated: as a PNG named by its seq
# and in the video, and an annotated frame must differ from the raw frame.
set -euo pipefail
BIN=$1; ROOT=$2
T=$(mktemp -d); trap 'rm -rf "$T"' EXIT
FRAMES=30
"$BIN/ld-synth" sequence --out "$T/seq" --frames $FRAMES --fps 10 --landmarks 2 --seed 3 --size 0.3 \
  --format mjpeg --log "$T/in.lcmlog" >/dev/null

"$ROOT/scripts/netns-run.sh" bash -c '
  set -euo pipefail
  BIN=$1; T=$2; ROOT=$3
  "$BIN/ld-view" --out "$T/live" 2> "$T/live.err" &
  view=$!
  source "$ROOT/tests/lcm_sockets.sh"
  lcm_sockets 1   # subscribed (0.4-2.6 s after its start), and the LCM self test over, before frames come
  "$BIN/ld-run" --replay "$T/in.lcmlog" --exit-when-replay-done --record "$T/run.lcmlog" \
    --status-interval 0 -q
  sleep 0.5
  kill -INT $view; wait $view
' view "$BIN" "$T" "$ROOT"
cat "$T/live.err"
live=$(ls "$T/live" | wc -l)
"$BIN/ld-view" --log "$T/in.lcmlog" --log "$T/run.lcmlog" --out "$T/logs" --video "$T/view.avi" --fps 10
logs=$(ls "$T/logs" | wc -l)
echo "live: $live frames, logs: $logs frames, video: $(stat -c %s "$T/view.avi") bytes"
[ "$logs" -eq $FRAMES ]
[ "$live" -eq $FRAMES ]
[ "$(ls "$T/logs")" = "$(ls "$T/live")" ]   # the same frames, named by seq
[ "$(ls "$T/logs" | head -1)" = 000000.png ]
[ "$(stat -c %s "$T/view.avi")" -gt 10000 ]
# drawn on: differs from the same frame drawn without tracks (--all, images only)
"$BIN/ld-view" --log "$T/in.lcmlog" --all --out "$T/plain" 2>/dev/null
[ "$(ls "$T/plain" | wc -l)" -eq $FRAMES ]
if cmp -s "$T/logs/000015.png" "$T/plain/000015.png"; then echo "frame 15 not annotated"; exit 1; fi
# no display, no output: a clear error
rc=0; env -u DISPLAY -u WAYLAND_DISPLAY "$BIN/ld-view" --log "$T/in.lcmlog" 2> "$T/err" || rc=$?
[ "$rc" -eq 2 ]
grep -q "no display" "$T/err"
echo "1 passed, 0 failed"
