//! Volume emission (issue 8): the integrator against closed-form answers for every
//! tracker, the blackbody mapping, loading from stages (bad input included) and the
//! EmberGen fire from ../shared/data.

mod common;

use common::{mean_se, paths, Setup};
use glam::{DMat4, DVec3};
use nimbus::color::usd_blackbody_rgb;
use nimbus::render::analysis::{CodePaths, Given};
use nimbus::render::lights::Lights;
use nimbus::track::free_path::{FreePathSampler, TransmittanceEstimator};
use nimbus::track::select::{SchemeKind, TrackerKind, TrackerSettings, TransmittanceKind};
use nimbus::volume::counters::Counters;
use nimbus::volume::emission::{
    blackbody_radiance, Emission, EmissionGrid, EmissionKind, EmissionParams,
};
use nimbus::volume::grid::{Grid, RawGrid};
use nimbus::volume::medium::Medium;
use nimbus::volume::procedural::grid_from_fn;
use std::path::{Path, PathBuf};
use std::process::Command;

// ----- analytic media ----------------------------------------------------------------------

/// A constant grid `value` over [−0.8125, 0.8125]³ (14³ voxels of 1/8, another transform
/// than the density's): its reconstruction is exactly `value` wherever the cube's
/// density is non-zero, so the emission is constant over the medium.
fn constant_grid(name: &str, value: f64) -> Grid {
    let raw = grid_from_fn(name, [14, 14, 14], DVec3::splat(-0.8125), 0.125, |_| value);
    Grid::from_raw(&raw).unwrap()
}

fn emission_grid(name: &str, value: f64) -> EmissionGrid {
    EmissionGrid::new("/Cube", name, constant_grid(name, value), DMat4::IDENTITY).unwrap()
}

/// Temperature 1500 grid units × 2 K/unit = 3000 K at blackbody intensity 0.01, plus an
/// emission field of 0.5 × colour (0.2, 0.4, 0.8) × scale 2.
fn both_sources() -> (Emission, [f64; 3]) {
    let params = EmissionParams {
        temperature_scale: 2.0,
        blackbody_intensity: 0.01,
        emission_color: [0.2, 0.4, 0.8],
        emission_scale: 2.0,
        ..Default::default()
    };
    let e = Emission::new(
        "/Cube",
        Some(emission_grid("temperature", 1500.0)),
        Some(emission_grid("flames", 0.5)),
        params,
        None,
    )
    .unwrap()
    .unwrap();
    let bb = usd_blackbody_rgb(3000.0);
    let le = [0, 1, 2].map(|c| 0.01 * 81.0 * bb[c] + 0.5 * 2.0 * params.emission_color[c]);
    (e, le)
}

/// Every free-path sampler: each tracker, each scheme where it matters (ratio shadows;
/// these media never scatter or use the shadow estimator where noted).
fn trackers() -> Vec<TrackerSettings> {
    common::all_settings(1.0)
        .into_iter()
        .filter(|s| s.transmittance == TransmittanceKind::Ratio)
        .collect()
}

fn name(s: &TrackerSettings) -> String {
    if s.tracker.uses_scheme() {
        format!("{}/{}", s.tracker.name(), s.scheme.name())
    } else {
        s.tracker.name().to_string()
    }
}

/// z-scores per channel of the mean of `n` paths through the image centre against
/// `expected` (standard error from the sample variance).
fn z_scores(setup: &Setup, s: &TrackerSettings, n: usize, expected: [f64; 3]) -> [f64; 3] {
    let p = paths(setup, s, 4.5, 4.5, n);
    let lookups: u64 = p.iter().map(|(_, c)| c.emission_lookups).sum();
    assert!(lookups > 0, "{}: no emission lookup", name(s));
    z_of(&p, expected)
}

/// z-scores per channel of the mean of the paths `p` against `expected`.
fn z_of(p: &[([f64; 3], Counters)], expected: [f64; 3]) -> [f64; 3] {
    [0, 1, 2].map(|c| {
        let v: Vec<f64> = p.iter().map(|(rgb, _)| rgb[c]).collect();
        let (m, se) = mean_se(&v);
        // A channel can have no variance at all: in the equilibrium test below, G has
        // grey extinction and analog weights, so every path returns exactly E_G (at
        // absorption, Le = E; on escape, E) up to the f32 rounding of its weights
        // (2^-24 relative per factor, a few dozen factors). The floor of 1e-6 × E
        // stands for that rounding, not for noise.
        (m - expected[c]) / se.max(1e-6 * expected[c].abs()).max(1e-12)
    })
}

