#!/usr/bin/env bash
# ld-generate's command line: the QR's error correction, more landmarks than a page holds go on
# numbered pages (each page's codes read back by zbarimg to their payloads),
# what fits stays one file, and bad requests are refused with a reason.
# usage: generate_cli_test.sh BIN_DIR
set -euo pipefail
BIN=$(cd "$1" && pwd)
T=$(mktemp -d); trap 'rm -rf "$T"' EXIT
fail() { echo "FAIL: $*" >&2; exit 1; }

# Three 15 cm landmarks: one per A4 page.
"$BIN/ld-generate" --sheet --size 0.15 -p dock -p room-101 -p lift --png "$T/p.png" --svg "$T/p.svg" --dpi 150 \
  >"$T/out"
for k in 1 2 3; do
  [ -s "$T/p-$k.svg" ] && [ -s "$T/p-$k.png" ] || fail "page $k missing: $(cat "$T/out")"
done
[ ! -e "$T/p-4.svg" ] && [ ! -e "$T/p.svg" ] || fail "pages beyond the third, or an unnumbered file"
read_page() { zbarimg --quiet --raw -Sdisable -Sqrcode.enable "$1" | sort | tr '\n' ' '; }
[ "$(read_page "$T/p-1.png")" = "dock " ] || fail "page 1 reads: $(read_page "$T/p-1.png")"
[ "$(read_page "$T/p-3.png")" = "lift " ] || fail "page 3 reads: $(read_page "$T/p-3.png")"
grep -q 'width="210mm" height="297mm"' "$T/p-2.svg" || fail "page 2 is not A4"

# Seven 6 cm landmarks: six on the first page, one on the second.
"$BIN/ld-generate" --sheet --size 0.06 -p a -p b -p c -p d -p e -p f -p g --png "$T/s.png" --dpi 150 >"$T/out"
[ "$(read_page "$T/s-1.png")" = "a b c d e f " ] || fail "6 cm page 1 reads: $(read_page "$T/s-1.png")"
[ "$(read_page "$T/s-2.png")" = "g " ] || fail "6 cm page 2 reads: $(read_page "$T/s-2.png")"
# Fewer pages than an earlier run: the earlier run's last page is named as left over.
"$BIN/ld-generate" --sheet --size 0.15 -p dock -p room-101 --svg "$T/p.svg" >/dev/null 2>"$T/err"
grep -q "p-3.svg from an earlier run left in place" "$T/err" || fail "stale page not named: $(cat "$T/err")"
"$BIN/ld-generate" --size 0.15 -p dock --svg "$T/p.svg" >/dev/null 2>"$T/err"
grep -q "p-1.svg, .*p-2.svg, .*p-3.svg from an earlier run" "$T/err" || fail "stale pages of one: $(cat "$T/err")"
"$BIN/ld-generate" --sheet --size 0.15 -p dock -p room-101 --svg "$T/p.svg" >/dev/null 2>"$T/err"
grep -q "p.svg, .*p-3.svg from an earlier run" "$T/err" || fail "stale unnumbered file: $(cat "$T/err")"
# What fits one page stays one file.
"$BIN/ld-generate" --sheet --size 0.06 -p a -p b --svg "$T/one.svg" >/dev/null
[ -s "$T/one.svg" ] && [ ! -e "$T/one-1.svg" ] || fail "two 6 cm landmarks not on one unnumbered page"

# Refused: a landmark larger than the page, several payloads without --sheet, no output.
if "$BIN/ld-generate" --sheet --size 0.5 -p x --svg "$T/x.svg" 2>"$T/err"; then fail "50 cm on A4 accepted"; fi
grep -q "does not fit on a 210x297 mm page (at most 190 mm with its label and 10 mm margins: --size 0.19; --page-width" "$T/err" ||
  fail "50 cm: $(cat "$T/err")"
