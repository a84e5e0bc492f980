"""Issue 44's three scenes against Cycles 5.0.1 at equal time, through the Blender add-on:
a point light inside smoke, a spot through thin smoke past a holdout occluder, and an
area light beside a thin cloud. The smoke is ../shared/data's Blender smoke VDB
(`openusd_blender_smoke/smoke_000002.vdb`, the add-on tests' volume) with a Principled
Volume; each scene has one light and a black world (transparent film), so every photon
comes from the local light.

Run under the bpy 5.0.1 venv with the nimbus wheel and pytest (.ci/run's blender-addon
stage makes one):
    NIMBUS_BIN=target/release/nimbus $BPY_PYTHON benches/local_lights/vs_cycles.py OUT.csv

Nimbus renders with the add-on's defaults (`--light-sampling auto`: nothing to set);
Cycles with the peers harness' settings (blender_export_scene.set_cycles: box filter,
no clamping, no adaptive sampling or denoising, light threshold 0, light tree on by
default). Same path length (max depth 8, Cycles' bounces 7), 2 threads each.

Per round r, each renderer renders seeds 2r and 2r+1 (the renderer order alternates
each round) and one 1-spp render. Efficiency = 1 / (relMSE x seconds): relMSE the
one-render relative MSE from the round's seed pair (half the mean over the pixels where
either renderer's mean alpha > 0.01 of (a - b)^2 / (m^2 + 0.01), m the mean of all the
renders of both renderers), seconds the whole F12 (export and translation, or Cycles'
scene sync, included) or the sampling time (F12 minus the round's 1-spp F12).

CYCLES_NEE_ONLY=1 renders Cycles with every light's Multiple Importance off (next-event
estimation alone), the configuration whose means are unbiased when a light's sphere
holds smoke (benches/local_lights/README.md, "The light's interior").

Bias: conftest.compare_stacks over all the seeds (image and 8 x 8-block means of alpha,
R, G, B; se from each pixel's variance over the seeds), |N - C| <= Z sqrt(se_N^2 +
se_C^2) + 0.5 % of C (Cycles' null-scattering volumes measured 0.2-0.5 % bright,
conftest.against_cycles).
"""

import importlib.util
import os
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO / "blender"))
sys.path.insert(0, str(REPO / "blender" / "tests"))
sys.path.insert(0, str(REPO / "tests" / "fixtures"))

import bpy  # noqa: E402
import numpy as np  # noqa: E402
import nimbus_blender  # noqa: E402
import blender_export_scene as bex  # noqa: E402
from conftest import SMOKE_VDB, compare_stacks, render, smoke_scene  # noqa: E402

import test_fog  # noqa: E402

# The add-on side of the fog comparison, shared: an F12 timed, and Nimbus' render of it.
_fog = importlib.util.spec_from_file_location(
    "fog_vs_cycles_run", REPO / "benches" / "fog_vs_cycles" / "run.py")
fog_vs_cycles = importlib.util.module_from_spec(_fog)
_fog.loader.exec_module(fog_vs_cycles)
timed, run_nimbus = fog_vs_cycles.timed, fog_vs_cycles.run_nimbus

RES = int(os.environ.get("RES", "96"))
ROUNDS = int(os.environ.get("ROUNDS", "3"))
Z = float(os.environ.get("Z", "4"))
CYCLES_BIAS = 0.005
MAX_DEPTH = int(os.environ.get("MAX_DEPTH", "8"))
CYCLES_NEE_ONLY = os.environ.get("CYCLES_NEE_ONLY", "0") == "1"


def smoke(density):
    """conftest.smoke_scene with no light and a black world (the add-on tests' smoke
    VDB and camera), its Principled Volume set to `density`, Color (0.9, 0.8, 0.6),
    no absorption colour, Anisotropy 0.3."""
    scene, obj, _ = smoke_scene(SMOKE_VDB, res=RES, lights=(), world=False, max_depth=MAX_DEPTH)
    pv = next(n for n in obj.data.materials[0].node_tree.nodes
              if n.bl_idname == "ShaderNodeVolumePrincipled")
    pv.inputs["Density"].default_value = density
    pv.inputs["Color"].default_value = (0.9, 0.8, 0.6, 1.0)
    pv.inputs["Absorption Color"].default_value = (0.0, 0.0, 0.0, 1.0)
    pv.inputs["Anisotropy"].default_value = 0.3
    return scene


