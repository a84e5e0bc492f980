//! Every tracker renders the example scenes to the same image as a high-sample `delta`
//! reference, within statistical error; decomposition saves density lookups.
//!
//! Per pixel i the estimate is the mean luminance x_i over n samples; its variance is
//! estimated by the `variance` AOV v_i / n. For a tracker image x (n = 1024 spp, seed
//! fixed) against the reference r (delta, 4096 spp):
//!
//! 1. Image mean: z = Σ(x_i − r_i) / sqrt(Σ(v_i/n + w_i/N)); |z| < 4.5.
//! 2. Per-pixel agreement as a relative-MSE bound: S = Σ(x_i − r_i)² / Σ(v_i/n + w_i/N)
//!    is 1 in expectation for unbiased estimators (bias adds Σ b_i² to the numerator);
//!    under a Gaussian approximation S ~ χ²_m/m over the m pixels with non-zero variance,
//!    so S < 1 + 5·sqrt(2/m).
//!
//! Why not per-pixel or per-block z-scores: the sun-lit wisps of the cloud and the
//! weighted trackers on the chromatic medium give skewed, heavy-tailed per-sample
//! distributions; at 1024 spp the sample variance of a pixel or small block often misses
//! the rare large values and block z-scores beyond 4.5 appeared with shifted seeds for
//! unbiased trackers (delta against delta included). The image-level sums pool 10⁵–10⁶
//! samples, where the normal approximation holds. The tests still catch bias: delta with
//! its majorant scaled by 0.3 (biased) fails (checked by hand with the config below).

mod common;

use common::medium_for_scene;
use nimbus::render::analysis::CodePaths;
use nimbus::render::camera::CameraRays;
use nimbus::render::film::Film;
use nimbus::render::job::RenderJob;
use nimbus::render::lights::Lights;
use nimbus::render::sampler::SamplerKind;
use nimbus::scene::{load_stage, LoadOptions};
use nimbus::track::select::{SchemeKind, TrackerKind, TrackerSettings, TransmittanceKind};
use nimbus::volume::counters::Counters;
use nimbus::volume::medium::Medium;
use std::path::PathBuf;

const W: u32 = 24;
const H: u32 = 18;

struct Setup {
    medium: Medium,
    lights: Lights,
    camera: CameraRays,
}

fn setup(scene: &str) -> Setup {
    let path =
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join(format!("scenes/{scene}/{scene}.usda"));
    let scene = load_stage(&path, &LoadOptions::default()).unwrap();
    Setup {
        medium: medium_for_scene(&scene, 8).unwrap(),
        lights: Lights::from_scene(&scene).expect("scene lights"),
        camera: CameraRays::new(&scene.camera, W, H),
    }
}

fn render(s: &Setup, tracking: TrackerSettings, spp: u32, seed: u64) -> Film {
    RenderJob {
        paths: CodePaths::default(),
        media: std::slice::from_ref(&s.medium),
        lights: &s.lights,
        camera: &s.camera,
        width: W,
        height: H,
        spp,
        max_depth: 64,
        seed,
        // Independent samples: the z-tests take each pixel's variance from its samples.
        sampler: SamplerKind::Independent,
        tracking,
        extras: Default::default(),
    }
    .render(&|| {})
}

/// Per-pixel mean luminance and the variance of that mean, for pixels with samples.
fn pixels(f: &Film) -> Vec<(f64, f64)> {
    f.pixels
        .iter()
        .map(|p| {
            let k = (p.samples - p.nonfinite) as f64;
            (p.lum / k, p.luminance_variance() / k)
        })
        .collect()
}

/// (image-mean z, S, S's bound) of `x` against the reference `r`.
fn agreement(x: &[(f64, f64)], r: &[(f64, f64)]) -> (f64, f64, f64) {
    let (mut diff, mut sq, mut var, mut m) = (0.0, 0.0, 0.0, 0usize);
    for ((xm, xv), (rm, rv)) in x.iter().zip(r) {
        diff += xm - rm;
        sq += (xm - rm).powi(2);
        var += xv + rv;
        if xv + rv > 0.0 {
            m += 1;
        }
    }
    if var == 0.0 {
        return (
            if diff.abs() < 1e-6 {
                0.0
            } else {
                f64::INFINITY
            },
            1.0,
            1.0,
        );
    }
    (
        diff / var.sqrt(),
        sq / var,
        1.0 + 5.0 * (2.0 / m.max(1) as f64).sqrt(),
    )
}

