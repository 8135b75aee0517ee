#!/usr/bin/env bash
# The installed project works outside the build tree:
#   1. `cmake --install` puts programs, libraries, headers, the CMake package,
#      systemd units, the types jar and the message definitions where
#      cmake/install.cmake says (into a staging DESTDIR, prefix /opt/landmark);
#   2. the installed programs run: ld-synth renders a landmark with a payload,
#      ld-detect --decode finds it and reads the payload;
#   3. the installed ld-spy uses the installed types jar, also after the
#      prefix is moved, and lcm-spy's class discovery finds every type in it;
#   4. a separate CMake project finds the package (find_package(landmark)),
#      builds against it and detects and decodes the same landmark;
#   5. the Debian packages (cpack): landmark holds the programs and what they
#      use under /usr, with dependencies found from the programs' libraries;
#      landmark-dev the libraries, headers and CMake package, depending on
#      landmark of the same version and the development packages.
# usage: install_test.sh BUILD_DIR SOURCE_DIR
set -euo pipefail
build=$(cd "$1" && pwd); src=$(cd "$2" && pwd)
T=$(mktemp -d); trap 'rm -rf "$T"' EXIT
fail() { echo "FAIL: $*" >&2; exit 1; }

DESTDIR=$T/stage cmake --install "$build" --prefix /opt/landmark >"$T/install.log"
P=$T/stage/opt/landmark
for f in bin/ld-camera bin/ld-detector bin/ld-tracker bin/ld-qr-reader bin/ld-run bin/ld-play bin/ld-view \
         bin/ld-detect bin/ld-synth bin/ld-generate bin/ld-eval bin/ld-bench bin/ld-spy bin/ld-bench-e2e \
         include/ld/detector.hpp include/ld/qr_reader.hpp include/ld/landmark_list_t.hpp include/ld/image_t.hpp \
         lib/libld_detector.a lib/cmake/landmark/landmarkConfig.cmake lib/cmake/landmark/landmarkTargets.cmake \
         lib/systemd/system/landmark.target lib/systemd/system/ld-run@.service lib/sysctl.d/99-landmark-rmem.conf \
         share/landmark/java/ld_lcmtypes.jar share/landmark/lcmtypes/landmark_list_t.lcm \
         share/landmark/examples/ld-run.example.json share/landmark/examples/ld-run.example.yaml \
         share/landmark/examples/landmark.default \
         share/doc/landmark/README.md; do
  [ -e "$P/$f" ] || fail "not installed: $f"
done
for f in bin/ld-publish-garbage bin/ld-tracker-testlog include/ld/detector_options.hpp; do
  [ ! -e "$P/$f" ] || fail "installed but only for the build's own use: $f"
done
[ -x "$P/bin/ld-detector" ] || fail "ld-detector not executable"
echo "layout: ok"

# 2. The installed programs, on a rendered landmark with a known payload.
"$P/bin/ld-synth" scene --out "$T/scene" --seed 3 --size 0.15 --distance 0.5 --yaw 10 --roll 30 \
  --x 0 --y 0 --payload installed-ok --lighting normal --degrade none --distractors 2 >/dev/null
"$P/bin/ld-detect" --decode "$T/scene/000000.png" >"$T/detect.jsonl"
payload=$(jq -r '.landmarks[0].payload' "$T/detect.jsonl")
[ "$payload" = installed-ok ] || fail "installed ld-detect read '$payload', not installed-ok"
echo "programs: ok (payload $payload)"

# 3. ld-spy and the jar, in place and moved.
jar=$("$P/bin/ld-spy" --types-jar)
[ "$jar" -ef "$P/share/landmark/java/ld_lcmtypes.jar" ] || fail "installed ld-spy uses $jar"
mv "$T/stage/opt/landmark" "$T/moved"
P=$T/moved
jar=$("$P/bin/ld-spy" --types-jar)
[ "$jar" -ef "$P/share/landmark/java/ld_lcmtypes.jar" ] || fail "moved ld-spy uses $jar"
ln -s "$P/bin/ld-spy" "$T/ld-spy-link"  # as /usr/local/bin/ld-spy -> /opt/landmark/bin/ld-spy
jar=$("$T/ld-spy-link" --types-jar)
[ "$jar" -ef "$P/share/landmark/java/ld_lcmtypes.jar" ] || fail "ld-spy through a link uses $jar"
bash "$src/tests/spy_types_test.sh" "$P/bin/ld-spy" "$P/share/landmark/lcmtypes" >/dev/null \
  || fail "lcm-spy's discovery misses a type in the installed jar"
echo "ld-spy: ok ($jar)"
# ld-netns-run (scripts/netns-run.sh): a command in a private namespace whose
# loopback carries multicast, for a program of one's own beside ld-run --netns
"$P/bin/ld-netns-run" ip route show 224.0.0.0/4 >"$T/netns.out" 2>&1 && grep -q "dev lo" "$T/netns.out" ||
  fail "ld-netns-run: $(cat "$T/netns.out")"

