"""Equal-time efficiency of Nimbus (through the Blender add-on) against Cycles 5.0.1 on
the add-on tests' fog scenes (blender/tests/test_fog.py): the fog box lit by a spot
through an occluder, and world fog over a holdout ground lit by a point light (with a
sun, both renderers give exactly 0 inside world fog).

Run under the bpy 5.0.1 venv with the nimbus wheel and pytest (.ci/run's blender-addon
stage makes one):
    NIMBUS_BIN=target/release/nimbus $BPY_PYTHON benches/fog_vs_cycles/run.py OUT.csv

Per round r, each renderer renders seeds 2r and 2r+1 (interleaved: the renderer order
alternates each round), plus one 1-spp render. Efficiency = 1 / (relMSE x seconds), with
relMSE the one-render relative MSE from the seed pair (half the mean over the pixels
where either alpha > 0.01 of (a - b)^2 / (m^2 + 0.01), m the mean of every render of
both renderers), and seconds either the whole F12 (export, translation or scene sync,
sampling) or the sampling time (F12 minus the round's 1-spp F12). Same path-length
limits (max depth 8: Cycles' volume bounces 7), box filter, no adaptive sampling or
denoising for Cycles, 2 threads each. The means of all seeds are printed per renderer
(the bias check is the tests'; this is about time).
"""

import csv
import os
import statistics
import tempfile
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO / "blender"))
sys.path.insert(0, str(REPO / "blender" / "tests"))
sys.path.insert(0, str(REPO / "tests" / "fixtures"))

import bpy  # noqa: E402
import numpy as np  # noqa: E402
import nimbus_blender  # noqa: E402
from blender_export_scene import set_cycles  # noqa: E402
from conftest import render  # noqa: E402

import test_fog  # noqa: E402

RES = int(os.environ.get("RES", "96"))
ROUNDS = int(os.environ.get("ROUNDS", "3"))
MAX_DEPTH = 8
CASES = {
    # name: (scene builder, Nimbus spp, Cycles spp)
    "fog_box_spot": (test_fog.fog_box_scene, int(os.environ.get("SPP_NB", "256")),
                     int(os.environ.get("SPP_CY", "64"))),
    "world_fog_point": (lambda: test_fog.world_fog_scene("point"),
                        int(os.environ.get("SPP_NB", "256")), int(os.environ.get("SPP_CY", "64"))),
}


def setup(builder):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    nimbus_blender.register()
    scene = builder()
    scene.render.resolution_x = RES
    scene.render.resolution_y = RES
    scene.nimbus.max_depth = MAX_DEPTH
    return scene


def timed(scene, path):
    t = time.perf_counter()
    img = render(scene, path)["Combined"].astype(np.float64)
    return img, time.perf_counter() - t


def run_nimbus(scene, out, spp, seed):
    scene.render.engine = "NIMBUS"
    scene.nimbus.samples = spp
    scene.nimbus.seed = seed
    return timed(scene, out)


def run_cycles(scene, out, spp, seed):
    transparent = scene.render.film_transparent
    scene.render.image_settings.media_type = "IMAGE"  # as conftest.against_cycles
    set_cycles((RES, RES), MAX_DEPTH, transparent)
    scene.render.image_settings.media_type = "MULTI_LAYER_IMAGE"
    scene.render.image_settings.color_depth = "32"
    scene.cycles.samples = spp
    scene.cycles.seed = seed
    return timed(scene, out)


def main(out_csv):
    out_csv = Path(out_csv)
    work = Path(tempfile.mkdtemp(prefix="fog_vs_cycles-"))  # the EXRs
    rows = []
    for case, (builder, spp_nb, spp_cy) in CASES.items():
        scene = setup(builder)
        runners = {"nimbus": (run_nimbus, spp_nb), "cycles": (run_cycles, spp_cy)}
        images = {r: [] for r in runners}
        for r in range(ROUNDS):
            order = list(runners) if r % 2 == 0 else list(reversed(runners))
            for name in order:
                fn, spp = runners[name]
                _, one = fn(scene, work / f"{case}_{name}_r{r}_1spp.exr", 1, 1000 + r)
                pair = []
                for seed in (2 * r, 2 * r + 1):
                    img, secs = fn(scene, work / f"{case}_{name}_s{seed}.exr", spp, seed)
                    images[name].append(img)
                    pair.append((seed, img, secs))
                rows.append(dict(case=case, renderer=name, spp=spp, round=r, one_spp_s=one,
                                 pair=pair))
        mask = score_case(rows, case, images)
        for name in images:
            mean = np.stack(images[name])[:, mask, :].mean(axis=(0, 1))
            print(f"{case} {name}: mean RGBA over {int(mask.sum())} px {np.round(mean, 5)}")
    write_and_summarise(rows, CASES, out_csv)


def score_case(rows, case, images):
    """Fills in each of `case`'s rows its relMSE (from its round's seed pair), mean
    seconds, sampling seconds and both efficiencies; returns the mask of pixels where
    either renderer's mean alpha exceeds 0.01, over which relMSE is taken."""
    stacks = {k: np.stack(v) for k, v in images.items()}
    mask = (stacks["nimbus"][..., 3].mean(0) > 0.01) | (stacks["cycles"][..., 3].mean(0) > 0.01)
    m = np.concatenate([stacks["nimbus"], stacks["cycles"]]).mean(0)[..., :3]
    for row in rows:
        if row["case"] != case:
            continue
        (_, a, sa), (_, b, sb) = row.pop("pair")
        d = (a[..., :3] - b[..., :3]) ** 2 / (m ** 2 + 0.01)
        row["relmse"] = 0.5 * d[mask].mean()
        row["seconds"] = (sa + sb) / 2
        row["sampling_s"] = row["seconds"] - row["one_spp_s"]
        row["efficiency"] = 1 / (row["relmse"] * row["seconds"])
        row["efficiency_sampling"] = 1 / (row["relmse"] * max(row["sampling_s"], 1e-9))
    return mask


def write_and_summarise(rows, cases, out_csv):
    """Writes the rows to `out_csv` and prints, per case, each renderer's medians and
    Nimbus' efficiency over Cycles' (whole F12 and sampling time)."""
    keys = ["case", "renderer", "spp", "round", "seconds", "one_spp_s", "sampling_s", "relmse",
            "efficiency", "efficiency_sampling"]
    with open(out_csv, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=keys)
        w.writeheader()
        for row in rows:
            w.writerow({k: row[k] for k in keys})
    print("medians:")
    for case in cases:
        eff = {}
        for name in ("nimbus", "cycles"):
            rs = [r for r in rows if r["case"] == case and r["renderer"] == name]
            med = {k: statistics.median(r[k] for r in rs)
                   for k in ("seconds", "sampling_s", "relmse", "efficiency", "efficiency_sampling")}
            eff[name] = med
            print(f"  {case} {name} spp {rs[0]['spp']}: " +
                  ", ".join(f"{k} {v:.4g}" for k, v in med.items()))
        print(f"  {case}: Nimbus/Cycles efficiency "
              f"{eff['nimbus']['efficiency'] / eff['cycles']['efficiency']:.2f} (whole F12), "
              f"{eff['nimbus']['efficiency_sampling'] / eff['cycles']['efficiency_sampling']:.2f}"
              " (sampling time)")

if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "benches/fog_vs_cycles/fog_vs_cycles.csv")
