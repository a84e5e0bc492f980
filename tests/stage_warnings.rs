//! Nothing silent: what a stage asks for and the render does not show as authored is a
//! warning naming the prim (one line per kind), listed by `info`, recorded in the stats,
//! and an error under `--strict` or `nimbus:strict`; the default sun and sky light only a
//! stage with no light prim at all and no emissive volume.

mod common;

use common::cli::{assert_clean_error, channel, channels, nimbus, root, stats_json, stderr};
use std::path::{Path, PathBuf};

/// The example cloud with its sun and sky replaced by `lights` (USD text inside /World).
fn cloud_lit_by(dir: &Path, lights: &str) -> PathBuf {
    let text = std::fs::read_to_string(root().join("scenes/cloud/cloud.usda")).unwrap();
    let start = text.find("    def DistantLight \"Sun\"").unwrap();
    let end = text.find("def Scope \"Render\"").unwrap();
    let text = format!("{}{lights}\n}}\n\n{}", &text[..start], &text[end..]).replace(
        "@./cloud.vdb@",
        &format!("@{}@", root().join("scenes/cloud/cloud.vdb").display()),
    );
    let path = dir.join("stage.usda");
    std::fs::write(&path, text).unwrap();
    path
}

/// Light prims of types Nimbus does not render (they stay unsupported: portals need a
/// dome to guide, geometry lights are deprecated, plugin lights are renderer-specific).
const UNREAD_LIGHTS: &str = r#"
    def PortalLight "Portal" {}
    def GeometryLight "Geo1" {}
    def GeometryLight "Geo2" {}
    def Mesh "Panel" ( prepend apiSchemas = ["MeshLightAPI"] ) {
        point3f[] points = [(5, 5, 5), (6, 5, 5), (6, 6, 5)]
        int[] faceVertexCounts = [3]
        int[] faceVertexIndices = [0, 1, 2]
    }
"#;

fn render(stage: &Path, out: &Path, extra: &[&str]) -> std::process::Output {
    let mut args = vec![
        "render",
        stage.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--res",
        "16x12",
        "--spp",
        "2",
    ];
    args.extend_from_slice(extra);
    nimbus(&args)
}

fn warning_lines(o: &std::process::Output) -> Vec<String> {
    stderr(o)
        .lines()
        .filter(|l| l.starts_with("nimbus: warning:"))
        .map(str::to_string)
        .collect()
}

