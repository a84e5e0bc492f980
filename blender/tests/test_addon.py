"""The Nimbus render engine in headless Blender (bpy 5.0.1): the image equals
`nimbus render` of the stage it hands over, the image agrees with Cycles on the same
scene within the noise, passes, cancelling, errors."""

import subprocess
import threading
import time

import bpy
import numpy as np
import pytest

import nimbus
from conftest import WORLD_RADIANCE, render, smoke_scene


def same_bits(a, b):
    a, b = np.ascontiguousarray(a, np.float32), np.ascontiguousarray(b, np.float32)
    return a.shape == b.shape and np.array_equal(a.view(np.uint32), b.view(np.uint32))


def test_registered_with_the_schema_defaults(addon):
    scene = bpy.context.scene
    assert addon.NimbusRenderEngine.bl_idname == "NIMBUS"
    assert addon.NimbusRenderEngine.bl_label == "Nimbus"
    s = scene.nimbus
    # nimbus:samples 16, maxDepth 64, seed 0, tracker auto, scheme hist-avg,
    # transmittance ratio, control 0.05, octreeDepth 0 (schemas/generatedSchema.usda).
    assert (s.samples, s.max_depth, s.seed, s.tracker) == (16, 64, 0, "auto")
    assert (s.scheme, s.transmittance, s.octree_depth) == ("hist-avg", "ratio", 0)
    assert s.control == pytest.approx(0.05) and s.time_limit == 0.0
    # The menus list what the module accepts.
    items = {i.identifier for i in s.bl_rna.properties["tracker"].enum_items}
    assert items == {"auto", *nimbus.tracker_names()}
    items = {i.identifier for i in s.bl_rna.properties["scheme"].enum_items}
    assert items == set(nimbus.scheme_names())
    items = {i.identifier for i in s.bl_rna.properties["transmittance"].enum_items}
    assert items == set(nimbus.transmittance_names())


def test_the_image_is_nimbus_render_of_the_stage_bit_for_bit(addon, smoke_vdb, nimbus_bin,
                                                             tmp_path):
    """The add-on's Combined pass against the CLI rendering the stage the add-on
    translated, with the same flags: bit for bit (transparent film, no world, so the
    add-on changes no pixel)."""
    scene, _, _ = smoke_scene(smoke_vdb, res=48, world=False, lights=("sun", "spot"))
    scene.nimbus.samples = 4
    scene.nimbus.seed = 7
    scene.nimbus.keep_files = True
    passes = render(scene, tmp_path / "addon.exr")
    used = addon.last_render
    k = used["kwargs"]
    exr = tmp_path / "cli.exr"
    subprocess.run(
        [str(nimbus_bin), "render", used["stage"], "-o", str(exr), "--camera", k["camera"],
         "--res", f"{k['res'][0]}x{k['res'][1]}", "--spp", str(k["spp"]), "--seed",
         str(k["seed"]), "--max-depth", str(k["max_depth"]), "--tracker", k["tracker"],
         "--threads", "1"],
        check=True, capture_output=True)
    cli = nimbus.read_exr(str(exr))
    combined = passes["Combined"]
    assert combined.shape == (48, 48, 4)
    assert combined[..., 3].max() > 0.1, "the smoke is not in the image"
    for i, c in enumerate("RGBA"):
        assert same_bits(combined[..., i], cli[c]), f"channel {c} differs from nimbus render's"


