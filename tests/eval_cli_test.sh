#!/usr/bin/env bash
# ld-eval's command line: the size advisor's answer, exit codes and plot,
# the QR table with and without --stack, its plot, the motion and pose
# tables, the lighting sweeps' choices, the frames kept by --misses (missed,
# found but not read, false landmarks among distractors),
# and bad options refused before any sweep.
# usage: eval_cli_test.sh BIN_DIR
set -euo pipefail
BIN=$(cd "$1" && pwd)
T=$(mktemp -d); trap 'rm -rf "$T"' EXIT
fail() { echo "FAIL: $*" >&2; exit 1; }

# A 30 cm landmark is detected at 1 m and its short payload read at 0.5 m.
"$BIN/ld-eval" size --detect-at 1 --read-at 0.5 --side 0.3 --trials 8 >"$T/size.md" 2>"$T/size.err" \
  || fail "size: exit $?"
grep -q "^smallest landmark: 30 cm" "$T/size.md" || fail "size: $(cat "$T/size.md")"
# ... with a line on stderr as each point ends, as every subcommand (a user audit: size printed none)
grep -q "^  landmark 30 cm detected, 1.00 m, yaw within +-30: detected [0-9]*/8$" "$T/size.err" &&
  grep -q "^  landmark 30 cm read, 0.50 m, yaw within +-30: detected [0-9]*/8, decoded [0-9]*$" "$T/size.err" ||
  fail "size, progress: $(cat "$T/size.err")"
# ... and says what code it measured: 20 bytes, version 2 at Q, 4.94 mm modules on 30 cm
grep -q "^its QR: 20 bytes, version 2 (25 modules), error correction Q, modules of 4.94 mm on a 30 cm landmark" \
  "$T/size.md" || fail "size, the code: $(cat "$T/size.md")"
# The backend that ran is said where it is not the CPU (the tables are the
# same whatever ran them: a helper's audit could not tell what --backend
# auto measured); the CPU, the default, says nothing.
LD_GLES_AUTO_SOFTWARE=1 "$BIN/ld-eval" yaw --backend auto --trials 1 --step 160 >/dev/null 2>"$T/auto.err" ||
  fail "yaw --backend auto: exit $?, $(cat "$T/auto.err")"
