#!/usr/bin/env bash
# ld-detect's command line: JSON Lines per image, --explain's account on
# stderr (what each stage kept, the check that refused a landmark, with its
# parameters), --adaptive's gains in it, unreadable files reported per file.
# usage: detect_cli_test.sh BIN_DIR SOURCE_DIR
set -euo pipefail
BIN=$(cd "$1" && pwd)
SRC=$(cd "$2" && pwd)
T=$(mktemp -d); trap 'rm -rf "$T"' EXIT
fail() { echo "FAIL: $*" >&2; exit 1; }

"$BIN/ld-synth" scene --out "$T/s" --seed 2 --count 2 --distance 1 --yaw 15 --lighting normal --degrade none \
  --background plain --distractors 0 >/dev/null
# Found: one landmark per image, counted in the explanation, nothing of it refused.
"$BIN/ld-detect" --explain "$T/s" >"$T/out" 2>"$T/err"
[ "$(grep -c '"landmarks":\[{' "$T/out")" -eq 2 ] || fail "defaults: $(cat "$T/out")"
[ "$(grep -c ': 1 landmark$' "$T/err")" -eq 2 ] || fail "defaults, explanation: $(cat "$T/err")"
grep -q '^  regions: [0-9]* blue, [0-9]* red (min_area_px 3' "$T/err" || fail "no region counts: $(cat "$T/err")"
grep -q '^  FIP graph (d_min 1.6, d_max 11' "$T/err" || fail "no graph counts: $(cat "$T/err")"
# A cover range no landmark meets: no landmark, and the explanation names the check and its parameters.
printf 'cover_max: 0.2\n' >"$T/p.yaml"
"$BIN/ld-detect" --explain --params "$T/p.yaml" "$T/s/000000.png" >"$T/out" 2>"$T/err"
grep -q '"landmarks":\[\]' "$T/out" || fail "cover_max 0.2 still finds: $(cat "$T/out")"
grep -q '000000.png: 0 landmarks$' "$T/err" || fail "cover: $(cat "$T/err")"
grep -q 'refused: 1 group of three FIPs (1 cover)' "$T/err" || fail "cover count: $(cat "$T/err")"
grep -q 'AP (.*): cover (cover_min, cover_max; where the colour is smeared, the absorbed light.s 0.25-0.42)$' "$T/err" || fail "cover check: $(cat "$T/err")"
# JSON stays exactly one line per image on stdout; detect_ms is the detection alone.
[ "$(wc -l <"$T/out")" -eq 1 ] && grep -q '"detect_ms":' "$T/out" || fail "stdout: $(cat "$T/out")"
# --adaptive: the adapter's gains are part of the account.
"$BIN/ld-detect" --explain --adaptive "$T/s/000001.png" >/dev/null 2>"$T/err"
grep -q '000001.png: 1 landmark; adaptive gains B [0-9.]* G [0-9.]* R [0-9.]*' "$T/err" || fail "adaptive: $(cat "$T/err")"
# --adaptive --explain on glare frames (ld-eval's glare point, the frames
# the fixed detector missed): the looks after the first pass are listed,
# round by round, and in some frame a veil window, its tint taken out, found
# the landmark.
"$BIN/ld-eval" lighting --sweeps glare --glare 0.75 --trials 24 --fp-frames 0 --seed 1 --misses "$T/glare" \
  >/dev/null 2>&1 || fail "ld-eval glare frames: exit $?"
