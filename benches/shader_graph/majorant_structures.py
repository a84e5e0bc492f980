"""Equal-sample relMSE and time of majorant structures on issue 47's scenes (a) and (b)
as the Blender add-on translates them (the tests' own builders), rendered by the nimbus
module at 160x160, max depth 8, `auto`'s tracker.

Run under the bpy 5.0.1 venv with the nimbus wheel installed, from the project root:
    NIMBUS_BIN=target/release/nimbus $BPY_PYTHON benches/shader_graph/majorant_structures.py
env: SCENES (a,b), SPP (64), WORK (/tmp/nimbus-majorants-47), STRUCTURES (comma-separated entries
`default` or `octree_depth=D[;octree_prune=C]` / `majorant_cell=N`).

Method. The add-on exports each scene once (F12 with `keep_files`, left in its
temporary folder); a reference is the
mean of two seeds at 1024 spp (octree depth 8, unpruned: any structure is unbiased);
then 3 interleaved rounds (seeds 1..3) of one SPP render per structure. relMSE = mean
over the pixels the reference covers (alpha > 0.01) and R, G, B, A of ((x - ref)^2 - v) /
(ref^2 + 0.01), v the reference's own noise ((ref0 - ref1)^2 / 4); time = the render's
`render_seconds` (sampling, without loading); efficiency = 1 / (relMSE x time); medians.
"""
import os
import statistics
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO / "blender" / "tests"))
sys.path.insert(0, str(REPO / "tests" / "fixtures"))

import bpy  # noqa: E402
import numpy as np  # noqa: E402

import conftest  # noqa: E402,F401  (registers nothing by itself)
import nimbus  # noqa: E402
import nimbus_blender  # noqa: E402
from conftest import SMOKE_VDB, render, smoke_scene  # noqa: E402
import test_shader_graph as tsg  # noqa: E402

SPP = int(os.environ.get("SPP", "64"))
WORK = Path(os.environ.get("WORK", "/tmp/nimbus-majorants-47"))
STRUCTURES = os.environ.get(
    "STRUCTURES",
    "default,octree_depth=8,octree_depth=8;octree_prune=0.2,"
    "octree_depth=8;octree_prune=0.05,octree_depth=8;octree_prune=0,majorant_cell=8",
).split(",")
RES = (160, 160)
KW = dict(res=RES, max_depth=8)


def export(name):
    """The add-on's translated stage of scene `name`, kept in WORK/name."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    nimbus_blender.register()
    if name == "a":
        scene = tsg.noise_cube_scene()
    else:
        scene, _, _ = smoke_scene(SMOKE_VDB, res=RES[0], lights=("sun",), world=False)
        tsg.smoke_density_graph()
    scene.render.resolution_x, scene.render.resolution_y = RES
    scene.render.engine = "NIMBUS"
    scene.nimbus.keep_files = True
    scene.nimbus.samples = 1
    scene.render.image_settings.media_type = "MULTI_LAYER_IMAGE"
    scene.render.image_settings.color_depth = "32"
    before = set(Path(os.environ.get("TMPDIR", "/tmp")).glob("nimbus-blender-*"))
    render(scene, WORK / f"{name}_export.exr")
    made = set(Path(os.environ.get("TMPDIR", "/tmp")).glob("nimbus-blender-*")) - before
    # Left where the add-on wrote it: the stage names the VDB by a relative path.
    (kept,) = made
    return kept / "scene_nimbus.usda"


def structure(entry):
    kw = {}
    for part in entry.split(";"):
        if part == "default":
            continue
        k, v = part.split("=")
        kw[k] = float(v) if k == "octree_prune" else int(v)
    return kw


def rgba(r):
    return np.asarray(r.rgba, dtype=np.float64)


def main():
    WORK.mkdir(parents=True, exist_ok=True)
    for name in os.environ.get("SCENES", "a,b").split(","):
        stage = str(export(name))
        refs = [
            rgba(nimbus.render(stage, spp=1024, seed=100 + i, octree_depth=8, octree_prune=0.0, **KW))
            for i in range(2)
        ]
        ref = (refs[0] + refs[1]) / 2
        v = (refs[0] - refs[1]) ** 2 / 4
        mask = ref[..., 3] > 0.01

        def relmse(x):
            return float(np.mean((((x - ref) ** 2 - v) / (ref**2 + 0.01))[mask]))

        rows = {s: [] for s in STRUCTURES}
        for seed in range(1, 4):
            for s in STRUCTURES:
                r = nimbus.render(stage, spp=SPP, seed=seed, **KW, **structure(s))
                st = r.stats
                rows[s].append(
                    (relmse(rgba(r)), st["render_seconds"], st["density_lookups"], st["cells_visited"])
                )
        for s in STRUCTURES:
            e = statistics.median(x[0] for x in rows[s])
            t = statistics.median(x[1] for x in rows[s])
            print(
                f"scene ({name}) {s:34s} relMSE {e:.3e} time {t:.2f} s "
                f"lookups {rows[s][0][2]} cells {rows[s][0][3]} efficiency {1 / (e * t):.1f}",
                flush=True,
            )


if __name__ == "__main__":
    main()
