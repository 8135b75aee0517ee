#!/usr/bin/env bash
# The whole process set, started by ld-run, over real LCM multicast in a
# private network namespace: an ld-synth sequence (a moving camera, three
# landmarks with QR payloads) replayed by lcm-logplayer to ld-detector,
# ld-tracker and ld-qr-reader; lcm-logger (ld-run --record) records their
# outputs and ld-run's monitor the latency of each frame. Checks, against the
# ground truth of the sequence:
#  - every frame is tracked once, with its utime and seq, and has a latency;
#  - every landmark that is in view and not tiny for a few frames is tracked
#    under one id (and no id covers two landmarks), in nearly all of those frames;
#  - every landmark seen large enough to decode has its own payload read;
#  - replaying the same log again gives the same tracks.
set -euo pipefail
BIN=$1
T=$(mktemp -d); trap 'rm -rf "$T"' EXIT
FRAMES=90
MIN_SIDE=24      # px: smaller landmarks are not required to be detected
MIN_FRAMES=5     # frames a landmark must be in view (and large enough) to be required
DECODE_SIDE=64   # px: QR codes of landmarks this large must be read (QR modules >= ~1.4 px)
COVERAGE=0.9     # share of a required landmark's frames in which its track must be seen

# 0.3 m landmarks: 35-110 px at 640x480 along the path, so the QR codes are readable.
"$BIN/ld-synth" sequence --out "$T/seq" --frames $FRAMES --fps 10 --landmarks 3 --seed 11 \
  --size 0.3 --format mjpeg --log "$T/in.lcmlog" --no-png >/dev/null

run_set() {  # $1: run name
  "$BIN/ld-run" --netns --replay "$T/in.lcmlog" --exit-when-replay-done --record "$T/$1.lcmlog" \
    --summary "$T/$1.json" --log-dir "$T" --status-interval 0 -q
  "$BIN/ld-dump" "$T/$1.lcmlog" -c LANDMARKS_TRACKED > "$T/$1.tracked.jsonl"
  "$BIN/ld-dump" "$T/$1.lcmlog" -c LANDMARK_CODES > "$T/$1.codes.jsonl"
}
run_set run1
run_set run2

# 1. Every frame tracked once, with the image's utime and seq, and its latency measured.
jq -c '[.seq, .utime]' "$T/seq/truth.jsonl" | sort > "$T/truth.keys"
jq -c '[.seq, .utime]' "$T/run1.tracked.jsonl" | sort > "$T/run1.keys"
diff "$T/truth.keys" "$T/run1.keys"
[ "$(jq '.summary.frames.images' "$T/run1.json")" -eq $FRAMES ]
[ "$(jq '[.summary.per_frame[] | select(.latency_ms != null and .latency_ms > 0)] | length' "$T/run1.json")" -eq $FRAMES ]
[ "$(jq -r .summary.latency_ms.from "$T/run1.json")" = arrival ]  # (a replay: the logged utimes)
[ "$(jq .summary.tracker_restarts "$T/run1.json")" -eq 0 ]  # (no restart seen where none was)
[ "$(jq '[.processes[] | .restarts] | add' "$T/run1.json")" -eq 0 ]