#[test]
fn unread_lights_warn_once_per_kind_and_are_errors_under_strict() {
    let dir = tempfile::tempdir().unwrap();
    let stage = cloud_lit_by(dir.path(), UNREAD_LIGHTS);
    let out = dir.path().join("out.exr");
    let stats = dir.path().join("stats.json");
    let o = render(&stage, &out, &["--stats", stats.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let lines = warning_lines(&o);
    let expect = [
        "/World/Portal: PortalLight lights are not supported",
        "/World/Geo1: GeometryLight lights are not supported: this light is left out of the render (the same for /World/Geo2)",
        "/World/Panel: MeshLightAPI makes this Mesh a light",
    ];
    for e in expect {
        assert_eq!(
            lines.iter().filter(|l| l.contains(e)).count(),
            1,
            "one line with {e:?} in {lines:#?}"
        );
    }
    // The stage has light prims: no default lights, so nothing lights the cloud.
    assert!(!stderr(&o).contains("default sun"), "{}", stderr(&o));
    let s = stats_json(&stats);
    let w = s["stage_warnings"].as_array().expect("stage_warnings");
    let prims: Vec<&str> = w.iter().map(|w| w["prim"].as_str().unwrap()).collect();
    assert_eq!(
        prims,
        [
            "/World/Portal",
            "/World/Geo1",
            "/World/Geo2",
            "/World/Panel"
        ]
    );
    assert_eq!(w[1]["kind"], "GeometryLight light");

    // `info` lists them.
    let info = nimbus(&["info", stage.to_str().unwrap()]);
    let text = String::from_utf8_lossy(&info.stdout);
    assert!(text.contains("/World/Portal: PortalLight"), "{text}");

    // --strict: an error naming every one, and no output.
    let strict_out = dir.path().join("strict.exr");
    let o = render(&stage, &strict_out, &["--strict"]);
    assert_clean_error(&o, "strict");
    for p in prims {
        assert!(stderr(&o).contains(p), "{p} not named: {}", stderr(&o));
    }
    assert!(!strict_out.exists(), "a refused render wrote its output");

    // nimbus:strict on the RenderSettings prim does the same.
    let text = std::fs::read_to_string(&stage).unwrap().replace(
        "int nimbus:seed = 1",
        "int nimbus:seed = 1\n        bool nimbus:strict = true",
    );
    std::fs::write(&stage, text).unwrap();
    let o = render(&stage, &strict_out, &[]);
    assert_clean_error(&o, "/World/Portal");
    assert!(!strict_out.exists());
}

#[test]
fn example_stages_have_no_stage_warnings() {
    let dir = tempfile::tempdir().unwrap();
    for name in ["cloud", "chromatic", "fire", "overlap"] {
        let stage = root().join(format!("scenes/{name}/{name}.usda"));
        let out = dir.path().join(format!("{name}.exr"));
        let stats = dir.path().join(format!("{name}.json"));
        let o = render(
            &stage,
            &out,
            &["--stats", stats.to_str().unwrap(), "--strict"],
        );
        assert!(o.status.success(), "{name}: {}", stderr(&o));
        assert_eq!(warning_lines(&o), Vec::<String>::new(), "{name}");
        assert_eq!(stats_json(&stats)["stage_warnings"], serde_json::json!([]));
    }
}

/// R, G, B, A of an EXR.
fn rgba(path: &Path) -> Vec<Vec<f32>> {
    let c = channels(path);
    ["R", "G", "B", "A"]
        .iter()
        .map(|n| channel(&c, n).to_vec())
        .collect()
}

#[test]
fn default_lights_only_for_a_stage_without_light_prims_or_emission() {
    let dir = tempfile::tempdir().unwrap();
    // No light prim at all: the default sun and sky, with a warning; the flag turns
    // them off (an unlit cloud: black, but opaque where it is dense); --strict refuses.
    let unlit = cloud_lit_by(dir.path(), "");
    let lit = dir.path().join("lit.exr");
    let o = render(&unlit, &lit, &[]);
    assert!(stderr(&o).contains("default sun and sky"), "{}", stderr(&o));
    let dark = dir.path().join("dark.exr");
    let o = render(&unlit, &dark, &["--no-default-lights"]);
    assert!(o.status.success() && !stderr(&o).contains("default sun"));
    let (lit, dark) = (rgba(&lit), rgba(&dark));
    assert!(
        lit[0].iter().sum::<f32>() > 0.0,
        "the defaults light the cloud"
    );
    for c in 0..3 {
        assert!(dark[c].iter().all(|&v| v == 0.0), "channel {c} is lit");
    }
    assert!(dark[3].iter().any(|&a| a > 0.5), "the cloud is still there");
    assert_clean_error(
        &render(&unlit, &dir.path().join("s.exr"), &["--strict"]),
        "no lights",
    );

    // A fire lit only by itself: no default lights, the same image as with the flag.
    let fire = std::fs::read_to_string(root().join("scenes/fire/fire.usda")).unwrap();
    let start = fire.find("    def DomeLight \"Sky\"").unwrap();
    let end = start + fire[start..].find("\n    }\n").unwrap() + 7;
    let fire = format!("{}{}", &fire[..start], &fire[end..]).replace(
        "@./fire.vdb@",
        &format!("@{}@", root().join("scenes/fire/fire.vdb").display()),
    );
    let fire_stage = dir.path().join("fire.usda");
    std::fs::write(&fire_stage, fire).unwrap();
    let (a, b) = (dir.path().join("fa.exr"), dir.path().join("fb.exr"));
    let o = render(&fire_stage, &a, &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(!stderr(&o).contains("default sun"), "{}", stderr(&o));
    assert!(render(&fire_stage, &b, &["--no-default-lights"])
        .status
        .success());
    assert_eq!(rgba(&a), rgba(&b));
    assert!(rgba(&a)[0].iter().sum::<f32>() > 0.0, "the fire emits");
}

/// The example cloud with `replace` applied (pairs of text to find, exactly once, and
/// what to put there), its VDB path made absolute.
fn cloud_with(dir: &Path, name: &str, replace: &[(&str, &str)]) -> PathBuf {
    let mut text = std::fs::read_to_string(root().join("scenes/cloud/cloud.usda"))
        .unwrap()
        .replace(
            "@./cloud.vdb@",
            &format!("@{}@", root().join("scenes/cloud/cloud.vdb").display()),
        );
    for (from, to) in replace {
        assert_eq!(text.matches(from).count(), 1, "{from:?} in cloud.usda");
        text = text.replace(from, to);
    }
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path
}

/// Prims besides lights that the render does not show as authored: gprims Nimbus has no
/// holdout for (one line per type, none for a prototype or for `nimbus:holdout =
/// false`), a point instancer with a gprim prototype (only volume prototypes are
/// placed), a Field3DAsset field, and render settings and a product
/// asking for non-square pixels, a crop, another conform policy and their own
/// resolution. Each names its prim and attribute; `--strict` refuses them.
#[test]
fn unread_prims_and_settings_warn_once_per_kind_and_are_errors_under_strict() {
    let dir = tempfile::tempdir().unwrap();
    let extra_prims = r#"
    def Points "Dust" { point3f[] points = [(0, 0, 0), (0.1, 0, 0)] float[] widths = [0.05, 0.05] }
    def Points "MoreDust" { point3f[] points = [(0, 0.1, 0)] float[] widths = [0.05] }
    def Points "NotAHoldout" { bool nimbus:holdout = false point3f[] points = [(0, 0, 0)] }
    def Points "Guide" { uniform token purpose = "guide" point3f[] points = [(0, 0, 0)] }
    def BasisCurves "Hair" {
        uniform token type = "linear"
        int[] curveVertexCounts = [2]
        point3f[] points = [(0, 0, 0), (0, 1, 0)]
    }
    def PointInstancer "Scatter" {
        rel prototypes = [</World/Scatter/Protos/Pebble>]
        int[] protoIndices = [0]
        point3f[] positions = [(5, 5, 5)]
        def Scope "Protos" {
            def Points "Pebble" { point3f[] points = [(0, 0, 0)] }
        }
    }

    def DistantLight "Sun""#;
    let stage = cloud_with(
        dir.path(),
        "stage.usda",
        &[
            ("\n    def DistantLight \"Sun\"", extra_prims),
            (
                "rel field:density = </World/Cloud/density>",
                "rel field:density = </World/Cloud/density>\n        \
                 rel field:temperature = </World/Cloud/temperature>",
            ),
            (
                "        def OpenVDBAsset \"density\"",
                "        def Field3DAsset \"temperature\" { asset filePath = @./heat.f3d@ }\n\n        \
                 def OpenVDBAsset \"density\"",
            ),
            (
                "uniform int2 resolution = (320, 240)",
                "uniform int2 resolution = (320, 240)\n        float pixelAspectRatio = 2\n        \
                 float4 dataWindowNDC = (0, 0, 0.5, 1)\n        \
                 uniform token aspectRatioConformPolicy = \"cropAperture\"",
            ),
            (
                "uniform token productName = \"cloud.exr\"",
                "uniform token productName = \"cloud.exr\"\n        uniform int2 resolution = (64, 48)",
            ),
        ],
    );
    let out = dir.path().join("out.exr");
    let stats = dir.path().join("stats.json");
    let o = render(&stage, &out, &["--stats", stats.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let lines = warning_lines(&o);
    let expect = [
        "/World/Dust: Points prims are not read as holdouts: this one does not occlude the volumes (set nimbus:holdout = false to say so) (the same for /World/MoreDust)",
        "/World/Hair: BasisCurves prims are not read as holdouts",
        "/World/Scatter.prototypes: 1 gprims beneath its prototypes are not placed",
        "/World/Cloud.field:temperature: targets /World/Cloud/temperature (Field3DAsset); Nimbus reads OpenVDBAsset fields only",
        "/Render/Settings.pixelAspectRatio: is 2: Nimbus renders square pixels",
        "/Render/Settings.dataWindowNDC: is [0.0, 0.0, 0.5, 1.0]: Nimbus renders the whole frame",
        "/Render/Settings.aspectRatioConformPolicy: is `cropAperture`",
        "/Render/Product.resolution: a product's own resolution is not read",
    ];
    for e in expect {
        assert_eq!(
            lines.iter().filter(|l| l.contains(e)).count(),
            1,
            "one line with {e:?} in {lines:#?}"
        );
    }
    assert_eq!(lines.len(), expect.len(), "{lines:#?}");
    let all = stderr(&o);
    for quiet in ["NotAHoldout", "Guide", "Pebble"] {
        assert!(!all.contains(quiet), "{quiet} warned: {all}");
    }
    let s = stats_json(&stats);
    let kinds: Vec<&str> = s["stage_warnings"]
        .as_array()
        .unwrap()
        .iter()
        .map(|w| w["kind"].as_str().unwrap())
        .collect();
    assert_eq!(
        kinds,
        [
            "Points holdout",
            "Points holdout",
            "BasisCurves holdout",
            "PointInstancer",
            "pixelAspectRatio",
            "dataWindowNDC",
            "aspectRatioConformPolicy",
            "RenderProduct resolution",
            "Field3DAsset field",
        ]
    );

    let strict_out = dir.path().join("strict.exr");
    let o = render(&stage, &strict_out, &["--strict"]);
    assert_clean_error(&o, "strict");
    for p in [
        "/World/Dust",
        "/World/Hair",
        "/World/Scatter",
        "/World/Cloud",
        "/Render/Product",
    ] {
        assert!(stderr(&o).contains(p), "{p} not named: {}", stderr(&o));
    }
    assert!(!strict_out.exists(), "a refused render wrote its output");
}

/// A material bound to a volume without NimbusVolumeAPI that has no volume output Nimbus
/// reads: the volume falls back to its nimbus:* attributes, with a warning naming the
/// binding; with NimbusVolumeAPI applied the material is not consulted and nothing warns.
#[test]
fn a_bound_material_without_a_volume_output_warns() {
    let dir = tempfile::tempdir().unwrap();
    let material = r#"

    def Material "Paint" {
        token outputs:surface.connect = </World/Paint/Surface.outputs:surface>
        def Shader "Surface" {
            uniform token info:id = "UsdPreviewSurface"
            token outputs:surface
        }
    }

    def DistantLight "Sun""#;
    let bind =
        "rel field:density = </World/Cloud/density>\n        rel material:binding = </World/Paint>";
    let stage = cloud_with(
        dir.path(),
        "bound.usda",
        &[
            ("\n    def DistantLight \"Sun\"", material),
            ("rel field:density = </World/Cloud/density>", bind),
            ("prepend apiSchemas = [\"NimbusVolumeAPI\"]", ""),
        ],
    );
    let o = render(&stage, &dir.path().join("a.exr"), &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(
        warning_lines(&o)
            .iter()
            .filter(|l| l.contains(
                "/World/Cloud.material:binding: the bound material /World/Paint has no volume output"
            ))
            .count(),
        1,
        "{}",
        stderr(&o)
    );
    let with_api = cloud_with(
        dir.path(),
        "api.usda",
        &[
            ("\n    def DistantLight \"Sun\"", material),
            ("rel field:density = </World/Cloud/density>", bind),
        ],
    );
    let o = render(&with_api, &dir.path().join("b.exr"), &["--strict"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(warning_lines(&o), Vec::<String>::new());
}
