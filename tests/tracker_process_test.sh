#!/usr/bin/env bash
# End to end over real LCM (UDP multicast on loopback in a private network
# namespace): a LANDMARKS log with three known tracks, replayed by
# lcm-logplayer to a live ld-tracker; lcm-logger records LANDMARKS_TRACKED.
# Every frame must come back once with its utime and seq, the three landmarks
# must keep three ids, the hidden one must coast (visible = false) and come
# back with its id; malformed messages are reported and do not stop the
# process, which exits cleanly on SIGINT. Bad options and channels that
# would feed a process itself are refused first.
set -euo pipefail
BIN=$1; ROOT=$2
T=$(mktemp -d); trap 'rm -rf "$T"' EXIT
FRAMES=40
"$BIN/ld-tracker-testlog" --out "$T/in.lcmlog" --frames $FRAMES --non-finite-at 20
# played with every list twice, the copy 10 ms after (a recording replayed
# onto the running set): each frame must still be tracked once
python3 - "$T/in.lcmlog" "$T/twice.lcmlog" <<'PY'
import struct, sys
data = open(sys.argv[1], 'rb').read(); out = bytearray(); pos = n = 0
while pos + 28 <= len(data):
    sync, num, ts, clen, dlen = struct.unpack_from('>IqqII', data, pos)
    event = data[pos + 28:pos + 28 + clen + dlen]
    for dt in (0, 10000):
        out += struct.pack('>IqqII', sync, n, ts + dt, clen, dlen) + event; n += 1
    pos += 28 + clen + dlen
open(sys.argv[2], 'wb').write(out)
PY

