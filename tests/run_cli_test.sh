#!/usr/bin/env bash
# ld-run refuses what its source or recorder would fail on, at once, in one
# line with status 2, instead of restarting that process again and again: a
# replay or play file that is not an LCM log (or is empty), an unknown
# --play-format, a recording or summary whose folder cannot be made, two
# sources, a non-positive --speed or --fps. Missing folders of --record and
# --summary are created. Every ld-run here has --netns: nothing reaches a
# real network even if a refusal were missed.
# usage: run_cli_test.sh BIN_DIR
set -euo pipefail
BIN=$(cd "$1" && pwd)
T=$(mktemp -d); trap 'rm -rf "$T"' EXIT
fail() { echo "FAIL: $*" >&2; exit 1; }

"$BIN/ld-synth" sequence --out "$T/seq" --frames 3 --fps 10 --landmarks 1 --seed 3 --size 0.3 \
  --format mjpeg --log "$T/in.lcmlog" --no-png >/dev/null
printf '\x89PNG\r\n\x1a\n an image, not a log' >"$T/lm.png"
: >"$T/empty.lcmlog"

# refused ERROR_PATTERN ARGS...: ld-run exits 2 within 10 s (no restart
# loop), with exactly one line on stderr that starts "ld-run: " and matches.
refused() {
  local pattern=$1; shift
  local rc=0
  timeout 10 "$BIN/ld-run" --netns --status-interval 0 "$@" >"$T/out" 2>"$T/err" || rc=$?
  [ $rc -eq 2 ] || fail "ld-run $*: exit $rc, not 2: $(cat "$T/err")"
  [ "$(wc -l <"$T/err")" -eq 1 ] || fail "ld-run $*: not one line: $(cat "$T/err")"
  grep -q "^ld-run: $pattern" "$T/err" || fail "ld-run $*: $(cat "$T/err")"
  echo "refused: ld-run $* -> $(cat "$T/err")"
}

refused "replay log $T/lm.png is not an LCM log (it starts with 89 50 4e 47" \
  --replay "$T/lm.png" --exit-when-replay-done
refused "play log $T/lm.png is not an LCM log" --play "$T/lm.png" --exit-when-replay-done
refused "replay log $T/empty.lcmlog is empty" --replay "$T/empty.lcmlog" --exit-when-replay-done
refused "cannot read log $T/missing.lcmlog: No such file" --replay "$T/missing.lcmlog"
refused "--play-format: unknown pixel format 'foo' (expected GRAY.*), or keep" \
  --play "$T/in.lcmlog" --play-format foo
printf '{"source": {"type": "play", "log": "%s", "format": "foo"}}\n' "$T/in.lcmlog" >"$T/run.json"
refused ".*run.json: source.format: unknown pixel format 'foo'" --config "$T/run.json"
refused "recording /proc/x/r.lcmlog: cannot create folder /proc/x" --replay "$T/in.lcmlog" --record /proc/x/r.lcmlog
refused "summary /proc/x/s.json: cannot create folder /proc/x" --replay "$T/in.lcmlog" --summary /proc/x/s.json
refused "recording $T: is a folder" --replay "$T/in.lcmlog" --record "$T"
refused "state file /proc/x/st.json: cannot create folder /proc/x" --replay "$T/in.lcmlog" --state-file /proc/x/st.json
refused "--log-dir /proc/x: cannot create folder /proc/x" --replay "$T/in.lcmlog" --log-dir /proc/x
refused "--replay and --play name two sources; give one" --replay "$T/in.lcmlog" --play "$T/in.lcmlog"
refused "--source camera and --replay name two sources; give one" --replay "$T/in.lcmlog" --source camera
# another source's options: refused, not dropped without a word
refused "--fps is for --play (ld-play's source), and this run's source is replay" --replay "$T/in.lcmlog" --fps 10
refused "--speed is for --replay (lcm-logplayer's source; --play takes --fps), and this run's source is play" --play "$T/in.lcmlog" --speed 2
refused "--camera-arg is for the camera source, and this run's source is play" --play "$T/in.lcmlog" --camera-arg=--fake
# an argument for the camera that is also one of ld-run's options is given with '='
refused "--camera-arg needs a value, and the word after it is the option --fps (to give --camera-arg that word, write --camera-arg=--fps=20)" \
  --camera-arg --fps=20
refused "--duration is for --play (ld-play's source), and this run's source is camera (--help lists the options)" --duration 5
refused "--processes: unknown process \"bogus\" (detector, tracker, qr-reader or none) (--help lists the options)" \
  --replay "$T/in.lcmlog" --processes bogus
