#!/bin/bash
# Interleaved A/B of two nimbus builds on fractal_box.usda: `before` and `after` are
# the binaries of the two commits (edit the paths); 5 rounds, wall time per render.
set -e
for r in 1 2 3 4 5; do
 for b in before after; do
  bin=/work/wt48/target/release/nimbus; [ $b = after ] && bin=/work/wt44/target/release/nimbus
  s=$(date +%s.%N); $bin render benches/shader_graph/fractal_box.usda -o /tmp/ab_$b.exr --spp 256 --res 96x96 --threads 2 --seed 1 >/dev/null 2>&1; e=$(date +%s.%N)
  echo "$b $(echo "$e - $s" | bc)"
 done
done