[ "$(grep -c "^ld-eval: our detector on the auto backend: gles: .*auto: timing it against the CPU on the first frames (each sweep point's detector chooses on its first frames)$" "$T/auto.err")" -eq 1 ] ||
  fail "yaw --backend auto: $(cat "$T/auto.err")"
"$BIN/ld-eval" yaw --trials 1 --step 160 >/dev/null 2>"$T/cpu.err" || fail "yaw: exit $?"
! grep -q "backend" "$T/cpu.err" || fail "yaw on the CPU: $(cat "$T/cpu.err")"
# No 5 cm landmark reads 100 bytes at 3 m: exit 3, and it says so. (Given
# by the names the other programs use: --size for --side, ld-qr-reader's
# --stack-frames for --stack.)
set +e
"$BIN/ld-eval" size --detect-at 3 --read-at 3 --size 0.05 --payload-bytes 100 --trials 4 --stack-frames 2 \
  >"$T/none.md" 2>/dev/null
rc=$?
set -e
[ $rc -eq 3 ] || fail "size with no answer: exit $rc, not 3"
grep -q "no candidate side reaches 95 %" "$T/none.md" || fail "size with no answer: $(cat "$T/none.md")"
grep -q "read at 3 m over 2 frames" "$T/none.md" || fail "size --stack: the table does not say so"

# The QR table: 5 columns, 7 with --stack, and the plot.
"$BIN/ld-eval" qr --trials 3 --from 0.3 --to 0.4 >"$T/qr.md" 2>/dev/null
[ "$(grep -c '^| 0\.[34] ' "$T/qr.md")" -eq 2 ] || fail "qr: $(cat "$T/qr.md")"
[ "$(head -1 "$T/qr.md" | tr -cd '|' | wc -c)" -eq 6 ] || fail "qr header: $(head -1 "$T/qr.md")"
# ... and under it what was measured and which codes were printed (--ecc
# changed the table without a word in it)
grep -q "^15 cm landmarks, yaw within +-40 deg, 3 frames a point for each payload length, seed 1; the largest code of each: 8-23 bytes: version 2 (25 modules), error correction M, modules of 2.47 mm; 99-100 bytes: version 5 (37 modules), error correction L, modules of 1.71 mm$" \
  "$T/qr.md" || fail "qr, what was measured: $(tail -1 "$T/qr.md")"
"$BIN/ld-eval" qr --trials 1 --from 0.3 --to 0.3 --ecc H >"$T/qrh.md" 2>/dev/null
grep -q "8-23 bytes: version [34] ([0-9]* modules), error correction H, .*; 99-100 bytes: version 10 (57 modules), error correction H, modules of 1.13 mm$" \
  "$T/qrh.md" || fail "qr --ecc H: $(tail -1 "$T/qrh.md")"
"$BIN/ld-eval" qr --trials 3 --from 0.3 --to 0.4 --stack 2 --png "$T/qr.png" >"$T/qrs.md" 2>/dev/null
[ "$(head -1 "$T/qrs.md" | tr -cd '|' | wc -c)" -eq 8 ] || fail "qr --stack header: $(head -1 "$T/qrs.md")"
grep -q "over 2 frames, 99-100 bytes" "$T/qrs.md" || fail "qr --stack: $(head -1 "$T/qrs.md")"
awk -F'|' '/^\| 0\.3 / { exit !($6 ~ /100.0 %/ && $7 ~ /100.0 %/) }' "$T/qrs.md" \
  || fail "qr --stack at 0.3 m: $(grep '^| 0.3 ' "$T/qrs.md")"
[ -s "$T/qr.png" ] || fail "no plot"

# The motion blur table: one row per blur length, a column per side and
# marker with --compare; no blur finds every landmark, 20 px none of the 9 cm
# ones (their squares are 8 px), the plot written.
"$BIN/ld-eval" motion --trials 4 --to 20 --step 10 --compare --png "$T/motion.png" >"$T/motion.md" 2>/dev/null \
  || fail "motion: exit $?"
[ "$(grep -c '^| [0-9]' "$T/motion.md")" -eq 3 ] || fail "motion rows: $(cat "$T/motion.md")"
head -1 "$T/motion.md" | grep -q '^| motion blur (px) | 9 cm at 1.5 m | 9 cm at 1.5 m AprilTag 3 | 9 cm at 1.5 m ArUco | 15 cm at 1.5 m |' \
  || fail "motion header: $(head -1 "$T/motion.md")"
awk -F'|' '/^\| 0 / { ok = ($3 ~ /100.0 %/ && $6 ~ /100.0 %/) } END { exit !ok }' "$T/motion.md" \
  || fail "motion at 0: $(grep '^| 0 ' "$T/motion.md")"
awk -F'|' '/^\| 20 / { ok = ($3 ~ / 0.0 %/) } END { exit !ok }' "$T/motion.md" \
  || fail "motion at 20: $(grep '^| 20 ' "$T/motion.md")"
[ -s "$T/motion.png" ] || fail "no motion plot"
if "$BIN/ld-eval" motion --side 0.1 --side 0.2 --distance 1 >/dev/null 2>"$T/err"; then fail "motion: 2 sides, 1 distance accepted"; fi
grep -q "one --distance per --side" "$T/err" || fail "motion sides/distances: $(cat "$T/err")"

# The pose table: one row per distance and detector (ours from the centroids,
# ours with sheet alignment, AprilTag 3 and ArUco with --compare); at 2 m the alignment's
# corners are better than the centroids', and every detector finds its target.
"$BIN/ld-eval" pose --trials 8 --from 1 --to 2 --step 1 --compare >"$T/pose.md" 2>/dev/null || fail "pose: exit $?"
[ "$(grep -c '^| [12] | ' "$T/pose.md")" -eq 8 ] || fail "pose rows: $(cat "$T/pose.md")"
for d in "ours, centroids" "ours, sheet alignment" "AprilTag 3" "ArUco"; do
  grep -q "^| 2 | $d | " "$T/pose.md" || fail "pose: no row for $d at 2 m: $(cat "$T/pose.md")"
done
awk -F'|' '/^\| 2 \| ours, centroids \|/ { split($5, a, " / "); plain = a[1] + 0 }
           /^\| 2 \| ours, sheet alignment \|/ { split($5, a, " / "); aligned = a[1] + 0 }
           END { exit !(aligned > 0 && aligned < plain) }' "$T/pose.md" ||
  fail "pose: alignment's corners not better at 2 m: $(grep '^| 2 ' "$T/pose.md")"
if "$BIN/ld-eval" pose --png "$T/p.png" >/dev/null 2>"$T/err"; then fail "pose --png accepted"; fi
if "$BIN/ld-eval" pose --align 101 >/dev/null 2>"$T/err"; then fail "pose --align 101 accepted"; fi
grep -q -- "--align" "$T/err" || fail "bad --align: $(cat "$T/err")"

# A bad option is refused with a message naming it.
if "$BIN/ld-eval" qr --stack 100 >/dev/null 2>"$T/err"; then fail "--stack 100 accepted"; fi
grep -q -- "--stack" "$T/err" || fail "bad --stack: $(cat "$T/err")"
if "$BIN/ld-eval" size --ecc Z >/dev/null 2>"$T/err"; then fail "--ecc Z accepted"; fi
grep -q -- "--ecc.*not 'Z'" "$T/err" || fail "bad --ecc: $(cat "$T/err")"
# Refused before any sweep, one line each: a step making too many points (a
# step of 1e-9 filled gigabytes), a plot not named .png (it failed after the
# sweep), an empty path, a negative seed, sides without their distances.
for args in "yaw --step 1e-9|--step 1e-09 from -80 to 80 makes 1.6e+11 sweep points (at most 1000)" \
            "distance --step 1e-6|sweep points (at most 1000)" \
            "yaw --png $T/plot|--png $T/plot: the plot is a PNG, its name must end in .png" \
            "yaw --seed -1|--seed: must be a whole number 0 or more, not -1" \
            "size --side 5|--side: must be in [0.01, 2], not 5" \
            "yaw --side 0.001 --distance 1|--side: must be in [0.01, 2], not 0.001" \
            "yaw --side 0.12|give one --distance per --side (1 side, 2 distances: the default distances 1.5 2.5 go with the default sides 0.09 0.15)"; do
  set +e; timeout 20 "$BIN/ld-eval" ${args%%|*} >/dev/null 2>"$T/err"; rc=$?; set -e
  [ $rc -eq 2 ] && [ "$(wc -l <"$T/err")" -eq 1 ] && grep -qF -- "${args#*|}" "$T/err" || fail "${args%%|*}: exit $rc, $(cat "$T/err")"
done
set +e; "$BIN/ld-eval" qr --png "" >/dev/null 2>"$T/err"; rc=$?; set -e
[ $rc -eq 2 ] && grep -qF -- '--png needs a path, not ""' "$T/err" || fail "--png '': exit $rc, $(cat "$T/err")"
# A table that cannot be written all (a full disk) is said, not taken as written.
set +e; "$BIN/ld-eval" distance --trials 1 --from 1 --to 1 --side 0.15 --markdown /dev/full >/dev/null 2>"$T/err"; rc=$?; set -e
[ $rc -eq 1 ] && grep -q "^ld-eval: cannot write /dev/full: No space left on device" "$T/err" ||
  fail "--markdown /dev/full: exit $rc, $(cat "$T/err")"
# an output that is the calibration or the parameters it reads: refused
# before the sweep (the table replaced the calibration)
printf '%%YAML:1.0\n---\nsecond_looks: 1\n' >"$T/p.yaml"; cp "$T/p.yaml" "$T/p.keep"
for out in "--markdown $T/p.yaml" "--markdown $T/./p.yaml"; do
  set +e; "$BIN/ld-eval" yaw --trials 1 --params "$T/p.yaml" $out >/dev/null 2>"$T/err"; rc=$?; set -e
  [ $rc -eq 2 ] && grep -q "is the --params file: it would be written over" "$T/err" && cmp -s "$T/p.yaml" "$T/p.keep" ||
    fail "$out over --params: exit $rc, $(cat "$T/err")"
done
# ... nor one output over another (the table went over the plot, the list
# of misses or lighting's glare plot, status 0)
for out in "--markdown $T/same.png --png $T/same.png|--png $T/same.png is also --markdown" \
           "--misses $T/mm --markdown $T/mm/misses.jsonl|--misses $T/mm/misses.jsonl is also --markdown"; do
  set +e; "$BIN/ld-eval" yaw --trials 1 ${out%%|*} >/dev/null 2>"$T/err"; rc=$?; set -e
  [ $rc -eq 2 ] && grep -qF -- "${out#*|}: one would be written over the other" "$T/err" && [ ! -e "$T/same.png" ] ||
    fail "${out%%|*}: exit $rc, $(cat "$T/err")"
done
set +e; "$BIN/ld-eval" lighting --trials 1 --png "$T/l.png" --markdown "$T/l_glare.png" >/dev/null 2>"$T/err"; rc=$?; set -e
[ $rc -eq 2 ] && grep -qF -- "--png $T/l_glare.png is also --markdown: one would be written over the other" "$T/err" ||
  fail "lighting, --markdown over the glare plot: exit $rc, $(cat "$T/err")"
# A misspelt subcommand is named ("A subcommand is required").
set +e; "$BIN/ld-eval" yaww --trials 1 >/dev/null 2>"$T/err"; rc=$?; set -e
[ $rc -eq 2 ] && grep -qF "ld-eval: 'yaww' is no subcommand (yaw, distance, qr, size, lighting, motion, pose)" "$T/err" ||
  fail "yaww: exit $rc, $(cat "$T/err")"
# A side given twice is one series.
"$BIN/ld-eval" distance --side 0.15 --side 0.15 --trials 1 --from 1 --to 1 >"$T/twice.md" 2>/dev/null || fail "distance, a side twice: exit $?"
head -1 "$T/twice.md" | grep -q '^| distance (m) | 15 cm |$' || fail "distance, a side twice: $(head -1 "$T/twice.md")"
# A lone --side in motion takes the default distance, 1.5 m.
"$BIN/ld-eval" motion --trials 1 --side 0.12 --to 5 --step 5 >"$T/m1.md" 2>/dev/null || fail "motion, one side: exit $?"
head -1 "$T/m1.md" | grep -q '^| motion blur (px) | 12 cm at 1.5 m |$' || fail "motion, one side: $(head -1 "$T/m1.md")"
# size --png plots every candidate (the answer still the smallest that does).
"$BIN/ld-eval" size --detect-at 1 --read-at 0.5 --side 0.3 --side 0.4 --trials 2 --png "$T/size.png" >"$T/size2.md" 2>/dev/null ||
  fail "size --png: exit $?"
[ -s "$T/size.png" ] && [ "$(grep -c '^| [34]0 cm' "$T/size2.md")" -eq 2 ] && grep -q "^smallest landmark: 30 cm" "$T/size2.md" ||
  fail "size --png: $(cat "$T/size2.md")"

# A level given (any case) is taken: codes printed at M read at 0.3 m.
"$BIN/ld-eval" qr --ecc m --trials 3 --from 0.3 --to 0.3 >"$T/qrm.md" 2>/dev/null || fail "qr --ecc m: exit $?"
grep -q '^| 0\.3 | 100.0 % | 100.0 % | 100.0 % | 0 |' "$T/qrm.md" || fail "qr --ecc m: $(cat "$T/qrm.md")"

# The lighting tables: a value with a unit as "2000 K", one without as
# "0.15" (it had a second space); no distractor frames, no false figure.
"$BIN/ld-eval" lighting --trials 1 --fp-frames 0 --markdown "$T/light.md" >/dev/null 2>&1 || fail "lighting: exit $?"
grep -q '^| 2000 K | [0-9.]* % | [0-9.]* % | - | - |$' "$T/light.md" && grep -q '^| 0\.15 | [0-9.]* % | [0-9.]* % | - | - |$' "$T/light.md" &&
  grep -q '^| 1\.2 | ' "$T/light.md" && ! grep -q '  |' "$T/light.md" || fail "lighting: $(cat "$T/light.md")"
# --sweeps and --glare: the glare sweep alone, at the strengths given, in
# rising order, each once; a sweep not known and a strength out of range refused.
"$BIN/ld-eval" lighting --sweeps glare --glare 0.75,0.45,0.75 --trials 1 --fp-frames 0 >"$T/glare.md" 2>/dev/null ||
  fail "lighting --glare: exit $?"
[ "$(grep -c '^| [0-9]' "$T/glare.md")" -eq 2 ] && [ "$(grep -c '^| glare on the landmark |' "$T/glare.md")" -eq 1 ] &&
  [ "$(grep '^| [0-9]' "$T/glare.md" | cut -d' ' -f2 | tr '\n' ' ')" = "0.45 0.75 " ] ||
  fail "lighting --glare: $(cat "$T/glare.md")"
for args in "--sweeps glow|--sweeps: glow not in {temperature,gain,glare}" "--glare 0.3,5|--glare: must be in [0, 3], not 5" \
            "--glare nan|--glare: 'nan' is not a number"; do
  set +e; "$BIN/ld-eval" lighting ${args%%|*} >/dev/null 2>"$T/err"; rc=$?; set -e
  [ $rc -eq 2 ] && grep -qF -- "${args#*|}" "$T/err" || fail "lighting ${args%%|*}: exit $rc, $(cat "$T/err")"
done
# --misses: each frame our detector missed, as a PNG and a line of
# misses.jsonl; ld-detect on the PNG misses it too (the same pixels; no
# landmark there by ld-eval's own match, every centre within max(2 px, 0.3
# of a FIP's side)). A second run starts the list anew; no folder, or a
# file for one, refused; a refused run leaves the list as it was.
"$BIN/ld-eval" yaw --side 0.15 --distance 2.5 --max-yaw 85 --step 170 --trials 4 --misses "$T/misses" \
  >/dev/null 2>"$T/misses.err" || fail "yaw --misses: exit $?"
missed=$(awk '/detected/ { split($NF, a, "/"); m += a[2] - a[1] } END { print m + 0 }' "$T/misses.err")
[ "$missed" -gt 0 ] && [ "$(wc -l <"$T/misses/misses.jsonl")" -eq "$missed" ] &&
  [ "$(ls "$T/misses" | grep -c '^side15_2\.5m_yaw[-+]85_seed1_trial00[0-3]_fixed\.png$')" -eq "$missed" ] ||
  fail "yaw --misses: $missed missed, $(ls "$T/misses" | tr '\n' ' ')"
"$BIN/ld-detect" "$T/misses" >"$T/misses.det" 2>/dev/null || fail "ld-detect on the misses: exit $?"
python3 - "$T/misses/misses.jsonl" "$T/misses.det" <<'PY' || fail "the misses: $(cat "$T/misses.det")"
import json, math, os, sys
lines = [json.loads(l) for l in open(sys.argv[1])]
truth = {l["image"]: l["truth"] for l in lines}
seen = 0
for line in open(sys.argv[2]):
    d = json.loads(line)
    t = truth[os.path.basename(d["image"])]
    seen += 1
    tol = max(2.0, 0.3 * math.dist(t["fip_tr"], t["fip_tl"]) / 3)
    for lm in d["landmarks"]:
        assert not all(math.dist(lm[k], t[k]) < tol for k in ("fip_tl", "fip_tr", "fip_bl", "ap")), d["image"]
assert seen == len(lines) > 0 and all(l["detector"] == "fixed" and l["side_m"] == 0.15 for l in lines)
PY
python3 - "$T/misses/misses.jsonl" <<'PY' || fail "kind of the misses: $(cat "$T/misses/misses.jsonl")"
import json, sys
assert all(json.loads(l)["kind"] == "not detected" for l in open(sys.argv[1]))
PY
# Found but not read (qr: 100-byte payloads at 1 m, mostly unread): kept
# with "_unread", the payload printed and what the frame read; ld-detect
# --decode on the frame reads what the line says it read.
"$BIN/ld-eval" qr --from 1 --to 1 --trials 4 --misses "$T/unread" >/dev/null 2>&1 || fail "qr --misses: exit $?"
[ "$(ls "$T/unread" | grep -c '^side15_1m_yaw+0_seed1_trial00[0-3]_long_fixed_unread\.png$')" -ge 1 ] &&
  [ "$(ls "$T/unread" | grep -c '\.png$')" -eq "$(wc -l <"$T/unread/misses.jsonl")" ] ||
  fail "qr --misses: $(ls "$T/unread" | tr '\n' ' ')"
"$BIN/ld-detect" --decode "$T/unread"/*_unread.png >"$T/unread.det" 2>/dev/null || fail "ld-detect --decode on the unread: exit $?"
python3 - "$T/unread/misses.jsonl" "$T/unread.det" <<'PY' || fail "the unread: $(cat "$T/unread/misses.jsonl" "$T/unread.det")"
import json, math, os, sys
lines = {l["image"]: l for l in map(json.loads, open(sys.argv[1])) if l["kind"] == "not read"}
seen = 0
for out in map(json.loads, open(sys.argv[2])):
    l = lines[os.path.basename(out["image"])]
    t = l["truth"]
    tol = max(2.0, 0.3 * math.dist(t["fip_tr"], t["fip_tl"]) / 3)
    mine = [lm for lm in out["landmarks"] if all(math.dist(lm[k], t[k]) < tol for k in ("fip_tl", "fip_tr", "fip_bl", "ap"))]
    assert len(mine) == 1 and mine[0].get("payload") == l["read"] != l["payload"], out["image"]
    assert l["tag"] == "long" and len(l["payload"].encode()) >= 99, l
    seen += 1
assert seen == len(lines) > 0
PY
# False landmarks (lighting's distractor frames, with checks loosened so
# that there are some): kept as distractors_..., with the landmarks found,
# which ld-detect finds there too, fixed and adaptive alike.
printf 'qr_max_brightness: 1.0\nsheet_uniformity: 0\nsheet_max_saturation: 1\nsheet_min_value: 0\ncover_min: 0\ncover_max: 1\nshape_tolerance: 1\nap_max_offset: 3\nmax_anisotropy: 10\nsquare_scale_min: 0.01\nsquare_scale_max: 10\n' >"$T/loose.yaml"
"$BIN/ld-eval" lighting --sweeps glare --glare 0.3 --trials 1 --fp-frames 4 --params "$T/loose.yaml" --misses "$T/fp" \
  >/dev/null 2>&1 || fail "lighting --misses: exit $?"
[ "$(ls "$T/fp" | grep -c '^distractors_glare0\.3_seed1_frame00[0-3]_fixed\.png$')" -ge 1 ] &&
  [ "$(ls "$T/fp" | grep -c '^distractors_glare0\.3_seed1_frame00[0-3]_adaptive\.png$')" -ge 1 ] ||
  fail "lighting --misses: $(ls "$T/fp" | tr '\n' ' ')"
for who in fixed adaptive; do
  flag=; [ $who = adaptive ] && flag=--adaptive
  for f in "$T/fp"/distractors_*_$who.png; do
    "$BIN/ld-detect" $flag --params "$T/loose.yaml" "$f" >>"$T/fp.det" 2>/dev/null || fail "ld-detect $flag on $f: exit $?"
  done
done
python3 - "$T/fp/misses.jsonl" "$T/fp.det" <<'PY' || fail "the false landmarks: $(cat "$T/fp/misses.jsonl" "$T/fp.det")"
import json, math, os, sys
lines = {l["image"]: l for l in map(json.loads, open(sys.argv[1])) if l["kind"] == "false landmarks"}
seen = 0
for out in map(json.loads, open(sys.argv[2])):
    l = lines[os.path.basename(out["image"])]
    assert l["detector"] in out["image"] and l["glare"] == 0.3 and len(l["landmarks"]) == len(out["landmarks"]) > 0, l
    for a, b in zip(l["landmarks"], out["landmarks"]):
        assert all(math.dist(a[k], b[k]) < 0.02 for k in ("fip_tl", "fip_tr", "fip_bl", "ap")), (a, b)
    seen += 1
assert seen == len(lines) > 0
PY
# (a refused run: the list stays)
set +e; "$BIN/ld-eval" yaw --side 0.15 --trials 1 --misses "$T/misses" >/dev/null 2>&1; rc=$?; set -e
[ $rc -eq 2 ] && [ "$(wc -l <"$T/misses/misses.jsonl")" -eq "$missed" ] || fail "a refused run emptied the list ($rc)"
"$BIN/ld-eval" yaw --side 0.15 --distance 1 --max-yaw 0 --trials 2 --misses "$T/misses" >/dev/null 2>"$T/again.err" ||
  fail "yaw --misses again: exit $?"
grep -q "detected 2/2" "$T/again.err" && [ -f "$T/misses/misses.jsonl" ] && [ ! -s "$T/misses/misses.jsonl" ] ||
  fail "yaw --misses again: $(cat "$T/again.err" "$T/misses/misses.jsonl")"
# each sweep point's progress line names its series: qr sweeps two payload kinds one after the
# other, and with --stack says what the frames read together (the lines looked the same)
"$BIN/ld-eval" qr --trials 1 --from 0.4 --to 0.4 --stack 2 >/dev/null 2>"$T/qr.err" || fail "qr --stack: exit $?"
grep -qE '^  8-23 bytes, 0\.40 m, yaw within \+-40: detected [01]/1, decoded [01], over 2 frames [01]$' "$T/qr.err" &&
  grep -qE '^  99-100 bytes, 0\.40 m, yaw within \+-40: detected [01]/1, decoded [01], over 2 frames [01]$' "$T/qr.err" ||
  fail "qr --stack progress: $(cat "$T/qr.err")"
: >"$T/afile"
set +e; "$BIN/ld-eval" yaw --trials 1 --misses "" >/dev/null 2>"$T/err"; rc=$?; set -e
[ $rc -eq 2 ] && grep -qF -- "--misses needs a folder" "$T/err" || fail "yaw --misses \"\": exit $rc, $(cat "$T/err")"
set +e; "$BIN/ld-eval" yaw --trials 1 --misses "$T/afile" >/dev/null 2>"$T/err"; rc=$?; set -e
[ $rc -eq 2 ] && grep -qF -- "not a folder that can be made" "$T/err" || fail "yaw --misses FILE: exit $rc, $(cat "$T/err")"
# --stack 1 is a single frame (its columns repeated the single-frame ones)
set +e; "$BIN/ld-eval" qr --stack 1 >/dev/null 2>"$T/err"; rc=$?; set -e
[ $rc -eq 2 ] && grep -q "^ld-eval: --stack: 1 frame is what the single-frame figures count: 0 (none), or 2 to 64" "$T/err" ||
  fail "qr --stack 1: exit $rc, $(cat "$T/err")"
# The glare sweep's strengths without the glare sweep (dropped without a word)
set +e; "$BIN/ld-eval" lighting --sweeps temperature --glare 0.75 >/dev/null 2>"$T/err"; rc=$?; set -e
[ $rc -eq 2 ] && grep -q "^ld-eval: --glare gives the glare sweep's strengths, and --sweeps leaves that sweep out" "$T/err" ||
  fail "lighting --glare without its sweep: exit $rc, $(cat "$T/err")"
# A step that does not divide the range: its end is swept too (yaw --step
# 100 swept -80 and 20, never +80)
timeout 60 "$BIN/ld-eval" yaw --side 0.15 --distance 1 --trials 1 --step 100 >"$T/steps" 2>/dev/null || fail "yaw --step 100: exit $?"
[ "$(grep -o '^| -\?[0-9]* |' "$T/steps" | tr -d '| ' | tr '\n' ' ')" = "-80 20 80 " ] || fail "yaw --step 100: $(cat "$T/steps")"
# A landmark larger than the view: said under the table (a silent 0 %, as
# the size table already said).
timeout 60 "$BIN/ld-eval" yaw --side 2 --distance 1 --trials 1 --step 80 >"$T/big" 2>/dev/null || fail "yaw, 2 m side: exit $?"
grep -q "^at 1 m the view is 0.80 m high: a 200 cm landmark (with its white margin) hardly fits in it" "$T/big" ||
  fail "yaw, 2 m side: $(cat "$T/big")"
echo ok