refused "--speed: must be in \[0.01, 1000\], not -1" --replay "$T/in.lcmlog" --speed -1
refused "--speed: must be in \[0.01, 1000\], not 0" --replay "$T/in.lcmlog" --speed 0
refused "--speed: must be in \[0.01, 1000\], not 1e300" --replay "$T/in.lcmlog" --speed 1e300
refused "--fps: must be in \[0.001, 1000\], not 0" --play "$T/in.lcmlog" --fps 0
# no file ld-run writes is the log it plays, nor another file it writes
cp "$T/in.lcmlog" "$T/keep.lcmlog"
refused "the recording $T/keep.lcmlog is the log: it would be written over" --replay "$T/keep.lcmlog" --record "$T/keep.lcmlog"
refused "the summary $T/keep.lcmlog is the log" --play "$T/keep.lcmlog" --summary "$T/keep.lcmlog"
refused "the summary $T/./r.out is the recording" --replay "$T/keep.lcmlog" --record "$T/r.out" --summary "$T/./r.out"
cmp -s "$T/in.lcmlog" "$T/keep.lcmlog" || fail "a refused run changed the log"
# ... nor its config (the summary replaced it), and a recording is written
# over an LCM log alone, a summary or state file over JSON alone (a PNG or
# a config named by mistake was replaced without a word)
printf '{"detector": {"args": []}}\n' >"$T/cfg.json"; cp "$T/cfg.json" "$T/cfg.keep"
refused "the summary $T/cfg.json is the config: it would be written over" --config "$T/cfg.json" --replay "$T/keep.lcmlog" --summary "$T/cfg.json"
refused "the state file $T/cfg.json is the config" --config "$T/cfg" --replay "$T/keep.lcmlog" --state-file "$T/cfg.json"
cmp -s "$T/cfg.json" "$T/cfg.keep" || fail "a refused run changed the config"
printf '\x89PNG\r\n\x1a\nxxxx' >"$T/photo.png"; printf '# robot notes\n' >"$T/notes.txt"
refused "recording $T/photo.png: is not an LCM log (it starts with 89 50 4e 47" --replay "$T/keep.lcmlog" --record "$T/photo.png"
refused "summary $T/notes.txt: is not a JSON file (it starts with \"# robot note\"): not written over" --replay "$T/keep.lcmlog" --summary "$T/notes.txt"
[ "$(head -c 4 "$T/photo.png" | od -An -tx1 | tr -d ' ')" = 89504e47 ] || fail "a refused run changed the PNG"
# a worker program that is not there (a config's "program" mistyped), an
# LCM URL without a port, memq (each process's own)
printf '{"detector": {"program": "ld-detectr"}}\n' >"$T/prog.json"
refused "the detector's program ld-detectr cannot be run" --config "$T/prog.json" --replay "$T/in.lcmlog"
refused "LCM URL udpm://239.255.76.67: no port" --replay "$T/in.lcmlog" --lcm-url udpm://239.255.76.67
refused "LCM URL tcpq://127.0.0.1:7700: ld-run runs its set over udpm:// multicast only (it waits" --replay "$T/in.lcmlog" --lcm-url tcpq://127.0.0.1:7700
refused "LCM URL file:///tmp/x.lcmlog?mode=w: ld-run runs its set over udpm:// multicast only" --replay "$T/in.lcmlog" --lcm-url 'file:///tmp/x.lcmlog?mode=w'
refused "LCM URL memq://: ld-run runs its set over udpm:// multicast only (memq is within one process" --replay "$T/in.lcmlog" --lcm-url memq://
# config keys given twice, a config that is a folder
printf '{"source": {"type": "replay", "log": "%s", "log": "%s"}}\n' "$T/in.lcmlog" "$T/in.lcmlog" >"$T/twice.json"
refused ".*twice.json: key \"log\" is given twice" --config "$T/twice.json"
printf 'source:\n  type: replay\n  type: play\n' >"$T/twice.yaml"
refused ".*twice.yaml: line 3: key \"type\" is given twice" --config "$T/twice.yaml"
# a process's args in the config repeating what ld-run passes: the file
# named, as for its other errors; from --camera-arg: no file named
printf '{"source": {"type": "replay", "log": "%s"}, "detector": {"args": ["--out", "X"]}}\n' "$T/in.lcmlog" >"$T/args.json"
refused "$T/args.json: detector's args give --out, which ld-run passes itself from the config's channels" --config "$T/args.json"
printf '{"source": {"type": "camera"}}\n' >"$T/cam.json"
refused "camera's args give --lcm-url, which ld-run passes itself" --config "$T/cam.json" --camera-arg=--lcm-url=udpm://239.255.76.67:7667
refused "detector's args give --lcm-url, which ld-run passes itself" --config "$T/cam.json" --detector-arg=--lcm-url=udpm://239.255.76.67:7667
refused "--tracker-arg is for ld-tracker, which this run does not start" --replay "$T/in.lcmlog" --processes detector --tracker-arg=--max-lifetime=2
refused "--qr-reader-arg needs a value, and the word after it is the option --speed" --replay "$T/in.lcmlog" --qr-reader-arg --speed=2
# a worker's arguments on the command line, after the config's
printf '{"source": {"type": "replay", "log": "%s"}, "tracker": {"args": ["--max-lifetime", "1"]}}\n' "$T/in.lcmlog" >"$T/wargs.json"
timeout 60 "$BIN/ld-run" --netns --status-interval 0 --config "$T/wargs.json" --exit-when-replay-done \
  --detector-arg=--adaptive --tracker-arg=--min-hits=1 --summary "$T/wargs_summary.json" >"$T/out" 2>&1 ||
  fail "--detector-arg and --tracker-arg: $(cat "$T/out")"
