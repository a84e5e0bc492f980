"""nimbus.render against the CLI, progress, Ctrl-C, threads, stage text, write."""

import os
import signal
import threading
import time

import numpy as np
import OpenEXR
import pytest

import nimbus
from conftest import RES, SPP, run_cli


def exr_channels(path):
    """Every channel of an EXR read with OpenEXR's own bindings (not Nimbus')."""
    with OpenEXR.File(str(path), separate_channels=True) as f:
        return {name: np.asarray(c.pixels, dtype=np.float32) for name, c in f.channels().items()}


def same_bits(a, b):
    a, b = np.ascontiguousarray(a, np.float32), np.ascontiguousarray(b, np.float32)
    return a.shape == b.shape and np.array_equal(a.view(np.uint32), b.view(np.uint32))


def test_render_equals_the_cli_bit_for_bit(stage, nimbus_bin, tmp_path):
    cli_exr = tmp_path / "cli.exr"
    run_cli(nimbus_bin, "render", stage, "-o", cli_exr, "--seed", 3, "--spp", 3)
    r = nimbus.render(stage, seed=3, spp=3, aovs=["lookups"])
    assert r.rgba.dtype == np.float32 and r.rgba.shape == (RES[1], RES[0], 4)
    assert r.rgba[..., :3].max() > 0, "the cloud renders black"
    cli = exr_channels(cli_exr)
    for k, name in enumerate("RGBA"):
        assert same_bits(r.rgba[..., k], cli[name]), f"channel {name} differs from the CLI's"
    assert same_bits(r.aovs["lookups"], cli["lookups"])
    # r.write writes the CLI's file: the same channels, the same values.
    py_exr = tmp_path / "py.exr"
    r.write(py_exr)
    mine = exr_channels(py_exr)
    assert sorted(mine) == sorted(cli)
    for name in cli:
        assert same_bits(mine[name], cli[name]), name
    assert r.stats["samples_per_pixel"] == 3 and r.stats["seed"] == 3
    assert r.stats["density_lookups"] > 0
    assert r.spp == 3 and r.width == RES[0] and r.height == RES[1]


def test_the_stage_decides_what_no_keyword_overrides(stage):
    r = nimbus.render(stage)
    assert r.spp == SPP and r.seed == 1 and r.rgba.shape == (RES[1], RES[0], 4)


def test_arrays_are_not_copies_of_copies(stage):
    r = nimbus.render(stage, spp=1, aovs=["lookups"])
    # numpy views the buffer the module handed over: the array owns no other copy.
    assert r.rgba.base is not None and r.rgba.flags["C_CONTIGUOUS"]
    assert r.rgba is r.rgba  # the same object on every access, not rebuilt


def test_progress_is_reported_on_the_calling_thread(stage):
    calls = []
    caller = threading.get_ident()

    def progress(done, total):
        calls.append((done, total, threading.get_ident()))

    nimbus.render(stage, spp=4, progress=progress)
    assert calls, "progress was never called"
    total = 4 * RES[1]
    assert all(t == total for _, t, _ in calls)
    assert all(tid == caller for _, _, tid in calls)
    dones = [d for d, _, _ in calls]
    assert dones == sorted(dones) and dones[-1] == total


def test_a_progress_callback_that_raises_stops_the_render(stage):
    def progress(done, total):
        raise RuntimeError("enough")

    with pytest.raises(RuntimeError, match="enough"):
        nimbus.render(stage, spp=100000, progress=progress)


def test_keyboard_interrupt_stops_a_long_render_within_a_second(stage):
    # Python raises KeyboardInterrupt on SIGINT only if SIGINT was not ignored when it
    # started; a test runner launched as a shell's background job inherits it ignored
    # (and this render would then never stop): install Python's handler for the test.
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        _interrupt_a_long_render(stage)
    finally:
        signal.signal(signal.SIGINT, previous)


def _interrupt_a_long_render(stage):
    sent = []
    timers = []

    def interrupt():
        sent.append(time.monotonic())
        os.kill(os.getpid(), signal.SIGINT)

    def progress(done, total):
        # Rows are finishing: the render is under way (the stage has loaded), so the
        # signal lands in the middle of rendering.
        if not timers:
            timers.append(threading.Timer(0.3, interrupt))
            timers[0].start()

    start = time.monotonic()
    with pytest.raises(KeyboardInterrupt):
        nimbus.render(stage, spp=10_000_000, res=(96, 72), progress=progress)
    end = time.monotonic()
    assert timers, "progress never came"
    timers[0].join()
    assert sent, "the signal was never sent (the render ended first?)"
    assert end - sent[0] < 1.0, f"stopped {end - sent[0]:.2f} s after SIGINT"
    assert end - start < 30.0
    # The next render is not affected by the stopped one.
    r = nimbus.render(stage, spp=1)
    assert r.spp == 1


