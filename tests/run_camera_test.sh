#!/usr/bin/env bash
# ld-run with its camera source: ld-camera on its built-in fake webcam
# (a moving test pattern), the set behind it, in a private network namespace.
# Frames flow (IMAGE and LANDMARKS_TRACKED at the camera's rate), a killed
# camera is back within 2 s, and SIGTERM ends everything with exit 0.
set -euo pipefail
BIN=$1
source "$(dirname "$0")/ld_run_lib.sh"
"$BIN/ld-run" --netns --source camera --camera-arg=--fake --camera-arg=--device=/dev/ld-fake0 \
  --camera-arg=--fps=20 --state-file "$T/state.json" --summary "$T/summary.json" --log-dir "$T" \
  --status-interval 0 -q &
RUN=$!
wait_ready "$T/state.json"
sleep 2
kill_and_wait camera
[ "$new" -gt 0 ] && [ "$new" != "$old" ]
[ "$dt" -le 2000 ]
sleep 2
stop_run
[ "$rc" -eq 0 ]
jq -c '.summary.channels, .summary.frames' "$T/summary.json"
images=$(jq .summary.frames.images "$T/summary.json")
tracked=$(jq .summary.frames.tracked "$T/summary.json")
rate=$(jq '.summary.channels.IMAGE.rate_hz' "$T/summary.json")
[ "$images" -ge 40 ]                      # ~4 s at 20 frames/s, less the restart
# the restarted camera counts from seq 0 again: frames came through after it
after=$(jq '[.summary.per_frame[].seq] as $s
            | [range(1; $s | length) | select($s[.] < $s[. - 1])] as $resets
            | if ($resets | length) == 1 then ($s | length) - $resets[0] else -1 end' "$T/summary.json")
echo "tracked frames from the restarted camera: $after"
[ "$after" -ge 10 ]
[ "$tracked" -ge $(( images * 9 / 10 )) ]  # nearly every frame through the set
jq -e '.summary.channels.LANDMARKS_TRACKED.rate_hz > 10' "$T/summary.json" >/dev/null
echo "camera frames: $images at $rate frames/s, tracked: $tracked"
[ "$(jq '.processes[] | select(.name == "camera") | .restarts' "$T/summary.json")" -eq 1 ]
# a size the camera does not offer: status 2, not restarted, the run ends naming it (it was
# status 1, and ld-run restarted the camera for ever)
rc=0
timeout 60 "$BIN/ld-run" --netns --source camera --camera-arg=--fake --camera-arg=--size=1x1 --processes none \
  --status-interval 0 >"$T/bad.out" 2>&1 || rc=$?
[ $rc -eq 2 ] && grep -q "\[camera\] failed (exit 2); not restarted" "$T/bad.out" &&
  grep -q "does not offer YUYV 1x1" "$T/bad.out" || { echo "a size the camera does not offer: $rc $(cat "$T/bad.out")"; exit 1; }
echo "1 passed, 0 failed"
