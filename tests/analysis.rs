//! The scene analysis classifies generated scenes correctly, and `--tracker auto`
//! picks what its rules say and reports it.

mod common;

use common::sky;
use glam::{DMat4, DVec3};
use nimbus::render::analysis::{Analysis, Given};
use nimbus::render::camera::CameraRays;
use nimbus::scene::Camera;
use nimbus::track::select::{SchemeKind, TrackerKind, TrackerSettings, TransmittanceKind};
use nimbus::volume::grid::Grid;
use nimbus::volume::majorant::MajorantSpec;
use nimbus::volume::medium::Medium;
use nimbus::volume::procedural::grid_from_fn;
use std::process::Command;

/// A 16³ grid over [-1, 1]³ with density `f`, as a medium with σa, σs per channel.
fn medium(f: impl Fn(DVec3) -> f64 + Sync, sa: [f64; 3], ss: [f64; 3], g: f64) -> Medium {
    let vs = 2.0 / 16.0;
    let raw = grid_from_fn("density", [16; 3], DVec3::splat(-1.0 + 0.5 * vs), vs, f);
    Medium::with_majorants(
        "/Vol",
        Grid::from_raw(&raw).unwrap(),
        DMat4::IDENTITY,
        1.0,
        sa,
        ss,
        g,
        MajorantSpec::Octree { depth: 5 },
    )
    .unwrap()
}

/// A camera at z = 10 looking down −Z (towards the volume), or turned around.
fn camera(away: bool) -> CameraRays {
    let turn = if away {
        DMat4::from_rotation_y(std::f64::consts::PI)
    } else {
        DMat4::IDENTITY
    };
    let cam = Camera {
        prim_path: "/Camera".into(),
        camera_to_world: DMat4::from_translation(DVec3::new(0.0, 0.0, 10.0)) * turn,
        focal_length: 50.0,
        horizontal_aperture: 36.0,
        vertical_aperture: 24.0,
        horizontal_aperture_offset: 0.0,
        vertical_aperture_offset: 0.0,
        clipping_range: (0.1, 1e6),
        projection: Default::default(),
        f_stop: 0.0,
        focus_distance: 0.0,
        shutter: None,
        motion: None,
    };
    CameraRays::new(&cam, 32, 24)
}

#[test]
fn analysis_classifies_generated_scenes() {
    let grey = [0.1; 3];
    let scat = [0.9; 3];
    // A constant cube: homogeneous, grey, isotropic, no empty leaves inside... except
    // the one-voxel rim of the majorant region, where the field falls off.
    let cube = medium(|_| 0.5, grey, scat, 0.0);
    let a = Analysis::of_media(
        std::slice::from_ref(&cube),
        &sky([1.0; 3]),
        &camera(false),
        (32, 24),
    );
    assert!(a.grey && a.homogeneous && a.isotropic && a.volume_visible);
    assert!(!a.emissive && a.constant_albedo);
    assert!((a.max_albedo - 0.9).abs() < 1e-6);
    assert_eq!((a.lights_emitting, a.lights_total), (1, 1));

    // A sphere of density in a corner-empty box, chromatic, anisotropic: not
    // homogeneous, some empty leaves, chromatic.
    let ball = medium(
        |p| if p.length() < 0.6 { 1.0 + p.x } else { 0.0 },
        [0.2, 0.3, 0.6],
        [1.1, 1.2, 1.0],
        0.4,
    );
    let a = Analysis::of_media(
        std::slice::from_ref(&ball),
        &sky([0.0; 3]),
        &camera(false),
        (32, 24),
    );
    assert!(!a.grey && !a.homogeneous && !a.isotropic && a.volume_visible);
    assert!(a.empty_cell_fraction > 0.2, "{}", a.empty_cell_fraction);
    assert_eq!((a.lights_emitting, a.lights_total), (0, 1));

    // The camera turned away sees nothing of it.
    let a = Analysis::of_media(
        std::slice::from_ref(&ball),
        &sky([1.0; 3]),
        &camera(true),
        (32, 24),
    );
    assert!(!a.volume_visible);
}

