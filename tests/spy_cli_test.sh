#!/usr/bin/env bash
# ld-spy's own command line: --help prints the wrapper's usage (its options,
# then that the others go to lcm-spy) and exits 0; without a display it
# refuses in one line that says what to do on a headless robot (instead of
# Java's HeadlessException), and --list-types still works there.
# usage: spy_cli_test.sh LD_SPY
set -euo pipefail
spy=$1
T=$(mktemp -d); trap 'rm -rf "$T"' EXIT
fail() { echo "FAIL: $*" >&2; exit 1; }

for h in --help -h; do
  rc=0; "$spy" $h >"$T/out" 2>"$T/err" || rc=$?
  [ $rc -eq 0 ] || fail "$h: exit $rc"
  [ ! -s "$T/err" ] || fail "$h: stderr: $(cat "$T/err")"
  grep -q '^usage: ld-spy' "$T/out" && grep -q -- '--list-types' "$T/out" && grep -q -- '--types-jar' "$T/out" &&
    grep -q 'lcm-spy' "$T/out" || fail "$h: $(cat "$T/out")"
done

# headless: no DISPLAY (WAYLAND_DISPLAY alone does not give Java a display);
# in a private network namespace, should lcm-spy start after all
netns=$(dirname "$0")/../scripts/netns-run.sh
for env in "env -u DISPLAY -u WAYLAND_DISPLAY" "env -u DISPLAY WAYLAND_DISPLAY=wayland-0"; do
  rc=0; timeout 20 "$netns" $env "$spy" --lcm-url 'udpm://239.255.76.67:7667?ttl=0' >"$T/out" 2>"$T/err" || rc=$?
  [ $rc -eq 2 ] || fail "$env: exit $rc: $(cat "$T/err")"
  [ "$(wc -l <"$T/err")" -eq 1 ] || fail "$env: not one line: $(cat "$T/err")"
  grep -q "^ld-spy: lcm-spy needs a display.*robot's LAN.*ld-dump --live" "$T/err" || fail "$env: $(cat "$T/err")"
done
echo "headless: $(cat "$T/err")"
# a local display with no X server behind it (a stale DISPLAY): one line too
rc=0; timeout 20 "$netns" env DISPLAY=:97 "$spy" --lcm-url 'udpm://239.255.76.67:7667?ttl=0' >"$T/out" 2>"$T/err" || rc=$?
if [ ! -S /tmp/.X11-unix/X97 ]; then
  [ $rc -eq 2 ] && [ "$(wc -l <"$T/err")" -eq 1 ] || fail "DISPLAY=:97: exit $rc: $(cat "$T/err")"
  grep -q "^ld-spy: no X server on display :97 (no /tmp/.X11-unix/X97)" "$T/err" || fail "DISPLAY=:97: $(cat "$T/err")"
fi
# (the list is read whole before it is searched: grep -q ends at the first
# match, and under pipefail ld-spy's SIGPIPE on the next line failed the test)
# a remote display nothing answers on (an ssh -X session that ended): one
# line too (Java's stack trace before), inside the namespace's loopback
rc=0; timeout 20 "$netns" env DISPLAY=localhost:97.0 "$spy" --lcm-url 'udpm://239.255.76.67:7667?ttl=0' >"$T/out" 2>"$T/err" || rc=$?
[ $rc -eq 2 ] && [ "$(wc -l <"$T/err")" -eq 1 ] || fail "DISPLAY=localhost:97.0: exit $rc: $(cat "$T/err")"
grep -q "^ld-spy: no X server answers on display localhost:97.0 (port 6097 of localhost" "$T/err" ||
  fail "DISPLAY=localhost:97.0: $(cat "$T/err")"
listed=$(env -u DISPLAY -u WAYLAND_DISPLAY "$spy" --list-types) || fail "--list-types headless: exit $?"
grep -qx ld.image_t <<<"$listed" || fail "--list-types headless: $listed"
# its own options after lcm-spy's too; a types jar that is not one, or holds no ld.* type, said so
listed=$(env -u DISPLAY -u WAYLAND_DISPLAY "$spy" --lcm-url 'udpm://239.255.76.67:7667?ttl=0' --list-types) ||
  fail "--list-types after --lcm-url: exit $?"
grep -qx ld.image_t <<<"$listed" || fail "--list-types after --lcm-url: $listed"
rc=0; LD_TYPES_JAR=/etc/passwd "$spy" --list-types >"$T/out" 2>"$T/err" || rc=$?
[ $rc -eq 2 ] && grep -q "^ld-spy: LD_TYPES_JAR=/etc/passwd is not a jar (a zip file)$" "$T/err" || fail "not a jar: $rc $(cat "$T/err")"
(cd "$T" && echo x >x.txt && jar cf empty.jar x.txt 2>/dev/null || python3 -c "import zipfile; zipfile.ZipFile('empty.jar','w').writestr('x.txt','x')")
rc=0; LD_TYPES_JAR="$T/empty.jar" "$spy" --list-types >"$T/out" 2>"$T/err" || rc=$?
[ $rc -eq 2 ] && grep -q "^ld-spy: no ld.\* message types in $T/empty.jar$" "$T/err" || fail "empty jar: $rc $(cat "$T/err")"
# ... also when lcm-spy would start (it checked for --list-types alone, and
# lcm-spy started decoding nothing, or died of Java's stack trace)
rc=0; timeout 20 "$netns" env LD_TYPES_JAR="$T/empty.jar" DISPLAY=:97 "$spy" >"$T/out" 2>"$T/err" || rc=$?
[ $rc -eq 2 ] && [ "$(cat "$T/err")" = "ld-spy: no ld.* message types in $T/empty.jar" ] || fail "empty jar, spy: $rc $(cat "$T/err")"
# a DISPLAY that is no display name: one line (Java's stack trace before)
rc=0; timeout 20 "$netns" env DISPLAY=nocolon "$spy" >"$T/out" 2>"$T/err" || rc=$?
[ $rc -eq 2 ] && [ "$(wc -l <"$T/err")" -eq 1 ] && grep -q "^ld-spy: DISPLAY=nocolon is not a display name (:N, unix:N or HOST:N)" "$T/err" ||
  fail "DISPLAY=nocolon: $rc $(cat "$T/err")"
