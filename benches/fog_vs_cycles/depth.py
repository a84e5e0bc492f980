"""Which path-length limit of Cycles matches Nimbus' maxDepth in world fog (issue 43)?

The add-on test scene `world_fog_point` (blender/tests/test_fog.py: World Volume Scatter
of Density 0.02, Color 0.8, over a holdout ground, a 1,000 W point light of radius 0.1)
rendered by Nimbus through the add-on at several scene.nimbus.max_depth, and by Cycles
with several volume bounce limits (blender_export_scene.set_cycles, then volume_bounces
and max_bounces overridden; set_cycles itself sets both to max_depth - 1), and optionally
with the point light's radius changed. Per configuration: SEEDS renders of SPP_NB
(Nimbus) or SPP_CY (Cycles) samples at RES x RES; the image mean of R and alpha over all
pixels, its standard error from the per-pixel variance over the seeds (se^2 = sum_p s_p^2
/ (K n^2)), and R relative to the reference configuration (Cycles with 64 volume bounces).

RADIUS=r adds both renderers at the light radius r (Cycles 7 bounces, Nimbus maxDepth 8).

ZOOM=1 instead renders the light's near field: the camera aimed at the light with a
LENS (720) mm lens, RES x RES pixels (at 48, 0.0125 units a pixel at the light), Nimbus
at maxDepth 8 and Cycles at 7 bounces; prints R against the rays' distance h from the
light's centre, beside sigma_s L_e chord(h) T: the single scattering of fog inside a
sphere that radiates L_e = P / (4 pi^2 r^2) into its inside too (chord = 2 sqrt(r^2 -
h^2), T = exp(-sigma_t D) from the camera at D).

Run under the bpy 5.0.1 venv with the nimbus wheel (.ci/run's blender-addon stage):
    RADIUS=0.01 NIMBUS_BIN=target/release/nimbus $BPY_PYTHON benches/fog_vs_cycles/depth.py
    ZOOM=1 SEEDS=4 SPP_NB=64 SPP_CY=32 $BPY_PYTHON benches/fog_vs_cycles/depth.py
"""

import math
import os
import sys
import tempfile
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

RES = int(os.environ.get("RES", "48"))
SEEDS = int(os.environ.get("SEEDS", "4"))
SPP_NB = int(os.environ.get("SPP_NB", "256"))
SPP_CY = int(os.environ.get("SPP_CY", "64"))
# (renderer, label, settings): Nimbus {max_depth, radius}, Cycles {volume, total, radius}.
CONFIGS = [
    ("cycles", "volume_bounces 6 (max_bounces 6)", dict(volume=6, total=6)),
    ("cycles", "volume_bounces 7 (max_bounces 7) = set_cycles(8)", dict(volume=7, total=7)),
    ("cycles", "volume_bounces 8 (max_bounces 8)", dict(volume=8, total=8)),
    ("cycles", "volume_bounces 64 (max_bounces 64)", dict(volume=64, total=64)),
    ("cycles", "volume_bounces 7, max_bounces 64", dict(volume=7, total=64)),
    ("nimbus", "max_depth 7", dict(max_depth=7)),
    ("nimbus", "max_depth 8", dict(max_depth=8)),
    ("nimbus", "max_depth 9", dict(max_depth=9)),
    ("nimbus", "max_depth 64", dict(max_depth=64)),
]
if os.environ.get("RADIUS"):
    r = float(os.environ["RADIUS"])
    CONFIGS += [
        ("cycles", f"volume_bounces 7, light radius {r}", dict(volume=7, total=7, radius=r)),
        ("nimbus", f"max_depth 8, light radius {r}", dict(max_depth=8, radius=r)),
    ]


ZOOM = os.environ.get("ZOOM") == "1"
LENS = float(os.environ.get("LENS", "720"))
LIGHT = (0.0, 2.0, 3.0)  # test_fog.world_fog_scene's point light
CAMERA = (0.0, -10.0, 2.0)  # and its camera


def setup(radius=None):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    nimbus_blender.register()
    scene = test_fog.world_fog_scene("point")
    scene.render.resolution_x = scene.render.resolution_y = RES
    if radius is not None:
        bpy.data.lights["point"].shadow_soft_size = radius
    if ZOOM:
        dy, dz = LIGHT[1] - CAMERA[1], LIGHT[2] - CAMERA[2]
        scene.camera.rotation_euler = (math.pi / 2 + math.atan2(dz, dy), 0.0, 0.0)
        scene.camera.data.lens = LENS
    return scene


