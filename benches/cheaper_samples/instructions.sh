#!/bin/bash
# Exact instructions per sample of nimbus builds on one stage (callgrind: repeatable on
# a noisy machine). Each build renders STAGE at 80x60 on one thread with 4 and with 12
# spp; (I12 - I4) / (8 * 4800) is what one sample costs, loading excluded, and
# I4 - (I12 - I4) / 2 the fixed cost of the process (start, loading, majorants).
# usage: benches/cheaper_samples/instructions.sh STAGE BIN[,ARGS]...  (ARGS: extra render
# arguments, comma-separated, e.g. /tmp/nimbus,--tracker,ratio-select)
st=$1; shift
cd "$(dirname "$0")/../.."
count() {
  IFS=, read -ra cmd <<< "$1"
  valgrind --tool=callgrind --callgrind-out-file=/dev/null "${cmd[0]}" render "$st" -o /tmp/instr.exr \
    --res 80x60 --spp "$2" --threads 1 "${cmd[@]:1}" 2>&1 | grep refs | tr -d ',' | awk '{print $NF}'
}
for b in "$@"; do
  a=$(count "$b" 4)
  c=$(count "$b" 12)
  echo "$(basename "$st") $b fixed $(( a - (c - a) / 2 )) per-sample $(( (c - a) / (8 * 4800) ))"
done