# Refused before LCM is opened, one line each, status 2: out-of-range
# parameters named by their option, and channels that would feed a process
# its own output (LCM reads --in as a pattern) or are empty.
for args in "ld-tracker --max-lifetime 0|--max-lifetime: must be > 0, not 0" \
            "ld-tracker --max-distance 0|--max-distance: must be in (0, 1000], not 0" \
            "ld-tracker --max-lifetime 1e-9|ld-tracker: max_lifetime_s must be a number of seconds, at least 1e-6" \
            "ld-tracker --max-distance 1001|--max-distance: must be in (0, 1000], not 1001" \
            "ld-tracker --min-hits 2147483648|--min-hits: must be in [1, 1000], not 2147483648" \
            "ld-tracker --max-size-ratio 0.5|--max-size-ratio: must be in [1, 1000], not 0.5" \
            "ld-tracker --min-hits 1.5|--min-hits: '1.5' is not a value it takes (a number of its kind" \
            "ld-tracker --in LANDMARKS.*|--in LANDMARKS.* takes the tracker's own output LANDMARKS_TRACKED: it would feed itself" \
            "ld-tracker --in X --out X|--in X takes the tracker's own output X" \
            "ld-tracker --in LANDMARKS\w*|--in LANDMARKS\w* takes the tracker's own output" \
            "ld-detector --in .*|--in .* takes the detector's own output LANDMARKS" \
            "ld-detector --explain 1e10|--explain: must be in [0, 86400], not 1e10" \
            "ld-qr-reader --tracks LANDMARK.*|--tracks LANDMARK.* takes the reader's own output LANDMARK_CODES" \
            "ld-qr-reader --image X --tracks X|--image X and --tracks X take the same channel: each needs its own" \
            "ld-qr-reader --image LANDMARKS_TRACKED|--image LANDMARKS_TRACKED and --tracks LANDMARKS_TRACKED take the same channel" \
            "ld-tracker --in LANDMARKS[|--in LANDMARKS[: LCM reads a subscription's channel as a regular expression, and this is none (missing terminating ] for character class)" \
            "ld-detector --in (|--in (: LCM reads a subscription's channel as a regular expression, and this is none (missing terminating ))"; do
  cmd=${args%%|*}; rc=0
  # (no glob: the patterns are passed as written)
  set -f; timeout 10 "$BIN/${cmd%% *}" ${cmd#* } >/dev/null 2>"$T/err" || rc=$?; set +f
  [ $rc -eq 2 ] && [ "$(wc -l <"$T/err")" -eq 1 ] && grep -qF -- "${args#*|}" "$T/err" ||
    { echo "FAIL: $cmd: exit $rc, $(cat "$T/err")"; exit 1; }
done
# LCM that will not open: a network without its multicast route (a private
# namespace with none, as at boot before the network is up) is status 1, a
# supervisor's to retry; a wrong URL is 2, which no restart mends.
flags=-n; [ "$(id -u)" -eq 0 ] || flags=-rn
rc=0; timeout 10 unshare $flags "$BIN/ld-tracker" >/dev/null 2>"$T/err" || rc=$?
[ $rc -eq 1 ] && grep -q "^ld-tracker: cannot open LCM at udpm://" "$T/err" || { echo "FAIL: no route: $rc $(cat "$T/err")"; exit 1; }
# an empty URL (an unset variable): LCM took it for its own default, without
# the receive buffer large images need
rc=0; timeout 10 "$BIN/ld-tracker" --lcm-url "" >/dev/null 2>"$T/err" || rc=$?
[ $rc -eq 2 ] && grep -q "^ld-tracker: LCM URL is empty (leave the option out for udpm://" "$T/err" || { echo "FAIL: empty URL: $rc $(cat "$T/err")"; exit 1; }
rc=0; timeout 10 "$BIN/ld-tracker" --lcm-url bogus://x >/dev/null 2>"$T/err" || rc=$?
[ $rc -eq 2 ] && grep -q "^ld-tracker: LCM URL bogus://x: LCM has no provider bogus" "$T/err" || { echo "FAIL: bogus URL: $rc $(cat "$T/err")"; exit 1; }
# a udpm URL without a port (LCM took it as port 0: it never received, and
# its wait aborted the process after a while), or with a group that is not
# multicast: refused at once
# a ttl or recv_buf_size that is no number (LCM took it as 0, said so on a line of its own, and ran on),
# or an option udpm does not have (a misspelt ttl: LCM said so on a line of its own and ran on)
for url in "udpm://239.255.76.67|no port" "udpm://999.1.1.1:7667|999.1.1.1 is not a multicast group" \
  "udpm://239.255.76.67:7667?ttl=abc|ttl abc is not one (0 to 255: 0 keeps packets on this machine, 1 on its LAN)" \
  "udpm://239.255.76.67:7667?ttl=0&recv_buf_size=-1|recv_buf_size -1 is not one (0 to 2147483647 bytes, 0 LCM's default)" \
  "udpm://239.255.76.67:7667?tll=1|udpm has no option tll (ttl, recv_buf_size; e.g. "; do
  rc=0; timeout 10 "$BIN/ld-tracker" --lcm-url "${url%%|*}" >/dev/null 2>"$T/err" || rc=$?
  [ $rc -eq 2 ] && grep -q "^ld-tracker: LCM URL ${url%%|*}: ${url#*|}" "$T/err" || { echo "FAIL: ${url%%|*}: $rc $(cat "$T/err")"; exit 1; }
done
# a tcpq URL whose server is not there (in a private namespace: loopback
# only): LCM opens without a connection, and its wait aborted the process
# (SIGABRT, "bit out of range ... on fd_set"): status 1, a supervisor retries
rc=0; timeout 10 "$ROOT/scripts/netns-run.sh" "$BIN/ld-tracker" --lcm-url tcpq://127.0.0.1:7700 >/dev/null 2>"$T/err" || rc=$?
[ $rc -eq 1 ] && grep -q "^ld-tracker: cannot open LCM at tcpq://127.0.0.1:7700 (no connection: is its tcpq server running?)$" "$T/err" ||
  { echo "FAIL: tcpq without a server: $rc $(cat "$T/err")"; exit 1; }
rc=0; timeout 10 "$BIN/ld-tracker" --in "" >/dev/null 2>"$T/err" || rc=$?
[ $rc -eq 2 ] && grep -qF -- "--in needs a channel name" "$T/err" || { echo "FAIL: --in '': $rc $(cat "$T/err")"; exit 1; }

"$ROOT/scripts/netns-run.sh" bash -c '
  set -euo pipefail
  BIN=$1; T=$2
  URL="udpm://239.255.76.67:7667?ttl=0&recv_buf_size=8388608"
  lcm-logger --lcm-url="$URL" -c LANDMARKS_TRACKED -f "$T/out.lcmlog" >/dev/null 2>&1 &
  logger=$!
  "$BIN/ld-tracker" --lcm-url "$URL" 2> "$T/tracker.err" &
  trk=$!
  sleep 1
  "$BIN/ld-publish-garbage" --lcm-url "$URL" --channel LANDMARKS
  sleep 0.3
  "$BIN/ld-publish-garbage" --lcm-url "$URL" --channel LANDMARKS --big-list 5000
  sleep 0.3
  lcm-logplayer --lcm-url="$URL" "$T/twice.lcmlog"
  sleep 1
  kill -0 $trk   # still running after the bad messages
  kill -INT $trk; wait $trk
  kill -INT $logger; wait $logger || true
' test "$BIN" "$T"

"$BIN/ld-dump" "$T/in.lcmlog" | jq -c '[.seq, .utime]' | sort > "$T/in.keys"
"$BIN/ld-dump" "$T/out.lcmlog" -c LANDMARKS_TRACKED > "$T/out.jsonl"
jq -c '[.seq, .utime]' "$T/out.jsonl" | sort > "$T/out.keys"
n_out=$(wc -l < "$T/out.jsonl")
ids=$(jq -c '[.landmarks[].track_id]' "$T/out.jsonl" | jq -s -c 'add | unique')
# visible may be written as a boolean or as 0/1
VIS='def vis: if (.visible | type) == "boolean" then .visible else .visible != 0 end;'
coasting=$(jq -c "$VIS"' select([.landmarks[] | select(vis | not)] | length > 0) | .seq' "$T/out.jsonl" | wc -l)
echo "frames in: $FRAMES, LANDMARKS_TRACKED out: $n_out, track ids: $ids, frames with a coasting track: $coasting"
cat "$T/tracker.err"
diff "$T/in.keys" "$T/out.keys"                          # each frame once, same utime and seq
[ "$(jq -r .backend "$T/out.jsonl" | sort -u)" = tracker ]
[ "$(jq -r '.stage_ms | has("saturation") and has("track")' "$T/out.jsonl" | sort -u)" = true ]
[ "$ids" = "[1,2,3]" ]                                   # three landmarks, three ids
[ "$coasting" -eq 5 ]                                    # C hidden for 5 frames, coasting
# C (id 3) is back and visible in the last frame, with age = frames since creation.
[ "$(jq -c "$VIS"' select(.seq == 1039) | [.landmarks[] | select(.track_id == 3) | vis, .age, .frames_since_seen]' "$T/out.jsonl")" = "[true,39,0]" ]
# While hidden: frames_since_seen and time_since_seen_us count up.
[ "$(jq -c 'select(.seq == 1012) | [.landmarks[] | select(.track_id == 3) | .frames_since_seen, .time_since_seen_us]' "$T/out.jsonl")" = "[3,150000]" ]
# The payload read once stays with its track.
[ "$(jq -r '.landmarks[] | select(.track_id == 1) | .payload' "$T/out.jsonl" | sort -u)" = A ]
grep -q "dropped message" "$T/tracker.err"               # the garbage was reported
# a list far beyond what a detector finds: dropped, said (it stalled the
# tracker for seconds and took hundreds of MB)
grep -q "^ld-tracker: dropped message: message on LANDMARKS is a list of 5000 landmarks (frame 0), more than the 1000 the tracker takes" "$T/tracker.err"
grep -q "stopped after" "$T/tracker.err"                  # clean exit on SIGINT
# a landmark whose corners are not numbers is not tracked, and said so
grep -q "^ld-tracker: 1 landmark of the list on LANDMARKS for frame 1020 (utime [0-9]*) not tracked: corners not finite" "$T/tracker.err"
grep -q "stopped after .*, 1 landmark not tracked, 0 late, [1-9][0-9]* repeated)" "$T/tracker.err"
grep -q "^ld-tracker: frame 10[0-9][0-9] (utime [0-9]*) came again: tracked once" "$T/tracker.err"

# Two publishers on LANDMARKS whose clocks are 5 s apart, interleaved (a
# second camera, a host with its clock off): every list of the one behind
# restarts the tracks. Said as bad input is, the first 10 in full, then
# every 100th (it was said at every list: 15 lines a second). (The lists of
# the clock behind come 20 ms after the others, each read on its own.)
python3 - "$T/in.lcmlog" "$T/clocks.lcmlog" <<'PY'
import struct, sys
data = open(sys.argv[1], 'rb').read(); out = bytearray(); pos = n = 0
while pos + 28 <= len(data):
    sync, num, ts, clen, dlen = struct.unpack_from('>IqqII', data, pos)
    chan = data[pos + 28:pos + 28 + clen]; msg = data[pos + 28 + clen:pos + 28 + clen + dlen]
    pos += 28 + clen + dlen
    if chan != b'LANDMARKS' or len(msg) < 24: continue
    utime, seq = struct.unpack_from('>qq', msg, 8)
    for k, back in enumerate((0, 5_000_000)):
        m = bytearray(msg); struct.pack_into('>qq', m, 8, utime - back, seq + 100000 * k)
        out += struct.pack(">IqqII", sync, n, ts + 20000 * k, clen, len(m)) + chan + m; n += 1
open(sys.argv[2], 'wb').write(out)
PY
"$ROOT/scripts/netns-run.sh" bash -c '
  set -euo pipefail
  BIN=$1; T=$2
  URL="udpm://239.255.76.67:7667?ttl=0&recv_buf_size=8388608"
  "$BIN/ld-tracker" --lcm-url "$URL" 2> "$T/clocks.err" &
  trk=$!
  sleep 1
  lcm-logplayer --lcm-url="$URL" "$T/clocks.lcmlog"
  sleep 0.5
  kill -INT $trk; wait $trk
' test "$BIN" "$T"
said=$(grep -c "tracks restarted" "$T/clocks.err" || true)
echo "two clocks: restarts said $said times"
[ "$said" -eq 10 ] || { echo "FAIL: two clocks: $(cat "$T/clocks.err")"; exit 1; }
grep -q "two publishers on LANDMARKS with clocks apart): tracks restarted (10 restarts so far; from here on every 100th is printed, all are counted)" "$T/clocks.err" ||
  { echo "FAIL: two clocks: $(cat "$T/clocks.err")"; exit 1; }
echo "1 passed, 0 failed"
