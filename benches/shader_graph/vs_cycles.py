"""Equal-time efficiency of Nimbus (through the Blender add-on, `auto`) against Cycles 5.0.1
on issue 47's scenes (a) and (b): the scenes of blender/tests/test_shader_graph.py, built by
its own builders, at RES x RES.

Run under the bpy 5.0.1 venv with the nimbus wheel installed, from the project root:
    NIMBUS_BIN=target/release/nimbus $BPY_PYTHON benches/shader_graph/vs_cycles.py
env: RES (64), SPP (64: the measured renders), REF_SPP (1024 per reference seed), ROUNDS (3).

Method. Per scene and renderer: a reference, the mean of two seeds at REF_SPP; then ROUNDS
interleaved rounds (Nimbus, Cycles) of one SPP render each (seeds 1..ROUNDS) and one 1-spp
render each (for the sampling time). relMSE = mean over the pixels either reference covers
(alpha > 0.01) and the R, G, B, A channels of ((x - ref)^2 - v) / (ref^2 + 0.01), v =
(ref0 - ref1)^2 / 4 (the reference's own noise, subtracted), against the renderer's own
reference. Efficiency = 1 / (relMSE x time); medians over the rounds. Time: F12's wall clock
(bpy.ops.render.render: Nimbus' export and translation, Cycles' sync, included), and the
sampling time: that minus the 1-spp render's median.
"""
import os
import statistics
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO / "blender" / "tests"))
sys.path.insert(0, str(REPO / "tests" / "fixtures"))

import bpy  # noqa: E402
import numpy as np  # noqa: E402

import conftest  # noqa: E402  (registers nothing by itself: the fixtures are not run)
import nimbus_blender  # noqa: E402
from blender_export_scene import set_cycles  # noqa: E402
from conftest import SMOKE_VDB, render, smoke_scene  # noqa: E402
import test_shader_graph as tsg  # noqa: E402

RES = int(os.environ.get("RES", "64"))
SPP = int(os.environ.get("SPP", "64"))
REF_SPP = int(os.environ.get("REF_SPP", "1024"))
ROUNDS = int(os.environ.get("ROUNDS", "3"))
WORK = Path(os.environ.get("WORK", "/tmp/nimbus-vs-cycles-47"))
WORK.mkdir(parents=True, exist_ok=True)


def build(name):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    nimbus_blender.register()
    if name == "a":
        scene = tsg.noise_cube_scene()
    else:
        scene, _, _ = smoke_scene(SMOKE_VDB, res=RES, lights=("sun",), world=False)
        tsg.smoke_density_graph()
    scene.render.resolution_x = scene.render.resolution_y = RES
    scene.nimbus.max_depth = 8
    return scene


def use(scene, renderer):
    if renderer == "nimbus":
        scene.render.engine = "NIMBUS"
    else:
        scene.render.image_settings.media_type = "IMAGE"
        set_cycles((RES, RES), 8, scene.render.film_transparent)
    scene.render.image_settings.media_type = "MULTI_LAYER_IMAGE"
    scene.render.image_settings.color_depth = "32"


def shot(scene, renderer, spp, seed, tag):
    use(scene, renderer)
    if renderer == "nimbus":
        scene.nimbus.samples, scene.nimbus.seed = spp, seed
    else:
        scene.cycles.samples, scene.cycles.seed = spp, seed
    t0 = time.perf_counter()
    img = render(scene, WORK / f"{tag}.exr")["Combined"].astype(np.float64)
    return img, time.perf_counter() - t0


def main():
    for name in ("a", "b"):
        scene = build(name)
        refs = {r: [shot(scene, r, REF_SPP, s, f"{name}_{r}_ref{s}")[0] for s in (101, 102)]
                for r in ("nimbus", "cycles")}
        mask = np.zeros((RES, RES), bool)
        for r in refs.values():
            mask |= 0.5 * (r[0][..., 3] + r[1][..., 3]) > 0.01
        stats = {r: {"t": [], "t1": [], "e": []} for r in refs}
        for k in range(ROUNDS):
            for r in (("nimbus", "cycles") if k % 2 == 0 else ("cycles", "nimbus")):
                img, t = shot(scene, r, SPP, k + 1, f"{name}_{r}_{k}")
                _, t1 = shot(scene, r, 1, k + 1, f"{name}_{r}_1spp_{k}")
                ref = 0.5 * (refs[r][0] + refs[r][1])
                v = 0.25 * (refs[r][0] - refs[r][1]) ** 2
                e = (((img - ref) ** 2 - v) / (ref ** 2 + 0.01))[mask].mean()
                stats[r]["t"].append(t)
                stats[r]["t1"].append(t1)
                stats[r]["e"].append(e)
        ra, rb = (0.5 * (refs[r][0] + refs[r][1]) for r in ("nimbus", "cycles"))
        cross = ((ra - rb) ** 2 / (rb ** 2 + 0.01))[mask].mean()
        means = {r: (0.5 * (refs[r][0] + refs[r][1]))[mask].mean(0) for r in refs}
        print(f"scene ({name}), {RES}x{RES}, {mask.sum()} pixels, {SPP} spp x {ROUNDS} rounds;"
              f" references {REF_SPP} spp x 2; reference relMSE Nimbus vs Cycles {cross:.3e};"
              f" mean R, G, B, A Nimbus / Cycles "
              + ", ".join(f"{a / b:.4f}" for a, b in zip(means["nimbus"], means["cycles"])))
        eff = {}
        for r, s in stats.items():
            t, t1, e = (statistics.median(s[x]) for x in ("t", "t1", "e"))
            eff[r] = (1 / (e * t), 1 / (e * max(t - t1, 1e-9)))
            print(f"  {r:7s} relMSE {e:.3e} (rounds {', '.join(f'{x:.3e}' for x in s['e'])}),"
                  f" time {t:.2f} s, 1-spp {t1:.2f} s, sampling {t - t1:.2f} s")
        print(f"  efficiency Nimbus / Cycles: whole render {eff['nimbus'][0] / eff['cycles'][0]:.2f}x,"
              f" sampling time {eff['nimbus'][1] / eff['cycles'][1]:.2f}x")


if __name__ == "__main__":
    main()