#[test]
fn auto_follows_its_rules() {
    let cam = camera(false);
    // Heterogeneous (a linear ramp) unless said otherwise.
    let ramp = |p: DVec3| 0.5 + 0.25 * p.x;
    let grey = medium(ramp, [0.1; 3], [0.9; 3], 0.0);
    let a = Analysis::of_media(std::slice::from_ref(&grey), &sky([1.0; 3]), &cam, (32, 24));
    assert!(!a.homogeneous);
    let (t, reason) = a.choose(TrackerSettings::default(), Given::default());
    // Grey: ratio-select with the analog defaults, so it runs single-channel (its
    // fallback is then analog decomposition); the emissive fire is checked through the
    // CLI below.
    assert_eq!(t.tracker, TrackerKind::RatioSelect);
    assert_eq!(t.transmittance, TransmittanceKind::Ratio);
    assert!(!t.options.no_absorption_events);
    assert!(reason.contains("grey"), "{reason}");

    let chroma = medium(ramp, [0.2, 0.3, 0.6], [1.1, 1.2, 1.0], 0.0);
    let a = Analysis::of_media(
        std::slice::from_ref(&chroma),
        &sky([1.0; 3]),
        &cam,
        (32, 24),
    );
    let base = TrackerSettings {
        scheme: SchemeKind::Max,
        ..TrackerSettings::default()
    };
    let (t, reason) = a.choose(base, Given::default());
    assert_eq!(t.tracker, TrackerKind::RatioSelect);
    // Its fallback where volumes overlap: spectral decomposition, hist-avg, no
    // absorption events.
    assert_eq!(t.scheme, SchemeKind::HistAvg);
    assert_eq!(t.transmittance, TransmittanceKind::Ratio);
    assert!(t.options.no_absorption_events);
    assert!(reason.contains("chromatic"));
    // A scheme the user named is kept.
    let named = Given {
        scheme: true,
        transmittance: true,
        majorants: true,
    };
    let (t, _) = a.choose(base, named);
    assert_eq!(t.scheme, SchemeKind::Max);

    // Homogeneous media with no majorant structure named: one global majorant (tight
    // inside), and the tracker of their colour.
    let cube = medium(|_| 0.5, [0.1; 3], [0.9; 3], 0.0);
    let a = Analysis::of_media(std::slice::from_ref(&cube), &sky([1.0; 3]), &cam, (32, 24));
    let (t, reason) = a.choose(TrackerSettings::default(), Given::default());
    assert_eq!(
        (t.tracker, t.transmittance),
        (TrackerKind::Delta, TransmittanceKind::Ratio)
    );
    assert!(reason.contains("global majorant"), "{reason}");
    assert_eq!(
        a.majorants(Given::default()),
        Some(MajorantSpec::Uniform { cell_voxels: 0 })
    );
    // With a structure named: the decomposition family with residual ratio tracking
    // (closed form inside), unless the user named the shadow-ray estimator too.
    let cells = Given::MAJORANTS;
    assert_eq!(a.majorants(cells), None);
    let (t, reason) = a.choose(TrackerSettings::default(), cells);
    assert_eq!(t.tracker, TrackerKind::Decomposition);
    assert_eq!(t.transmittance, TransmittanceKind::ResidualRatio);
    assert!(reason.contains("closed form"), "{reason}");
    let (t, _) = a.choose(TrackerSettings::default(), named);
    assert_eq!(t.transmittance, TransmittanceKind::Ratio);
    let chroma_cube = medium(|_| 0.5, [0.2, 0.3, 0.6], [1.1, 1.2, 1.0], 0.0);
    let a = Analysis::of_media(
        std::slice::from_ref(&chroma_cube),
        &sky([1.0; 3]),
        &cam,
        (32, 24),
    );
    let (t, _) = a.choose(TrackerSettings::default(), cells);
    assert_eq!(t.tracker, TrackerKind::SpectralDecomposition);
    assert_eq!(t.transmittance, TransmittanceKind::ResidualRatio);
    let (t, _) = a.choose(TrackerSettings::default(), Given::default());
    assert_eq!(
        (t.tracker, t.transmittance),
        (TrackerKind::SpectralDecomposition, TransmittanceKind::Ratio)
    );
    assert!(t.options.no_absorption_events);
    // Heterogeneous media keep the structure they were loaded with.
    let a = Analysis::of_media(std::slice::from_ref(&grey), &sky([1.0; 3]), &cam, (32, 24));
    assert_eq!(a.majorants(Given::default()), None);
}

