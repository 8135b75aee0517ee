#!/usr/bin/env bash
# ld-view's refusals, headless: a window on a display that does not answer
# is found out before ld-view opens one (a child process tries; Qt would
# abort ld-view itself) and refused in one line; a --video that cannot be
# written, and a --log that is not an LCM log, likewise, without OpenCV's
# own warnings. A window system that works is let through; a --video in a
# missing folder is written there.
# usage: view_cli_test.sh BIN_DIR
set -euo pipefail
BIN=$(cd "$1" && pwd)
T=$(mktemp -d); trap 'rm -rf "$T"' EXIT
fail() { echo "FAIL: $*" >&2; exit 1; }
unset QT_QPA_PLATFORM   # offscreen would open a "window" anywhere

"$BIN/ld-synth" sequence --out "$T/seq" --frames 3 --fps 10 --landmarks 1 --seed 3 --size 0.3 \
  --format mjpeg --log "$T/in.lcmlog" --no-png >/dev/null

# refused ERROR_PATTERN COMMAND...: exit 2 within 30 s, one line on stderr matching
refused() {
  local pattern=$1; shift
  local rc=0
  timeout 30 "$@" >"$T/out" 2>"$T/err" || rc=$?
  [ $rc -eq 2 ] || fail "$*: exit $rc, not 2: $(cat "$T/err")"
  [ "$(wc -l <"$T/err")" -eq 1 ] || fail "$*: not one line: $(cat "$T/err")"
  grep -q "^ld-view: $pattern" "$T/err" || fail "$*: $(cat "$T/err")"
  echo "refused: $(cat "$T/err")"
}

# An empty channel name (it was taken, and "no images on  in the logs" said)
refused "--image needs a channel name" "$BIN/ld-view" --image "" --all --log "$T/in.lcmlog" --out "$T/e"
# A display with no server: a number with no X socket here, and in a private
# network namespace (no abstract or TCP X socket reachable either).
n=99
while [ -e "/tmp/.X11-unix/X$n" ]; do n=$((n + 1)); done
netns=$(dirname "$0")/../scripts/netns-run.sh
refused "cannot open a window on display :$n (.*); give --out DIR or --video FILE$" \
  "$netns" env DISPLAY=:$n "$BIN/ld-view" --window --all --log "$T/in.lcmlog"
# the window is the default with a display and no --out/--video: the same
refused "cannot open a window on display :$n " "$netns" env DISPLAY=:$n "$BIN/ld-view" --all --log "$T/in.lcmlog"
refused "cannot open a window: DISPLAY and WAYLAND_DISPLAY are unset" \
  "$netns" env -u DISPLAY -u WAYLAND_DISPLAY "$BIN/ld-view" --window --all --log "$T/in.lcmlog"

# a window system that works (Qt's offscreen one, no display needed): the probe lets it through
QT_QPA_PLATFORM=offscreen timeout 30 "$BIN/ld-view" --window --all --log "$T/in.lcmlog" 2>"$T/err" ||
  fail "offscreen window: $(cat "$T/err")"
grep -q '^ld-view: 3 images, 0 tracked lists, 3 frames written$' "$T/err" || fail "offscreen window: $(cat "$T/err")"

refused "--video /proc/x/x.avi: cannot create folder /proc/x" \
  env -u DISPLAY -u WAYLAND_DISPLAY "$BIN/ld-view" --log "$T/in.lcmlog" --all --video /proc/x/x.avi
mkdir -p "$T/dir.avi"
refused "--video $T/dir.avi: is a folder" env -u DISPLAY -u WAYLAND_DISPLAY "$BIN/ld-view" --log "$T/in.lcmlog" --all --video "$T/dir.avi"
# the video is MJPG in AVI: another name is refused at the start (it failed at the first frame)
refused "--video $T/v.mp4: the video is MJPG in AVI, its name must end in .avi" \
  env -u DISPLAY -u WAYLAND_DISPLAY "$BIN/ld-view" --log "$T/in.lcmlog" --all --video "$T/v.mp4"
refused "--all is for --log" env -u DISPLAY -u WAYLAND_DISPLAY "$BIN/ld-view" --all --out "$T/live"
refused "--all is for --log" env -u DISPLAY -u WAYLAND_DISPLAY "$BIN/ld-view" --all -o "$T/live"  # (-o as ld-synth's)
# an LCM URL with logs: refused, as ld-dump does (it was dropped without a word: a user audit)
refused "--lcm-url is for live viewing (--log reads its files) (--help lists the options)" \
  env -u DISPLAY -u WAYLAND_DISPLAY "$BIN/ld-view" --log "$T/in.lcmlog" --lcm-url "udpm://239.255.76.67:7667?ttl=0" --out "$T/lu"
# live: a channel that is no regular expression (LCM reads a subscription's channel as one) is
# refused before anything is created (LCM printed its own line and ld-view waited on nothing)
refused "--tracks TRACKS\\[: LCM reads a subscription's channel as a regular expression, and this is none" \
  env -u DISPLAY -u WAYLAND_DISPLAY "$BIN/ld-view" --tracks 'TRACKS[' --out "$T/pattern"
