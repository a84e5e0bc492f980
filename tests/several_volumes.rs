//! Several volumes along a ray: their coefficients add (`track::race`).
//!
//! Three media on 32³ unit-voxel grids, one grey and two chromatic, the third shifted
//! along x so it overlaps the others only in part. Rays run along +x through voxel
//! centres, where the trilinear reconstruction is the piecewise-linear interpolant of
//! the samples along x, so optical depths are exact trapezoid sums (as in
//! tests/tracking.rs) and every expected value below is closed-form or a 1-D
//! quadrature of them.

mod common;

use common::{all_settings, label, mean_se};
use glam::{DMat4, DVec3};
use nimbus::render::analysis::CodePaths;
use nimbus::render::camera::CameraRays;
use nimbus::render::job::RenderJob;
use nimbus::render::lights::Lights;
use nimbus::render::sampler::SamplerKind;
use nimbus::track::free_path::{FreePath, FreePathSampler, Query, TransmittanceEstimator};
use nimbus::track::select::{Dispatch, TrackerKind, TrackerSettings};
use nimbus::volume::counters::Counters;
use nimbus::volume::grid::Grid;
use nimbus::volume::medium::{IndexRay, Medium};
use nimbus::volume::procedural::grid_from_fn;
use rand::SeedableRng;
use rand_pcg::Pcg32;

const N: i32 = 32;
const X0: f64 = 2.0;
const X1: f64 = 29.0;

type Field = fn(f64) -> f64;

struct Part {
    field: Field,
    /// World x of index x = 0.
    shift: f64,
    sigma_a: [f64; 3],
    sigma_s: [f64; 3],
}

fn ramp(x: f64) -> f64 {
    0.02 + 0.012 * x
}
fn steps(x: f64) -> f64 {
    if x < 12.0 {
        0.1
    } else if x < 20.0 {
        0.6
    } else {
        0.03
    }
}
/// Zero near the grid's faces, so the shifted copy has no boundary ramp on the ray.
fn slab(x: f64) -> f64 {
    if (4.0..=18.0).contains(&x) {
        0.35
    } else {
        0.0
    }
}

fn parts() -> [Part; 3] {
    [
        Part {
            field: ramp,
            shift: 0.0,
            sigma_a: [0.1; 3],
            sigma_s: [0.3; 3],
        },
        Part {
            field: steps,
            shift: 0.0,
            sigma_a: [0.02, 0.05, 0.15],
            sigma_s: [0.25, 0.15, 0.05],
        },
        Part {
            field: slab,
            shift: 8.0,
            sigma_a: [0.2, 0.05, 0.01],
            sigma_s: [0.1, 0.2, 0.3],
        },
    ]
}

fn medium(p: &Part, cell: u32) -> Medium {
    let f = p.field;
    let raw = grid_from_fn("density", [N, N, N], DVec3::ZERO, 1.0, move |q| f(q.x));
    Medium::new(
        "/part",
        Grid::from_raw(&raw).unwrap(),
        DMat4::from_translation(DVec3::new(p.shift, 0.0, 0.0)),
        1.0,
        p.sigma_a,
        p.sigma_s,
        0.0,
        cell,
    )
    .unwrap()
}

/// Each medium's index-space ray for the world ray from (X0, 16, 16) along +x.
fn rays(media: &[Medium]) -> Vec<IndexRay> {
    media
        .iter()
        .map(|m| m.index_ray(DVec3::new(X0, 16.0, 16.0), DVec3::X))
        .collect()
}

/// One query per medium over [X0, X1] with bounding majorants.
fn queries<'a>(media: &'a [Medium], rays: &'a [IndexRay]) -> Vec<Query<'a>> {
    media
        .iter()
        .zip(rays)
        .map(|(m, r)| Query {
            medium: m,
            sigma: &m.sigma,
            ray: r,
            tmin: 0.0,
            tmax: (X1 - X0) as f32,
            majorant_scale: 1.0,
        })
        .collect()
}

/// The density of part `p` at world x along the ray (the piecewise-linear interpolant
/// of its samples; 0 outside the grid's samples).
fn density(p: &Part, x: f64) -> f64 {
    let u = x - p.shift;
    if !(0.0..=(N - 1) as f64).contains(&u) {
        return 0.0;
    }
    let i = u.floor();
    let f = p.field;
    f(i) + (f(i + 1.0) - f(i)) * (u - i)
}

