#!/usr/bin/env bash
# Every lcmtypes/*.lcm type is in the jar and found by LCM's class discovery
# on ld-spy's class path, which is what lcm-spy uses to decode channels.
set -euo pipefail
spy="$1"; types_dir="$2"
listed=$("$spy" --list-types)
status=0
for f in "$types_dir"/*.lcm; do
  t="ld.$(basename "$f" .lcm)"
  if grep -qx "$t" <<<"$listed"; then echo "found $t"; else echo "MISSING $t"; status=1; fi
done
exit $status