# 4. A project of the user's own against the installed package (moved prefix:
#    the package's paths are relative to where it lies).
cmake -S "$src/tests/install_consumer" -B "$T/consumer" -DCMAKE_PREFIX_PATH="$P" \
  -DCMAKE_BUILD_TYPE=Release >"$T/consumer.log" 2>&1 || { cat "$T/consumer.log"; fail "consumer configure"; }
cmake --build "$T/consumer" >>"$T/consumer.log" 2>&1 || { cat "$T/consumer.log"; fail "consumer build"; }
out=$("$T/consumer/consumer" "$T/scene/000000.png")
[ "$(wc -l <<<"$out")" -eq 1 ] || fail "consumer found not one landmark: $out"
[ "$(cut -d' ' -f1 <<<"$out")" = installed-ok ] || fail "consumer read: $out"
[ "$(cut -d' ' -f4 <<<"$out")" = 1 ] || fail "consumer's track id: $out"
want=$(jq -r '.landmarks[0].corners[0] | "\(.[0]) \(.[1])"' "$T/detect.jsonl")
awk -v a="$out" -v b="$want" 'BEGIN { split(a, x, " "); split(b, y, " ");
  exit !((x[2] - y[1])^2 + (x[3] - y[2])^2 < 0.01) }' || fail "consumer corner $out, ld-detect $want"
echo "find_package(landmark): ok ($out)"

# 4b. A node that only reads the messages asks for them alone, and needs
#     neither OpenCV nor zbar nor EGL (OpenCV's package switched off here);
#     a component the package has not is named.
cmake -S "$src/tests/install_consumer_msgs" -B "$T/msgs_consumer" -DCMAKE_PREFIX_PATH="$P" \
  -DCMAKE_DISABLE_FIND_PACKAGE_OpenCV=ON -DCMAKE_BUILD_TYPE=Release >"$T/msgs_consumer.log" 2>&1 ||
  { cat "$T/msgs_consumer.log"; fail "messages-only consumer configure"; }
cmake --build "$T/msgs_consumer" >>"$T/msgs_consumer.log" 2>&1 ||
  { cat "$T/msgs_consumer.log"; fail "messages-only consumer build"; }
out=$("$T/msgs_consumer/msgs_consumer")
[ "$out" = "7 42 dock 10.5 20.25" ] || fail "messages-only consumer read: $out"
mkdir -p "$T/bad_component"
printf 'cmake_minimum_required(VERSION 3.18)\nproject(bad LANGUAGES CXX)\nfind_package(landmark REQUIRED CONFIG COMPONENTS viewer)\n' \
  >"$T/bad_component/CMakeLists.txt"
if cmake -S "$T/bad_component" -B "$T/bad_component/build" -DCMAKE_PREFIX_PATH="$P" >"$T/bad.log" 2>&1; then
  fail "find_package(landmark COMPONENTS viewer) configured"
fi
# (cmake wraps its message's lines)
tr -s ' \n' '  ' <"$T/bad.log" |
  grep -q "landmark has no component 'viewer' (its components: core, detector, qr_reader, tracker, landmark_msg, msgs, lcmtypes)" ||
  { cat "$T/bad.log"; fail "unknown component: not named"; }
# a project of an old CMake (a catkin package's 3.0.2: this file runs under
# its policies) that asks for an optional component the package has not:
# found, that one not
mkdir -p "$T/old_cmake"
printf '%s\n' 'cmake_minimum_required(VERSION 3.0.2)' 'project(old CXX)' \
  'find_package(landmark REQUIRED CONFIG COMPONENTS lcmtypes OPTIONAL_COMPONENTS extra)' \
  'if(landmark_extra_FOUND OR NOT landmark_lcmtypes_FOUND OR NOT TARGET landmark::lcmtypes)' \
  '  message(FATAL_ERROR "components: extra ${landmark_extra_FOUND} lcmtypes ${landmark_lcmtypes_FOUND}")' 'endif()' \
  >"$T/old_cmake/CMakeLists.txt"
cmake -S "$T/old_cmake" -B "$T/old_cmake/build" -DCMAKE_PREFIX_PATH="$P" -DCMAKE_DISABLE_FIND_PACKAGE_OpenCV=ON \
  >"$T/old.log" 2>&1 || { cat "$T/old.log"; fail "an old CMake's project with an optional unknown component"; }
# (and without COMPONENTS, OpenCV is needed: the switch above does switch it off)
if cmake -S "$src/tests/install_consumer" -B "$T/consumer_no_cv" -DCMAKE_PREFIX_PATH="$P" \
     -DCMAKE_DISABLE_FIND_PACKAGE_OpenCV=ON >"$T/no_cv.log" 2>&1; then
  fail "the full consumer configured with OpenCV switched off"
