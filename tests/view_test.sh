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
# calibrations of the frames' camera (640x480, f = 600 px), of the same
# camera at 1280x960, and at 1280x720 (another crop of the sensor)
calib() {  # W H F
  printf '%%YAML:1.0\n---\nimage_width: %d\nimage_height: %d\ncamera_matrix: !!opencv-matrix\n  rows: 3\n  cols: 3\n  dt: d\n  data: [%d, 0, %s, 0, %d, %s, 0, 0, 1]\ndistortion_coefficients: !!opencv-matrix\n  rows: 1\n  cols: 5\n  dt: d\n  data: [0, 0, 0, 0, 0]\n' \
    "$1" "$2" "$3" "$(awk "BEGIN{print ($1-1)/2}")" "$3" "$(awk "BEGIN{print ($2-1)/2}")"
}
calib 640 480 600 >"$T/cam640.yaml"; calib 1280 960 1200 >"$T/cam1280.yaml"; calib 1280 720 1200 >"$T/cam720.yaml"
printf '{"detector": {"args": ["--camera", "%s", "--size", "0.3"]}}\n' "$T/cam640.yaml" >"$T/run.json"
"$BIN/ld-synth" sequence --out "$T/seq" --frames $FRAMES --fps 10 --landmarks 2 --seed 3 --size 0.3 \
  --format mjpeg --log "$T/in.lcmlog" >/dev/null

"$ROOT/scripts/netns-run.sh" bash -c '
  set -euo pipefail
  BIN=$1; T=$2; ROOT=$3
  "$BIN/ld-view" --out "$T/live" 2> "$T/live.err" &
  view=$!
  # a viewer that falls behind (stopped for 1.5 s: 15 frames at 10 fps): it
  # drops the oldest lists beyond 8, counted, rather than falling behind for good
  "$BIN/ld-view" --out "$T/slow" 2> "$T/slow.err" &
  slow=$!
  source "$ROOT/tests/lcm_sockets.sh"
  lcm_sockets 2   # subscribed (0.4-2.6 s after its start), and the LCM self test over, before frames come
  (for _ in $(seq 300); do [ "$(ls "$T/slow" 2>/dev/null | wc -l)" -lt 3 ] || break; sleep 0.02; done
   kill -STOP $slow; sleep 1.5; kill -CONT $slow) &
  stopper=$!
  "$BIN/ld-run" --config "$T/run.json" --replay "$T/in.lcmlog" --exit-when-replay-done --record "$T/run.lcmlog" \
    --status-interval 0 -q
  wait $stopper
  sleep 0.5
  kill -INT $view $slow; wait $view; wait $slow
' view "$BIN" "$T" "$ROOT"
cat "$T/live.err"
live=$(ls "$T/live" | wc -l)
"$BIN/ld-view" --log "$T/in.lcmlog" --log "$T/run.lcmlog" --out "$T/logs" --video "$T/view.avi" --fps 10
logs=$(ls "$T/logs" | wc -l)
echo "live: $live frames, logs: $logs frames, video: $(stat -c %s "$T/view.avi") bytes"
[ "$logs" -eq $FRAMES ]
[ "$live" -eq $FRAMES ]
cat "$T/slow.err"
slow=$(ls "$T/slow" | wc -l)
skipped=$(sed -n 's/.* frames drawn, \([0-9]*\) skipped (drawing was slower than the camera).*/\1/p' "$T/slow.err")
# (at least one: how many came during the stop depends on when the stopper
# saw its third frame, late on a loaded machine; 7 when early, 2 seen in CI)
[ -n "$skipped" ] && [ "$skipped" -ge 1 ] && [ $((slow + skipped)) -eq $FRAMES ] ||
  { echo "a viewer stopped for 1.5 s: $slow drawn, '$skipped' skipped of $FRAMES"; exit 1; }
[ "$(ls "$T/logs")" = "$(ls "$T/live")" ]   # the same frames, named by seq
[ "$(ls "$T/logs" | head -1)" = 000000.png ]
[ "$(stat -c %s "$T/view.avi")" -gt 10000 ]
# drawn on: differs from the same frame drawn without tracks (--all, images only)
"$BIN/ld-view" --log "$T/in.lcmlog" --all --out "$T/plain" 2>/dev/null
[ "$(ls "$T/plain" | wc -l)" -eq $FRAMES ]
if cmp -s "$T/logs/000015.png" "$T/plain/000015.png"; then echo "frame 15 not annotated"; exit 1; fi
# pose axes (the run's detector had the calibration): drawn with the
# frames' calibration, and the same with that camera's at another size
# (scaled to the frames: drawn unscaled, they missed the landmark); a
# calibration of another aspect ratio draws none, said once
"$BIN/ld-view" --log "$T/in.lcmlog" --log "$T/run.lcmlog" --out "$T/axes640" --camera "$T/cam640.yaml" 2>"$T/err"
"$BIN/ld-view" --log "$T/in.lcmlog" --log "$T/run.lcmlog" --out "$T/axes1280" --camera "$T/cam1280.yaml" 2>>"$T/err"
"$BIN/ld-view" --log "$T/in.lcmlog" --log "$T/run.lcmlog" --out "$T/axes720" --camera "$T/cam720.yaml" 2>"$T/err720"
if cmp -s "$T/axes640/000015.png" "$T/logs/000015.png"; then echo "frame 15: no pose axes"; exit 1; fi
for f in $(ls "$T/logs"); do
  cmp -s "$T/axes640/$f" "$T/axes1280/$f" || { echo "$f: axes of the 1280x960 calibration differ"; exit 1; }
  cmp -s "$T/axes720/$f" "$T/logs/$f" || { echo "$f: axes drawn with a calibration of another aspect ratio"; exit 1; }
done
! grep -q note "$T/err" || { echo "calibrations that fit: $(cat "$T/err")"; exit 1; }
[ "$(grep -c 'note: no pose axes: the camera calibration is for 1280x720 images and this frame is 640x480' "$T/err720")" -eq 1 ] ||
  { echo "another aspect ratio: $(cat "$T/err720")"; exit 1; }
# two runs' lists for the same frames (the recording given twice): drawn
# with the last, said in a note; lists whose image no log holds (an image
# log cut short) said too
"$BIN/ld-view" --log "$T/in.lcmlog" --log "$T/run.lcmlog" --log "$T/run.lcmlog" --out "$T/twice" 2>"$T/err"
[ "$(ls "$T/twice" | wc -l)" -eq $FRAMES ]
grep -q "^ld-view: note: $FRAMES tracked lists came again for frames already listed (two runs' logs, or a recording that also holds a replayed run's?): each frame is drawn with the last one$" "$T/err" ||
  { echo "lists twice: $(cat "$T/err")"; exit 1; }
head -c $(( $(stat -c %s "$T/in.lcmlog") / 2 )) "$T/in.lcmlog" >"$T/half.lcmlog"
"$BIN/ld-view" --log "$T/half.lcmlog" --log "$T/run.lcmlog" --out "$T/half" 2>"$T/err" || true
drawn=$(ls "$T/half" | wc -l)
grep -q "^ld-view: note: $((FRAMES - drawn)) of the $FRAMES tracked lists have no image in the logs: not drawn$" "$T/err" ||
  { echo "image log cut: $drawn drawn; $(cat "$T/err")"; exit 1; }
# no display, no output: a clear error
rc=0; env -u DISPLAY -u WAYLAND_DISPLAY "$BIN/ld-view" --log "$T/in.lcmlog" 2> "$T/err" || rc=$?
[ "$rc" -eq 2 ]
grep -q "no display" "$T/err"
echo "1 passed, 0 failed"
