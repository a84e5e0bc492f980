"""Interleaved CPU-time comparison of two nimbus builds on the same renders.

usage: ab.py BASEBIN NEWBIN ROUNDS SPP STAGE... [-- EXTRA RENDER ARGS]

Each round renders every stage once with each binary (base first), at $RES
(default 160x120) with SPP samples on $THREADS threads (default 1), and reads the children's CPU seconds (user + system) from
getrusage. Prints the median per binary, their ratio, and whether the exact counts
(density lookups, cells visited) agree. Relative stage paths are taken from the
repository root.
"""
import json, os, resource, statistics, subprocess, sys
args = sys.argv[1:]
extra = []
if '--' in args:
    i = args.index('--'); extra = args[i+1:]; args = args[:i]
if len(args) < 5:
    sys.exit(__doc__)
bins = {"base": args[0], "new": args[1]}
# Stage paths are taken relative to the repository root (two levels above this file's folder).
ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
rounds, spp = int(args[2]), args[3]
for sc in args[4:]:
    t = {k: [] for k in bins}
    for r in range(rounds):
        for k, b in bins.items():
            before = resource.getrusage(resource.RUSAGE_CHILDREN)
            subprocess.run([b, "render", sc, "-o", f"/tmp/ab_{k}.exr", "--res", os.environ.get("RES", "160x120"), "--spp", spp, "--threads", os.environ.get("THREADS", "1"), "--stats", f"/tmp/ab_{k}.json"] + extra, check=True, capture_output=True, cwd=ROOT)
            after = resource.getrusage(resource.RUSAGE_CHILDREN)
            t[k].append(after.ru_utime - before.ru_utime + after.ru_stime - before.ru_stime)
    st = {k: json.load(open(f"/tmp/ab_{k}.json")) for k in bins}
    cnt = {k: (st[k]["density_lookups"], st[k]["cells_visited"]) for k in bins}
    mb, mn = statistics.median(t["base"]), statistics.median(t["new"])
    print(f"{sc.split('/')[-1]} {' '.join(extra)}: median CPU s base {mb:.3f} new {mn:.3f} ratio {mn/mb:.3f}; counts equal {cnt['base']==cnt['new']} {cnt['new']}", flush=True)
