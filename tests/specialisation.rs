//! The specialised code paths of the scene analysis give the general path's image:
//! - single-channel tracking of grey media makes the same decisions from the same
//!   random numbers as the general RGB trackers (same counts; the images differ only by
//!   the rounding of collision weights that are 1 in a grey medium);
//! - compiling the counting out changes no pixel;
//! - the closed-form path `auto` picks for homogeneous media (the decomposition
//!   family with residual ratio tracking) has the same image mean as delta tracking
//!   (a z-test) for a fraction of the lookups;
//! - prefetching the next tentative collision's stencil (on for grids beyond the
//!   caches) changes no pixel and no count of any tracker.

mod common;

use common::medium_for_scene;
use glam::{DMat4, DVec3};
use nimbus::render::analysis::{Analysis, CodePaths, Given};
use nimbus::render::camera::CameraRays;
use nimbus::render::film::{Aov, Film};
use nimbus::render::job::RenderJob;
use nimbus::render::lights::Lights;
use nimbus::scene::{load_stage, Camera, LoadOptions};
use nimbus::track::scheme::SchemeOptions;
use nimbus::track::select::{SchemeKind, TrackerKind, TrackerSettings, TransmittanceKind};
use nimbus::volume::counters::Counters;
use nimbus::volume::grid::Grid;
use nimbus::volume::majorant::MajorantSpec;
use nimbus::volume::medium::Medium;
use nimbus::volume::procedural::grid_from_fn;
use std::path::PathBuf;

const W: u32 = 24;
const H: u32 = 18;

struct Scene {
    media: Vec<Medium>,
    lights: Lights,
    camera: CameraRays,
    size: (u32, u32),
}

fn example(name: &str) -> Scene {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join(format!("scenes/{name}/{name}.usda"));
    let scene = load_stage(&path, &LoadOptions::default()).unwrap();
    Scene {
        media: vec![medium_for_scene(&scene, 8).unwrap()],
        lights: Lights::from_scene(&scene).unwrap(),
        camera: CameraRays::new(&scene.camera, W, H),
        size: (W, H),
    }
}

fn job(
    s: &Scene,
    tracking: TrackerSettings,
    paths: CodePaths,
    spp: u32,
    seed: u64,
) -> RenderJob<'_> {
    RenderJob {
        media: &s.media,
        lights: &s.lights,
        camera: &s.camera,
        width: s.size.0,
        height: s.size.1,
        spp,
        max_depth: 64,
        seed,
        sampler: Default::default(),
        tracking,
        paths,
        extras: Default::default(),
    }
}

fn rgba(f: &Film) -> Vec<f32> {
    [Aov::R, Aov::G, Aov::B, Aov::A]
        .iter()
        .flat_map(|&c| f.channel(c))
        .collect()
}

fn totals(f: &Film) -> Counters {
    f.totals().0
}

const GENERAL: CodePaths = CodePaths {
    count: true,
    specialise: false,
};
const SPECIALISED: CodePaths = CodePaths {
    count: true,
    specialise: true,
};

/// The auto choice for a scene whose media were built with the majorant structure
/// they are rendered with (named, as by `--majorant-cell` or `--octree-depth`).
fn auto(s: &Scene) -> TrackerSettings {
    let a = Analysis::of_media(&s.media, &s.lights, &s.camera, s.size);
    a.choose(TrackerSettings::default(), Given::MAJORANTS).0
}

/// Renders `t` on `s` single-channel and general with the same seed, and checks they
/// made the same decisions: every count equal, pixels equal up to rounding.
fn assert_same_decisions(s: &Scene, t: TrackerSettings, what: &str) {
    let spec = job(s, t, SPECIALISED, 16, 3);
    let gen = job(s, t, GENERAL, 16, 3);
    assert!(spec.grey_tracking() && !gen.grey_tracking(), "{what}");
    let (a, b) = (spec.render(&|| {}), gen.render(&|| {}));
    // Same events from the same numbers: every count is equal.
    let (ca, cb) = (totals(&a), totals(&b));
    let counts = |c: &Counters| {
        (
            c.density_lookups,
            c.residual_lookups,
            c.real_collisions,
            c.null_collisions,
            c.control_collisions,
            c.cells_visited,
            c.majorant_violations,
        )
    };
    assert_eq!(counts(&ca), counts(&cb), "{what}");
    // Enough events that a differing decision would show (the homogeneous cube's
    // closed form looks up only its rim: 286 lookups at 8 spp, without shadow rays
    // towards its constant sky).
    assert!(
        ca.real_collisions > 1_000 && ca.density_lookups > 500,
        "{what}: {ca:?}"
    );
    // The general path multiplies by weights that are 1 up to rounding (f32, ~6e-8
    // per factor, a few dozen factors per path): pixels agree far below the noise
    // (a different decision anywhere would move a pixel by O(0.1)).
    let worst = rgba(&a)
        .iter()
        .zip(rgba(&b))
        .map(|(x, y)| (x - y).abs())
        .fold(0f32, f32::max);
    assert!(worst < 1e-4, "{what}: largest pixel difference {worst}");
}