grep -q "ld-detector: adaptive lighting on" "$T/out" || fail "--detector-arg=--adaptive did not reach the detector: $(cat "$T/out")"
[ "$(jq -c '.processes[] | select(.name == "tracker") | .argv[-3:]' "$T/wargs_summary.json")" = '["--max-lifetime","1","--min-hits=1"]' ] ||
  fail "the tracker's argv: $(jq -c '.processes[] | select(.name == "tracker") | .argv' "$T/wargs_summary.json")"
# A recording split into files (record.split_mb, record.keep): FILE.0 the
# newest; a second run keeps the first's, shifted (one file is written anew)
printf '{"source": {"type": "play", "log": "%s", "fps": 60, "duration_s": 1.5}, "record": {"file": "%s", "split_mb": 0.03, "keep": 20}}\n' \
  "$T/in.lcmlog" "$T/rec.lcmlog" >"$T/rec.json"
for pass in 1 2; do
  timeout 60 "$BIN/ld-run" --netns --status-interval 0 -q --config "$T/rec.json" --exit-when-replay-done \
    --summary "$T/rec_summary$pass.json" >"$T/out" 2>&1 || fail "a split recording, pass $pass: $(cat "$T/out")"
  n=$(ls "$T"/rec.lcmlog.* | wc -l)
  if [ "$pass" -eq 1 ]; then
    first=$n
    last1=$("$BIN/ld-dump" -c LANDMARKS_TRACKED "$T"/rec.lcmlog.* | jq -s 'map(.utime) | max')
  fi
  [ ! -e "$T/rec.lcmlog" ] || fail "a split recording wrote $T/rec.lcmlog itself"
done
echo "split recording: $first files after one run, $n after two"
# (the first run's files kept, the second's two or more: their counts vary with the codes read)
[ "$first" -ge 2 ] && [ "$n" -ge $((first + 2)) ] || fail "split recording: $first files, then $n"
# (every tracked list of both runs, 90 frames each less what a loaded
# machine skipped, as ld-run's summaries count them, in the files together;
# the second run's FILE.0 its own alone: lcm-logger appended to the last
# run's, which grew without end over short runs; no file much over 0.03 MB)
lists=$("$BIN/ld-dump" -c LANDMARKS_TRACKED "$T"/rec.lcmlog.* | wc -l)
tracked=$(( $(jq .summary.frames.tracked "$T/rec_summary1.json") + $(jq .summary.frames.tracked "$T/rec_summary2.json") ))
[ "$tracked" -gt 120 ] && [ "$lists" -eq "$tracked" ] ||
  fail "split recording: $lists tracked lists in the files, $tracked tracked in the two runs"
first0=$("$BIN/ld-dump" -c LANDMARKS_TRACKED "$T/rec.lcmlog.0" | jq -s 'map(.utime) | min')
[ "$first0" -gt "$last1" ] || fail "split recording: FILE.0 holds the first run's lists ($first0 <= $last1)"
for f in "$T"/rec.lcmlog.*; do [ "$(stat -c %s "$f")" -lt 40000 ] || fail "split recording: $f is $(stat -c %s "$f") bytes"; done
refused "the summary $T/rec.lcmlog.3 is the recording: it would be written over" --config "$T/rec.json" --summary "$T/rec.lcmlog.3"
# SIGUSR1 opens the --log-dir files again (logrotate moves them, then
# signals; SIGHUP stops the set): the lines after it go to a new file
"$BIN/ld-run" --netns --status-interval 0 -q --play "$T/in.lcmlog" --fps 30 --duration 4 --exit-when-replay-done \
  --log-dir "$T/logs" >"$T/out" 2>&1 &
