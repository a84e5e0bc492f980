"""Marginal CPU seconds per sample of two nimbus builds, interleaved.

usage: per_sample.py BASEBIN NEWBIN ROUNDS SPP_LO SPP_HI STAGE... [-- EXTRA RENDER ARGS]

Each round renders every stage with each binary (base first) at SPP_LO and at SPP_HI
samples per pixel, at $RES (default 160x120) on $THREADS threads (default 1), and reads
the children's CPU seconds (user + system) from getrusage. A round's cost per sample is
(CPU at SPP_HI - CPU at SPP_LO) / (SPP_HI - SPP_LO) / pixels: the process start, the
stage and grid loading and the majorant build are paid once per process and cancel,
so this is what one more sample costs. Prints, per stage and binary, the median over
rounds (ns per sample), the ratio new / base of the medians, the per-round ratios, the
same for the render passes' own seconds at SPP_HI (`render_seconds` of --stats: loading
excluded, wall clock, so one thread), and the exact counts per sample (density
lookups, cells visited) at SPP_HI.
Relative stage paths are taken from the repository root.
"""
import json, os, statistics, sys

from common import render_cpu, split_extra

args, extra = split_extra(sys.argv[1:])
if len(args) < 6:
    sys.exit(__doc__)
bins = {"base": args[0], "new": args[1]}
rounds, lo, hi = int(args[2]), int(args[3]), int(args[4])
res = os.environ.get("RES", "160x120")
w, h = (int(v) for v in res.split("x"))
threads = os.environ.get("THREADS", "1")


def cpu(b, stage, spp, tag):
    return render_cpu([b, "render", stage, "-o", f"/tmp/ps_{tag}.exr", "--res", res, "--spp", str(spp),
                       "--threads", threads, "--stats", f"/tmp/ps_{tag}.json"] + extra)


for stage in args[5:]:
    per = {k: [] for k in bins}
    rs = {k: [] for k in bins}
    for _ in range(rounds):
        for k, b in bins.items():
            c_lo = cpu(b, stage, lo, k)
            c_hi = cpu(b, stage, hi, k)
            per[k].append((c_hi - c_lo) / ((hi - lo) * w * h) * 1e9)
            rs[k].append(json.load(open(f"/tmp/ps_{k}.json"))["render_seconds"] / (hi * w * h) * 1e9)
    st = {k: json.load(open(f"/tmp/ps_{k}.json")) for k in bins}
    n = hi * w * h
    cnt = {k: (st[k]["density_lookups"] / n, st[k]["cells_visited"] / n) for k in bins}
    mb, mn = statistics.median(per["base"]), statistics.median(per["new"])
    rr = " ".join(f"{a / b:.3f}" for a, b in zip(per["new"], per["base"]))
    print(f"{stage.split('/')[-1]} {' '.join(extra)}: ns/sample median base {mb:.0f} new {mn:.0f} "
          f"ratio {mn / mb:.3f} (rounds {rr}); lookups, cells per sample base "
          f"{cnt['base'][0]:.2f}, {cnt['base'][1]:.2f} new {cnt['new'][0]:.2f}, {cnt['new'][1]:.2f}",
          flush=True)
    rb, rn = statistics.median(rs["base"]), statistics.median(rs["new"])
    rr = " ".join(f"{a / b:.3f}" for a, b in zip(rs["new"], rs["base"]))
    print(f"    render ns/sample median base {rb:.0f} new {rn:.0f} ratio {rn / rb:.3f} (rounds {rr})",
          flush=True)
