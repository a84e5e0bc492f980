//! End-to-end tests of the `nimbus` binary: rendering the shipped scenes, the same stage
//! in .usda/.usdc/.usdz, a stage authored with Pixar's USD, and bad input.

mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn nimbus(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_nimbus"))
        .args(args)
        .output()
        .expect("run nimbus")
}

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// Asserts a clean failure: non-zero exit, no panic, an error message containing `needle`.
fn assert_clean_error(o: &Output, needle: &str) {
    let e = stderr(o);
    assert!(
        !o.status.success(),
        "expected failure, got success; stderr: {e}"
    );
    assert_eq!(o.status.code(), Some(1), "exit code; stderr: {e}");
    assert!(!e.contains("panicked"), "panic: {e}");
    assert!(e.contains("nimbus: error:"), "no error line: {e}");
    assert!(e.contains(needle), "error does not mention '{needle}': {e}");
}

fn channels(path: &Path) -> Vec<(String, Vec<f32>)> {
    nimbus::output::exr::read_channels(path)
        .expect("read exr")
        .2
}

fn channel<'a>(chans: &'a [(String, Vec<f32>)], name: &str) -> &'a [f32] {
    &chans
        .iter()
        .find(|c| c.0 == name)
        .unwrap_or_else(|| panic!("no channel {name}"))
        .1
}

#[test]
fn renders_example_scenes_with_rgba_and_lookups() {
    let dir = tempfile::tempdir().unwrap();
    for scene in ["cloud", "chromatic", "overlap"] {
        let stage = root().join(format!("scenes/{scene}/{scene}.usda"));
        let out = dir.path().join(format!("{scene}.exr"));
        let stats = dir.path().join(format!("{scene}.json"));
        let o = nimbus(&[
            "render",
            stage.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
            "--res",
            "32x24",
            "--spp",
            "4",
            "--stats",
            stats.to_str().unwrap(),
        ]);
        assert!(o.status.success(), "{}", stderr(&o));
        let chans = channels(&out);
        for name in ["R", "G", "B", "A", "lookups"] {
            let c = channel(&chans, name);
            assert_eq!(c.len(), 32 * 24);
            assert!(
                c.iter().all(|v| v.is_finite()),
                "{scene}: non-finite {name}"
            );
        }
        // The volume is in view: some pixels are (partly) opaque and made lookups.
        assert!(
            channel(&chans, "A").iter().any(|&a| a > 0.5),
            "{scene}: no opaque pixel"
        );
        assert!(channel(&chans, "lookups").iter().any(|&l| l > 0.0));
        let json: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&stats).unwrap()).unwrap();
        for key in [
            "samples_per_pixel",
            "width",
            "height",
            "wall_seconds",
            "density_lookups",
            "real_collisions",
            "null_collisions",
            "nonfinite_samples",
            "vdb_reader",
        ] {
            assert!(json.get(key).is_some(), "stats lack {key}");
        }
        assert_eq!(json["samples_per_pixel"], 4);
        assert_eq!(json["width"], 32);
        // The lookups AOV is the per-sample mean: its pixel sum times spp is the total.
        let aov_total: f64 = channel(&chans, "lookups")
            .iter()
            .map(|&v| v as f64 * 4.0)
            .sum();
        let total = json["density_lookups"].as_f64().unwrap();
        assert!(
            (aov_total - total).abs() <= 1e-4 * total,
            "AOV {aov_total} vs stats {total}"
        );
    }
}

/// The overlap example renders both of its volumes: the stats count two, and each
/// volume alone (the other made invisible) makes fewer density lookups than the pair.
#[test]
fn stage_with_two_volumes_renders_both() {
    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(root().join("scenes/overlap/overlap.usda")).unwrap();
    // The example's layout, so its relative asset paths resolve.
    for scene in ["cloud", "chromatic", "overlap"] {
        std::fs::create_dir(dir.path().join(scene)).unwrap();
    }
    for vdb in ["cloud/cloud.vdb", "chromatic/chromatic.vdb"] {
        std::fs::copy(root().join("scenes").join(vdb), dir.path().join(vdb)).unwrap();
    }
    let run = |name: &str, text: &str| -> serde_json::Value {
        let stage = dir.path().join(format!("overlap/{name}.usda"));
        std::fs::write(&stage, text).unwrap();
        let out = dir.path().join(format!("{name}.exr"));
        let stats = dir.path().join(format!("{name}.json"));
        let o = nimbus(&[
            "render",
            stage.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
            "--res",
            "32x24",
            "--spp",
            "2",
            "--stats",
            stats.to_str().unwrap(),
        ]);
        assert!(o.status.success(), "{name}: {}", stderr(&o));
        assert!(
            !stderr(&o).contains("ignored"),
            "{name}: a volume was ignored: {}",
            stderr(&o)
        );
        serde_json::from_str(&std::fs::read_to_string(&stats).unwrap()).unwrap()
    };
    let hide = |prim: &str| {
        text.replace(
            &format!("def Volume \"{prim}\" (\n        prepend apiSchemas = [\"NimbusVolumeAPI\"]\n    )\n    {{\n"),
            &format!("def Volume \"{prim}\" (\n        prepend apiSchemas = [\"NimbusVolumeAPI\"]\n    )\n    {{\n        token visibility = \"invisible\"\n"),
        )
    };
    let (no_cloud, no_puff) = (hide("Cloud"), hide("Puff"));
    assert!(
        no_cloud != text && no_puff != text,
        "the stage changed its layout"
    );
    let both = run("both", &text);
    assert_eq!(both["analysis"]["volumes"], 2);
    let lookups = |j: &serde_json::Value| j["density_lookups"].as_f64().unwrap();
    for (name, alone) in [("puff", no_cloud), ("cloud", no_puff)] {
        let j = run(name, &alone);
        assert_eq!(j["analysis"]["volumes"], 1, "{name}");
        assert!(
            lookups(&j) < lookups(&both),
            "{name} alone: {} lookups, both: {}",
            lookups(&j),
            lookups(&both)
        );
    }
}

