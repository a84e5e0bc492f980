"""Fixtures of the add-on's tests: headless Blender (`bpy` 5.0.1 from PyPI) with the
`nimbus` wheel installed, the add-on imported from `blender/` and registered, the smoke
VDB of the shared data, and scenes built in Python.

Run: `NIMBUS_BIN=target/release/nimbus $BPY_PYTHON -m pytest blender/tests -q`, with
$BPY_PYTHON a CPython 3.11 with bpy==5.0.1, numpy, pytest and the nimbus wheel (.ci/run's
blender-addon stage). A missing input fails (no skips: NIMBUS_REQUIRE_DATA semantics).
"""

import math
import os
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO / "blender"))
sys.path.insert(0, str(REPO / "tests" / "fixtures"))

import bpy  # noqa: E402  (a missing bpy fails the run)
import mathutils  # noqa: E402

import nimbus  # noqa: E402,F401  (a missing wheel fails the run)
import nimbus_blender  # noqa: E402

assert bpy.app.version_string == "5.0.1", f"bpy {bpy.app.version_string}, not 5.0.1"

SHARED = Path(os.environ.get("NIMBUS_SHARED_DATA", REPO.parent / "shared" / "data"))
SMOKE_VDB = SHARED / "openusd_blender_smoke" / "smoke_000002.vdb"


@pytest.fixture(scope="session")
def smoke_vdb():
    assert SMOKE_VDB.is_file(), (
        f"{SMOKE_VDB} is absent (the shared data; NIMBUS_SHARED_DATA overrides the location)")
    return SMOKE_VDB


@pytest.fixture(scope="session")
def nimbus_bin():
    path = Path(os.environ.get("NIMBUS_BIN", REPO / "target" / "release" / "nimbus"))
    assert path.is_file(), f"no nimbus binary at {path}: build it (cargo b) or set NIMBUS_BIN"
    return path