run=$!
for _ in $(seq 1 100); do [ -e "$T/logs/detector.log" ] && break; sleep 0.1; done
sleep 1
mv "$T/logs/detector.log" "$T/logs/detector.log.1"
[ "$run" -gt 1 ] && kill -USR1 "$run"
rc=0; wait "$run" || rc=$?
[ $rc -eq 0 ] || fail "SIGUSR1: ld-run exit $rc: $(cat "$T/out")"
grep -q "^ld-detector: stopped after" "$T/logs/detector.log" || fail "SIGUSR1: no new detector.log: $(ls "$T/logs")"
grep -q "^\[ld-run\] started" "$T/logs/detector.log.1" || fail "SIGUSR1: the moved file: $(cat "$T/logs/detector.log.1")"
mkdir "$T/cfgdir.json"
refused "config $T/cfgdir.json is a folder" --config "$T/cfgdir.json"
refused "--fps: 'nan' is not a number" --play "$T/in.lcmlog" --fps nan
refused "--duration: must be >= 0, not -2" --play "$T/in.lcmlog" --duration -2
refused "--stop-grace: must be >= 0, not -1" --replay "$T/in.lcmlog" --stop-grace -1
refused "--wait-ready: must be >= 0, not -1" --replay "$T/in.lcmlog" --wait-ready -1
refused "--drain: must be >= 0, not -1" --replay "$T/in.lcmlog" --drain -1

# A source that fails on its input after starting (ld-play: a log without
# images, exit 2) ends the run (status 2) instead of being restarted again
# and again.
"$BIN/ld-synth" sequence --frames 3 --landmarks 1 --channel OTHER --log "$T/noimg.lcmlog" --no-png >/dev/null
rc=0
timeout 20 "$BIN/ld-run" --netns --status-interval 0 --play "$T/noimg.lcmlog" --exit-when-replay-done \
  >"$T/out" 2>&1 || rc=$?
[ $rc -eq 2 ] || fail "a source failing with exit 2: ld-run exit $rc: $(cat "$T/out")"
grep -q "the source play failed (exit 2; its error is above); stopping" "$T/out" || fail "source failure: $(cat "$T/out")"
grep -q "ld-play: no IMAGE images in $T/noimg.lcmlog (its channels: OTHER (3))$" "$T/out" ||
  fail "the source's own error: $(cat "$T/out")"
# A replay whose log has no images on the image channel (its images on
# another, or ld-run's own recording of the outputs) feeds the set nothing:
# refused at once, naming the log's channels (it ended with status 0, then
# said so with status 1 once the whole log had been replayed).
rc=0
timeout 30 "$BIN/ld-run" --netns --status-interval 0 --replay "$T/noimg.lcmlog" --exit-when-replay-done \
  >"$T/out" 2>&1 || rc=$?
[ $rc -eq 2 ] || fail "a replay without images: ld-run exit $rc: $(cat "$T/out")"
[ "$(cat "$T/out")" = "ld-run: replay log $T/noimg.lcmlog holds no message on IMAGE (its channels: OTHER (3)): nothing for the set to work on; replay the log the images are in (a recording of the set's outputs holds none unless record.channels takes them), or name their channel with the config's channels.image" ] ||
  fail "a replay without images: $(cat "$T/out")"
# ... checked against the config's source.channels where it gives one (a
# replay of other channels, the lists to the tracker alone, runs)
printf '{"source": {"channels": "LANDMARKS"}}\n' >"$T/replay_lm.json"
rc=0
timeout 30 "$BIN/ld-run" --netns --status-interval 0 --config "$T/replay_lm.json" --processes tracker \
  --replay "$T/noimg.lcmlog" --exit-when-replay-done >"$T/out" 2>&1 || rc=$?
[ $rc -eq 2 ] && [ "$(cat "$T/out")" = "ld-run: replay log $T/noimg.lcmlog holds no message on a channel source.channels LANDMARKS plays (its channels: OTHER (3)): nothing to replay" ] ||
  fail "a replay of a pattern that plays nothing: exit $rc, $(cat "$T/out")"
printf '{"source": {"channels": "OTH.*"}}\n' >"$T/replay_other.json"
timeout 30 "$BIN/ld-run" --netns --status-interval 0 --config "$T/replay_other.json" --processes none \
  --replay "$T/noimg.lcmlog" --exit-when-replay-done >"$T/out" 2>&1 || true
! grep -q "holds no message" "$T/out" && grep -q "replay done" "$T/out" ||
  fail "a replay of a pattern that plays the log's channel: $(cat "$T/out")"
# A log whose messages on IMAGE are another project's type: said so, not
# taken for images on another channel (a helper's foreign log).
python3 - "$T/foreign.lcmlog" <<'PY'
import struct, sys, time
out = b''
t = int(time.time() * 1e6)
for n in range(5):
    data = bytes(range(8)) + b'not an image_t at all' * 3
    out += struct.pack('>IqqII', 0xEDA1DA01, n, t + n * 100000, 5, len(data)) + b'IMAGE' + data
open(sys.argv[1], 'wb').write(out)
PY
rc=0
timeout 30 "$BIN/ld-run" --netns --status-interval 0 --replay "$T/foreign.lcmlog" --exit-when-replay-done \
  >"$T/out" 2>&1 || rc=$?