[ ! -e "$T/pattern" ] || fail "a refused channel created --out's folder"
# --out over frames already there (ld-synth's frames are named as ld-view names its own, and were
# written over without a word): refused, none touched
mkdir "$T/orig"
for f in 000002.png 000000.png 000001-2.png; do echo "original $f" >"$T/orig/$f"; done
echo notes >"$T/orig/notes.png"   # (not a frame's name: no matter)
refused "--out $T/orig holds 3 frames named as ld-view names its own (000000.png, ...): they would be written over" \
  env -u DISPLAY -u WAYLAND_DISPLAY "$BIN/ld-view" --log "$T/in.lcmlog" --all --out "$T/orig"
[ "$(cat "$T/orig/000000.png")" = "original 000000.png" ] || fail "the frames already there were touched"
# --window with --out and no display: the advice is to drop --window; an empty DISPLAY is none
refused "cannot open a window: DISPLAY and WAYLAND_DISPLAY are unset (.*); drop --window$" \
  "$netns" env -u WAYLAND_DISPLAY DISPLAY= "$BIN/ld-view" --window --all --log "$T/in.lcmlog" --out "$T/w"
refused "--out /proc/x: cannot create folder /proc/x" \
  env -u DISPLAY -u WAYLAND_DISPLAY "$BIN/ld-view" --log "$T/in.lcmlog" --all --out /proc/x
printf '\x89PNG\r\n\x1a\n an image, not a log' >"$T/lm.png"
refused "log $T/lm.png is not an LCM log" \
  env -u DISPLAY -u WAYLAND_DISPLAY "$BIN/ld-view" --log "$T/lm.png" --all --out "$T/frames"
[ ! -e "$T/frames" ] || fail "a refused log created --out's folder"

# a video in a folder that does not exist yet: written, and only ld-view's own line
env -u DISPLAY -u WAYLAND_DISPLAY "$BIN/ld-view" --log "$T/in.lcmlog" --all --video "$T/new/v.avi" 2>"$T/err" ||
  fail "video in a new folder: $(cat "$T/err")"
[ "$(stat -c %s "$T/new/v.avi")" -gt 1000 ] || fail "no video"
[ "$(cat "$T/err")" = "ld-view: 3 images, 0 tracked lists, 3 frames written" ] || fail "video: $(cat "$T/err")"
# written again over an earlier video; never over one of its logs (a
# recording named .avi was replaced by a one-frame video, status 0), nor
# over a file that is not a video
env -u DISPLAY -u WAYLAND_DISPLAY "$BIN/ld-view" --log "$T/in.lcmlog" --all --video "$T/new/v.avi" 2>"$T/err" ||
  fail "video written again: $(cat "$T/err")"
cp "$T/in.lcmlog" "$T/rec.avi"
refused "--video $T/rec.avi is the --log file: it would be written over" \
  env -u DISPLAY -u WAYLAND_DISPLAY "$BIN/ld-view" --log "$T/rec.avi" --all --video "$T/rec.avi"
cmp -s "$T/in.lcmlog" "$T/rec.avi" || fail "the log named as the video was changed"
echo "robot notes" >"$T/notes.avi"
refused "--video $T/notes.avi: is not an AVI video (it starts with 72 6f 62 6f, ...): not written over" \
  env -u DISPLAY -u WAYLAND_DISPLAY "$BIN/ld-view" --log "$T/in.lcmlog" --all --video "$T/notes.avi"
[ "$(cat "$T/notes.avi")" = "robot notes" ] || fail "the notes were written over"
# --from / --to: the images logged that many seconds after their log's first
# (0, 0.1 and 0.2 s here): with --all, the raw frames about a moment, for
# ld-detect --explain
env -u DISPLAY -u WAYLAND_DISPLAY "$BIN/ld-view" --log "$T/in.lcmlog" --all --from 0.05 --to 0.15 --out "$T/span" 2>"$T/err" ||
  fail "--from/--to: $(cat "$T/err")"
[ "$(ls "$T/span")" = 000001.png ] && [ "$(cat "$T/err")" = "ld-view: 1 images, 0 tracked lists, 1 frames written" ] ||
  fail "--from 0.05 --to 0.15: $(ls "$T/span"); $(cat "$T/err")"
rc=0; env -u DISPLAY -u WAYLAND_DISPLAY "$BIN/ld-view" --log "$T/in.lcmlog" --all --from 3 --out "$T/span2" 2>"$T/err" || rc=$?
[ $rc -eq 1 ] && grep -q "^ld-view: no image from 3 s on after its log's first message (the images lie 0.000 to 0.200 s after their log's first)$" "$T/err" ||
  fail "--from past the end: exit $rc, $(cat "$T/err")"
[ ! -e "$T/span2" ] || fail "a run that drew nothing left its --out folder behind"
refused "--to 0.1 is before --from 0.2" \
  env -u DISPLAY -u WAYLAND_DISPLAY "$BIN/ld-view" --log "$T/in.lcmlog" --all --from 0.2 --to 0.1 --out "$T/span3"