#[test]
fn grey_single_channel_makes_the_general_paths_decisions() {
    let s = example("cloud");
    let t = auto(&s);
    assert_eq!(t.tracker, TrackerKind::RatioSelect);
    assert_same_decisions(&s, t, "auto");
    // Every single-channel twin: delta and analog decomposition (also spelled
    // spectral-decomposition with the avg scheme), with either shadow-ray estimator.
    // ratio-select walks with one scalar T̂ (its weights formed per channel from it).
    for (tracker, scheme) in [
        (TrackerKind::Delta, SchemeKind::HistAvg),
        (TrackerKind::Decomposition, SchemeKind::HistAvg),
        (TrackerKind::SpectralDecomposition, SchemeKind::Avg),
        (TrackerKind::RatioSelect, SchemeKind::HistAvg),
    ] {
        for transmittance in [TransmittanceKind::Ratio, TransmittanceKind::ResidualRatio] {
            let t = TrackerSettings {
                tracker,
                scheme,
                transmittance,
                ..TrackerSettings::default()
            };
            let what = format!(
                "{} {} {}",
                tracker.name(),
                scheme.name(),
                transmittance.name()
            );
            assert_same_decisions(&s, t, &what);
        }
    }
    // auto's pick for a homogeneous grey medium: the closed-form path, where most
    // collisions are the control's.
    let homogeneous = homogeneous_cube();
    let t = auto(&homogeneous);
    assert_eq!(
        (t.tracker, t.transmittance),
        (TrackerKind::Decomposition, TransmittanceKind::ResidualRatio)
    );
    assert_same_decisions(&homogeneous, t, "homogeneous cube, auto");
    // Two overlapping grey volumes: the single-channel trackers race them too.
    let two = sky_scene(vec![
        cube("/A", DVec3::new(-0.4, 0.0, 0.0), |p: DVec3| 0.5 + 0.4 * p.x),
        cube("/B", DVec3::new(0.5, 0.1, -0.3), |p: DVec3| 0.3 + 0.2 * p.y),
    ]);
    // (ratio-select's segments through both take its fallback free path.)
    for tracker in [
        TrackerKind::Delta,
        TrackerKind::Decomposition,
        TrackerKind::RatioSelect,
    ] {
        for transmittance in [TransmittanceKind::Ratio, TransmittanceKind::ResidualRatio] {
            let t = TrackerSettings {
                tracker,
                transmittance,
                ..TrackerSettings::default()
            };
            let what = format!("two volumes, {} {}", tracker.name(), transmittance.name());
            assert_same_decisions(&two, t, &what);
        }
    }
}

#[test]
fn weighted_choices_keep_the_general_path_on_grey_media() {
    // Weights other than 1 in a grey medium: a history-aware scheme, a control above the
    // minimum, or the scheme options. These have no single-channel twin.
    let s = example("cloud");
    let d = TrackerSettings::default();
    let weighted = [
        TrackerSettings {
            tracker: TrackerKind::SpectralDecomposition,
            scheme: SchemeKind::HistAvg,
            ..d
        },
        TrackerSettings {
            tracker: TrackerKind::DecompositionWeighted,
            ..d
        },
        TrackerSettings {
            tracker: TrackerKind::Decomposition,
            options: SchemeOptions {
                no_absorption_events: true,
                reduced_termination: false,
            },
            ..d
        },
        TrackerSettings {
            tracker: TrackerKind::Spectral,
            ..d
        },
        // Its fallback free path (overlaps, deep camera rays) carries the options.
        TrackerSettings {
            tracker: TrackerKind::RatioSelect,
            options: SchemeOptions {
                no_absorption_events: true,
                reduced_termination: false,
            },
            ..d
        },
    ];
    for t in weighted {
        assert!(!job(&s, t, SPECIALISED, 1, 1).grey_tracking(), "{t:?}");
    }
}

