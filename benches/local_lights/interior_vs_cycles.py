"""A point light inside the smoke, Nimbus against Cycles 5.0.1 through the add-on, with
the scene's knobs as environment variables: the experiments that found the light's
interior (benches/local_lights/README.md, "The light's interior").

vs_cycles.py's smoke (the add-on tests' VDB, Principled Volume, black world) with one
orange point light of 3,000 W at (0, 0, LZ), radius LR, Soft Falloff off:

    DEN (4)  Density          COL (0.9,0.8,0.6)  Color        ANI (0.3)  Anisotropy
    LZ (1)   light height     LR (0.05)          its radius   D (8)      max depth
    K (8)    seeds            SNB (256), SCY (128): Nimbus' and Cycles' spp
    LMIS=0   the light's Multiple Importance off in Cycles (next events alone)

Each seed renders with Nimbus then Cycles; the line printed holds each renderer's image
mean RGB over the K seeds, the ratio Nimbus / Cycles and its z = (N - C) / sqrt(se_N^2 +
se_C^2), se from the K per-seed image means (K - 1 dof).

    DEN=1 LR=0.5 NIMBUS_BIN=target/release/nimbus $BPY_PYTHON benches/local_lights/interior_vs_cycles.py
"""
import importlib.util
import os
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
_spec = importlib.util.spec_from_file_location("vs_cycles", HERE / "vs_cycles.py")
vs = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(vs)

import bpy  # noqa: E402
import numpy as np  # noqa: E402

E = os.environ
DEN = float(E.get("DEN", "4"))
COL = tuple(map(float, E.get("COL", "0.9,0.8,0.6").split(",")))
ANI = float(E.get("ANI", "0.3"))
LZ = float(E.get("LZ", "1.0"))
LR = float(E.get("LR", "0.05"))
K = int(E.get("K", "8"))
SNB = int(E.get("SNB", "256"))
SCY = int(E.get("SCY", "128"))
DEPTH = int(E.get("D", "8"))
vs.MAX_DEPTH = DEPTH


def build():
    bpy.ops.wm.read_factory_settings(use_empty=True)
    vs.nimbus_blender.register()
    scene = vs.smoke(DEN)
    pv = next(n for o in bpy.data.objects if o.type == "VOLUME"
              for n in o.data.materials[0].node_tree.nodes
              if n.bl_idname == "ShaderNodeVolumePrincipled")
    pv.inputs["Color"].default_value = (*COL, 1.0)
    pv.inputs["Anisotropy"].default_value = ANI
    light = bpy.data.lights.new("fire", "POINT")
    light.energy = 3000.0
    light.color = (1.0, 0.6, 0.3)
    light.shadow_soft_size = LR
    light.use_soft_falloff = False
    if E.get("LMIS") == "0":
        light.cycles.use_multiple_importance_sampling = False
    obj = bpy.data.objects.new("fire", light)
    bpy.context.scene.collection.objects.link(obj)
    obj.location = (0.0, 0.0, LZ)
    scene.nimbus.max_depth = DEPTH
    return scene


def main():
    work = Path(tempfile.mkdtemp(prefix="interior_vs_cycles-"))
    means = {"nimbus": [], "cycles": []}
    for seed in range(K):
        for name, fn, spp in (("nimbus", vs.run_nimbus, SNB), ("cycles", vs.run_cycles, SCY)):
            img, _ = fn(build(), work / f"{name}_{seed}.exr", spp, seed)
            means[name].append(img[..., :3].mean(axis=(0, 1)))
    m = {k: np.array(v) for k, v in means.items()}
    mn, mc = m["nimbus"].mean(0), m["cycles"].mean(0)
    sn, sc = (m[k].std(0, ddof=1) / np.sqrt(K) for k in ("nimbus", "cycles"))
    print(f"DEN {DEN} COL {COL} ANI {ANI} LZ {LZ} LR {LR} D {DEPTH} K {K} "
          f"LMIS {E.get('LMIS', '1')}: Nimbus {mn.round(5)} Cycles {mc.round(5)} "
          f"ratio {(mn / mc).round(4)} z {((mn - mc) / np.hypot(sn, sc)).round(2)}")


if __name__ == "__main__":
    main()
