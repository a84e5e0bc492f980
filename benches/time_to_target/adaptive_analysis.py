"""Why adaptive sampling does not pay on the time-to-target cloud (issue 48).

Needs run.py's work folder (WORK, default /tmp/tt48/w: cloud.usda and the two 4096-spp
Nimbus references cloud/nimbus_1.exr, cloud/nimbus_3.exr) and NIMBUS_BIN. Prints, per
noise threshold (cap 4096 spp), the `samples` AOV over the foreground (pixels whose
reference differs from the sky) and the background; then, from one 256-spp render, the
lookups per sample in each and the foreground's share of them, and per brightness
quartile of the foreground the per-sample variance relative to I² + 0.01 (what relMSE
weighs) and to I (what Cycles' error measure, which Nimbus' adaptive sampling uses,
weighs).

    NIMBUS_BIN=target/release/nimbus /tmp/nimbus-bpy-venv/bin/python \\
        benches/time_to_target/adaptive_analysis.py
"""
import os
import subprocess
import tempfile

import numpy as np
import nimbus

WORK = os.environ.get("WORK", "/tmp/tt48/w")
NB = os.environ.get("NIMBUS_BIN", "target/release/nimbus")
SKY = np.array([0.25, 0.35, 0.5])  # the scene's environment radiance

a = nimbus.read_exr(f"{WORK}/cloud/nimbus_1.exr")
b = nimbus.read_exr(f"{WORK}/cloud/nimbus_3.exr")
ref = np.stack([(a[c] + b[c]) / 2 for c in "RGB"], -1).astype(float)
fg = np.abs(ref - SKY).max(-1) > 1e-5
tmp = tempfile.mkdtemp()


def render(out, *args):
    subprocess.run([NB, "render", f"{WORK}/cloud.usda", "-o", out, "--threads", "2", *args],
                   check=True, capture_output=True)
    return nimbus.read_exr(out)


for thr in (0.01, 0.005, 0.0025, 0.001):
    s = render(f"{tmp}/s.exr", "--spp", "4096", "--noise-threshold", str(thr),
               "--aovs", "samples")["samples"].astype(float)
    print(f"threshold {thr}: foreground {fg.sum()} px: mean spp {s[fg].mean():.0f}, median "
          f"{np.median(s[fg]):.0f}, at the cap {np.mean(s[fg] >= 4096) * 100:.1f} %; background "
          f"{(~fg).sum()} px: mean spp {s[~fg].mean():.0f}; frame mean {s.mean():.0f}")
e = render(f"{tmp}/c.exr", "--spp", "256", "--aovs", "lookups,variance")
lk = e["lookups"].astype(float)
print(f"lookups per sample: foreground {lk[fg].mean():.1f}, background {lk[~fg].mean():.2f}; "
      f"the foreground's share of all lookups {lk[fg].sum() / lk.sum():.3f}")
v = e["variance"].astype(float)
lum = ref.mean(-1)
q = np.quantile(lum[fg], [0.25, 0.5, 0.75])
for lo, hi in zip([0.0, *q], [*q, np.inf]):
    m = fg & (lum >= lo) & (lum < hi)
    print(f"foreground brightness {lo:.3f}..{hi:.3f} ({m.sum()} px): variance/(I²+0.01) "
          f"{(v[m] / (lum[m] ** 2 + 0.01)).mean():.3f}, variance/I "
          f"{(v[m] / np.maximum(lum[m], 1e-6)).mean():.4f}")
# relMSE over the foreground, Σ r_i / n_i / N with r_i = variance_i / (I_i² + 0.01), for
# the same total of foreground samples spread three ways (no cap, no minimum): evenly
# (fixed spp), n_i ∝ variance_i / I_i (where Cycles' measure stops every pixel at the
# same threshold) and n_i ∝ √r_i (the split that minimises relMSE).
r = (v / (lum ** 2 + 0.01))[fg]
cyc = (v / np.maximum(lum, 1e-6))[fg]
total = float(fg.sum())
for name, w in [("even", np.ones_like(r)), ("Cycles' measure", cyc), ("relMSE-optimal", np.sqrt(r))]:
    n = total * w / w.sum()
    print(f"foreground samples spread {name}: relMSE × (samples per pixel) "
          f"{np.mean(r / np.maximum(n, 1e-12)):.4f}")