def run(renderer, settings, work, tag):
    scene = setup(settings.get("radius"))
    images = []
    t = time.perf_counter()
    for seed in range(SEEDS):
        if renderer == "nimbus":
            scene.render.engine = "NIMBUS"
            scene.nimbus.samples = SPP_NB
            scene.nimbus.max_depth = settings["max_depth"]
            scene.nimbus.seed = seed
        else:
            scene.render.image_settings.media_type = "IMAGE"  # as conftest.against_cycles
            set_cycles((RES, RES), 8, scene.render.film_transparent)
            scene.render.image_settings.media_type = "MULTI_LAYER_IMAGE"
            scene.render.image_settings.color_depth = "32"
            scene.cycles.max_bounces = settings["total"]
            scene.cycles.volume_bounces = settings["volume"]
            scene.cycles.samples = SPP_CY
            scene.cycles.seed = seed
        images.append(render(scene, work / f"{tag}_{seed}.exr")["Combined"].astype(np.float64))
    secs = time.perf_counter() - t
    if ZOOM:
        return np.stack(images), secs
    s = np.stack(images).reshape(SEEDS, -1, 4)
    n = s.shape[1]
    mean = s.mean(axis=(0, 1))
    se = np.sqrt(s.var(axis=0, ddof=1).sum(axis=0) / (SEEDS * n * n))
    return mean, se, secs


def zoom(work):
    r = float(os.environ.get("RADIUS", "0.1"))
    light = dict(radius=r)
    imgs = {"nimbus": run("nimbus", dict(max_depth=8, **light), work, "zn")[0],
            "cycles": run("cycles", dict(volume=7, total=7, **light), work, "zc")[0]}
    d = math.dist(LIGHT, CAMERA)
    pix = d * 36.0 / LENS / RES  # sensor width 36 mm (test_fog._camera)
    c0 = (RES - 1) / 2
    yy, xx = np.mgrid[:RES, :RES]
    h = np.hypot(yy - c0, xx - c0) * pix
    sigma = test_fog.WORLD_FOG_DENSITY * 0.8
    le = 1000.0 / (4 * math.pi ** 2 * r * r)  # the point light's 1,000 W
    print(f"light radius {r}, {RES}x{RES} at {pix:.4f} units a pixel, {SEEDS} seeds x "
          f"{SPP_NB} (Nimbus) / {SPP_CY} (Cycles) spp; R (+- se) against h\n")
    print("| h (units) | pixels | Nimbus R | Cycles R | inside-sphere term |")
    print("|---|---|---|---|---|")
    edges = [0, 0.025, 0.05, 0.075, 0.09, 0.1, 0.11, 0.125, 0.15, 0.2, 0.3]
    for lo, hi in zip(edges, edges[1:]):
        m = (h >= lo) & (h < hi)
        if not m.any():
            continue
        hm = h[m].mean()
        inside = sigma * le * 2 * math.sqrt(max(r * r - hm * hm, 0)) * math.exp(-sigma * d)
        cells = []
        for name in ("nimbus", "cycles"):
            px = imgs[name][:, m, 0].astype(np.float64)
            se = math.sqrt(px.mean(1).var(ddof=1) / SEEDS)
            cells.append(f"{px.mean():.3f} +- {se:.3f}")
        print(f"| {lo:.3f}-{hi:.3f} | {int(m.sum())} | {cells[0]} | {cells[1]} | {inside:.2f} |")


def main():
    work = Path(tempfile.mkdtemp(prefix="fog_depth-"))
    if ZOOM:
        zoom(work)
        return
    rows = []
    for i, (renderer, label, settings) in enumerate(CONFIGS):
        mean, se, secs = run(renderer, settings, work, f"c{i}")
        rows.append((renderer, label, mean, se, secs))
        print(f"{renderer:6s} {label:48s} R {mean[0]:.5f} +- {se[0]:.5f}  "
              f"A {mean[3]:.5f} +- {se[3]:.5f}  ({secs:.1f} s)", flush=True)
    ref = next(r for r in rows if r[0] == "cycles" and r[1].startswith("volume_bounces 64"))
    print(f"\n{RES}x{RES}, {SEEDS} seeds x {SPP_NB} spp (Nimbus) / {SPP_CY} spp (Cycles)\n")
    print("| renderer | setting | mean R | se R | R / Cycles(64) | mean alpha |")
    print("|---|---|---|---|---|---|")
    for renderer, label, mean, se, _ in rows:
        ratio = mean[0] / ref[2][0]
        rse = ratio * np.hypot(se[0] / mean[0], ref[3][0] / ref[2][0])
        print(f"| {renderer} | {label} | {mean[0]:.5f} | {se[0]:.5f} | {ratio:.4f} +- "
              f"{rse:.4f} | {mean[3]:.5f} |")


if __name__ == "__main__":
    main()
