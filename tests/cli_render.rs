//! End-to-end tests of `nimbus render`: the shipped scenes with RGBA and lookup AOVs,
//! several volumes, tracker settings from the stage and the flags, time limits,
//! interrupted renders, and the outputs' permissions.

mod common;

use common::cli::{
    assert_clean_error, channel, channels, nimbus, render_args, root, stats_json, stderr,
};
use std::path::Path;
use std::process::Command;

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
    assert_eq!(j["code_paths"]["grey_tracking"], true);
    let j = render("octree.usda", "int nimbus:octreeDepth = 5");
    assert_eq!(
        (j["tracker"].as_str(), j["transmittance"].as_str()),
        (Some("decomposition"), Some("residual-ratio"))
    );
    assert_eq!(j["octree_depth"], 5);
    assert_eq!(j["code_paths"]["grey_tracking"], true);
    let j = render(
        "named.usda",
        "int nimbus:octreeDepth = 5\n        token nimbus:transmittance = \"ratio\"",
    );
    assert_eq!(
        (j["tracker"].as_str(), j["transmittance"].as_str()),
        (Some("decomposition"), Some("ratio"))
    );
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