#[test]
fn chromatic_media_keep_the_general_path() {
    let s = example("chromatic");
    for tracker in [TrackerKind::Delta, TrackerKind::SpectralDecomposition] {
        let t = TrackerSettings {
            tracker,
            ..TrackerSettings::default()
        };
        let spec = job(&s, t, SPECIALISED, 2, 5);
        assert!(!spec.grey_tracking());
        let gen = job(&s, t, GENERAL, 2, 5);
        assert_eq!(rgba(&spec.render(&|| {})), rgba(&gen.render(&|| {})));
    }
}

#[test]
fn counting_compiled_out_changes_no_pixel() {
    for name in ["cloud", "chromatic"] {
        let s = example(name);
        let t = auto(&s);
        let counted = job(&s, t, SPECIALISED, 4, 9).render(&|| {});
        let rgb_only = job(
            &s,
            t,
            CodePaths {
                count: false,
                specialise: true,
            },
            4,
            9,
        )
        .render(&|| {});
        assert_eq!(rgba(&counted), rgba(&rgb_only), "{name}");
        assert!(totals(&counted).density_lookups > 0, "{name}");
        let c = totals(&rgb_only);
        assert_eq!(
            (c.density_lookups, c.real_collisions, c.cells_visited),
            (0, 0, 0),
            "{name}: nothing is counted"
        );
    }
}

/// `Medium::prefetch` is a hint: with it on, every tracker (both shadow estimators,
/// grey and chromatic media, specialised paths) makes the same decisions and the same
/// pixels as with it off. The example grids are below the threshold, so the test
/// turns it on; a grid above the threshold has it on by itself.
#[test]
fn prefetching_changes_no_pixel() {
    let trackers = [
        TrackerKind::NaiveDelta,
        TrackerKind::Delta,
        TrackerKind::Decomposition,
        TrackerKind::Spectral,
        TrackerKind::SpectralDecomposition,
        TrackerKind::SpectralMis,
        TrackerKind::RatioSelect,
    ];
    for name in ["cloud", "chromatic"] {
        let mut s = example(name);
        assert!(
            !s.media[0].prefetch,
            "{name}: a small grid does not prefetch"
        );
        for tracker in trackers {
            for transmittance in [TransmittanceKind::Ratio, TransmittanceKind::ResidualRatio] {
                let t = TrackerSettings {
                    tracker,
                    transmittance,
                    ..TrackerSettings::default()
                };
                let what = format!("{name} {tracker:?} {transmittance:?}");
                s.media[0].prefetch = false;
                let off = job(&s, t, SPECIALISED, 2, 11).render(&|| {});
                s.media[0].prefetch = true;
                let on = job(&s, t, SPECIALISED, 2, 11).render(&|| {});
                assert_eq!(rgba(&off), rgba(&on), "{what}");
                let (a, b) = (totals(&off), totals(&on));
                assert!(a.density_lookups > 1_000, "{what}: {a:?}");
                assert_eq!(
                    (
                        a.density_lookups,
                        a.real_collisions,
                        a.null_collisions,
                        a.cells_visited
                    ),
                    (
                        b.density_lookups,
                        b.real_collisions,
                        b.null_collisions,
                        b.cells_visited
                    ),
                    "{what}"
                );
            }
        }
    }
    // 224³ voxels: 21,952 bricks, 42.9 MiB, above PREFETCH_BYTES (32 MiB).
    let big = cube("/Big", DVec3::ZERO, |_| 0.5);
    assert!(!big.prefetch && big.density.memory_bytes() < nimbus::volume::medium::PREFETCH_BYTES);
    let n = 224;
    let vs = 2.0 / n as f64;
    let raw = grid_from_fn("density", [n; 3], DVec3::splat(-1.0 + 0.5 * vs), vs, |_| {
        0.5
    });
    let grid = Grid::from_raw(&raw).unwrap();
    assert!(grid.memory_bytes() > nimbus::volume::medium::PREFETCH_BYTES);
    let m = Medium::with_majorants(
        "/Big",
        grid,
        DMat4::IDENTITY,
        1.0,
        [0.5; 3],
        [4.5; 3],
        0.0,
        MajorantSpec::Octree { depth: 4 },
    )
    .unwrap();
    assert!(m.prefetch);
}