/// μt(x, λ) of the sum medium at world x, per channel.
fn mu_t(ps: &[Part], x: f64) -> [f64; 3] {
    [0, 1, 2].map(|c| {
        ps.iter()
            .map(|p| density(p, x) * (p.sigma_a[c] + p.sigma_s[c]))
            .sum()
    })
}

/// Midpoint quadrature over [X0, X1] with `n` steps of `f(x, T(x))`, T the sum
/// medium's transmittance from X0 (exact up to O(h²); h = 27/200000).
fn quadrature(ps: &[Part], f: impl Fn(f64, [f64; 3]) -> [f64; 3]) -> [f64; 3] {
    let n = 200_000;
    let h = (X1 - X0) / n as f64;
    let mut tau = [0f64; 3];
    let mut acc = [0f64; 3];
    for i in 0..n {
        let x = X0 + (i as f64 + 0.5) * h;
        let mt = mu_t(ps, x);
        // τ at the midpoint: half a step of the midpoint's μt on top of the sum so far.
        let tr = [0, 1, 2].map(|c| (-(tau[c] + 0.5 * h * mt[c])).exp());
        let v = f(x, tr);
        for c in 0..3 {
            acc[c] += v[c] * h;
            tau[c] += mt[c] * h;
        }
    }
    acc
}

fn transmittance(ps: &[Part]) -> [f64; 3] {
    let tau = quadrature(ps, |x, _| mu_t(ps, x));
    tau.map(|t| (-t).exp())
}

fn z_check(what: &str, samples: &[Vec<f64>; 3], expected: [f64; 3]) -> f64 {
    let mut worst = 0f64;
    for c in 0..3 {
        let (m, se) = mean_se(&samples[c]);
        let z = if se > 0.0 {
            (m - expected[c]) / se
        } else {
            // A zero-variance estimate (analog grey) must match to rounding.
            if (m - expected[c]).abs() < 1e-5 {
                0.0
            } else {
                f64::INFINITY
            }
        };
        assert!(
            z.abs() < 4.0,
            "{what} ch {c}: mean {m} expected {} z {z}",
            expected[c]
        );
        worst = worst.max(z.abs());
    }
    worst
}

struct RaceRun {
    cell: u32,
    n: usize,
    seed: u64,
}

/// Per tracker: the escape weight (transmittance) and the weights of scatter and
/// absorption events attributed to each medium, against
/// T = exp(−Σᵢ∫μtᵢ), E[w·1{scatter in i}] = ∫T·μsᵢ and E[w·1{absorb in i}] = ∫T·μaᵢ.
impl Dispatch<()> for &RaceRun {
    fn run<F: FreePathSampler, E: TransmittanceEstimator>(self, tracker: F, _e: E) {
        let ps = parts();
        let media: Vec<Medium> = ps.iter().map(|p| medium(p, self.cell)).collect();
        let rays = rays(&media);
        let qs = queries(&media, &rays);
        let mut rng = Pcg32::seed_from_u64(self.seed);
        let mut c = Counters::default();
        let k = ps.len();
        let mut escape: [Vec<f64>; 3] = Default::default();
        let mut scatter: Vec<[Vec<f64>; 3]> = (0..k).map(|_| Default::default()).collect();
        let mut absorb: Vec<[Vec<f64>; 3]> = (0..k).map(|_| Default::default()).collect();
        for _ in 0..self.n {
            let mut w = [1f32; 3];
            let (e, lane) = tracker.sample_race(&qs, &mut w, &mut rng, &mut c);
            for ch in 0..3 {
                let v = w[ch] as f64;
                escape[ch].push(if e == FreePath::Escape { v } else { 0.0 });
                for i in 0..k {
                    let hit = |f: bool| if f && lane == i { v } else { 0.0 };
                    scatter[i][ch].push(hit(matches!(e, FreePath::Scatter { .. })));
                    absorb[i][ch].push(hit(matches!(e, FreePath::Absorb { .. })));
                }
            }
        }
        let what = format!("cell {}", self.cell);
        z_check(&format!("{what} escape"), &escape, transmittance(&ps));
        for i in 0..k {
            let p = &ps[i];
            let s = quadrature(&ps, |x, tr| {
                [0, 1, 2].map(|ch| tr[ch] * density(p, x) * p.sigma_s[ch])
            });
            let a = quadrature(&ps, |x, tr| {
                [0, 1, 2].map(|ch| tr[ch] * density(p, x) * p.sigma_a[ch])
            });
            z_check(&format!("{what} scatter in medium {i}"), &scatter[i], s);
            z_check(&format!("{what} absorb in medium {i}"), &absorb[i], a);
        }
    }
}

