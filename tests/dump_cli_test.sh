#!/usr/bin/env bash
# ld-dump on files: a whole log prints one JSON object per message; a file
# that is not an LCM log, or a missing or unreadable one, is refused in one
# line (status 2, as ld-run and ld-play refuse it); a log cut off
# mid-event prints the messages before the cut, then says in one line where
# it ends (status 1), wherever the cut is; bytes that are no event, likewise
# at the end, and skipped with the whole events after them read elsewhere;
# an empty log (a recorder that recorded nothing) is no error.
# usage: dump_cli_test.sh BIN_DIR
set -euo pipefail
BIN=$(cd "$1" && pwd)
T=$(mktemp -d); trap 'rm -rf "$T"' EXIT
fail() { echo "FAIL: $*" >&2; exit 1; }

"$BIN/ld-synth" sequence --out "$T/seq" --frames 3 --fps 10 --landmarks 1 --seed 3 --size 0.3 \
  --format mjpeg --log "$T/in.lcmlog" --no-png >/dev/null
size=$(stat -c %s "$T/in.lcmlog")

# dump FILE...: runs ld-dump; sets rc, out (lines on stdout), err (stderr)
dump() {
  rc=0
  "$BIN/ld-dump" "$@" >"$T/out" 2>"$T/err" || rc=$?
  out=$(wc -l <"$T/out")
  err=$(cat "$T/err")
}

dump "$T/in.lcmlog"
[ $rc -eq 0 ] && [ "$out" -eq 3 ] && [ -z "$err" ] || fail "whole log: exit $rc, $out lines, $err"
# where each event starts: its magic (the MJPEG frames do not contain it here)
mapfile -t starts < <(LC_ALL=C grep -obUaP '\xed\xa1\xda\x01' "$T/in.lcmlog" | cut -d: -f1)
[ "${#starts[@]}" -eq 3 ] || fail "cannot find the events in the log"
[ "${starts[0]}" -eq 0 ] || fail "the log does not start with an event"

# --from / --to: the messages logged that many seconds after the log's
# first (3 frames at 10 frames/s: 0, 0.1 and 0.2 s), ends included
dump "$T/in.lcmlog" --from 0.05 --to 0.1
[ $rc -eq 0 ] && [ "$out" -eq 1 ] && [ "$(jq -r .seq "$T/out")" = 1 ] && [ -z "$err" ] ||
  fail "--from 0.05 --to 0.1: exit $rc, $out lines, $err"
dump "$T/in.lcmlog" --from 0.1
[ $rc -eq 0 ] && [ "$(jq -r .seq "$T/out" | tr '\n' ' ')" = "1 2 " ] || fail "--from 0.1: exit $rc, $(cat "$T/out")"
dump "$T/in.lcmlog" --from 5
[ $rc -eq 0 ] && [ "$out" -eq 0 ] &&
  [ "$err" = "ld-dump: note: no message from 5 s on after a log's first (the longest log spans 0.2 s)" ] ||
  fail "--from past the end: exit $rc, $err"
# a log whose clock goes back (two sessions appended): every message without
# a span (those before the first were dropped); with one, those logged
# before the first are outside it
cat "$T/in.lcmlog" "$T/in.lcmlog" >"$T/appended.lcmlog"
dump "$T/appended.lcmlog"
[ $rc -eq 0 ] && [ "$out" -eq 6 ] || fail "appended log: exit $rc, $out lines, $err"
dump "$T/appended.lcmlog" --to 0.1
[ $rc -eq 0 ] && [ "$(jq -r .seq "$T/out" | tr '\n' ' ')" = "0 1 0 1 " ] || fail "appended --to 0.1: $(cat "$T/out")"
# a misspelt channel with a span: the channel is said, not the span
dump "$T/in.lcmlog" -c IMAGX --from 0.1
[ $rc -eq 0 ] && grep -q "^ld-dump: note: no channel of the logs matches -c" "$T/err" || fail "-c IMAGX --from: $err"
for bad in "--from 0.3 --to 0.1|--to 0.1 is before --from 0.3" "--to -1|--to: must be >= 0, not -1" \
           "--live --from 1|--from and --to are for logs (seconds after a log's first message)"; do
  read -ra args <<<"${bad%%|*}"
  [ "${args[0]}" = --live ] && dump "${args[@]}" || dump "$T/in.lcmlog" "${args[@]}"
  [ $rc -eq 2 ] && [ "$err" = "ld-dump: ${bad#*|} (--help lists the options)" ] || fail "${bad%%|*}: exit $rc, $err"
