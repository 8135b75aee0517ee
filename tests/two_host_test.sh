#!/usr/bin/env bash
# Two "hosts" on one machine: two network namespaces joined by a veth pair
# that this test makes (and removes), with the multicast route over the veth
# only and ttl=1 in the LCM URL, so every message crosses exactly one hop.
# Host A replays the log (ld-run --processes none); host B runs ld-detector,
# ld-tracker and ld-qr-reader (ld-run --source none) and records their
# output. The tracks must be the same as those of the whole set on one host
# (ld-run --netns), frame by frame, with the same payloads.
set -euo pipefail
BIN=$1
[ "$(id -u)" -eq 0 ] || { echo "needs root (ip netns, veth)"; exit 77; }
A=ldA$$; B=ldB$$; VA=vA$$; VB=vB$$
extra_cleanup() {
  ip netns del "$A" 2>/dev/null || true
  ip netns del "$B" 2>/dev/null || true
}
source "$(dirname "$0")/ld_run_lib.sh"
FRAMES=60
"$BIN/ld-synth" sequence --out "$T/seq" --frames $FRAMES --fps 10 --landmarks 3 --seed 11 --size 0.3 \
  --format mjpeg --log "$T/in.lcmlog" --no-png >/dev/null

# One host: the reference.
"$BIN/ld-run" --netns --replay "$T/in.lcmlog" --exit-when-replay-done --record "$T/one.lcmlog" \
  --summary "$T/one.json" --status-interval 0 -q

# Two hosts.
ip netns add "$A"
ip netns add "$B"
ip link add "$VA" type veth peer name "$VB"
ip link set "$VA" netns "$A"
ip link set "$VB" netns "$B"
ip -n "$A" addr add 10.231.0.1/30 dev "$VA"
ip -n "$B" addr add 10.231.0.2/30 dev "$VB"
for ns in "$A" "$B"; do ip -n "$ns" link set lo up; done
ip -n "$A" link set "$VA" up
ip -n "$B" link set "$VB" up
ip -n "$A" route add 224.0.0.0/4 dev "$VA"
ip -n "$B" route add 224.0.0.0/4 dev "$VB"
URL="udpm://239.255.76.67:7667?ttl=1&recv_buf_size=8388608"

ip netns exec "$B" env LD_IN_NETNS=1 "$BIN/ld-run" --lcm-url "$URL" --source none --record "$T/two.lcmlog" \
  --summary "$T/b.json" --state-file "$T/b.state" --log-dir "$T" --status-interval 0 -q &
RUN=$!
wait_ready "$T/b.state"
[ "$(jq .ready "$T/b.state")" = true ]
ip netns exec "$A" env LD_IN_NETNS=1 "$BIN/ld-run" --lcm-url "$URL" --processes none \
  --replay "$T/in.lcmlog" --exit-when-replay-done --drain 0.5 --summary "$T/a.json" --status-interval 0 -q
sleep 1.5  # B finishes the last frames
stop_run
[ "$rc" -eq 0 ]

VIS='def vis: .visible == true or .visible == 1;'
for run in one two; do
  "$BIN/ld-dump" "$T/$run.lcmlog" -c LANDMARKS_TRACKED |
    jq -c "$VIS"' [.seq, .utime, [.landmarks[] | select(vis) | .track_id]]' > "$T/$run.ids"
  "$BIN/ld-dump" "$T/$run.lcmlog" -c LANDMARK_CODES | jq -r '.codes[] | "\(.track_id) \(.payload)"' |
    sort -u > "$T/$run.codes"
done
echo "one host: $(wc -l < "$T/one.ids") tracked frames, two hosts: $(wc -l < "$T/two.ids")"
echo "payloads on two hosts:"; cat "$T/two.codes"
echo "host A saw $(jq .summary.frames.tracked "$T/a.json") tracked frames come back over the veth;" \
     "host B latency (ms): $(jq -c .summary.latency_ms "$T/b.json")"
[ "$(wc -l < "$T/two.ids")" -eq $FRAMES ]
diff "$T/one.ids" "$T/two.ids"
diff "$T/one.codes" "$T/two.codes"
[ "$(wc -l < "$T/two.codes")" -ge 3 ]
# the outputs crossed the veth back to A (one hop, ttl=1)
[ "$(jq .summary.frames.tracked "$T/a.json")" -eq $FRAMES ]
echo "1 passed, 0 failed"
