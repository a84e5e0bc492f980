//! Light-group and path-split AOVs (issue 18, part 2): RenderVars whose light path
//! expressions split the beauty by source and by scattering events. The layers of a
//! partition sum to the beauty within float rounding, computing them changes no bit of
//! the beauty, and bad expressions or groups are clear errors naming the RenderVar.

use nimbus::render::analysis::CodePaths;
use nimbus::render::film::{Aov, Film};
use nimbus::render::session::{Overrides, Session};
use nimbus::render::splits::SplitLayer;
use std::path::{Path, PathBuf};

mod common;

use common::cli::{assert_clean_error, channel, channels, nimbus};
use common::repo;

/// A fire (emissive, light group `fire`) lit by a sun and a sphere light (group `key`)
/// and a sky dome (no group: its prim path), with one RenderVar per split in `vars`
/// (name, sourceType, sourceName).
fn stage(dir: &Path, vars: &[(&str, &str, &str)]) -> PathBuf {
    let vdb = repo().join("scenes/fire/fire.vdb");
    let var_defs: String = vars
        .iter()
        .map(|(name, ty, source)| {
            format!(
                "        def RenderVar \"{name}\"\n        {{\n            uniform token sourceType = \"{ty}\"\n            string sourceName = \"{source}\"\n        }}\n"
            )
        })
        .collect();
    let var_rels: Vec<String> = std::iter::once("</Render/Vars/color>".to_string())
        .chain(vars.iter().map(|(n, _, _)| format!("</Render/Vars/{n}>")))
        .collect();
    let text = format!(
        r#"#usda 1.0
(
    defaultPrim = "World"
    renderSettingsPrimPath = "/Render/Settings"
)

def Xform "World"
{{
    def Volume "Fire" (
        prepend apiSchemas = ["NimbusVolumeAPI", "NimbusLightAPI"]
    )
    {{
        rel field:density = </World/Fire/density>
        rel field:temperature = </World/Fire/temperature>
        float nimbus:densityScale = 10
        color3f nimbus:absorption = (0.5, 0.5, 0.5)
        color3f nimbus:scattering = (0.5, 0.5, 0.5)
        float nimbus:anisotropy = 0.3
        token nimbus:temperatureField = "temperature"
        float nimbus:temperatureScale = 1900
        token nimbus:lightGroup = "fire"
        def OpenVDBAsset "density"
        {{
            asset filePath = @{vdb}@
            token fieldName = "density"
        }}
        def OpenVDBAsset "temperature"
        {{
            asset filePath = @{vdb}@
            token fieldName = "temperature"
        }}
    }}
    def Camera "Camera"
    {{
        float focalLength = 50
        float horizontalAperture = 27
        float verticalAperture = 36
        double3 xformOp:translate = (0, 0, 3.4)
        uniform token[] xformOpOrder = ["xformOp:translate"]
    }}
    def DistantLight "Sun" (
        prepend apiSchemas = ["NimbusLightAPI"]
    )
    {{
        float inputs:intensity = 2
        token nimbus:lightGroup = "key"
        double3 xformOp:rotateXYZ = (-40, 30, 0)
        uniform token[] xformOpOrder = ["xformOp:rotateXYZ"]
    }}
    def SphereLight "Bulb"
    {{
        float inputs:intensity = 3
        float inputs:radius = 0.1
        token nimbus:lightGroup = "key"
        double3 xformOp:translate = (0.8, 0.3, 0.5)
        uniform token[] xformOpOrder = ["xformOp:translate"]
    }}
    def DomeLight "Sky"
    {{
        float inputs:intensity = 0.3
        color3f inputs:color = (0.45, 0.6, 0.9)
    }}
}}

def Scope "Render"
{{
    def RenderSettings "Settings"
    {{
        rel camera = </World/Camera>
        uniform int2 resolution = (30, 40)
        rel products = </Render/Product>
    }}
    def RenderProduct "Product"
    {{
        rel orderedVars = [{rels}]
    }}
    def Scope "Vars"
    {{
        def RenderVar "color"
        {{
            string sourceName = "color"
        }}
{var_defs}    }}
}}
"#,
        vdb = vdb.display(),
        rels = var_rels.join(", "),
    );
    let path = dir.join("groups.usda");
    std::fs::write(&path, text).unwrap();
    path
}

const SPLITS: [(&str, &str, &str); 7] = [
    ("emission", "lpe", "C[LO]"),
    ("direct", "lpe", "CV[LO]"),
    ("indirect", "lpe", "lpe:CV.+[LO]"),
    ("key", "lpe", "C.*<L.'key'>"),
    ("sky", "lpe", "C.*<L.'/World/Sky'>"),
    ("fire", "lpe", "C.*<O.'fire'>"),
    ("sun_direct", "raw", "lightgroup:/World/Sun"),
];