refused "--from and --to are for --log" env -u DISPLAY -u WAYLAND_DISPLAY "$BIN/ld-view" --from 1 --out "$T/span4"
# a log cut off mid-event: what it holds is drawn, with one warning line
head -c $(( $(stat -c %s "$T/in.lcmlog") - 100 )) "$T/in.lcmlog" >"$T/cut.lcmlog"
env -u DISPLAY -u WAYLAND_DISPLAY "$BIN/ld-view" --log "$T/cut.lcmlog" --all --out "$T/cutframes" 2>"$T/err" ||
  fail "cut log: $(cat "$T/err")"
grep -q "^ld-view: warning: $T/cut.lcmlog: the log ends mid-event after 2 messages" "$T/err" || fail "cut log: $(cat "$T/err")"
grep -q "^ld-view: 2 images, 0 tracked lists, 2 frames written" "$T/err" || fail "cut log: $(cat "$T/err")"
# bad numbers, and a log whose images no tracked list matches (without --all): said why
refused "--fps: must be in \[0.1, 1000\], not 0" env -u DISPLAY -u WAYLAND_DISPLAY "$BIN/ld-view" --log "$T/in.lcmlog" --all --video "$T/v0.avi" --fps 0
refused "--axis-length: must be > 0, not -1" env -u DISPLAY -u WAYLAND_DISPLAY "$BIN/ld-view" --log "$T/in.lcmlog" --axis-length -1 --out "$T/f"
rc=0; env -u DISPLAY -u WAYLAND_DISPLAY "$BIN/ld-view" --log "$T/in.lcmlog" --out "$T/none" 2>"$T/err" || rc=$?
[ $rc -eq 1 ] && grep -q "^ld-view: no tracked lists on LANDMARKS_TRACKED (the logs' channels: IMAGE (3)); --all draws every image$" "$T/err" ||
  fail "nothing to draw: exit $rc, $(cat "$T/err")"
# logs without images (the run's log alone): said so
rc=0; env -u DISPLAY -u WAYLAND_DISPLAY "$BIN/ld-view" --log "$T/in.lcmlog" --image CAMERA --all --out "$T/none2" 2>"$T/err" || rc=$?
[ $rc -eq 1 ] && grep -q "^ld-view: no images on CAMERA in the logs (their channels: IMAGE (3)): frames are drawn on their images" "$T/err" ||
  fail "no images: exit $rc, $(cat "$T/err")"
# two logs whose seqs overlap, of two sizes: no PNG written over another
# (the second gets -2), and the video takes every frame, scaled to its size
"$BIN/ld-synth" sequence --out "$T/small" --frames 2 --log "$T/small.lcmlog" --landmarks 1 --resolution 320x240 >/dev/null
env -u DISPLAY -u WAYLAND_DISPLAY "$BIN/ld-view" --log "$T/in.lcmlog" --log "$T/small.lcmlog" --all \
  --out "$T/both" --video "$T/both.avi" 2>"$T/err" || fail "two logs: $(cat "$T/err")"
[ "$(ls "$T/both" | wc -l)" -eq 5 ] && [ -s "$T/both/000000-2.png" ] || fail "two logs: $(ls "$T/both")"
grep -q "^ld-view: note: 320x240 frames are scaled to the video's " "$T/err" || fail "two logs, video: $(cat "$T/err")"
"$BIN/ld-log-images" "$T/both.avi" "$T/both.lcmlog" >"$T/out" 2>/dev/null
grep -q "wrote 5 frames" "$T/out" || fail "the video holds: $(cat "$T/out")"
# a video the disk has no room for: said in one line, status 1 (OpenCV's
# writer says nothing: "3 frames written", status 0, and a video cut short)
mkdir "$T/full"
rc=0; unshare -m bash -c 'mount -t tmpfs -o size=8k tmpfs "$1" && exec "$2" --log "$3" --all --video "$1/v.avi"' _ \
  "$T/full" "$BIN/ld-view" "$T/in.lcmlog" 2>"$T/err" || rc=$?
[ $rc -eq 1 ] && [ "$(wc -l <"$T/err")" -eq 2 ] &&
  grep -q "^ld-view: 3 images, 0 tracked lists, 3 frames drawn (the video holds fewer: above)$" "$T/err" &&
  grep -q "^ld-view: --video $T/full/v.avi holds [0-9]* of the 3 frames written (.*: is the disk full?)$" "$T/err" ||
  fail "full disk: exit $rc, $(cat "$T/err")"
# ... and PNGs: said with the system's reason
rc=0; unshare -m bash -c 'mount -t tmpfs -o size=8k tmpfs "$1" && exec "$2" --log "$3" --all --out "$1/png"' _ \
  "$T/full" "$BIN/ld-view" "$T/in.lcmlog" 2>"$T/err" || rc=$?
[ $rc -eq 1 ] && grep -q "^ld-view: cannot write $T/full/png/000000.png: No space left on device$" "$T/err" ||
  fail "full disk, PNG: exit $rc, $(cat "$T/err")"
echo "ld-view command line: ok"