def test_two_threads_render_what_sequential_renders_give(stage):
    seeds = [11, 12]
    sequential = [nimbus.render(stage, seed=s, spp=2).rgba for s in seeds]
    results = {}
    errors = []

    def work(s):
        try:
            results[s] = nimbus.render(stage, seed=s, spp=2).rgba
        except BaseException as e:  # noqa: BLE001 - reported below
            errors.append(e)

    threads = [threading.Thread(target=work, args=(s,)) for s in seeds]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert not errors, errors
    for s, seq in zip(seeds, sequential):
        assert same_bits(results[s], seq), f"seed {s}: threaded render differs"
    assert not same_bits(sequential[0], sequential[1]), "seeds should change the image"


def test_stage_text_renders_like_the_file(stage, stage_dir):
    text = stage.read_text()
    before = set(os.listdir(stage_dir))
    r_text = nimbus.render(stage_text=text, base_dir=stage_dir, spp=2)
    r_file = nimbus.render(stage, spp=2)
    assert same_bits(r_text.rgba, r_file.rgba)
    assert set(os.listdir(stage_dir)) == before, "the temporary stage was left behind"


def test_output_keywords_write_like_the_cli(stage, nimbus_bin, tmp_path):
    cli_exr, cli_stats = tmp_path / "cli.exr", tmp_path / "cli.json"
    run_cli(nimbus_bin, "render", stage, "-o", cli_exr, "--spp", 2, "--stats", cli_stats,
            "--aovs", "variance")
    py_exr, py_stats = tmp_path / "py.exr", tmp_path / "py.json"
    r = nimbus.render(stage, spp=2, output=py_exr, stats=py_stats, aovs=["variance"])
    cli, mine = exr_channels(cli_exr), exr_channels(py_exr)
    assert sorted(mine) == sorted(cli)
    for name in cli:
        assert same_bits(mine[name], cli[name]), name
    import json
    a, b = json.loads(py_stats.read_text()), json.loads(cli_stats.read_text())
    for key in ["samples_per_pixel", "density_lookups", "real_collisions", "tracker", "analysis"]:
        assert a[key] == b[key], key
    assert r.stats["density_lookups"] == b["density_lookups"]


def test_sampler_keyword_renders_like_the_cli(stage, nimbus_bin, tmp_path):
    cli_exr = tmp_path / "cli.exr"
    run_cli(nimbus_bin, "render", stage, "-o", cli_exr, "--seed", 3, "--spp", 2,
            "--sampler", "independent")
    r = nimbus.render(stage, seed=3, spp=2, sampler="independent")
    cli = exr_channels(cli_exr)
    for k, name in enumerate("RGBA"):
        assert same_bits(r.rgba[..., k], cli[name]), f"channel {name} differs from the CLI's"
    assert r.stats["sampler"] == "independent"
    sobol = nimbus.render(stage, seed=3, spp=2)
    assert sobol.stats["sampler"] == "sobol"
    assert not same_bits(sobol.rgba[..., 0], r.rgba[..., 0]), "the sampler changed nothing"


def test_adaptive_sampling_keywords_render_like_the_cli(stage, nimbus_bin, tmp_path):
    cli_exr = tmp_path / "cli.exr"
    run_cli(nimbus_bin, "render", stage, "-o", cli_exr, "--seed", 3, "--spp", 32,
            "--noise-threshold", 0.05, "--min-spp", 8, "--aovs", "samples")
    r = nimbus.render(stage, seed=3, spp=32, noise_threshold=0.05, min_spp=8, aovs=["samples"])
    cli = exr_channels(cli_exr)
    for k, name in enumerate("RGBA"):
        assert same_bits(r.rgba[..., k], cli[name]), f"channel {name} differs from the CLI's"
    assert same_bits(r.aovs["samples"], cli["samples"])
    assert r.stats["noise_threshold"] == 0.05 and r.stats["min_samples"] == 8
    assert 8 <= r.aovs["samples"].min() < 32
    assert r.stats["samples_taken"] == int(r.aovs["samples"].sum())


