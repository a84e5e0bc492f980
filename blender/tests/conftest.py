"""Fixtures of the add-on's tests: headless Blender (`bpy` 5.0.1 from PyPI) with the
`nimbus` wheel installed, the add-on imported from `blender/` and registered, the smoke
VDB of the shared data, and scenes built in Python.

Run: `NIMBUS_BIN=target/release/nimbus $BPY_PYTHON -m pytest blender/tests -q`, with
$BPY_PYTHON a CPython 3.11 with bpy==5.0.1, numpy, pytest and the nimbus wheel (.ci/run's
blender-addon stage). A missing input fails (no skips: NIMBUS_REQUIRE_DATA semantics).
"""

import math
import os
import shutil
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO / "blender"))
sys.path.insert(0, str(REPO / "tests" / "fixtures"))

import bpy  # noqa: E402  (a missing bpy fails the run)

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
    engine.last_render.clear()
    yield engine
    engine.break_hook = None
    # A stage kept for the test (scene.nimbus.keep_files) goes with it.
    stage = engine.last_render.get("stage")
    if stage and Path(stage).parent.name.startswith("nimbus-blender-"):
        shutil.rmtree(Path(stage).parent, ignore_errors=True)


# The chromatic medium of the Cycles comparison (Principled Volume inputs).
DENSITY = 4.0
COLOR = (0.9, 0.6, 0.3)
ABSORPTION_COLOR = (0.2, 0.4, 0.8)
ANISOTROPY = 0.4


def smoke_scene(vdb, res=64, lights=("sun", "spot", "disk"), world=True, transparent=True,
                max_depth=8):
    """The scene of tests/fixtures/blender_export_scene.py (its builders, so Nimbus and
    Cycles see what tests/blender_export.rs checks light by light): the smoke VDB with
    a chromatic Principled Volume (Color and Absorption Color coloured, Anisotropy
    0.4), its camera, the named lights (a hard-coned spot; Soft Falloff off: the
    settings docs/blender.md shows to have exact UsdLux equivalents) and its world
    colour (0.4, 0.5, 0.7) x 1.5, or a black world. Rendered by Nimbus; maxDepth as
    given (Cycles' bounces are set from it by set_cycles)."""
    import blender_export_scene as bex

    bex.DENSITY, bex.COLOR, bex.ABSORPTION_COLOR, bex.ANISOTROPY = (
        DENSITY, COLOR, ABSORPTION_COLOR, ANISOTROPY)
    scene = bpy.context.scene
    obj = bex.add_volume(str(vdb))
    cam_data = bpy.data.cameras.new("camera")
    cam_data.lens = bex.FOCAL_MM
    cam_data.sensor_fit = "HORIZONTAL"
    cam_data.sensor_width = bex.SENSOR_MM
    cam_data.clip_start = 0.1
    cam_data.clip_end = 1000.0
    camera = bpy.data.objects.new("camera", cam_data)
    scene.collection.objects.link(camera)
    bex.look_at(camera, bex.CAMERA_AT, bex.CAMERA_TARGET)
    scene.camera = camera
    made = {kind: bex.add_light(kind) for kind in lights}
    bex.set_world("world" if world else "sun", None)
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


# The world colour of set_world("world") times its strength.
WORLD_RADIANCE = (0.4 * 1.5, 0.5 * 1.5, 0.7 * 1.5)


def render(scene, path):
    """F12 and the render result as Blender writes it (a multilayer EXR, 32-bit
    float): {pass name: (H, W, C) array, channels in the pass' order}, row 0 at the
    top, read back with nimbus.read_exr."""
    import numpy as np

    # write_still, not Image.save_render: after a Cycles render, save_render of the
    # Render Result wrote the same pixels for every seed (bpy 5.0.1; seen while writing
    # the Cycles test).
    scene.render.filepath = str(path)
    bpy.ops.render.render(write_still=True)
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


def volume_cube_tree(material, size=1.0, resolution=64):
    """A Geometry Nodes tree: a Volume Cube node (density 1 in [-size, size]^3, the
    given voxel resolution) with `material` set on it."""
    ng = bpy.data.node_groups.new("volume_cube", "GeometryNodeTree")
    ng.interface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
    out = ng.nodes.new("NodeGroupOutput")
    cube = ng.nodes.new("GeometryNodeVolumeCube")
    cube.inputs["Min"].default_value = (-size, -size, -size)
    cube.inputs["Max"].default_value = (size, size, size)
    for k in "XYZ":
        cube.inputs[f"Resolution {k}"].default_value = resolution
    mat = ng.nodes.new("GeometryNodeSetMaterial")
    mat.inputs["Material"].default_value = material
    ng.links.new(cube.outputs[0], mat.inputs["Geometry"])
    ng.links.new(mat.outputs[0], out.inputs[0])
    return ng


