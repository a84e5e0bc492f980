"""Interleaved CPU-time comparison of two nimbus builds on the same renders.

usage: ab.py BASEBIN NEWBIN ROUNDS SPP STAGE... [-- EXTRA RENDER ARGS]

Each round renders every stage once with each binary (base first), at $RES
(default 160x120) with SPP samples on $THREADS threads (default 1), and reads the children's CPU seconds (user + system) from
getrusage. Prints the median per binary, their ratio, and whether the exact counts
(density lookups, cells visited) agree. Relative stage paths are taken from the
repository root.
"""
import json, os, statistics, sys

from common import render_cpu, split_extra

args, extra = split_extra(sys.argv[1:])
if len(args) < 5:
    sys.exit(__doc__)
bins = {"base": args[0], "new": args[1]}
rounds, spp = int(args[2]), args[3]
for sc in args[4:]:
    t = {k: [] for k in bins}
    for r in range(rounds):
        for k, b in bins.items():
            t[k].append(render_cpu([b, "render", sc, "-o", f"/tmp/ab_{k}.exr", "--res", os.environ.get("RES", "160x120"), "--spp", spp, "--threads", os.environ.get("THREADS", "1"), "--stats", f"/tmp/ab_{k}.json"] + extra))
    st = {k: json.load(open(f"/tmp/ab_{k}.json")) for k in bins}
    cnt = {k: (st[k]["density_lookups"], st[k]["cells_visited"]) for k in bins}
    mb, mn = statistics.median(t["base"]), statistics.median(t["new"])
    print(f"{sc.split('/')[-1]} {' '.join(extra)}: median CPU s base {mb:.3f} new {mn:.3f} ratio {mn/mb:.3f}; counts equal {cnt['base']==cnt['new']} {cnt['new']}", flush=True)
