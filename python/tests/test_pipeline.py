"""What pipelines and a render engine need of nimbus.render: exceptions that cross
process boundaries (pickle), the image after each pass (on_pass), cancellation from
the caller (cancel, on_pass returning False), a pixel region, split layers."""

import multiprocessing
import pickle
import time
from concurrent.futures import ProcessPoolExecutor

import numpy as np
import pytest

import nimbus
from conftest import RES, SPP, run_cli
from test_render import exr_channels, same_bits

EXCEPTIONS = [
    nimbus.Error,
    nimbus.StageError,
    nimbus.VdbError,
    nimbus.SettingsError,
    nimbus.OutputError,
    nimbus.Cancelled,
]


@pytest.mark.parametrize("kind", EXCEPTIONS, ids=lambda k: k.__name__)
def test_exceptions_pickle_as_themselves(kind):
    assert kind.__module__ == "nimbus", kind.__module__
    e = kind("stage.usda: no prim /World")
    back = pickle.loads(pickle.dumps(e))
    assert type(back) is kind and back.args == e.args and str(back) == str(e)


def test_a_raised_error_pickles_with_its_message(tmp_path):
    bad = tmp_path / "bad.usda"
    bad.write_text("#usda 1.0\ndef Volume \"v\" {\n")  # unterminated
    with pytest.raises(nimbus.StageError) as info:
        nimbus.render(bad)
    back = pickle.loads(pickle.dumps(info.value))
    assert type(back) is nimbus.StageError and str(back) == str(info.value)
    assert "bad.usda" in str(back)


def test_a_failing_render_in_a_process_pool_raises_stage_error_in_the_parent(tmp_path):
    """The worker's exception travels back pickled; with the module `_nimbus` it could
    not be unpickled and the pool broke (BrokenProcessPool) instead. A fresh process
    (spawn) so no thread of this one is forked."""
    bad = tmp_path / "bad.usda"
    bad.write_text("#usda 1.0\ndef Volume \"v\" {\n")
    ctx = multiprocessing.get_context("spawn")
    with ProcessPoolExecutor(max_workers=1, mp_context=ctx) as pool:
        future = pool.submit(nimbus.render, str(bad), spp=1)
        with pytest.raises(nimbus.StageError, match="bad.usda"):
            future.result(timeout=120)
        # The pool survives the error: the next task runs.
        assert pool.submit(nimbus.tracker_names).result(timeout=60) == nimbus.tracker_names()


def test_on_pass_sees_each_pass_and_the_last_is_the_result(stage):
    seen = []

    def on_pass(spp, total, rgba):
        assert rgba.dtype == np.float32 and rgba.shape == (RES[1], RES[0], 4)
        seen.append((spp, total, rgba.copy()))

    r = nimbus.render(stage, spp=7, seed=5, on_pass=on_pass)
    # The CLI's passes: 1 sample, then at most doubling, up to the cap.
    spps = [s for s, _, _ in seen]
    assert spps[0] == 1 and spps[-1] == 7 and spps == sorted(set(spps))
    assert all(b - a <= 2 * (a - p) for p, a, b in zip([0] + spps, spps, spps[1:]))
    assert all(t == 7 for _, t, _ in seen)
    assert same_bits(seen[-1][2], r.rgba), "the last pass's image is not the result"
    assert r.stats["passes"] == len(seen)
    # Earlier passes are the image of fewer samples: not the final one.
    assert not same_bits(seen[0][2], r.rgba)


def test_on_noise_gives_each_pass_noise_estimate_before_its_image(stage):
    """on_noise(spp, noise, converged) after each pass, before on_pass: the last is the
    stats' estimated_noise and converged_pixels; converged is None without adaptive
    sampling."""
    calls = []
    on_noise = lambda spp, noise, converged: calls.append(("noise", spp, noise, converged))
    on_pass = lambda spp, total, rgba: calls.append(("pass", spp))
    r = nimbus.render(stage, spp=40, seed=5, noise_threshold=0.05, min_spp=8,
                      on_noise=on_noise, on_pass=on_pass)
    assert [c[0] for c in calls] == ["noise", "pass"] * r.stats["passes"]
    assert all(n[1] == p[1] for n, p in zip(calls[::2], calls[1::2]))
    last = calls[-2]
    assert last[2] == r.stats["estimated_noise"] and last[3] == r.stats["converged_pixels"]
    assert len({c[2] for c in calls[::2]}) > 1 and all(0 <= c[3] <= 1 for c in calls[::2])
    plain = []
    nimbus.render(stage, spp=3, on_noise=lambda *a: plain.append(a))
    assert plain and all(a[2] is None and a[1] > 0 for a in plain)