fi
echo "find_package(landmark COMPONENTS lcmtypes): ok ($out)"

# 5. The Debian packages.
(cd "$build" && cpack --config CPackConfig.cmake -B "$T/pkg" >"$T/cpack.log" 2>&1) \
  || { cat "$T/cpack.log"; fail "cpack"; }
deb=$(ls "$T"/pkg/landmark_*.deb)
dev=$(ls "$T"/pkg/landmark-dev_*.deb)
dpkg-deb -c "$deb" >"$T/deb.list"
dpkg-deb -c "$dev" >"$T/dev.list"
for f in ./usr/bin/ld-detector ./usr/bin/ld-spy ./usr/lib/systemd/system/landmark.target \
         ./usr/share/landmark/java/ld_lcmtypes.jar ./usr/lib/sysctl.d/99-landmark-rmem.conf; do
  grep -q " $f\$" "$T/deb.list" || fail "package lacks $f"
  ! grep -q " $f\$" "$T/dev.list" || fail "landmark-dev has the runtime's $f"
done
for f in ./usr/lib/cmake/landmark/landmarkConfig.cmake ./usr/lib/libld_detector.a ./usr/include/ld/detector.hpp \
         ./usr/include/ld/landmark_list_t.hpp; do
  grep -q " $f\$" "$T/dev.list" || fail "landmark-dev lacks $f"
  ! grep -q " $f\$" "$T/deb.list" || fail "the runtime package has landmark-dev's $f"
done
depends=$(dpkg-deb -f "$deb" Depends)
for d in liblcm libopencv-core libzbar libjchart2d-java; do
  grep -q "$d" <<<"$depends" || fail "package Depends lacks $d: $depends"
done
version=$(dpkg-deb -f "$deb" Version)
dev_depends=$(dpkg-deb -f "$dev" Depends)
for d in "landmark (= $version)" libopencv-dev liblcm-dev libglib2.0-dev libzbar-dev pkg-config; do
  grep -qF "$d" <<<"$dev_depends" || fail "landmark-dev Depends lacks $d: $dev_depends"
done
echo "packages: ok ($(basename "$deb"), $(basename "$dev"))"

# 6. Its maintainer scripts, run as dpkg runs them, against stub sysctl,
#    systemd-sysctl and systemctl (a systemd root under DPKG_ROOT) that log
#    their calls.
dpkg-deb -e "$deb" "$T/control"
for f in postinst prerm postrm; do
  [ -x "$T/control/$f" ] || fail "package has no executable $f"
done
dpkg-deb -e "$dev" "$T/dev-control"
[ ! -e "$T/dev-control/postinst" ] || fail "landmark-dev has maintainer scripts"
R=$T/root; mkdir -p "$R/run/systemd/system" "$R/usr/lib/systemd" "$T/stubs"
printf '#!/bin/sh\necho "systemd-sysctl $*" >>"%s/calls"\n' "$T" >"$R/usr/lib/systemd/systemd-sysctl"
printf '#!/bin/sh\necho "systemctl $*" >>"%s/calls"\n' "$T" >"$T/stubs/systemctl"
printf '#!/bin/sh\n[ "$1" = -n ] && cat "%s/rmem_max"\n' "$T" >"$T/stubs/sysctl"
chmod +x "$R/usr/lib/systemd/systemd-sysctl" "$T/stubs/systemctl" "$T/stubs/sysctl"
script() {  # script args...: its calls, one line each
  : >"$T/calls"
  DPKG_ROOT=$R PATH="$T/stubs:$PATH" sh "$T/control/$1" "${@:2}" || fail "$1 $* failed"
  cat "$T/calls"
}
echo 212992 >"$T/rmem_max"
calls=$(script postinst configure "")
grep -qx "systemd-sysctl 99-landmark-rmem.conf" <<<"$calls" || fail "postinst did not raise rmem_max: $calls"
grep -qx "systemctl daemon-reload" <<<"$calls" || fail "postinst did not reload systemd: $calls"
! grep -q try-restart <<<"$calls" || fail "postinst restarted units on a first install: $calls"
echo 16777216 >"$T/rmem_max"
calls=$(script postinst configure 0.0.9)
! grep -q systemd-sysctl <<<"$calls" || fail "postinst lowered a higher rmem_max: $calls"
grep -q "^systemctl try-restart ld-run@\*.service " <<<"$calls" || fail "postinst did not restart on upgrade: $calls"
calls=$(script prerm remove)
grep -q "^systemctl stop landmark.target ld-run@\*.service " <<<"$calls" || fail "prerm did not stop the units: $calls"
[ -z "$(script prerm upgrade 0.1.1)" ] || fail "prerm stopped the units on an upgrade"
[ "$(script postrm remove)" = "systemctl daemon-reload" ] || fail "postrm did not reload systemd"
echo "maintainer scripts: ok"