def principled_volume(name, density, color=(0.8, 0.8, 0.8)):
    m = bpy.data.materials.new(name)
    m.use_nodes = True
    nt = m.node_tree
    nt.nodes.clear()
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    pv = nt.nodes.new("ShaderNodeVolumePrincipled")
    pv.inputs["Density"].default_value = density
    pv.inputs["Color"].default_value = (*color, 1.0)
    nt.links.new(pv.outputs["Volume"], out.inputs["Volume"])
    return m


# The volume cube scene: a cube [-1, 1]^3 at the origin seen along +Y from CUBE_DISTANCE.
CUBE_DISTANCE = 10.0


def cube_scene(res=(64, 64), density=20.0, on="mesh", lens=50.0, sensor=36.0):
    """A Geometry Nodes Volume Cube (on a mesh object, an instance the exporter leaves
    out, or on a Volume object, which the exporter writes to volumes/Volume.vdb) with a
    Principled Volume of `density`, a sun, a camera at (0, -CUBE_DISTANCE, 0) looking
    along +Y (image x = world X, image up = world Z), film transparent, no world."""
    scene = bpy.context.scene
    material = principled_volume("cube_material", density)
    data = bpy.data.meshes.new("cube_mesh") if on == "mesh" else bpy.data.volumes.new("cube_vol")
    obj = bpy.data.objects.new("cube", data)
    scene.collection.objects.link(obj)
    obj.modifiers.new("volume", "NODES").node_group = volume_cube_tree(material)
    cam_data = bpy.data.cameras.new("camera")
    cam_data.lens = lens
    cam_data.sensor_width = sensor
    cam_data.sensor_fit = "AUTO"
    camera = bpy.data.objects.new("camera", cam_data)
    scene.collection.objects.link(camera)
    camera.location = (0.0, -CUBE_DISTANCE, 0.0)
    camera.rotation_euler = (math.pi / 2, 0.0, 0.0)
    scene.camera = camera
    sun = bpy.data.lights.new("sun", "SUN")
    sun.energy = 2.0
    sun_obj = bpy.data.objects.new("sun", sun)
    scene.collection.objects.link(sun_obj)
    sun_obj.rotation_euler = (0.5, 0.3, 0.0)
    r = scene.render
    r.engine = "NIMBUS"
    r.resolution_x, r.resolution_y = res
    r.resolution_percentage = 100
    r.film_transparent = True
    scene.view_settings.view_transform = "Standard"
    scene.view_settings.look = "None"
    s = r.image_settings
    s.media_type = "MULTI_LAYER_IMAGE"
    s.color_depth = "32"
    scene.nimbus.samples = 2
    scene.nimbus.max_depth = 4
    return scene, obj, camera


def t_quantile(p, dof):
    """The upper-tail-p quantile of Student's t with `dof` degrees of freedom: the
    normal quantile z corrected by the Cornish-Fisher series in 1/dof (Abramowitz and
    Stegun 26.7.5, four terms). Checked against the integrated t density at upper
    tails 7.8e-6 (alpha 1e-3 over 64 comparisons): the quantile's true tail is the
    asked one within 0.1 % for dof >= 20, 2 % at 10, 20 % at 5."""
    from statistics import NormalDist

    z = NormalDist().inv_cdf(1.0 - p)
    if not math.isfinite(dof):
        return z
    g = ((z**3 + z) / 4,
         (5 * z**5 + 16 * z**3 + 3 * z) / 96,
         (3 * z**7 + 19 * z**5 + 17 * z**3 - 15 * z) / 384,
         (79 * z**9 + 776 * z**7 + 1482 * z**5 - 1920 * z**3 - 945 * z) / 92160)
    return z + sum(gi / dof ** (i + 1) for i, gi in enumerate(g))


# Family-wise false-failure probability of the block comparison (Bonferroni over the
# blocks x channels compared) and the fewest mask pixels a block needs to be compared.
BLOCK_ALPHA = 1e-3
BLOCK_MIN_PIXELS = 16


