#!/usr/bin/env bash
# The main job on the embedded default, no camera needed:
#  1. print a landmark (PNG + SVG) and a sheet of several;
#  2. make a synthetic sequence with ld-synth (landmarks with QR payloads,
#     a moving camera): PNG frames, ground truth and an LCM log of IMAGE;
#  3. run ld-detect over the frames (overlays in out/demo/overlay);
#  4. run the whole process set with ld-run in a private network namespace:
#     lcm-logplayer replays the log to ld-detector (with the camera's
#     calibration, so landmarks get a pose), ld-tracker and ld-qr-reader;
#     ld-run records their outputs and prints a summary (frames, landmarks per
#     frame, track ids with payloads, end-to-end latency percentiles);
#  5. draw the tracked landmarks on the frames with ld-view (PNGs and a video).
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
BUILD=${1:-$ROOT/build}   # (the repository's build/ wherever the script is run from)
[ -d "$BUILD/bin" ] || { echo "demo.sh: no programs in $BUILD/bin (make build first, or give the build folder)" >&2; exit 2; }
BIN=$(cd "$BUILD/bin" && pwd)
# Where the outputs go (LD_DEMO_OUT, default out/demo): emptied first; a
# folder given by LD_DEMO_OUT only when it is the demo's own (it holds
# .ld-demo) or empty, never a folder of anything else.
OUT=${LD_DEMO_OUT:-$ROOT/out/demo}
if [ -e "$OUT" ] && [ ! -d "$OUT" ]; then
  echo "demo.sh: $OUT is a file, not a folder: give LD_DEMO_OUT an empty or new folder" >&2
  exit 2
fi
if [ -n "${LD_DEMO_OUT:-}" ] && [ -e "$OUT" ] && [ ! -e "$OUT/.ld-demo" ] && [ -n "$(ls -A "$OUT" 2>/dev/null)" ]; then
  echo "demo.sh: $OUT holds files that are not the demo's: give LD_DEMO_OUT an empty or new folder" >&2
  exit 2
fi
rm -rf "$OUT" && mkdir -p "$OUT" && touch "$OUT/.ld-demo"
SIDE=0.3   # printed landmark side, metres: QR codes readable along the whole path at 640x480

echo "== 1. printable landmarks"
"$BIN/ld-generate" -p "room-214/door" -s 0.15 --dpi 300 --png "$OUT/landmark.png" --svg "$OUT/landmark.svg"
"$BIN/ld-generate" --sheet -p dock -p lift -p room-101 -p room-102 -s 0.09 --svg "$OUT/sheet.svg" --png "$OUT/sheet.png" --dpi 150

echo "== 2. synthetic sequence"
"$BIN/ld-synth" sequence --out "$OUT/seq" --frames 120 --fps 30 --landmarks 3 --seed 7 --size $SIDE \
  --format mjpeg --log "$OUT/demo.lcmlog"

echo "== 3. ld-detect over the frames"
"$BIN/ld-detect" "$OUT/seq" --draw "$OUT/overlay" -o "$OUT/detections.jsonl" --summary

echo "== 4. the process set on the replayed log (ld-run --netns)"
# ld-synth's default camera (640x480, f = 600 px), as an OpenCV calibration file.
cat > "$OUT/camera.yaml" <<'YAML'
%YAML:1.0
---
image_width: 640
image_height: 480
camera_matrix: !!opencv-matrix
   rows: 3
   cols: 3
   dt: d
   data: [ 600., 0., 319.5, 0., 600., 239.5, 0., 0., 1. ]
distortion_coefficients: !!opencv-matrix
   rows: 1
   cols: 5
   dt: d
   data: [ 0., 0., 0., 0., 0. ]
YAML
cat > "$OUT/run.json" <<JSON
{
  "source": {"type": "replay", "log": "$OUT/demo.lcmlog"},
  "detector": {"args": ["--camera", "$OUT/camera.yaml", "--size", "$SIDE"]},
  "record": {"file": "$OUT/run.lcmlog"}
}
JSON
"$BIN/ld-run" --netns --config "$OUT/run.json" --exit-when-replay-done --summary "$OUT/summary.json" \
  --log-dir "$OUT" --status-interval 1 --report

echo "== 5. tracked landmarks drawn on the frames (ld-view)"
"$BIN/ld-view" --log "$OUT/demo.lcmlog" --log "$OUT/run.lcmlog" --camera "$OUT/camera.yaml" \
  --axis-length 0.15 --out "$OUT/view" --video "$OUT/view.avi" --fps 30
echo "outputs in $OUT: summary.json, view/ (annotated PNGs), view.avi, overlay/ (ld-detect), run.lcmlog"
