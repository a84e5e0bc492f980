"""Cycles' own bias on issue 44's point-in-smoke scene, measured with Cycles.

Cycles 5.0 draws free paths against a majorant octree (128^3 cells over the object's
bounds) whose cell maxima are sampled, not bounded: 16 points per cell padded by 20 %
(intern/cycles/bvh/octree.cpp, kernel_volume_density_evaluate), and where the density
exceeds that majorant its kernel rescales the throughput of the event it sampled, not the
segments it skipped (shade_volume.h, volume_integrate_step_scattering: "this is not
really unbiased"). A shader with a Light Path node makes Cycles estimate the majorant of
every non-camera segment on the fly instead (4 samples x 1.5, at least 0.5:
volume_estimate_extrema). So the same smoke rendered twice by Cycles, its Density once
a constant and once `Density x max(Is Camera Ray, 1)` (the same value everywhere, for
every ray), differs by the part of Cycles' bias that its second majorant removes.

The light sits inside the smoke, and Cycles lights the smoke inside its sphere
(Nimbus does too since `nimbus:lightsInterior`); with the light's Multiple Importance
on (Cycles' default), paths that scatter inside the sphere and hit it from there were
measured to lose light (docs: benches/local_lights/README.md), so a fourth render turns
it off: next-event estimation alone, unbiased.

This renders vs_cycles.py's point_in_smoke with seeds 0..K-1 four ways (Nimbus through
the add-on, Cycles, Cycles with the Light Path node, Cycles with the light's Multiple
Importance off), each seed in turn, and compares pairs with conftest.compare_stacks
(image and 8 x 8-block means, |z| tolerance Z from both stacks' per-pixel variance,
plus 0.5 % of the second):

    K=12 NIMBUS_BIN=target/release/nimbus $BPY_PYTHON benches/local_lights/cycles_bias.py
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

K = int(os.environ.get("K", "12"))
SPP_NB = int(os.environ.get("SPP_NB_POINT", "1024"))
SPP_CY = int(os.environ.get("SPP_CY_POINT", "512"))
BLOCK = (40, 24)  # the block vs_cycles.py found disagreeing (row, column; 8 x 8)


def light_path_density(scene):
    """The smoke's Density (4) times max(Light Path's Is Camera Ray, 1): the same field,
    with a Light Path node in the shader."""
    obj = next(o for o in scene.objects if o.type == "VOLUME")
    nt = obj.data.materials[0].node_tree
    pv = next(n for n in nt.nodes if n.bl_idname == "ShaderNodeVolumePrincipled")
    lp = nt.nodes.new("ShaderNodeLightPath")
    one = nt.nodes.new("ShaderNodeMath")
    one.operation = "MAXIMUM"
    one.inputs[1].default_value = 1.0
    density = nt.nodes.new("ShaderNodeMath")
    density.operation = "MULTIPLY"
    density.inputs[1].default_value = pv.inputs["Density"].default_value
    nt.links.new(lp.outputs["Is Camera Ray"], one.inputs[0])
    nt.links.new(one.outputs[0], density.inputs[0])
    nt.links.new(density.outputs[0], pv.inputs["Density"])


def light_nee_only(scene):
    """The light sampled by next-event estimation alone (Multiple Importance off)."""
    for light in bpy.data.lights:
        light.cycles.use_multiple_importance_sampling = False


RUNS = {
    "nimbus": (vs.run_nimbus, SPP_NB, None),
    "cycles": (vs.run_cycles, SPP_CY, None),
    "cycles_light_path": (vs.run_cycles, SPP_CY, light_path_density),
    "cycles_nee_only": (vs.run_cycles, SPP_CY, light_nee_only),
}


def block_mean(stack, row, col):
    b = stack[:, row:row + 8, col:col + 8, 0].mean(axis=(1, 2))
    return b.mean(), b.std(ddof=1) / np.sqrt(len(b))


def main():
    work = Path(tempfile.mkdtemp(prefix="cycles_bias-"))
    images = {name: [] for name in RUNS}
    secs = {name: [] for name in RUNS}
    for seed in range(K):
        for name, (fn, spp, edit) in RUNS.items():
            scene = vs.setup(vs.point_in_smoke)
            if edit:
                edit(scene)
            img, s = fn(scene, work / f"{name}_s{seed}.exr", spp, seed)
            images[name].append(img)
            secs[name].append(s)
            print(f"{name} seed {seed} {spp} spp: {s:.2f} s", flush=True)
    stacks = {k: np.stack(v) for k, v in images.items()}
    np.savez(work / "stacks.npz", **stacks)
    print(f"\nK {K} seeds; EXRs and stacks.npz in {work}")
    for name, st in stacks.items():
        m = st[..., :3].mean(axis=(0, 1, 2))
        b, se = block_mean(st, *BLOCK)
        print(f"{name}: median F12 {np.median(secs[name]):.2f} s; image mean RGB "
              f"{np.round(m, 5)}; block {BLOCK} R {b:.5f} +- {se:.5f}")
    for a, c in (("nimbus", "cycles"), ("nimbus", "cycles_nee_only"),
                 ("cycles_nee_only", "cycles"), ("nimbus", "cycles_light_path"),
                 ("cycles_light_path", "cycles")):
        ok, report, n = vs.compare_stacks({"nimbus": stacks[a], "cycles": stacks[c]},
                                          z=vs.Z, bias=vs.CYCLES_BIAS, block=8)
        print(f"\n{a} (as 'nimbus') against {c} (as 'cycles') over {n} px: "
              f"{'agree' if ok else 'DISAGREE'}")
        for line in report:
            print(f"  {line}")
        (ba, sa), (bc, sc) = block_mean(stacks[a], *BLOCK), block_mean(stacks[c], *BLOCK)
        print(f"  block {BLOCK} R difference {ba - bc:+.5f} +- {np.hypot(sa, sc):.5f} "
              f"(z {(ba - bc) / np.hypot(sa, sc):+.2f})")


if __name__ == "__main__":
    main()