[ $rc -eq 1 ] || fail "a replay of another type on IMAGE: ld-run exit $rc: $(cat "$T/out")"
grep -q "replay done, but none of the 5 messages on IMAGE is an image (another project's type" "$T/out" ||
  fail "a replay of another type on IMAGE: $(cat "$T/out")"
# A full disk under the state file, the log folder and the summary: each
# said with why, the files as they were, status 1 (a state file and logs
# of 0 bytes, without a word, and status 0; a summary cut short)
rc=0
timeout 60 unshare -rm bash -c '
  mkdir -p "$1/tiny" && mount -t tmpfs -o size=4k none "$1/tiny" && head -c 4096 /dev/zero >"$1/tiny/fill" 2>/dev/null
  "$2/ld-run" --netns --processes none --play "$1/in.lcmlog" --fps 60 --exit-when-replay-done --status-interval 0 \
    --state-file "$1/tiny/st.json" --log-dir "$1/tiny/logs" --summary "$1/tiny/s.json"' _ "$T" "$BIN" >"$T/out" 2>&1 || rc=$?
[ $rc -eq 1 ] && grep -q "cannot write the state file $T/tiny/st.json: No space left on device" "$T/out" &&
  grep -q "cannot write $T/tiny/logs/play.log: No space left on device" "$T/out" &&
  grep -q "^ld-run: cannot write $T/tiny/s.json: No space left on device" "$T/out" ||
  fail "a full disk under ld-run's files: exit $rc, $(cat "$T/out")"
# ... and so does a worker that refuses its options (exit 2): status 2, not
# a run that restarts it again and again and ends with status 0.
printf '{"detector": {"args": ["--bogus-detector-opt"]}}\n' >"$T/badworker.json"
rc=0
timeout 30 "$BIN/ld-run" --netns --status-interval 0 --config "$T/badworker.json" --replay "$T/in.lcmlog" \
  --exit-when-replay-done >"$T/out" 2>&1 || rc=$?
[ $rc -eq 2 ] || fail "a worker failing with exit 2: ld-run exit $rc: $(cat "$T/out")"
grep -q "detector failed (exit 2; its error is above); stopping" "$T/out" || fail "worker failure: $(cat "$T/out")"
grep -q "^\[detector\] ld-detector: .*bogus-detector-opt" "$T/out" || fail "worker failure, its own line: $(cat "$T/out")"
[ "$(grep -c "^\[detector\] ld-detector: " "$T/out")" -eq 1 ] || fail "worker failure: started again: $(cat "$T/out")"
# Live too (no --exit-when-replay-done: a robot's set, where it was
# restarted every 5 s for ever): a tracker parameter file with a typo ends
# the run with status 2 at once, naming the file and the tracker.
printf 'max_lifetime_s: 2\nmax_lifetme_s: 3\n' >"$T/typo.yaml"
printf '{"tracker": {"args": ["--params", "%s"]}}\n' "$T/typo.yaml" >"$T/badlive.json"
rc=0
timeout 30 "$BIN/ld-run" --netns --status-interval 0 --config "$T/badlive.json" --replay "$T/in.lcmlog" \
  >"$T/out" 2>&1 || rc=$?
[ $rc -eq 2 ] || fail "live, a worker failing with exit 2: ld-run exit $rc: $(cat "$T/out")"
grep -q "tracker failed (exit 2; its error is above); stopping" "$T/out" && grep -q "typo.yaml" "$T/out" ||
  fail "live worker failure: $(cat "$T/out")"
# A worker that dies at once each time it starts (exit 1: restarted with
# backoff) did none of the run's work: the run ends with status 1, naming
# it, where it said "exit 0"; the wait for it to listen names it too.
printf '{"detector": {"program": "/bin/false"}}\n' >"$T/deadworker.json"
rc=0
timeout 30 "$BIN/ld-run" --netns --status-interval 0 --config "$T/deadworker.json" --replay "$T/in.lcmlog" \
  --exit-when-replay-done --wait-ready 1 >"$T/out" 2>&1 || rc=$?
[ $rc -eq 1 ] || fail "a worker that never ran: ld-run exit $rc: $(cat "$T/out")"
grep -q "^\[ld-run\] not every process listens after 1.00 s (.*detector (not running: exit 1).*); starting" "$T/out" &&
  grep -q "^\[ld-run\] detector was not running at the end: it was waiting to be started again (started [0-9]* times; its last end: exit 1)" "$T/out" ||
  fail "a worker that never ran: $(cat "$T/out")"

# ... and with -q, where its error line is not shown, it says so (and the
# run does not wait out --wait-ready first)
rc=0; start=$(date +%s)
timeout 30 "$BIN/ld-run" --netns --status-interval 0 -q --config "$T/badworker.json" --replay "$T/in.lcmlog" \
  --exit-when-replay-done --wait-ready 20 >"$T/out" 2>&1 || rc=$?
