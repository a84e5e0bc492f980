//! End-to-end tests of `nimbus render` on the same stage in .usda/.usdc/.usdz and on a
//! stage authored with Pixar's USD (Python `pxr`).

mod common;

use common::cli::{channel, channels, nimbus, python, root, stderr};

/// The same stage as .usda, .usdc (exported by Pixar's USD) and .usdz (packaged with its
/// VDB by UsdUtils) renders to the same image: identical bits, since the scene is the same
/// and rendering is deterministic.
#[test]
fn usda_usdc_usdz_render_identically() {
    if !common::pxr_python() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::copy(root().join("scenes/cloud/cloud.usda"), d.join("cloud.usda")).unwrap();
    std::fs::copy(root().join("scenes/cloud/cloud.vdb"), d.join("cloud.vdb")).unwrap();
    python(
        "import sys\nfrom pxr import Usd, UsdUtils\nd=sys.argv[1]\nUsd.Stage.Open(d+'/cloud.usda').Export(d+'/cloud.usdc')\nassert UsdUtils.CreateNewUsdzPackage(d+'/cloud.usda', d+'/cloud.usdz')\n",
        &[d.to_str().unwrap()],
    );
    let mut images = Vec::new();
    for ext in ["usda", "usdc", "usdz"] {
        let out = d.join(format!("out_{ext}.exr"));
        let o = nimbus(&[
            "render",
            d.join(format!("cloud.{ext}")).to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
            "--res",
            "24x18",
            "--spp",
            "2",
        ]);
        assert!(o.status.success(), "{ext}: {}", stderr(&o));
        images.push(channels(&out));
    }
    assert_eq!(images[0], images[1], "usda vs usdc");
    assert_eq!(images[0], images[2], "usda vs usdz");
}

/// A stage authored with Pixar's USD, applying Nimbus' schemas through the plugin in
/// schemas/, renders with nimbus; the schema's fallbacks are what pxr reports.
#[test]
fn stage_authored_with_pxr_and_nimbus_schema_renders() {
    if !common::pxr_python() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::copy(
        root().join("scenes/chromatic/chromatic.vdb"),
        d.join("puff.vdb"),
    )
    .unwrap();
    python(
        r#"
import sys
from pxr import Usd, UsdGeom, UsdVol, UsdLux, UsdRender, Sdf, Gf
d = sys.argv[1]
reg = Usd.SchemaRegistry()
vdef = reg.FindAppliedAPIPrimDefinition('NimbusVolumeAPI')
assert vdef is not None, 'pxr does not know NimbusVolumeAPI'
assert abs(vdef.GetAttributeFallbackValue('nimbus:densityScale') - 1.0) < 1e-6
stage = Usd.Stage.CreateNew(d + '/pxr.usda')
UsdGeom.Xform.Define(stage, '/W')
vol = UsdVol.Volume.Define(stage, '/W/Vol')
vol.GetPrim().ApplyAPI('NimbusVolumeAPI')
vol.GetPrim().GetAttribute('nimbus:densityScale').Set(3.0)
asset = UsdVol.OpenVDBAsset.Define(stage, '/W/Vol/density')
asset.CreateFilePathAttr(Sdf.AssetPath('./puff.vdb'))
asset.CreateFieldNameAttr('density')
vol.CreateFieldRelationship('density', asset.GetPath())
cam = UsdGeom.Camera.Define(stage, '/W/Cam')
cam.AddTranslateOp().Set(Gf.Vec3d(0, 0, 5))
UsdLux.DomeLight.Define(stage, '/W/Dome')
rs = UsdRender.Settings.Define(stage, '/Render/Settings')
rs.GetPrim().ApplyAPI('NimbusRenderSettingsAPI')
rs.GetPrim().GetAttribute('nimbus:samples').Set(3)
rs.CreateResolutionAttr(Gf.Vec2i(16, 12))
rs.CreateCameraRel().SetTargets([cam.GetPath()])
stage.GetRootLayer().Save()
"#,
        &[d.to_str().unwrap()],
    );
    let out = d.join("pxr.exr");
    let stats = d.join("pxr.json");
    let o = nimbus(&[
        "render",
        d.join("pxr.usda").to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--stats",
        stats.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&stats).unwrap()).unwrap();
    assert_eq!(
        json["samples_per_pixel"], 3,
        "nimbus:samples authored with pxr"
    );
    assert_eq!(json["width"], 16);
    assert!(channel(&channels(&out), "A").iter().any(|&a| a > 0.1));
}
