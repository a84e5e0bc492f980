"""Interleaved A/B of renders of one stage (issue 44, first measurements).

usage: python3 ab.py STAGE K LABEL=NIMBUS[:FLAG,FLAG...] LABEL=... -- [common nimbus flags]

Each variant renders the stage K times (seeds 1..K, interleaved: every variant once per
seed, in the order given). Per variant: the median of the CLI's own sampling seconds
(the "N s" it prints, without the stage load), the per-pixel variance over the K seeds
(unbiased, ddof 1) as relMSE = mean over pixels and R, G, B of var / (m^2 + 0.01), m
the mean of all images of all variants, efficiency 1 / (relMSE x s), and the image
mean of R with its standard error over the seeds. The last line gives each variant's
ratios to the first.
"""
import os, re, subprocess, sys, tempfile
import numpy as np
import OpenEXR, Imath


def load(p):
    f = OpenEXR.InputFile(p)
    dw = f.header()["dataWindow"]
    w, h = dw.max.x - dw.min.x + 1, dw.max.y - dw.min.y + 1
    px = Imath.PixelType(Imath.PixelType.FLOAT)
    return np.stack([np.frombuffer(f.channel(c, px), np.float32).reshape(h, w)
                     for c in "RGB"], -1).astype(np.float64)


args = sys.argv[1:]
common = args[args.index("--") + 1:] if "--" in args else []
args = args[:args.index("--")] if "--" in args else args
stage, k = args[0], int(args[1])
variants = []
for spec in args[2:]:
    label, rest = spec.split("=", 1)
    binary, _, flags = rest.partition(":")
    variants.append((label, binary, [f for f in flags.split(",") if f]))
images = {v[0]: [] for v in variants}
secs = {v[0]: [] for v in variants}
with tempfile.TemporaryDirectory() as d:
    for seed in range(1, k + 1):
        for label, binary, flags in variants:
            out = os.path.join(d, f"{label}_{seed}.exr")
            r = subprocess.run([binary, "render", stage, "-o", out, "--seed", str(seed),
                                *common, *flags], capture_output=True, text=True)
            if r.returncode != 0:
                sys.exit(r.stderr)
            secs[label].append(float(re.search(r", ([0-9.]+) s,", r.stderr).group(1)))
            images[label].append(load(out))
allm = np.mean([i for v in images.values() for i in v], axis=0)
print(f"{stage} {' '.join(common)}: {k} seeds per variant")
res = {}
for label, _, flags in variants:
    st = np.stack(images[label])
    rel = float(np.mean(st.var(axis=0, ddof=1) / (allm ** 2 + 0.01)))
    t = float(np.median(secs[label]))
    res[label] = (rel, t)
    means = st.mean(axis=(1, 2))
    print(f"  {label:24s} {' '.join(flags):40s} time {t:.3f} s  relMSE {rel:.4g}  "
          f"efficiency {1 / (rel * t):.4g}  mean R {means[:, 0].mean():.5f} +- "
          f"{means[:, 0].std(ddof=1) / np.sqrt(k):.5f}")
(r0, t0) = res[variants[0][0]]
print("  against " + variants[0][0] + ": " + "; ".join(
    f"{l} variance x{r / r0:.3f} time x{t / t0:.3f} efficiency x{(r0 * t0) / (r * t):.3f}"
    for l, (r, t) in list(res.items())[1:]))
