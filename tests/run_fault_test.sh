#!/usr/bin/env bash
# ld-run as a supervisor, in a private network namespace: the set runs on a
# looped log (ld-play, 15 frames/s). Each of ld-detector, ld-tracker and
# ld-qr-reader in turn is killed with SIGKILL: it must be running again (a
# new pid, the same program) within 2 s while the other processes keep their
# pids, and frames must be tracked again afterwards. Then the tracker is
# stopped (SIGSTOP): found hung, said, killed and restarted. SIGTERM to ld-run then
# stops every process, and ld-run exits 0; its summary keeps the restarted
# tracker's tracks apart from the first run's.
set -euo pipefail
BIN=$1
source "$(dirname "$0")/ld_run_lib.sh"
"$BIN/ld-synth" sequence --out "$T/seq" --frames 30 --fps 15 --landmarks 2 --seed 3 --size 0.3 \
  --format mjpeg --log "$T/in.lcmlog" --no-png >/dev/null

printf '{"restart": {"hang_s": 2}}\n' >"$T/hang.json"
"$BIN/ld-run" --netns --config "$T/hang.json" --play "$T/in.lcmlog" --fps 15 --duration 120 --state-file "$T/state.json" \
  --summary "$T/summary.json" --log-dir "$T" --status-interval 0 -q 2>"$T/console" &
RUN=$!

wait_ready "$T/state.json"
[ "$(jq .ready "$T/state.json")" = true ]
sleep 1

for victim in detector tracker qr-reader; do
  declare -A before=()
  for p in detector tracker qr-reader play; do before[$p]=$(pid_of $p); done
  exe=$(readlink "/proc/${before[$victim]}/exe")
  kill_and_wait "$victim"
  [ "$new" -gt 0 ] && [ "$new" != "$old" ]
  [ "$dt" -le 2000 ]
  [ "$(readlink "/proc/$new/exe")" = "$exe" ]
  for p in detector tracker qr-reader play; do
    [ "$p" = "$victim" ] && continue
    [ "$(pid_of $p)" = "${before[$p]}" ] || { echo "$p changed pid"; exit 1; }
    kill -0 "${before[$p]}"
  done
  sleep 1.5  # the restarted process works again before the next kill
done

# A hung process (SIGSTOP: it runs no more, and does not die) is found by
# its silence while its input comes, said, killed and restarted (hang_s 2
# here; it was never noticed, the state file saying it ran)
old=$(pid_of tracker)
kill -STOP "$old"
t0=$(now_ms)
while [ $(( $(now_ms) - t0 )) -lt 10000 ]; do
  new=$(pid_of tracker)
  [ "$new" -gt 0 ] 2>/dev/null && [ "$new" != "$old" ] && break
  sleep 0.1
done
echo "tracker: pid $old stopped, back as pid $new after $(( $(now_ms) - t0 )) ms"
[ "$new" -gt 0 ] && [ "$new" != "$old" ]
grep -q "^\[tracker\] published nothing on LANDMARKS_TRACKED for [0-9.]* s while its input came ([0-9]* on LANDMARKS)\(, [0-9]* bytes of it unread\)\?\(, its main thread not run since\)\?; it is T (stopped): hung, killed to be restarted$" "$T/console" ||
  { echo "the hang is not said: $(cat "$T/console")"; exit 1; }
sleep 1.5

pids=$(jq -r '.processes[] | .pid' "$T/state.json")
stop_run
echo "ld-run exit status after SIGTERM: $rc"
[ "$rc" -eq 0 ]
for p in $pids; do
  if kill -0 "$p" 2>/dev/null; then echo "pid $p still running"; exit 1; fi   # every process gone
done
[ "$(jq -r .end "$T/summary.json")" = "stopped by SIGTERM" ]
[ "$(jq '[.processes[] | select(.name == "detector" or .name == "tracker" or .name == "qr-reader") | .restarts] | add' "$T/summary.json")" -eq 4 ]
[ "$(jq '[.processes[] | select(.name == "tracker") | .hangs] | add' "$T/summary.json")" -eq 1 ]
[ "$(jq '[.processes[] | .hangs] | add' "$T/summary.json")" -eq 1 ]
[ "$(jq '[.processes[] | select(.name == "play") | .restarts] | add' "$T/summary.json")" -eq 0 ]
# the restarted tracker numbered its tracks from 1 again: the summary tells
# its tracks from the first run's (two restarts: killed, then hung; seen from the tracks' ages)
echo "tracker restarts seen on the bus: $(jq .summary.tracker_restarts "$T/summary.json")," \
  "tracks: $(jq -c '[.summary.tracks[] | "\(.id)/\(.tracker_run)"]' "$T/summary.json")"
[ "$(jq .summary.tracker_restarts "$T/summary.json")" -eq 2 ]
[ "$(jq '[.summary.tracks[] | select(.tracker_run == 2)] | length' "$T/summary.json")" -ge 1 ]
[ "$(jq '[.summary.tracks[] | [.id, .tracker_run]] | length == (unique | length)' "$T/summary.json")" = true ]
# frames kept flowing through the restarts: the last tracked frame is recent
last=$(jq '.summary.per_frame[-1].seq' "$T/summary.json")
images=$(jq '.summary.frames.images' "$T/summary.json")
echo "images: $images, tracked: $(jq .summary.frames.tracked "$T/summary.json"), last tracked seq: $last"
[ "$last" -ge $(( images - 5 )) ]
# ld-play's images are timed from their publication (utime), never below 0
[ "$(jq -r .summary.latency_ms.from "$T/summary.json")" = capture ]
[ "$(jq '[.summary.per_frame[] | select(.latency_ms != null and .latency_ms <= 0)] | length' "$T/summary.json")" -eq 0 ]
# which process died and was restarted is said on the console, though the
# processes' lines go to --log-dir (there alone, the console said nothing)
for victim in detector tracker qr-reader; do
  grep -q "^\[$victim\] died (signal 9 (Killed)); restarting in " "$T/console" &&
    grep -q "^\[$victim\] restarted, pid " "$T/console" &&
    grep -q "^\[ld-run\] died (signal 9 (Killed)); restarting in " "$T/$victim.log" ||
    { echo "the console or $victim.log does not say $victim died: $(cat "$T/console")"; exit 1; }
done
echo "1 passed, 0 failed"
