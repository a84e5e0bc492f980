"""What the add-on translates beyond the smoke VDB: volumes made by Geometry Nodes
(written to a temporary VDB), the camera (sensor fit, shift, orthographic, clipping,
depth of field) checked against the image a Blender camera projects analytically."""

import math
import subprocess

import bpy
import numpy as np
import pytest

import nimbus
from conftest import CUBE_DISTANCE, cube_scene, principled_volume, render, volume_cube_tree


def same_bits(a, b):
    a, b = np.ascontiguousarray(a, np.float32), np.ascontiguousarray(b, np.float32)
    return a.shape == b.shape and np.array_equal(a.view(np.uint32), b.view(np.uint32))


def cli_render(addon, nimbus_bin, tmp_path):
    """`nimbus render` of the stage the add-on rendered last, with its settings."""
    k = addon.last_render["kwargs"]
    exr = tmp_path / "cli.exr"
    subprocess.run(
        [str(nimbus_bin), "render", addon.last_render["stage"], "-o", str(exr), "--camera",
         k["camera"], "--res", f"{k['res'][0]}x{k['res'][1]}", "--spp", str(k["spp"]),
         "--seed", str(k["seed"]), "--max-depth", str(k["max_depth"]), "--tracker",
         k["tracker"]], check=True, capture_output=True)
    return nimbus.read_exr(str(exr))


# ---- the analytic image of boxes ------------------------------------------------------


def blender_rays(cam, w, h, u, v, lens_uv=(0.0, 0.0)):
    """Blender's camera (BKE_camera_params_compute_viewplane) for the test cameras,
    which sit at (0, -CUBE_DISTANCE, 0) looking along +Y with image up = +Z: world
    ray origins and directions through film points (u right, v down, in pixels from
    the top left) and the lens point lens_uv (unit disk)."""
    fit = cam.sensor_fit
    if fit == "AUTO":
        fit = "HORIZONTAL" if w >= h else "VERTICAL"
        sensor = cam.sensor_width
    else:
        sensor = cam.sensor_width if fit == "HORIZONTAL" else cam.sensor_height
    viewfac = w if fit == "HORIZONTAL" else h
    if cam.type == "ORTHO":
        pix = cam.ortho_scale / viewfac
    else:
        pix = sensor / cam.lens / viewfac
    x = (u - w / 2 + cam.shift_x * viewfac) * pix
    z = (h / 2 - v + cam.shift_y * viewfac) * pix
    if cam.type == "ORTHO":
        o = np.stack([x, np.full_like(x, -CUBE_DISTANCE), z], -1)
        d = np.broadcast_to(np.array([0.0, 1.0, 0.0]), o.shape)
        return o, d
    d = np.stack([x, np.ones_like(x), z], -1)
    o = np.broadcast_to(np.array([0.0, -CUBE_DISTANCE, 0.0]), d.shape)
    if cam.dof.use_dof:
        # Thin lens: radius lens / (2 f-stop) (mm -> m), the plane at depth s sharp.
        s = cam.dof.focus_distance
        r = cam.lens * 1e-3 / (2 * cam.dof.aperture_fstop)
        focus = o + d * s
        o = o + np.array([lens_uv[0] * r, 0.0, lens_uv[1] * r])
        d = focus - o
    return o, d / np.linalg.norm(d, axis=-1, keepdims=True)


def chords(o, d, boxes, near, far):
    """Summed length of the rays' segments inside the boxes (lo, hi) and inside the
    camera's depth range [near, far] (depth = y + CUBE_DISTANCE)."""
    total = np.zeros(o.shape[:-1])
    with np.errstate(divide="ignore", invalid="ignore"):
        for lo, hi in boxes:
            t0 = (np.array(lo) - o) / d
            t1 = (np.array(hi) - o) / d
            tn = np.nanmax(np.minimum(t0, t1), -1)
            tf = np.nanmin(np.maximum(t0, t1), -1)
            # Depth clipping: depth(t) = o_y + CUBE_DISTANCE + t d_y.
            dn = (near - (o[..., 1] + CUBE_DISTANCE)) / d[..., 1]
            df = (far - (o[..., 1] + CUBE_DISTANCE)) / d[..., 1]
            tn = np.maximum(np.maximum(tn, dn), 0.0)
            tf = np.minimum(tf, df)
            total += np.maximum(tf - tn, 0.0)
    return total


def expected_coverage(cam, w, h, boxes):
    """(inside, outside): pixels where every ray through the pixel's 3 x 3 points 1 px
    apart (the margin of a 1-pixel filter and of the voxels' trilinear edge) and
    through 17 lens points (centre, rim) crosses at least 0.5 units of the boxes
    (optical depth >= 10 at density 20: alpha is 1 but for e^-10), and where none
    crosses any."""
    v, u = np.mgrid[0:h, 0:w] + 0.5
    lens = [(0.0, 0.0)]
    if cam.dof.use_dof:
        lens += [(math.cos(a), math.sin(a)) for a in np.linspace(0, 2 * math.pi, 16,
                                                                   endpoint=False)]
    inside = np.ones((h, w), bool)
    outside = np.ones((h, w), bool)
    for du in (-1, 0, 1):
        for dv in (-1, 0, 1):
            for luv in lens:
                o, d = blender_rays(cam, w, h, u + du, v + dv, luv)
                c = chords(o, d, boxes, cam.clip_start, cam.clip_end)
                inside &= c >= 0.5
                outside &= c == 0.0
    return inside, outside


