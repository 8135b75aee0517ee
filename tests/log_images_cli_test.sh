#!/usr/bin/env bash
# ld-log-images' command line: a folder (unreadable files skipped and
# counted), a single image, a video whole and cut short (a note), an odd
# width in YUYV (cropped, a note), refusals with one line, and no empty log
# left behind when nothing could be read.
# usage: log_images_cli_test.sh BIN_DIR
set -euo pipefail
BIN=$(cd "$1" && pwd)
T=$(mktemp -d); trap 'rm -rf "$T"' EXIT
fail() { echo "FAIL: $*" >&2; exit 1; }

"$BIN/ld-synth" scene --out "$T/f" --count 2 --seed 3 >/dev/null
echo "not an image" >"$T/f/000002.png"
"$BIN/ld-log-images" "$T/f" "$T/a.lcmlog" --fps 10 >"$T/out" 2>"$T/err"
grep -q "wrote 2 frames to $T/a.lcmlog (mjpeg, 10 fps), 1 unreadable skipped" "$T/out" || fail "folder: $(cat "$T/out")"
grep -q "000002.png: cannot read as an image, skipped" "$T/err" || fail "folder, skipped: $(cat "$T/err")"
[ "$("$BIN/ld-dump" "$T/a.lcmlog" -c IMAGE | wc -l)" -eq 2 ] || fail "the log does not hold 2 images"
# a link whose file is gone, a loop of links and a pipe with images' names:
# each named and counted (they were passed over without a word)
mkdir "$T/odd"; cp "$T/f/000000.png" "$T/odd/"; ln -s "$T/gone.png" "$T/odd/gone.png"
ln -s "$T/odd/loop.png" "$T/odd/loop.png"; mkfifo "$T/odd/pipe.png"
timeout 20 "$BIN/ld-log-images" "$T/odd" "$T/odd.lcmlog" >"$T/out" 2>"$T/err" || fail "odd entries: exit $?"
grep -q "wrote 1 frame to $T/odd.lcmlog (mjpeg, 30 fps), 3 unreadable skipped" "$T/out" &&
  grep -q "gone.png: no such file, skipped$" "$T/err" && grep -q "loop.png: is a loop of symbolic links, skipped$" "$T/err" &&
  grep -q "pipe.png: is not a file (a pipe, a device?), skipped$" "$T/err" || fail "odd entries: $(cat "$T/out" "$T/err")"
"$BIN/ld-log-images" "$T/f/000001.png" "$T/one.lcmlog" --format bgr >"$T/out"
grep -q "wrote 1 frame to" "$T/out" || fail "one image: $(cat "$T/out")"
# A video (MJPG .avi, written by ld-view from the first log): every frame.
"$BIN/ld-view" --log "$T/a.lcmlog" --all --video "$T/v.avi" >/dev/null 2>&1 || fail "ld-view --video"
"$BIN/ld-log-images" "$T/v.avi" "$T/v.lcmlog" >"$T/out" 2>"$T/err" || fail "video: $(cat "$T/err")"
grep -q "wrote 2 frames to $T/v.lcmlog" "$T/out" || fail "video: $(cat "$T/out")"
# A video cut short: the frames before the cut, and a note saying how far it got.
"$BIN/ld-synth" scene --out "$T/t" --count 10 --seed 3 >/dev/null
"$BIN/ld-log-images" "$T/t" "$T/t.lcmlog" >/dev/null
"$BIN/ld-view" --log "$T/t.lcmlog" --all --video "$T/t.avi" >/dev/null 2>&1 || fail "ld-view --video, 10 frames"
head -c $(( $(stat -c %s "$T/t.avi") / 2 )) "$T/t.avi" >"$T/cut.avi"
"$BIN/ld-log-images" "$T/cut.avi" "$T/cut.lcmlog" >"$T/out" 2>"$T/err" || fail "cut video: exit $?, $(cat "$T/err")"
grep -q "note: $T/cut.avi says it holds 10 frames and [1-9] could be read (a file cut short or damaged?)" "$T/err" ||
  fail "cut video, no note: $(cat "$T/err")"
