"""info, compare, schema constants and the exceptions bad input raises."""

import json

import numpy as np
import pytest

import nimbus
from conftest import CLOUD_VDB, RES, run_cli


def test_schema_constants():
    assert nimbus.schema.DENSITY_SCALE == "nimbus:densityScale"
    assert nimbus.schema.TRACKER == "nimbus:tracker"
    assert nimbus.schema.VOLUME_API == "NimbusVolumeAPI"


def test_vdb_reader_is_openvdb_when_required():
    import os
    if os.environ.get("NIMBUS_OPENVDB", "").lower() == "require":
        assert nimbus.vdb_reader() == "openvdb"
    else:
        assert nimbus.vdb_reader() in ("openvdb", "rust")


def test_info(stage):
    i = nimbus.info(stage)
    (v,) = i["volumes"]
    assert v["prim_path"] == "/World/Cloud" and v["density_scale"] == pytest.approx(12.0)
    assert "density" in v["fields"]
    grids = v["fields"]["density"]["grids"]
    assert any(g["name"] == "density" for g in grids)
    assert {l["type"] for l in i["lights"]} == {"distant", "dome"}
    assert i["render_settings"]["resolution"] == list(RES)
    assert i["analysis"]["volumes"] == 1
    assert i["auto"]["tracker"] in nimbus.tracker_names() and i["auto"]["reason"]


def without_timings(v):
    """`v` without its wall-time keys (`*_seconds`: octree and BVH build times), the
    only values two descriptions of the same stage may differ in."""
    if isinstance(v, dict):
        return {k: without_timings(x) for k, x in v.items() if not k.endswith("_seconds")}
    if isinstance(v, list):
        return [without_timings(x) for x in v]
    return v


def test_info_is_what_the_cli_prints_as_json(stage, nimbus_bin):
    # One description in the library: `nimbus info --json` prints it, nimbus.info
    # converts the same JSON, so the two are equal value for value.
    for args, kwargs in [((), {}), (("--octree-depth", "3"), {"octree_depth": 3})]:
        cli = json.loads(run_cli(nimbus_bin, "info", "--json", stage, *args).stdout)
        mine = nimbus.info(stage, **kwargs)
        assert cli["kind"] == "stage" and cli["volumes"][0]["fields"]["density"]["loaded"]
        assert without_timings(mine) == without_timings(cli)
    vdb = json.loads(run_cli(nimbus_bin, "info", "--json", CLOUD_VDB).stdout)
    assert vdb["kind"] == "vdb" and vdb["grids"][0]["channels"]
    assert nimbus.info(CLOUD_VDB) == vdb


def test_compare_is_what_the_cli_prints_as_json(stage, nimbus_bin, tmp_path):
    a, b = tmp_path / "a.exr", tmp_path / "b.exr"
    nimbus.render(stage, spp=1, seed=1).write(a)
    rb = nimbus.render(stage, spp=2, seed=2)
    rb.write(b)
    # One function in the library computes both: equal to the last bit of every float.
    cli = json.loads(run_cli(nimbus_bin, "compare", a, b, "--json").stdout)
    mine = nimbus.compare(a, b)
    assert [c["channel"] for c in mine["channels"]] == ["R", "G", "B", "A"]
    assert mine["rgb"]["mse"] > 0
    assert mine == cli
    # Arrays go through the same function: the R channel of a as a grey image against
    # b's RGB gives the files' R error in R.
    arrays = nimbus.compare(nimbus.read_exr(a)["R"][..., None].repeat(3, -1), rb.rgba[..., :3])
    assert arrays["a"] == "<array>" and arrays["channels"][0]["channel"] == "R"
    for k in ["mse", "relmse", "mean_a", "mean_b"]:
        assert arrays["channels"][0][k] == pytest.approx(mine["channels"][0][k], rel=1e-12), k
    x = np.full((4, 4, 4), 2.0, np.float32)
    y = np.ones((4, 4, 4), np.float32)
    e = nimbus.compare(x, y)["channels"][0]
    assert e["mse"] == 1.0 and e["relmse"] == pytest.approx(1 / 1.01)
    with pytest.raises(nimbus.SettingsError, match="differ in size"):
        nimbus.compare(x, np.ones((4, 5, 3), np.float32))