def block_means(stacks, mask, block, bias, alpha=BLOCK_ALPHA, min_pixels=BLOCK_MIN_PIXELS,
                tols=None):
    """The block-mean comparison of against_cycles: the image cut into block x block
    pixel squares; a square with fewer than `min_pixels` pixels of `mask` is left out
    (its se would rest on a few pixels' variances; its pixels stay in the image mean).
    Per square b and channel c, each renderer's mean over its masked pixels and se_b^2
    = sum_p s_p^2 / (K n_b^2) (s_p^2 the pixel's variance over the K seeds), as for the
    image mean. The test: |N_b - C_b| <= t se + bias |C_b| with se = sqrt(se_N^2 +
    se_C^2) and t the Student-t quantile of upper tail alpha / (2 M) (two-sided,
    Bonferroni over the M = squares x channels compared: the whole family falsely fails
    with probability <= alpha when both renderers converge to the same image) for the
    block's Welch-Satterthwaite degrees of freedom (each renderer's sum_p s_p^2 has
    (sum s_p^2)^2 / sum (s_p^4 / (K - 1)) of them). A block and channel where both
    renderers' pixels have no variance (Cycles' exact 0 inside world fog under a sun,
    alpha 1 on an opaque film) has tolerance bias |C_b|. tols: a dict that receives
    each compared block's tolerance, {(row, column, channel): tol}. Returns (ok, report
    lines)."""
    import numpy as np

    h, w = mask.shape
    squares, left_out = [], 0
    for y in range(0, h, block):
        for x in range(0, w, block):
            m = np.zeros_like(mask)
            m[y:y + block, x:x + block] = mask[y:y + block, x:x + block]
            if m.sum() >= min_pixels:
                squares.append(((y, x), m))
            else:
                left_out += 1
    comparisons = len(squares) * 4
    p = alpha / (2 * max(comparisons, 1))
    ok, worst, failed, dofs, ts = True, {}, [], [], []
    for (y, x), m in squares:
        n = int(m.sum())
        for ci, name in enumerate("RGBA"):
            stat = {}
            for r, s in stacks.items():
                k = s.shape[0]
                px = s[:, m, ci]
                v = px.var(axis=0, ddof=1)
                sv, sv2 = v.sum(), (v * v).sum()
                dof = sv * sv / (sv2 / (k - 1)) if sv2 > 0 else math.inf
                stat[r] = (px.mean(), sv / (k * n * n), dof)
            (mn, vn, dn), (mc, vc, dc) = stat["nimbus"], stat["cycles"]
            var = vn + vc
            if var > 0:
                dof = var * var / sum(v * v / d for v, d in ((vn, dn), (vc, dc))
                                      if v > 0)
                t = t_quantile(p, dof)
                dofs.append(dof)
                ts.append(t)
            else:
                t = 0.0
            tol = t * math.sqrt(var) + bias * abs(mc)
            if tols is not None:
                tols[(y, x, name)] = tol
            d = abs(mn - mc)
            q = d / tol if tol > 0 else (0.0 if d == 0 else math.inf)
            if q > worst.get(name, (-1,))[0]:
                worst[name] = (q, (y, x), mn, mc, tol)
            if d > tol:
                ok = False
                failed.append(f"  block at row {y}, column {x} ({n} px) {name}: nimbus "
                              f"{mn:.5f}, cycles {mc:.5f}, |diff| {d:.5f} > {tol:.5f}")
    report = [f"{block}x{block} blocks: {len(squares)} compared, {left_out} left out "
              f"(< {min_pixels} px); Bonferroni alpha {alpha:g} over {comparisons}: "
              + (f"t {min(ts):.2f}-{max(ts):.2f} (dof >= {min(dofs):.0f})" if ts else
                 "no variance")]
    for name, (q, (y, x), mn, mc, tol) in worst.items():
        report.append(f"  {name}: worst block (row {y}, column {x}) |diff| / tol {q:.2f} "
                      f"(nimbus {mn:.5f}, cycles {mc:.5f}, tol {tol:.5f})")
    return ok and bool(squares), report + failed


