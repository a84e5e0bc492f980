//! `nimbus bench error`: error against time per tracker ([`crate::bench::error`]
//! measures). Parses the arguments, then writes a CSV, a log-log plot, and prints the
//! equal-time table.

use super::choice;
use super::error_plot::{self, Series};
use super::render::{MajorantArgs, SamplingArgs};
use crate::bench::error::{
    csv_text, measure, parse_tracker, resolve_auto, summarize, Cell, Run, TrackerSpec,
    NO_ABSORPTION_EVENTS, REFERENCE_SEED,
};
use crate::bench::reference::{self, ReferenceSettings, Rgb};
use crate::output::{check_writable, write_atomically};
use crate::render::analysis::CodePaths;
use crate::render::job::RenderJob;
use crate::render::progressive::Clock;
use crate::render::session::Session;
use crate::track::select::TrackerSettings;
use anyhow::{bail, Result};
use clap::Args;
use std::path::PathBuf;

#[derive(Args, Debug)]
pub struct ErrorArgs {
    /// The USD stage.
    pub stage: PathBuf,
    /// Trackers to compare (comma-separated), each TRACKER[:SCHEME][:TRANSMITTANCE]
    /// [:no-absorption-events][:reduced-termination][:LIGHT-SAMPLING][:lights|:phase],
    /// e.g. `spectral-decomposition:hist-avg`, `decomposition:residual-ratio` or
    /// `ratio-select:collisions:phase`. Scheme default hist-avg, shadow rays default
    /// ratio tracking, light sampling and scatter guiding default auto; the options as
    /// the `render` flags.
    /// `auto` is what `render --tracker auto` picks for the stage.
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "naive-delta,delta,spectral,decomposition,spectral-decomposition,spectral-mis"
    )]
    pub trackers: Vec<String>,
    /// Time budgets in seconds of rendering (comma-separated).
    #[arg(long, value_delimiter = ',', required = true)]
    pub budgets: Vec<f64>,
    /// Seeds per tracker and budget: the base seed (`--seed`, else the stage's) and the
    /// ones after it.
    #[arg(long, default_value_t = 3)]
    pub seeds: u32,
    /// Reference image (R, G, B at the bench resolution). Without it a reference is
    /// rendered with delta tracking and cached.
    #[arg(long)]
    pub reference: Option<PathBuf>,
    /// Samples per pixel of a rendered reference.
    #[arg(long, default_value_t = 1024)]
    pub reference_spp: u32,
    /// Folder of cached references (default `$XDG_CACHE_HOME/nimbus`, else
    /// `~/.cache/nimbus`).
    #[arg(long)]
    pub cache_dir: Option<PathBuf>,
    /// Write one row per tracker, budget and seed to this CSV file.
    #[arg(long)]
    pub csv: Option<PathBuf>,
    /// Write the plot of relMSE against time to PATH_PREFIX.png and PATH_PREFIX.svg.
    #[arg(long, value_name = "PATH_PREFIX")]
    pub plot: Option<PathBuf>,
    /// Samples, resolution, base seed, threads; `--spp` caps the samples of every render.
    #[command(flatten)]
    pub sampling: SamplingArgs,
    /// Majorant structure, as for `render`.
    #[command(flatten)]
    pub majorants: MajorantArgs,
    /// The clock of the budgets: `cpu` (the process' CPU seconds, all threads: fair on
    /// a shared, loaded machine) or `wall`.
    #[arg(long, value_parser = choice::parser::<Clock>(), default_value = "cpu")]
    pub clock: Clock,
}