"$BIN/ld-log-images" "$T/t.avi" "$T/whole.lcmlog" >"$T/out" 2>"$T/err" || fail "whole video"
grep -q "wrote 10 frames" "$T/out" && ! grep -q "note:" "$T/err" || fail "whole video: $(cat "$T/out") $(cat "$T/err")"
# A video is stamped by its own clock (a 10 frames/s video was stamped at
# 30): frames 100 ms apart; --fps overrides it.
"$BIN/ld-view" --log "$T/t.lcmlog" --all --video "$T/t10.avi" --fps 10 >/dev/null 2>&1 || fail "ld-view --video --fps 10"
"$BIN/ld-log-images" "$T/t10.avi" "$T/t10.lcmlog" --start-utime 1000000 >"$T/out" 2>"$T/err" || fail "10 fps video"
grep -q "wrote 10 frames to $T/t10.lcmlog (mjpeg, the video's own timestamps, 10 fps)" "$T/out" ||
  fail "10 fps video: $(cat "$T/out") $(cat "$T/err")"
[ "$("$BIN/ld-dump" "$T/t10.lcmlog" -c IMAGE | grep -o '"utime":[0-9]*' | tr '\n' ' ')" = \
  '"utime":1000000 "utime":1100000 "utime":1200000 "utime":1300000 "utime":1400000 "utime":1500000 "utime":1600000 "utime":1700000 "utime":1800000 "utime":1900000 ' ] ||
  fail "10 fps video, utimes: $("$BIN/ld-dump" "$T/t10.lcmlog" -c IMAGE | grep -o '"utime":[0-9]*' | tr '\n' ' ')"
"$BIN/ld-log-images" "$T/t10.avi" "$T/t25.lcmlog" --start-utime 1000000 --fps 25 >"$T/out" || fail "--fps 25"
grep -q "(mjpeg, 25 fps)" "$T/out" && "$BIN/ld-dump" "$T/t25.lcmlog" -c IMAGE | grep -q '"utime":1040000' ||
  fail "--fps 25: $(cat "$T/out")"
# Files of image kinds OpenCV does not read (a phone's HEIC) are named in a
# note (they were passed over without a word); a HEIC given alone is named.
mkdir "$T/phone"; cp "$T/f/000000.png" "$T/phone/IMG_0002.png"
printf '\0\0\0\030ftypheic\0\0\0\0mif1heic' >"$T/phone/IMG_0001.HEIC"
"$BIN/ld-log-images" "$T/phone" "$T/phone.lcmlog" >"$T/out" 2>"$T/err" || fail "HEIC beside a PNG: $(cat "$T/err")"
grep -q "wrote 1 frame" "$T/out" && grep -q "note: $T/phone: 1 file of image kinds OpenCV does not read (HEIC/HEIF, AVIF, GIF, camera raw) left out (IMG_0001.HEIC): convert them to JPEG or PNG" "$T/err" ||
  fail "HEIC beside a PNG: $(cat "$T/out" "$T/err")"
set +e; "$BIN/ld-detect" "$T/phone/IMG_0001.HEIC" >/dev/null 2>"$T/err"; rc=$?; set -e
[ $rc -eq 1 ] && grep -q "IMG_0001.HEIC: cannot read as an image: it is a HEIF/HEIC image (a phone's), which OpenCV does not read: convert it to JPEG or PNG" "$T/err" ||
  fail "HEIC alone: exit $rc, $(cat "$T/err")"