/// The example scenes through the CLI: `auto` (the default) picks ratio-select for
/// all three, single-channel with analog defaults for the grey cloud and the emissive
/// fire and with no absorption events in its fallback for the chromatic medium,
/// and the stats say so and why; a named tracker is used as named, with no reason.
#[test]
fn auto_is_the_default_and_is_reported() {
    let dir = tempfile::tempdir().unwrap();
    let run = |scene: &str, extra: &[&str]| -> serde_json::Value {
        let stage = format!("{}/scenes/{scene}/{scene}.usda", env!("CARGO_MANIFEST_DIR"));
        let stats = dir.path().join(format!("{scene}.json"));
        let out = Command::new(env!("CARGO_BIN_EXE_nimbus"))
            .args(["render", &stage, "--res", "8x6", "--spp", "1", "-o"])
            .arg(dir.path().join(format!("{scene}.exr")))
            .arg("--stats")
            .arg(&stats)
            .args(extra)
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        serde_json::from_str(&std::fs::read_to_string(&stats).unwrap()).unwrap()
    };
    let cloud = run("cloud", &[]);
    assert_eq!(cloud["tracker"], "ratio-select");
    assert_eq!(cloud["no_absorption_events"], false);
    // The grey cloud runs the single-channel trackers unless told not to; the stats
    // need the counts, so counting is on.
    assert_eq!(cloud["code_paths"]["grey_tracking"], true);
    assert_eq!(cloud["code_paths"]["counting"], true);
    let general = run("cloud", &["--no-specialise"]);
    assert_eq!(general["code_paths"]["grey_tracking"], false);
    assert_eq!(cloud["analysis"]["grey"], true);
    assert!(cloud["tracker_auto_reason"]
        .as_str()
        .unwrap()
        .contains("grey"));
    // A sun and a sky: nothing for equiangular sampling (tests/cli_info.rs has a stage
    // with local lights).
    assert_eq!(
        cloud["light_sampling"],
        "no local lights: next events at the collisions only"
    );
    let fire = run("fire", &[]);
    assert_eq!(fire["tracker"], "ratio-select");
    assert_eq!(fire["no_absorption_events"], false);
    assert_eq!(fire["code_paths"]["grey_tracking"], true);
    let chromatic = run("chromatic", &[]);
    assert_eq!(chromatic["tracker"], "ratio-select");
    assert_eq!(chromatic["scheme"], "hist-avg");
    assert_eq!(chromatic["no_absorption_events"], true);
    assert_eq!(chromatic["analysis"]["grey"], false);
    assert_eq!(chromatic["code_paths"]["grey_tracking"], false);
    // A chromatic copy of the fire: ratio-select, with the absorption events that
    // collect emission left on in its fallback.
    let fire_dir = format!("{}/scenes/fire", env!("CARGO_MANIFEST_DIR"));
    let text = std::fs::read_to_string(format!("{fire_dir}/fire.usda"))
        .unwrap()
        .replace("@./fire.vdb@", &format!("@{fire_dir}/fire.vdb@"))
        .replace(
            "color3f nimbus:absorption = (0.5, 0.5, 0.5)",
            "color3f nimbus:absorption = (0.3, 0.5, 0.8)",
        );
    assert!(text.contains("(0.3, 0.5, 0.8)"));
    let chroma_fire = dir.path().join("chroma_fire.usda");
    std::fs::write(&chroma_fire, text).unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_nimbus"))
        .arg("info")
        .arg(&chroma_fire)
        .output()
        .unwrap();
    let info = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(
        info.contains("grey false, emissive true")
            && info.contains("tracker auto: ratio-select")
            && info.contains("absorption events collect the emission"),
        "{info}"
    );
    let named = run("chromatic", &["--tracker", "delta"]);
    assert_eq!(named["tracker"], "delta");
    assert!(named["tracker_auto_reason"].is_null());
    assert_eq!(named["no_absorption_events"], false);
}
