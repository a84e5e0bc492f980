#!/bin/bash
# usage: benches/cheaper_samples/bitid.sh BASEBIN NEWBIN [extra args] : renders 9 stages x 6 trackers, compares uint32 bits of every channel
# (TRACKERS="a b" replaces the 6 trackers)
B=$1; N=$2; shift 2
tmp=$(mktemp -d); trap 'rm -rf "$tmp"' EXIT
cd "$(dirname "$0")/../.."
eq=0; tot=0; diff=""
for st in scenes/*/*.usda benches/*/*.usda; do for tr in ${TRACKERS:-auto delta decomposition spectral-decomposition spectral spectral-mis}; do
  $B render $st -o $tmp/b.exr --res 24x18 --spp 2 --tracker $tr --aovs lookups,real_collisions,null_collisions "$@" >/dev/null 2>&1 || { echo "base fail $st $tr"; continue; }
  $N render $st -o $tmp/n.exr --res 24x18 --spp 2 --tracker $tr --aovs lookups,real_collisions,null_collisions "$@" >/dev/null 2>&1 || { echo "new fail $st $tr"; continue; }
  r=$(python3 -c "
import OpenEXR,numpy as np
a=OpenEXR.File('$tmp/b.exr').channels(); b=OpenEXR.File('$tmp/n.exr').channels()
ok = set(a)==set(b) and all(np.array_equal(np.ascontiguousarray(a[k].pixels).view(np.uint8), np.ascontiguousarray(b[k].pixels).view(np.uint8)) for k in a)
print(1 if ok else 0)")
  tot=$((tot+1)); eq=$((eq+r)); [ "$r" = 1 ] || diff="$diff $(basename $st .usda):$tr"
done; done
echo "equal $eq of $tot; differ:$diff"