def test_on_pass_returning_false_cancels(stage):
    calls = []

    def on_pass(spp, total, rgba):
        calls.append(spp)
        return False

    start = time.monotonic()
    with pytest.raises(nimbus.Cancelled):
        nimbus.render(stage, spp=1_000_000, on_pass=on_pass)
    assert calls == [1]
    assert time.monotonic() - start < 30
    # None (a callback without a return) does not cancel.
    r = nimbus.render(stage, spp=2, on_pass=lambda *a: None)
    assert r.spp == 2


def test_cancel_stops_a_long_render_within_a_second(stage):
    state = {"rows": 0, "asked": None}

    def progress(done, total):
        state["rows"] = done

    def cancel():
        # Once rows are finishing (the render is under way) and 0.3 s later, stop.
        if state["rows"] and state["asked"] is None:
            state["asked"] = time.monotonic() + 0.3
        return state["asked"] is not None and time.monotonic() >= state["asked"]

    with pytest.raises(nimbus.Cancelled):
        nimbus.render(stage, spp=10_000_000, res=(96, 72), progress=progress, cancel=cancel)
    late = time.monotonic() - state["asked"]
    assert late < 1.0, f"returned {late:.2f} s after cancel() said True"
    r = nimbus.render(stage, spp=1)
    assert r.spp == 1


def test_region_renders_the_pixels_of_the_whole_frame(stage, nimbus_bin, tmp_path):
    full = nimbus.render(stage, spp=2, seed=4)
    x0, y0, x1, y1 = 5, 7, 30, 20
    part = nimbus.render(stage, spp=2, seed=4, region=(x0, y0, x1, y1))
    assert part.rgba.shape == (y1 - y0, x1 - x0, 4)
    assert same_bits(part.rgba, full.rgba[y0:y1, x0:x1])
    # As the CLI's --region writes it.
    exr = tmp_path / "region.exr"
    run_cli(nimbus_bin, "render", stage, "-o", exr, "--spp", 2, "--seed", 4,
            "--region", f"{x0},{y0},{x1},{y1}")
    cli = exr_channels(exr)
    assert cli["R"].size == part.rgba[..., 0].size
    assert same_bits(part.rgba[..., 0].ravel(), cli["R"].ravel())
    with pytest.raises(nimbus.SettingsError, match="region"):
        nimbus.render(stage, spp=1, region=(0, 0, RES[0] + 1, 4))
    with pytest.raises(nimbus.SettingsError, match="region"):
        nimbus.render(stage, spp=1, region=(4, 0, 4, 4))


def test_light_group_layers_come_back_and_sum_to_the_beauty(stage):
    r = nimbus.render(stage, spp=SPP, aovs=["lightgroup:/World/Sun", "lightgroup:/World/Sky",
                                           "lookups"])
    sun, sky = r.aovs["lightgroup__World_Sun"], r.aovs["lightgroup__World_Sky"]
    assert sun.shape == (RES[1], RES[0], 3) and sun.dtype == np.float32
    assert sun.max() > 0 and sky.max() > 0
    beauty = r.rgba[..., :3].astype(np.float64)
    parts = sun.astype(np.float64) + sky.astype(np.float64)
    # Each channel an f64 mean rounded to f32 once (docs/aovs.md).
    bound = 2.0**-24 * (np.abs(beauty) + np.abs(sun) + np.abs(sky)) + 1e-30
    assert np.all(np.abs(parts - beauty) <= bound)
    # The beauty is the render without layers, bit for bit.
    plain = nimbus.render(stage, spp=SPP)
    assert same_bits(plain.rgba, r.rgba)
    assert r.aovs["lookups"].shape == (RES[1], RES[0])


def test_a_light_path_expression_layer(stage):
    """`NAME=EXPR` in aovs: a layer of a RenderVar's lpe sourceName. Light reaching the
    camera unscattered from the sky is all of the `emission` split here (the sun is a
    distant light, never hit, and nothing else emits): the same sums, the same bits."""
    r = nimbus.render(stage, spp=2, aovs=["emission", "seen=C<L.'/World/Sky'>"])
    assert r.aovs["seen"].shape == (RES[1], RES[0], 3) and r.aovs["seen"].max() > 0
    assert same_bits(r.aovs["seen"], r.aovs["emission"])
    with pytest.raises(nimbus.SettingsError, match="light path expression"):
        nimbus.render(stage, spp=1, aovs=["bad=C<RD>L"])
    with pytest.raises(nimbus.SettingsError, match="no layer name"):
        nimbus.render(stage, spp=1, aovs=["=C.*"])
