#!/usr/bin/env bash
# Deep hierarchies (issue 34): wall time of `nimbus info` on the example cloud under
# 250, 1,000 and 5,000 nested Xforms (make_stage.py), best of $REPS (default 3), for each binary given.
#
#   bash benches/deep_hierarchy/run.sh OLD_BIN NEW_BIN [DEPTHS...]
#
# A run is cut off after 120 s (printed as "> 120"). Results: docs/robustness.md.
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
repo="$(cd "$here/../.." && pwd)"
bins=("$1" "$2")
shift 2
[ $# -gt 0 ] && depths=("$@") || depths=(250 1000 5000)
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
for d in "${depths[@]}"; do
    python3 "$here/make_stage.py" "$d" "$tmp/deep$d.usda" "$repo/scenes/cloud/cloud.vdb"
done
printf '%-8s' depth
for b in "${bins[@]}"; do printf '  %-40s' "$b"; done
printf '\n'
for d in "${depths[@]}"; do
    printf '%-8s' "$d"
    for b in "${bins[@]}"; do
        best=""
        for _ in $(seq "${REPS:-3}"); do
            start=$(date +%s.%N)
            if timeout 120 "$b" info "$tmp/deep$d.usda" >/dev/null 2>"$tmp/err"; then
                t=$(echo "$(date +%s.%N) - $start" | bc)
            else
                t="> 120"
                [ -s "$tmp/err" ] && t="failed: $(tail -1 "$tmp/err")"
                break
            fi
            if [ -z "$best" ] || [ "$(echo "$t < $best" | bc)" = 1 ]; then best=$t; fi
        done
        printf '  %-40s' "${best:-$t} s"
    done
    printf '\n'
done