def test_denoise_is_nimbus_render_denoise_with_blenders_oidn(addon, smoke_vdb, nimbus_bin,
                                                             tmp_path):
    """Cycles' Denoise checkbox (use_denoising on scene.nimbus): F12 denoises with Blender's
    own Open Image Denoise and equals `nimbus render --denoise` with that library bit for
    bit; the Denoising Albedo pass is then the albedo AOV the denoiser was given (it
    prefilters it before use)."""
    import os
    scene, _, _ = smoke_scene(smoke_vdb, res=32, world=False, lights=("sun",))
    s = scene.nimbus
    assert not s.use_denoising
    s.samples = 4
    s.use_denoising = True
    s.keep_files = True
    scene.view_layers[0].nimbus.use_pass_albedo = True
    passes = render(scene, tmp_path / "addon.exr")
    k = addon.last_render["kwargs"]
    assert k["denoise"] is True, k
    lib = os.environ.get("NIMBUS_OIDN_LIBRARY", "")
    assert lib.endswith("libOpenImageDenoise.so.2") and os.path.isfile(lib), lib
    exr = tmp_path / "cli.exr"
    subprocess.run(
        [str(nimbus_bin), "render", addon.last_render["stage"], "-o", str(exr), "--camera",
         k["camera"], "--res", "32x32", "--spp", "4", "--seed", str(k["seed"]),
         "--max-depth", str(k["max_depth"]), "--denoise", "--threads", "1"],
        check=True, capture_output=True, env=dict(os.environ, NIMBUS_OIDN_LIBRARY=lib))
    cli = nimbus.read_exr(str(exr))
    for i, c in enumerate("RGB"):
        assert same_bits(passes["Combined"][..., i], cli[c]), f"channel {c} differs"
        assert not same_bits(cli[c], cli[f"noisy.{c}"]), f"channel {c} was not denoised"
    for i, c in enumerate("RGB"):
        assert same_bits(passes["Denoising Albedo"][..., i], cli[f"albedo.{c}"])


def test_adaptive_sampling_is_nimbus_render_with_the_same_threshold(addon, smoke_vdb, nimbus_bin,
                                                                   tmp_path):
    """Cycles' Noise Threshold and Min Samples (the same property names on scene.nimbus):
    F12 with them on equals `nimbus render --noise-threshold T --min-spp N` bit for bit,
    and the Samples pass shows pixels stopped between the minimum and the cap."""
    scene, _, _ = smoke_scene(smoke_vdb, res=32, world=False, lights=("sun",))
    s = scene.nimbus
    assert not s.use_adaptive_sampling and s.adaptive_threshold == pytest.approx(0.01)
    s.samples = 64
    s.use_adaptive_sampling = True
    s.adaptive_threshold = 0.05
    s.adaptive_min_samples = 8
    s.keep_files = True
    scene.view_layers[0].nimbus.use_pass_samples = True
    passes = render(scene, tmp_path / "addon.exr")
    k = addon.last_render["kwargs"]
    assert k["noise_threshold"] == pytest.approx(0.05) and k["min_spp"] == 8, k
    taken = passes["Nimbus Samples"][..., 0]
    assert taken.min() >= 8 and taken.max() <= 64 and taken.min() < 64, (taken.min(), taken.max())
    exr = tmp_path / "cli.exr"
    subprocess.run(
        [str(nimbus_bin), "render", addon.last_render["stage"], "-o", str(exr), "--camera",
         k["camera"], "--res", "32x32", "--spp", "64", "--seed", str(k["seed"]),
         "--max-depth", str(k["max_depth"]), "--noise-threshold", str(k["noise_threshold"]),
         "--min-spp", "8", "--threads", "1"], check=True, capture_output=True)
    cli = nimbus.read_exr(str(exr))
    for i, c in enumerate("RGBA"):
        assert same_bits(passes["Combined"][..., i], cli[c]), f"channel {c} differs"


def test_the_status_line_shows_the_estimated_noise(addon, smoke_vdb, tmp_path, monkeypatch):
    """While F12 renders, the status line after each pass shows the estimated noise the
    CLI's progress line shows (and, with adaptive sampling, the share of pixels
    converged); the last pass's is the render's stats' `estimated_noise`, which the final
    line repeats."""
    import re

    scene, _, _ = smoke_scene(smoke_vdb, res=32, world=False, lights=("sun",))
    s = scene.nimbus
    s.samples = 64
    s.use_adaptive_sampling = True
    s.adaptive_threshold = 0.05
    s.adaptive_min_samples = 8
    lines = []
    original = addon.NimbusRenderEngine.status

    def record(self, text):
        lines.append(text)
        original(self, text)

    monkeypatch.setattr(addon.NimbusRenderEngine, "status", record)
    render(scene, tmp_path / "addon.exr")
    during = [x for x in lines if " / 64 samples" in x]
    pattern = r"noise (\d+\.\d{4}), (\d+)% converged"
    assert during and all(re.search(pattern, x) for x in during), lines
    noises = [float(re.search(pattern, x).group(1)) for x in during]
    assert len(set(noises)) > 1, during  # it changes as samples come in
    final = re.search(r"noise (\d+\.\d{4})", lines[-1])
    assert final and float(final.group(1)) == noises[-1], (during[-1], lines[-1])