def point_in_smoke():
    """A point light (radius 0.05) inside the lower plume of dense smoke (Density 4):
    fire lighting its own smoke."""
    scene = smoke(4.0)
    light = bpy.data.lights.new("fire", "POINT")
    light.energy = 3000.0
    light.color = (1.0, 0.6, 0.3)
    light.shadow_soft_size = 0.05
    light.use_soft_falloff = False
    obj = bpy.data.objects.new("fire", light)
    bpy.context.scene.collection.objects.link(obj)
    obj.location = (0.0, 0.0, 1.0)
    return scene


def spot_through_smoke():
    """God rays: a 20-degree spot straight down through the smoke made thin (Density
    0.3), a holdout plane across half of its beam above the smoke."""
    scene = smoke(0.3)
    test_fog._mesh_object("occluder", "plane", test_fog._holdout_material(), size=1.0,
                          location=(0.5, 0.0, 11.0))
    test_fog._spot((0.0, 0.0, 14.0), 40000.0, size_deg=20.0, radius=0.25)
    return scene


def area_beside_cloud():
    """A 4 x 4 square area light 7 units beside the smoke made thin (Density 0.5),
    facing it."""
    scene = smoke(0.5)
    light = bpy.data.lights.new("panel", "AREA")
    light.energy = 8000.0
    light.shape = "SQUARE"
    light.size = 4.0
    obj = bpy.data.objects.new("panel", light)
    bpy.context.scene.collection.objects.link(obj)
    bex.look_at(obj, (7.0, 0.0, 4.0), (0.0, 0.0, 4.0))
    return scene


CASES = {
    # name: (scene builder, Nimbus spp, Cycles spp)
    "point_in_smoke": (point_in_smoke, int(os.environ.get("SPP_NB_POINT", "128")),
                       int(os.environ.get("SPP_CY_POINT", "32"))),
    "spot_through_smoke": (spot_through_smoke, int(os.environ.get("SPP_NB_SPOT", "128")),
                           int(os.environ.get("SPP_CY_SPOT", "32"))),
    "area_beside_cloud": (area_beside_cloud, int(os.environ.get("SPP_NB_AREA", "128")),
                          int(os.environ.get("SPP_CY_AREA", "32"))),
}


def setup(builder):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    nimbus_blender.register()
    scene = builder()
    scene.nimbus.max_depth = MAX_DEPTH
    return scene


def run_cycles(scene, out, spp, seed):
    if CYCLES_NEE_ONLY:
        # Cycles' Multiple Importance on a light whose sphere holds medium loses light
        # (measured: README, "The light's interior"); next events alone do not.
        for light in bpy.data.lights:
            light.cycles.use_multiple_importance_sampling = False
    transparent = scene.render.film_transparent
    scene.render.image_settings.media_type = "IMAGE"  # as conftest.against_cycles
    bex.set_cycles((RES, RES), MAX_DEPTH, transparent)
    scene.render.image_settings.media_type = "MULTI_LAYER_IMAGE"
    scene.render.image_settings.color_depth = "32"
    scene.cycles.samples = spp
    scene.cycles.seed = seed
    return timed(scene, out)


def main(out_csv, only=None):
    out_csv = Path(out_csv)
    work = Path(tempfile.mkdtemp(prefix="local_lights_vs_cycles-"))  # the EXRs
    rows = []
    cases = {k: v for k, v in CASES.items() if not only or k in only}
    for case, (builder, spp_nb, spp_cy) in cases.items():
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
                    print(f"{case} {name} seed {seed} {spp} spp: {secs:.2f} s", flush=True)
                rows.append(dict(case=case, renderer=name, spp=spp, round=r, one_spp_s=one,
                                 pair=pair))
        mask = fog_vs_cycles.score_case(rows, case, images)
        stacks = {k: np.stack(v) for k, v in images.items()}
        ok, report, n = compare_stacks(stacks, z=Z, bias=CYCLES_BIAS, block=8)
        print(f"{case}: bias check over {n} px, |N - C| <= {Z} se + {CYCLES_BIAS:.1%} C: "
              f"{'agree' if ok else 'DISAGREE'}")
        for line in report:
            print(f"  {line}")
        for name in images:
            mean = stacks[name][:, mask, :].mean(axis=(0, 1))
            print(f"{case} {name}: mean RGBA {np.round(mean, 5)}", flush=True)
    fog_vs_cycles.write_and_summarise(rows, cases, out_csv)

if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "benches/local_lights/vs_cycles.csv",
         sys.argv[2].split(",") if len(sys.argv) > 2 else None)