[ $rc -eq 2 ] && grep -q "detector failed (exit 2; -q kept its error out: run without it)" "$T/out" ||
  fail "worker failure, -q: exit $rc, $(cat "$T/out")"
[ $(( $(date +%s) - start )) -lt 15 ] || fail "worker failure: the run waited out --wait-ready"

# A payload that is not UTF-8 (bytes as printed): the summary holds it with
# U+FFFD, as ld-detect writes it (ld-run aborted writing the summary).
"$BIN/ld-synth" sequence --frames 20 --landmarks 1 --size 0.3 --seed 3 -p $'caf\xe9' --log "$T/latin.lcmlog" --no-png >/dev/null
timeout 60 "$BIN/ld-run" --netns --replay "$T/latin.lcmlog" --exit-when-replay-done --summary "$T/latin.json" \
  --report -q --status-interval 0 >"$T/out" 2>&1 || fail "a payload that is not UTF-8: $(tail -3 "$T/out")"
jq -e '[.summary.tracks[].payload] | index("caf\ufffd")' "$T/latin.json" >/dev/null || fail "latin payload: $(cat "$T/latin.json")"
# (the QR reader, the slowest, may skip a frame on a loaded machine: seen
# once with other tests beside it)
grep -q "^frames: 20 images, 20 tracked (skipped: 0 by the detector, 0 by the tracker, [01] by the QR reader)$" "$T/out" ||
  fail "report, every frame tracked: $(grep '^frames' "$T/out")"
# the images no tracked list came for are said in the report (here: no tracker)
timeout 60 "$BIN/ld-run" --netns --replay "$T/latin.lcmlog" --exit-when-replay-done --processes detector \
  --report -q --status-interval 0 >"$T/out" 2>&1 || true
grep -q "^frames: 20 images, 0 tracked (skipped: 0 by the detector, 0 by the tracker); 20 more never tracked (no tracked list came for them: a process stopped, restarting or left out, frames the detector could not decode, lost on the bus, or on their way at the end)$" "$T/out" ||
  fail "report, no tracker: $(cat "$T/out")"
[ "$(jq .log_images "$T/latin.json")" -eq 20 ] || fail "log_images: $(jq .log_images "$T/latin.json")"
# A replay log damaged in the middle: lcm-logplayer stops there; ld-run says so.
{ head -c 5000000 "$T/latin.lcmlog"; head -c 3000 /dev/zero; tail -c +5000001 "$T/latin.lcmlog"; } >"$T/damaged.lcmlog"
timeout 60 "$BIN/ld-run" --netns --replay "$T/damaged.lcmlog" --exit-when-replay-done --processes none \
  --status-interval 0 -q >"$T/out" 2>&1 || true
grep -q "warning: replay log $T/damaged.lcmlog: skipped .* bytes that are no whole LCM event.*lcm-logplayer stops at the damage (--play reads past it)" "$T/out" ||
  fail "damaged replay log: $(cat "$T/out")"
grep -q "warning: 15 of the log's 20 images on IMAGE never came (lcm-logplayer stopped at the log's damage" "$T/out" ||
  fail "damaged replay log, images: $(cat "$T/out")"
# A replay log whose IMAGE channel holds malformed messages besides its
# frames: they came, and are said as not images, not as lost on the bus.
python3 - "$T/latin.lcmlog" "$T/junk.lcmlog" <<'PY'
import struct, sys
data = open(sys.argv[1], 'rb').read(); out = bytearray(); pos = n = 0
while pos + 28 <= len(data):
    sync, num, ts, clen, dlen = struct.unpack_from('>IqqII', data, pos)
    event = data[pos + 28:pos + 28 + clen + dlen]
    out += struct.pack('>IqqII', sync, n, ts, clen, dlen) + event; n += 1
    if n <= 6 and event[:clen] == b'IMAGE':  # the first 3 frames, each with a message of junk behind
        out += struct.pack('>IqqII', sync, n, ts + 1, clen, 40) + b'IMAGE' + bytes(range(40)); n += 1
    pos += 28 + clen + dlen
open(sys.argv[2], 'wb').write(out)
PY
timeout 60 "$BIN/ld-run" --netns --replay "$T/junk.lcmlog" --exit-when-replay-done --processes detector \
  --status-interval 0 --summary "$T/junk.json" -q >"$T/out" 2>&1 || fail "malformed images in the log: $(cat "$T/out")"
grep -q "warning: 3 of the log's 23 messages on IMAGE are not images (malformed: the detector's lines say why)" "$T/out" &&
  ! grep -q "never came" "$T/out" && [ "$(jq .summary.frames.bad_images "$T/junk.json")" -eq 3 ] ||
  fail "malformed images in the log: $(cat "$T/out")"