def test_an_opaque_film_is_nimbus_render_with_alpha_one(addon, smoke_vdb, nimbus_bin, tmp_path):
    """Film not transparent, a world colour: R, G, B are `nimbus render`'s bit for bit
    (the dome seen behind the volume, as Cycles shows the world), alpha is 1."""
    scene, _, _ = smoke_scene(smoke_vdb, res=32, world=True, transparent=False,
                              lights=("disk",))
    scene.nimbus.samples = 2
    scene.nimbus.keep_files = True
    combined = render(scene, tmp_path / "addon.exr")["Combined"]
    k = addon.last_render["kwargs"]
    exr = tmp_path / "cli.exr"
    subprocess.run(
        [str(nimbus_bin), "render", addon.last_render["stage"], "-o", str(exr), "--camera",
         k["camera"], "--res", "32x32", "--spp", "2", "--seed", str(k["seed"]),
         "--max-depth", str(k["max_depth"])], check=True, capture_output=True)
    cli = nimbus.read_exr(str(exr))
    for i, c in enumerate("RGB"):
        assert same_bits(combined[..., i], cli[c]), f"channel {c} differs from nimbus render's"
    assert np.all(combined[..., 3] == 1.0)
    assert cli["A"].min() < 0.5, "the volume should not cover the whole frame"


def test_passes_are_present_and_light_groups_sum_to_combined(addon, smoke_vdb, tmp_path):
    scene, smoke, lights = smoke_scene(smoke_vdb, res=32)
    vl = scene.view_layers[0]
    for name in ("key", "fill", "sky", "empty"):
        vl.lightgroups.add().name = name
    lights["sun"].lightgroup = "key"
    lights["spot"].lightgroup = "fill"
    lights["disk"].lightgroup = "fill"
    scene.world.lightgroup = "sky"
    for p in ("use_pass_lookups", "use_pass_collisions", "use_pass_max_throughput",
              "use_pass_variance", "use_pass_albedo"):
        setattr(vl.nimbus, p, True)
    scene.nimbus.samples = 4
    passes = render(scene, tmp_path / "passes.exr")
    assert set(passes) == {
        "Combined", "Combined_key", "Combined_fill", "Combined_sky", "Combined_empty",
        "Nimbus Lookups", "Nimbus Real Collisions", "Nimbus Null Collisions",
        "Nimbus Max Throughput", "Nimbus Variance", "Denoising Albedo"}
    c = passes["Combined"].astype(np.float64)
    parts = [passes[f"Combined_{g}"].astype(np.float64) for g in ("key", "fill", "sky", "empty")]
    assert all(p.max() > 0 for p in parts[:3]) and parts[3].max() == 0
    assert passes["Nimbus Lookups"].max() > 0 and passes["Denoising Albedo"].max() > 0
    # Each layer is an f64 mean rounded to f32 once (docs/aovs.md), and with the film
    # transparent the add-on subtracts the dome seen directly, W, from Combined and the
    # sky group in f32. The raw beauty is Combined + W and the raw sky layer sky + W,
    # with W at most the world's radiance: five roundings of at most 2^-24 of
    # |Combined| + sum |part| + 2 W each bound the error.
    world = np.array(WORLD_RADIANCE)
    total = sum(parts)
    bound = 5 * 2.0**-24 * (np.abs(c[..., :3]) + sum(np.abs(p) for p in parts) + 2 * world)
    err = np.abs(total - c[..., :3])
    worst = np.unravel_index(np.argmax(err - bound), err.shape)
    assert np.all(err <= bound), (
        f"light groups miss Combined by {err[worst]} at {worst} (bound {bound[worst]})")


