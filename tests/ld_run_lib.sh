# Helpers of the tests that drive ld-run from bash (sourced, not run).
# Callers set `set -euo pipefail` first; T is a fresh temporary folder, and
# RUN the pid of an ld-run started in the background, killed and T removed
# on exit (then extra_cleanup, when a caller defines one).
T=$(mktemp -d)
RUN=
cleanup() {
  [ -n "$RUN" ] && kill -KILL "$RUN" 2>/dev/null || true
  if declare -F extra_cleanup >/dev/null; then extra_cleanup; fi
  rm -rf "$T"
}
trap cleanup EXIT

now_ms() { date +%s%3N; }

# wait_ready STATE_FILE: up to 30 s for ld-run's set to be up (beyond
# ld-run's own 10 s --wait-ready, after which it starts the source anyway);
# status 1, said, when it is not.
wait_ready() {
  for _ in $(seq 300); do
    [ -s "$1" ] && [ "$(jq .ready "$1")" = true ] && return 0
    sleep 0.1
  done
  echo "wait_ready: ld-run's set not up after 30 s: $(cat "$1" 2>/dev/null)" >&2
  return 1
}

# pid_of NAME: the pid ld-run's state file ($T/state.json) gives the process.
pid_of() { jq -r ".processes[] | select(.name == \"$1\") | .pid" "$T/state.json"; }

# kill_and_wait NAME: SIGKILL the process and wait up to 5 s for ld-run to
# start it again; sets old, new (its pids) and dt (ms until it was back).
kill_and_wait() {
  old=$(pid_of "$1")
  # (a process waiting to be started again has pid -1: kill -KILL -1 would
  # kill every process this user may signal)
  if ! [ "$old" -gt 0 ] 2>/dev/null; then
    echo "kill_and_wait: $1 has no running process (pid '$old')" >&2
    return 1
  fi
  kill -KILL "$old"
  local t0
  t0=$(now_ms)
  new=$old
  while [ $(( $(now_ms) - t0 )) -lt 5000 ]; do
    new=$(pid_of "$1")
    if [ "$new" -gt 0 ] && [ "$new" != "$old" ] && kill -0 "$new" 2>/dev/null; then break; fi
    sleep 0.02
  done
  dt=$(( $(now_ms) - t0 ))
  echo "$1: pid $old killed, back as pid $new after $dt ms"
}

# stop_run: SIGTERM to ld-run and wait for it; sets rc (its exit status).
stop_run() {
  kill -TERM "$RUN"
  rc=0
  wait "$RUN" || rc=$?
  RUN=
}