# A replay log of two sessions an hour apart: lcm-logplayer would wait the
# hour in silence; ld-run says so as it starts.
python3 - "$T/latin.lcmlog" "$T/gap.lcmlog" <<'PY'
import struct, sys
data = bytearray(open(sys.argv[1], 'rb').read()); pos = n = 0
while pos + 28 <= len(data):
    sync, num, ts, clen, dlen = struct.unpack_from('>IqqII', data, pos)
    if num >= 10: struct.pack_into('>q', data, pos + 12, ts + 3600 * 10**6)
    pos += 28 + clen + dlen
open(sys.argv[2], 'wb').write(data)
PY
timeout 5 "$BIN/ld-run" --netns --replay "$T/gap.lcmlog" --exit-when-replay-done --processes none \
  --status-interval 0 -q >"$T/out" 2>&1 || true
grep -q "warning: replay log $T/gap.lcmlog: 3600.0 s without a message after its message 10 (two sessions in one log, as lcm-logger -a appends?): lcm-logplayer waits 3600.0 s there at speed 1 (--play plays the images without the wait)" "$T/out" ||
  fail "a log with a gap of an hour: $(cat "$T/out")"

# What is accepted: a pixel format in any case, and missing folders of the
# recording and the summary, which ld-run creates.
timeout 60 "$BIN/ld-run" --netns --processes none --play "$T/in.lcmlog" --play-format Mjpg --fps 30 \
  --exit-when-replay-done --record "$T/new/a/r.lcmlog" --summary "$T/new/b/s.json" --status-interval 0 -q \
  2>"$T/err" || fail "accepted run: $(cat "$T/err")"
[ -f "$T/new/a/r.lcmlog" ] || fail "no recording in a created folder"
[ "$(jq .summary.frames.images "$T/new/b/s.json")" -eq 3 ] || fail "summary: $(cat "$T/new/b/s.json")"
# GRAY frames (a camera set to a grey format): the detector says once that
# no landmark can be in them (it found nothing without a word).
timeout 60 "$BIN/ld-run" --netns --processes detector --play "$T/in.lcmlog" --play-format gray --fps 30 \
  --exit-when-replay-done --status-interval 0 >"$T/out" 2>&1 || fail "gray run: $(cat "$T/out")"
[ "$(grep -c "ld-detector: GRAY frames have no colour: landmarks are found by their blue and red squares, so none can be found in them (is the camera set to a grey format?)" "$T/out")" -eq 1 ] ||
  fail "gray run: $(cat "$T/out")"
# ld-play alone: a file that is not a log is named as such (not "no IMAGE images").
rc=0; "$BIN/ld-play" "$T/lm.png" 2>"$T/err" || rc=$?
[ $rc -eq 2 ] && [ "$(cat "$T/err")" = "ld-play: log $T/lm.png is not an LCM log (it starts with 89 50 4e 47, not LCM's event magic ed a1 da 01)" ] ||
  fail "ld-play on a PNG: $rc $(cat "$T/err")"
# ld-play on a log cut off mid-event: plays what it holds, with one warning line.
head -c $(( $(stat -c %s "$T/in.lcmlog") - 100 )) "$T/in.lcmlog" >"$T/cut.lcmlog"
"$BIN/ld-play" "$T/cut.lcmlog" --lcm-url memq:// --fps 100 >"$T/out" 2>"$T/err" || fail "ld-play cut log: $(cat "$T/err")"
grep -q "^ld-play: warning: $T/cut.lcmlog: the log ends mid-event after 2 messages" "$T/err" || fail "ld-play cut log: $(cat "$T/err")"
# ... and reads only the frames it plays: with --frames 1 it never gets to the cut.
"$BIN/ld-play" "$T/cut.lcmlog" --lcm-url memq:// --fps 100 --frames 1 >"$T/out" 2>"$T/err" || fail "ld-play --frames 1: $(cat "$T/err")"
! grep -q "warning" "$T/err" && grep -q "^ld-play: published 1 frame (.*) in .* s, - frames/s;" "$T/err" || fail "ld-play --frames 1 read on: $(cat "$T/err")"
# ld-play plays a log back and forth: a loop from its last frame to its
# first was a cut the tracker could not see (it gave the last frame's ids,
# and their payloads, to the first frame's landmarks). The frames told
# apart by their JPEG sizes.
"$BIN/ld-synth" sequence --out "$T/bf" --frames 4 --fps 10 --landmarks 1 --seed 2 --format mjpeg \
  --log "$T/bf.lcmlog" --no-png >/dev/null
"$BIN/ld-play" "$T/bf.lcmlog" --lcm-url "file://$T/bf-out.lcmlog?mode=w" --fps 100 --frames 9 2>/dev/null ||
  fail "ld-play to a file"
