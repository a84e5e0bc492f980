"""Fixtures of the Python module's tests: a stage authored with Pixar's USD (pxr, from
the usd-core wheel; its absence is an error, not a skip) and the `nimbus` binary the
module's renders are checked against."""

import os
import shutil
import subprocess
from pathlib import Path

import pytest
from pxr import Gf, Sdf, Usd, UsdGeom, UsdLux, UsdRender, UsdVol  # noqa: F401  (required)

import nimbus

REPO = Path(__file__).resolve().parents[2]
CLOUD_VDB = REPO / "scenes" / "cloud" / "cloud.vdb"

# Small enough to render in well under a second on a loaded 2-core machine.
RES = (48, 36)
SPP = 4


@pytest.fixture(scope="session")
def nimbus_bin():
    """The CLI of the same checkout: $NIMBUS_BIN, else target/release/nimbus."""
    path = Path(os.environ.get("NIMBUS_BIN", REPO / "target" / "release" / "nimbus"))
    assert path.is_file(), f"no nimbus binary at {path}: build it (cargo b) or set NIMBUS_BIN"
    return path


def run_cli(nimbus_bin, *args):
    r = subprocess.run([str(nimbus_bin), *map(str, args)], capture_output=True, text=True)
    assert r.returncode == 0, f"nimbus {' '.join(map(str, args))} failed:\n{r.stderr}"
    return r


def author_cloud(path: Path, vdb_rel: str = "./cloud.vdb"):
    """The cloud of scenes/cloud authored with pxr: a Volume with NimbusVolumeAPI, its
    OpenVDBAsset (a relative filePath), a camera, a sun, a sky and render settings."""
    stage = Usd.Stage.CreateNew(str(path))
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
    world = UsdGeom.Xform.Define(stage, "/World")
    stage.SetDefaultPrim(world.GetPrim())
    vol = UsdVol.Volume.Define(stage, "/World/Cloud")
    prim = vol.GetPrim()
    prim.AddAppliedSchema(nimbus.schema.VOLUME_API)
    f = Sdf.ValueTypeNames
    prim.CreateAttribute(nimbus.schema.DENSITY_FIELD, f.Token).Set("density")
    prim.CreateAttribute(nimbus.schema.DENSITY_SCALE, f.Float).Set(12.0)
    prim.CreateAttribute(nimbus.schema.ABSORPTION, f.Color3f).Set(Gf.Vec3f(0.02, 0.03, 0.02))
    prim.CreateAttribute(nimbus.schema.SCATTERING, f.Color3f).Set(Gf.Vec3f(0.98, 0.9, 0.8))
    prim.CreateAttribute(nimbus.schema.ANISOTROPY, f.Float).Set(0.5)
    UsdGeom.XformCommonAPI(vol).SetRotate(Gf.Vec3f(0, 20, 0))
    field = UsdVol.OpenVDBAsset.Define(stage, "/World/Cloud/density")
    field.CreateFilePathAttr(Sdf.AssetPath(vdb_rel))
    field.CreateFieldNameAttr("density")
    vol.CreateFieldRelationship("density", field.GetPath())
    cam = UsdGeom.Camera.Define(stage, "/World/Camera")
    cam.CreateFocalLengthAttr(50.0)
    cam.CreateHorizontalApertureAttr(36.0)
    cam.CreateVerticalApertureAttr(27.0)
    UsdGeom.XformCommonAPI(cam).SetTranslate(Gf.Vec3d(0, 0.25, 4.6))
    sun = UsdLux.DistantLight.Define(stage, "/World/Sun")
    sun.CreateIntensityAttr(10.0)
    sun.CreateNormalizeAttr(True)
    sun.CreateColorAttr(Gf.Vec3f(1, 0.95, 0.88))
    UsdGeom.XformCommonAPI(sun).SetRotate(Gf.Vec3f(-40, 35, 0))
    sky = UsdLux.DomeLight.Define(stage, "/World/Sky")
    sky.CreateIntensityAttr(0.4)
    sky.CreateColorAttr(Gf.Vec3f(0.45, 0.6, 0.9))
    settings = UsdRender.Settings.Define(stage, "/Render/Settings")
    settings.GetPrim().AddAppliedSchema(nimbus.schema.RENDER_SETTINGS_API)
    settings.CreateCameraRel().SetTargets([cam.GetPath()])
    settings.CreateResolutionAttr(Gf.Vec2i(*RES))
    sp = settings.GetPrim()
    sp.CreateAttribute(nimbus.schema.SAMPLES, f.Int).Set(SPP)
    sp.CreateAttribute(nimbus.schema.MAX_DEPTH, f.Int).Set(32)
    sp.CreateAttribute(nimbus.schema.SEED, f.Int).Set(1)
    stage.SetMetadata("renderSettingsPrimPath", "/Render/Settings")
    stage.GetRootLayer().Save()
    return path


@pytest.fixture(scope="session")
def stage_dir(tmp_path_factory):
    d = tmp_path_factory.mktemp("stage")
    shutil.copy(CLOUD_VDB, d / "cloud.vdb")
    author_cloud(d / "cloud.usda")
    return d


@pytest.fixture(scope="session")
def stage(stage_dir):
    return stage_dir / "cloud.usda"