UNIT_CUBE = [((-1.0, -1.0, -1.0), (1.0, 1.0, 1.0))]


def assert_coverage(alpha, cam, boxes=UNIT_CUBE, min_inside=20):
    h, w = alpha.shape
    inside, outside = expected_coverage(cam, w, h, boxes)
    assert inside.sum() >= min_inside, f"only {inside.sum()} pixels surely inside"
    bad_in = inside & (alpha <= 0.5)
    bad_out = outside & (alpha != 0.0)
    assert not bad_in.any(), (
        f"{bad_in.sum()} of {inside.sum()} pixels inside the silhouette have alpha <= 0.5, "
        f"e.g. {np.argwhere(bad_in)[:5].tolist()}")
    assert not bad_out.any(), (
        f"{bad_out.sum()} of {outside.sum()} pixels outside the silhouette have alpha > 0, "
        f"e.g. {np.argwhere(bad_out)[:5].tolist()}")


# ---- volumes made by Geometry Nodes ---------------------------------------------------


@pytest.mark.parametrize("on", ["mesh", "volume"])
def test_a_geometry_nodes_volume_renders(addon, nimbus_bin, tmp_path, on):
    """A Volume Cube node (density 1 in [-1, 1]^3, 64^3 voxels, Set Material: a
    Principled Volume of density 20) on a mesh (an instance the exporter leaves out:
    the add-on writes its grids with VolumeGrids.save and defines the volume) and on
    a Volume object (the exporter writes volumes/Volume.vdb; the add-on its own
    file): the cube is where the camera projects it (alpha > 0.5 on every pixel
    surely inside, 0 on every pixel surely outside), with the material's density,
    and the image is `nimbus render` of the translated stage bit for bit."""
    scene, obj, cam = cube_scene(on="mesh" if on == "mesh" else "volume")
    scene.nimbus.keep_files = True
    combined = render(scene, tmp_path / "addon.exr")["Combined"]
    assert_coverage(combined[..., 3], cam.data)
    stage = open(addon.last_render["stage"]).read()
    assert "volumes_nimbus/" in stage, "the grids are not the add-on's VDB"
    cli = cli_render(addon, nimbus_bin, tmp_path)
    for i, c in enumerate("RGBA"):
        assert same_bits(combined[..., i], cli[c]), f"channel {c} differs from nimbus render's"


def test_two_geometry_nodes_volumes_keep_their_own_grids(addon, tmp_path):
    """Blender's exporter writes every Geometry Nodes volume whose evaluated data is
    named 'Volume' to the same volumes/Volume.vdb (the last one wins: two cubes of
    half-size 1 and 0.5 both rendered at 0.5); the add-on writes one VDB per object."""
    scene, obj, cam = cube_scene(on="volume")
    material = principled_volume("small_material", 20.0)
    small = bpy.data.objects.new("small", bpy.data.volumes.new("small_vol"))
    scene.collection.objects.link(small)
    small.modifiers.new("volume", "NODES").node_group = volume_cube_tree(material, size=0.5)
    obj.location = (-1.5, 0.0, 0.0)
    small.location = (1.5, 0.0, 0.0)
    alpha = render(scene, tmp_path / "two.exr")["Combined"][..., 3]
    boxes = [((-2.5, -1.0, -1.0), (-0.5, 1.0, 1.0)), ((1.0, -0.5, -0.5), (2.0, 0.5, 0.5))]
    assert_coverage(alpha, cam.data, boxes)


def test_a_fluid_domain_is_a_warning_and_no_holdout(addon, tmp_path):
    """A fluid domain (Mantaflow cannot bake in bpy from PyPI: its script fails with
    'LevelsetGrid' object has no attribute 'setConst' and aborts the process): the
    domain's mesh would hide the volume as a holdout; it is left out, with a warning
    naming the object."""
    scene, obj, cam = cube_scene()
    me = bpy.data.meshes.new("domain_mesh")
    s = 3.0
    me.from_pydata([(x, y, z) for x in (-s, s) for y in (-s, s) for z in (-s, s)], [],
                   [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4),
                    (1, 5, 7, 3)])
    domain = bpy.data.objects.new("domain", me)
    scene.collection.objects.link(domain)
    domain.modifiers.new("Fluid", "FLUID").fluid_type = "DOMAIN"
    try:
        alpha = render(scene, tmp_path / "fluid.exr")["Combined"][..., 3]
    finally:
        # A Mantaflow domain alive at exit aborts the interpreter ("can't clean grid
        # cache, some grids are still in use"): free it here.
        domain.modifiers.clear()
        bpy.data.objects.remove(domain)
        bpy.context.evaluated_depsgraph_get()
    assert any("'domain'" in w and "fluid" in w for w in addon.last_render["warnings"])
    assert_coverage(alpha, cam.data)