def test_denoise_keyword_renders_like_the_cli(stage, nimbus_bin, tmp_path):
    """render(denoise=True) is `nimbus render --denoise` bit for bit: the denoised beauty
    in rgba, the noisy one and the albedo in aovs, each split layer denoised; written,
    the EXR is the CLI's."""
    cli_exr = tmp_path / "cli.exr"
    run_cli(nimbus_bin, "render", stage, "-o", cli_exr, "--seed", 3, "--spp", 4,
            "--aovs", "direct,indirect", "--denoise")
    r = nimbus.render(stage, seed=3, spp=4, aovs=["direct", "indirect"], denoise=True)
    cli = exr_channels(cli_exr)
    for k, name in enumerate("RGBA"):
        assert same_bits(r.rgba[..., k], cli[name]), f"channel {name} differs from the CLI's"
    for k, name in enumerate("RGB"):
        assert same_bits(r.aovs["noisy"][..., k], cli[f"noisy.{name}"])
        assert same_bits(r.aovs["albedo"][..., k], cli[f"albedo.{name}"])
        assert same_bits(r.aovs["direct"][..., k], cli[f"direct.{name}"])
        assert not same_bits(r.rgba[..., k], r.aovs["noisy"][..., k]), "not denoised"
    assert r.stats["denoise"] == "denoised" and r.stats["denoise_seconds"] > 0
    noisy = nimbus.render(stage, seed=3, spp=4)
    assert same_bits(noisy.rgba[..., :3], r.aovs["noisy"])
    assert noisy.stats["denoise"] is None
    written = tmp_path / "py.exr"
    r.write(str(written))
    again = exr_channels(written)
    for name in ("R", "G", "B", "noisy.R", "albedo.G"):
        assert same_bits(again[name], cli[name]), name


def test_tracker_keywords(stage):
    names = nimbus.tracker_names()
    assert "spectral" in names or len(names) > 3
    r = nimbus.render(stage, spp=1, tracker=names[0])
    assert r.tracker == names[0] and r.auto_summary is None
    r = nimbus.render(stage, spp=1, tracker="auto")
    assert r.auto_summary and r.auto_summary.startswith("tracker auto:")


def test_a_product_with_light_group_vars_writes_them_like_the_cli(stage_dir, nimbus_bin, tmp_path):
    """A RenderProduct whose RenderVars are light path expressions: nimbus.render with
    output= writes the same split layers as the CLI, bit for bit, and they sum to the
    beauty within the f32 rounding of each stored mean (2^-24 relative)."""
    from pxr import Usd, UsdRender

    path = stage_dir / "groups.usda"
    stage = Usd.Stage.Open(str(stage_dir / "cloud.usda"))
    stage.GetRootLayer().Export(str(path))
    stage = Usd.Stage.Open(str(path))
    product = UsdRender.Product.Define(stage, "/Render/Product")
    names = {"emission": "C[LO]", "direct": "CV[LO]", "indirect": "CV.+[LO]"}
    targets = []
    for name, lpe in names.items():
        var = UsdRender.Var.Define(stage, f"/Render/Vars/{name}")
        var.CreateSourceTypeAttr("lpe")
        var.CreateSourceNameAttr(lpe)
        targets.append(var.GetPath())
    product.CreateOrderedVarsRel().SetTargets(targets)
    UsdRender.Settings(stage.GetPrimAtPath("/Render/Settings")).CreateProductsRel().SetTargets(
        [product.GetPath()])
    stage.GetRootLayer().Save()

    cli_exr, py_exr = tmp_path / "cli.exr", tmp_path / "py.exr"
    run_cli(nimbus_bin, "render", path, "-o", cli_exr, "--spp", 2)
    nimbus.render(path, spp=2, output=py_exr)
    cli, mine = exr_channels(cli_exr), exr_channels(py_exr)
    assert sorted(mine) == sorted(cli)
    assert "direct.R" in mine
    for name in cli:
        assert same_bits(mine[name], cli[name]), name
    for c in "RGB":
        parts = [mine[f"{n}.{c}"].astype(np.float64) for n in names]
        beauty = mine[c].astype(np.float64)
        bound = 2.0 ** -24 * (np.abs(beauty) + sum(np.abs(p) for p in parts)) + 1e-30
        assert np.all(np.abs(sum(parts) - beauty) <= bound), c