fn settings(tracker: TrackerKind, scheme: SchemeKind) -> TrackerSettings {
    TrackerSettings {
        tracker,
        scheme,
        ..TrackerSettings::default()
    }
}

fn per_sample(c: &Counters, f: &Film) -> f64 {
    c.density_lookups as f64 / f.totals().1 as f64
}

#[test]
fn trackers_agree_with_delta_reference() {
    use SchemeKind::*;
    use TrackerKind::*;
    for scene in ["chromatic", "cloud"] {
        let s = setup(scene);
        let reference = pixels(&render(
            &s,
            settings(Delta, Avg),
            4096,
            1000 + seed_offset(),
        ));
        let mut configs = vec![
            ("naive-delta", settings(NaiveDelta, Avg)),
            ("delta", settings(Delta, Avg)),
            ("weighted-delta", settings(WeightedDelta, Avg)),
            ("decomposition", settings(Decomposition, Avg)),
            (
                "decomposition-weighted",
                TrackerSettings {
                    control: 0.5,
                    ..settings(DecompositionWeighted, Avg)
                },
            ),
            ("spectral max", settings(Spectral, Max)),
            ("spectral avg", settings(Spectral, Avg)),
            ("spectral hist-max", settings(Spectral, HistMax)),
            ("spectral hist-avg", settings(Spectral, HistAvg)),
            (
                "spectral-decomposition hist-avg",
                settings(SpectralDecomposition, HistAvg),
            ),
            ("spectral-mis", settings(SpectralMis, Avg)),
            ("ratio-select", settings(RatioSelect, Avg)),
            (
                "residual-ratio shadows",
                TrackerSettings {
                    transmittance: TransmittanceKind::ResidualRatio,
                    ..settings(Delta, Avg)
                },
            ),
            (
                "decomposition, tracking shadows",
                TrackerSettings {
                    transmittance: TransmittanceKind::Tracking,
                    ..settings(Decomposition, Avg)
                },
            ),
            (
                "spectral-decomposition, tracking shadows",
                TrackerSettings {
                    transmittance: TransmittanceKind::Tracking,
                    ..settings(SpectralDecomposition, HistAvg)
                },
            ),
        ];
        // Non-bounding majorants: the weighted tracker stays unbiased.
        configs.push((
            "weighted-delta, majorant × 0.5",
            TrackerSettings {
                majorant_scale: 0.5,
                ..settings(WeightedDelta, Avg)
            },
        ));
        configs.push((
            "ratio-select, majorant × 0.5",
            TrackerSettings {
                majorant_scale: 0.5,
                ..settings(RatioSelect, Avg)
            },
        ));
        configs.push((
            "spectral-mis, majorant × 0.5",
            TrackerSettings {
                majorant_scale: 0.5,
                ..settings(SpectralMis, Avg)
            },
        ));
        for (i, (name, t)) in configs.into_iter().enumerate() {
            let film = render(&s, t, 1024, 2000 + i as u64 + seed_offset());
            let (z, ratio, bound) = agreement(&pixels(&film), &reference);
            eprintln!("{scene} {name}: image-mean z = {z:.2}, S = {ratio:.3} (bound {bound:.3})");
            assert!(
                z.abs() < 4.5,
                "{scene} {name}: image mean differs from the reference, z = {z:.2}"
            );
            assert!(ratio < bound, "{scene} {name}: squared error {ratio:.3}× what the variance predicts (bound {bound:.3})");
        }
    }
}

/// Decomposition makes fewer density lookups per sample than delta tracking with the
/// same cells, and spectral decomposition fewer than spectral tracking (exact counts,
/// 16 spp, seed 7; the ratios are printed for the record).
#[test]
fn decomposition_saves_lookups_on_the_scenes() {
    use SchemeKind::*;
    use TrackerKind::*;
    for scene in ["cloud", "chromatic"] {
        let s = setup(scene);
        let lookups = |t: TrackerSettings| {
            let f = render(&s, t, 16, 7);
            per_sample(&f.totals().0, &f)
        };
        let delta = lookups(settings(Delta, Avg));
        let dec = lookups(settings(Decomposition, Avg));
        let spectral = lookups(settings(Spectral, HistAvg));
        let sdec = lookups(settings(SpectralDecomposition, HistAvg));
        eprintln!(
            "{scene}: lookups/sample delta {delta:.2} decomposition {dec:.2} ({:.3}×), spectral {spectral:.2} spectral-decomposition {sdec:.2} ({:.3}×)",
            dec / delta,
            sdec / spectral
        );
        assert!(dec < delta, "{scene}: decomposition {dec} vs delta {delta}");
        assert!(
            sdec < spectral,
            "{scene}: spectral-decomposition {sdec} vs spectral {spectral}"
        );
    }
}

