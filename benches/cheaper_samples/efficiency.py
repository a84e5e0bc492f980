"""Equal-time error of nimbus builds (or settings), interleaved: efficiency = 1 / (relMSE x CPU s).

usage: efficiency.py ROUNDS SPP RES STAGE NAME=BIN[,ARG,ARG...] ...

Round r renders STAGE with every configuration at seeds 2r and 2r+1 (configurations
interleaved, in the order given), at RES (WxH) with SPP samples per pixel on $THREADS
threads (default 2), reading each render's CPU seconds (user + system of the whole
process) from getrusage. A seed pair's two images a, b are independent renders of the
same image, so the relative MSE of one render is estimated as

    relMSE = mean over pixels and R, G, B of (a - b)^2 / (((a + b) / 2)^2 + 0.01) / 2

(the difference of two independent renders has twice one render's variance; 0.01 keeps
dark pixels from dominating). Prints per configuration the mean relMSE over rounds with
its standard error, the median CPU seconds per render, the efficiency, and its ratio
to the first configuration's: the equal-time relMSE of a configuration relative to the
first is the inverse of that ratio. Needs the OpenEXR and numpy Python modules.
"""
import os, statistics, sys

import numpy as np
import OpenEXR

from common import render_cpu

args = sys.argv[1:]
if len(args) < 5:
    sys.exit(__doc__)
rounds, spp, res, stage = int(args[0]), args[1], args[2], args[3]
configs = []
for c in args[4:]:
    name, rest = c.split("=", 1)
    parts = rest.split(",")
    configs.append((name, parts[0], parts[1:]))
threads = os.environ.get("THREADS", "2")


def render(b, extra, seed, out):
    return render_cpu([b, "render", stage, "-o", out, "--res", res, "--spp", spp, "--threads", threads,
                       "--seed", str(seed)] + extra)


def rgb(path):
    ch = OpenEXR.File(path).channels()
    for k in ("RGBA", "RGB"):
        if k in ch:
            return np.asarray(ch[k].pixels, dtype=np.float64)[..., :3]
    return np.stack([np.asarray(ch[k].pixels, dtype=np.float64) for k in "RGB"], axis=-1)


err = {n: [] for n, _, _ in configs}
cpu = {n: [] for n, _, _ in configs}
for r in range(rounds):
    for name, b, extra in configs:
        outs = []
        for s in (2 * r, 2 * r + 1):
            out = f"/tmp/eff_{name}_{s % 2}.exr"
            cpu[name].append(render(b, extra, s, out))
            outs.append(out)
        a, c = rgb(outs[0]), rgb(outs[1])
        m = (a + c) / 2
        err[name].append(float(np.mean((a - c) ** 2 / (m * m + 0.01)) / 2))
first = None
for name, _, _ in configs:
    e = statistics.mean(err[name])
    se = statistics.stdev(err[name]) / len(err[name]) ** 0.5 if len(err[name]) > 1 else float("nan")
    t = statistics.median(cpu[name])
    eff = 1 / (e * t)
    first = first or eff
    print(f"{stage.split('/')[-1]} {name}: relMSE {e:.4e} +- {se:.1e}, CPU s {t:.3f}, "
          f"efficiency {eff:.1f}, ratio to {configs[0][0]} {eff / first:.3f}", flush=True)