# 2. Truth landmark -> track id, frame by frame: the visible track whose
#    centre lies within half a side of the truth's centre.
jq -n -c --slurpfile truth "$T/seq/truth.jsonl" --slurpfile trk "$T/run1.tracked.jsonl" '
  def centre: [(.corners | map(.[0]) | add / 4), (.corners | map(.[1]) | add / 4)];
  def side: (.corners[1][0] - .corners[0][0]) as $dx | (.corners[1][1] - .corners[0][1]) as $dy
            | ($dx * $dx + $dy * $dy) | sqrt;
  def vis: .visible == true or .visible == 1;
  ($trk | map({key: (.seq | tostring), value: [.landmarks[] | select(vis) | {id: .track_id, c: centre}]})
        | from_entries) as $tracks
  | [$truth[] | .seq as $s | .landmarks[] | select(.in_view)
     | {id, payload, side: side, c: centre} as $t
     | {id: $t.id, payload: $t.payload, seq: $s, side: $t.side,
        track: ([$tracks[$s | tostring][]
                 | select(((.c[0] - $t.c[0]) | fabs) < $t.side / 2 and ((.c[1] - $t.c[1]) | fabs) < $t.side / 2)
                 | .id] | first)}]
  | group_by(.id)[]
  | {id: .[0].id, payload: .[0].payload,
     required: ([.[] | select(.side >= '$MIN_SIDE')] | length),
     decodable: ([.[] | select(.side >= '$DECODE_SIDE')] | length),
     seen: ([.[] | select(.side >= '$MIN_SIDE' and .track != null)] | length),
     tracks: ([.[] | .track | select(. != null)] | unique)}' > "$T/landmarks.jsonl"
cat "$T/landmarks.jsonl"
jq -r '.codes[] | "\(.track_id) \(.payload)"' "$T/run1.codes.jsonl" | sort -u > "$T/codes"
echo "payloads read (track id, payload):"; cat "$T/codes"
required=$(jq -s "[.[] | select(.required >= $MIN_FRAMES)] | length" "$T/landmarks.jsonl")
[ "$required" -eq 3 ]   # the sequence shows all three landmarks well (else the test proves little)
while read -r lm; do
  id=$(jq -r .id <<<"$lm"); payload=$(jq -r .payload <<<"$lm")
  required=$(jq .required <<<"$lm"); decodable=$(jq .decodable <<<"$lm")
  [ "$required" -ge $MIN_FRAMES ] || continue
  # one stable id, seen in nearly all of its frames
  [ "$(jq '.tracks | length' <<<"$lm")" -eq 1 ] || { echo "landmark $id: tracks $(jq -c .tracks <<<"$lm")"; exit 1; }
  jq -e ".seen >= $COVERAGE * .required" <<<"$lm" >/dev/null || { echo "landmark $id: seen in too few frames"; exit 1; }
  track=$(jq '.tracks[0]' <<<"$lm")
  if [ "$decodable" -ge $MIN_FRAMES ]; then
    # its payload read, for its own track, and no other payload on that track
    [ "$(awk -v t="$track" '$1 == t { print $2 }' "$T/codes")" = "$payload" ] ||
      { echo "landmark $id (track $track): payload not read as \"$payload\""; exit 1; }
  fi
done < "$T/landmarks.jsonl"
# no track id stands for two landmarks
[ "$(jq -s '[.[] | .tracks[]] | (length == (unique | length))' "$T/landmarks.jsonl")" = true ]
# the summary agrees: each read payload on the track the codes name
for id in $(cut -d' ' -f1 "$T/codes"); do
  [ "$(jq -r ".summary.tracks[] | select(.id == $id) | .payload" "$T/run1.json")" = "$(awk -v t="$id" '$1 == t { print $2 }' "$T/codes")" ]
done

# 3. The same log replayed again gives the same tracks, frame by frame.
VIS='def vis: .visible == true or .visible == 1;'
jq -c "$VIS"' [.seq, [.landmarks[] | select(vis) | .track_id]]' "$T/run1.tracked.jsonl" > "$T/ids1"
jq -c "$VIS"' [.seq, [.landmarks[] | select(vis) | .track_id]]' "$T/run2.tracked.jsonl" > "$T/ids2"
diff "$T/ids1" "$T/ids2"
jq -r '.codes[] | "\(.track_id) \(.payload)"' "$T/run2.codes.jsonl" | sort -u > "$T/codes2"
diff "$T/codes" "$T/codes2"

echo "latency (ms): $(jq -c '.summary.latency_ms' "$T/run1.json")"
echo "1 passed, 0 failed"