/// Local lights in a heterogeneous medium (issue 44): `cloud` with a point light
/// (intensity 3) at the centre of its grid's box and a 40° spot (intensity 6) above
/// it aimed down through the cloud, added to the scene's sun and sky. Equiangular
/// sampling with MIS renders the same image as the collisions alone, under delta,
/// spectral decomposition and ratio-select, the last two with scattered directions
/// guided towards the lights (`--scatter-guiding lights`): each at 1024 spp against
/// the delta reference at 4096 spp (collisions, phase sampling), the image-mean z and
/// the squared-error ratio S of [`agreement`] (bounds as in
/// `trackers_agree_with_delta_reference`).
#[test]
fn equiangular_mis_agrees_with_delta_reference_in_a_cloud() {
    use nimbus::render::lights::{Shaping, SphereEmitter};
    use nimbus::track::select::{LightSampling, ScatterGuiding};
    use SchemeKind::*;
    use TrackerKind::*;
    let mut s = setup("cloud");
    let (lo, hi) = s.medium.world_bounds().expect("the cloud has a box");
    let centre = (lo + hi) * 0.5;
    let above = centre + glam::DVec3::Z * (hi.z - lo.z) * 0.6;
    let cone = nimbus::scene::Shaping {
        cone_angle: 40.0,
        ..Default::default()
    };
    // The light's local −Z is the world's −Z: no rotation.
    let spot = Shaping::new(&cone, &glam::DMat4::IDENTITY);
    assert!(spot.is_some());
    for (center, radiance, shaping) in [(centre, 3.0, None), (above, 6.0, spot)] {
        s.lights.spheres.push(SphereEmitter {
            center,
            radius: 0.0,
            radiance: [radiance; 3],
            shaping,
            ..Default::default()
        });
    }
    let with = |light_sampling, scatter_guiding, t: TrackerSettings| TrackerSettings {
        light_sampling,
        scatter_guiding,
        ..t
    };
    use ScatterGuiding::{Lights, Phase};
    let reference = pixels(&render(
        &s,
        with(LightSampling::Collisions, Phase, settings(Delta, Avg)),
        4096,
        3000 + seed_offset(),
    ));
    let configs = [
        ("delta", Phase, settings(Delta, Avg)),
        (
            "spectral-decomposition hist-avg",
            Lights,
            settings(SpectralDecomposition, HistAvg),
        ),
        ("ratio-select", Lights, settings(RatioSelect, Avg)),
    ];
    for (i, (name, guiding, t)) in configs.into_iter().enumerate() {
        let t = with(LightSampling::EquiangularMis, guiding, t);
        let film = render(&s, t, 1024, 3100 + i as u64 + seed_offset());
        let (z, ratio, bound) = agreement(&pixels(&film), &reference);
        let guiding = guiding.name();
        eprintln!("cloud + local lights, {name} equiangular-mis, scatter guiding {guiding}: image-mean z = {z:.2}, S = {ratio:.3} (bound {bound:.3})");
        assert!(
            z.abs() < 4.5,
            "{name}: image mean differs from the reference, z = {z:.2}"
        );
        assert!(
            ratio < bound,
            "{name}: squared error {ratio:.3}× what the variance predicts (bound {bound:.3})"
        );
    }
}

/// Plain delta tracking under a non-bounding majorant reports the violations.
#[test]
fn delta_reports_violations_with_non_bounding_majorant() {
    let s = setup("chromatic");
    let f = render(
        &s,
        TrackerSettings {
            majorant_scale: 0.5,
            ..settings(TrackerKind::Delta, SchemeKind::Avg)
        },
        4,
        3,
    );
    assert!(f.totals().0.majorant_violations > 0);
    let f = render(&s, settings(TrackerKind::Delta, SchemeKind::Avg), 4, 3);
    assert_eq!(f.totals().0.majorant_violations, 0);
}

/// Seeds are fixed so the test is deterministic; `NIMBUS_TEST_SEED_OFFSET` shifts them to
/// check by hand that passing is not an accident of one seed.
fn seed_offset() -> u64 {
    std::env::var("NIMBUS_TEST_SEED_OFFSET")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(0)
}