pub fn run(args: ErrorArgs) -> Result<()> {
    let mut trackers = args
        .trackers
        .iter()
        .map(|t| parse_tracker(t))
        .collect::<Result<Vec<_>>>()?;
    if trackers.is_empty() {
        bail!("--trackers needs at least one tracker");
    }
    for (i, t) in trackers.iter().enumerate() {
        if trackers[..i].iter().any(|u| u.label == t.label) {
            bail!("tracker '{}' is listed twice in --trackers", t.label);
        }
    }
    if args.budgets.is_empty() {
        bail!("--budgets needs at least one time budget");
    }
    for &b in &args.budgets {
        if !(b.is_finite() && b > 0.0) {
            bail!("time budgets must be positive numbers of seconds, got {b}");
        }
    }
    if args.seeds == 0 {
        bail!("--seeds must be at least 1");
    }
    if args.reference_spp == 0 {
        bail!("--reference-spp must be at least 1");
    }
    if args.sampling.spp == Some(0) {
        bail!("--spp must be at least 1");
    }
    if let Some(p) = &args.csv {
        check_writable(p)?;
    }
    if let Some(prefix) = &args.plot {
        for p in error_plot::plot_paths(prefix) {
            check_writable(&p)?;
        }
    }

    // The session loads and prunes as `nimbus render` with the same flags does; each
    // tracker below gets the majorant structure pruned for it (`Session::retrack`).
    let mut session = Session::open(&args.stage, &args.sampling.overrides(&args.majorants))?;
    let (width, height) = (session.width, session.height);
    let base_seed = session.seed;
    let seeds: Vec<u64> = (0..args.seeds as u64)
        .map(|i| base_seed.wrapping_add(i))
        .collect();
    if args.reference.is_none() && seeds.contains(&REFERENCE_SEED) {
        bail!("seed {REFERENCE_SEED} is the reference's seed; choose another --seed");
    }
    let reference_given = match &args.reference {
        Some(path) => {
            let r = Rgb::read(path)?;
            if (r.width, r.height) != (width as usize, height as usize) {
                bail!(
                    "the reference {} is {}x{} but the bench renders at {width}x{height} (set --res {}x{} or use another reference)",
                    path.display(),
                    r.width,
                    r.height,
                    r.width,
                    r.height
                );
            }
            Some(r)
        }
        None => None,
    };
    if let Some(medium) = session.media().iter().find(|m| m.emission.is_some()) {
        if let Some(t) = trackers
            .iter()
            .find(|t| t.settings.options.no_absorption_events)
        {
            bail!(
                "{}: volume {} emits light, and emission is collected at absorption events; drop {NO_ABSORPTION_EVENTS} from it",
                t.label,
                medium.prim_path
            );
        }
    }
    if let Some(reason) = resolve_auto(&mut trackers, &session.analysis) {
        println!("auto: {reason}");
    }
    let pool = session.pool(0)?;
    // The reference is rendered with delta tracking; give it the octree pruned for
    // delta, as a delta render would have it.
    session.retrack(TrackerSettings::default());
    let reference = match reference_given {
        Some(r) => r,
        None => {
            let Some(dir) = args.cache_dir.clone().or_else(reference::default_cache_dir) else {
                bail!("no cache folder for the reference: set --cache-dir (or HOME / XDG_CACHE_HOME), or pass --reference");
            };
            let r = ReferenceSettings {
                spp: args.reference_spp,
                seed: REFERENCE_SEED,
            };
            let job = RenderJob {
                spp: args.sampling.spp.unwrap_or(u32::MAX),
                ..session.job_with(CodePaths::default())
            };
            reference::cached_or_render(&session.scene, &job, &r, &dir, &pool)?.0
        }
    };

    let runs = measure(
        &mut session,
        args.sampling.spp.unwrap_or(u32::MAX),
        &pool,
        &trackers,
        &args.budgets,
        &seeds,
        &reference,
        args.clock,
        |r, nonfinite| {
            let label = &trackers[r.tracker].label;
            if nonfinite > 0 {
                eprintln!(
                    "nimbus: warning: {label} seed {}: {nonfinite} NaN/infinite samples dropped",
                    r.seed
                );
            }
            eprintln!(
                "nimbus: {label} {} s seed {}: {} spp in {:.2} s, relMSE {:.3e}",
                args.budgets[r.budget], r.seed, r.spp, r.seconds, r.relmse
            );
        },
    )?;

    if let Some(path) = &args.csv {
        write_csv(path, &trackers, &args.budgets, &runs)?;
    }
    println!(
        "{} {width}x{height}, {} seeds from {base_seed}, {} clock, spp cap {}",
        args.stage.display(),
        seeds.len(),
        match args.clock {
            Clock::Cpu => "process CPU",
            Clock::Wall => "wall",
        },
        args.sampling
            .spp
            .map_or("none".to_string(), |s| s.to_string())
    );
    print_table(&trackers, &args.budgets, &runs);
    if let Some(prefix) = &args.plot {
        let series = plot_series(&trackers, &args.budgets, &runs);
        let title = format!(
            "{}: relMSE vs time ({width}x{height}, {} seeds)",
            args.stage
                .file_name()
                .map_or_else(String::new, |n| n.to_string_lossy().into_owned()),
            seeds.len()
        );
        let [png, svg] = error_plot::write_plots(prefix, &title, &series)?;
        eprintln!("nimbus: wrote {} and {}", png.display(), svg.display());
    }
    Ok(())
}