/// A purely absorbing cube (σs = 0) with constant emission Le in a constant
/// environment E, seen along its axis (length 1, optical depth σa):
/// L = E·e^{−σa} + Le·(1 − e^{−σa}) per channel. Grey σa = 1 and chromatic
/// σa = (0.5, 1, 2) (which exercises delta tracking's absorption weight σa(λ)/avg σa).
/// Estimator: one path per sample (emission collected at absorption events), every
/// tracker and scheme, N = 40,000 paths each through the centre pixel, seed 5;
/// |z| < 4 per channel with the standard error from the sample variance (a family of
/// 2 × 13 × 3 tests: a false alarm has probability ≈ 5e-3 for a correct estimator).
#[test]
fn absorbing_emitting_cube_matches_closed_form() {
    let env = [0.3, 0.2, 0.1];
    let lights = Lights {
        environment: env,
        ..Default::default()
    };
    let cam = common::camera_on_z(10.0, 1000.0, 10.0, 9, 9);
    for sigma_a in [[1.0; 3], [0.5, 1.0, 2.0]] {
        let mut m = common::unit_cube(1.0, sigma_a, [0.0; 3], 0.0);
        let (e, le) = both_sources();
        m.set_emission(Some(e));
        let expected =
            [0, 1, 2].map(|c| env[c] * (-sigma_a[c]).exp() + le[c] * (1.0 - (-sigma_a[c]).exp()));
        let setup = Setup {
            medium: &m,
            lights: &lights,
            camera: &cam,
            width: 9,
            height: 9,
            spp: 1,
            max_depth: 64,
            seed: 5,
        };
        for s in trackers() {
            let z = z_scores(&setup, &s, 40_000, expected);
            eprintln!("σa {sigma_a:?} {}: z {z:.2?}", name(&s));
            assert!(
                z.iter().all(|z| z.abs() < 4.0),
                "σa {sigma_a:?} {}: z = {z:?} (expected {expected:?})",
                name(&s)
            );
        }
    }
}

/// ∫T·S dz along the axis of the 16³-voxel cube of density `mu_a` (per unit length)
/// for a constant source `s` where μa > 0: trilinear reconstruction makes μa = `mu_a`
/// between the outer voxels' centres, [−0.5 + h/2, 0.5 − h/2], ramping linearly to 0
/// at the empty neighbours' centres, ±(0.5 + h/2) (voxel size h). The optical depth
/// is `mu_a` as for a box of length 1, but S emits over 1 + h. Trapezoidal rule with
/// 10⁶ steps (error far below 1e-9 of the result).
fn source_through_ramped_cube(s: f64, mu_a: f64, h: f64) -> f64 {
    let n = 1_000_000;
    let (z0, z1) = (-0.5 - h / 2.0, 0.5 + h / 2.0);
    let dz = (z1 - z0) / n as f64;
    let mu = |z: f64| mu_a * ((0.5 + h / 2.0 - z.abs()) / h).clamp(0.0, 1.0);
    let (mut tau, mut sum, mut t_prev) = (0.0, 0.0, 1.0);
    for i in 0..n {
        let za = z0 + i as f64 * dz;
        tau += 0.5 * (mu(za) + mu(za + dz)) * dz;
        let t = (-tau).exp();
        sum += 0.5 * (t_prev + t) * dz;
        t_prev = t;
    }
    s * sum
}

/// `nimbus:emissionKind = "source"`: the emission model gives the source term S per
/// unit length (Cycles' Principled Volume emission), independent of density. A purely
/// absorbing cube of constant density d = 0.3 (not 1, where the two kinds would agree
/// up to σa) and σa = (1, 2, 4) per unit density, so μa = (0.3, 0.6, 1.2), in a constant
/// environment E, seen along its axis (length 1):
/// L = E·e^{−μa} + ∫T·S per channel, ∫T·S through the density's reconstruction
/// ([`source_through_ramped_cube`]: ≈ S·(1 − e^{−μa})/μa, 1.0 to 1.05 × that with the
/// half-voxel ramps, which a test of the plain box formula measured at 7–12 standard
/// errors: the test sees where μa > 0), against the radiance kind's
/// E·e^{−μa} + Le·(1 − e^{−μa}) for the same numbers (which differ by 1/μa =
/// 3.3, 1.7, 0.83: the test can tell the kinds apart). Two sources: the constant field
/// (no emission grid; S = scale·colour = (0.4, 0.8, 1.6)) and both grids of
/// [`both_sources`] (temperature and field). Estimator: one path per sample, S/μa(λ, x)
/// collected at absorption events (one extra density lookup each), every tracker and
/// scheme, N = 40,000 paths each through the centre pixel, seed 5; |z| < 4 per channel
/// with the standard error from the sample variance (2 × 13 × 3 tests: a false alarm
/// has probability ≈ 5e-3 for a correct estimator).
#[test]
fn source_emission_of_a_thin_cube_matches_closed_form() {
    let env = [0.3, 0.2, 0.1];
    let lights = Lights {
        environment: env,
        ..Default::default()
    };
    let cam = common::camera_on_z(10.0, 1000.0, 10.0, 9, 9);
    let (d, sigma_a) = (0.3, [1.0, 2.0, 4.0]);
    let n = 16;
    let vs = 1.0 / n as f64;
    let density = grid_from_fn(
        "density",
        [n, n, n],
        DVec3::splat(-0.5 + 0.5 * vs),
        vs,
        |_| d,
    );
    let mut m = Medium::new(
        "/Cube",
        Grid::from_raw(&density).unwrap(),
        DMat4::IDENTITY,
        1.0,
        sigma_a,
        [0.0; 3],
        0.0,
        8,
    )
    .unwrap();
    let constant = EmissionParams {
        emission_color: [0.2, 0.4, 0.8],
        emission_scale: 2.0,
        kind: EmissionKind::Source,
        ..Default::default()
    };
    let (_, both) = both_sources();
    let both_params = EmissionParams {
        kind: EmissionKind::Source,
        ..both_sources().0.params
    };
    let cases = [
        (
            "constant field",
            Emission::new("/Cube", None, None, constant, None).unwrap(),
            [0.4, 0.8, 1.6],
        ),
        (
            "temperature and field grids",
            Emission::new(
                "/Cube",
                Some(emission_grid("temperature", 1500.0)),
                Some(emission_grid("flames", 0.5)),
                both_params,
                None,
            )
            .unwrap(),
            both,
        ),
    ];
    for (what, e, source) in cases {
        m.set_emission(e);
        let mu_a = sigma_a.map(|s| d * s);
        let expected = [0, 1, 2].map(|c| {
            env[c] * (-mu_a[c]).exp() + source_through_ramped_cube(source[c], mu_a[c], vs)
        });
        let setup = Setup {
            medium: &m,
            lights: &lights,
            camera: &cam,
            width: 9,
            height: 9,
            spp: 1,
            max_depth: 64,
            seed: 5,
        };
        for s in trackers() {
            // (The constant field looks no emission grid up: no lookup count to check.)
            let p = paths(&setup, &s, 4.5, 4.5, 40_000);
            let z = z_of(&p, expected);
            eprintln!("source, {what} {}: z {z:.2?}", name(&s));
            assert!(
                z.iter().all(|z| z.abs() < 4.0),
                "source, {what} {}: z = {z:?} (expected {expected:?})",
                name(&s)
            );
        }
    }
}

