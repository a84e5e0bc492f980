//! The integrator against closed-form answers, on a homogeneous cube lit by a constant
//! dome (built in Rust, no files involved; the CLI-level tests render stages).

mod common;

use glam::{DMat4, DVec3};
use nimbus::render::camera::CameraRays;
use nimbus::render::integrator::{Integrator, SelectSegments};
use nimbus::render::lights::Lights;
use nimbus::render::sampler::pixel_sampler;
use nimbus::scene::Camera;
use nimbus::track::delta::Delta;
use nimbus::track::free_path::FreePathSampler;
use nimbus::track::ratio::Ratio;
use nimbus::track::scheme::SchemeOptions;
use nimbus::track::spectral_mis::SpectralMis;
use nimbus::volume::counters::Counters;
use nimbus::volume::medium::Medium;

/// A narrow camera on the +Z axis at distance 10 looking at the origin: every ray of the
/// central pixels crosses the cube within 1e-4 of its axis length.
fn camera() -> CameraRays {
    let cam = Camera {
        prim_path: "/Camera".into(),
        camera_to_world: DMat4::from_translation(DVec3::new(0.0, 0.0, 10.0)),
        focal_length: 1000.0,
        horizontal_aperture: 10.0,
        vertical_aperture: 10.0,
        horizontal_aperture_offset: 0.0,
        vertical_aperture_offset: 0.0,
        clipping_range: (0.1, 1e6),
        projection: Default::default(),
        f_stop: 0.0,
        focus_distance: 0.0,
        shutter: None,
        motion: None,
    };
    CameraRays::new(&cam, 9, 9)
}

/// Delta tracking with ratio-tracked shadows over the 9×9 test camera.
fn integrator<'a>(
    medium: &'a Medium,
    lights: &'a Lights,
    camera: &'a CameraRays,
    spp: u32,
    max_depth: u32,
    seed: u64,
) -> Integrator<'a, Delta, Ratio> {
    integrator_with(Delta, medium, lights, camera, spp, max_depth, seed)
}

/// `free_path` with ratio-tracked shadows over the 9×9 test camera.
fn integrator_with<'a, F: FreePathSampler>(
    free_path: F,
    medium: &'a Medium,
    lights: &'a Lights,
    camera: &'a CameraRays,
    spp: u32,
    max_depth: u32,
    seed: u64,
) -> Integrator<'a, F, Ratio> {
    Integrator {
        free_path,
        transmittance: Ratio,
        channel_per_path: false,
        majorant_scale: 1.0,
        count: true,
        profile: false,
        media: std::slice::from_ref(medium),
        lights,
        camera,
        width: 9,
        height: 9,
        spp,
        max_depth,
        seed,
        qmc_dims: 0,
        extras: Default::default(),
        select_segments: SelectSegments::Off,
        locals: Vec::new(),
        shutter: None,
        guide: None,
        light_choice: None,
    }
}

fn samples(medium: &Medium, lights: &Lights, max_depth: u32, n: usize) -> Vec<[f64; 3]> {
    samples_with(Delta, medium, lights, max_depth, n, SelectSegments::Off)
}

fn samples_with<F: FreePathSampler>(
    free_path: F,
    medium: &Medium,
    lights: &Lights,
    max_depth: u32,
    n: usize,
    select_segments: SelectSegments,
) -> Vec<[f64; 3]> {
    let cam = camera();
    let mut it = integrator_with(free_path, medium, lights, &cam, 1, max_depth, 5);
    it.select_segments = select_segments;
    let mut rng = pixel_sampler(5, 40);
    let mut c = Counters::default();
    (0..n)
        .map(|_| it.sample(4.5, 4.5, &mut rng, &mut c).rgb)
        .collect()
}

fn z_scores(s: &[[f64; 3]], expected: [f64; 3]) -> [f64; 3] {
    let n = s.len() as f64;
    [0, 1, 2].map(|c| {
        let m = s.iter().map(|v| v[c]).sum::<f64>() / n;
        let var = s.iter().map(|v| (v[c] - m).powi(2)).sum::<f64>() / (n - 1.0);
        (m - expected[c]) / (var / n).sqrt().max(1e-12)
    })
}

