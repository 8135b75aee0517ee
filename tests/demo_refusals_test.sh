#!/usr/bin/env bash
# scripts/demo.sh refuses, before it runs anything, an LD_DEMO_OUT that is a
# file, or a folder of other files (it empties its own folder first).
# usage: demo_refusals_test.sh SOURCE_DIR BUILD_DIR
set -euo pipefail
SRC=$1; BUILD=$2
T=$(mktemp -d); trap 'rm -rf "$T"' EXIT
fail() { echo "FAIL: $*"; exit 1; }
: >"$T/afile"
rc=0; LD_DEMO_OUT="$T/afile" bash "$SRC/scripts/demo.sh" "$BUILD" >/dev/null 2>"$T/err" || rc=$?
[ $rc -eq 2 ] && grep -qx "demo.sh: $T/afile is a file, not a folder: give LD_DEMO_OUT an empty or new folder" "$T/err" ||
  fail "a file: $rc $(cat "$T/err")"
[ -f "$T/afile" ] || fail "the file was removed"
mkdir "$T/mine" && echo keep >"$T/mine/notes.txt"
rc=0; LD_DEMO_OUT="$T/mine" bash "$SRC/scripts/demo.sh" "$BUILD" >/dev/null 2>"$T/err" || rc=$?
[ $rc -eq 2 ] && grep -q "holds files that are not the demo's" "$T/err" || fail "a folder of other files: $rc $(cat "$T/err")"
[ "$(cat "$T/mine/notes.txt")" = keep ] || fail "the folder's file was touched"
echo ok
