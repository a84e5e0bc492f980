#!/bin/bash
# Interleaved A/B of two nimbus builds on a stage without motion (the cloud example):
# BEFORE and AFTER are the binaries of the two commits. 7 rounds, wall time per render,
# then whether the two images are the same bits.
set -e
BEFORE=${BEFORE:?path to the nimbus binary of the commit before}
AFTER=${AFTER:?path to the nimbus binary of this commit}
for r in 1 2 3 4 5 6 7; do
 for b in before after; do
  bin=$BEFORE; [ $b = after ] && bin=$AFTER
  s=$(date +%s.%N); $bin render scenes/cloud/cloud.usda -o /tmp/ab_$b.exr --spp 64 --res 160x120 --threads 2 >/dev/null 2>&1; e=$(date +%s.%N)
  echo "$b $(echo "$e - $s" | bc)"
 done
done
cmp /tmp/ab_before.exr /tmp/ab_after.exr && echo "images: identical files"
