#!/usr/bin/env python3
"""F12 overhead of the add-on (docs/blender.md): scenes/cloud built in Blender (the
cloud VDB with a Principled Volume meaning the stage's coefficients, its camera, sun
and sky), rendered at 320 x 240 / 64 spp through the NIMBUS engine, against
`nimbus render` of the stage the add-on translated, same flags. Not a test (no timed
tests): a measurement, run with the Python that imports bpy 5.0.1 and the wheel.

    NIMBUS_BIN=target/release/nimbus $BPY_PYTHON blender/f12_overhead.py [--runs 5]

Prints every run and the medians: the add-on's wall time around
bpy.ops.render.render() (export, overlay, stage load, render, pixel copies, Blender's
result handling), the CLI's wall time (process start, stage load, render, EXR write),
and the difference.
"""

import argparse
import math
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "blender"))

import bpy  # noqa: E402
import mathutils  # noqa: E402

import nimbus_blender  # noqa: E402
from nimbus_blender import engine  # noqa: E402


def cloud_scene():
    """scenes/cloud/cloud.usda in Blender's Z-up frame (USD (x, y, z) -> (x, -z, y))."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    nimbus_blender.register()
    scene = bpy.context.scene
    vol = bpy.data.volumes.new("Cloud")
    vol.filepath = str(REPO / "scenes" / "cloud" / "cloud.vdb")
    obj = bpy.data.objects.new("Cloud", vol)
    # The stage's rotateXYZ (0, 20, 0) about USD's +Y, which is Blender's +Z, after the
    # Y-up -> Z-up turn of the grid itself.
    obj.rotation_euler = (math.radians(90), 0, math.radians(20))
    scene.collection.objects.link(obj)
    m = bpy.data.materials.new("cloud")
    if m.node_tree is None:
        m.use_nodes = True
    t = m.node_tree
    for n in list(t.nodes):
        t.nodes.remove(n)
    out = t.nodes.new("ShaderNodeOutputMaterial")
    pv = t.nodes.new("ShaderNodeVolumePrincipled")
    # densityScale 24, scattering 0.98, absorption 0.02: sigma_s = C D, sigma_a =
    # (1 - C) (1 - sqrt(A)) D with A black.
    pv.inputs["Density"].default_value = 24.0
    pv.inputs["Color"].default_value = (0.98, 0.98, 0.98, 1)
    pv.inputs["Absorption Color"].default_value = (0, 0, 0, 1)
    pv.inputs["Anisotropy"].default_value = 0.5
    t.links.new(pv.outputs["Volume"], out.inputs["Volume"])
    vol.materials.append(m)
    cd = bpy.data.cameras.new("Camera")
    cd.lens = 50
    cd.sensor_fit = "HORIZONTAL"
    cd.sensor_width = 36
    cd.clip_start, cd.clip_end = 0.1, 1000
    cam = bpy.data.objects.new("Camera", cd)
    cam.location = (0, -4.2, -0.5)
    cam.rotation_euler = (math.radians(95), 0, 0)
    scene.collection.objects.link(cam)
    scene.camera = cam
    sun = bpy.data.lights.new("Sun", "SUN")
    sun.energy = 6
    sun.color = (1, 0.95, 0.88)
    sun.angle = math.radians(0.53)
    so = bpy.data.objects.new("Sun", sun)
    so.rotation_euler = mathutils.Euler((math.radians(-30 + 90), 0, math.radians(80)))
    scene.collection.objects.link(so)
    w = bpy.data.worlds.new("Sky")
    scene.world = w
    if w.node_tree is None:
        w.use_nodes = True
    bg = w.node_tree.nodes["Background"]
    bg.inputs["Color"].default_value = (0.35, 0.55, 1, 1)
    bg.inputs["Strength"].default_value = 0.35
    r = scene.render
    r.engine = "NIMBUS"
    r.resolution_x, r.resolution_y, r.resolution_percentage = 320, 240, 100
    scene.nimbus.samples = 64
    scene.nimbus.max_depth = 64
    scene.nimbus.seed = 1
    scene.nimbus.keep_files = True
    return scene


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--runs", type=int, default=5)
    o = ap.parse_args()
    nimbus_bin = os.environ.get("NIMBUS_BIN", str(REPO / "target" / "release" / "nimbus"))
    scene = cloud_scene()
    addon, cli = [], []
    for i in range(o.runs):
        t0 = time.perf_counter()
        bpy.ops.render.render()
        addon.append(time.perf_counter() - t0)
        used = dict(engine.last_render)
        k = used["kwargs"]
        with tempfile.TemporaryDirectory() as d:
            cmd = [nimbus_bin, "render", used["stage"], "-o", os.path.join(d, "cli.exr"),
                   "--camera", k["camera"], "--res", f"{k['res'][0]}x{k['res'][1]}",
                   "--spp", str(k["spp"]), "--seed", str(k["seed"]), "--max-depth",
                   str(k["max_depth"]), "--tracker", k["tracker"], "--threads", str(k["threads"])]
            t0 = time.perf_counter()
            subprocess.run(cmd, check=True, capture_output=True)
            cli.append(time.perf_counter() - t0)
        print(f"run {i}: add-on {addon[-1]:.3f} s (translate {used['translate_seconds']:.3f} s, "
              f"nimbus.render {used['render_call_seconds']:.3f} s), nimbus render "
              f"{cli[-1]:.3f} s, difference {addon[-1] - cli[-1]:+.3f} s")
    a, c = statistics.median(addon), statistics.median(cli)
    print(f"median of {o.runs}: add-on {a:.3f} s, nimbus render {c:.3f} s, overhead "
          f"{a - c:+.3f} s ({(a - c) / c * 100:+.1f} %); budget 0.5 s + 5 % = "
          f"{0.5 + 0.05 * c:.3f} s")


if __name__ == "__main__":
    main()
