#!/bin/bash
# Interleaved A/B(/C…) of nimbus builds: each round renders STAGE once with every
# build, in the order given, and prints the wall time of each render; then the median
# per build and its ratio to the first build's.
#
#   ab_eval.sh STAGE SPP ROUNDS name=/path/to/nimbus [name=/path/to/nimbus …]
#
# e.g. ab_eval.sh benches/shader_graph/fractal_box.usda 512 5 before=/tmp/nimbus-old \
#          after=target/release/nimbus
# Renders at 96x96, 2 threads, seed 1; the images of the builds are kept as
# /tmp/ab_<name>.exr for a comparison.
set -e
stage=$1 spp=$2 rounds=$3
shift 3
declare -A times
for r in $(seq "$rounds"); do
  for build in "$@"; do
    name=${build%%=*} bin=${build#*=}
    s=$(date +%s.%N)
    "$bin" render "$stage" -o "/tmp/ab_$name.exr" --spp "$spp" --res 96x96 --threads 2 --seed 1 >/dev/null 2>&1
    e=$(date +%s.%N)
    t=$(echo "$e - $s" | bc)
    echo "round $r $name $t"
    times[$name]="${times[$name]} $t"
  done
done
first=
for build in "$@"; do
  name=${build%%=*}
  median=$(echo ${times[$name]} | tr ' ' '\n' | sort -g | awk '{v[NR]=$1} END {print (NR % 2) ? v[(NR + 1) / 2] : (v[NR / 2] + v[NR / 2 + 1]) / 2}')
  [ -z "$first" ] && first=$median
  echo "median $name ${median} s ($(echo "scale=3; $median / $first" | bc)x the first)"
done
