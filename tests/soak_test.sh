#!/usr/bin/env bash
# ld-soak, short: the set at 30 frames per second for 20 s at 640x480 keeps
# memory and fds flat and loses nothing (ld-soak's own verdict, its exit
# status), and the counts it prints for each process are the process's own
# (read from its exit line by label). Bad options are refused first, one
# line each, status 2. Runs inside a private network namespace.
set -euo pipefail
BIN=$1; ROOT=$2
T=$(mktemp -d); trap 'rm -rf "$T"' EXIT
NS="$ROOT/scripts/netns-run.sh"

for args in "--fps 1e-9|--fps: must be in [0.1, 1000], not 1e-9" \
            "--duration 10|--warmup (20 s) must be shorter than --duration (10 s)" \
            "--loop-frames 100000|--loop-frames: must be in [1, 300]" \
            "--format bogus|--format: unknown pixel format 'bogus'" \
            "--bin $T/none|no ld-detector to run in $T/none (--bin)" \
            "--csv $T/none/x.csv|cannot write $T/none/x.csv (--csv)" \
            "--format yuyv --width 33 --height 32|--format yuyv needs an even width, not 33"; do
  rc=0
  timeout 20 "$NS" "$BIN/ld-soak" ${args%%|*} >/dev/null 2>"$T/err" || rc=$?
  [ $rc -eq 2 ] && [ "$(wc -l <"$T/err")" -eq 1 ] && grep -qF -- "${args#*|}" "$T/err" ||
    { echo "FAIL: ${args%%|*}: exit $rc, $(cat "$T/err")"; exit 1; }
done

rc=0
"$NS" "$BIN/ld-soak" --duration 20 --width 640 --height 480 --warmup 8 --sample-interval 4 \
  --log-dir "$T/logs" --csv "$T/samples.csv" | tee "$T/out" || rc=$?
[ $rc -eq 0 ] || { echo "FAIL: ld-soak exit $rc"; exit 1; }
grep -q "^verdict: PASS" "$T/out"
[ "$(wc -l <"$T/samples.csv")" -ge 6 ] || { echo "FAIL: samples.csv"; cat "$T/samples.csv"; exit 1; }
# The QR reader's line as ld-soak prints it, against the reader's own.
own=$(grep "^ld-qr-reader: stopped after" "$T/logs/ld-qr-reader.err")
printed=$(grep "^ld-qr-reader: " "$T/out")
for label in "tracks read" skipped unmatched bad; do
  a=$(grep -o "[0-9]* $label" <<<"$own" | head -1); b=$(grep -o "[0-9]* $label" <<<"$printed" | head -1)
  [ -n "$a" ] && [ "$a" = "$b" ] || { echo "FAIL: $label: reader '$own', ld-soak '$printed'"; exit 1; }
done
a=$(grep -o "after [0-9]* frames" <<<"$own"); b=$(grep -o "[0-9]* frames joined" <<<"$printed")
[ "${a//[^0-9]/}" = "${b//[^0-9]/}" ] || { echo "FAIL: frames: '$own' / '$printed'"; exit 1; }
# Stopped by a signal: the figures up to the stop, not of processes that had
# ended (RSS 0, fds 0), no "could not keep 30 fps", the frame in flight not
# called lost
rc=0
timeout -s INT 9 "$NS" "$BIN/ld-soak" --duration 60 --width 320 --height 240 --warmup 1 --sample-interval 1 \
  --loop-frames 4 --log-dir "$T/logs2" >"$T/out2" 2>&1 || rc=$?
cat "$T/out2"
[ $rc -ne 0 ] && grep -q "^verdict: FAIL (stopped by a signal; up to then memory flat, fds flat; [0-9]* messages\? in flight at the stop)$" "$T/out2" ||
  { echo "FAIL: stopped run: exit $rc"; exit 1; }
! grep -q -e "could not keep" -e "-> 0.0 MB" -e "fds [0-9]* -> 0$" "$T/out2" || { echo "FAIL: stopped run's figures"; exit 1; }
echo "PASS"
