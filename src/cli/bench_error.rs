//! `nimbus bench error`: error against time per tracker. Each tracker renders the stage
//! progressively for each time budget with several seeds; every image is compared with
//! a high-sample reference (relMSE and MSE as `nimbus compare` defines them, mean over
//! R, G, B). Writes a CSV, a log-log plot, and prints the equal-time table.

use super::choice;
use super::compare::channel_error;
use super::error_plot::{self, Series};
use super::reference::{self, ReferenceSettings, Rgb};
use super::render::{MajorantArgs, SamplingArgs};
use crate::output::{check_writable, write_atomically};
use crate::render::analysis::{Analysis, CodePaths, Given};
use crate::render::job::RenderJob;
use crate::render::progressive::{render_progressive, Budget, Clock};
use crate::render::session::Session;
use crate::track::select::Choice;
use crate::track::select::{SchemeKind, TrackerKind, TrackerSettings, TransmittanceKind};
use anyhow::{bail, Result};
use clap::Args;
use std::path::PathBuf;
use std::sync::atomic::AtomicBool;

#[derive(Args, Debug)]
pub struct ErrorArgs {
    /// The USD stage.
    pub stage: PathBuf,
    /// Trackers to compare (comma-separated), each TRACKER[:SCHEME][:TRANSMITTANCE]
    /// [:no-absorption-events][:reduced-termination], e.g.
    /// `spectral-decomposition:hist-avg` or `decomposition:residual-ratio`. Scheme default
    /// hist-avg, shadow rays default ratio tracking; the options as the `render` flags.
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

pub const CSV_HEADER: &str = "tracker,budget_seconds,seed,spp,density_lookups,relmse,mse";

/// Seed of a rendered reference: fixed, and refused as a bench seed, so the reference's
/// noise is independent of every image compared with it.
pub const REFERENCE_SEED: u64 = 0x5eed_0f_5eed_0f_5e;

/// A tracker to benchmark and the label it has in the CSV, table and plot.
#[derive(Clone, Debug, PartialEq)]
pub struct TrackerSpec {
    pub label: String,
    pub settings: TrackerSettings,
}

/// The tracker item that stands for `--tracker auto`'s choice on the stage.
const AUTO: &str = "auto";

/// Replaces an `auto` item by the settings the scene analysis picks, labelled
/// `auto=LABEL`, and returns the reason to print.
fn resolve_auto(trackers: &mut [TrackerSpec], analysis: &Analysis) -> Option<String> {
    let spec = trackers.iter_mut().find(|t| t.label == AUTO)?;
    let (settings, reason) = analysis.choose(TrackerSettings::default(), Given::MAJORANTS);
    spec.label = format!("{AUTO}={}", label_of(&settings));
    spec.settings = settings;
    Some(reason)
}

/// The scheme options as they are spelled in a tracker item (as the `render` flags).
const NO_ABSORPTION_EVENTS: &str = "no-absorption-events";
const REDUCED_TERMINATION: &str = "reduced-termination";

/// Parses TRACKER[:SCHEME][:TRANSMITTANCE][:no-absorption-events][:reduced-termination]
/// (parts after the tracker in any order). The label is canonical: the scheme for
/// trackers that use one, then the shadow-ray estimator when it is not ratio tracking,
/// then the options.
pub fn parse_tracker(item: &str) -> Result<TrackerSpec> {
    if item.trim() == AUTO {
        // Resolved per stage by `resolve_auto`, once the scene is analysed.
        return Ok(TrackerSpec {
            label: AUTO.into(),
            settings: TrackerSettings::default(),
        });
    }
    let mut parts = item.trim().split(':');
    let name = parts.next().unwrap_or_default().trim();
    if name.is_empty() {
        bail!(
            "empty tracker in --trackers; known trackers: {}",
            TrackerKind::names()
        );
    }
    let Some(tracker) = TrackerKind::from_name(name) else {
        bail!(
            "unknown tracker '{name}' in --trackers; known trackers: {}",
            TrackerKind::names()
        );
    };
    let mut s = TrackerSettings {
        tracker,
        ..TrackerSettings::default()
    };
    let (mut scheme, mut transmittance) = (None, None);
    for p in parts.map(str::trim) {
        if let Some(k) = SchemeKind::from_name(p) {
            if !tracker.uses_scheme() {
                bail!("tracker '{name}' takes no scheme, got '{item}'");
            }
            if scheme.replace(k).is_some() {
                bail!("'{item}' names two schemes");
            }
        } else if let Some(k) = TransmittanceKind::from_name(p) {
            if transmittance.replace(k).is_some() {
                bail!("'{item}' names two shadow-ray estimators");
            }
        } else if p == NO_ABSORPTION_EVENTS || p == REDUCED_TERMINATION {
            // spectral-mis honours no-absorption-events (not reduced termination).
            let mis = tracker == TrackerKind::SpectralMis && p == NO_ABSORPTION_EVENTS;
            if !tracker.uses_scheme() && !mis {
                bail!("tracker '{name}' takes no scheme options, got '{item}'");
            }
            let o = &mut s.options;
            let flag = if p == NO_ABSORPTION_EVENTS {
                &mut o.no_absorption_events
            } else {
                &mut o.reduced_termination
            };
            if std::mem::replace(flag, true) {
                bail!("'{item}' names '{p}' twice");
            }
        } else {
            bail!(
                "'{p}' in '{item}' is neither a scheme ({}), a shadow-ray estimator ({}) nor an option ({NO_ABSORPTION_EVENTS}, {REDUCED_TERMINATION})",
                SchemeKind::names(),
                TransmittanceKind::names()
            );
        }
    }
    s.scheme = scheme.unwrap_or(s.scheme);
    s.transmittance = transmittance.unwrap_or(s.transmittance);
    Ok(TrackerSpec {
        label: label_of(&s),
        settings: s,
    })
}

/// The canonical label of tracker settings: the tracker, its scheme when it uses one,
/// the shadow-ray estimator when it is not ratio tracking, then the options.
pub fn label_of(s: &TrackerSettings) -> String {
    let tracker = s.tracker;
    let mut label = tracker.name().to_string();
    if tracker.uses_scheme() {
        label = format!("{label}:{}", s.scheme.name());
    }
    if s.transmittance != TransmittanceKind::Ratio {
        label = format!("{label}:{}", s.transmittance.name());
    }
    if s.options.no_absorption_events {
        label = format!("{label}:{NO_ABSORPTION_EVENTS}");
    }
    if s.options.reduced_termination {
        label = format!("{label}:{REDUCED_TERMINATION}");
    }
    label
}

/// One render of the bench.
#[derive(Clone, Debug)]
pub struct Run {
    pub tracker: usize,
    pub budget: usize,
    pub seed: u64,
    pub spp: u32,
    pub seconds: f64,
    pub density_lookups: u64,
    pub relmse: f64,
    pub mse: f64,
}

/// relMSE and MSE of `image` against `reference`, mean over R, G, B (as `compare`).
pub fn rgb_error(image: &Rgb, reference: &Rgb) -> (f64, f64) {
    let (mut rel, mut mse) = (0.0, 0.0);
    for c in 0..3 {
        let e = channel_error("", &image.channels[c], &reference.channels[c]);
        rel += e.relmse / 3.0;
        mse += e.mse / 3.0;
    }
    (rel, mse)
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

/// Renders every tracker at every budget with every seed. Trackers alternate innermost
/// so a change of machine load spreads over all of them rather than hitting one.
fn measure(
    session: &mut Session,
    spp_cap: u32,
    pool: &rayon::ThreadPool,
    trackers: &[TrackerSpec],
    budgets: &[f64],
    seeds: &[u64],
    reference: &Rgb,
    clock: Clock,
) -> Result<Vec<Run>> {
    let never = AtomicBool::new(false);
    let mut runs = Vec::new();
    for &seed in seeds {
        for (b, &budget) in budgets.iter().enumerate() {
            for (t, spec) in trackers.iter().enumerate() {
                if session.tracking != spec.settings {
                    session.retrack(spec.settings);
                }
                let j = RenderJob {
                    seed,
                    spp: spp_cap,
                    ..session.job_with(CodePaths::default())
                };
                let limits = Budget {
                    spp_cap,
                    time_limit: Some(budget),
                    checkpoint: None,
                    clock,
                };
                let (film, p) =
                    render_progressive(&j, None, pool, &limits, &never, &|_| {}, |_, _| {
                        Ok::<(), anyhow::Error>(())
                    })?;
                let (counters, _, nonfinite) = film.totals();
                if nonfinite > 0 {
                    eprintln!(
                        "nimbus: warning: {} seed {seed}: {nonfinite} NaN/infinite samples dropped",
                        spec.label
                    );
                }
                let (relmse, mse) = rgb_error(&Rgb::from_film(&film), reference);
                eprintln!(
                    "nimbus: {} {budget} s seed {seed}: {} spp in {:.2} s, relMSE {relmse:.3e}",
                    spec.label, p.spp, p.seconds
                );
                runs.push(Run {
                    tracker: t,
                    budget: b,
                    seed,
                    spp: p.spp,
                    seconds: p.seconds,
                    density_lookups: counters.density_lookups,
                    relmse,
                    mse,
                });
            }
        }
    }
    Ok(runs)
}

fn write_csv(
    path: &std::path::Path,
    trackers: &[TrackerSpec],
    budgets: &[f64],
    runs: &[Run],
) -> Result<()> {
    let mut text = format!("{CSV_HEADER}\n");
    for r in runs {
        text.push_str(&format!(
            "{},{},{},{},{},{:e},{:e}\n",
            trackers[r.tracker].label,
            budgets[r.budget],
            r.seed,
            r.spp,
            r.density_lookups,
            r.relmse,
            r.mse
        ));
    }
    write_atomically(path, |f| {
        use std::io::Write;
        f.write_all(text.as_bytes()).map_err(|e| e.to_string())
    })?;
    Ok(())
}

/// Summary of one tracker at one budget over the seeds.
pub struct Cell {
    pub spp_median: f64,
    pub seconds_mean: f64,
    pub relmse_mean: f64,
    pub relmse_median: f64,
    pub relmse_min: f64,
    pub relmse_max: f64,
}

pub fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n == 0 {
        f64::NAN
    } else if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

pub fn summarize(runs: &[Run], tracker: usize, budget: usize) -> Cell {
    let rs: Vec<&Run> = runs
        .iter()
        .filter(|r| r.tracker == tracker && r.budget == budget)
        .collect();
    let n = rs.len() as f64;
    let mut rel: Vec<f64> = rs.iter().map(|r| r.relmse).collect();
    let mut spp: Vec<f64> = rs.iter().map(|r| r.spp as f64).collect();
    Cell {
        spp_median: median(&mut spp),
        seconds_mean: rs.iter().map(|r| r.seconds).sum::<f64>() / n,
        relmse_mean: rel.iter().sum::<f64>() / n,
        relmse_min: rel.iter().copied().fold(f64::INFINITY, f64::min),
        relmse_max: rel.iter().copied().fold(f64::NEG_INFINITY, f64::max),
        relmse_median: median(&mut rel),
    }
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tracker_items_parse_with_optional_scheme_and_shadow_estimator() {
        let t = parse_tracker("spectral-decomposition:hist-max").unwrap();
        assert_eq!(t.label, "spectral-decomposition:hist-max");
        assert_eq!(t.settings.scheme, SchemeKind::HistMax);
        let t = parse_tracker("spectral").unwrap();
        assert_eq!(t.label, "spectral:hist-avg");
        let t = parse_tracker("decomposition:residual-ratio").unwrap();
        assert_eq!(t.label, "decomposition:residual-ratio");
        assert_eq!(t.settings.transmittance, TransmittanceKind::ResidualRatio);
        assert_eq!(parse_tracker(" delta ").unwrap().label, "delta");
        let t = parse_tracker("spectral:no-absorption-events:max").unwrap();
        assert_eq!(t.label, "spectral:max:no-absorption-events");
        assert!(t.settings.options.no_absorption_events && !t.settings.options.reduced_termination);
        assert!(parse_tracker("delta:reduced-termination").is_err());
        let t = parse_tracker("spectral-mis:no-absorption-events").unwrap();
        assert_eq!(t.label, "spectral-mis:no-absorption-events");
        assert!(t.settings.options.no_absorption_events);
        assert!(parse_tracker("spectral-mis:reduced-termination").is_err());
        assert!(parse_tracker("spectral-mis:hist-avg").is_err());
        for bad in [
            "",
            "deltaa",
            "delta:hist-avg",
            "spectral:avg:max",
            "spectral:foo",
        ] {
            assert!(parse_tracker(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn medians() {
        assert_eq!(median(&mut [3.0, 1.0, 2.0]), 2.0);
        assert_eq!(median(&mut [4.0, 1.0, 3.0, 2.0]), 2.5);
        assert!(median(&mut []).is_nan());
    }
}
