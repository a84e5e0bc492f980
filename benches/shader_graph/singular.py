"""The variance cost of estimated majorants (issue 47): a density graph with no bound where
it is singular, k / |p - q| (singular_box.usda), tracked under estimated majorants, against
the same density capped at 300 (singular_box_capped.usda, bounded everywhere: the two
differ only within 1e-3 of q) under exact majorants; each with `auto` (ratio-select) and
with weighted delta.

Run from the project root with a Python that has numpy and OpenEXR:
    python benches/shader_graph/singular.py target/release/nimbus
env: RES (64), SPP (64 per seed), SEEDS (8), ROUNDS (3), THREADS (2).

Method. ROUNDS interleaved rounds; in each, every configuration renders SEEDS seeds at SPP.
The per-pixel variance of one SPP render is the seeds' sample variance; its mean over the
pixels and R, G, B is V. Time: the stats' render_seconds summed over the seeds. Efficiency
= 1 / (V x time), medians over the rounds; the table gives each against the capped stage
under `auto` (the same tracker, exact majorants), so the second row's ratios are the cost
of the estimates alone. Also printed: the image means (each configuration's mean over all its
renders) and majorant_violations per sample.
"""
import json
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
import OpenEXR

HERE = Path(__file__).resolve().parent
RES = int(os.environ.get("RES", "64"))
SPP = int(os.environ.get("SPP", "64"))
SEEDS = int(os.environ.get("SEEDS", "8"))
ROUNDS = int(os.environ.get("ROUNDS", "3"))
THREADS = os.environ.get("THREADS", "2")

CONFIGS = [
    ("capped, auto (exact majorants)", "singular_box_capped.usda", "auto"),
    ("singular, auto (estimated majorants)", "singular_box.usda", "auto"),
    ("capped, weighted-delta (exact majorants)", "singular_box_capped.usda", "weighted-delta"),
    ("singular, weighted-delta (estimated majorants)", "singular_box.usda", "weighted-delta"),
]


def rgb(path):
    with OpenEXR.File(str(path)) as f:
        ch = f.parts[0].channels
        for whole in ("RGBA", "RGB"):
            if whole in ch:
                return np.moveaxis(np.asarray(ch[whole].pixels, dtype=np.float64)[..., :3], -1, 0)
        return np.stack([np.asarray(ch[c].pixels, dtype=np.float64) for c in "RGB"])


def render(nimbus, stage, tracker, seed, out):
    exr, stats = out / "x.exr", out / "x.json"
    cmd = [nimbus, "render", str(HERE / stage), "-o", str(exr), "--res", f"{RES}x{RES}",
           "--spp", str(SPP), "--seed", str(seed), "--threads", THREADS,
           "--tracker", tracker, "--stats", str(stats)]
    subprocess.run(cmd, check=True, capture_output=True)
    s = json.loads(stats.read_text())
    return rgb(exr), s["render_seconds"], s["majorant_violations"] / s["samples_taken"], s["tracker"]


def main():
    nimbus = sys.argv[1] if len(sys.argv) > 1 else "target/release/nimbus"
    rows = {name: {"v": [], "t": [], "mean": [], "viol": [], "tracker": ""} for name, _, _ in CONFIGS}
    with tempfile.TemporaryDirectory() as d:
        out = Path(d)
        for r in range(ROUNDS):
            for name, stage, tracker in CONFIGS:
                images, seconds, viol = [], 0.0, []
                for k in range(SEEDS):
                    img, t, v, used = render(nimbus, stage, tracker, 1 + r * SEEDS + k, out)
                    images.append(img)
                    seconds += t
                    viol.append(v)
                    rows[name]["tracker"] = used
                stack = np.stack(images)
                rows[name]["v"].append(stack.var(axis=0, ddof=1).mean())
                rows[name]["t"].append(seconds)
                rows[name]["mean"].append(stack.mean())
                rows[name]["viol"].append(float(np.mean(viol)))
                print(f"round {r}: {name}: V {rows[name]['v'][-1]:.4e}, {seconds:.2f} s", flush=True)
    base = CONFIGS[0][0]
    eff = {n: statistics.median(1 / (v * t) for v, t in zip(x["v"], x["t"])) for n, x in rows.items()}
    print(f"\n{RES}x{RES}, {SPP} spp x {SEEDS} seeds, {ROUNDS} rounds, {THREADS} threads; medians")
    print("| configuration | tracker | image mean | V (per-pixel variance, one render) | render s | violations / sample | V / capped auto | efficiency / capped auto |")
    print("|---|---|---|---|---|---|---|---|")
    for name, x in rows.items():
        v, t = statistics.median(x["v"]), statistics.median(x["t"])
        print(f"| {name} | {x['tracker']} | {np.mean(x['mean']):.5f} | {v:.4e} | {t:.2f} | "
              f"{statistics.median(x['viol']):.4f} | {v / statistics.median(rows[base]['v']):.3f} | "
              f"{eff[name] / eff[base]:.3f} |")


if __name__ == "__main__":
    main()
