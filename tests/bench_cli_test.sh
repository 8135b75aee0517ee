#!/usr/bin/env bash
# ld-bench, ld-bench-tracker and ld-bench-e2e on their command lines: bad
# numbers and sizes are refused in one line before anything runs; a tiny
# ld-bench run prints its tables and writes --markdown; ld-bench-e2e's help
# is its header alone.
# usage: bench_cli_test.sh BIN_DIR
set -euo pipefail
BIN=$(cd "$1" && pwd)
T=$(mktemp -d); trap 'rm -rf "$T"' EXIT
fail() { echo "FAIL: $*" >&2; exit 1; }

refused() {  # PATTERN COMMAND...: exit 2 within 20 s, one line on stderr matching
  local pat=$1; shift
  local rc=0
  timeout 20 "$@" >"$T/out" 2>"$T/err" || rc=$?
  [ $rc -eq 2 ] || fail "$*: exit $rc, not 2: $(cat "$T/err")"
  [ "$(wc -l <"$T/err")" -eq 1 ] && grep -q -- "$pat" "$T/err" || fail "$*: $(cat "$T/err")"
}
refused "^ld-bench: --frames: must be in \[1, 1000\], not 0 (--help lists the options)$" "$BIN/ld-bench" --frames 0
refused "^ld-bench: --repeats: must be in \[1, 10000\], not 0" "$BIN/ld-bench" --repeats 0
refused "^ld-bench: --size: must be in \[0.01, 2\], not -1" "$BIN/ld-bench" --size -1
refused "^ld-bench: --resolutions: '640' is not WIDTHxHEIGHT" "$BIN/ld-bench" --resolutions 640
refused "^ld-bench: --resolutions: '32x32' is out of 64x48 .. 8192x8192" "$BIN/ld-bench" --resolutions 640x480,32x32
refused "^ld-bench: cannot write $T: is a folder$" "$BIN/ld-bench" --markdown "$T"
printf '%%YAML:1.0\n---\ncentre_iterations: 11\n' >"$T/bad.yaml"
refused "^ld-bench: .*bad.yaml.*centre_iterations" "$BIN/ld-bench" --params "$T/bad.yaml"
refused "^ld-bench: .*missing.yaml" "$BIN/ld-bench" --params "$T/missing.yaml"
# the tables over the parameters it read (they replaced them, status 0)
printf '%%YAML:1.0\n---\nsecond_looks: 1\n' >"$T/p.yaml"; cp "$T/p.yaml" "$T/p.keep"
refused "^ld-bench: --markdown $T/p.yaml is the --params file: it would be written over" "$BIN/ld-bench" --params "$T/p.yaml" --markdown "$T/p.yaml"
cmp -s "$T/p.yaml" "$T/p.keep" || fail "--markdown over --params: the parameters changed"
# tables that cannot be written all (a full disk): said with why, status 1
ln -s /dev/full "$T/full.md"
set +e; timeout 120 "$BIN/ld-bench" --frames 1 --repeats 1 --resolutions 640x480 --backend cpu --no-paper \
  --tracker-landmarks 10 --tracker-repeats 1 --markdown "$T/full.md" >/dev/null 2>"$T/err"; rc=$?; set -e
[ $rc -eq 1 ] && grep -q "^ld-bench: cannot write $T/full.md: No space left on device$" "$T/err" ||
  fail "--markdown /dev/full: exit $rc, $(cat "$T/err")"
refused "^ld-bench-tracker: --landmarks: must be in \[1, 1000\], not -5" "$BIN/ld-bench-tracker" --landmarks -5
refused "^ld-bench-tracker: --landmarks: must be in \[1, 1000\], not 100000" "$BIN/ld-bench-tracker" --landmarks 100000
refused "^ld-bench: --tracker-landmarks: must be in \[1, 1000\], not 100000" "$BIN/ld-bench" --tracker-landmarks 10,100000
timeout 60 "$BIN/ld-bench-tracker" --landmarks 5,7 --repeats 1 >"$T/out" || fail "ld-bench-tracker 5,7"
[ "$(grep -c '^| [57] |' "$T/out")" -eq 2 ] || fail "ld-bench-tracker 5,7: $(cat "$T/out")"
grep -q '^| landmarks | assignment | update |$' "$T/out" || fail "ld-bench-tracker's table is not ld-bench's: $(cat "$T/out")"
# output that cannot be written (a full disk): said, status 1 (it was 0, without a word)
rc=0; timeout 60 "$BIN/ld-bench-tracker" --landmarks 5 --repeats 1 >/dev/full 2>"$T/err" || rc=$?
[ $rc -eq 1 ] && grep -qx "ld-bench-tracker: cannot write its output: No space left on device" "$T/err" ||
  fail "ld-bench-tracker to a full disk: $rc $(cat "$T/err")"