"$BIN/ld-detect" --adaptive --explain "$T/glare"/*_fixed.png >"$T/out" 2>"$T/err" || fail "glare frames: exit $?"
[ "$(grep -c '^  looks after the first pass:$' "$T/err")" -eq "$(ls "$T/glare"/*_fixed.png | wc -l)" ] ||
  fail "glare frames, no looks: $(cat "$T/err")"
grep -q '^    veil round (veil_looks 8): [0-9]* red squares\{0,1\} no landmark took, [0-9]* windows\{0,1\} looked at' "$T/err" ||
  fail "glare frames, no veil round: $(cat "$T/err")"
# (the landmarks --explain reports are those ld-detect gives without it)
"$BIN/ld-detect" --adaptive "$T/glare"/*_fixed.png 2>/dev/null | sed 's/"detect_ms":[0-9.]*,//' >"$T/plain" ||
  fail "glare frames without --explain: exit $?"
sed 's/"detect_ms":[0-9.]*,//' "$T/out" | cmp -s - "$T/plain" || fail "glare frames: --explain changed the landmarks"
veil_found=$(awk '/^    [a-z]/ { round = $1 " " $2 } round == "veil round" && /^      window .*, tint B [-+][0-9]* G [-+][0-9]* R [-+][0-9]* taken out.*; 1 landmark found($|;)/ { n++ } END { print n + 0 }' "$T/err")
[ "$veil_found" -ge 1 ] || fail "glare frames, no veil window found a landmark: $(cat "$T/err")"
# An unreadable file: one line on stderr, an error object, the others still done, exit 1.
echo "not an image" >"$T/s/broken.png"
set +e; "$BIN/ld-detect" --explain "$T/s" >"$T/out" 2>"$T/err"; rc=$?; set -e
[ $rc -eq 1 ] || fail "broken file: exit $rc"
grep -q 'broken.png: cannot read as an image' "$T/err" || fail "broken file: $(cat "$T/err")"
[ "$(grep -c '"landmarks":\[{' "$T/out")" -eq 2 ] && grep -q '"error":"cannot read as an image"' "$T/out" ||
  fail "broken file, output: $(cat "$T/out")"
# A PNG cut short: one line, with libpng's own words (libpng printed them
# on a line of its own, naming no file).
mkdir "$T/png"; head -c 3000 "$T/s/000000.png" >"$T/png/cut.png"
set +e; "$BIN/ld-detect" "$T/png/cut.png" >"$T/out" 2>"$T/err"; rc=$?; set -e
[ $rc -eq 1 ] && [ "$(wc -l <"$T/err")" -eq 1 ] &&
  grep -q "^ld-detect: $T/png/cut.png: cannot read as an image (libpng error: PNG input buffer is incomplete)$" "$T/err" ||
  fail "PNG cut short: exit $rc: $(cat "$T/err")"
# A calibration of another aspect ratio: no pose, said once on stderr, and the landmarks as ever.
printf '%%YAML:1.0\n---\nimage_width: 1280\nimage_height: 720\ncamera_matrix: !!opencv-matrix\n  rows: 3\n  cols: 3\n  dt: d\n  data: [1200, 0, 639.5, 0, 1200, 359.5, 0, 0, 1]\ndistortion_coefficients: !!opencv-matrix\n  rows: 1\n  cols: 5\n  dt: d\n  data: [0, 0, 0, 0, 0]\n' >"$T/wide.yaml"
"$BIN/ld-detect" --camera "$T/wide.yaml" --size 0.15 "$T/s/000000.png" "$T/s/000001.png" >"$T/out" 2>"$T/err" || fail "wide calibration: exit $?: $(cat "$T/err")"
[ "$(grep -c '"landmarks":\[{' "$T/out")" -eq 2 ] && ! grep -q '"pose"' "$T/out" || fail "wide calibration, output: $(cat "$T/out")"
[ "$(grep -c 'calibration is for 1280x720 images and this frame is 640x480' "$T/err")" -eq 1 ] ||
  fail "wide calibration, stderr: $(cat "$T/err")"
# A phone's portrait photo: stored landscape as the sensor took it, with an
# Exif orientation (6: turn a quarter clockwise; 3: upside down). ld-detect
# reads it turned (as OpenCV does) and turns the sensor's calibration with it
# (here one whose principal point is off the middle, as a real lens's): the
# pose is the stored frame's, turned (a quarter: x' = -y, y' = x; half:
# x' = -x, y' = -y). The portrait one was refused as a calibration of
# another aspect ratio, and the upside-down one's pose was off by the
# principal point's offset, reflected.
"$BIN/ld-synth" scene --out "$T/phone" --seed 4 --count 1 --resolution 1280x720 --distance 0.9 --x 0.1 --y -0.05 \
  --yaw 20 --lighting normal --degrade none --jpg >/dev/null
printf '%%YAML:1.0\n---\nimage_width: 1280\nimage_height: 720\ncamera_matrix: !!opencv-matrix\n  rows: 3\n  cols: 3\n  dt: d\n  data: [1200, 0, 679.5, 0, 1200, 339.5, 0, 0, 1]\ndistortion_coefficients: !!opencv-matrix\n  rows: 1\n  cols: 5\n  dt: d\n  data: [0, 0, 0, 0, 0]\n' >"$T/phone.yaml"
python3 - "$T/phone/000000.jpg" "$T/phone" <<'PY'
import struct, sys
jpeg = open(sys.argv[1], 'rb').read()
assert jpeg[:2] == b'\xff\xd8'
for o in (6, 3):
    ifd = b'II*\x00' + struct.pack('<IH', 8, 1) + struct.pack('<HHIHH', 0x0112, 3, 1, o, 0) + struct.pack('<I', 0)
    app1 = b'Exif\x00\x00' + ifd
    open('%s/turned%d.jpg' % (sys.argv[2], o), 'wb').write(jpeg[:2] + b'\xff\xe1' + struct.pack('>H', len(app1) + 2) + app1 + jpeg[2:])
PY
"$BIN/ld-detect" --camera "$T/phone.yaml" --size 0.15 "$T/phone/000000.jpg" "$T/phone/turned6.jpg" "$T/phone/turned3.jpg" \
  >"$T/out" 2>"$T/err" || fail "Exif-turned photo: exit $?: $(cat "$T/err")"
[ ! -s "$T/err" ] || fail "Exif-turned photo, stderr: $(cat "$T/err")"
python3 - "$T/out" <<'PY' || fail "Exif-turned photo: $(cat "$T/out")"
import json, sys
stored, quarter, half = [json.loads(l) for l in open(sys.argv[1])]
assert (stored['width'], stored['height']) == (1280, 720) and (quarter['width'], quarter['height']) == (720, 1280), (stored, quarter)
a = stored['landmarks'][0]['pose']['t']
for got, want in ((quarter, [-a[1], a[0], a[2]]), (half, [-a[0], -a[1], a[2]])):
    b = got['landmarks'][0]['pose']['t']
    assert all(abs(x - y) < 0.005 for x, y in zip(b, want)), (a, b, want)
assert abs(a[2] - 0.9) < 0.1, a
PY
# Grey images (a monochrome camera's): no landmark can be in them, and that
# is said for the first and counted at the end (nothing was said, even by
# --explain). A colour frame beside them says nothing.
mkdir "$T/grey"
for n in 1 2; do { printf 'P5\n64 48\n255\n'; head -c 3072 /dev/urandom; } >"$T/grey/g$n.pgm"; done
"$BIN/ld-detect" "$T/grey" "$T/s/000000.png" >"$T/out" 2>"$T/err" || fail "grey images: exit $?: $(cat "$T/err")"
[ "$(cat "$T/err")" = "ld-detect: $T/grey/g1.pgm: a grey image (no colour in it): landmarks are found by their blue and red squares, so none can be found in it
ld-detect: 2 grey images in all: no landmark can be found in them" ] || fail "grey images, stderr: $(cat "$T/err")"
# Bytes that are not UTF-8, in a file's name or in a QR's payload, come out
# as U+FFFD in the JSON; the run goes on.
set +e; "$BIN/ld-detect" "$T/s/000000.png" "$T/s/nope"$'\xe9'".png" "$T/s/000001.png" >"$T/out" 2>"$T/err"; rc=$?; set -e
[ $rc -eq 1 ] || fail "non-UTF-8 name: exit $rc: $(cat "$T/err")"
[ "$(grep -c '"landmarks":\[{' "$T/out")" -eq 2 ] && grep -q $'nope\xef\xbf\xbd.png","error":"no such file"' "$T/out" ||
  fail "non-UTF-8 name, output: $(cat "$T/out")"
"$BIN/ld-synth" scene --out "$T/latin1" --seed 2 --count 1 --distance 0.5 --yaw 0 --lighting normal --degrade none \
  --background plain --distractors 0 --payload $'caf\xe9' >/dev/null || fail "ld-synth, Latin-1 payload: exit $?"
grep -q $'"payload":"caf\xef\xbf\xbd"' "$T/latin1/truth.jsonl" || fail "ld-synth truth: $(cat "$T/latin1/truth.jsonl")"
"$BIN/ld-detect" --decode "$T/latin1/000000.png" >"$T/out" 2>"$T/err" || fail "--decode, Latin-1 payload: exit $?: $(cat "$T/err")"
grep -q $'"payload":"caf\xef\xbf\xbd"' "$T/out" || fail "--decode, Latin-1 payload: $(cat "$T/out")"
# The README's parameters file, as printed there (comments after values included), loads.
awk '/^### Parameters/{p=1} p&&/^```yaml/{y=1;next} y&&/^```/{exit} y' "$SRC/README.md" >"$T/readme.yaml"
[ "$(wc -l <"$T/readme.yaml")" -gt 10 ] || fail "no YAML block under the README's Parameters"
"$BIN/ld-detect" --params "$T/readme.yaml" "$T/s/000000.png" >/dev/null 2>"$T/err" || fail "README's YAML: $(cat "$T/err")"
# A bad value names the file, the key and the value.
printf 'front_end: papr   # typo\n' >"$T/typo.yaml"
set +e; "$BIN/ld-detect" --params "$T/typo.yaml" "$T/s/000000.png" >/dev/null 2>"$T/err"; rc=$?; set -e
[ $rc -eq 2 ] && [ "$(wc -l <"$T/err")" -eq 1 ] || fail "typo: exit $rc, $(cat "$T/err")"
grep -q "typo.yaml: front_end must be \"fast\" or \"paper\", not \"papr\"" "$T/err" || fail "typo: $(cat "$T/err")"
# Overlays: one per image, same-named images of two folders included (the second gets -2).
mkdir -p "$T/other"; cp "$T/s/000000.png" "$T/other/000000.png"
"$BIN/ld-detect" --draw "$T/ov" "$T/s/000000.png" "$T/other" >/dev/null
[ -s "$T/ov/000000.png" ] && [ -s "$T/ov/000000-2.png" ] || fail "overlays: $(ls "$T/ov")"
# One line each, naming what is wrong: a missing file, --size 0, --size without --camera (and the
# other way round), an unwritable -o or --draw.
set +e; "$BIN/ld-detect" "$T/nothere.png" >"$T/out" 2>"$T/err"; rc=$?; set -e
[ $rc -eq 1 ] && [ "$(cat "$T/err")" = "ld-detect: $T/nothere.png: no such file" ] || fail "missing: $rc $(cat "$T/err")"
for args in "--size 0|ld-detect: --size: must be in [0.01, 10], not 0 (--help lists the options)" \
            "--size 1e9|ld-detect: --size: must be in [0.01, 10], not 1e9 (--help lists the options)" \
            "--size 0.15|ld-detect: --size requires --camera (--help lists the options)" \
            "--camera $T/cam.yaml|ld-detect: --camera requires --size (--help lists the options)" \
            "-o /proc/no/such.jsonl|ld-detect: cannot write /proc/no/such.jsonl: cannot create folder /proc/no: No such file or directory" \
            "--draw /proc/no/such|ld-detect: --draw: cannot create folder /proc/no/such: No such file or directory"; do
  set +e; "$BIN/ld-detect" ${args%%|*} "$T/s/000000.png" >/dev/null 2>"$T/err"; rc=$?; set -e
  [ $rc -eq 2 ] && [ "$(cat "$T/err")" = "${args#*|}" ] || fail "${args%%|*}: exit $rc, $(cat "$T/err")"
done
# a misspelt option is named, not the option it left without its partner
set +e; "$BIN/ld-detect" --size 0.15 --camra "$T/cam.yaml" "$T/s/000000.png" >/dev/null 2>"$T/err"; rc=$?; set -e
[ $rc -eq 2 ] && grep -qF "The following argument was not expected: --camra" "$T/err" || fail "--camra: exit $rc, $(cat "$T/err")"
set +e; "$BIN/ld-detect" --draw "" "$T/s/000000.png" >/dev/null 2>"$T/err"; rc=$?; set -e
[ $rc -eq 2 ] && [ "$(cat "$T/err")" = 'ld-detect: --draw needs a path, not "" (--help lists the options)' ] || fail "--draw '': exit $rc, $(cat "$T/err")"
# an option left without its value does not take the next option as it:
# `--draw --decode` wrote overlays into a folder named "--decode"
(cd "$T" && set +e && "$BIN/ld-detect" --draw --decode s/000000.png >/dev/null 2>"$T/err"; echo $? >"$T/rc")
[ "$(cat "$T/rc")" -eq 2 ] && [ "$(cat "$T/err")" = 'ld-detect: --draw needs a value, and the word after it is the option --decode (to give --draw that word, write --draw=--decode) (--help lists the options)' ] ||
  fail "--draw --decode: exit $(cat "$T/rc"), $(cat "$T/err")"
[ ! -e "$T/--decode" ] || fail "--draw --decode made a folder named --decode"
set +e; "$BIN/ld-detect" -o --summary "$T/s/000000.png" >/dev/null 2>"$T/err"; rc=$?; set -e
[ $rc -eq 2 ] && grep -qF -- "-o needs a value, and the word after it is the option --summary (to give -o that word, write --output=--summary)" "$T/err" ||
  fail "-o --summary: exit $rc, $(cat "$T/err")"
# ... nor one whose CLI11 error would hide it ("--size: '--camera' is not a number")
set +e; "$BIN/ld-detect" --size --camera "$T/cam.yaml" "$T/s/000000.png" >/dev/null 2>"$T/err"; rc=$?; set -e
[ $rc -eq 2 ] && grep -qF -- "--size needs a value, and the word after it is the option --camera" "$T/err" ||
  fail "--size --camera: exit $rc, $(cat "$T/err")"
# a negative number is a value, not an option
"$BIN/ld-synth" scene --out "$T/neg" --count 1 --seed 3 --x -0.05:-0.01 >/dev/null || fail "--x -0.05:-0.01 refused"
# What it writes is never what it reads: -o naming an input, --draw into an
# input's folder (an overlay would take an input's name) are refused, the
# inputs untouched.
mkdir -p "$T/keep"; cp "$T/s/000000.png" "$T/s/000001.png" "$T/keep/"
sum=$(md5sum "$T/keep/"*.png)
set +e; "$BIN/ld-detect" "$T/keep/000000.png" -o "$T/keep/000000.png" >/dev/null 2>"$T/err"; rc=$?; set -e
[ $rc -eq 2 ] && grep -q "is one of the input images: it would be emptied" "$T/err" || fail "-o = input: exit $rc, $(cat "$T/err")"
set +e; "$BIN/ld-detect" "$T/keep" --draw "$T/keep" >/dev/null 2>"$T/err"; rc=$?; set -e
[ $rc -eq 2 ] && grep -q "would write its overlay over the input $T/keep/000000.png" "$T/err" || fail "--draw = input folder: exit $rc, $(cat "$T/err")"
[ "$(md5sum "$T/keep/"*.png)" = "$sum" ] || fail "the inputs changed"
# nor one output the other: -o as an overlay's name (its JSON was written
# over the overlay), or as the --draw folder itself (the folder was made,
# then the file refused)
set +e; "$BIN/ld-detect" "$T/keep" --draw "$T/ov2" -o "$T/ov2/000001.png" >/dev/null 2>"$T/err"; rc=$?; set -e
[ $rc -eq 2 ] && grep -q "^ld-detect: -o $T/ov2/000001.png is the name of an overlay --draw writes ($T/ov2/000001.png): it would be written over" "$T/err" &&
  [ ! -e "$T/ov2" ] || fail "-o = an overlay: exit $rc, $(cat "$T/err")"
set +e; "$BIN/ld-detect" "$T/keep" --draw "$T/ov2" -o "$T/ov2" >/dev/null 2>"$T/err"; rc=$?; set -e
[ $rc -eq 2 ] && grep -q "^ld-detect: -o $T/ov2 is the --draw folder: name a file" "$T/err" && [ ! -e "$T/ov2" ] ||
  fail "-o = the --draw folder: exit $rc, $(cat "$T/err")"
# --summary even when no image could be read, counted in the singular where one.
echo "not an image" >"$T/bad.png"
set +e; "$BIN/ld-detect" "$T/bad.png" --summary >/dev/null 2>"$T/err"; rc=$?; set -e
[ $rc -eq 1 ] && grep -q "^ld-detect: 0 images, 0 with landmarks, 0 landmarks; 1 unreadable; backend" "$T/err" || fail "summary of none: $(cat "$T/err")"
"$BIN/ld-detect" "$T/s/000000.png" --summary >/dev/null 2>"$T/err"
grep -q "^ld-detect: 1 image, 1 with landmarks, 1 landmark, 1.00 per image" "$T/err" || fail "summary of one: $(cat "$T/err")"
# A JPEG cut short is no image (OpenCV read it as grey rows, exit 0); a link
# in a folder whose file is gone is named, not skipped without a word
"$BIN/ld-synth" scene --out "$T/j" --count 1 --jpg >/dev/null
head -c 20000 "$T/j/000000.jpg" >"$T/j/cut.jpg"
ln -s "$T/gone.png" "$T/j/gone.png"
set +e; "$BIN/ld-detect" "$T/j" >"$T/out" 2>"$T/err"; rc=$?; set -e
[ $rc -eq 1 ] && grep -q "cut.jpg: cannot read as an image: it is a JPEG cut short (no end-of-image marker)$" "$T/err" &&
  grep -q "gone.png: no such file$" "$T/err" && [ "$(wc -l <"$T/out")" -eq 3 ] ||
  fail "cut JPEG, broken link: exit $rc, $(cat "$T/err")"
# -o naming a folder (a trailing /): refused, no folder made
set +e; "$BIN/ld-detect" "$T/s/000000.png" -o "$T/newdir/" >/dev/null 2>"$T/err"; rc=$?; set -e
[ $rc -eq 2 ] && grep -q "^ld-detect: cannot write $T/newdir/: names a folder (it ends in /), not a file$" "$T/err" &&
  [ ! -e "$T/newdir" ] || fail "-o DIR/: exit $rc, $(cat "$T/err")"
# results that cannot be written all (a full disk): status 1, said, to a file or stdout
# no input, or a folder without images: said so, naming the folder ("inputs
# is required", "no image files found" before)
set +e; "$BIN/ld-detect" >/dev/null 2>"$T/err"; rc=$?; set -e
[ $rc -eq 2 ] && grep -q "^ld-detect: no input: give image files or folders" "$T/err" || { echo "FAIL: no input: $rc $(cat "$T/err")"; exit 1; }
mkdir -p "$T/noimages"; touch "$T/noimages/notes.txt"
set +e; "$BIN/ld-detect" "$T/noimages" >/dev/null 2>"$T/err"; rc=$?; set -e
[ $rc -eq 2 ] && grep -q "^ld-detect: no image files in $T/noimages (folders are searched for .png" "$T/err" ||
  { echo "FAIL: a folder without images: $rc $(cat "$T/err")"; exit 1; }
# ... even beside an image (it was passed over without a word), before anything is read
set +e; "$BIN/ld-detect" "$T/s/000000.png" "$T/noimages" >"$T/out" 2>"$T/err"; rc=$?; set -e
[ $rc -eq 2 ] && [ "$(grep -c "^ld-detect: no image files in $T/noimages (folders" "$T/err")" -eq 1 ] && [ ! -s "$T/out" ] ||
  { echo "FAIL: a folder without images beside an image: $rc $(cat "$T/err")"; exit 1; }
# -o naming the parameters or calibration it reads: refused, left as it was
printf '%%YAML:1.0\n---\nsecond_looks: 1\n' >"$T/params.yaml"; cp "$T/params.yaml" "$T/params.keep"
set +e; "$BIN/ld-detect" "$T/s/000000.png" --params "$T/params.yaml" -o "$T/../$(basename "$T")/params.yaml" >/dev/null 2>"$T/err"; rc=$?; set -e
[ $rc -eq 2 ] && grep -q "is the --params file: it would be written over" "$T/err" && cmp -s "$T/params.yaml" "$T/params.keep" ||
  { echo "FAIL: -o over --params: $rc $(cat "$T/err")"; exit 1; }
for out in "-o /dev/full" ""; do
  set +e; "$BIN/ld-detect" "$T/s/000000.png" $out >/dev/full 2>"$T/err"; rc=$?; set -e
  [ $rc -eq 1 ] && grep -q "^ld-detect: write to .* failed: No space left on device" "$T/err" ||
    fail "full disk ($out): exit $rc, $(cat "$T/err")"
done
# --draw on a full disk: said once, no cut or empty overlay left, the rest
# not drawn but counted, status 1 (a line for every frame, each leaving an
# empty or cut PNG)
rc=0
timeout 60 unshare -rm bash -c 'mkdir -p "$1/tiny" && mount -t tmpfs -o size=64k none "$1/tiny" &&
  "$2/ld-detect" "$1/s" --draw "$1/tiny/draw" >/dev/null 2>"$1/err"' _ "$T" "$BIN" || rc=$?
[ $rc -eq 1 ] && [ "$(grep -c "cannot write .*: No space left on device; the overlays after it are not drawn" "$T/err")" -eq 1 ] &&
  [ "$(grep -c "cannot write" "$T/err")" -eq 1 ] ||
  fail "--draw on a full disk: exit $rc, $(cat "$T/err")"
# Files that are no images in a folder: a loop of links (ld-detect aborted
# on it) and a pipe (it blocked the run for ever), each said in one line,
# the folder's image still read; a pipe named alone likewise.
mkdir -p "$T/odd"; cp "$T/s/000000.png" "$T/odd/good.png"
ln -s l2.png "$T/odd/l1.png"; ln -s l1.png "$T/odd/l2.png"; mkfifo "$T/odd/cam.png"
set +e; timeout 60 "$BIN/ld-detect" "$T/odd" "$T/odd/cam.png" >"$T/out" 2>"$T/err"; rc=$?; set -e
[ $rc -eq 1 ] && [ "$(grep -c '"landmarks"' "$T/out")" -eq 1 ] &&
  [ "$(grep -c "^ld-detect: $T/odd/l[12].png: is a loop of symbolic links$" "$T/err")" -eq 2 ] &&
  [ "$(grep -c "^ld-detect: $T/odd/cam.png: is not a file (a pipe, a device?)$" "$T/err")" -eq 2 ] ||
  fail "a loop of links and a pipe: exit $rc, $(cat "$T/err")"
# -o naming a hard link of an input: refused, the image left as it was
ln "$T/odd/good.png" "$T/odd/hard.jsonl"
set +e; "$BIN/ld-detect" "$T/odd/good.png" -o "$T/odd/hard.jsonl" >/dev/null 2>"$T/err"; rc=$?; set -e
[ $rc -eq 2 ] && grep -q "^ld-detect: -o $T/odd/hard.jsonl is one of the input images: it would be emptied" "$T/err" &&
  cmp -s "$T/odd/good.png" "$T/s/000000.png" || fail "-o a hard link of an input: exit $rc, $(cat "$T/err")"
# an overlay that cannot be written: said with why, status 1
mkdir -p "$T/draw/000000.png"
set +e; "$BIN/ld-detect" "$T/s/000000.png" --draw "$T/draw" >/dev/null 2>"$T/err"; rc=$?; set -e
[ $rc -eq 1 ] && grep -q "^ld-detect: cannot write $T/draw/000000.png: Is a directory$" "$T/err" ||
  fail "an overlay not written: exit $rc, $(cat "$T/err")"
echo "ld-detect command line: ok"
