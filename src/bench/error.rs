//! `nimbus bench error`'s measurement: error against time per tracker. Each tracker
//! renders the stage progressively for each time budget with several seeds; every image
//! is compared with a high-sample reference ([`super::reference`]; relMSE and MSE as
//! [`crate::output::compare`] defines them, mean over R, G, B). The CLI parses the
//! arguments and prints the table, CSV and plot of what [`measure`] returns.

use super::reference::Rgb;
use super::stats::median;
use crate::output::compare::channel_error;
use crate::render::analysis::{Analysis, CodePaths, Given};
use crate::render::job::RenderJob;
use crate::render::progressive::{render_progressive, Budget, Clock};
use crate::render::session::Session;
use crate::track::select::Choice;
use crate::track::select::{
    LightSampling, ScatterGuiding, SchemeKind, TrackerKind, TrackerSettings, TransmittanceKind,
};
use anyhow::{bail, Result};
use std::sync::atomic::AtomicBool;

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
pub const AUTO: &str = "auto";

/// Replaces an `auto` item by the settings the scene analysis picks, labelled
/// `auto=LABEL`, and returns the reason to print.
pub fn resolve_auto(trackers: &mut [TrackerSpec], analysis: &Analysis) -> Option<String> {
    let spec = trackers.iter_mut().find(|t| t.label == AUTO)?;
    let (settings, reason) = analysis.choose(TrackerSettings::default(), Given::MAJORANTS);
    spec.label = format!("{AUTO}={}", label_of(&settings));
    spec.settings = settings;
    Some(reason)
}

/// The scheme options as they are spelled in a tracker item (as the `render` flags).
pub const NO_ABSORPTION_EVENTS: &str = "no-absorption-events";
pub const REDUCED_TERMINATION: &str = "reduced-termination";

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
    let (mut scheme, mut transmittance, mut lights) = (None, None, None);
    let mut guiding = None;
    for p in parts.map(str::trim) {
        if let Some(k) = LightSampling::from_name(p) {
            if lights.replace(k).is_some() {
                bail!("'{item}' names two ways of sampling near local lights");
            }
        } else if let Some(k) = ScatterGuiding::from_name(p) {
            // `auto` is taken by the light sampling above: `lights` or `phase` here.
            if guiding.replace(k).is_some() {
                bail!("'{item}' names two ways of guiding scattered directions");
            }
        } else if let Some(k) = SchemeKind::from_name(p) {
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
                "'{p}' in '{item}' is neither a scheme ({}), a shadow-ray estimator ({}), a light sampling ({}), a scatter guiding (lights, phase) nor an option ({NO_ABSORPTION_EVENTS}, {REDUCED_TERMINATION})",
                SchemeKind::names(),
                TransmittanceKind::names(),
                LightSampling::names()
            );
        }
    }
    s.scheme = scheme.unwrap_or(s.scheme);
    s.transmittance = transmittance.unwrap_or(s.transmittance);
    s.light_sampling = lights.unwrap_or(s.light_sampling);
    s.scatter_guiding = guiding.unwrap_or(s.scatter_guiding);
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
    if s.light_sampling != LightSampling::Auto {
        label = format!("{label}:{}", s.light_sampling.name());
    }
    if s.scatter_guiding != ScatterGuiding::Auto {
        label = format!("{label}:{}", s.scatter_guiding.name());
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

/// Renders every tracker at every budget with every seed. Trackers alternate innermost
/// so a change of machine load spreads over all of them rather than hitting one.
/// `on_run` hears of each render as it ends, with the NaN/infinite samples it dropped.
#[allow(clippy::too_many_arguments)]
pub fn measure(
    session: &mut Session,
    spp_cap: u32,
    pool: &rayon::ThreadPool,
    trackers: &[TrackerSpec],
    budgets: &[f64],
    seeds: &[u64],
    reference: &Rgb,
    clock: Clock,
    mut on_run: impl FnMut(&Run, u64),
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
                let (relmse, mse) = rgb_error(&Rgb::from_film(&film), reference);
                let run = Run {
                    tracker: t,
                    budget: b,
                    seed,
                    spp: p.spp,
                    seconds: p.seconds,
                    density_lookups: counters.density_lookups,
                    relmse,
                    mse,
                };
                on_run(&run, nonfinite);
                runs.push(run);
            }
        }
    }
    Ok(runs)
}

/// The CSV of the runs: [`CSV_HEADER`], then one row per run.
pub fn csv_text(trackers: &[TrackerSpec], budgets: &[f64], runs: &[Run]) -> String {
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
    text
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
        let t = parse_tracker("ratio-select:phase:collisions").unwrap();
        assert_eq!(t.label, "ratio-select:collisions:phase");
        assert_eq!(t.settings.scatter_guiding, ScatterGuiding::Phase);
        assert_eq!(t.settings.light_sampling, LightSampling::Collisions);
        assert_eq!(parse_tracker("delta:lights").unwrap().label, "delta:lights");
        assert!(parse_tracker("delta:lights:phase").is_err());
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
}