def test_exceptions(stage, tmp_path):
    assert issubclass(nimbus.StageError, nimbus.Error)
    with pytest.raises(nimbus.StageError, match="nope.usda"):
        nimbus.render(tmp_path / "nope.usda")
    with pytest.raises(nimbus.SettingsError, match="tracker"):
        nimbus.render(stage, tracker="no-such-tracker")
    with pytest.raises(nimbus.SettingsError, match="scheme"):
        nimbus.render(stage, scheme="no-such-scheme")
    with pytest.raises(nimbus.SettingsError, match="sampler"):
        nimbus.render(stage, sampler="no-such-sampler")
    with pytest.raises(nimbus.SettingsError, match="unknown AOV"):
        nimbus.render(stage, aovs=["nope"])
    with pytest.raises(nimbus.SettingsError, match="zero side"):
        nimbus.render(stage, res=(0, 10))
    with pytest.raises(nimbus.SettingsError, match="control"):
        nimbus.render(stage, control=2.0)
    with pytest.raises(nimbus.SettingsError):
        nimbus.render()
    r = nimbus.render(stage, spp=1)
    with pytest.raises(nimbus.OutputError):
        r.write(tmp_path / "no" / "such" / "dir" / "x.exr")


def test_a_broken_vdb_raises_vdb_error(tmp_path):
    from conftest import author_cloud
    (tmp_path / "cloud.vdb").write_bytes(b"not a vdb file at all\n" * 10)
    author_cloud(tmp_path / "broken.usda")
    with pytest.raises(nimbus.VdbError):
        nimbus.render(tmp_path / "broken.usda", spp=1)


def test_a_malformed_stage_raises_stage_error(tmp_path):
    bad = tmp_path / "bad.usda"
    bad.write_text("#usda 1.0\ndef Volume \"V\" {\n")
    with pytest.raises(nimbus.StageError):
        nimbus.info(bad)


def test_session_warnings_become_python_warnings(stage_dir):
    # A volume alone: the session frames it with a default camera and lights it with a
    # default sun and sky, and says so.
    text = """#usda 1.0
def Volume "Cloud" (prepend apiSchemas = ["NimbusVolumeAPI"])
{
    rel field:density = </Cloud/density>
    def OpenVDBAsset "density"
    {
        asset filePath = @./cloud.vdb@
        token fieldName = "density"
    }
}
"""
    import warnings
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        r = nimbus.render(stage_text=text, base_dir=stage_dir, spp=1, res=(16, 12))
    messages = [str(w.message) for w in caught if issubclass(w.category, UserWarning)]
    assert any("no lights" in m for m in messages), messages
    assert any("default camera" in m for m in messages), messages
    assert any("default camera" in w for w in r.warnings)
    assert r.rgba.shape == (12, 16, 4)


def test_strict_and_no_default_lights(stage_dir):
    # `render --strict` and `--no-default-lights` as keywords, on a stage without
    # lights or camera: strict refuses the default sun and sky, no_default_lights
    # renders the non-emissive cloud unlit (black, its alpha still there).
    text = """#usda 1.0
def Volume "Cloud"
{
    rel field:density = </Cloud/density>
    def OpenVDBAsset "density"
    {
        asset filePath = @./cloud.vdb@
        token fieldName = "density"
    }
}
"""
    kw = dict(stage_text=text, base_dir=stage_dir, spp=1, res=(16, 12))
    with pytest.raises(nimbus.SettingsError, match="--strict refuses to add the default sun"):
        nimbus.render(strict=True, **kw)
    with pytest.warns(UserWarning, match="default camera"):
        r = nimbus.render(no_default_lights=True, **kw)
    assert not any("no lights" in w for w in r.warnings), r.warnings
    assert r.rgba[..., :3].max() == 0 and r.rgba[..., 3].max() > 0
