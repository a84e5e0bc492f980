//! End-to-end tests of `nimbus info` (a VDB file, a stage) and of bad voxels as counted
//! by `info` and by render statistics.

mod common;

use common::cli::{
    assert_clean_error, channels, nimbus, render_args, root, stage_with_field, stats_json, stderr,
};
use std::process::Command;

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

/// `nimbus info` says whether the stage asks for adaptive sampling and denoising
/// (`nimbus:noiseThreshold`, `nimbus:minSamples`, `nimbus:denoise`), and says "off"
/// for the example cloud, which asks for neither.
#[test]
fn info_states_adaptive_sampling_and_denoising() {
    let info = |stage: &std::path::Path| {
        let o = Command::new(env!("CARGO_BIN_EXE_nimbus"))
            .args(["info", stage.to_str().unwrap()])
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", stderr(&o));
        String::from_utf8_lossy(&o.stdout).to_string()
    };
    let cloud = root().join("scenes/cloud/cloud.usda");
    let plain = info(&cloud);
    assert!(
        plain.contains("  adaptive sampling off; denoise off"),
        "{plain}"
    );
    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(&cloud)
        .unwrap()
        .replace("@./cloud.vdb@", &format!("@{}@", root().join("scenes/cloud/cloud.vdb").display()))
        .replace(
            "int nimbus:samples = 64",
            "int nimbus:samples = 64\n        float nimbus:noiseThreshold = 0.05\n        int nimbus:minSamples = 32\n        bool nimbus:denoise = 1",
        );
    let stage = dir.path().join("adaptive.usda");
    std::fs::write(&stage, text).unwrap();
    let asked = info(&stage);
    assert!(
        asked.contains("  adaptive sampling noise threshold 0.05 min samples 32; denoise on"),
        "{asked}"
    );
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

fn info_json(args: &[&str]) -> serde_json::Value {
    let mut all = vec!["info", "--json"];
    all.extend_from_slice(args);
    let o = nimbus(&all);
    assert!(o.status.success(), "{}", stderr(&o));
    serde_json::from_slice(&o.stdout).expect("info --json prints JSON")
}

/// `nimbus info --json STAGE` is the description the text prints: the same volumes,
/// fields, loaded grids, octree depth, analysis and `auto` choice (one description
/// prints both ways), and `--octree-depth` reaches the octrees and the analysis.
#[test]
fn info_json_is_the_description_the_text_prints() {
    let stage = root().join("scenes/cloud/cloud.usda");
    let stage = stage.to_str().unwrap();
    let j = info_json(&[stage, "--octree-depth", "5"]);
    let o = nimbus(&["info", stage, "--octree-depth", "5"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = String::from_utf8_lossy(&o.stdout);
    assert_eq!(j["kind"], "stage");
    assert_eq!(j["octree_depth"], 5);
    assert_eq!(
        j["render_settings"]["resolution"],
        serde_json::json!([320, 240])
    );
    let v = &j["volumes"][0];
    assert_eq!(v["prim_path"], "/World/Cloud");
    let density = &v["fields"]["density"];
    let loaded = &density["loaded"];
    assert_eq!(loaded["as"], "float");
    assert_eq!(loaded["octree"]["depth"], 5);
    assert!(density["grids"].as_array().is_some_and(|g| !g.is_empty()));
    let active = loaded["active_voxels"].as_u64().unwrap();
    assert!(active > 0);
    let a = &j["analysis"];
    let auto = &j["auto"];
    for needle in [
        format!("loaded 'density': {active} active voxels"),
        format!(
            "majorant octree depth 5: {} levels",
            loaded["octree"]["levels"]
        ),
        format!("analysis: volumes {}, grey {}", a["volumes"], a["grey"]),
        "(depth 5)".to_string(),
        format!(
            "tracker auto: {} scheme {} transmittance {}",
            auto["tracker"].as_str().unwrap(),
            auto["scheme"].as_str().unwrap(),
            auto["transmittance"].as_str().unwrap()
        ),
        auto["reason"].as_str().unwrap().to_string(),
    ] {
        assert!(text.contains(&needle), "text lacks {needle:?}:\n{text}");
    }
    let lights: Vec<&str> = j["lights"]
        .as_array()
        .unwrap()
        .iter()
        .map(|l| l["type"].as_str().unwrap())
        .collect();
    assert_eq!(lights, ["distant", "dome"]);
    assert!(j["warnings"].as_array().is_some());
}

/// `nimbus info --json FILE.vdb`: the grids with their loaded channels (the example
/// cloud: one float grid, 0 < density ≤ 1).
#[test]
fn info_json_describes_a_vdb_file() {
    let vdb = root().join("scenes/cloud/cloud.vdb");
    let j = info_json(&[vdb.to_str().unwrap()]);
    assert_eq!(j["kind"], "vdb");
    let grids = j["grids"].as_array().unwrap();
    assert_eq!(grids.len(), 1);
    assert_eq!(grids[0]["name"], "density");
    assert_eq!(grids[0]["type"], "Tree_float_5_4_3");
    let c = &grids[0]["channels"][0];
    let (lo, hi) = (
        c["value_range"][0].as_f64().unwrap(),
        c["value_range"][1].as_f64().unwrap(),
    );
    assert!(lo > 0.0 && hi <= 1.0 && lo < hi, "range {lo} .. {hi}");
    assert_eq!(c["active_voxels"], grids[0]["active_voxels"]);
}

/// A light's JSON is its prim path, light group, `type` and that type's parameters side
/// by side; a light whose parameters the description does not list yet is `other`.
#[test]
fn a_light_description_is_flat_json_with_its_type() {
    use nimbus::output::describe::{LightDescription, LightParams};
    let rect = LightDescription {
        prim_path: "/Rig/Panel".into(),
        light_group: Some("key".into()),
        params: LightParams::Rect {
            position: [1.0, 2.0, 3.0],
            width: 2.0,
            height: 0.5,
            intensity: 5.0,
            exposure: 0.0,
            color: [1.0; 3],
            normalize: true,
        },
        motion_keys: 0,
    };
    let j = serde_json::to_value(&rect).unwrap();
    assert_eq!(j["type"], "rect");
    assert_eq!(j["light_group"], "key");
    assert_eq!(j["width"], 2.0);
    let other = LightDescription {
        prim_path: "/Rig/New".into(),
        light_group: None,
        params: LightParams::Other,
        motion_keys: 2,
    };
    assert_eq!(
        serde_json::to_value(&other).unwrap(),
        serde_json::json!({"prim_path": "/Rig/New", "light_group": null, "type": "other", "motion_keys": 2})
    );
}

/// `nimbus info` says what `--light-sampling auto` does with the local lights (issue
/// 44), in the text and the JSON: none in the example cloud (a sun and a sky); in its
/// grid, of a spot, a point light and a point light that lights its interior, the
/// spot and, on the chord through its ball, the last (docs/trackers.md: equiangular
/// points towards unshaped lights were measured to lose in grids).
#[test]
fn info_says_which_local_lights_auto_samples_equiangularly() {
    let cloud = root().join("scenes/cloud/cloud.usda");
    let j = info_json(&[cloud.to_str().unwrap()]);
    assert_eq!(
        j["auto"]["light_sampling"],
        "no local lights: next events at the collisions only"
    );
    let dir = tempfile::tempdir().unwrap();
    let stage = dir.path().join("lit.usda");
    std::fs::write(
        &stage,
        format!(
            r#"#usda 1.0
(
    subLayers = [@{}@]
)

over "World"
{{
    def SphereLight "Spot" (
        prepend apiSchemas = ["ShapingAPI"]
    )
    {{
        float inputs:intensity = 100
        float inputs:radius = 0.1
        float inputs:shaping:cone:angle = 20
        double3 xformOp:translate = (0, 3, 0)
        float3 xformOp:rotateXYZ = (-90, 0, 0)
        uniform token[] xformOpOrder = ["xformOp:translate", "xformOp:rotateXYZ"]
    }}

    def SphereLight "Point"
    {{
        float inputs:intensity = 100
        float inputs:radius = 0.1
    }}

    def SphereLight "Bulb"
    {{
        float inputs:intensity = 100
        float inputs:radius = 0.1
        bool nimbus:lightsInterior = 1
    }}
}}
"#,
            cloud.display()
        ),
    )
    .unwrap();
    let stage = stage.to_str().unwrap();
    let j = info_json(&[stage]);
    let summary = j["auto"]["light_sampling"].as_str().unwrap();
    assert!(
        summary.starts_with("equiangular-mis: 2 of 3 local lights sampled equiangularly")
            && summary.contains("heterogeneous medium spots")
            && summary.contains("sphere lights that light their interior"),
        "{summary}"
    );
    let o = nimbus(&["info", stage]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(
        text.contains(&format!("light sampling {summary}")),
        "{text}"
    );
}
