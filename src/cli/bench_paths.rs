//! `nimbus bench paths`: what the specialised code paths of the scene analysis buy on a
//! stage. The tracker `--tracker auto` picks (or the one named) is rendered four ways — the general RGB
//! trackers or the specialised ones (single-channel tracking of grey media), each with
//! the per-pixel counting on (cost AOVs, stats) or compiled out (an RGB-only render) —
//! in interleaved rounds with the same seed, so machine noise hits all four alike,
//! timed on the process' CPU clock (other programs on a shared machine do not inflate
//! it).
//! Prints the median seconds per sample of each and the ratios, and checks that the
//! four images agree (equal decisions: differences are rounding only).

use super::choice;
use super::render::{MajorantArgs, SamplingArgs};
use crate::render::analysis::CodePaths;
use crate::render::film::{Aov, Film};
use crate::render::progressive::{Clock, Stopwatch};
use crate::render::session::Session;
use crate::track::select::{SchemeKind, TrackerKind, TransmittanceKind};
use anyhow::{bail, Result};
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
    #[arg(long, value_parser = choice::parser::<TrackerKind>())]
    pub tracker: Option<TrackerKind>,
    /// Event probabilities for `spectral` and `spectral-decomposition` instead of
    /// `auto`'s pick.
    #[arg(long, value_parser = choice::parser::<SchemeKind>())]
    pub scheme: Option<SchemeKind>,
    /// Shadow-ray transmittance estimator instead of `auto`'s pick.
    #[arg(long, value_parser = choice::parser::<TransmittanceKind>())]
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
    // The session resolves the flags as `nimbus render` does (same `auto`, same
    // majorant structure and pruning), so the four variants time what a user runs.
    let mut overrides = args.sampling.overrides(&args.majorants);
    overrides.threads = Some(args.sampling.threads.unwrap_or(1));
    overrides.tracker = args.tracker.map(|t| t.name().to_string());
    overrides.scheme = args.scheme;
    overrides.transmittance = args.transmittance;
    let session = Session::open(&args.stage, &overrides)?;
    let (width, height, spp) = (session.width, session.height, session.spp);
    let tracking = session.tracking;
    let reason = session
        .auto_reason
        .clone()
        .unwrap_or_else(|| "named on the command line".into());
    let pool = session.pool(1)?;
    let job = |paths| session.job_with(paths);
    println!(
        "{}: {width}x{height}, {spp} spp, {} thread(s), {} rounds; tracker: {}, scheme {}, shadow rays {} ({reason})",
        args.stage.display(),
        pool.current_num_threads(),
        args.rounds,
        tracking.tracker.name(),
        tracking.scheme.name(),
        tracking.transmittance.name()
    );
    if !job(VARIANTS[2].1).grey_tracking() {
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
    let mut disagree = Vec::new();
    for (i, (name, paths)) in VARIANTS.iter().enumerate().skip(1) {
        let f = films[i].as_ref().expect("rendered");
        let d = largest_difference(reference, f);
        println!(
            "largest |difference| in R, G, B, A against \"{}\": {name} {d:.3e}",
            VARIANTS[0].0,
        );
        // Counting never changes a decision: the same trackers give the same image bit
        // for bit. The single-channel trackers make the same decisions in other
        // floating-point order: rounding only.
        let tolerance = if paths.specialise == VARIANTS[0].1.specialise {
            0.0
        } else {
            SPECIALISED_TOLERANCE
        };
        if !(d <= tolerance) {
            disagree.push(format!("{name}: {d:.3e} > {tolerance:e}"));
        }
    }
    if !disagree.is_empty() {
        bail!(
            "the variants' images disagree with \"{}\" beyond rounding: {}",
            VARIANTS[0].0,
            disagree.join("; ")
        );
    }
    Ok(())
}

/// Largest pixel difference allowed between the general and the single-channel
/// trackers (the same decisions, other rounding; `tests/specialisation.rs` checks the
/// same bound).
const SPECIALISED_TOLERANCE: f64 = 1e-4;

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