done

printf '\x89PNG\r\n\x1a\n an image, not a log' >"$T/lm.png"
dump "$T/lm.png"
[ $rc -eq 2 ] && [ "$out" -eq 0 ] || fail "not a log: exit $rc, $out lines"
[ "$err" = "ld-dump: $T/lm.png is not an LCM log (it starts with 89 50 4e 47, not LCM's event magic ed a1 da 01)" ] ||
  fail "not a log: $err"

# cut CUT_AT EXPECTED_MESSAGES PATTERN: the log's first CUT_AT bytes
cut_at() {
  head -c "$1" "$T/in.lcmlog" >"$T/cut.lcmlog"
  dump "$T/cut.lcmlog"
  [ $rc -eq 1 ] || fail "cut at $1: exit $rc"
  [ "$out" -eq "$2" ] || fail "cut at $1: $out messages printed, not $2"
  [ "$(wc -l <"$T/err")" -eq 1 ] && grep -q "^ld-dump: $T/cut.lcmlog: $3" "$T/err" || fail "cut at $1: $err"
  echo "cut at $1: $out messages, $err"
}
cut_at $((size - 100)) 2 "the log ends mid-event after 2 messages ([0-9]* of the event's [0-9]* bytes)$"
cut_at $((starts[2] + 2)) 2 "the log ends mid-event after 2 messages (2 bytes of an event header)$"
cut_at $((starts[1] + 20)) 1 "the log ends mid-event after 1 message (20 bytes of an event header)$"
cut_at 10 0 "the log ends mid-event after 0 messages (10 bytes of an event header)$"
cut_at 3 0 "the log ends mid-event after 0 messages (3 bytes of an event header)$"  # (within the magic: a cut log, not another file)

{ cat "$T/in.lcmlog"; printf 'trailing junk'; } >"$T/junk.lcmlog"
dump "$T/junk.lcmlog"
[ $rc -eq 1 ] && [ "$out" -eq 3 ] || fail "junk: exit $rc, $out lines"
[ "$err" = "ld-dump: $T/junk.lcmlog: unreadable data after 3 messages (at byte $size no LCM event starts)" ] ||
  fail "junk: $err"
# an event header whose data length is over 2^31 (unsigned in the format):
# said as it is written ("-16 bytes of data" before)
{ cat "$T/in.lcmlog"; printf '\xed\xa1\xda\x01\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\x05\xff\xff\xff\xf0IMAGE'; } >"$T/huge.lcmlog"
dump "$T/huge.lcmlog"
[ $rc -eq 1 ] && [ "$out" -eq 3 ] &&
  [ "$err" = "ld-dump: $T/huge.lcmlog: unreadable data after 3 messages (at byte $size an event header with a channel of 5 bytes and 4294967280 bytes of data)" ] ||
  fail "a huge data length: exit $rc, $err"

# A cut event with more appended after it (a recorder killed mid-write and
# restarted with lcm-logger -a): the cut event is skipped, every whole one
# before and after it printed, and one line says what was skipped (status 1).
{ head -c $((starts[1] + 100)) "$T/in.lcmlog"; cat "$T/in.lcmlog"; } >"$T/mid.lcmlog"
dump "$T/mid.lcmlog"
[ $rc -eq 1 ] && [ "$out" -eq 4 ] || fail "cut in the middle: exit $rc, $out lines, $err"
[ "$err" = "ld-dump: $T/mid.lcmlog: skipped 100 bytes that are no whole LCM event (at byte ${starts[1]}), read 4 messages" ] ||
  fail "cut in the middle: $err"
# Junk between events, likewise.
{ head -c "${starts[1]}" "$T/in.lcmlog"; printf 'junk!'; tail -c +$((starts[1] + 1)) "$T/in.lcmlog"; } >"$T/junk2.lcmlog"
dump "$T/junk2.lcmlog"
[ $rc -eq 1 ] && [ "$out" -eq 3 ] || fail "junk between events: exit $rc, $out lines, $err"
[ "$err" = "ld-dump: $T/junk2.lcmlog: skipped 5 bytes that are no whole LCM event (at byte ${starts[1]}), read 3 messages" ] ||
  fail "junk between events: $err"