/// Kirchhoff's law: a medium that emits Le = E inside a constant environment E is in
/// equilibrium, L = E everywhere, whatever σa, σs and g (L = E solves the transfer
/// equation: −μt·E + μa·E + μs·E = 0). Exercises emission at absorption events after
/// any number of scatterings, with NEE and MIS. Chromatic σa = (0.5, 1, 1.5), σs =
/// (1.5, 1, 0.5), g = 0.3; depth 10,000 with Russian roulette (bias far below the
/// noise). Every tracker and scheme, N = 20,000 paths each, seed 5; |z| < 4 per channel.
#[test]
fn emitting_cube_in_matching_environment_is_invisible() {
    let env = [0.8, 1.0, 1.3];
    let lights = Lights {
        environment: env,
        ..Default::default()
    };
    let cam = common::camera_on_z(10.0, 1000.0, 10.0, 9, 9);
    let mut m = common::unit_cube(1.0, [0.5, 1.0, 1.5], [1.5, 1.0, 0.5], 0.3);
    let e = Emission::new(
        "/Cube",
        None,
        Some(emission_grid("flames", 2.0)),
        EmissionParams {
            emission_color: env,
            emission_scale: 0.5,
            ..Default::default()
        },
        None,
    )
    .unwrap();
    m.set_emission(e);
    let setup = Setup {
        medium: &m,
        lights: &lights,
        camera: &cam,
        width: 9,
        height: 9,
        spp: 1,
        max_depth: 10_000,
        seed: 5,
    };
    for s in trackers() {
        let z = z_scores(&setup, &s, 20_000, env);
        eprintln!("{}: z {z:.2?}", name(&s));
        assert!(z.iter().all(|z| z.abs() < 4.0), "{}: z = {z:?}", name(&s));
    }
}

/// Without emission the medium has no emission lookups at all; with it, lookups happen
/// only at absorption events (one per configured grid), never in the free-path loops,
/// and density lookups do not count them.
#[test]
fn emission_lookups_only_at_absorption_events() {
    let lights = Lights::default();
    let cam = common::camera_on_z(10.0, 1000.0, 10.0, 9, 9);
    let s = TrackerSettings::default();
    let mut m = common::unit_cube(1.0, [1.0; 3], [0.0; 3], 0.0);
    let run = |m: &Medium| {
        let setup = Setup {
            medium: m,
            lights: &lights,
            camera: &cam,
            width: 9,
            height: 9,
            spp: 1,
            max_depth: 64,
            seed: 3,
        };
        paths(&setup, &s, 4.5, 4.5, 2_000)
    };
    let plain = run(&m);
    assert!(plain.iter().all(|(_, c)| c.emission_lookups == 0));
    let (e, _) = both_sources();
    m.set_emission(Some(e));
    let lit = run(&m);
    for ((_, a), (rgb, b)) in plain.iter().zip(&lit) {
        // Same random stream, same collisions: emission consumes no random numbers.
        assert_eq!(a.density_lookups, b.density_lookups);
        assert_eq!(a.real_collisions, b.real_collisions);
        // σs = 0: every real collision is an absorption, two grids each.
        assert_eq!(b.emission_lookups, 2 * b.real_collisions);
        assert_eq!(rgb.iter().any(|&v| v > 0.0), b.real_collisions > 0);
    }
}

// ----- the blackbody mapping ------------------------------------------------------------------