/// Albedo 0: the camera sees dome · exp(−σt). Estimator: one path per sample (delta
/// tracking, then spectral MIS, escape carrying the dome radiance; then ratio-select,
/// its ratio-tracked transmittance times the dome), N = 100,000 each,
/// seed 5; |z| < 4 per channel.
#[test]
fn absorbing_cube_transmits_dome_exactly() {
    let sigma_a = [0.5, 1.0, 2.0];
    let m = common::unit_cube(1.0, sigma_a, [0.0; 3], 0.0);
    let lights = Lights {
        suns: vec![],
        environment: [1.0, 2.0, 0.5],
        ..Default::default()
    };
    let expected = [0, 1, 2].map(|c| lights.environment[c] * (-sigma_a[c]).exp());
    let s = samples(&m, &lights, 64, 100_000);
    let z = z_scores(&s, expected);
    assert!(z.iter().all(|z| z.abs() < 4.0), "z = {z:?}");
    let mis = SpectralMis::new(SchemeOptions::default());
    let s = samples_with(mis, &m, &lights, 64, 100_000, SelectSegments::Off);
    let z = z_scores(&s, expected);
    assert!(z.iter().all(|z| z.abs() < 4.0), "spectral-mis: z = {z:?}");
    let s = samples_with(Delta, &m, &lights, 64, 100_000, SelectSegments::Rgb);
    let z = z_scores(&s, expected);
    assert!(z.iter().all(|z| z.abs() < 4.0), "ratio-select: z = {z:?}");
}

/// Albedo 1 inside a constant environment: radiance is the environment's everywhere,
/// whatever the density, phase function or colour of σs (energy conservation; exact in
/// the limit of unbounded depth, and depth 10,000 with Russian roulette leaves a bias far
/// below the noise). Checks multiple scattering, environment NEE, phase sampling and
/// their MIS together. Delta tracking, spectral MIS, ratio-select: N = 50,000 each, seed 5;
/// |z| < 4 per channel.
#[test]
fn conservative_cube_in_constant_environment_is_invisible() {
    for g in [0.0, 0.7] {
        let m = common::unit_cube(1.0, [0.0; 3], [4.0, 2.0, 1.0], g);
        let lights = Lights {
            suns: vec![],
            environment: [0.8, 1.0, 1.3],
            ..Default::default()
        };
        let s = samples(&m, &lights, 10_000, 50_000);
        let z = z_scores(&s, lights.environment);
        assert!(z.iter().all(|z| z.abs() < 4.0), "g {g}: z = {z:?}");
        let mis = SpectralMis::new(SchemeOptions::default());
        let s = samples_with(mis, &m, &lights, 10_000, 50_000, SelectSegments::Off);
        let z = z_scores(&s, lights.environment);
        assert!(
            z.iter().all(|z| z.abs() < 4.0),
            "spectral-mis g {g}: z = {z:?}"
        );
        let s = samples_with(Delta, &m, &lights, 10_000, 50_000, SelectSegments::Rgb);
        let z = z_scores(&s, lights.environment);
        assert!(
            z.iter().all(|z| z.abs() < 4.0),
            "ratio-select g {g}: z = {z:?}"
        );
    }
}

/// Rendering is deterministic for a seed, whatever the number of threads.
#[test]
fn render_is_deterministic_across_thread_counts() {
    let m = common::unit_cube(1.0, [0.2; 3], [1.5, 1.0, 0.5], 0.3);
    let lights = Lights {
        suns: vec![],
        environment: [1.0; 3],
        ..Default::default()
    };
    let cam = camera();
    let it = integrator(&m, &lights, &cam, 4, 16, 9);
    let render = |threads| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| it.render(&|| {}))
            .pixels
            .iter()
            .map(|p| (p.rgb, p.counters.density_lookups))
            .collect::<Vec<_>>()
    };
    assert_eq!(render(1), render(2));
}

/// Progressive rendering: N samples split into passes give the film of one pass of N,
/// bit for bit (each pixel's random stream is carried in the film between passes).
#[test]
fn passes_accumulate_like_a_single_pass() {
    use nimbus::render::film::Film;
    let m = common::unit_cube(1.0, [0.2; 3], [1.5, 1.0, 0.5], 0.3);
    let lights = Lights {
        suns: vec![],
        environment: [1.0; 3],
        ..Default::default()
    };
    let cam = camera();
    let it = integrator(&m, &lights, &cam, 7, 16, 11);
    let key = |f: &Film| {
        f.pixels
            .iter()
            .map(|p| {
                (
                    p.rgb.map(f64::to_bits),
                    p.alpha.to_bits(),
                    p.lum_sq.to_bits(),
                    p.samples,
                    p.counters.density_lookups,
                    p.counters.real_collisions,
                )
            })
            .collect::<Vec<_>>()
    };
    let one = it.render(&|| {});
    let mut split = Film::new(9, 9, 11);
    for n in [1, 2, 4] {
        it.render_pass(&mut split, n, &|| {});
    }
    assert_eq!(key(&one), key(&split));
    assert_eq!(one.pixels[40].samples, 7);
}