/// `nimbus info FILE.vdb` lists the grids with their types, counts and active value
/// ranges (the example cloud: one float grid, 0 < density ≤ 1), and a missing file is a
/// clean error naming it.
#[test]
fn info_describes_a_vdb_file() {
    let vdb = root().join("scenes/cloud/cloud.vdb");
    let o = nimbus(&["info", vdb.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let s = String::from_utf8_lossy(&o.stdout);
    assert!(s.contains("(1 grids)"), "{s}");
    assert!(s.contains("grid 'density' type Tree_float_5_4_3"), "{s}");
    let range = s
        .split("active values ")
        .nth(1)
        .and_then(|r| r.split(',').next())
        .expect("a value range");
    let (lo, hi) = range.split_once(" .. ").expect("lo .. hi");
    let (lo, hi): (f32, f32) = (lo.parse().unwrap(), hi.parse().unwrap());
    assert!(lo > 0.0 && hi <= 1.0 && lo < hi, "range {lo} .. {hi}");
    let missing = root().join("scenes/cloud/missing.vdb");
    assert_clean_error(&nimbus(&["info", missing.to_str().unwrap()]), "missing.vdb");
}

#[test]
fn info_describes_the_stage() {
    let o = Command::new(env!("CARGO_BIN_EXE_nimbus"))
        .args([
            "info",
            root().join("scenes/cloud/cloud.usda").to_str().unwrap(),
        ])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    let s = String::from_utf8_lossy(&o.stdout);
    for needle in [
        "/World/Cloud",
        "/World/Camera",
        "/World/Sun",
        "/World/Sky",
        "vdb reader",
        "density",
        "320x240",
    ] {
        assert!(s.contains(needle), "info lacks {needle}: {s}");
    }
}

/// Runs `python3 -c script args...` and asserts success.
fn python(script: &str, args: &[&str]) {
    let o = Command::new("python3")
        .arg("-c")
        .arg(script)
        .args(args)
        .env("PXR_PLUGINPATH_NAME", root().join("schemas"))
        .output()
        .unwrap();
    assert!(
        o.status.success(),
        "python failed: {}",
        String::from_utf8_lossy(&o.stderr)
    );
}

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

/// Writes a stage whose density field points at `file` with grid name `grid`.
fn stage_with_field(dir: &Path, file: &str, grid: &str) -> PathBuf {
    let text = std::fs::read_to_string(root().join("scenes/cloud/cloud.usda"))
        .unwrap()
        .replace("@./cloud.vdb@", &format!("@./{file}@"))
        .replace(
            "token fieldName = \"density\"",
            &format!("token fieldName = \"{grid}\""),
        );
    let path = dir.join("stage.usda");
    std::fs::write(&path, text).unwrap();
    path
}

fn render_args<'a>(stage: &'a str, out: &'a str) -> Vec<&'a str> {
    vec!["render", stage, "-o", out, "--res", "8x6", "--spp", "1"]
}

#[test]
fn bad_input_fails_cleanly_and_leaves_existing_output_untouched() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let out = d.join("keep.exr");
    std::fs::write(&out, b"precious").unwrap();
    let out_s = out.to_str().unwrap();
    let check_untouched = || assert_eq!(std::fs::read(&out).unwrap(), b"precious");

    // Missing stage.
    let missing = d.join("nope.usda");
    assert_clean_error(
        &nimbus(&render_args(missing.to_str().unwrap(), out_s)),
        "nope.usda",
    );
    check_untouched();

    // Malformed stage text.
    let bad = d.join("bad.usda");
    std::fs::write(&bad, "#usda 1.0\ndef Xform \"W\" {\n  float x = \n").unwrap();
    assert_clean_error(
        &nimbus(&render_args(bad.to_str().unwrap(), out_s)),
        "bad.usda",
    );
    check_untouched();

    // Missing VDB file.
    let s = stage_with_field(d, "missing.vdb", "density");
    assert_clean_error(
        &nimbus(&render_args(s.to_str().unwrap(), out_s)),
        "missing.vdb",
    );
    check_untouched();

    // Wrong grid name.
    std::fs::copy(root().join("scenes/cloud/cloud.vdb"), d.join("good.vdb")).unwrap();
    let s = stage_with_field(d, "good.vdb", "nosuchgrid");
    assert_clean_error(
        &nimbus(&render_args(s.to_str().unwrap(), out_s)),
        "nosuchgrid",
    );
    check_untouched();

    // Corrupt VDBs: zero bytes, text, truncated.
    let good = std::fs::read(root().join("scenes/cloud/cloud.vdb")).unwrap();
    for (name, bytes) in [
        ("zero.vdb", Vec::new()),
        (
            "text.vdb",
            b"this is not a vdb file at all, just some text\n".to_vec(),
        ),
        ("truncated.vdb", good[..good.len() / 2].to_vec()),
        ("header.vdb", good[..40.min(good.len())].to_vec()),
    ] {
        std::fs::write(d.join(name), bytes).unwrap();
        let s = stage_with_field(d, name, "density");
        assert_clean_error(&nimbus(&render_args(s.to_str().unwrap(), out_s)), name);
        check_untouched();
    }

    // Unwritable output path (a folder that does not exist).
    let stage = root().join("scenes/cloud/cloud.usda");
    let o = nimbus(&render_args(
        stage.to_str().unwrap(),
        d.join("no/such/dir/out.exr").to_str().unwrap(),
    ));
    assert_clean_error(&o, "no/such/dir");

    // Resolution 0 and absurd resolutions are refused before rendering.
    let mut a = render_args(stage.to_str().unwrap(), out_s);
    a[5] = "0x10";
    let o = nimbus(&a);
    assert!(!o.status.success() && !stderr(&o).contains("panicked"));
    a[5] = "4000000x4000000";
    assert_clean_error(&nimbus(&a), "memory");
    check_untouched();

    // Negative spp is rejected by the argument parser.
    let o = nimbus(&[
        "render",
        stage.to_str().unwrap(),
        "-o",
        out_s,
        "--spp",
        "-3",
    ]);
    assert!(!o.status.success() && !stderr(&o).contains("panicked"));
    check_untouched();

    // No temporary files are left behind.
    let leftovers: Vec<_> = std::fs::read_dir(d)
        .unwrap()
        .filter_map(|e| e.ok())
        .filter(|e| e.file_name().to_string_lossy().starts_with(".nimbus-"))
        .collect();
    assert!(leftovers.is_empty(), "temporary files left: {leftovers:?}");
}

/// The tracker comes from the stage's render settings unless a flag overrides it; an
/// unknown tracker token or render var is a clear error.
#[test]
fn tracker_settings_from_stage_and_flags() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::copy(
        root().join("scenes/chromatic/chromatic.vdb"),
        d.join("chromatic.vdb"),
    )
    .unwrap();
    let text = std::fs::read_to_string(root().join("scenes/chromatic/chromatic.usda")).unwrap();
    let write = |name: &str, extra: &str, var: &str| {
        let t = text
            .replace(
                "int nimbus:seed = 1",
                &format!("int nimbus:seed = 1\n        {extra}"),
            )
            .replace(
                "uniform string sourceName = \"lookups\"",
                &format!("uniform string sourceName = \"{var}\""),
            );
        let p = d.join(name);
        std::fs::write(&p, t).unwrap();
        p
    };
    let stats = d.join("s.json");
    let out = d.join("o.exr");
    let run = |stage: &Path, extra: &[&str]| {
        let mut a = vec![
            "render",
            stage.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
            "--res",
            "8x6",
            "--spp",
            "1",
            "--stats",
            stats.to_str().unwrap(),
        ];
        a.extend_from_slice(extra);
        nimbus(&a)
    };
    let tracker = || -> String {
        let j: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&stats).unwrap()).unwrap();
        format!(
            "{} {} {}",
            j["tracker"].as_str().unwrap(),
            j["scheme"].as_str().unwrap(),
            j["transmittance"].as_str().unwrap()
        )
    };
    let s = write(
        "a.usda",
        "token nimbus:tracker = \"spectral\"\n        token nimbus:scheme = \"max\"\n        token nimbus:transmittance = \"residual-ratio\"",
        "max_throughput",
    );
    let o = run(&s, &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(tracker(), "spectral max residual-ratio");
    assert!(
        channels(&out).iter().any(|c| c.0 == "max_throughput"),
        "render var max_throughput written"
    );
    let o = run(
        &s,
        &[
            "--tracker",
            "decomposition",
            "--scheme",
            "avg",
            "--transmittance",
            "ratio",
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(tracker(), "decomposition avg ratio");

    let bad = write("b.usda", "token nimbus:tracker = \"warp-drive\"", "lookups");
    assert_clean_error(&run(&bad, &[]), "nimbus:tracker");
    let bad = write("c.usda", "", "nosuchaov");
    assert_clean_error(&run(&bad, &[]), "nosuchaov");
}

/// `auto` on a homogeneous grey volume rendered from the command line: with no majorant
/// structure named, one global majorant and delta tracking; with one named on the
/// stage (`nimbus:octreeDepth`), the closed-form path (decomposition with residual
/// ratio shadow rays), although the stage applies `NimbusRenderSettingsAPI`, whose
/// schema fallbacks (scheme hist-avg, transmittance ratio) are not choices the stage
/// made; an authored `nimbus:transmittance` still wins.
#[test]
fn auto_is_not_overruled_by_schema_fallbacks() {
    use glam::DVec3;
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let vs = 2.0 / 32.0;
    let cube = nimbus::volume::procedural::grid_from_fn(
        "density",
        [32; 3],
        DVec3::splat(-1.0 + 0.5 * vs),
        vs,
        |_| 0.5,
    );
    nimbus::volume::vdb::write_float_grid(&d.join("cube.vdb"), &cube).unwrap();
    let text = std::fs::read_to_string(root().join("scenes/cloud/cloud.usda"))
        .unwrap()
        .replace("@./cloud.vdb@", "@./cube.vdb@");
    assert!(text.contains("NimbusRenderSettingsAPI"));
    let stats = d.join("s.json");
    let out = d.join("o.exr");
    let render = |name: &str, extra: &str| -> serde_json::Value {
        let stage = d.join(name);
        let t = text.replace(
            "int nimbus:seed = 1",
            &format!("int nimbus:seed = 1\n        {extra}"),
        );
        std::fs::write(&stage, t).unwrap();
        let o = nimbus(&[
            "render",
            stage.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
            "--res",
            "8x6",
            "--spp",
            "1",
            "--stats",
            stats.to_str().unwrap(),
        ]);
        assert!(o.status.success(), "{}", stderr(&o));
        stats_json(&stats)
    };
    let j = render("auto.usda", "");
    assert_eq!(j["analysis"]["homogeneous"], true);
    assert_eq!(
        (j["tracker"].as_str(), j["transmittance"].as_str()),
        (Some("delta"), Some("ratio"))
    );
    assert_eq!(j["majorant_cells"], 1);
    assert_eq!(j["code_paths"]["single_channel"], true);
    let j = render("octree.usda", "int nimbus:octreeDepth = 5");
    assert_eq!(
        (j["tracker"].as_str(), j["transmittance"].as_str()),
        (Some("decomposition"), Some("residual-ratio"))
    );
    assert_eq!(j["octree_depth"], 5);
    assert_eq!(j["code_paths"]["single_channel"], true);
    let j = render(
        "named.usda",
        "int nimbus:octreeDepth = 5\n        token nimbus:transmittance = \"ratio\"",
    );
    assert_eq!(
        (j["tracker"].as_str(), j["transmittance"].as_str()),
        (Some("decomposition"), Some("ratio"))
    );
}

/// Writes an EXR with f32 channels `(name, values)`, optionally inside a named layer.
fn write_test_exr(
    path: &Path,
    w: usize,
    h: usize,
    layer: Option<&str>,
    chans: &[(&str, Vec<f32>)],
) {
    use exr::prelude::*;
    let channels: Vec<AnyChannel<FlatSamples>> = chans
        .iter()
        .map(|(n, v)| AnyChannel::new(*n, FlatSamples::F32(v.clone())))
        .collect();
    let mut attrs = LayerAttributes::default();
    attrs.layer_name = layer.map(Text::from);
    let layer = Layer::new(
        (w, h),
        attrs,
        Encoding::FAST_LOSSLESS,
        AnyChannels::sort(channels.into()),
    );
    Image::from_layer(layer).write().to_file(path).unwrap();
}

fn compare_json(a: &Path, b: &Path) -> serde_json::Value {
    let o = nimbus(&[
        "compare",
        a.to_str().unwrap(),
        b.to_str().unwrap(),
        "--json",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    serde_json::from_slice(&o.stdout).unwrap()
}

#[test]
fn compare_reports_known_errors() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (w, h) = (4, 2);
    // Reference: R = 1, G = 0, B = 2. Test: R off by 0.5 everywhere, G off by 0.1 in
    // half the pixels, B exact except one pixel at 1e6 (clamped to 65504).
    let refc = vec![
        ("R", vec![1.0; 8]),
        ("G", vec![0.0; 8]),
        ("B", vec![2.0; 8]),
    ];
    let mut b_test = vec![2.0f32; 8];
    b_test[3] = 1e6;
    let test = vec![
        ("R", vec![1.5; 8]),
        (
            "G",
            (0..8).map(|i| if i % 2 == 0 { 0.1 } else { 0.0 }).collect(),
        ),
        ("B", b_test),
    ];
    let (a, b) = (d.join("a.exr"), d.join("b.exr"));
    write_test_exr(&a, w, h, None, &test);
    write_test_exr(&b, w, h, None, &refc);
    let j = compare_json(&a, &b);
    let ch = |i: usize, k: &str| j["channels"][i][k].as_f64().unwrap();
    let close = |x: f64, y: f64| (x - y).abs() <= 1e-6 * y.abs().max(1e-6);
    assert_eq!(j["channels"][0]["channel"], "R");
    assert!(close(ch(0, "mse"), 0.25));
    assert!(close(ch(0, "rmse"), 0.5));
    assert!(close(ch(0, "relmse"), 0.25 / 1.01));
    assert!(close(ch(0, "mean_a"), 1.5));
    assert!(close(ch(0, "mean_b"), 1.0));
    let g_d2 = (0.1f32 as f64).powi(2);
    assert!(close(ch(1, "mse"), g_d2 / 2.0));
    assert!(close(ch(1, "relmse"), g_d2 / 0.01 / 2.0));
    let b_d2 = (65504.0f64 - 2.0).powi(2);
    assert!(close(ch(2, "mse"), b_d2 / 8.0));
    assert!(close(ch(2, "relmse"), b_d2 / 4.01 / 8.0));
    // An image against itself: zero error.
    let z = compare_json(&b, &b);
    assert_eq!(z["rgb"]["mse"].as_f64().unwrap(), 0.0);

    // RGBA inside a named layer (`rgba.R` on read-back) is found.
    let layered = d.join("layered.exr");
    write_test_exr(&layered, w, h, Some("rgba"), &test);
    let jl = compare_json(&layered, &b);
    assert_eq!(jl["channels"][0]["mse"], j["channels"][0]["mse"]);
    // So are channels named `beauty.R` etc. without a layer attribute.
    let dotted = d.join("dotted.exr");
    let dotted_chans: Vec<(&str, Vec<f32>)> = vec![
        ("beauty.R", test[0].1.clone()),
        ("beauty.G", test[1].1.clone()),
        ("beauty.B", test[2].1.clone()),
    ];
    write_test_exr(&dotted, w, h, None, &dotted_chans);
    assert_eq!(compare_json(&dotted, &b)["rgb"], j["rgb"]);

    // Text output has the table.
    let o = nimbus(&["compare", a.to_str().unwrap(), b.to_str().unwrap()]);
    assert!(o.status.success());
    assert!(String::from_utf8_lossy(&o.stdout).contains("relMSE"));

    // Different sizes, a missing channel, a file that is not an EXR: clean errors.
    let small = d.join("small.exr");
    write_test_exr(
        &small,
        2,
        2,
        None,
        &[
            ("R", vec![0.0; 4]),
            ("G", vec![0.0; 4]),
            ("B", vec![0.0; 4]),
        ],
    );
    let o = nimbus(&["compare", small.to_str().unwrap(), b.to_str().unwrap()]);
    assert_clean_error(&o, "differ in size");
    let nog = d.join("nog.exr");
    write_test_exr(
        &nog,
        w,
        h,
        None,
        &[("R", vec![0.0; 8]), ("B", vec![0.0; 8])],
    );
    let o = nimbus(&["compare", nog.to_str().unwrap(), b.to_str().unwrap()]);
    assert_clean_error(&o, "no channel G");
    let junk = d.join("junk.exr");
    std::fs::write(&junk, b"not an exr").unwrap();
    let o = nimbus(&["compare", a.to_str().unwrap(), junk.to_str().unwrap()]);
    assert_clean_error(&o, "junk.exr");
}

fn stats_json(path: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

#[test]
fn time_limit_is_honoured_within_one_pass() {
    let dir = tempfile::tempdir().unwrap();
    let stage = root().join("scenes/cloud/cloud.usda");
    let out = dir.path().join("t.exr");
    let stats = dir.path().join("t.json");
    let limit = 1.5;
    let o = nimbus(&[
        "render",
        stage.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--res",
        "48x36",
        "--spp",
        "1000000",
        "--time-limit",
        &limit.to_string(),
        "--stats",
        stats.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let j = stats_json(&stats);
    let spp = j["samples_per_pixel"].as_u64().unwrap();
    let secs = j["render_seconds"].as_f64().unwrap();
    let max_pass = j["max_pass_seconds"].as_f64().unwrap();
    let passes = j["passes"].as_u64().unwrap();
    assert!(spp > 1 && spp < 1_000_000, "spp {spp}");
    assert!(passes >= 2, "passes {passes}");
    assert!(
        (secs - limit).abs() <= max_pass + 0.05,
        "render took {secs} s for a {limit} s budget (longest pass {max_pass} s)"
    );
    assert_eq!(j["interrupted"], false);
    let meta = nimbus::output::exr::read_i32_attribute(&out, "nimbus:spp").unwrap();
    assert_eq!(meta, Some(spp as i32));

    // The cap wins when it comes first.
    let o = nimbus(&[
        "render",
        stage.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--res",
        "16x12",
        "--spp",
        "3",
        "--time-limit",
        "30",
        "--stats",
        stats.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(stats_json(&stats)["samples_per_pixel"], 3);

    for bad in ["0", "-1", "nan"] {
        let o = nimbus(&[
            "render",
            stage.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
            "--time-limit",
            bad,
        ]);
        assert!(!o.status.success());
        assert!(!stderr(&o).contains("panicked"));
    }
}

#[cfg(unix)]
#[test]
fn interrupted_render_keeps_finished_passes() {
    let dir = tempfile::tempdir().unwrap();
    let stage = root().join("scenes/cloud/cloud.usda");
    let out = dir.path().join("i.exr");
    let stats = dir.path().join("i.json");
    let child = Command::new(env!("CARGO_BIN_EXE_nimbus"))
        .args([
            "render",
            stage.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
            "--res",
            "40x30",
            "--seed",
            "17",
            "--time-limit",
            "120",
            "--checkpoint",
            "0.3",
            "--stats",
            stats.to_str().unwrap(),
        ])
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    // Wait for the first checkpoint, then ask the render to stop.
    let t0 = std::time::Instant::now();
    while !out.exists() {
        assert!(t0.elapsed().as_secs() < 60, "no checkpoint written");
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    let checkpoint_spp = nimbus::output::exr::read_i32_attribute(&out, "nimbus:spp")
        .unwrap()
        .unwrap();
    assert!(checkpoint_spp >= 1);
    unsafe { libc::kill(child.id() as i32, libc::SIGTERM) };
    let o = child.wait_with_output().unwrap();
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(1), "{e}");
    assert!(e.contains("interrupted"), "{e}");
    assert!(!e.contains("panicked"), "{e}");
    let j = stats_json(&stats);
    assert_eq!(j["interrupted"], true);
    let spp = j["samples_per_pixel"].as_u64().unwrap();
    assert_eq!(
        nimbus::output::exr::read_i32_attribute(&out, "nimbus:spp").unwrap(),
        Some(spp as i32)
    );
    assert!(spp >= checkpoint_spp as u64);
    // No temporary files left behind.
    let leftovers: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .filter_map(|e| e.ok())
        .filter(|e| e.file_name().to_string_lossy().ends_with(".tmp"))
        .collect();
    assert!(leftovers.is_empty());

    // The same seed and sample count, uninterrupted: the same pixels, bit for bit.
    let full = dir.path().join("full.exr");
    let spp_s = spp.to_string();
    let o = nimbus(&[
        "render",
        stage.to_str().unwrap(),
        "-o",
        full.to_str().unwrap(),
        "--res",
        "40x30",
        "--seed",
        "17",
        "--spp",
        &spp_s,
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let (a, b) = (channels(&out), channels(&full));
    for name in ["R", "G", "B", "A", "lookups"] {
        let (x, y) = (channel(&a, name), channel(&b, name));
        assert!(
            x.iter().zip(y).all(|(p, q)| p.to_bits() == q.to_bits()),
            "channel {name} differs"
        );
    }
}

/// The example cloud stage with its density `filePath` replaced by `file_path` (an
/// `asset filePath...` line: a default value or time samples) and `extra` authored on
/// the volume.
fn cloud_stage_with(dir: &Path, file_path: &str, grid: &str, extra: &str) -> PathBuf {
    let text = std::fs::read_to_string(root().join("scenes/cloud/cloud.usda"))
        .unwrap()
        .replace("asset filePath = @./cloud.vdb@", file_path)
        .replace(
            "token fieldName = \"density\"",
            &format!("token fieldName = \"{grid}\""),
        )
        .replace(
            "float nimbus:anisotropy = 0.5",
            &format!("float nimbus:anisotropy = 0.5\n        {extra}"),
        );
    let path = dir.join("stage.usda");
    std::fs::write(&path, text).unwrap();
    path
}

/// The cloud stage with its density replaced by a VDB sequence of the EmberGen fire
/// (`(frame, path)` time samples on `filePath`, `temperature` as density), scaled into
/// the camera's view.
fn fire_stage(d: &Path, samples: &[(i32, String)]) -> PathBuf {
    let samples: Vec<String> = samples.iter().map(|(n, p)| format!("{n}: @{p}@")).collect();
    let stage = cloud_stage_with(
        d,
        &format!("asset filePath.timeSamples = {{ {} }}", samples.join(", ")),
        "temperature",
        // Fits the fire (world bounds about (-28..26, -29..22, -128..-86)) into the
        // camera's view of the unit cube.
        "float3 xformOp:scale = (0.0333, 0.0333, 0.0333)",
    );
    let text = std::fs::read_to_string(&stage)
        .unwrap()
        .replace(
            "double3 xformOp:translate = (0, 0, 0)",
            "double3 xformOp:translate = (0, 0.1, 3.57)",
        )
        // The volume's op order is the first in the file.
        .replacen(
            "[\"xformOp:translate\", \"xformOp:rotateXYZ\"]",
            "[\"xformOp:translate\", \"xformOp:scale\"]",
            1,
        );
    std::fs::write(&stage, text).unwrap();
    stage
}

/// A real VDB sequence (EmberGen, half floats, blosc) packaged with its stage by pxr's
/// UsdUtils.CreateNewUsdzPackage: the .usdz renders every frame bit-identically to the
/// loose files (VDB bytes read through openusd's package resolver, handed to OpenVDB as
/// a temporary file that is removed afterwards), and `info` lists the packaged grids.
#[test]
fn usdz_packaged_vdb_sequence_renders_like_loose_files() {
    let Some(data) = common::shared_data() else {
        return;
    };
    if !common::pxr_python() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::create_dir(d.join("fire")).unwrap();
    let mut samples = Vec::new();
    for n in [10, 20] {
        let name = format!("fire/fire_{n}.vdb");
        std::fs::copy(
            data.join(format!("embergen_fire_a/embergen_fire_a_{n}.vdb")),
            d.join(&name),
        )
        .unwrap();
        samples.push((n, format!("./{name}")));
    }
    let stage = fire_stage(d, &samples);
    let usdz = d.join("fire.usdz");
    python(
        "import sys\nfrom pxr import UsdUtils\nassert UsdUtils.CreateNewUsdzPackage(sys.argv[1], sys.argv[2])\n",
        &[stage.to_str().unwrap(), usdz.to_str().unwrap()],
    );
    // OpenVDB's temporary copies go here, so their removal can be checked.
    let tmp = d.join("tmp");
    std::fs::create_dir(&tmp).unwrap();
    let render = |stage: &Path, out: &Path| {
        let mut args = render_args(stage.to_str().unwrap(), out.to_str().unwrap());
        args.extend(["--frames", "15-20"]);
        let o = Command::new(env!("CARGO_BIN_EXE_nimbus"))
            .args(&args)
            .env("TMPDIR", &tmp)
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", stderr(&o));
    };
    render(&stage, &d.join("loose.exr"));
    render(&usdz, &d.join("packed.exr"));
    for f in 15..=20 {
        let loose = channels(&d.join(format!("loose.00{f}.exr")));
        let packed = channels(&d.join(format!("packed.00{f}.exr")));
        assert_eq!(loose, packed, "frame {f}");
        assert!(
            channel(&packed, "A").iter().any(|&a| a > 0.05),
            "frame {f}: fire in view"
        );
    }
    let left: Vec<_> = std::fs::read_dir(&tmp).unwrap().collect();
    assert!(left.is_empty(), "temporary VDB copies left: {left:?}");
    let o = nimbus(&["info", usdz.to_str().unwrap(), "--frame", "20"]);
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        out.contains("fire.usdz[fire/fire_20.vdb]") && out.contains("grid 'flames'"),
        "{out}"
    );
}

/// `--frames` over the EmberGen fire, a VDB sequence through time samples on
/// `filePath` (its `temperature` grid standing in for density): one EXR per frame
/// named by the `#` run or before the extension, the file held between samples (same
/// image for the same seed), a new file at the next sample, and each frame identical
/// to a single `--frame` render.
#[test]
fn frames_render_a_vdb_time_sequence() {
    let Some(data) = common::shared_data() else {
        return;
    };
    let fire = data.join("embergen_fire_a");
    let samples: Vec<(i32, String)> = [10, 20, 30]
        .iter()
        .map(|n| {
            let f = fire.join(format!("embergen_fire_a_{n}.vdb"));
            (*n, f.display().to_string())
        })
        .collect();
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let stage = fire_stage(d, &samples);
    let s = stage.to_str().unwrap();
    let seq = d.join("fire.###.exr");
    let stats = d.join("fire.json");
    let mut args = render_args(s, seq.to_str().unwrap());
    args.extend(["--frames", "18-20", "--stats", stats.to_str().unwrap()]);
    let o = nimbus(&args);
    let e = stderr(&o);
    assert!(o.status.success(), "{e}");
    for (i, f) in [18, 19, 20].iter().enumerate() {
        assert!(e.contains(&format!("frame {f} ({}/3)", i + 1)), "{e}");
        assert!(d.join(format!("fire.0{f}.exr")).is_file(), "frame {f}");
        assert!(d.join(format!("fire.00{f}.json")).is_file(), "stats {f}");
    }
    let a = channels(&d.join("fire.018.exr"));
    let b = channels(&d.join("fire.019.exr"));
    let c = channels(&d.join("fire.020.exr"));
    assert_eq!(a, b, "frames 18 and 19 hold the frame-10 file");
    assert!(channel(&c, "A").iter().any(|&x| x > 0.05), "fire in view");
    assert_ne!(
        channel(&b, "A"),
        channel(&c, "A"),
        "frame 20 reads a new file"
    );
    let single = d.join("single.exr");
    let mut args = render_args(s, single.to_str().unwrap());
    args.extend(["--frame", "20"]);
    let o = nimbus(&args);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(channels(&single), c, "--frame 20 == frame 20 of --frames");
}

/// A frame that fails (its VDB is missing) is reported, the other frames are written,
/// the exit status is non-zero, and the failed frame's existing file is untouched.
#[test]
fn failing_frame_keeps_good_frames() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::copy(root().join("scenes/cloud/cloud.vdb"), d.join("cloud.vdb")).unwrap();
    let stage = cloud_stage_with(
        d,
        "asset filePath.timeSamples = { 1: @./cloud.vdb@, 3: @./missing.vdb@ }",
        "density",
        "",
    );
    let previous = b"frame 3 from an earlier run";
    std::fs::write(d.join("out.0003.exr"), previous).unwrap();
    let out = d.join("out.exr");
    let mut args = render_args(stage.to_str().unwrap(), out.to_str().unwrap());
    args.extend(["--frames", "1-3"]);
    let o = nimbus(&args);
    assert_clean_error(&o, "1 of 3 frames failed: 3");
    assert!(stderr(&o).contains("frame 3: "), "{}", stderr(&o));
    assert!(stderr(&o).contains("missing.vdb"), "{}", stderr(&o));
    for f in [1, 2] {
        assert!(!channels(&d.join(format!("out.000{f}.exr"))).is_empty());
    }
    assert_eq!(std::fs::read(d.join("out.0003.exr")).unwrap(), previous);
    let leftovers: Vec<_> = std::fs::read_dir(d)
        .unwrap()
        .filter_map(|e| e.ok())
        .filter(|e| e.file_name().to_string_lossy().starts_with(".nimbus-"))
        .collect();
    assert!(leftovers.is_empty(), "temporary files left: {leftovers:?}");

    // Malformed ranges and --frame with --frames are refused before any work.
    for bad in ["5-2", "a-b", "1-"] {
        let mut args = render_args(stage.to_str().unwrap(), out.to_str().unwrap());
        args.extend(["--frames", bad]);
        let o = nimbus(&args);
        assert!(!o.status.success(), "--frames {bad} accepted");
        assert!(stderr(&o).contains("frame range"), "{}", stderr(&o));
    }
    let mut args = render_args(stage.to_str().unwrap(), out.to_str().unwrap());
    args.extend(["--frames", "1-2", "--frame", "1"]);
    assert!(!nimbus(&args).status.success(), "--frame with --frames");
}

/// A text attribute of an EXR's first header (e.g. `nimbus:scheme`).
fn exr_text_attribute(path: &Path, key: &str) -> Option<String> {
    use exr::meta::attribute::{AttributeValue, Text};
    let meta = exr::meta::MetaData::read_from_file(path, false).expect("EXR header");
    let h = meta.headers.first()?;
    let key = Text::from(key);
    match h.own_attributes.other.get(&key)? {
        AttributeValue::Text(t) => Some(t.to_string()),
        _ => None,
    }
}

/// The chromatic scene with two RenderProducts at `beauty` and `counters`: the first
/// with color and lookups, the second with alpha, real_collisions and variance.
fn two_product_stage(dir: &Path, beauty: &str, counters: &str) -> PathBuf {
    std::fs::copy(
        root().join("scenes/chromatic/chromatic.vdb"),
        dir.join("chromatic.vdb"),
    )
    .unwrap();
    let text = std::fs::read_to_string(root().join("scenes/chromatic/chromatic.usda"))
        .unwrap()
        .replace(
            "rel products = </Render/Product>",
            "rel products = [</Render/Product>, </Render/Counters>]",
        )
        .replace(
            "uniform token productName = \"chromatic.exr\"",
            &format!("uniform token productName = \"{beauty}\""),
        )
        .replace(
            "    def Scope \"Vars\"\n",
            &format!(
                "    def RenderProduct \"Counters\"
    {{
        uniform token productName = \"{counters}\"
        rel orderedVars = [</Render/Extra/alpha>, </Render/Extra/real>, </Render/Extra/variance>]
    }}

    def Scope \"Extra\"
    {{
        def RenderVar \"alpha\" {{ uniform string sourceName = \"alpha\" }}
        def RenderVar \"real\" {{ uniform string sourceName = \"real_collisions\" }}
        def RenderVar \"variance\" {{ uniform string sourceName = \"variance\" }}
    }}

    def Scope \"Vars\"
"
            ),
        );
    let path = dir.join("products.usda");
    std::fs::write(&path, text).unwrap();
    path
}

/// Every RenderVar of every RenderProduct is a channel of that product's EXR (plus R, G,
/// B, A in each); `-o` replaces the first product's path only; the header records the
/// settings; products colliding on one path, unknown source names and a stage without
/// products or -o are clear errors.
#[test]
fn render_products_each_get_their_vars() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let beauty = d.join("beauty.exr");
    let counters = d.join("counters.exr");
    let stage = two_product_stage(d, beauty.to_str().unwrap(), counters.to_str().unwrap());
    let s = stage.to_str().unwrap();
    let base = ["render", s, "--res", "8x6", "--spp", "2"];
    let o = nimbus(&base);
    assert!(o.status.success(), "{}", stderr(&o));
    let names = |p: &Path| -> Vec<String> {
        let mut n: Vec<String> = channels(p).into_iter().map(|c| c.0).collect();
        n.sort();
        n
    };
    assert_eq!(names(&beauty), ["A", "B", "G", "R", "lookups"]);
    assert_eq!(
        names(&counters),
        ["A", "B", "G", "R", "real_collisions", "variance"]
    );
    // One film: the channels both products share are the same pixels.
    let (b, c) = (channels(&beauty), channels(&counters));
    for ch in ["R", "G", "B", "A"] {
        assert_eq!(channel(&b, ch), channel(&c, ch), "{ch}");
    }
    assert!(channel(&c, "real_collisions").iter().any(|&v| v > 0.0));
    assert_eq!(
        exr_text_attribute(&beauty, "nimbus:renderProduct").as_deref(),
        Some("/Render/Product")
    );
    assert_eq!(
        exr_text_attribute(&counters, "nimbus:renderProduct").as_deref(),
        Some("/Render/Counters")
    );
    for (key, want) in [
        // `auto` (the default) picks spectral decomposition: the medium is chromatic.
        ("nimbus:tracker", "spectral-decomposition"),
        ("nimbus:scheme", "hist-avg"),
        ("nimbus:transmittance", "ratio"),
        ("nimbus:version", env!("CARGO_PKG_VERSION")),
        ("nimbus:stage", s),
    ] {
        assert_eq!(
            exr_text_attribute(&beauty, key).as_deref(),
            Some(want),
            "{key}"
        );
    }
    assert_eq!(
        nimbus::output::exr::read_i32_attribute(&beauty, "nimbus:spp").unwrap(),
        Some(2)
    );

    // -o replaces the first product's path; the second product keeps its own.
    std::fs::remove_file(&counters).unwrap();
    let over = d.join("over.exr");
    let mut args = base.to_vec();
    args.extend(["-o", over.to_str().unwrap(), "--aovs", "null_collisions"]);
    let o = nimbus(&args);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(
        names(&over),
        ["A", "B", "G", "R", "lookups", "null_collisions"]
    );
    assert_eq!(channel(&channels(&over), "R"), channel(&b, "R"));
    assert!(counters.is_file(), "second product written");

    // Two products on one file.
    let same = two_product_stage(d, beauty.to_str().unwrap(), beauty.to_str().unwrap());
    assert_clean_error(
        &nimbus(&["render", same.to_str().unwrap(), "--res", "8x6"]),
        "both write",
    );
    // No products and no -o.
    std::fs::copy(root().join("scenes/cloud/cloud.vdb"), d.join("cloud.vdb")).unwrap();
    let plain = cloud_stage_with(d, "asset filePath = @./cloud.vdb@", "density", "");
    let text = std::fs::read_to_string(&plain)
        .unwrap()
        .replace("rel products = </Render/Product>", "");
    std::fs::write(&plain, text).unwrap();
    assert_clean_error(
        &nimbus(&["render", plain.to_str().unwrap(), "--res", "8x6"]),
        "give one with -o",
    );
    // An unknown source name lists the known ones.
    let text = std::fs::read_to_string(&stage)
        .unwrap()
        .replace("\"real_collisions\"", "\"depth\"");
    std::fs::write(&stage, text).unwrap();
    let o = nimbus(&base);
    assert_clean_error(&o, "/Render/Extra/real: sourceName \"depth\"");
    assert!(
        stderr(&o).contains("known: color, alpha, R, G, B, A, lookups"),
        "{}",
        stderr(&o)
    );
}

/// Writes `files` (name, text) into `dir` and renders `dir/first`: every case must fail
/// cleanly, naming `needle`, leaving `keep` untouched.
fn assert_stage_refused(dir: &Path, files: &[(&str, &[u8])], needle: &str) {
    for (name, bytes) in files {
        std::fs::write(dir.join(name), bytes).unwrap();
    }
    let out = dir.join("keep.exr");
    std::fs::write(&out, b"precious").unwrap();
    let stage = dir.join(files[0].0);
    let o = nimbus(&render_args(stage.to_str().unwrap(), out.to_str().unwrap()));
    assert_clean_error(&o, needle);
    assert_eq!(std::fs::read(&out).unwrap(), b"precious");
    let o = nimbus(&["info", stage.to_str().unwrap()]);
    assert_clean_error(&o, needle);
}

/// Cyclic sublayers and references (between two files, and a prim referencing itself)
/// are composition errors naming the stage and the cycle, not a stack overflow or hang.
#[test]
fn cyclic_sublayers_and_references_are_clear_errors() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    assert_stage_refused(
        d,
        &[
            ("a.usda", b"#usda 1.0\n(\n    subLayers = [@./b.usda@]\n)\n"),
            ("b.usda", b"#usda 1.0\n(\n    subLayers = [@./a.usda@]\n)\n"),
        ],
        "cycle",
    );
    assert_stage_refused(
        d,
        &[
            (
                "r.usda",
                b"#usda 1.0\ndef Xform \"W\" (\n    references = @./r2.usda@</W>\n)\n{\n}\n",
            ),
            (
                "r2.usda",
                b"#usda 1.0\ndef Xform \"W\" (\n    references = @./r.usda@</W>\n)\n{\n}\n",
            ),
        ],
        "cycle",
    );
    assert_stage_refused(
        d,
        &[(
            "self.usda",
            b"#usda 1.0\ndef Xform \"W\" (\n    references = </W>\n)\n{\n}\n",
        )],
        "self.usda",
    );
    assert_stage_refused(
        d,
        &[(
            "payload.usda",
            b"#usda 1.0\ndef Xform \"W\" (\n    payload = @./payload.usda@</W>\n)\n{\n}\n",
        )],
        "cycle",
    );
}

/// Malformed .usdz packages: not a zip, empty, truncated, no layer inside, a
/// compressed (unsupported) member, a layer that does not parse.
#[test]
fn malformed_usdz_is_a_clear_error() {
    use std::io::Write;
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // Python's zipfile writes the packages (USDZ members are stored, not deflated).
    if !common::python_imports(&["zipfile"], "the zip-built cases need python3") {
        return;
    }
    let good = d.join("good.usdz");
    let script = "import sys, zipfile\nd = sys.argv[1]\nsrc = sys.argv[2]\n\
z = zipfile.ZipFile(d + '/good.usdz', 'w'); z.write(src + '/cloud.usda', 'cloud.usda'); z.write(src + '/cloud.vdb', 'cloud.vdb'); z.close()\n\
z = zipfile.ZipFile(d + '/nolayer.usdz', 'w'); z.writestr('readme.txt', 'hi'); z.close()\n\
z = zipfile.ZipFile(d + '/deflated.usdz', 'w', compression=zipfile.ZIP_DEFLATED); z.writestr('a.usda', '#usda 1.0\\n'); z.close()\n\
z = zipfile.ZipFile(d + '/badlayer.usdz', 'w'); z.writestr('a.usda', '#usda 1.0\\ndef X \"A\" {\\n float x = \\n'); z.close()\n";
    let o = Command::new("python3")
        .args([
            "-c",
            script,
            d.to_str().unwrap(),
            root().join("scenes/cloud").to_str().unwrap(),
        ])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    let bytes = std::fs::read(&good).unwrap();
    let mut garbage = std::fs::File::create(d.join("garbage.usdz")).unwrap();
    garbage.write_all(b"PK\x03\x04 not really a zip").unwrap();
    std::fs::write(d.join("empty.usdz"), b"").unwrap();
    std::fs::write(d.join("truncated.usdz"), &bytes[..bytes.len() / 2]).unwrap();
    let out = d.join("keep.exr");
    std::fs::write(&out, b"precious").unwrap();
    for name in [
        "garbage.usdz",
        "empty.usdz",
        "truncated.usdz",
        "nolayer.usdz",
        "deflated.usdz",
        "badlayer.usdz",
    ] {
        let stage = d.join(name);
        let o = nimbus(&render_args(stage.to_str().unwrap(), out.to_str().unwrap()));
        assert_clean_error(&o, name);
        assert_eq!(std::fs::read(&out).unwrap(), b"precious", "{name}");
    }
    // The well-formed package renders (the cases above fail for their own reasons).
    let o = nimbus(&render_args(good.to_str().unwrap(), out.to_str().unwrap()));
    assert!(o.status.success(), "{}", stderr(&o));
}

/// A Vec3 grid where the density field expects a float grid: a clear error naming the
/// file, the grid and both types.
#[test]
fn vec3_grid_for_a_float_field_is_a_clear_error() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let mut bytes = std::fs::read(root().join("scenes/cloud/cloud.vdb")).unwrap();
    let from = b"Tree_float_5_4_3";
    let at = bytes
        .windows(from.len())
        .position(|w| w == from)
        .expect("grid type in the header");
    bytes[at..at + from.len()].copy_from_slice(b"Tree_vec3s_5_4_3");
    std::fs::write(d.join("vel.vdb"), &bytes).unwrap();
    let stage = stage_with_field(d, "vel.vdb", "density");
    let out = d.join("out.exr");
    let o = nimbus(&render_args(stage.to_str().unwrap(), out.to_str().unwrap()));
    assert_clean_error(&o, "vel.vdb");
    let e = stderr(&o);
    assert!(
        e.contains("\"density\"") && e.contains("Vec3s") && e.contains("float"),
        "{e}"
    );
    assert!(!out.exists());
}

/// Unreadable stage and VDB files (permission denied) are clear errors naming the file.
/// As root, permissions do not stop reads, so the binary runs as `nobody` there.
#[test]
fn unreadable_stage_and_vdb_are_clear_errors() {
    use std::os::unix::fs::PermissionsExt;
    use std::os::unix::process::CommandExt;
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::set_permissions(d, std::fs::Permissions::from_mode(0o777)).unwrap();
    let is_root = unsafe { libc::geteuid() } == 0;
    let run = |args: &[&str]| -> Output {
        let mut c = Command::new(env!("CARGO_BIN_EXE_nimbus"));
        c.args(args);
        if is_root {
            c.uid(65534).gid(65534);
        }
        c.output().expect("run nimbus")
    };
    if is_root {
        // The binary must be reachable by `nobody` (it is, under a world-readable tree).
        let probe = run(&["--version"]);
        if !probe.status.success() {
            eprintln!("cannot run nimbus as nobody: skipping ({})", stderr(&probe));
            return;
        }
    }
    std::fs::copy(root().join("scenes/cloud/cloud.vdb"), d.join("locked.vdb")).unwrap();
    let stage = stage_with_field(d, "locked.vdb", "density");
    let locked = d.join("locked.usda");
    std::fs::copy(&stage, &locked).unwrap();
    for p in [&stage, &locked] {
        std::fs::set_permissions(p, std::fs::Permissions::from_mode(0o644)).unwrap();
    }
    std::fs::set_permissions(d.join("locked.vdb"), std::fs::Permissions::from_mode(0o000)).unwrap();
    std::fs::set_permissions(&locked, std::fs::Permissions::from_mode(0o000)).unwrap();
    let out = d.join("out.exr");
    let out_s = out.to_str().unwrap();
    assert_clean_error(
        &run(&render_args(locked.to_str().unwrap(), out_s)),
        "locked.usda",
    );
    assert_clean_error(
        &run(&render_args(stage.to_str().unwrap(), out_s)),
        "locked.vdb",
    );
    assert!(!out.exists());
}

/// NaN, ±Inf and negative voxels in a VDB: `nimbus info` and `--stats` count them, and
/// the render is finite with no sample dropped.
#[test]
fn bad_voxels_are_counted_by_info_and_stats() {
    use nimbus::volume::procedural::grid_from_fn;
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let mut raw = grid_from_fn(
        "density",
        [8, 8, 8],
        glam::DVec3::splat(-0.5),
        0.125,
        |_| 1.0,
    );
    for (i, v) in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY, -2.0]
        .into_iter()
        .enumerate()
    {
        raw.leaves[0].values[i * 100] = v;
    }
    nimbus::volume::vdb::write_float_grid(&d.join("bad.vdb"), &raw).unwrap();
    let stage = stage_with_field(d, "bad.vdb", "density");
    let o = nimbus(&["info", stage.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(out.contains("sanitized voxels 4"), "{out}");
    let exr = d.join("out.exr");
    let stats = d.join("stats.json");
    let mut args = render_args(stage.to_str().unwrap(), exr.to_str().unwrap());
    args.extend([
        "--stats",
        stats.to_str().unwrap(),
        "--aovs",
        "max_throughput,variance,null_collisions",
    ]);
    let o = nimbus(&args);
    assert!(o.status.success(), "{}", stderr(&o));
    let j = stats_json(&stats);
    assert_eq!(j["sanitized_voxels"], 4);
    assert_eq!(j["nonfinite_samples"], 0);
    for (name, values) in channels(&exr) {
        assert!(values.iter().all(|v| v.is_finite()), "channel {name}");
    }
}

/// A volume whose transform has scale 0 is refused naming the prim.
#[test]
fn zero_scale_volume_is_a_clear_error() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::copy(root().join("scenes/cloud/cloud.vdb"), d.join("cloud.vdb")).unwrap();
    let text = std::fs::read_to_string(root().join("scenes/cloud/cloud.usda"))
        .unwrap()
        .replacen(
            "uniform token[] xformOpOrder = [\"xformOp:translate\", \"xformOp:rotateXYZ\"]",
            "float3 xformOp:scale = (0, 0, 0)\n        uniform token[] xformOpOrder = [\"xformOp:translate\", \"xformOp:rotateXYZ\", \"xformOp:scale\"]",
            1,
        );
    let stage = d.join("flat.usda");
    std::fs::write(&stage, text).unwrap();
    let out = d.join("out.exr");
    let o = nimbus(&render_args(stage.to_str().unwrap(), out.to_str().unwrap()));
    assert_clean_error(&o, "singular");
    assert!(!out.exists());
}

/// Results are ordinary files: a new EXR is rw-r--r-- (not the temporary file's private
/// 0600), and a re-render keeps the mode the user gave the old file.
#[cfg(unix)]
#[test]
fn outputs_get_ordinary_permissions() {
    use std::os::unix::fs::PermissionsExt;
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("new.exr");
    let stage = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/cloud/cloud.usda");
    let o = nimbus(&render_args(stage, out.to_str().unwrap()));
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let mode = |p: &Path| std::fs::metadata(p).unwrap().permissions().mode() & 0o777;
    assert_eq!(mode(&out), 0o644);
    std::fs::set_permissions(&out, std::fs::Permissions::from_mode(0o640)).unwrap();
    let o = nimbus(&render_args(stage, out.to_str().unwrap()));
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(mode(&out), 0o640);
}
