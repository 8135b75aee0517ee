#!/usr/bin/env bash
# ld-qr-reader reads a track's 100-byte code from its stacked frames where no
# single frame reads it: ten frames of one 15 cm landmark at 1 m (about a
# pixel per module; sensor noise 6 and JPEG quality 60, as a cheap camera in
# dim light gives: with noise 4 and quality 80 the reader fits single frames'
# modules to the pixels and reads them), a fraction of a pixel apart, replayed through the whole
# process set (ld-run --netns, real LCM multicast). With --stack-frames 0 the
# same replay gives no payload.
# usage: qr_stack_process_test.sh BIN_DIR
set -euo pipefail
BIN=$(cd "$1" && pwd)
T=$(mktemp -d); trap 'rm -rf "$T"' EXIT
# Its schedule's options out of range are refused at once, in one line,
# with status 2 (before any LCM is opened).
for bad in "--max-decodes 0|--max-decodes: must be in \[1, 100\], not 0" \
           "--retry-interval nan|--retry-interval: 'nan' is not a number" \
           "--recheck-interval -5|--recheck-interval: must be > 0, not -5" \
           "--decode-budget-ms 0|--decode-budget-ms: must be in \[1, 10000\], not 0" \
           "--nice 20|--nice: must be in \[0, 19\], not 20"; do
  rc=0; "$BIN/ld-qr-reader" ${bad%%|*} 2>"$T/err" || rc=$?
  [ $rc -eq 2 ] && [ "$(wc -l <"$T/err")" -eq 1 ] && grep -q "^ld-qr-reader: ${bad#*|}" "$T/err" ||
    { echo "FAIL: ld-qr-reader ${bad%%|*}: exit $rc: $(cat "$T/err")"; exit 1; }
done
# It runs 10 steps of nice below where it was started (--nice; at most 19),
# so that the detector and the tracker come first on shared cores; --nice 0
# leaves it. (Steps from this shell's own nice: the suite may run niced.)
base=$(awk '{print $19}' /proc/$$/stat)
[ "$base" -le 15 ] || echo "note: the test runs at nice $base: --nice's steps are not told apart at the top (19)"
# (the nice of the reader $pid; nothing once it has ended)
niceOf() { [ -r /proc/$pid/stat ] && awk '$3 != "Z" { print $19 }' /proc/$pid/stat 2>/dev/null; }
for case in "--nice 3|3" "|10" "--nice 0|0"; do
  opt=${case%%|*}; want=$((base + ${case#*|} > 19 ? 19 : base + ${case#*|}))
  "$BIN/ld-qr-reader" --lcm-url memq:// $opt 2>"$T/nice.err" & pid=$!
  # (a step above where it started shows it applied; then a moment more, so
  # that nothing after it would have moved it again)
  for _ in $(seq 50); do
    ni=$(niceOf || true); [ -n "$ni" ] || break
    [ "$want" = "$base" ] || [ "$ni" = "$want" ] && break
    sleep 0.1
  done
  sleep 0.3
  ni=$(niceOf || true)
  [ -n "$ni" ] || { echo "FAIL: ld-qr-reader ${opt:-without --nice} ended before it was stopped: $(cat "$T/nice.err")"; exit 1; }
  kill $pid 2>/dev/null || true; rc=0; wait $pid || rc=$?
  [ "$ni" = "$want" ] || { echo "FAIL: ld-qr-reader ${opt:-without --nice}: nice $ni, not $want"; exit 1; }
  # (stopped by SIGTERM: 0 once its handler is set, 143 before; anything else is a fault)
  [ $rc -eq 0 ] || [ $rc -eq 143 ] || { echo "FAIL: ld-qr-reader ${opt:-without --nice}: exit $rc on SIGTERM"; exit 1; }
done
payload=$(printf 'stacked-frames-%085d' 7)
"$BIN/ld-synth" scene --out "$T/sc" --count 10 --seed 5 --size 0.15 --distance 1.0 --yaw 5 --roll 10 \
  --x=-0.002:0.002 --y=-0.002:0.002 --payload "$payload" --lighting normal --background plain \
  --distractors 0 --noise 6 --jpeg 60 --defocus 0.5 --motion 0 >/dev/null
single=$("$BIN/ld-detect" --decode "$T/sc" | jq -r '.landmarks[0].payload' | grep -c stacked || true)
[ "$single" -eq 0 ] || { echo "FAIL: single frames read the code ($single of 10): the test tests nothing"; exit 1; }
"$BIN/ld-log-images" "$T/sc" "$T/sc.lcmlog" --fps 5 >/dev/null
for frames in 8 0; do
  # (a YAML config, the number written as a number)
  echo "qr_reader: {args: [--stack-frames, $frames]}" >"$T/cfg$frames.yaml"
  timeout 60 "$BIN/ld-run" --config "$T/cfg$frames.yaml" --netns --replay "$T/sc.lcmlog" \
    --exit-when-replay-done --summary "$T/sum$frames.json" --log-dir "$T/log$frames" --status-interval 0 -q
  jq -r '.summary.tracks[] | "\(.id) \(.payload)"' "$T/sum$frames.json" >"$T/tracks$frames"
  # (the log's utimes, made a moment ago, are not capture times: timed from
  # arrival; this catches the old rule only when the replay starts within a
  # second of the log's making: BusMonitor.TimesALogsImagesFromTheirArrival...
  # is the test that always does)
  [ "$(jq -r .summary.latency_ms.from "$T/sum$frames.json")" = arrival ] ||
    { echo "FAIL: a replay's latency timed from $(jq -c .summary.latency_ms "$T/sum$frames.json")"; exit 1; }
  echo "--stack-frames $frames: $(cut -c1-40 "$T/tracks$frames")"
done
[ "$(wc -l <"$T/tracks8")" -eq 1 ] || { echo "FAIL: not one track"; exit 1; }
[ "$(cut -d' ' -f2 "$T/tracks8")" = "$payload" ] || { echo "FAIL: stacked frames did not give the payload"; exit 1; }
[ "$(cut -d' ' -f2 "$T/tracks0")" = null ] || { echo "FAIL: a payload without stacking"; exit 1; }
# Fed the detector's lists (no track ids) it says so, once.
printf 'tracker: {enabled: false}\nchannels: {tracked: LANDMARKS}\n' >"$T/cfgdet.yaml"
timeout 60 "$BIN/ld-run" --config "$T/cfgdet.yaml" --netns --replay "$T/sc.lcmlog" \
  --exit-when-replay-done --log-dir "$T/logdet" --status-interval 0 -q
[ "$(grep -c "the landmarks on LANDMARKS carry no track ids (from backend 'cpu'): --tracks must name the tracker's output" \
    "$T/logdet/qr-reader.log")" -eq 1 ] || { echo "FAIL: no word on untracked lists: $(cat "$T/logdet/qr-reader.log")"; exit 1; }
echo "ok"