/// A constant-density cube of 64³ voxels over [-1, 1]³, optical thickness 5 across,
/// albedo 0.9, under a white sky, seen from z = 6.
fn homogeneous_cube() -> Scene {
    sky_scene(vec![cube("/Cube", DVec3::ZERO, |_| 0.5)])
}

/// A cube of 64³ voxels over [-1, 1]³ moved to `centre`, density `f`, albedo 0.9.
fn cube(name: &str, centre: DVec3, f: impl Fn(DVec3) -> f64 + Sync) -> Medium {
    let vs = 2.0 / 64.0;
    let raw = grid_from_fn("density", [64; 3], DVec3::splat(-1.0 + 0.5 * vs), vs, f);
    Medium::with_majorants(
        name,
        Grid::from_raw(&raw).unwrap(),
        DMat4::from_translation(centre),
        1.0,
        [0.5; 3],
        [4.5; 3],
        0.0,
        MajorantSpec::Octree { depth: 7 },
    )
    .unwrap()
}

/// `media` under a white sky, seen from z = 6.
fn sky_scene(media: Vec<Medium>) -> Scene {
    let cam = Camera {
        prim_path: "/Camera".into(),
        camera_to_world: DMat4::from_translation(DVec3::new(0.0, 0.0, 6.0)),
        focal_length: 50.0,
        horizontal_aperture: 36.0,
        vertical_aperture: 27.0,
        horizontal_aperture_offset: 0.0,
        vertical_aperture_offset: 0.0,
        clipping_range: (0.1, 1e6),
        projection: Default::default(),
        f_stop: 0.0,
        focus_distance: 0.0,
        shutter: None,
        motion: None,
    };
    Scene {
        media,
        lights: Lights {
            suns: vec![],
            environment: [1.0; 3],
            ..Lights::default()
        },
        camera: CameraRays::new(&cam, 16, 12),
        size: (16, 12),
    }
}

/// Image-mean z of two independent renders: Σ(x_i − y_i) / sqrt(Σ(v_i + w_i)) with
/// v_i, w_i the variances of the pixel means (sample variance / n).
fn image_mean_z(a: &Film, b: &Film) -> f64 {
    let (mut diff, mut var) = (0.0, 0.0);
    for (p, q) in a.pixels.iter().zip(&b.pixels) {
        let (n, m) = (p.samples as f64, q.samples as f64);
        diff += p.lum / n - q.lum / m;
        var += p.luminance_variance() / n + q.luminance_variance() / m;
    }
    diff / var.sqrt()
}

#[test]
fn homogeneous_closed_form_agrees_with_delta_for_fewer_lookups() {
    let s = homogeneous_cube();
    let a = Analysis::of_media(&s.media, &s.lights, &s.camera, s.size);
    assert!(a.homogeneous && a.grey);
    let t = a.choose(TrackerSettings::default(), Given::MAJORANTS).0;
    assert_eq!(
        (t.tracker, t.transmittance),
        (TrackerKind::Decomposition, TransmittanceKind::ResidualRatio)
    );
    // Estimator: the image mean of luminance, 16×12 pixels × 256 spp each, seeds 1 and
    // 2 (independent streams); under the null hypothesis z ~ N(0, 1) by the CLT over
    // 49k samples per image; |z| < 4.5 fails by chance with probability 7e-6.
    let closed = job(&s, t, SPECIALISED, 256, 1).render(&|| {});
    let delta = job(&s, TrackerSettings::default(), SPECIALISED, 256, 2).render(&|| {});
    let z = image_mean_z(&closed, &delta);
    assert!(z.abs() < 4.5, "z = {z}");
    // Lookups (exact counts): delta looks up every collision and every shadow-ray step;
    // the closed form only in the one-leaf rim where the field falls off (about 1/32
    // of the cube's width on each side). Measured: 19,467 against 119,342 (0.16×).
    let (lc, ld) = (
        totals(&closed).density_lookups as f64,
        totals(&delta).density_lookups as f64,
    );
    assert!(lc < 0.25 * ld, "closed form {lc} lookups vs delta {ld}");
}