/// Largest |Σ parts − beauty| over pixels and channels, relative to the bound of
/// rounding: each channel value is an f64 mean rounded once to f32 (relative error
/// ≤ 2⁻²⁴), so |Σ parts − beauty| ≤ 2⁻²⁴ (|beauty| + Σ |parts|) up to the f64 sums'
/// own error (≈ 1e-16). Returns the worst ratio to that bound: ≤ 1 passes.
fn worst_ratio(chans: &[(String, Vec<f32>)], parts: &[&str]) -> f64 {
    let mut worst: f64 = 0.0;
    for c in ["R", "G", "B"] {
        let beauty = channel(chans, c);
        for (i, &b) in beauty.iter().enumerate() {
            let vals: Vec<f64> = parts
                .iter()
                .map(|p| channel(chans, &format!("{p}.{c}"))[i] as f64)
                .collect();
            let sum: f64 = vals.iter().sum();
            let bound = (b.abs() as f64 + vals.iter().map(|v| v.abs()).sum::<f64>())
                * 2f64.powi(-24)
                + 1e-30;
            worst = worst.max((sum - b as f64).abs() / bound);
        }
    }
    worst
}

#[test]
fn splits_and_light_groups_sum_to_the_beauty() {
    let dir = tempfile::tempdir().unwrap();
    let path = stage(dir.path(), &SPLITS);
    let out = dir.path().join("groups.exr");
    let o = nimbus(&[
        "render",
        path.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--spp",
        "6",
        "--seed",
        "4",
    ]);
    assert!(o.status.success(), "{}", common::cli::stderr(&o));
    let chans = channels(&out);
    let path_splits = worst_ratio(&chans, &["emission", "direct", "indirect"]);
    assert!(
        path_splits <= 1.0,
        "emission + direct + indirect vs beauty: {path_splits}× the rounding bound"
    );
    let groups = worst_ratio(&chans, &["key", "sky", "fire"]);
    assert!(
        groups <= 1.0,
        "key + sky + fire vs beauty: {groups}× the rounding bound"
    );
    // Every layer holds light (the scene has all three kinds of path and source), and
    // a layer short of the partition does not sum to the beauty (the check has power).
    for (name, _, _) in SPLITS {
        let total: f64 = ["R", "G", "B"]
            .iter()
            .flat_map(|c| channel(&chans, &format!("{name}.{c}")).to_vec())
            .map(f64::from)
            .sum();
        assert!(total > 0.0, "layer {name} is black");
    }
    assert!(worst_ratio(&chans, &["key", "sky"]) > 1e3);
    assert!(worst_ratio(&chans, &["direct", "indirect"]) > 1e3);
    // The sun alone is part of the key group.
    let (sun, key) = (channel(&chans, "sun_direct.R"), channel(&chans, "key.R"));
    assert!(sun
        .iter()
        .zip(key)
        .all(|(s, k)| *s <= *k * (1.0 + 1e-6) + 1e-30));
    assert!(sun.iter().zip(key).any(|(s, k)| *s < *k * 0.999));
}

/// Renders `session` with the split layers `layers` (none: the plain job).
fn render(session: &Session, layers: Vec<SplitLayer>) -> Film {
    let extra = session.extra_outputs(layers, false).unwrap();
    let mut job = session.job_with(CodePaths {
        count: true,
        specialise: true,
    });
    extra.apply(&mut job);
    common::render_job(session, &job, None)
}

/// Splitting costs no tracking and changes nothing: the beauty, alpha and every counter
/// AOV are bit-identical with and without split layers, on the grey (single-channel)
/// cloud and the chromatic example.
#[test]
fn splitting_leaves_the_beauty_and_counts_bit_identical() {
    for scene in ["scenes/cloud/cloud.usda", "scenes/chromatic/chromatic.usda"] {
        let o = Overrides {
            spp: Some(3),
            res: Some((24, 18)),
            ..Overrides::default()
        };
        let session = Session::open(&repo().join(scene), &o).unwrap();
        let layers: Vec<SplitLayer> = ["emission", "direct", "indirect"]
            .iter()
            .map(|s| SplitLayer::parse(s, s, "raw").unwrap())
            .collect();
        let plain = render(&session, Vec::new());
        let split = render(&session, layers);
        for aov in Aov::ALL {
            let (a, b) = (plain.channel(aov), split.channel(aov));
            assert!(
                a.iter().zip(&b).all(|(x, y)| x.to_bits() == y.to_bits()),
                "{scene}: {} differs",
                aov.channel_name()
            );
        }
        assert_eq!(split.layer_count, 3);
    }
}

#[test]
fn a_bad_expression_or_group_is_an_error_naming_it() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("x.exr");
    let run = |path: &Path| {
        nimbus(&[
            "render",
            path.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
            "--spp",
            "1",
        ])
    };
    let path = stage(dir.path(), &[("diffuse", "lpe", "C<RD>L")]);
    assert_clean_error(&run(&path), "/Render/Vars/diffuse");
    let path = stage(dir.path(), &[("rim", "lpe", "C.*<L.'rim'>")]);
    assert_clean_error(&run(&path), "light group 'rim' matches no light");
    // Emission of a group of lights only is not emission of a volume of that group.
    let path = stage(dir.path(), &[("k", "lpe", "C.*<O.'key'>")]);
    assert_clean_error(&run(&path), "matches no volume");
    let path = stage(dir.path(), &[]);
    let o = nimbus(&[
        "render",
        path.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--aovs",
        "lightgroup:nobody",
    ]);
    assert_clean_error(&o, "lightgroup_nobody");
    assert!(!out.exists(), "a failed render wrote {}", out.display());
}