/// Every tracker and scheme (`common::all_settings`, bounding majorants) races three
/// overlapping media correctly: the escape weight estimates the sum medium's
/// transmittance, and scatter/absorption weights attributed to each medium estimate
/// ∫T·μsᵢ and ∫T·μaᵢ (so each collision is credited to the medium that made it, with
/// that medium's weights). Estimators: the per-path indicator × throughput;
/// N = 40,000 paths per tracker, seed 11, flat cells of 8 voxels and a global
/// majorant; |z| < 4 per channel and quantity (21 z-tests per tracker and cell size).
#[test]
fn every_tracker_races_overlapping_media() {
    for settings in all_settings(1.0) {
        if settings.tracker == TrackerKind::NaiveDelta {
            continue; // the integrator picks its channel; its tracker is `delta`
        }
        for cell in [8, 0] {
            let run = RaceRun {
                cell,
                n: 40_000,
                seed: 11,
            };
            eprintln!("{}", label(&settings));
            nimbus::track::select::dispatch(&settings, &run);
        }
    }
}

/// The product of per-medium transmittance estimates is unbiased for the sum
/// medium's transmittance, for ratio and residual ratio tracking. Estimator: T̂ per
/// shadow ray; N = 100,000, seed 12; |z| < 4 per channel.
#[test]
fn transmittance_of_overlapping_media_is_the_product() {
    struct Shadow;
    impl Dispatch<()> for Shadow {
        fn run<F: FreePathSampler, E: TransmittanceEstimator>(self, _f: F, e: E) {
            let ps = parts();
            let media: Vec<Medium> = ps.iter().map(|p| medium(p, 8)).collect();
            let rays = rays(&media);
            let qs = queries(&media, &rays);
            let mut rng = Pcg32::seed_from_u64(12);
            let mut c = Counters::default();
            let mut s: [Vec<f64>; 3] = Default::default();
            for _ in 0..100_000 {
                let t = e.transmittance_race(&qs, &mut rng, &mut c);
                for ch in 0..3 {
                    s[ch].push(t[ch] as f64);
                }
            }
            z_check("shadow", &s, transmittance(&ps));
        }
    }
    for transmittance in [
        nimbus::track::select::TransmittanceKind::Ratio,
        nimbus::track::select::TransmittanceKind::ResidualRatio,
    ] {
        let settings = TrackerSettings {
            transmittance,
            ..TrackerSettings::default()
        };
        nimbus::track::select::dispatch(&settings, Shadow);
    }
}

/// The race has power: crediting every collision of the race to the first medium
/// (as a renderer that ignores the others would, in effect) fails the attribution
/// check by a wide margin. Deterministic: it compares two quadratures.
#[test]
fn the_attribution_check_can_fail() {
    let ps = parts();
    let s0 = quadrature(&ps, |x, tr| {
        [0, 1, 2].map(|ch| tr[ch] * density(&ps[0], x) * ps[0].sigma_s[ch])
    });
    let all: [f64; 3] = quadrature(&ps, |x, tr| {
        [0, 1, 2].map(|ch| {
            tr[ch]
                * ps.iter()
                    .map(|p| density(p, x) * p.sigma_s[ch])
                    .sum::<f64>()
        })
    });
    for ch in 0..3 {
        assert!(all[ch] > 1.5 * s0[ch], "ch {ch}: {} vs {}", all[ch], s0[ch]);
    }
}

/// Two overlapping cubes of densities 0.4 and 0.6, and twenty of density 0.05, render
/// like one cube of density 1 (same σ, same g): the integrator's race, its shadow-ray
/// product and its choice of phase function per collision. Estimator: the image mean of each render (8×6
/// pixels, 64 spp, seeds 21 and 22); the difference of the two means is tested with
/// the pixels' standard errors combined, |z| < 4 per channel, for delta and
/// spectral-decomposition.
#[test]
fn overlapping_cubes_render_like_their_sum() {
    let sun_lights = common_lights();
    let cam = camera();
    let cube = |d: f64| common::unit_cube(1.0, [0.3 * d; 3], [0.9 * d; 3], 0.4);
    let one = [cube(1.0)];
    let two = [cube(0.4), cube(0.6)];
    // More volumes than the largest per-ray array below 64 (16), all on every ray.
    let twenty: Vec<Medium> = (0..20).map(|_| cube(0.05)).collect();
    for tracker in [TrackerKind::Delta, TrackerKind::SpectralDecomposition] {
        let settings = TrackerSettings {
            tracker,
            ..TrackerSettings::default()
        };
        let a = render(&one, &sun_lights, &cam, &settings, 21);
        for (name, split, seed) in [("two", &two[..], 22), ("twenty", &twenty[..], 23)] {
            let b = render(split, &sun_lights, &cam, &settings, seed);
            for ch in 0..3 {
                let (ma, sa) = mean_se(&a[ch]);
                let (mb, sb) = mean_se(&b[ch]);
                let z = (ma - mb) / (sa * sa + sb * sb).sqrt();
                assert!(
                    z.abs() < 4.0,
                    "{}: ch {ch}: one cube {ma} ± {sa}, {name} cubes {mb} ± {sb}, z {z}",
                    tracker.name()
                );
            }
        }
    }
}

