#!/usr/bin/env bash
# The systemd units in tools/systemd: systemd-analyze verify finds nothing to
# say about them (unknown keys, bad syntax), and every program they start
# is one the build makes. Skipped (77) where systemd-analyze is missing.
set -euo pipefail
BIN=$1; ROOT=$2
command -v systemd-analyze >/dev/null || { echo "no systemd-analyze"; exit 77; }
T=$(mktemp -d); trap 'rm -rf "$T"' EXIT
units=()
for f in "$ROOT"/tools/systemd/*.service "$ROOT"/tools/systemd/*.target; do
  name=$(basename "$f")
  [[ $name == *@.service ]] && name=${name/@.service/@test.service}   # a template's instance
  cp "$f" "$T/$name"
  units+=("$T/$name")
done
systemd-analyze verify --man=no "${units[@]}" > "$T/out" 2>&1 || { cat "$T/out"; exit 1; }
cat "$T/out"
[ ! -s "$T/out" ]
for f in "$ROOT"/tools/systemd/*.service; do
  prog=$(sed -n 's|^ExecStart=/usr/bin/env \([^ ]*\).*|\1|p' "$f")
  [ -n "$prog" ] && [ -x "$BIN/$prog" ] || { echo "$f: ExecStart program '$prog' not built"; exit 1; }
  echo "$(basename "$f"): $prog"
done
grep -q '^Wants=.*ld-detector.service' "$ROOT/tools/systemd/landmark.target"
# each process's unit restarts for as long as it takes (a camera plugged in
# late: a start limit would put it in "failed" for good) and waits for the network
for u in ld-camera ld-detector ld-tracker ld-qr-reader; do
  grep -q '^StartLimitIntervalSec=0$' "$ROOT/tools/systemd/$u.service" || { echo "$u: a start limit"; exit 1; }
  grep -q '^Wants=network-online.target$' "$ROOT/tools/systemd/$u.service" || { echo "$u: no Wants=network-online"; exit 1; }
  grep -q '^RestartPreventExitStatus=2$' "$ROOT/tools/systemd/$u.service" || { echo "$u: restarts on status 2"; exit 1; }
done
grep -q '^Wants=network-online.target$' "$ROOT/tools/systemd/landmark.target"
# ld-run ends with status 2 when its set cannot run (a process refuses its
# arguments): systemd must not restart it into the same failure
grep -q '^RestartPreventExitStatus=2$' "$ROOT/tools/systemd/ld-run@.service" || { echo "ld-run@: restarts on status 2"; exit 1; }
echo "1 passed, 0 failed"