: >"$T/empty.lcmlog"
dump "$T/empty.lcmlog"
[ $rc -eq 0 ] && [ "$out" -eq 0 ] && [ -z "$err" ] || fail "empty log: exit $rc, $out lines, $err"

# a missing log and a folder: one line each, status 2
dump "$T/missing.lcmlog"
[ $rc -eq 2 ] && [ "$out" -eq 0 ] && [ "$(wc -l <"$T/err")" -eq 1 ] && grep -q "cannot read log $T/missing.lcmlog" "$T/err" \
  || fail "missing log: exit $rc, $out lines, $(cat "$T/err")"
dump "$T"
[ $rc -eq 2 ] && [ "$out" -eq 0 ] && [ "$(wc -l <"$T/err")" -eq 1 ] || fail "a folder: exit $rc, $out lines, $(cat "$T/err")"

# several files: each is dumped or reported; the worst status wins
dump "$T/in.lcmlog" "$T/cut.lcmlog" "$T/in.lcmlog"
[ $rc -eq 1 ] && [ "$out" -eq 6 ] || fail "several: exit $rc, $out lines"
dump "$T/cut.lcmlog" "$T/lm.png" "$T/in.lcmlog"
[ $rc -eq 2 ] && [ "$out" -eq 3 ] && [ "$(wc -l <"$T/err")" -eq 2 ] || fail "several: exit $rc, $out lines, $err"
dump "$T/in.lcmlog" "$T/missing.lcmlog" "$T/in.lcmlog"
[ $rc -eq 2 ] && [ "$out" -eq 6 ] || fail "several with a missing one: exit $rc, $out lines"
# a channel pattern that matches none of the logs' channels: a note naming them
dump "$T/in.lcmlog" -c image
[ $rc -eq 0 ] && [ "$out" -eq 0 ] &&
  [ "$err" = "ld-dump: note: no channel of the logs matches -c (a pattern matches the whole name, case and all); their channels: IMAGE" ] ||
  fail "-c matching nothing: exit $rc, $err"
dump "$T/in.lcmlog" -c IMAGE
[ $rc -eq 0 ] && [ "$out" -eq 3 ] && [ -z "$err" ] || fail "-c IMAGE: exit $rc, $out lines, $err"
# --live, in a private network namespace: the bus's messages, without LCM's
# self-test messages (its own and the player's came first, as "not a
# project message"), unless a pattern asks for them
"$(dirname "$0")/../scripts/netns-run.sh" bash -c '
  set -euo pipefail
  BIN=$1; T=$2
  "$BIN/ld-dump" --live >"$T/live.out" 2>"$T/live.err" &
  all=$!
  "$BIN/ld-dump" --live -c "LCM_.*" >"$T/self.out" 2>"$T/self.err" &
  self=$!
  "$BIN/ld-dump" --live >/dev/full 2>"$T/full.err" &
  full=$!
  source "$3/lcm_sockets.sh"
  lcm_sockets 3
  "$BIN/ld-play" "$T/in.lcmlog" --fps 30 2>/dev/null
  sleep 0.5
  kill -INT $all $self; wait $all; wait $self
  # (output that cannot be written ends it, said, status 1: it ran on, silent)
  kill -INT $full 2>/dev/null || true
  rc=0; wait $full || rc=$?; echo $rc >"$T/full.rc"
' _ "$BIN" "$T" "$(dirname "$0")" || fail "--live: $(cat "$T/live.err" "$T/self.err" 2>/dev/null)"
[ "$(cat "$T/full.rc")" = 1 ] && grep -q "^ld-dump: write to stdout failed: No space left on device" "$T/full.err" ||
  fail "--live to a full disk: $(cat "$T/full.rc") $(cat "$T/full.err")"
[ "$(grep -c '"channel":"IMAGE"' "$T/live.out")" -eq 3 ] && ! grep -q LCM_SELF_TEST "$T/live.out" ||
  fail "--live: $(cat "$T/live.out" "$T/live.err")"
grep -q '"channel":"LCM_SELF_TEST"' "$T/self.out" && ! grep -q '"channel":"IMAGE"' "$T/self.out" ||
  fail "--live -c 'LCM_.*': $(cat "$T/self.out" "$T/self.err")"