fn common_lights() -> Lights {
    let mut l = Lights::default();
    l.environment = [0.5, 0.6, 0.7];
    l
}

fn camera() -> CameraRays {
    common::camera_on_z(3.0, 50.0, 24.0, 8, 6)
}

/// Per channel, every sample's radiance (8×6 pixels × 64 spp, through the pixel
/// centres, row by row).
fn render(
    media: &[Medium],
    lights: &Lights,
    cam: &CameraRays,
    settings: &TrackerSettings,
    seed: u64,
) -> [Vec<f64>; 3] {
    let job = RenderJob {
        media,
        lights,
        camera: cam,
        width: 8,
        height: 6,
        spp: 64,
        max_depth: 16,
        seed,
        sampler: SamplerKind::Independent,
        tracking: *settings,
        paths: CodePaths {
            count: false,
            specialise: false,
        },
        extras: Default::default(),
    };
    let centres: Vec<(f64, f64)> = (0..6)
        .flat_map(|y| (0..8).map(move |x| (x as f64 + 0.5, y as f64 + 0.5)))
        .collect();
    let paths = job.paths(&centres, 64);
    [0, 1, 2].map(|ch| paths.iter().map(|(rgb, _)| rgb[ch]).collect())
}

/// Culling is conservative and culls: over 20,000 random rays (seed 31) against a
/// rotated, translated, scaled cube, every ray whose majorant walk meets a cell is
/// kept by `may_meet`, and rays that miss the cube's box by far are culled.
#[test]
fn culling_keeps_every_ray_that_meets_the_volume() {
    use rand::Rng;
    let raw = grid_from_fn("density", [12, 12, 12], DVec3::ZERO, 1.0, |_| 1.0);
    let xf = DMat4::from_scale_rotation_translation(
        DVec3::new(0.1, 0.2, 0.15),
        glam::DQuat::from_euler(glam::EulerRot::XYZ, 0.3, 0.7, -0.2),
        DVec3::new(0.5, -0.3, 0.2),
    );
    let m = Medium::new(
        "/c",
        Grid::from_raw(&raw).unwrap(),
        xf,
        1.0,
        [1.0; 3],
        [1.0; 3],
        0.0,
        4,
    )
    .unwrap();
    let mut rng = Pcg32::seed_from_u64(31);
    let (mut met, mut culled) = (0, 0);
    for _ in 0..20_000 {
        let o = DVec3::new(rng.gen(), rng.gen(), rng.gen()) * 8.0 - 4.0;
        let d = DVec3::new(rng.gen(), rng.gen(), rng.gen()) * 2.0 - 1.0;
        let tmax: f64 = if rng.gen() {
            f64::INFINITY
        } else {
            rng.gen::<f64>() * 6.0
        };
        let r = m.index_ray(o, d);
        let meets = m
            .majorants
            .walk(r.o, r.d, 0.0, tmax as f32)
            .next()
            .is_some();
        let kept = m.may_meet(o, d, 0.0, tmax);
        assert!(
            !meets || kept,
            "ray {o} + t·{d} (t < {tmax}) meets the cube but was culled"
        );
        met += meets as u32;
        culled += !kept as u32;
    }
    assert!(met > 100 && culled > 10_000, "met {met}, culled {culled}");
    // Axis-parallel rays (zero direction components).
    let c = xf.transform_point3(DVec3::splat(6.0));
    for a in 0..3 {
        let mut d = DVec3::ZERO;
        d[a] = 1.0;
        let mut o = c;
        o[a] -= 10.0;
        assert!(m.may_meet(o, d, 0.0, f64::INFINITY), "axis {a}");
        assert!(!m.may_meet(o, d, 0.0, 1.0), "axis {a}, stopping short");
        o[(a + 1) % 3] += 10.0;
        assert!(!m.may_meet(o, d, 0.0, f64::INFINITY), "axis {a}, beside");
    }
}