@pytest.fixture(autouse=True)
def addon():
    """A factory-fresh Blender with the add-on registered, for every test."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    nimbus_blender.register()
    from nimbus_blender import engine

    engine.break_hook = None
    yield engine
    engine.break_hook = None


def look_at(obj, at, target):
    obj.location = at
    d = mathutils.Vector(target) - mathutils.Vector(at)
    # Blender cameras and lights look down their local -Z with +Y up.
    obj.rotation_euler = d.to_track_quat("-Z", "Y").to_euler()


# The chromatic medium of the Cycles comparison (Principled Volume inputs).
DENSITY = 4.0
COLOR = (0.9, 0.6, 0.3)
ABSORPTION_COLOR = (0.2, 0.4, 0.8)
ANISOTROPY = 0.4


def smoke_scene(vdb, res=64, lights=("sun", "spot", "disk"), world=(0.3, 0.4, 0.6),
                transparent=True, max_depth=8):
    """The smoke VDB with a chromatic Principled Volume (Color and Absorption Color
    coloured, Anisotropy 0.4), a camera, the named lights (hard-coned spot, lights with
    Soft Falloff off: the settings docs/blender.md shows to have exact UsdLux
    equivalents) and a world colour; Nimbus' maxDepth and Cycles' bounces agree."""
    scene = bpy.context.scene
    volume = bpy.data.volumes.new("smoke")
    volume.filepath = str(vdb)
    volume.render.precision = "FULL"
    volume.render.clipping = 0.0
    obj = bpy.data.objects.new("smoke", volume)
    scene.collection.objects.link(obj)
    material = bpy.data.materials.new("smoke_material")
    tree = material.node_tree
    if tree is None:
        material.use_nodes = True
        tree = material.node_tree
    for node in list(tree.nodes):
        tree.nodes.remove(node)
    out = tree.nodes.new("ShaderNodeOutputMaterial")
    pv = tree.nodes.new("ShaderNodeVolumePrincipled")
    pv.inputs["Density"].default_value = DENSITY
    pv.inputs["Color"].default_value = (*COLOR, 1.0)
    pv.inputs["Absorption Color"].default_value = (*ABSORPTION_COLOR, 1.0)
    pv.inputs["Anisotropy"].default_value = ANISOTROPY
    pv.inputs["Emission Strength"].default_value = 0.0
    pv.inputs["Blackbody Intensity"].default_value = 0.0
    tree.links.new(pv.outputs["Volume"], out.inputs["Volume"])
    volume.materials.append(material)

    cam_data = bpy.data.cameras.new("camera")
    cam_data.lens = 50.0
    cam_data.sensor_fit = "HORIZONTAL"
    cam_data.sensor_width = 36.0
    camera = bpy.data.objects.new("camera", cam_data)
    scene.collection.objects.link(camera)
    look_at(camera, (0.0, -24.0, 4.0), (0.0, 0.0, 4.0))
    scene.camera = camera

    target = (0.0, 0.0, 4.0)
    made = {}
    for kind in lights:
        if kind == "sun":
            light = bpy.data.lights.new("sun", "SUN")
            light.energy = 3.0
            light.angle = 0.0
            at = (-10.0, -6.0, 14.0)
        elif kind == "spot":
            light = bpy.data.lights.new("spot", "SPOT")
            light.energy = 3000.0
            light.shadow_soft_size = 0.5
            light.spot_size = math.radians(40.0)
            light.spot_blend = 0.0
            light.use_soft_falloff = False
            at = (7.0, -6.0, 8.0)
        elif kind == "disk":
            light = bpy.data.lights.new("disk", "AREA")
            light.energy = 3000.0
            light.shape = "DISK"
            light.size = 3.0
            at = (0.0, -8.0, -4.0)
        else:
            raise ValueError(kind)
        o = bpy.data.objects.new(kind, light)
        scene.collection.objects.link(o)
        look_at(o, at, target)
        made[kind] = o

    w = bpy.data.worlds.new("world")
    scene.world = w
    if w.node_tree is None:
        w.use_nodes = True
    bg = w.node_tree.nodes.get("Background") or w.node_tree.nodes.new("ShaderNodeBackground")
    bg.inputs["Color"].default_value = (*(world or (0.0, 0.0, 0.0)), 1.0)
    bg.inputs["Strength"].default_value = 1.0 if world else 0.0

    r = scene.render
    r.engine = "NIMBUS"
    r.resolution_x = r.resolution_y = res
    r.resolution_percentage = 100
    r.film_transparent = transparent
    r.threads_mode = "FIXED"
    r.threads = os.cpu_count() or 1
    scene.view_settings.view_transform = "Standard"
    scene.view_settings.look = "None"
    s = r.image_settings
    s.media_type = "MULTI_LAYER_IMAGE"
    s.color_depth = "32"
    scene.nimbus.max_depth = max_depth
    return scene, obj, made


def render(scene, path):
    """F12, then the render result as Blender writes it (a multilayer EXR, 32-bit
    float): {pass name: (H, W, C) array, channels in the pass' order}, row 0 at the
    top, read back with nimbus.read_exr."""
    import numpy as np

    bpy.ops.render.render()
    bpy.data.images["Render Result"].save_render(str(path))
    channels = nimbus.read_exr(str(path))
    passes = {}
    for name, arr in channels.items():
        # Blender names them VIEWLAYER.PASS.VIEWLAYER.PASS.CHANNEL in the file.
        layer_pass, chan = name.rsplit(".", 1)
        pass_name = layer_pass.split(".")[-1]
        passes.setdefault(pass_name, {})[chan] = arr
    order = {"R": 0, "G": 1, "B": 2, "A": 3, "X": 0}
    return {
        p: np.stack([c[k] for k in sorted(c, key=lambda k: order.get(k, 9))], axis=-1)
        for p, c in passes.items()
    }