def test_escape_stops_the_render_within_a_second(addon, smoke_vdb):
    scene, _, _ = smoke_scene(smoke_vdb, res=64)
    scene.nimbus.samples = 1_000_000
    pressed = {}

    def key():
        # Esc 0.3 s after the first call (the render is under way).
        now = time.monotonic()
        pressed.setdefault("first", now)
        if now - pressed["first"] >= 0.3:
            pressed.setdefault("at", now)
            return True
        return False

    addon.break_hook = key
    start = time.monotonic()
    bpy.ops.render.render()
    end = time.monotonic()
    assert "at" in pressed, "the render ended before Esc"
    assert end - pressed["at"] < 1.0, f"stopped {end - pressed['at']:.2f} s after Esc"
    assert end - start < 60


def test_a_missing_vdb_is_a_reported_error_naming_the_object(addon, smoke_vdb, tmp_path):
    scene, smoke, _ = smoke_scene(smoke_vdb, res=16)
    smoke.data.filepath = str(tmp_path / "gone" / "smoke.vdb")
    with pytest.raises(RuntimeError, match="volume 'smoke'.*gone/smoke.vdb"):
        bpy.ops.render.render()
    # Blender keeps running: the same scene renders once the file is back.
    smoke.data.filepath = str(smoke_vdb)
    scene.nimbus.samples = 1
    passes = render(scene, tmp_path / "after.exr")
    assert passes["Combined"][..., 3].max() > 0


def test_a_missing_grid_is_a_reported_error_naming_the_object(addon, smoke_vdb, tmp_path):
    """Density Attribute naming a grid the VDB lacks: Nimbus' error (naming the prim)
    is reported with the Blender object's name; Blender keeps running."""
    scene, smoke, _ = smoke_scene(smoke_vdb, res=16, lights=("sun",), world=False)
    pv = smoke.active_material.node_tree.nodes["Principled Volume"]
    pv.inputs["Density Attribute"].default_value = "nosuchgrid"
    with pytest.raises(RuntimeError, match="object 'smoke'.*nosuchgrid"):
        bpy.ops.render.render()
    pv.inputs["Density Attribute"].default_value = "density"
    scene.nimbus.samples = 1
    assert render(scene, tmp_path / "after.exr")["Combined"][..., 3].max() > 0


def test_border_renders_the_region_of_the_frame(addon, smoke_vdb, tmp_path):
    scene, _, _ = smoke_scene(smoke_vdb, res=40, world=False)
    scene.nimbus.samples = 2
    full = render(scene, tmp_path / "full.exr")["Combined"]
    r = scene.render
    r.use_border = True
    r.use_crop_to_border = True
    r.border_min_x, r.border_max_x, r.border_min_y, r.border_max_y = 0.25, 0.75, 0.5, 1.0
    part = render(scene, tmp_path / "part.exr")["Combined"]
    # Rows from the top: the upper half, columns 10..30.
    assert same_bits(part, full[0:20, 10:30])


def test_an_animation_renders_each_frame_of_a_vdb_sequence(addon, smoke_vdb, tmp_path):
    """smoke_000002.vdb, smoke_000003.vdb as a sequence on frames 1 and 2; Ctrl-F12
    (render.render(animation=True)) writes a frame each; frame 2 is, bit for bit, the
    render of a volume reading smoke_000003.vdb (the same seed: not animated)."""
    scene, smoke, _ = smoke_scene(smoke_vdb, res=24, lights=("sun",), world=False)
    scene.nimbus.samples = 2
    v = smoke.data
    v.is_sequence = True
    v.frame_start, v.frame_duration, v.frame_offset = 1, 2, 1
    scene.frame_start, scene.frame_end = 1, 2
    scene.render.filepath = str(tmp_path / "anim_####")
    bpy.ops.render.render(animation=True)
    frames = []
    for f in (1, 2):
        (path,) = tmp_path.glob(f"anim_{f:04d}*")
        ch = nimbus.read_exr(str(path))
        frames.append(np.stack([ch[k] for k in sorted(ch) if k.split(".")[-1] in "RGBA"
                                and "Combined." in k], -1))
    assert not same_bits(frames[0], frames[1]), "the two frames are the same image"
    v.is_sequence = False
    v.filepath = str(smoke_vdb.parent / "smoke_000003.vdb")
    scene.frame_set(2)
    static = render(scene, tmp_path / "static.exr")["Combined"]
    # sorted(ch) orders A, B, G, R: compare channel sets in that order.
    assert same_bits(frames[1], static[..., [3, 2, 1, 0]])


