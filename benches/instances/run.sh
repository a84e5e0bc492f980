#!/usr/bin/env bash
# Load time and resident memory of N instances of smoke.vdb (../shared/data), from a
# PointInstancer and, for N = 1000, from 1,000 Volume prims written out: each VDB is read
# once, so memory should not grow with N. Usage: benches/instances/run.sh [nimbus binary]
# Writes the stages to a temporary folder; prints one CSV row per case.
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
bin="${1:-$here/../../target/release/nimbus}"
vdb="${NIMBUS_SHARED_DATA:-$here/../../../shared/data}/openvdb_samples/smoke.vdb"
[ -f "$vdb" ] || { echo "no $vdb" >&2; exit 1; }
dir="$(mktemp -d)"
trap 'rm -rf "$dir"' EXIT
echo "case,instances,wall_s,load_s,max_rss_mib"
for n in 1 10 100 1000 explicit; do
    python3 "$here/make_stage.py" "$vdb" "$n" > "$dir/s.usda"
    count=$([ "$n" = explicit ] && echo 1000 || echo "$n")
    /usr/bin/time -f "%e %M" -o "$dir/time" "$bin" render "$dir/s.usda" -o "$dir/s.exr" \
        --res 64x64 --spp 1 --stats "$dir/stats.json" 2>/dev/null
    read -r wall rss < "$dir/time"
    load=$(python3 -c "import json,sys; print(json.load(open(sys.argv[1]))['load_seconds'])" "$dir/stats.json")
    echo "$n,$count,$wall,$load,$((rss / 1024))"
done