# (a page with room for no landmark ld-generate makes, 10 mm or more: no
# size suggested; it said --size 0.001, which it refuses)
if "$BIN/ld-generate" --sheet --size 0.01 -p a --page-width 25 --page-height 25 --svg "$T/x.svg" 2>"$T/err"; then fail "25 mm page accepted"; fi
grep -q "does not fit on a 25x25 mm page (room for none of 10 mm or more within its margins;" "$T/err" || fail "25 mm page: $(cat "$T/err")"
# README's deployment example: 20 cm needs A3 pages.
"$BIN/ld-generate" --sheet --size 0.20 --page-width 297 --page-height 420 -p room-214/door -p room-215/door \
  --svg "$T/deploy/landmarks.svg" >/dev/null
[ -s "$T/deploy/landmarks-1.svg" ] && [ -s "$T/deploy/landmarks-2.svg" ] || fail "20 cm on A3: $(ls "$T/deploy")"
if "$BIN/ld-generate" -p x -p y --svg "$T/x.svg" 2>"$T/err"; then fail "two payloads without --sheet accepted"; fi
grep -q "several payloads need --sheet" "$T/err" || fail "no --sheet: $(cat "$T/err")"
# a page's size without --sheet: said (a single landmark was written, the page dropped without a word)
if "$BIN/ld-generate" -p a --page-width 297 --svg "$T/page.svg" 2>"$T/err"; then fail "--page-width without --sheet accepted"; fi
grep -q -- "--page-width is for --sheet" "$T/err" && [ ! -e "$T/page.svg" ] || fail "--page-width alone: $(cat "$T/err")"
if "$BIN/ld-generate" -p x 2>"$T/err"; then fail "no output accepted"; fi
grep -q "give --png and/or --svg (--help lists the options)" "$T/err" || fail "no output: $(cat "$T/err")"
if "$BIN/ld-generate" -p x --svg /proc/no/x.svg 2>"$T/err"; then fail "unwritable --svg accepted"; fi
grep -q "cannot write /proc/no/x.svg: cannot create folder /proc/no" "$T/err" || fail "unwritable: $(cat "$T/err")"
if "$BIN/ld-generate" -p x --png "$T/x" 2>"$T/err"; then fail "a PNG name without .png accepted"; fi
grep -q "must end in .png" "$T/err" || fail "png name: $(cat "$T/err")"
if "$BIN/ld-generate" -p x --svg "$T/x.png" 2>"$T/err"; then fail "an SVG named .png accepted"; fi
grep -q -- "--svg $T/x.png: the file name must end in .svg" "$T/err" && [ ! -e "$T/x.png" ] || fail "svg name: $(cat "$T/err")"

# Error correction: auto says what it chose (100 bytes: level L's version 5; a
# short payload keeps its version at a higher level); an explicit level is
# used and read back; an unknown one is refused by name.
long=$(printf 'x%.0s' $(seq 100))
"$BIN/ld-generate" -p "$long" -p dock --sheet --svg "$T/e.svg" >"$T/out"
grep -q "version 5 (37 modules), error correction L" "$T/out" || fail "auto, 100 bytes: $(cat "$T/out")"
grep -q '"dock": version 1 (21 modules), error correction H' "$T/out" || fail "auto, dock: $(cat "$T/out")"
"$BIN/ld-generate" -p "$long" --ecc h --png "$T/h.png" --dpi 200 >"$T/out"
grep -q "version 10 (57 modules), error correction H" "$T/out" || fail "--ecc h: $(cat "$T/out")"
[ "$(read_page "$T/h.png")" = "$long " ] || fail "--ecc h reads: $(read_page "$T/h.png")"
grep -q "at 200 dpi" "$T/out" || fail "dpi: $(cat "$T/out")"
if "$BIN/ld-generate" -p x --ecc Z --svg "$T/x.svg" 2>"$T/err"; then fail "--ecc Z accepted"; fi
grep -q -- "--ecc: .*not 'Z'" "$T/err" || fail "--ecc Z: $(cat "$T/err")"

