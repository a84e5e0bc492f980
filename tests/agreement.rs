//! Every tracker renders the example scenes to the same image as a high-sample `delta`
//! reference, within statistical error; decomposition saves density lookups.
//!
//! Estimator: per pixel, the mean luminance over spp samples, with its variance from
//! the per-pixel sample variance (the `variance` AOV) divided by spp. Pixels are pooled
//! into blocks (mean of the block's pixel means; variance Σ var_i/n_i / P²) so the CLT
//! holds at modest spp even for heavy-tailed trackers. For each block,
//! z = (tracker − reference)/sqrt(var_t + var_ref); every |z| must be < 4.5. Across
//! 2 scenes × 12 configurations × 36 blocks (864 two-sided tests) the chance of a false
//! alarm under the null is about 864 × 6.8e-6 ≈ 0.6%.

use nimbus::render::camera::CameraRays;
use nimbus::render::film::Film;
use nimbus::render::job::{medium_for_scene, RenderJob};
use nimbus::render::lights::Lights;
use nimbus::scene::{load_stage, LoadOptions};
use nimbus::track::{SchemeKind, TrackerKind, TrackerSettings, TransmittanceKind};
use nimbus::volume::medium::{Counters, Medium};
use std::path::PathBuf;

const W: u32 = 24;
const H: u32 = 18;
const BLOCK: (u32, u32) = (4, 3);

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
        lights: Lights::from_scene(&scene),
        camera: CameraRays::new(&scene.camera, W, H),
    }
}

fn render(s: &Setup, tracking: TrackerSettings, spp: u32, seed: u64) -> Film {
    RenderJob {
        medium: &s.medium,
        lights: &s.lights,
        camera: &s.camera,
        width: W,
        height: H,
        spp,
        max_depth: 64,
        seed,
        tracking,
    }
    .render(&|| {})
}

/// Block means and variances of the mean, for the luminance of a film.
fn blocks(f: &Film) -> Vec<(f64, f64)> {
    let mut out = Vec::new();
    for by in 0..H / BLOCK.1 {
        for bx in 0..W / BLOCK.0 {
            let (mut m, mut v, mut n) = (0.0, 0.0, 0.0);
            for y in by * BLOCK.1..(by + 1) * BLOCK.1 {
                for x in bx * BLOCK.0..(bx + 1) * BLOCK.0 {
                    let p = &f.pixels[(y * W + x) as usize];
                    let k = (p.samples - p.nonfinite) as f64;
                    m += p.lum / k;
                    v += p.luminance_variance() / k;
                    n += 1.0;
                }
            }
            out.push((m / n, v / (n * n)));
        }
    }
    out
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
        let reference = blocks(&render(&s, settings(Delta, Avg), 512, 1000));
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
            (
                "residual-ratio shadows",
                TrackerSettings {
                    transmittance: TransmittanceKind::ResidualRatio,
                    ..settings(Delta, Avg)
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
        for (i, (name, t)) in configs.into_iter().enumerate() {
            let film = render(&s, t, 64, 2000 + i as u64);
            let b = blocks(&film);
            for (k, ((mt, vt), (mr, vr))) in b.iter().zip(&reference).enumerate() {
                let sd = (vt + vr).sqrt();
                if sd == 0.0 {
                    assert!(
                        (mt - mr).abs() < 1e-9,
                        "{scene} {name} block {k}: {mt} vs {mr}"
                    );
                    continue;
                }
                let z = (mt - mr) / sd;
                assert!(
                    z.abs() < 4.5,
                    "{scene} {name} block {k}: {mt} vs reference {mr}, z = {z:.2}"
                );
            }
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