/// Le_bb = I·(T/1000 K)⁴·rgb(T) with rgb(T) = UsdLux's colour (pxr's table; compared
/// with pxr itself in tests/lights.rs and tests/usd_loading.rs), whose Rec. 709
/// luminance is 1: the luminance of Le_bb is I·(T/1000 K)⁴ (Stefan–Boltzmann's shape).
/// T ≤ 0 (and NaN) emits nothing.
#[test]
fn blackbody_radiance_is_t4_times_usdlux_colour() {
    for &(t, i) in &[
        (1000.0, 1.0),
        (1500.0, 2.0),
        (3000.0, 0.25),
        (6500.0, 1.0),
        (12000.0, 0.5),
    ] {
        let got = blackbody_radiance(t, i);
        let rgb = usd_blackbody_rgb(t);
        let s = i * (t / 1000.0f64).powi(4);
        for c in 0..3 {
            assert!((got[c] - s * rgb[c]).abs() <= 1e-12 * s, "{t} K: {got:?}");
        }
        let y = 0.2126 * got[0] + 0.7152 * got[1] + 0.0722 * got[2];
        assert!(
            (y - s).abs() <= 1e-9 * s,
            "{t} K: luminance {y}, expected {s}"
        );
    }
    assert_eq!(blackbody_radiance(1000.0, 1.0), usd_blackbody_rgb(1000.0));
    for t in [0.0, -300.0, f64::NAN] {
        assert_eq!(blackbody_radiance(t, 1.0), [0.0; 3], "{t}");
    }
}

/// `Emission::radiance` at a point: the temperature grid × temperatureScale through the
/// blackbody, plus the emission field × colour × scale; one lookup per grid.
#[test]
fn emission_radiance_combines_both_sources() {
    let (e, le) = both_sources();
    let mut c = Counters::default();
    let got = e.radiance(DVec3::new(0.1, -0.2, 0.3), &mut c);
    for ch in 0..3 {
        assert!(
            (got[ch] - le[ch]).abs() <= 1e-6 * le[ch],
            "{got:?} vs {le:?}"
        );
    }
    assert_eq!((c.emission_lookups, c.density_lookups), (2, 0));
    // Outside the grids: nothing.
    assert_eq!(e.radiance(DVec3::splat(5.0), &mut c), [0.0; 3]);
    // A temperature-only source with a temperature scale.
    let t = Emission::new(
        "/Cube",
        Some(emission_grid("temperature", 0.5)),
        None,
        EmissionParams {
            temperature_scale: 4000.0,
            blackbody_intensity: 3.0,
            ..Default::default()
        },
        None,
    )
    .unwrap()
    .unwrap();
    let got = t.radiance(DVec3::ZERO, &mut c);
    let want = blackbody_radiance(2000.0, 3.0);
    for ch in 0..3 {
        assert!(
            (got[ch] - want[ch]).abs() <= 1e-6 * want[0],
            "{got:?} vs {want:?}"
        );
    }
}

/// Negative or non-finite parameters are errors naming the prim and the attribute.
#[test]
fn bad_emission_parameters_are_errors() {
    let cases: [(&str, EmissionParams); 5] = [
        (
            "nimbus:temperatureScale",
            EmissionParams {
                temperature_scale: -1.0,
                ..Default::default()
            },
        ),
        (
            "nimbus:blackbodyIntensity",
            EmissionParams {
                blackbody_intensity: f64::NAN,
                ..Default::default()
            },
        ),
        (
            "nimbus:emissionScale",
            EmissionParams {
                emission_scale: f64::INFINITY,
                ..Default::default()
            },
        ),
        (
            "nimbus:emissionScale",
            EmissionParams {
                emission_scale: -0.5,
                ..Default::default()
            },
        ),
        (
            "nimbus:emissionColor",
            EmissionParams {
                emission_color: [1.0, -1.0, 1.0],
                ..Default::default()
            },
        ),
    ];
    for (attr, p) in cases {
        let e = Emission::new("/Fire", None, Some(emission_grid("flames", 1.0)), p, None)
            .err()
            .unwrap_or_else(|| panic!("{attr}: accepted"))
            .to_string();
        assert!(e.contains("/Fire") && e.contains(attr), "{e}");
    }
    // No grid at all: no emission.
    assert!(
        Emission::new("/Fire", None, None, EmissionParams::default(), None)
            .unwrap()
            .is_none()
    );
}

// ----- stages ------------------------------------------------------------------------------------

use nimbus::render::job::media_for_scene_with;
use nimbus::scene::{load_stage, LoadOptions};
use nimbus::volume::majorant::MajorantSpec;

fn write_vdb(path: &Path, grids: &[RawGrid]) {
    nimbus::volume::vdb::write_float_grids(path, grids).expect("write vdb");
}

/// A stage with a volume `/V` whose fields `density`, `temperature` and `flames` are the
/// grids of one file `grids.vdb`; `attrs` go on the volume.
fn fire_stage(dir: &Path, attrs: &str) -> PathBuf {
    common::grids_stage(dir, "fire", &["density", "temperature", "flames"], attrs)
}

fn cube_grids() -> Vec<RawGrid> {
    let n = 16;
    let vs = 1.0 / n as f64;
    let o = DVec3::splat(-0.5 + 0.5 * vs);
    vec![
        grid_from_fn("density", [n, n, n], o, vs, |_| 1.0),
        grid_from_fn(
            "temperature",
            [14, 14, 14],
            DVec3::splat(-0.8125),
            0.125,
            |_| 1.5,
        ),
        grid_from_fn("flames", [14, 14, 14], DVec3::splat(-0.8125), 0.125, |_| {
            0.5
        }),
    ]
}