def test_an_unknown_volume_node_is_a_warning_naming_material_and_node(addon, smoke_vdb):
    scene, smoke, _ = smoke_scene(smoke_vdb, res=16, lights=("sun",), world=False)
    scene.nimbus.samples = 1
    tree = smoke.active_material.node_tree
    out = tree.nodes["Material Output"]
    other = tree.nodes.new("ShaderNodeBsdfDiffuse")
    other.name = "Odd Node"
    add = tree.nodes.new("ShaderNodeAddShader")
    tree.links.new(tree.nodes["Principled Volume"].outputs["Volume"], add.inputs[0])
    tree.links.new(other.outputs["BSDF"], add.inputs[1])
    tree.links.new(add.outputs["Shader"], out.inputs["Volume"])
    bpy.ops.render.render()
    warnings = addon.last_render["warnings"]
    assert any("'smoke_material'" in w and "'Odd Node'" in w for w in warnings), warnings


def test_resolution_percentage(addon, smoke_vdb, tmp_path):
    scene, _, _ = smoke_scene(smoke_vdb, res=40, world=False)
    scene.nimbus.samples = 1
    scene.render.resolution_percentage = 50
    assert render(scene, tmp_path / "half.exr")["Combined"].shape == (20, 20, 4)


# The comparison with Cycles: K seeds each, at 64 x 64.
SEEDS = [0, 1, 2, 3]
SPP = 64
MAX_DEPTH = 8
# Standard errors allowed: 4 values (mean alpha, R, G, B), false alarm ~1e-6 each for
# normal errors.
Z = 5.0
# Cycles' null-scattering volumes measured 0.2-0.5 % too bright against a
# deterministic reference (../shared/peers/README.md); tests/blender_export.rs allows
# the same.
BIAS = 0.005


def test_against_cycles_on_the_same_scene(addon, smoke_vdb, tmp_path):
    """Smoke with a chromatic Principled Volume (Color (0.9, 0.6, 0.3), Absorption
    Color (0.2, 0.4, 0.8), Anisotropy 0.4), a sun, a spot (blend 0), a disk light and a
    world colour (tests/fixtures/blender_export_scene.py's lights and world), film transparent, rendered by Nimbus through the add-on and by
    Cycles (the peer harness' settings: tests/fixtures/blender_export_scene.py
    set_cycles; maxDepth 8 = 7 volume bounces), 4 seeds x 64 spp each at 64 x 64.

    Estimator: over the pixels where either renderer's mean alpha exceeds 0.01 (the
    volume), the mean of alpha and of R, G, B per renderer; its standard error from
    the per-pixel sample variance over the seeds, se^2 = sum_p s_p^2 / (K n^2).
    Pass: |Nimbus - Cycles| <= Z sqrt(se_N^2 + se_C^2) + BIAS |Cycles|."""
    from blender_export_scene import set_cycles

    scene, _, _ = smoke_scene(smoke_vdb, res=64, max_depth=MAX_DEPTH)
    scene.nimbus.samples = SPP
    images = {"nimbus": [], "cycles": []}
    t0 = time.monotonic()
    for seed in SEEDS:
        scene.nimbus.seed = seed
        images["nimbus"].append(render(scene, tmp_path / f"n{seed}.exr")["Combined"])
    t1 = time.monotonic()
    scene.render.image_settings.media_type = "IMAGE"
    set_cycles((64, 64), MAX_DEPTH, True)
    scene.render.image_settings.media_type = "MULTI_LAYER_IMAGE"
    scene.render.image_settings.color_depth = "32"
    scene.cycles.samples = SPP
    for seed in SEEDS:
        scene.cycles.seed = seed
        images["cycles"].append(render(scene, tmp_path / f"c{seed}.exr")["Combined"])
    t2 = time.monotonic()
    stacks = {k: np.stack(v).astype(np.float64) for k, v in images.items()}
    mask = (stacks["nimbus"][..., 3].mean(0) > 0.01) | (stacks["cycles"][..., 3].mean(0) > 0.01)
    n = int(mask.sum())
    assert n > 200, f"the volume covers only {n} pixels"
    k = len(SEEDS)
    report = []
    ok = True
    for ci, name in enumerate("RGBA"):
        stat = {}
        for r, s in stacks.items():
            px = s[:, mask, ci]  # (K, n)
            mean = px.mean()
            se = np.sqrt(px.var(axis=0, ddof=1).sum() / (k * n * n))
            stat[r] = (mean, se)
        (mn, sn), (mc, sc) = stat["nimbus"], stat["cycles"]
        tol = Z * np.hypot(sn, sc) + BIAS * abs(mc)
        report.append(f"{name}: nimbus {mn:.5f} +- {sn:.5f}, cycles {mc:.5f} +- {sc:.5f}, "
                      f"ratio {mn / mc:.4f}, |diff| {abs(mn - mc):.5f} <= {tol:.5f}")
        ok &= abs(mn - mc) <= tol
    print(f"\nagainst Cycles ({n} pixels; Nimbus {t1 - t0:.1f} s, Cycles {t2 - t1:.1f} s):\n"
          + "\n".join(report))
    assert ok, "\n".join(report)


