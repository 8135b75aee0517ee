#!/usr/bin/env bash
# ld-synth's command line: --ecc draws the codes at the level asked for (auto as
# ld-generate picks it), frames at close range read back to their payload, the
# same seed gives the same bytes, and bad options are refused with one line.
# usage: synth_cli_test.sh BIN_DIR
set -euo pipefail
BIN=$(cd "$1" && pwd)
T=$(mktemp -d); trap 'rm -rf "$T"' EXIT
fail() { echo "FAIL: $*" >&2; exit 1; }

scene() {  # OUT PAYLOAD ECC
  "$BIN/ld-synth" scene --out "$T/$1" --seed 5 --count 1 --distance 0.35 --yaw 10 --roll 0 --x 0 --y 0 \
    --lighting normal --degrade none -p "$2" --ecc "$3" >/dev/null
}
long=$(printf 'ld-synth/%.0s0123456789' 1 2 3 4 5 6 7 8 9 | head -c 100)
[ ${#long} -eq 100 ] || fail "payload of ${#long} bytes"
# 100 bytes: the smallest symbol is level L's, so auto is L; H is another picture.
scene long-auto "$long" auto
scene long-L "$long" L
scene long-H "$long" h
cmp -s "$T/long-auto/000000.png" "$T/long-L/000000.png" || fail "100 bytes: auto differs from L"
cmp -s "$T/long-auto/000000.png" "$T/long-H/000000.png" && fail "100 bytes: --ecc H drew the same code as L"
# 4 bytes: H still fits the smallest symbol, so auto is H.
scene short-auto dock auto
scene short-H dock H
scene short-L dock L
cmp -s "$T/short-auto/000000.png" "$T/short-H/000000.png" || fail "4 bytes: auto differs from H"
cmp -s "$T/short-auto/000000.png" "$T/short-L/000000.png" && fail "4 bytes: --ecc L drew the same code as H"
# Each code reads back to its payload from the frame.
for d in long-auto long-H short-L; do
  want=$([ "${d%%-*}" = long ] && echo "$long" || echo dock)
  got=$("$BIN/ld-detect" --decode "$T/$d/000000.png" | sed -n 's/.*"payload": *"\([^"]*\)".*/\1/p')
  [ "$got" = "$want" ] || fail "$d reads '$got'"
done
# A sequence takes the level too: the same drive with a 100-byte code at
# auto draws L's code, at H another.
seq() {  # OUT ECC
  "$BIN/ld-synth" sequence --out "$T/$1" --frames 24 --landmarks 1 --seed 4 -p "$long" --ecc "$2" >/dev/null
}
seq seq-auto auto
seq seq-L L
seq seq-H H
diff -rq "$T/seq-auto" "$T/seq-L" >/dev/null || fail "sequence: auto differs from L"
diff -rq "$T/seq-auto" "$T/seq-H" >/dev/null && fail "sequence: --ecc H drew the same frames as L"

# Refused with one line naming the option, exit status 2.
refused() {  # PATTERN ARGS...
  local pat=$1; shift
  set +e; "$BIN/ld-synth" "$@" >/dev/null 2>"$T/err"; local rc=$?; set -e
  [ $rc -eq 2 ] || fail "ld-synth $* exited $rc"
  [ "$(wc -l <"$T/err")" -eq 1 ] && grep -q -- "$pat" "$T/err" || fail "ld-synth $*: $(cat "$T/err")"
}
refused "--ecc: QR error correction must be auto, L, M, Q or H, not 'X'" scene --out "$T/x" --ecc X
# a misspelt subcommand is named ("A subcommand is required")
refused "'scenes' is no subcommand (scene, sequence)" scenes --out "$T/x"
refused "--ecc: QR error correction" sequence --out "$T/x" --ecc 7
# --write-camera: the camera the frames were rendered with, which gives
# ld-detect the truth's pose (an integrator wrote one by hand); never over
# an input or another output of the run
"$BIN/ld-synth" scene --out "$T/cam" --count 1 --size 0.3 --distance 1 --frame-size 320x240 \
  --write-camera "$T/cam.yaml" >"$T/out" || fail "--write-camera: exit $?"
grep -q "^camera (320x240, f = 300 px) written to $T/cam.yaml$" "$T/out" || fail "--write-camera: $(cat "$T/out")"
"$BIN/ld-detect" --camera "$T/cam.yaml" --size 0.3 "$T/cam/000000.png" >"$T/det.jsonl" || fail "ld-detect with the written camera"
d=$(grep -o '"distance":[0-9.]*' "$T/det.jsonl" | cut -d: -f2)
t=$(grep -o '"distance":[0-9.]*' "$T/cam/truth.jsonl" | cut -d: -f2)
awk -v d="$d" -v t="$t" 'BEGIN { exit !(d > 0 && (d - t) / t < 0.02 && (t - d) / t < 0.02) }' ||
  fail "pose from the written camera: $d m against the truth's $t m"
refused "--write-camera $T/x/truth.jsonl is a file this run writes in --out $T/x" scene --out "$T/x" --write-camera "$T/x/truth.jsonl"
refused "--write-camera $T/cam.yaml is the --camera file this run reads" scene --out "$T/x" --camera "$T/cam.yaml" --write-camera "$T/cam.yaml"
refused "--write-camera $T/q.lcmlog is the --log file" sequence --out "$T/x" --log "$T/q.lcmlog" --write-camera "$T/q.lcmlog"

# an option's value is not the next option, in a subcommand too
refused "--seed needs a value, and the word after it is the option --out (to give --seed that word, write --seed=--out)" \
  sequence --seed --out "$T/x"
refused "--yaw must lie within -89.9:89.9 (--help lists the options)" scene --out "$T/x" --yaw 95
refused "--quality: must be in \[1, 100\], not 500" sequence --out "$T/x" --quality 500
refused "--count must be at least 1" scene --out "$T/x" --count 0
refused "--lighting must be" scene --out "$T/x" --lighting sunset
refused "--jpeg must lie within 0:100" scene --out "$T/x" --jpeg 150
refused "--jpeg: a whole quality 0..100, not '1.5'" scene --out "$T/x" --jpeg 1.5
refused "--defocus must lie within 0:50" scene --out "$T/x" --defocus -1
refused "--motion must lie within 0:200" scene --out "$T/x" --motion 1e6
refused "--noise must lie within 0:100" scene --out "$T/x" --noise -3
refused "--resolution: 7x5 is out of 16x16 .. 16384x16384" scene --out "$T/x" --resolution 7x5
# a calibration scaled to another aspect ratio would lie (the detector refuses it too); the same one does
printf '%%YAML:1.0\n---\nimage_width: 1280\nimage_height: 720\ncamera_matrix: !!opencv-matrix\n  rows: 3\n  cols: 3\n  dt: d\n  data: [1200, 0, 639.5, 0, 1200, 359.5, 0, 0, 1]\ndistortion_coefficients: !!opencv-matrix\n  rows: 1\n  cols: 5\n  dt: d\n  data: [0, 0, 0, 0, 0]\n' >"$T/wide.yaml"
refused "--resolution: 640x480 is another aspect ratio than the camera file's 1280x720" scene --out "$T/x" --camera "$T/wide.yaml" --resolution 640x480
refused "--resolution: 640x480 is another aspect ratio" sequence --out "$T/x" --camera "$T/wide.yaml" --resolution 640x480
"$BIN/ld-synth" scene --out "$T/half" --camera "$T/wide.yaml" --resolution 640x360 --count 1 >/dev/null ||
  fail "the same aspect ratio, scaled, was refused"
size=$(od -An -tx1 -j16 -N8 "$T/half/000000.png" | tr -d ' \n')  # the PNG's width and height
[ "$size" = 0000028000000168 ] || fail "scaled frame: not 640x360 ($size)"
# the names other programs use: --frame-size (ld-camera's) for --resolution,
# --frames / --count for either subcommand's number of frames
"$BIN/ld-synth" scene --out "$T/alias" --frame-size 320x240 --frames 2 >/dev/null || fail "scene --frame-size --frames refused"
[ "$(ls "$T/alias"/*.png | wc -l)" -eq 2 ] || fail "scene --frames 2: $(ls "$T/alias")"
[ "$(od -An -tx1 -j16 -N8 "$T/alias/000000.png" | tr -d ' \n')" = 00000140000000f0 ] || fail "--frame-size 320x240: not so"
"$BIN/ld-synth" sequence --out "$T/aliasq" --frame-size 320x240 --count 2 >/dev/null || fail "sequence --count refused"
[ "$(ls "$T/aliasq"/*.png | wc -l)" -eq 2 ] || fail "sequence --count 2: $(ls "$T/aliasq")"
refused "--fps: must be in \[0.1, 1000\], not 0 (--help lists the options)" sequence --out "$T/x" --fps 0
refused "--size: must be in \[0.01, 2\], not 0" sequence --out "$T/x" --size 0
refused "--channel: an empty channel name" sequence --log "$T/x.lcmlog" --channel ""
refused "--format: unknown pixel format 'nv12'" sequence --log "$T/x.lcmlog" --format nv12
# A log is never written over a file that is not one (an image a user meant
# as input), and it is checked before anything is written: no frames, no
# truth.jsonl. A log's missing folder is created.
cp "$T/half/000000.png" "$T/image.png"
refused "--log $T/image.png is not an LCM log (it starts with 89 50 4e 47" sequence --out "$T/y" --log "$T/image.png"
[ ! -e "$T/y" ] && cmp -s "$T/image.png" "$T/half/000000.png" || fail "a refused --log wrote something"
"$BIN/ld-synth" sequence -n 2 --log "$T/new/folder/s.lcmlog" >"$T/out" || fail "--log in a new folder"
grep -q "^wrote 2 frames to $T/new/folder/s.lcmlog (bgr)" "$T/out" || fail "$(cat "$T/out")"
[ -z "$(ls -A "$T/new/folder" | grep -v '^s.lcmlog$')" ] || fail "left behind: $(ls -A "$T/new/folder")"
# Frames of an earlier, longer run left in the folder are said in a note.
"$BIN/ld-synth" sequence --out "$T/seq" -n 4 >/dev/null
"$BIN/ld-synth" sequence --out "$T/seq" -n 1 >"$T/out" 2>"$T/err"
grep -q "^wrote 1 frame to $T/seq;" "$T/out" || fail "$(cat "$T/out")"
grep -q "^ld-synth: note: 3 frames of an earlier run are left in $T/seq (truth.jsonl lists this run's 1)$" "$T/err" ||
  fail "leftover frames: $(cat "$T/err")"
"$BIN/ld-synth" scene --out "$T/seq" --count 4 --jpg >/dev/null 2>"$T/err"
grep -q "note: 4 frames of an earlier run are left in $T/seq (truth.jsonl lists this run's 4)" "$T/err" ||
  fail "leftover PNGs beside JPEGs: $(cat "$T/err")"
# --no-png: the truth names frames this run did not write; those there are an earlier run's
"$BIN/ld-synth" sequence --out "$T/seq" -n 2 --no-png >/dev/null 2>"$T/err"
grep -q "note: 4 frames of an earlier run are left in $T/seq: truth.jsonl names frames that this run did not write (--no-png)" "$T/err" ||
  fail "--no-png beside frames: $(cat "$T/err")"
refused "--frames: must be in \[1, 100000\], not 0" sequence --out "$T/x" --frames 0
# Seeds as written (-1 and 2^64 were taken as 2^64-1), times of 0 or more,
# a payload of a byte or more (scene took "" for room-101).
refused "--seed: must be a whole number 0 or more, not -1" scene --out "$T/x" --seed -1
refused "--seed: must be under 2^64, not 18446744073709551616" sequence --out "$T/x" --seed 18446744073709551616
refused "--start-utime: must be whole microseconds, 0 or more, not -5" sequence --out "$T/x" --start-utime -5
refused "--start-utime: must be at most 2^62 (4611686018427387904), not 9223372036854775807" sequence --out "$T/x" --start-utime 9223372036854775807
refused "--start-utime: must be at most 2^62 (4611686018427387904), not 99999999999999999999" sequence --out "$T/x" --start-utime 99999999999999999999
refused "--payload: an empty payload" scene --out "$T/x" -p ""
refused "camera file $T/none.yml: cannot open: No such file or directory" scene --out "$T/x" --camera "$T/none.yml"
# Refused before anything is written: a YUYV/UYVY log of odd width, and a
# log over a file the run writes in --out (it replaced truth.jsonl, status 0).
refused "--format uyvy needs an even width, and the frames are 641 px wide" sequence --out "$T/odd" --log "$T/odd.lcmlog" --format uyvy --resolution 641x480 -n 2
[ ! -e "$T/odd" ] || fail "odd width: $(ls "$T/odd")"
refused "--format mjpeg takes 33554432 pixels a frame at most, and the frames are 8192x6144" sequence --out "$T/big" --log "$T/big.lcmlog" --format mjpeg --resolution 8192x6144 -n 2
[ ! -e "$T/big" ] || fail "too big for mjpeg: $(ls "$T/big")"
refused "--log $T/own/truth.jsonl is a file this run writes in --out $T/own" sequence --out "$T/own" --log "$T/own/truth.jsonl" -n 2
refused "--log $T/own/000001.png is a file this run writes in --out $T/own" sequence --out "$T/own" --log "$T/own/000001.png" -n 2
# ... and the calibration it reads in --out under a name it writes (the truth
# or a frame replaced it)
printf '%%YAML:1.0\n---\nimage_width: 640\nimage_height: 480\ncamera_matrix: !!opencv-matrix\n  rows: 3\n  cols: 3\n  dt: d\n  data: [600, 0, 319.5, 0, 600, 239.5, 0, 0, 1]\n' >"$T/cam.yaml"
mkdir -p "$T/own3"; cp "$T/cam.yaml" "$T/own3/truth.jsonl"; cp "$T/cam.yaml" "$T/own3/000000.png"
refused "--camera $T/own3/truth.jsonl is a file this run writes in --out $T/own3: it would be written over" scene --out "$T/own3" --camera "$T/own3/truth.jsonl"
refused "--camera $T/own3/000000.png is a file this run writes in --out $T/own3: it would be written over" sequence --out "$T/own3" --camera "$T/own3/000000.png" -n 2
cmp -s "$T/cam.yaml" "$T/own3/truth.jsonl" && cmp -s "$T/cam.yaml" "$T/own3/000000.png" || fail "--camera in --out: written over"
# (a folder named with a trailing slash, not there yet, was not its own name)
refused "--log $T/own2/truth.jsonl is a file this run writes in --out $T/own2/" sequence --out "$T/own2/" --log "$T/own2/truth.jsonl" -n 2
# Landmarks that cannot be placed apart are refused, not drawn over each
# other (the one hidden was in the truth as in view); 20 of them with the
# default options are placed (a landmark with no room left beside those
# placed before it starts the frame over: one seed in 15 was refused).
refused "frame 0: landmark 2 of 2 overlapped another in each of 200 poses drawn, 20 times over: ask for fewer landmarks, or give them room" scene --out "$T/ov" -k 2 --x 0 --y 0
refused "landmark [0-9]* of 6 overlapped another" scene --out "$T/ov6" -k 6 --distance 0.4
# A refused run leaves an earlier run's frames and truth as they were (it emptied truth.jsonl):
# landmarks with no room, a payload no QR code holds (scene and sequence)
"$BIN/ld-synth" scene --out "$T/kept" -n 2 >/dev/null
"$BIN/ld-synth" sequence --out "$T/kept2" -n 2 --no-png >/dev/null
cp "$T/kept/truth.jsonl" "$T/kept.truth"; cp "$T/kept2/truth.jsonl" "$T/kept2.truth"
long=$(head -c 3000 /dev/zero | tr '\0' a)
refused "frame 0: landmark 2 of 2 overlapped another" scene --out "$T/kept" -n 2 -k 2 --x 0 --y 0
refused "QR payload of 3000 bytes cannot be encoded" scene --out "$T/kept" -n 1 -p "$long"
refused "QR payload of 3000 bytes cannot be encoded" sequence --out "$T/kept2" -n 1 -k 1 -p "$long"
cmp -s "$T/kept/truth.jsonl" "$T/kept.truth" && cmp -s "$T/kept2/truth.jsonl" "$T/kept2.truth" ||
  fail "a refused run changed an earlier run's truth.jsonl"
"$BIN/ld-synth" scene --out "$T/k20" -n 110 -k 20 --seed 5 --degrade none >/dev/null || fail "-k 20, seed 5: exit $?"
# The whole range of --landmarks (91 to 100 failed in OpenCV's remap: the wall's texture was too wide).
"$BIN/ld-synth" sequence --out "$T/k100" -n 1 -k 100 --no-png >/dev/null || fail "-k 100: exit $?"
# A truth that cannot be written all (a full disk): said with why, status 2
# (scene said "wrote 2 frames" over an empty truth.jsonl, status 0)
mkdir -p "$T/full" && ln -s /dev/full "$T/full/truth.jsonl"
rc=0; "$BIN/ld-synth" scene --out "$T/full" -n 2 >"$T/out" 2>"$T/err" || rc=$?
[ $rc -eq 2 ] && grep -q "^ld-synth: write to $T/full/truth.jsonl failed: No space left on device" "$T/err" ||
  fail "scene, truth on a full disk: exit $rc, $(cat "$T/err") $(cat "$T/out")"
echo "ld-synth command line: ok"