fn write_csv(
    path: &std::path::Path,
    trackers: &[TrackerSpec],
    budgets: &[f64],
    runs: &[Run],
) -> Result<()> {
    let text = csv_text(trackers, budgets, runs);
    write_atomically(path, |f| {
        use std::io::Write;
        f.write_all(text.as_bytes()).map_err(|e| e.to_string())
    })?;
    Ok(())
}

/// The equal-time table: per budget, each tracker's relMSE (mean and median over the
/// seeds), its mean relMSE divided by the best tracker's, and the efficiency
/// 1/(relMSE × seconds) with the measured render seconds.
fn print_table(trackers: &[TrackerSpec], budgets: &[f64], runs: &[Run]) {
    let w = trackers
        .iter()
        .map(|t| t.label.len())
        .max()
        .unwrap_or(7)
        .max(7);
    for (b, &budget) in budgets.iter().enumerate() {
        let cells: Vec<Cell> = (0..trackers.len()).map(|t| summarize(runs, t, b)).collect();
        let best = cells
            .iter()
            .map(|c| c.relmse_mean)
            .fold(f64::INFINITY, f64::min);
        println!("\nbudget {budget} s: relMSE over seeds, ÷best from the means");
        println!(
            "{:<w$} {:>8} {:>8} {:>12} {:>12} {:>7} {:>11}",
            "tracker", "spp", "seconds", "relMSE mean", "relMSE med", "÷best", "efficiency"
        );
        for (t, c) in cells.iter().enumerate() {
            println!(
                "{:<w$} {:>8} {:>8.3} {:>12.4e} {:>12.4e} {:>7.2} {:>11.4e}",
                trackers[t].label,
                c.spp_median,
                c.seconds_mean,
                c.relmse_mean,
                c.relmse_median,
                c.relmse_mean / best,
                1.0 / (c.relmse_mean * c.seconds_mean)
            );
        }
    }
}

/// One line per tracker: mean relMSE over seeds at the mean measured seconds, with the
/// range over seeds, in order of time.
fn plot_series(trackers: &[TrackerSpec], budgets: &[f64], runs: &[Run]) -> Vec<Series> {
    trackers
        .iter()
        .enumerate()
        .map(|(t, spec)| {
            let mut points: Vec<_> = (0..budgets.len())
                .map(|b| {
                    let c = summarize(runs, t, b);
                    (c.seconds_mean, c.relmse_mean, c.relmse_min, c.relmse_max)
                })
                .collect();
            points.sort_by(|a, b| a.0.total_cmp(&b.0));
            Series {
                label: spec.label.clone(),
                points,
            }
        })
        .collect()
}