: >"$T/phone/empty.png"
set +e; "$BIN/ld-detect" "$T/phone/empty.png" >/dev/null 2>"$T/err"; rc=$?; set -e
[ $rc -eq 1 ] && grep -q "empty.png: is empty (0 bytes: a copy or a download that failed?)" "$T/err" || fail "empty file: $(cat "$T/err")"
# An odd width in YUYV (pixels in pairs): cropped by one column, said once.
"$BIN/ld-synth" scene --out "$T/odd" --count 2 --resolution 59x45 >/dev/null
"$BIN/ld-log-images" "$T/odd" "$T/odd.lcmlog" --format yuyv >/dev/null 2>"$T/err" || fail "odd width: $(cat "$T/err")"
[ "$(grep -c "note: 59 px wide frames are cropped to 58 for yuyv" "$T/err")" -eq 1 ] || fail "odd width: $(cat "$T/err")"
[ "$("$BIN/ld-dump" "$T/odd.lcmlog" | jq -s '[.[] | .width] | unique | .[0]')" -eq 58 ] || fail "odd width: not 58 wide"

refused() {  # STATUS LOG PATTERN ARGS...
  local want=$1 log=$2 pat=$3; shift 3
  set +e; "$BIN/ld-log-images" "$@" "$log" >/dev/null 2>"$T/err"; local rc=$?; set -e
  [ $rc -eq "$want" ] || fail "$*: exit $rc, $(cat "$T/err")"
  grep -q -- "$pat" "$T/err" || fail "$*: $(cat "$T/err")"
  [ ! -e "$log" ] || fail "$*: $log left behind"
}
refused 2 "$T/b.lcmlog" "^ld-log-images: $T/f/000002.png: cannot read as an image$" "$T/f/000002.png"
head -c 2000 /dev/urandom >"$T/noise.mp4"
refused 2 "$T/c.lcmlog" "^ld-log-images: cannot open $T/noise.mp4 as a video$" "$T/noise.mp4"
refused 2 "$T/d.lcmlog" "^ld-log-images: $T/missing does not exist$" "$T/missing"
mkdir "$T/bad"; cp "$T/f/000002.png" "$T/bad/"
refused 1 "$T/e.lcmlog" "no frame could be read from $T/bad; $T/e.lcmlog not written" "$T/bad"
# Frames that cannot be an image_t of the format: said and skipped (a 1 px
# wide frame for YUYV died of an exception and left its partial log; a side
# over 32768 px was logged, and no reader took it).
printf 'P5\n1 4\n255\n\x10\x20\x30\x40' >"$T/w1.pgm"
refused 1 "$T/w1.lcmlog" "^ld-log-images: $T/w1.pgm: cannot be logged as yuyv: it is 1 px wide, and the format's pixels come in pairs, skipped$" "$T/w1.pgm" --format yuyv
grep -q "^ld-log-images: no frame could be logged from $T/w1.pgm; $T/w1.lcmlog not written$" "$T/err" || fail "1 px wide: $(cat "$T/err")"
mkdir "$T/wide"; cp "$T/f/000001.png" "$T/wide/"
{ printf 'P5\n40000 2\n255\n'; head -c 80000 /dev/zero; } >"$T/wide/000002.pgm"
"$BIN/ld-log-images" "$T/wide" "$T/wide.lcmlog" --format gray >"$T/out" 2>"$T/err" || fail "wide: exit $?: $(cat "$T/err")"
grep -q "^ld-log-images: $T/wide/000002.pgm: cannot be logged as gray: a 40000x2 image is more than the 32768 px a side that image_t takes, skipped$" "$T/err" &&
  grep -q "wrote 1 frame to $T/wide.lcmlog (gray, 30 fps), 1 that could not be logged skipped" "$T/out" ||
  fail "wide: $(cat "$T/out" "$T/err")"
