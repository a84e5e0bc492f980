"""The block of vs_cycles.py's point_in_smoke that Nimbus and Cycles disagreed on (8 x 8
pixels at row 40, column 24 of 96 x 96, on the smoke's silhouette), rendered alone with
far more samples: does each estimator's mean move when its samples grow?

The add-on translates the scene (as vs_cycles.py builds it) to a stage; `nimbus render
--region 24,40,32,48 --res 96x96` renders the block with Nimbus' defaults (`auto`) and
with its plainest estimator (`--tracker delta --light-sampling collisions
--scatter-guiding phase`), and Cycles renders it through a render border, each K seeds.
Printed: per estimator, spp, the block's mean R over its 64 pixels per seed, and their
mean +- standard error (K - 1 dof).

    NIMBUS_BIN=target/release/nimbus $BPY_PYTHON benches/local_lights/silhouette_convergence.py
env: K (4), SPP_AUTO (65536), SPP_DELTA (262144), SPP_CYCLES (65536), SPP_LOW (1024).
"""
import importlib.util
import os
import subprocess
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
_spec = importlib.util.spec_from_file_location("vs_cycles", HERE / "vs_cycles.py")
vs = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(vs)

import bpy  # noqa: E402
import nimbus  # noqa: E402
import numpy as np  # noqa: E402
from nimbus_blender import translate  # noqa: E402

K = int(os.environ.get("K", "4"))
ROW, COL = 40, 24
BIN = os.environ["NIMBUS_BIN"]


def nimbus_block(stage, out, spp, seed, flags):
    subprocess.run([BIN, "render", str(stage), "-o", str(out), "--res", f"{vs.RES}x{vs.RES}",
                    "--region", f"{COL},{ROW},{COL + 8},{ROW + 8}", "--max-depth",
                    str(vs.MAX_DEPTH), "--seed", str(seed), "--spp", str(spp), *flags],
                   check=True, capture_output=True)
    return float(nimbus.read_exr(str(out))["R"].astype(np.float64).mean())


def cycles_block(out, spp, seed):
    scene = vs.setup(vs.point_in_smoke)
    r = scene.render
    r.use_border, r.use_crop_to_border = True, False
    res = vs.RES
    r.border_min_x, r.border_max_x = COL / res, (COL + 8) / res
    r.border_min_y, r.border_max_y = (res - ROW - 8) / res, (res - ROW) / res
    img, _ = vs.run_cycles(scene, out, spp, 100 + seed)
    return float(img[ROW:ROW + 8, COL:COL + 8, 0].mean())


def report(name, spp, values):
    v = np.array(values)
    print(f"{name}, {spp} spp: per seed {np.round(v, 5)}; mean {v.mean():.5f} +- "
          f"{v.std(ddof=1) / np.sqrt(len(v)):.5f}", flush=True)


def main():
    work = Path(tempfile.mkdtemp(prefix="silhouette-"))
    vs.setup(vs.point_in_smoke)
    stage = translate.translate(bpy.context.evaluated_depsgraph_get(), str(work)).stage
    plain = ["--tracker", "delta", "--light-sampling", "collisions", "--scatter-guiding", "phase"]
    low = int(os.environ.get("SPP_LOW", "1024"))
    runs = [
        ("Nimbus auto", int(os.environ.get("SPP_AUTO", "65536")), []),
        ("Nimbus auto", low, []),
        ("Nimbus delta/collisions/phase", int(os.environ.get("SPP_DELTA", "262144")), plain),
        ("Nimbus delta/collisions/phase", low, plain),
    ]
    for name, spp, flags in runs:
        report(name, spp, [nimbus_block(stage, work / f"n{seed}.exr", spp, seed + 1, flags)
                           for seed in range(K)])
    for spp in (int(os.environ.get("SPP_CYCLES", "65536")), low // 2):
        report("Cycles", spp, [cycles_block(work / f"c{seed}.exr", spp, seed)
                               for seed in range(K)])


if __name__ == "__main__":
    main()