/// A stage's emission attributes reach the medium: the loaded medium radiates what the
/// attributes say (files written by Nimbus' VDB writer, read back by the reader).
#[test]
fn stage_emission_reaches_the_medium() {
    let dir = tempfile::tempdir().unwrap();
    write_vdb(&dir.path().join("grids.vdb"), &cube_grids());
    let stage = fire_stage(
        dir.path(),
        r#"    token nimbus:temperatureField = "temperature"
    float nimbus:temperatureScale = 2000
    float nimbus:blackbodyIntensity = 0.1
    token nimbus:emissionField = "flames"
    color3f nimbus:emissionColor = (0.25, 0.5, 1)
    float nimbus:emissionScale = 4"#,
    );
    let scene = load_stage(&stage, &LoadOptions::default()).unwrap();
    let v = &scene.volumes[0];
    assert_eq!(v.emission.temperature.as_ref().unwrap().0, "temperature");
    assert_eq!(v.emission.emission.as_ref().unwrap().0, "flames");
    assert_eq!(v.emission.emission_color, [0.25, 0.5, 1.0]);
    let m = media_for_scene_with(&scene, MajorantSpec::Uniform { cell_voxels: 8 })
        .unwrap()
        .remove(0);
    let e = m.emission.as_ref().expect("emissive");
    let got = e.radiance(DVec3::ZERO, &mut Counters::default());
    let bb = blackbody_radiance(3000.0, 0.1);
    let want = [0, 1, 2].map(|c| bb[c] + [0.25, 0.5, 1.0][c] * 4.0 * 0.5);
    for c in 0..3 {
        assert!(
            (got[c] - want[c]).abs() <= 1e-5 * want[c],
            "{got:?} vs {want:?}"
        );
    }
    // Without the attributes, the same stage does not emit (and no grid is loaded).
    let plain = fire_stage(dir.path(), "");
    let scene = load_stage(&plain, &LoadOptions::default()).unwrap();
    assert!(!scene.volumes[0].emission.is_emissive());
    assert!(
        media_for_scene_with(&scene, MajorantSpec::Uniform { cell_voxels: 8 })
            .unwrap()
            .remove(0)
            .emission
            .is_none()
    );
}

/// `nimbus:emissionKind`: "source" without an emission field is emissive with the
/// constant field (S = scale·colour wherever the medium is), the fallback is "radiance",
/// and another token is an error naming the prim, the attribute and the value.
#[test]
fn stage_emission_kind_is_read() {
    let dir = tempfile::tempdir().unwrap();
    write_vdb(&dir.path().join("grids.vdb"), &cube_grids());
    let stage = fire_stage(
        dir.path(),
        r#"    uniform token nimbus:emissionKind = "source"
    color3f nimbus:emissionColor = (0.25, 0.5, 1)
    float nimbus:emissionScale = 4"#,
    );
    let scene = load_stage(&stage, &LoadOptions::default()).unwrap();
    let v = &scene.volumes[0];
    assert_eq!(v.emission.kind, EmissionKind::Source);
    assert!(v.emission.is_emissive());
    let m = media_for_scene_with(&scene, MajorantSpec::Uniform { cell_voxels: 8 })
        .unwrap()
        .remove(0);
    let e = m.emission.as_ref().expect("emissive");
    assert_eq!(e.params.kind, EmissionKind::Source);
    let mut c = Counters::default();
    let got = e.radiance(DVec3::ZERO, &mut c);
    assert_eq!(got, [1.0, 2.0, 4.0]);
    assert_eq!(c.emission_lookups, 0, "the constant field looks nothing up");
    let plain = fire_stage(dir.path(), "");
    let scene = load_stage(&plain, &LoadOptions::default()).unwrap();
    assert_eq!(scene.volumes[0].emission.kind, EmissionKind::Radiance);
    let bad = fire_stage(
        dir.path(),
        r#"    uniform token nimbus:emissionKind = "glow""#,
    );
    let err = format!(
        "{:#}",
        load_stage(&bad, &LoadOptions::default()).unwrap_err()
    );
    for want in ["/V", "nimbus:emissionKind", "glow"] {
        assert!(err.contains(want), "{want} missing from: {err}");
    }
}

/// A field name with no relationship: the error names the prim, the attribute and the
/// missing relationship, and lists the volume's fields.
#[test]
fn missing_emission_field_lists_the_fields() {
    let dir = tempfile::tempdir().unwrap();
    write_vdb(&dir.path().join("grids.vdb"), &cube_grids());
    for attr in ["nimbus:emissionField", "nimbus:temperatureField"] {
        let stage = fire_stage(dir.path(), &format!("    token {attr} = \"heat\""));
        let msg = common::load_message(&stage);
        assert_mentions(
            &msg,
            &[
                "/V",
                attr,
                "field:heat",
                "field:density, field:flames, field:temperature",
            ],
        );
    }
}

/// A grid the file does not hold is an error naming the volume, the attribute, the field
/// prim and the grids the file has.
#[test]
fn emission_grid_missing_from_file() {
    let dir = tempfile::tempdir().unwrap();
    let mut grids = cube_grids();
    grids.truncate(2); // no flames grid
    write_vdb(&dir.path().join("grids.vdb"), &grids);
    let stage = fire_stage(dir.path(), "    token nimbus:emissionField = \"flames\"");
    let msg = common::load_message(&stage);
    assert_mentions(
        &msg,
        &[
            "/V",
            "nimbus:emissionField",
            "/V/flames",
            "\"density\", \"temperature\"",
        ],
    );
}