[ "$("$BIN/ld-dump" "$T/wide.lcmlog" -c IMAGE | wc -l)" -eq 1 ] || fail "wide: the log does not hold 1 image"
! ls -a "$T" | grep -q partial || fail "a partial log left behind: $(ls -a "$T")"
refused 2 "$T/g.lcmlog" "ld-log-images: --fps: must be in \[0.1, 1000\], not 0" "$T/f" --fps 0
refused 2 "$T/h.lcmlog" "ld-log-images: --start-utime: must be whole microseconds, 0 or more, not -5" "$T/f" --start-utime -5
# beyond 2^62, or not whole: refused (99999999999999999999 was taken as now,
# 9223372036854775807 overflowed into negative utimes)
refused 2 "$T/h.lcmlog" "ld-log-images: --start-utime: must be at most 2^62 (4611686018427387904), not 99999999999999999999" "$T/f" --start-utime 99999999999999999999
refused 2 "$T/h.lcmlog" "ld-log-images: --start-utime: must be at most 2^62 (4611686018427387904), not 9223372036854775807" "$T/f" --start-utime 9223372036854775807
refused 2 "$T/h.lcmlog" "ld-log-images: --start-utime: must be whole microseconds, 0 or more, not 1e6" "$T/f" --start-utime 1e6
# --start-utime 0 is 0 (it was taken as not given: now)
"$BIN/ld-log-images" "$T/f/000001.png" "$T/zero.lcmlog" --start-utime 0 >/dev/null
"$BIN/ld-dump" "$T/zero.lcmlog" -c IMAGE | grep -q '"utime":0,' || fail "--start-utime 0: $("$BIN/ld-dump" "$T/zero.lcmlog" -c IMAGE)"
refused 2 "$T/i.lcmlog" "ld-log-images: --channel: an empty channel name" "$T/f" --channel ""
refused 2 "$T/j.lcmlog" "^ld-log-images: --format: unknown pixel format 'foo' (expected .*) (--help lists the options)$" "$T/f" --format foo
refused 2 /proc/j.lcmlog "ld-log-images: /proc/j.lcmlog cannot write in folder /proc: files cannot be created there" \
  "$T/f/000001.png"
# The output is never an input image, nor any other file that is not a log
# (two images given as if both were inputs): refused, the image untouched.
cp "$T/f/000000.png" "$T/keep.png"
set +e; "$BIN/ld-log-images" "$T/f/000001.png" "$T/keep.png" >/dev/null 2>"$T/err"; rc=$?; set -e
[ $rc -eq 2 ] && grep -q "^ld-log-images: $T/keep.png is not an LCM log (it starts with 89 50 4e 47.*: not written over$" "$T/err" ||
  fail "an image as the output: exit $rc, $(cat "$T/err")"
cmp -s "$T/keep.png" "$T/f/000000.png" || fail "the image given as the output was changed"
# A run that reads nothing leaves an earlier log as it was; a log's missing
# folder is created; nothing of the temporary file is left.
cp "$T/a.lcmlog" "$T/prev.lcmlog"
set +e; "$BIN/ld-log-images" "$T/bad" "$T/prev.lcmlog" >/dev/null 2>"$T/err"; rc=$?; set -e
[ $rc -eq 1 ] && cmp -s "$T/a.lcmlog" "$T/prev.lcmlog" || fail "a failed run changed the earlier log: exit $rc"
"$BIN/ld-log-images" "$T/f" "$T/new/dir/n.lcmlog" >/dev/null || fail "a log in a new folder"
[ "$(ls -A "$T/new/dir")" = n.lcmlog ] && [ -z "$(ls -A "$T" | grep partial)" ] || fail "left behind: $(ls -A "$T" "$T/new/dir")"
# An LCM log as the input (FFmpeg takes an MJPEG log for a video): refused,
# and given as the output too, left as it was.
cp "$T/a.lcmlog" "$T/same.lcmlog"
set +e; "$BIN/ld-log-images" "$T/same.lcmlog" "$T/same.lcmlog" >/dev/null 2>"$T/err"; rc=$?; set -e
[ $rc -eq 2 ] && [ "$(cat "$T/err")" = "ld-log-images: $T/same.lcmlog is an LCM log already (ld-play or lcm-logplayer replays it; ld-log-images makes logs of images and videos)" ] &&
  cmp -s "$T/a.lcmlog" "$T/same.lcmlog" || fail "a log as the input: exit $rc, $(cat "$T/err")"
echo "ld-log-images command line: ok"