INSTALL_SCRIPT = """
import sys, bpy, addon_utils
bpy.ops.wm.read_factory_settings(use_empty=True)
r = bpy.ops.extensions.package_install_files(filepath=sys.argv[1], repo="user_default",
                                              enable_on_install=True)
assert r == {"FINISHED"}, r
addon_utils.enable("bl_ext.user_default.nimbus_blender", default_set=True)
sys.path.insert(0, sys.argv[2])
from conftest import smoke_scene, render
scene, _, _ = smoke_scene(sys.argv[3], res=16, lights=("sun",), world=False)
scene.nimbus.samples = 1
passes = render(scene, sys.argv[4])
assert passes["Combined"][..., 3].max() > 0, "nothing rendered"
import nimbus
print("nimbus from", nimbus.__file__)
"""


def test_the_zip_installs_as_an_extension_and_renders(smoke_vdb, tmp_path):
    """blender/build.py's zip, installed as Blender installs an extension from disk
    (its wheel pip-installed into the extensions' site-packages), in a Blender with
    its own HOME: the engine renders."""
    import os
    import sys
    from pathlib import Path

    repo = Path(__file__).resolve().parents[2]
    subprocess.run([sys.executable, str(repo / "blender" / "build.py"), "--out", str(tmp_path)],
                   check=True, capture_output=True)
    (zip_path,) = tmp_path.glob("nimbus_blender-*.zip")
    env = dict(os.environ, HOME=str(tmp_path / "home"))
    r = subprocess.run(
        [sys.executable, "-c", INSTALL_SCRIPT, str(zip_path), str(Path(__file__).parent),
         str(smoke_vdb), str(tmp_path / "installed.exr")],
        env=env, capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]
    site = tmp_path / "home" / ".config" / "blender" / "5.0" / "extensions" / ".local"
    assert list(site.rglob("nimbus/_nimbus*.so")), "the bundled wheel was not installed"