# a pipe (a log read from its start more than once): refused in one line
# (it was read from where the first look stopped: "cannot read log /dev/fd/63")
dump <(cat "$T/in.lcmlog")
[ $rc -eq 2 ] && [ "$out" -eq 0 ] && [ "$err" = "ld-dump: cannot read log /dev/fd/63: it is not a file (a pipe, a device?): logs are read from files" ] ||
  fail "a pipe: exit $rc: $err"
# ... and a named pipe no one writes into, before a log: said, the log after
# it dumped (opening it waited for a writer for ever)
mkfifo "$T/fifo.lcmlog"
rc=0; timeout 20 "$BIN/ld-dump" "$T/fifo.lcmlog" "$T/in.lcmlog" >"$T/out" 2>"$T/err" || rc=$?
[ $rc -eq 2 ] && [ "$(cat "$T/err")" = "ld-dump: cannot read log $T/fifo.lcmlog: it is not a file (a pipe, a device?): logs are read from files" ] &&
  [ "$(wc -l <"$T/out")" -eq "$(timeout 20 "$BIN/ld-dump" "$T/in.lcmlog" | wc -l)" ] || fail "a named pipe: exit $rc: $(cat "$T/err")"
rc=0; "$BIN/ld-view" --log <(cat "$T/in.lcmlog") --all --out "$T/v0" 2>"$T/err" || rc=$?
[ $rc -eq 2 ] && [ ! -e "$T/v0" ] && grep -q "^ld-view: log /dev/fd/[0-9]* cannot be read: it is not a file (a pipe, a device?)" "$T/err" ||
  fail "ld-view, a pipe: exit $rc: $(cat "$T/err")"
# logs and --live, or --lcm-url with logs: refused in one line
dump "$T/in.lcmlog" --live
[ $rc -eq 2 ] && [ "$err" = "ld-dump: give log files or --live, not both (--help lists the options)" ] || fail "both: $err"
dump "$T/in.lcmlog" --lcm-url memq://
[ $rc -eq 2 ] && grep -q "^ld-dump: --lcm-url is for --live" "$T/err" || fail "--lcm-url with logs: $err"
# a dump that cannot be written all (a full disk) is status 1, said
rc=0; "$BIN/ld-dump" "$T/in.lcmlog" >/dev/full 2>"$T/err" || rc=$?
[ $rc -eq 1 ] && grep -q "^ld-dump: write to stdout failed" "$T/err" || fail "full disk: exit $rc, $(cat "$T/err")"
# a message of the project's type that is damaged: what was wrong with it
# ("not a project message" before, where ld-play and ld-view said why)
python3 - "$T/in.lcmlog" "$T/short.lcmlog" <<'PY'
import struct, sys
data = open(sys.argv[1], 'rb').read()
sync, num, ts, clen, dlen = struct.unpack_from('>IqqII', data, 0)
event = data[28:28 + clen + 50]  # the channel, and the first image's first 50 bytes
open(sys.argv[2], 'wb').write(struct.pack('>IqqII', sync, num, ts, clen, 50) + event)
PY
"$BIN/ld-dump" "$T/short.lcmlog" >"$T/out" 2>"$T/err" || true
grep -q '"error":"not a valid ld.image_t (50 bytes): image size [0-9]* does not fit in the 14 bytes left at byte 36"' "$T/out" ||
  fail "a damaged image_t: $(cat "$T/out")"
# LANDMARK_CODES of an older build (ld.qr_code_list_t before
# withheld_track_ids): said as an earlier version, not as another program's
python3 - "$T/old.lcmlog" <<'PY'
import struct, sys
data = bytes.fromhex('553eb387ecca27c4') + struct.pack('>qqi', 1000, 7, 0)
ch = b'LANDMARK_CODES'
open(sys.argv[1], 'wb').write(struct.pack('>IqqII', 0xEDA1DA01, 0, 1000, len(ch), len(data)) + ch + data)
PY
dump "$T/old.lcmlog"
[ $rc -eq 0 ] && grep -qF '"error":"an ld.qr_code_list_t before withheld_track_ids (2026-12-07), an earlier version no longer decoded (28 bytes; a recording by an older build?)"' "$T/out" ||
  fail "an earlier version's message: exit $rc, $(cat "$T/out")"
echo "ld-dump on files: ok"