# a closed pipe (its reader gone): said, status 1, as a full disk is (it
# died of SIGPIPE without a word)
python3 - "$BIN/ld-bench-tracker" --landmarks 5 --repeats 1 >"$T/rc" 2>"$T/err" <<'PY'
import os, subprocess, sys
r, w = os.pipe()
os.close(r)  # (no reader: the write fails; the child gets SIGPIPE's default back)
p = subprocess.run(sys.argv[1:], stdout=w, stderr=subprocess.PIPE)
print(p.returncode)
sys.stderr.write(p.stderr.decode())
PY
[ "$(cat "$T/rc")" = 1 ] && grep -qx "ld-bench-tracker: cannot write its output: Broken pipe" "$T/err" ||
  fail "ld-bench-tracker to a closed pipe: $(cat "$T/rc") $(cat "$T/err")"
# (bounded: every timing is held; 2e9 repeats overflowed an int and asked for 16 GB)
refused "^ld-bench-tracker: --repeats: must be in \[1, 1000000\], not 2000000000" "$BIN/ld-bench-tracker" --repeats 2000000000
refused "^ld-bench: --frames: must be in \[1, 1000\], not 5000" "$BIN/ld-bench" --frames 5000
refused "^ld-bench-e2e: unknown option --bogus (--help lists the options)$" "$BIN/ld-bench-e2e" --bogus
refused "^ld-bench-e2e: --seconds must be a number of seconds, not x" "$BIN/ld-bench-e2e" --seconds x
refused "^ld-bench-e2e: --seconds must be above 0" "$BIN/ld-bench-e2e" --seconds 0.0
refused "^ld-bench-e2e: --format must be keep, bgr, rgb, gray, yuyv, uyvy or mjpeg, not foo" "$BIN/ld-bench-e2e" --format foo
"$BIN/ld-bench-e2e" --help >"$T/help"
head -1 "$T/help" | grep -q "^ld-bench-e2e: end-to-end latency" || fail "e2e help: $(head -2 "$T/help")"
! grep -q "set -euo" "$T/help" || fail "e2e help shows the script: $(cat "$T/help")"
# nothing tracked (the detector alone), nothing timed: "-", not 0 ms
timeout 120 "$BIN/ld-bench-e2e" --processes detector --seconds 1 --hd-seconds 0 >"$T/e2e" 2>"$T/err" ||
  fail "e2e, detector alone: $(cat "$T/err")"
grep -q "^| 640x480 yuyv | [0-9]* | [0-9]* | 0 | [0-9]* / 0 | - | - | - | - |$" "$T/e2e" || fail "e2e untimed: $(cat "$T/e2e")"

# A tiny run: every table, and the same tables in --markdown (a new folder).
timeout 120 "$BIN/ld-bench" --frames 1 --repeats 1 --resolutions 320x240 --backend cpu --no-paper \
  --tracker-landmarks 10 --tracker-repeats 1 --markdown "$T/new/bench.md" >"$T/out" 2>"$T/err" ||
  fail "tiny run: $(cat "$T/err")"
grep -q "^| 320x240 | cpu | fast | " "$T/out" || fail "no detector row: $(cat "$T/out")"
grep -q "^| 10 | " "$T/out" || fail "no tracker row: $(cat "$T/out")"
grep -q '^| landmarks | assignment | update |$' "$T/out" || fail "ld-bench's tracker table: $(cat "$T/out")"
grep -q "^| 320x240 | cpu | fast | " "$T/new/bench.md" || fail "no --markdown"
# the header gives the command as run, to measure it again
grep -qF "Measured by \`ld-bench --frames 1 --repeats 1 --resolutions 320x240 --backend cpu --no-paper --tracker-landmarks 10 --tracker-repeats 1 --markdown $T/new/bench.md\`" "$T/out" ||
  fail "header: $(grep Measured "$T/out")"
# --params: the rows start from the file's parameters (sheet alignment on:
# the corners column takes its time) and the header says so.
printf '%%YAML:1.0\n---\nalign_iterations: 10\n' >"$T/align.yaml"
# (a resolution given twice is one row)
timeout 120 "$BIN/ld-bench" --frames 1 --repeats 1 --resolutions 640x480,640x480 --backend cpu --no-paper \
  --tracker-landmarks 10 --tracker-repeats 1 --params "$T/align.yaml" >"$T/out" 2>"$T/err" ||
  fail "--params run: $(cat "$T/err")"
grep -q -- "--params $T/align.yaml" "$T/out" || fail "--params not in the header: $(head -2 "$T/out")"
[ "$(grep -c "^| 640x480 | cpu | fast | " "$T/out")" -eq 1 ] || fail "not one detector row with --params: $(cat "$T/out")"
# a paper file's sigma for its own kernel: the fast rows leave it (they
# refused it, and ld-bench aborted after rendering, status 134)
printf '%%YAML:1.0\n---\nfront_end: paper\nblur_sigma: 2\n' >"$T/paper.yaml"
timeout 120 "$BIN/ld-bench" --frames 1 --repeats 1 --resolutions 320x240 --backend cpu \
  --tracker-landmarks 10 --tracker-repeats 1 --params "$T/paper.yaml" >"$T/out" 2>"$T/err" ||
  fail "--params paper with blur_sigma: $(cat "$T/err")"
grep -q "^| 320x240 | cpu | fast | " "$T/out" && grep -q "^| 320x240 | cpu | paper | " "$T/out" ||
  fail "--params paper: rows $(cat "$T/out")"
echo "bench command lines: ok"