/// An emission field that is not a float grid (a Vec3s grid) is an error naming the
/// volume, the attribute and the grid's type.
#[test]
fn non_float_emission_grid_is_an_error() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("grids.vdb");
    write_vdb(&path, &cube_grids());
    // Same-length type name for the third grid (flames), so the file stays consistent.
    let mut bytes = std::fs::read(&path).unwrap();
    let at: Vec<usize> = bytes
        .windows(16)
        .enumerate()
        .filter(|(_, w)| *w == b"Tree_float_5_4_3")
        .map(|(i, _)| i)
        .collect();
    assert_eq!(at.len(), 3, "one type name per grid");
    bytes[at[2]..at[2] + 16].copy_from_slice(b"Tree_vec3s_5_4_3");
    std::fs::write(&path, &bytes).unwrap();
    let stage = fire_stage(dir.path(), "    token nimbus:emissionField = \"flames\"");
    let msg = common::load_message(&stage);
    assert_mentions(
        &msg,
        &[
            "/V",
            "nimbus:emissionField",
            "flames",
            "Vec3s, expected float",
        ],
    );
}

/// Negative scales authored on the stage are errors naming the prim and the attribute.
#[test]
fn bad_scale_on_stage_is_an_error() {
    let dir = tempfile::tempdir().unwrap();
    write_vdb(&dir.path().join("grids.vdb"), &cube_grids());
    for (attr, line) in [
        ("nimbus:emissionScale", "float nimbus:emissionScale = -2"),
        (
            "nimbus:temperatureScale",
            "float nimbus:temperatureScale = -300",
        ),
        (
            "nimbus:blackbodyIntensity",
            "float nimbus:blackbodyIntensity = -1",
        ),
    ] {
        let stage = fire_stage(
            dir.path(),
            &format!(
                "    token nimbus:emissionField = \"flames\"\n    token nimbus:temperatureField = \"temperature\"\n    {line}"
            ),
        );
        let msg = common::load_message(&stage);
        assert!(
            msg.contains("/V") && msg.contains(attr) && msg.contains("non-negative"),
            "{msg}"
        );
    }
}