# A payload that cannot be encoded: refused with one line, nothing half-written on stdout.
if "$BIN/ld-generate" -p "" --svg "$T/e.svg" >"$T/out" 2>"$T/err"; then fail "empty payload accepted"; fi
[ ! -s "$T/out" ] && [ "$(wc -l <"$T/err")" -eq 1 ] || fail "empty payload: '$(cat "$T/out")' $(cat "$T/err")"
# (it said a code holds at most 2953 bytes: a user audit)
grep -q "QR payload is empty: a code holds at least one byte" "$T/err" || fail "empty payload: $(cat "$T/err")"
big=$(head -c 3000 /dev/zero | tr '\0' a)
if "$BIN/ld-generate" -p "$big" --svg "$T/e.svg" >"$T/out" 2>"$T/err"; then fail "3000 bytes accepted"; fi
[ ! -s "$T/out" ] && grep -q "payload of 3000 bytes cannot be encoded: a QR code holds at most 2953 bytes at level L" "$T/err" || fail "3000 bytes: $(cat "$T/err")"
# Beyond version 5 (100 bytes): written, with a note; a long payload shown shortened.
"$BIN/ld-generate" -p "$(head -c 500 /dev/zero | tr '\0' b)" --svg "$T/v.svg" >"$T/out" 2>"$T/err"
grep -q '^QR "b\{32\}... (500 bytes)": version 15' "$T/out" || fail "500 bytes: $(cat "$T/out")"
grep -q "needs QR version 15 (77 modules, more than the 37 of version 5.*(ld-eval size --payload-bytes 500 says how close)" "$T/err" || fail "500 bytes, note: $(cat "$T/err")"
# (the command that measures that code: its level too; none past ld-eval's 1000 bytes)
"$BIN/ld-generate" -p "$(head -c 98 /dev/zero | tr '\0' b)" --ecc H --svg "$T/v.svg" >"$T/out" 2>"$T/err"
grep -q "(ld-eval size --payload-bytes 98 --ecc H says how close)" "$T/err" || fail "98 bytes at H, note: $(cat "$T/err")"
"$BIN/ld-generate" -p "$(head -c 1500 /dev/zero | tr '\0' b)" --svg "$T/v.svg" >"$T/out" 2>"$T/err"
grep -q "(ld-eval size measures ASCII payloads of up to 1000 bytes, so none of its figures is this code's)" "$T/err" ||
  fail "1500 bytes, note: $(cat "$T/err")"

# A PNG whose QR modules are under 3 px (too few for a reader): written, with
# a warning saying which --dpi would do; none at the default 300 dpi.
"$BIN/ld-generate" -p a --dpi 10 --png "$T/d10.png" >"$T/out" 2>"$T/err" || fail "--dpi 10: exit $?"
[ -s "$T/d10.png" ] && grep -q "warning: $T/d10.png: a QR module is 1.1 px at 10 dpi, too few to read (3 or more): raise --dpi to 27 or more" "$T/err" ||
  fail "--dpi 10: $(cat "$T/err")"
"$BIN/ld-generate" -p a --png "$T/d300.png" >"$T/out" 2>"$T/err" || fail "--dpi 300: exit $?"
[ ! -s "$T/err" ] || fail "--dpi 300 warned: $(cat "$T/err")"

# The PNG carries its resolution (a pHYs chunk right after IHDR: 300 dpi is
# 11811 pixels per metre, 0x2e23), so printing it at 100 % gives the size.
[ "$(od -An -tx1 -j33 -N17 "$T/d300.png" | tr -d ' \n')" = 000000097048597300002e2300002e2301 ] ||
  fail "no pHYs of 300 dpi: $(od -An -tx1 -j33 -N17 "$T/d300.png")"

# An unknown option is named as such, not as the missing --payload; a
# landmark too large for the page is refused before any QR line is printed.
if "$BIN/ld-generate" --bogus 2>"$T/err"; then fail "--bogus accepted"; fi
grep -q "^ld-generate: The following argument was not expected: --bogus" "$T/err" || fail "--bogus: $(cat "$T/err")"
if "$BIN/ld-generate" --sheet --size 0.5 -p a --svg "$T/big.svg" >"$T/out" 2>"$T/err"; then fail "500 mm on A4 accepted"; fi
[ ! -s "$T/out" ] && [ "$(wc -l <"$T/err")" -eq 1 ] && grep -q "does not fit on a 210x297 mm page" "$T/err" ||
  fail "500 mm on A4: '$(cat "$T/out")' $(cat "$T/err")"