mapfile -t sizes < <("$BIN/ld-dump" "$T/bf.lcmlog" | jq -r .size)
want="${sizes[0]} ${sizes[1]} ${sizes[2]} ${sizes[3]} ${sizes[2]} ${sizes[1]} ${sizes[0]} ${sizes[1]} ${sizes[2]}"
got=$("$BIN/ld-dump" "$T/bf-out.lcmlog" | jq -r .size | tr '\n' ' ' | sed 's/ $//')
[ "$got" = "$want" ] || fail "ld-play back and forth: $got, not $want"
[ "$("$BIN/ld-dump" "$T/bf-out.lcmlog" | jq -r .seq | tr '\n' ' ')" = "0 1 2 3 4 5 6 7 8 " ] || fail "ld-play seqs"
# ld-play takes --frames or --duration, not both.
rc=0; "$BIN/ld-play" "$T/in.lcmlog" --frames 3 --duration 2 2>"$T/err" || rc=$?
[ $rc -eq 2 ] && grep -q "^ld-play: --frames excludes --duration" "$T/err" || fail "ld-play --frames --duration: $rc $(cat "$T/err")"
# ... each a count of 1 and more (0 published the log once), no duration
# so long that its frame count wraps (1e19 s published nothing), no negative seq
for args in "--frames 0|--frames: must be in [1, 1000000000000], not 0" "--duration 0|--duration: must be > 0, not 0" \
            "--duration 1e19|--duration 1e+19 at --fps 30 is over 1e12 frames" \
            "--first-seq -5|--first-seq: must be >= 0, not -5" \
            "--first-seq 9223372036854775806|--first-seq: must be at most 2^62 (4611686018427387904), not 9223372036854775806" \
            "--format foo|--format: must be keep, or a pixel format to convert to (bgr, rgb, rgba, bgra, gray, yuyv, uyvy, mjpeg), not 'foo' (--help lists the options)"; do
  rc=0; "$BIN/ld-play" "$T/in.lcmlog" --lcm-url memq:// ${args%%|*} 2>"$T/err" || rc=$?
  [ $rc -eq 2 ] && grep -qF -- "ld-play: ${args#*|}" "$T/err" || fail "ld-play ${args%%|*}: $rc $(cat "$T/err")"
done
# an odd-width log played as YUYV: its frames lose their last column, said
# once (each frame was skipped, and the run ended with "no IMAGE images")
"$BIN/ld-synth" scene --out "$T/odd" --count 2 --resolution 641x481 >/dev/null
"$BIN/ld-log-images" "$T/odd" "$T/odd.lcmlog" --format gray >/dev/null
"$BIN/ld-play" "$T/odd.lcmlog" --lcm-url memq:// --fps 100 --format yuyv >"$T/out" 2>"$T/err" || fail "ld-play odd width: $(cat "$T/err")"
[ "$(grep -c "^ld-play: note: 641 px wide frames are cropped to 640 for YUYV (its pixels come in pairs)$" "$T/err")" -eq 1 ] &&
  grep -q "published 2 frames" "$T/err" && ! grep -q skipping "$T/err" || fail "ld-play odd width: $(cat "$T/err")"
# SIGTERM stops it at once, not when the next frame is due (10 s away here)
"$BIN/ld-play" "$T/in.lcmlog" --lcm-url memq:// --fps 0.1 --frames 5 >/dev/null 2>&1 &
play=$!
# (once it handles SIGTERM: its SigCgt mask has bit 15; a fixed 0.5 s was
# too short on a loaded machine, where SIGTERM's default action killed it)
for _ in $(seq 400); do
  mask=$(awk '/^SigCgt:/ {print $2}' "/proc/$play/status" 2>/dev/null || true)
  if [ -n "$mask" ] && (( (16#$mask >> 14) & 1 )); then break; fi
  sleep 0.05
done
kill -TERM $play
start=$(date +%s%N); rc=0; wait $play || rc=$?
[ $(( ($(date +%s%N) - start) / 1000000 )) -lt 2000 ] || fail "ld-play took over 2 s to stop on SIGTERM"
[ $rc -eq 0 ] || fail "ld-play stopped by SIGTERM: exit $rc"
# a duration under half a frame is one frame, not the log once; --fps within 0.001-1000
"$BIN/ld-play" "$T/in.lcmlog" --lcm-url memq:// --duration 0.01 2>"$T/err" || fail "ld-play --duration 0.01: $(cat "$T/err")"
grep -q "published 1 frame (" "$T/err" || fail "ld-play --duration 0.01: $(cat "$T/err")"
rc=0; "$BIN/ld-play" "$T/in.lcmlog" --lcm-url memq:// --fps 1e-10 2>"$T/err" || rc=$?
[ $rc -eq 2 ] && grep -qF "ld-play: --fps: must be in [0.001, 1000], not 1e-10" "$T/err" || fail "ld-play --fps 1e-10: $rc $(cat "$T/err")"
echo "ld-run command line: ok"
