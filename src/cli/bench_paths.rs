//! `nimbus bench paths`: what the specialised code paths of the scene analysis buy on a
//! stage. The tracker `--tracker auto` picks (or the one named) is rendered four ways — the general RGB
//! trackers or the specialised ones (single-channel tracking of grey media), each with
//! the per-pixel counting on (cost AOVs, stats) or compiled out (an RGB-only render) —
//! in interleaved rounds with the same seed, so machine noise hits all four alike,
//! timed on the process' CPU clock (other programs on a shared machine do not inflate
//! it).
//! Prints the median seconds per sample of each and the ratios, and checks that the
//! four images agree (equal decisions: differences are rounding only).

use super::render::{MajorantArgs, SamplingArgs};
use crate::render::analysis::{Analysis, CodePaths, Given};
use crate::render::camera::CameraRays;
use crate::render::film::{Aov, Film};
use crate::render::job::{media_for_scene_with, RenderJob};
use crate::render::lights::Lights;
use crate::render::progressive::{Clock, Stopwatch};
use crate::track::{SchemeKind, TrackerKind, TrackerSettings, TransmittanceKind};
use anyhow::{bail, Context, Result};
use clap::Args;
use std::path::PathBuf;

#[derive(Args, Debug)]
pub struct PathsArgs {
    /// The USD stage.
    pub stage: PathBuf,
    /// Rounds; each renders all four variants once.
    #[arg(long, default_value_t = 5)]
    pub rounds: u32,
    /// Samples, resolution, seed, threads (default 1 thread: the machine's other
    /// work disturbs one worker least).
    #[command(flatten)]
    pub sampling: SamplingArgs,
    /// Majorant structure, as for `render`.
    #[command(flatten)]
    pub majorants: MajorantArgs,
    /// Free-path sampler instead of `auto`'s pick.
    #[arg(long, value_enum)]
    pub tracker: Option<TrackerKind>,
    /// Event probabilities for `spectral` and `spectral-decomposition` instead of
    /// `auto`'s pick.
    #[arg(long, value_enum)]
    pub scheme: Option<SchemeKind>,
    /// Shadow-ray transmittance estimator instead of `auto`'s pick.
    #[arg(long, value_enum)]
    pub transmittance: Option<TransmittanceKind>,
}

/// The four variants, in the order they are rendered in each round.
const VARIANTS: [(&str, CodePaths); 4] = [
    (
        "general, counting",
        CodePaths {
            count: true,
            specialise: false,
        },
    ),
    (
        "general, RGB only",
        CodePaths {
            count: false,
            specialise: false,
        },
    ),
    (
        "specialised, counting",
        CodePaths {
            count: true,
            specialise: true,
        },
    ),
    (
        "specialised, RGB only",
        CodePaths {
            count: false,
            specialise: true,
        },
    ),
];

pub fn run(args: PathsArgs) -> Result<()> {
    if args.rounds == 0 {
        bail!("--rounds must be at least 1");
    }
    let (scene, width, height) = args.sampling.load_stage(&args.stage)?;
    let s = &scene.settings;
    let spp = args.sampling.spp.unwrap_or(s.samples);
    if spp == 0 {
        bail!("--spp must be at least 1");
    }
    let spec = args.majorants.spec(s)?;
    let media = media_for_scene_with(&scene, spec)?;
    let lights = Lights::from_scene(&scene)?;
    let camera = CameraRays::new(&scene.camera, width, height);
    let analysis = Analysis::of_media(&media, &lights, &camera, (width, height));
    let (mut tracking, mut reason) = analysis.choose(TrackerSettings::default(), Given::MAJORANTS);
    if args.tracker.is_some() || args.scheme.is_some() || args.transmittance.is_some() {
        // Named choices replace auto's; the options auto set go with its tracker.
        if let Some(t) = args.tracker {
            tracking.tracker = t;
            tracking.options = Default::default();
        }
        tracking.scheme = args.scheme.unwrap_or(tracking.scheme);
        tracking.transmittance = args.transmittance.unwrap_or(tracking.transmittance);
        reason = "named on the command line".into();
    }
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(args.sampling.threads.unwrap_or(1))
        .build()
        .context("cannot start worker threads")?;
    let job = |paths| RenderJob {
        media: &media,
        lights: &lights,
        camera: &camera,
        width,
        height,
        spp,
        max_depth: s.max_depth,
        seed: args.sampling.seed.unwrap_or(s.seed),
        tracking,
        paths,
    };
    println!(
        "{}: {width}x{height}, {spp} spp, {} thread(s), {} rounds; tracker: {}, scheme {}, shadow rays {} ({reason})",
        args.stage.display(),
        pool.current_num_threads(),
        args.rounds,
        tracking.tracker.name(),
        tracking.scheme.name(),
        tracking.transmittance.name()
    );
    if !job(VARIANTS[2].1).single_channel() {
        println!("note: the medium is not grey (or the tracker has no single-channel twin), so the specialised and general trackers are the same code");
    }
    let mut seconds = vec![Vec::new(); VARIANTS.len()];
    let mut films: Vec<Option<Film>> = VARIANTS.iter().map(|_| None).collect();
    for _ in 0..args.rounds {
        for (i, (_, paths)) in VARIANTS.iter().enumerate() {
            let j = job(*paths);
            let t0 = Stopwatch::start(Clock::Cpu);
            let film = pool.install(|| j.render(&|| {}));
            seconds[i].push(t0.elapsed());
            films[i] = Some(film);
        }
    }
    let samples = width as f64 * height as f64 * spp as f64;
    let medians: Vec<f64> = seconds.iter_mut().map(|v| median(v)).collect();
    println!(
        "{:<24} {:>12} {:>14}",
        "variant", "median CPU s", "ns per sample"
    );
    for ((name, _), m) in VARIANTS.iter().zip(&medians) {
        println!("{name:<24} {m:>12.4} {:>14.1}", m / samples * 1e9);
    }
    println!(
        "specialised vs general: {:.3}x faster with counting, {:.3}x RGB only",
        medians[0] / medians[2],
        medians[1] / medians[3]
    );
    println!(
        "counting costs: {:+.2}% general, {:+.2}% specialised (RGB only = counting compiled out)",
        100.0 * (medians[0] / medians[1] - 1.0),
        100.0 * (medians[2] / medians[3] - 1.0)
    );
    let reference = films[0].as_ref().expect("rendered");
    for (i, (name, _)) in VARIANTS.iter().enumerate().skip(1) {
        let f = films[i].as_ref().expect("rendered");
        println!(
            "largest |difference| in R, G, B, A against \"{}\": {name} {:.3e}",
            VARIANTS[0].0,
            largest_difference(reference, f)
        );
    }
    Ok(())
}

fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

/// The largest absolute difference between two films over R, G, B and A.
pub fn largest_difference(a: &Film, b: &Film) -> f64 {
    [Aov::R, Aov::G, Aov::B, Aov::A]
        .iter()
        .flat_map(|&c| {
            a.channel(c)
                .into_iter()
                .zip(b.channel(c))
                .map(|(x, y)| (x as f64 - y as f64).abs())
        })
        .fold(0.0, f64::max)
}