def against_cycles(scene, tmp_path, seeds=(0, 1, 2, 3), spp=32, max_depth=8, z=5.0,
                   bias=0.005, erode=0, block=0, exclude=None, keep=None):
    """test_addon.py's comparison with Cycles as a function: `scene` (set up for
    Nimbus) rendered through the add-on and by Cycles (blender_export_scene.set_cycles:
    the peer harness' settings), len(seeds) x spp each. Over the pixels where either's
    mean alpha > 0.01, the mean of alpha and of R, G, B per renderer, its standard error
    from the per-pixel variance over the seeds (se^2 = sum_p s_p^2 / (K n^2)); returns
    (ok, report lines, pixel count): ok when every |N - C| <= z sqrt(se_N^2 + se_C^2)
    + bias |C| (bias: Cycles' null-scattering volumes measured 0.2-0.5 % bright).
    erode > 0 keeps only pixels whose (2 erode + 1)^2 neighbourhood is all in the mask
    (the volume's inside, away from its silhouette). block > 0 also compares the means
    of block x block pixel squares (block_means; ok then needs both). exclude: an (H, W)
    boolean array of pixels left out of every comparison (row 0 at the top). keep: a
    dict that receives the image stacks ("stacks": {"nimbus", "cycles"}: (K, H, W, 4))
    and the compared pixels ("mask"), and with block > 0 the blocks' tolerances
    ("block_tols", as block_means')."""
    import numpy as np
    from blender_export_scene import set_cycles

    w, h = scene.render.resolution_x, scene.render.resolution_y
    transparent = scene.render.film_transparent
    scene.nimbus.samples = spp
    scene.nimbus.max_depth = max_depth
    images = {"nimbus": [], "cycles": []}
    for seed in seeds:
        scene.nimbus.seed = seed
        images["nimbus"].append(render(scene, tmp_path / f"n{seed}.exr")["Combined"])
    scene.render.image_settings.media_type = "IMAGE"
    set_cycles((w, h), max_depth, transparent)
    scene.render.image_settings.media_type = "MULTI_LAYER_IMAGE"
    scene.render.image_settings.color_depth = "32"
    scene.cycles.samples = spp
    for seed in seeds:
        scene.cycles.seed = seed
        images["cycles"].append(render(scene, tmp_path / f"c{seed}.exr")["Combined"])
    scene.render.engine = "NIMBUS"
    stacks = {k: np.stack(v).astype(np.float64) for k, v in images.items()}
    return compare_stacks(stacks, z, bias, erode, block, exclude, keep)


def compare_stacks(stacks, z=5.0, bias=0.005, erode=0, block=0, exclude=None, keep=None):
    """against_cycles' comparison of two image stacks {"nimbus", "cycles"}: (K, H, W, 4),
    K_r independent images each (the seeds; K may differ between the two) whose means
    estimate the two images; the arguments and the result as against_cycles'."""
    import numpy as np

    mask = (stacks["nimbus"][..., 3].mean(0) > 0.01) | (stacks["cycles"][..., 3].mean(0) > 0.01)
    for _ in range(erode):
        m = mask.copy()
        m[1:] &= mask[:-1]
        m[:-1] &= mask[1:]
        m[:, 1:] &= mask[:, :-1]
        m[:, :-1] &= mask[:, 1:]
        m[0], m[-1], m[:, 0], m[:, -1] = False, False, False, False
        mask = m
    if exclude is not None:
        mask &= ~exclude
    n = int(mask.sum())
    if keep is not None:
        keep.update(stacks=stacks, mask=mask)
    report, ok = [], n > 0
    for ci, name in enumerate("RGBA"):
        stat = {}
        for r, s in stacks.items():
            k = s.shape[0]
            px = s[:, mask, ci]
            stat[r] = (px.mean(), np.sqrt(px.var(axis=0, ddof=1).sum() / (k * n * n)))
        (mn, sn), (mc, sc) = stat["nimbus"], stat["cycles"]
        tol = z * np.hypot(sn, sc) + bias * abs(mc)
        ratio = f"{mn / mc:.4f}" if mc != 0 else "-"  # Cycles' 0: the tolerance is 0
        report.append(f"{name}: nimbus {mn:.5f} +- {sn:.5f}, cycles {mc:.5f} +- {sc:.5f}, "
                      f"ratio {ratio}, |diff| {abs(mn - mc):.5f} <= {tol:.5f}")
        ok &= bool(abs(mn - mc) <= tol)
    if block:
        tols = keep.setdefault("block_tols", {}) if keep is not None else None
        block_ok, lines = block_means(stacks, mask, block, bias, tols=tols)
        ok &= block_ok
        report += lines
    return ok, report, n
