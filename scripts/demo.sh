#!/usr/bin/env bash
# The main job on the embedded default, no camera needed:
#  1. print a landmark (PNG + SVG) and a sheet of several;
#  2. make a synthetic sequence with ld-synth (landmarks with QR payloads,
#     a moving camera): PNG frames, ground truth and an LCM log of IMAGE;
#  3. run ld-detect over the frames (overlays in out/demo/overlay);
#  4. run ld-detector on the log replayed by lcm-logplayer, inside a private
#     network namespace, record LANDMARKS with lcm-logger and summarise it.
set -euo pipefail
BUILD=${1:-build}
BIN=$(cd "$BUILD/bin" && pwd)
ROOT=$(cd "$(dirname "$0")/.." && pwd)
OUT=${LD_DEMO_OUT:-$ROOT/out/demo}
rm -rf "$OUT" && mkdir -p "$OUT"

echo "== 1. printable landmarks"
"$BIN/ld-generate" -p "room-214/door" -s 0.15 --dpi 300 --png "$OUT/landmark.png" --svg "$OUT/landmark.svg"
"$BIN/ld-generate" --sheet -p dock -p lift -p room-101 -p room-102 -s 0.09 --svg "$OUT/sheet.svg" --png "$OUT/sheet.png" --dpi 150

echo "== 2. synthetic sequence"
"$BIN/ld-synth" sequence --out "$OUT/seq" --frames 120 --fps 30 --landmarks 3 --seed 7 \
  --format mjpeg --log "$OUT/demo.lcmlog"

echo "== 3. ld-detect over the frames"
"$BIN/ld-detect" "$OUT/seq" --draw "$OUT/overlay" -o "$OUT/detections.jsonl" --summary

echo "== 4. ld-detector on the replayed log (private network namespace)"
"$ROOT/scripts/netns-run.sh" bash -c '
  set -euo pipefail
  BIN=$1; OUT=$2
  URL="udpm://239.255.76.67:7667?ttl=0&recv_buf_size=8388608"
  lcm-logger --lcm-url="$URL" -c LANDMARKS -f "$OUT/landmarks.lcmlog" >/dev/null &
  logger=$!
  "$BIN/ld-detector" --lcm-url "$URL" &
  det=$!
  sleep 1
  lcm-logplayer --lcm-url="$URL" "$OUT/demo.lcmlog"
  sleep 1
  kill -INT $det; wait $det || true
  kill -INT $logger; wait $logger || true
' demo "$BIN" "$OUT"
"$BIN/ld-dump" "$OUT/landmarks.lcmlog" > "$OUT/landmarks.jsonl"
msgs=$(grep -c '"type":"landmark_list_t"' "$OUT/landmarks.jsonl" || true)
found=$(grep -c '"fip_tl"' "$OUT/landmarks.jsonl" || true)
echo "ld-detector published $msgs LANDMARKS messages for 120 frames; $found with landmarks"
echo "outputs in $OUT"