# an X server that refuses the connection (no authorisation): one line with
# Xlib's reason (Java's AWTError stack trace before); a fake server in the
# namespace answers the X11 connection setup with "Failed"
cat >"$T/refusing_x.py" <<'PY'
import socket, struct
s = socket.socket()
s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
s.bind(("127.0.0.1", 6095))
s.listen(8)
reason = b"Authorization required, but no authorization protocol specified\n"
pad = -len(reason) % 4
while True:
    c, _ = s.accept()
    try:
        c.recv(4096)
        c.sendall(struct.pack("<BBHHH", 0, len(reason), 11, 0, (len(reason) + pad) // 4) + reason + b"\0" * pad)
    except OSError:
        pass
    c.close()
PY
rc=0
timeout 60 "$netns" bash -c 'python3 "$1" & server=$!; for i in $(seq 50); do (exec 3<>/dev/tcp/127.0.0.1/6095) 2>/dev/null && break; sleep 0.1; done
  rc=0; DISPLAY=localhost:95.0 "$2" --lcm-url "udpm://239.255.76.67:7667?ttl=0" || rc=$?; kill $server; exit $rc' _ "$T/refusing_x.py" "$spy" >"$T/out" 2>"$T/err" || rc=$?
[ $rc -ne 0 ] && [ "$(wc -l <"$T/err")" -eq 1 ] || fail "refused by the X server: exit $rc: $(cat "$T/err")"
grep -q "^ld-spy: the X server on display localhost:95.0 did not take the connection (Authorization required, but no authorization protocol specified): let this user in (xhost +SI:localuser:.* there, or XAUTHORITY naming the display's cookie file), or on a headless robot" "$T/err" ||
  fail "refused by the X server: $(cat "$T/err")"
# a signal ends lcm-spy, and then ld-spy by the same signal (so that a
# script running it stops on Ctrl-C; it exited with Java's status 143 for
# all three before): a stand-in java on PATH runs the real one for the type
# list, and as lcm-spy waits, noting its end (by ld-spy's TERM, or a HUP to
# the group, as Java's shutdown does) and saying a last line on stderr; a listener in the namespace stands for the X server. Python starts
# ld-spy with INT at its default (a script's background job has it
# ignored), and sends the signal to ld-spy alone or, as a terminal's Ctrl-C
# does, to its whole process group (the stderr filter died of it, and
# lcm-spy's last lines were lost).
mkdir "$T/bin"
cat >"$T/bin/java" <<'SH'
#!/usr/bin/env bash
case " $* " in
  *" lcm.spy.Spy "*) ended() { echo "$1" >"$SPY_MARK.ended"; echo "lcm-spy stand-in: ended" >&2; kill $!; exit $2; }
                     trap 'ended TERM 143' TERM; trap 'ended HUP 129' HUP  # (as Java's shutdown does)
                     sleep 60 </dev/null >/dev/null 2>&1 & echo up >"$SPY_MARK"; wait ;;
  *) exec /usr/bin/java "$@" ;;
esac
SH
chmod +x "$T/bin/java"
cat >"$T/spy_signal.py" <<'PY'
import os, signal, socket, subprocess, sys, time
spy, mark, name, group = sys.argv[1], sys.argv[2], sys.argv[3], sys.argv[4] == "group"
x = socket.socket(); x.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
x.bind(("127.0.0.1", 6094)); x.listen(8)
p = subprocess.Popen([spy, "--lcm-url", "udpm://239.255.76.67:7667?ttl=0"],
                     env=dict(os.environ, DISPLAY="localhost:94.0", SPY_MARK=mark),
                     stderr=subprocess.PIPE, start_new_session=True,
                     preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
for _ in range(300):
    if os.path.exists(mark): break
    time.sleep(0.1)
else:
    sys.exit("lcm-spy's stand-in never started")
if group: os.killpg(p.pid, getattr(signal, name))
else: p.send_signal(getattr(signal, name))
try:
    _, err = p.communicate(timeout=20)
except subprocess.TimeoutExpired:
    p.kill(); sys.exit("ld-spy still running 20 s after " + name)
print(p.returncode, "ended" if os.path.exists(mark + ".ended") else "not ended",
      "last line" if b"lcm-spy stand-in: ended" in err else "no last line: " + repr(err))
PY
for sig in INT:2 TERM:15 HUP:1; do
  for to in alone group; do
    got=$(timeout 60 "$netns" env PATH="$T/bin:$PATH" python3 "$T/spy_signal.py" "$spy" "$T/mark.${sig%:*}.$to" "SIG${sig%:*}" $to) ||
      fail "SIG${sig%:*} ($to): $got"
    [ "$got" = "-${sig#*:} ended last line" ] ||
      fail "SIG${sig%:*} ($to): ld-spy's end, lcm-spy's, its last line: $got (want -${sig#*:} ended last line)"
  done
done
echo "ld-spy command line: ok"