# A PNG too large to draw (2 m at 2400 dpi: 188976 px a side) or too small
# for the layout: refused before anything is written, naming a --dpi that does.
if "$BIN/ld-generate" -p x -s 2 --dpi 2400 --svg "$T/hu.svg" --png "$T/hu.png" >"$T/out" 2>"$T/err"; then
  fail "a 188976 px PNG accepted"
fi
[ ! -e "$T/hu.svg" ] && [ ! -e "$T/hu.png" ] && [ "$(wc -l <"$T/err")" -eq 1 ] &&
  grep -q "is 188976x188976 px, over the 20000 px a side it may have: --dpi 253 or less" "$T/err" ||
  fail "2 m at 2400 dpi: $(ls "$T"/hu.* 2>&1) $(cat "$T/err")"
if "$BIN/ld-generate" -p x -s 0.01 --dpi 10 --svg "$T/s.svg" --png "$T/s.png" >"$T/out" 2>"$T/err"; then
  fail "a 4 px landmark accepted"
fi
[ ! -e "$T/s.svg" ] && grep -q "a 10 mm landmark at --dpi 10 is 4 px a side, under the 9 px of its layout: --dpi 23 or more" "$T/err" ||
  fail "10 mm at 10 dpi: $(cat "$T/err")"

# --dpi without a PNG (it was dropped without a word; the SVG has no pixels)
if "$BIN/ld-generate" -p x --dpi 300 --svg "$T/d.svg" >"$T/out" 2>"$T/err"; then fail "--dpi with --svg alone accepted"; fi
[ ! -e "$T/d.svg" ] && grep -q "^ld-generate: --dpi is the PNG's resolution, and no --png is written" "$T/err" ||
  fail "--dpi with --svg alone: $(cat "$T/err")"

# Payloads that are not UTF-8 text, or hold control characters: the QR keeps
# their bytes; the SVG (XML), the labels and the terminal show U+FFFD.
"$BIN/ld-generate" --sheet -s 0.09 -p $'ab\xffcd' -p $'ctl\x01x' --svg "$T/u.svg" >"$T/out" 2>"$T/err" || fail "odd bytes: $(cat "$T/err")"
grep -qF $'>ab\xef\xbf\xbdcd (90 mm)</text>' "$T/u.svg" && grep -qF $'>ctl\xef\xbf\xbdx (90 mm)</text>' "$T/u.svg" ||
  fail "odd bytes in the labels: $(grep '<text' "$T/u.svg")"
if LC_ALL=C grep -q $'[\x01\xff]' "$T/u.svg" "$T/out"; then fail "raw odd bytes written: $(cat "$T/out")"; fi

# A file that cannot be written (a full disk) is said with why, status 2.
for f in png svg; do
  ln -s /dev/full "$T/full.$f"
  set +e; "$BIN/ld-generate" -p x --$f "$T/full.$f" >/dev/null 2>"$T/err"; rc=$?; set -e
  [ $rc -eq 2 ] && [ "$(cat "$T/err")" = "ld-generate: cannot write $T/full.$f: No space left on device" ] ||
    fail "--$f on a full disk: exit $rc, $(cat "$T/err")"
done

# Page names: a folder with a dot in its name, an extension in capitals.
mkdir -p "$T/out.d"
"$BIN/ld-generate" --sheet --size 0.15 -p a -p b --svg "$T/out.d/sheet.SVG" >/dev/null
[ -s "$T/out.d/sheet-1.SVG" ] && [ -s "$T/out.d/sheet-2.SVG" ] || fail "pages in a dotted folder: $(ls "$T/out.d")"
echo ok