/// `--no-absorption-events` on an emissive medium is refused (emission is collected at
/// absorption events); the same render without the flag works and emits.
#[test]
fn no_absorption_events_refused_for_emissive_media() {
    let dir = tempfile::tempdir().unwrap();
    write_vdb(&dir.path().join("grids.vdb"), &cube_grids());
    let stage = fire_stage(dir.path(), "    token nimbus:emissionField = \"flames\"");
    let out = dir.path().join("out.exr");
    let run = |extra: &[&str]| {
        let mut args = vec![
            "render".to_string(),
            stage.display().to_string(),
            "-o".into(),
            out.display().to_string(),
            "--res".into(),
            "8x8".into(),
            "--spp".into(),
            "4".into(),
        ];
        args.extend(extra.iter().map(|s| s.to_string()));
        Command::new(env!("CARGO_BIN_EXE_nimbus"))
            .args(&args)
            .output()
            .unwrap()
    };
    let o = run(&["--tracker", "spectral", "--no-absorption-events"]);
    let e = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{e}");
    assert!(!e.contains("panicked"), "{e}");
    assert!(
        e.contains("--no-absorption-events") && e.contains("/V") && e.contains("emits"),
        "{e}"
    );
    let o = run(&["--tracker", "spectral"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let (_, _, chans) = nimbus::output::exr::read_channels(&out).unwrap();
    let r = &chans.iter().find(|c| c.0 == "R").unwrap().1;
    assert!(r.iter().any(|&v| v > 0.0), "no emission in the render");
    // `nimbus bench error` refuses the option too, before rendering anything.
    let o = Command::new(env!("CARGO_BIN_EXE_nimbus"))
        .args(["bench", "error"])
        .arg(&stage)
        .args(["--trackers", "delta,spectral:hist-avg:no-absorption-events"])
        .args([
            "--res",
            "4x4",
            "--budgets",
            "0.1",
            "--seeds",
            "1",
            "--cache-dir",
        ])
        .arg(dir.path().join("cache"))
        .output()
        .unwrap();
    let e = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{e}");
    assert!(
        e.contains("no-absorption-events") && e.contains("/V"),
        "{e}"
    );
}

/// `nimbus info` prints the emission configuration and the analysis says emissive.
#[test]
fn info_prints_emission() {
    let dir = tempfile::tempdir().unwrap();
    write_vdb(&dir.path().join("grids.vdb"), &cube_grids());
    let stage = fire_stage(
        dir.path(),
        "    token nimbus:temperatureField = \"temperature\"\n    float nimbus:temperatureScale = 1500\n    token nimbus:emissionField = \"flames\"\n    float nimbus:emissionScale = 3",
    );
    let o = Command::new(env!("CARGO_BIN_EXE_nimbus"))
        .arg("info")
        .arg(&stage)
        .output()
        .unwrap();
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    for needle in [
        "blackbody from temperatureField temperature (/V/temperature) temperatureScale 1500",
        "emissionField flames (/V/flames) emissionColor [1.0, 1.0, 1.0] emissionScale 3",
        "emissive true",
    ] {
        assert!(out.contains(needle), "no '{needle}' in:\n{out}");
    }
}

// ----- real data ---------------------------------------------------------------------------------

/// The EmberGen fire (frame 50: grids `flames` and `temperature`, no density) with
/// `temperature` as the density field and `flames` as the emission field, unlit (no
/// lights, black environment): everything the camera sees is emission. It renders with
/// non-zero, finite radiance under the tracker `auto` picks and under spectral
/// tracking; each is checked to look emission up.
#[test]
fn embergen_fire_emits() {
    use nimbus::render::analysis::Analysis;
    use nimbus::render::camera::CameraRays;
    use nimbus::render::job::RenderJob;
    let Some(vdb) = common::shared_file("embergen_fire_a/embergen_fire_a_50.vdb") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let stage = dir.path().join("fire.usda");
    std::fs::write(
        &stage,
        format!(
            r#"#usda 1.0
def Camera "Cam" {{
    double3 xformOp:translate = (0, -25, 120)
    uniform token[] xformOpOrder = ["xformOp:translate"]
    float focalLength = 50
    float horizontalAperture = 36
    float verticalAperture = 36
}}
def Volume "Fire" (apiSchemas = ["NimbusVolumeAPI"]) {{
    token nimbus:densityField = "temperature"
    color3f nimbus:absorption = (0.5, 0.5, 0.5)
    color3f nimbus:scattering = (0.5, 0.5, 0.5)
    token nimbus:emissionField = "flames"
    color3f nimbus:emissionColor = (1, 0.5, 0.2)
    float nimbus:emissionScale = 40
    rel field:temperature = </Fire/temperature>
    rel field:flames = </Fire/flames>
    def OpenVDBAsset "temperature" {{ asset filePath = @{vdb}@
        token fieldName = "temperature" }}
    def OpenVDBAsset "flames" {{ asset filePath = @{vdb}@
        token fieldName = "flames" }}
}}
"#,
            vdb = vdb.display()
        ),
    )
    .unwrap();
    let scene = load_stage(&stage, &LoadOptions::default()).unwrap();
    let medium = media_for_scene_with(&scene, MajorantSpec::Uniform { cell_voxels: 8 })
        .unwrap()
        .remove(0);
    assert!(medium.emission.is_some());
    let lights = Lights::from_scene(&scene).unwrap();
    let (w, h) = (32, 32);
    let camera = CameraRays::new(&scene.camera, w, h);
    let analysis = Analysis::of_media(std::slice::from_ref(&medium), &lights, &camera, (w, h));
    assert!(analysis.emissive && analysis.volume_visible);
    let (auto, _) = analysis.choose(TrackerSettings::default(), Given::default());
    assert!(!auto.options.no_absorption_events);
    let spectral = TrackerSettings {
        tracker: TrackerKind::Spectral,
        ..TrackerSettings::default()
    };
    for tracking in [auto, spectral] {
        let job = RenderJob {
            media: std::slice::from_ref(&medium),
            lights: &lights,
            camera: &camera,
            width: w,
            height: h,
            spp: 8,
            max_depth: 16,
            seed: 1,
            sampler: Default::default(),
            tracking,
            paths: CodePaths::default(),
            extras: Default::default(),
        };
        let film = job.render(&|| {});
        common::assert_film_finite(tracking.tracker.name(), &film);
        let (totals, samples, _) = film.totals();
        let sum: [f64; 3] = [0, 1, 2].map(|c| film.pixels.iter().map(|p| p.rgb[c]).sum());
        eprintln!(
            "{}: radiance sum {sum:?} over {samples} samples, {} emission lookups, {} density lookups",
            tracking.tracker.name(),
            totals.emission_lookups,
            totals.density_lookups
        );
        assert!(totals.emission_lookups > 0);
        assert!(sum.iter().all(|&s| s.is_finite() && s > 0.0), "{sum:?}");
        // Colour (1, 0.5, 0.2): the channels keep the emission colour's ratios.
        assert!((sum[1] / sum[0] - 0.5).abs() < 1e-3, "{sum:?}");
    }
}

/// The analysis marks an emissive medium, and `auto` then keeps absorption events for a
/// chromatic medium (spectral decomposition, hist-avg) instead of dropping them.
#[test]
fn analysis_of_emissive_media_keeps_absorption_events() {
    use nimbus::render::analysis::Analysis;
    let cam = common::camera_on_z(10.0, 1000.0, 10.0, 9, 9);
    let lights = Lights::default();
    let mut m = common::unit_cube(1.0, [0.2, 0.3, 0.6], [1.1, 1.2, 1.0], 0.0);
    let a = Analysis::of_media(std::slice::from_ref(&m), &lights, &cam, (9, 9));
    assert!(!a.emissive);
    let (t, _) = a.choose(TrackerSettings::default(), Given::default());
    assert!(t.options.no_absorption_events);
    let (e, _) = both_sources();
    m.set_emission(Some(e));
    let a = Analysis::of_media(std::slice::from_ref(&m), &lights, &cam, (9, 9));
    assert!(a.emissive && !a.grey);
    let (t, reason) = a.choose(TrackerSettings::default(), Given::default());
    assert_eq!(
        (t.tracker, t.scheme),
        (TrackerKind::SpectralDecomposition, SchemeKind::HistAvg)
    );
    assert!(!t.options.no_absorption_events, "{reason}");
}

/// The example fire (scenes/fire, generated by scenes/make_scenes.rs) loads as an
/// emissive medium and renders finite, non-zero emission; the flame is warm (red above
/// blue where it is brightest).
#[test]
fn example_fire_scene_emits() {
    use nimbus::render::camera::CameraRays;
    use nimbus::render::job::RenderJob;
    let stage = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("scenes/fire/fire.usda");
    let scene = load_stage(&stage, &LoadOptions::default()).unwrap();
    let medium = media_for_scene_with(&scene, MajorantSpec::Uniform { cell_voxels: 8 })
        .unwrap()
        .remove(0);
    assert!(medium.emission.as_ref().unwrap().temperature.is_some());
    // No lights: only emission shows.
    let lights = Lights::default();
    let (w, h) = (12, 16);
    let camera = CameraRays::new(&scene.camera, w, h);
    let job = RenderJob {
        media: std::slice::from_ref(&medium),
        lights: &lights,
        camera: &camera,
        width: w,
        height: h,
        spp: 16,
        max_depth: 8,
        seed: 2,
        sampler: Default::default(),
        tracking: TrackerSettings::default(),
        paths: CodePaths::default(),
        extras: Default::default(),
    };
    let film = job.render(&|| {});
    common::assert_film_finite("fire", &film);
    let sum: [f64; 3] = [0, 1, 2].map(|c| film.pixels.iter().map(|p| p.rgb[c]).sum());
    assert!(sum[0] > 0.0 && sum[0] > sum[2], "{sum:?}");
    assert!(film.totals().0.emission_lookups > 0);
}

/// The single-channel trackers of grey media (`GreyDelta` with `GreyRatio`;
/// `GreyDecomposition` with `GreyResidualRatio`, `auto`'s pick for homogeneous grey
/// media; and the single-channel ratio-select walk with `GreyStochasticRatio`, its
/// pick for heterogeneous ones) collect emission too: grey σa = 1, the closed form of
/// `absorbing_emitting_cube_matches_closed_form`. N = 40,000 paths through the centre,
/// seed 5; |z| < 4 per channel.
#[test]
fn grey_single_channel_trackers_collect_emission() {
    use nimbus::render::integrator::SelectSegments;
    use nimbus::track::grey::{
        GreyDecomposition, GreyDelta, GreyRatio, GreyResidualRatio, GreyStochasticRatio,
    };
    check_grey_emission(GreyDelta, GreyRatio, SelectSegments::Off, "delta");
    check_grey_emission(
        GreyDecomposition,
        GreyResidualRatio,
        SelectSegments::Off,
        "decomposition",
    );
    check_grey_emission(
        GreyDecomposition,
        GreyStochasticRatio,
        SelectSegments::Grey,
        "ratio-select",
    );
}

fn check_grey_emission<F: FreePathSampler, E: TransmittanceEstimator>(
    free_path: F,
    transmittance: E,
    select_segments: nimbus::render::integrator::SelectSegments,
    what: &str,
) {
    use nimbus::render::integrator::Integrator;
    use nimbus::render::sampler::pixel_sampler;
    let env = [0.3, 0.2, 0.1];
    let lights = Lights {
        environment: env,
        ..Default::default()
    };
    let cam = common::camera_on_z(10.0, 1000.0, 10.0, 9, 9);
    let mut m = common::unit_cube(1.0, [1.0; 3], [0.0; 3], 0.0);
    let (e, le) = both_sources();
    m.set_emission(Some(e));
    let it = Integrator {
        free_path,
        transmittance,
        channel_per_path: false,
        majorant_scale: 1.0,
        count: true,
        profile: false,
        media: std::slice::from_ref(&m),
        lights: &lights,
        camera: &cam,
        width: 9,
        height: 9,
        spp: 1,
        max_depth: 64,
        seed: 5,
        qmc_dims: 0,
        extras: Default::default(),
        select_segments,
        locals: Vec::new(),
        shutter: None,
        guide: None,
        light_choice: None,
    };
    let mut rng = pixel_sampler(5, 0);
    let mut c = Counters::default();
    let s: Vec<[f64; 3]> = (0..40_000)
        .map(|_| it.sample(4.5, 4.5, &mut rng, &mut c).rgb)
        .collect();
    assert!(c.emission_lookups > 0, "{what}");
    let tr = (-1.0f64).exp();
    let z = [0, 1, 2].map(|ch| {
        let v: Vec<f64> = s.iter().map(|rgb| rgb[ch]).collect();
        let (mean, se) = mean_se(&v);
        (mean - (env[ch] * tr + le[ch] * (1.0 - tr))) / se.max(1e-12)
    });
    assert!(z.iter().all(|z| z.abs() < 4.0), "{what}: z = {z:?}");
}

/// Asserts that the message `msg` contains every one of `needles`.
fn assert_mentions(msg: &str, needles: &[&str]) {
    for needle in needles {
        assert!(msg.contains(needle), "no '{needle}' in: {msg}");
    }
}