def test_scatter_plus_absorption_with_a_density_attribute_maps_as_cycles_means_it(addon,
                                                                                 smoke_vdb):
    """Volume Scatter (Color Cs, Density from Attribute 'density' times 4 by a Math
    node, Anisotropy 0.2) + Volume Absorption (Color Ca, same density): Cycles'
    closures give sigma_s = Cs 4 d(x), sigma_a = (1 - Ca) 4 d(x)."""
    from nimbus_blender import translate

    scene, smoke, _ = smoke_scene(smoke_vdb, res=16, lights=("sun",), world=False)
    tree = smoke.active_material.node_tree
    for n in list(tree.nodes):
        tree.nodes.remove(n)
    out = tree.nodes.new("ShaderNodeOutputMaterial")
    attr = tree.nodes.new("ShaderNodeAttribute")
    attr.attribute_name = "density"
    mul = tree.nodes.new("ShaderNodeMath")
    mul.operation = "MULTIPLY"
    mul.inputs[1].default_value = 4.0
    tree.links.new(attr.outputs["Fac"], mul.inputs[0])
    sc = tree.nodes.new("ShaderNodeVolumeScatter")
    sc.inputs["Color"].default_value = (0.9, 0.6, 0.3, 1)
    sc.inputs["Anisotropy"].default_value = 0.2
    ab = tree.nodes.new("ShaderNodeVolumeAbsorption")
    ab.inputs["Color"].default_value = (0.5, 0.75, 1.0, 1)
    tree.links.new(mul.outputs["Value"], sc.inputs["Density"])
    tree.links.new(mul.outputs["Value"], ab.inputs["Density"])
    add = tree.nodes.new("ShaderNodeAddShader")
    tree.links.new(sc.outputs["Volume"], add.inputs[0])
    tree.links.new(ab.outputs["Volume"], add.inputs[1])
    tree.links.new(add.outputs["Shader"], out.inputs["Volume"])
    warnings = []
    attrs, albedo = translate.volume_medium(smoke, warnings)
    assert warnings == []
    f = attrs
    scale = float(f["float nimbus:densityScale"])
    assert f["token nimbus:densityField"] == '"density"'
    assert scale == pytest.approx(3.6, rel=1e-6)  # the largest coefficient, 0.9 x 4
    sig_s = np.array(eval(f["color3f nimbus:scattering"])) * scale
    sig_a = np.array(eval(f["color3f nimbus:absorption"])) * scale
    np.testing.assert_allclose(sig_s, [3.6, 2.4, 1.2], rtol=1e-6)
    np.testing.assert_allclose(sig_a, [2.0, 1.0, 0.0], rtol=1e-6, atol=1e-7)
    assert float(f["float nimbus:anisotropy"]) == pytest.approx(0.2, rel=1e-6)
    np.testing.assert_allclose(albedo, sig_s / (sig_s + sig_a), rtol=1e-6)


def test_a_cycles_denoise_graph_runs_on_the_passes(addon, smoke_vdb, tmp_path):
    """A compositor graph as made for Cycles — Render Layers' Image and Denoising
    Albedo into a Denoise node, to the output — finds its sockets on Nimbus' passes
    and denoises: at 2 spp the denoised image is closer to a 64-spp render (mean
    squared error over R, G, B) than the raw 2-spp image is."""
    scene, _, lights = smoke_scene(smoke_vdb, res=48)
    vl = scene.view_layers[0]
    vl.lightgroups.add().name = "key"
    lights["sun"].lightgroup = "key"
    vl.nimbus.use_pass_albedo = True
    tree = bpy.data.node_groups.new("compositing", "CompositorNodeTree")
    scene.compositing_node_group = tree
    rl = tree.nodes.new("CompositorNodeRLayers")
    rl.scene = scene
    outputs = {o.name for o in rl.outputs if o.enabled}
    assert {"Image", "Alpha", "Denoising Albedo", "Combined_key"} <= outputs, outputs
    dn = tree.nodes.new("CompositorNodeDenoise")
    tree.interface.new_socket("Image", in_out="OUTPUT", socket_type="NodeSocketColor")
    out = tree.nodes.new("NodeGroupOutput")
    tree.links.new(rl.outputs["Image"], dn.inputs["Image"])
    tree.links.new(rl.outputs["Denoising Albedo"], dn.inputs["Albedo"])
    tree.links.new(dn.outputs["Image"], out.inputs[0])
    s = scene.render.image_settings
    s.media_type = "IMAGE"
    s.file_format = "OPEN_EXR"
    s.color_depth = "32"

    def rgb(path, spp, compositing):
        scene.nimbus.samples = spp
        scene.render.use_compositing = compositing
        scene.render.filepath = str(path)
        bpy.ops.render.render(write_still=True)
        ch = nimbus.read_exr(str(path))
        return np.stack([ch[f".{c}"] for c in "RGB"], -1).astype(np.float64)

    reference = rgb(tmp_path / "ref.exr", 64, False)
    raw = rgb(tmp_path / "raw.exr", 2, False)
    denoised = rgb(tmp_path / "den.exr", 2, True)
    assert np.all(np.isfinite(denoised))
    mse_raw = np.mean((raw - reference) ** 2)
    mse_den = np.mean((denoised - reference) ** 2)
    print(f"\nDenoise: MSE against 64 spp, raw 2 spp {mse_raw:.4g}, denoised {mse_den:.4g}")
    assert mse_den < mse_raw, f"denoised MSE {mse_den:.4g} not below raw {mse_raw:.4g}"
