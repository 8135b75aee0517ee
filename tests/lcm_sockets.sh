# lcm_sockets N: waits (up to 30 s) until N sockets are bound to LCM's port
# (7667, 0x1DF3 in /proc/net/udp) in this network namespace, one per
# subscribing process, then 0.5 s for LCM's self test (which drops what
# arrives meanwhile); status 1, said, when they are not. Sourced by the
# tests' scripts that run inside scripts/netns-run.sh: processes take 0.2 s
# to 2.6 s to subscribe on a loaded machine, where fixed sleeps lost frames.
lcm_sockets() {
  for _ in $(seq 600); do
    if [ "$(grep -c ":1DF3 " /proc/net/udp)" -ge "$1" ]; then
      sleep 0.5
      return 0
    fi
    sleep 0.05
  done
  echo "lcm_sockets: not $1 sockets on port 7667 after 30 s" >&2
  return 1
}
