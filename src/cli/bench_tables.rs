//! `nimbus bench cumulus` (the production-size thick and thin cloud) and `nimbus bench
//! tables` (the supplement's Tables 1 and 2 on a stage): argument parsing and printing;
//! the machinery is [`crate::bench::cumulus`] and [`crate::bench::octree_tables`].

use crate::bench::cumulus::{self, CumulusSpec};
use crate::bench::octree_tables::{self, Row, Run, Shadows, Tables, TablesConfig, TRACKERS};
use crate::output::{check_writable, write_atomically};
use crate::render::session::Session;
use crate::track::select::TrackerKind;
use anyhow::Result;
use clap::Args;
use std::path::{Path, PathBuf};

#[derive(Args, Debug)]
pub struct CumulusArgs {
    /// Output folder (created if missing): cumulus.vdb, thick.usda, thin.usda.
    #[arg(long)]
    pub out: PathBuf,
    /// Voxels across the example cloud's [-1, 1] box (the example has 128); 1152
    /// gives 203 M active voxels.
    #[arg(long, default_value_t = CumulusSpec::default().resolution)]
    pub resolution: u32,
    /// Mean free path at density 1 (the core) in the thick stage, in voxels.
    #[arg(long, default_value_t = CumulusSpec::default().mean_free_path)]
    pub mean_free_path: f64,
    /// The thin stage's density scale is the thick one's divided by this.
    #[arg(long, default_value_t = CumulusSpec::default().thin_factor)]
    pub thin_factor: f64,
}

pub fn cumulus(a: CumulusArgs) -> Result<()> {
    let spec = CumulusSpec {
        resolution: a.resolution,
        mean_free_path: a.mean_free_path,
        thin_factor: a.thin_factor,
    };
    let f = cumulus::write(&a.out, &spec)?;
    println!(
        "cumulus at {} voxels across (voxel {:.6}): {} active voxels, {} leaves, core (density ≥ 0.9) mean density {:.3}; generated in {:.1} s on {} threads",
        spec.resolution,
        spec.voxel_size(),
        f.active_voxels,
        f.leaves,
        f.core_density,
        f.generate_seconds,
        rayon::current_num_threads()
    );
    println!(
        "wrote {} ({:.1} MB, {:.1} s), {} (density scale {:.4}: mean free path {:.2} voxels at the core's mean density) and {} (density scale {:.4})",
        f.vdb.display(),
        f.vdb_bytes as f64 / 1e6,
        f.write_seconds,
        f.thick.display(),
        spec.thick_density_scale(),
        spec.mean_free_path / f.core_density,
        f.thin.display(),
        spec.thin_density_scale()
    );
    Ok(())
}

#[derive(Args, Debug)]
pub struct TablesArgs {
    /// The USD stage.
    pub stage: PathBuf,
    /// Octree depths (comma-separated).
    #[arg(long, value_delimiter = ',', default_value = "1,4,8,16")]
    pub depths: Vec<u32>,
    #[command(flatten)]
    pub sampling: super::render::SamplingArgs,
    /// Interleaved rounds per depth (each: both trackers untimed, then both timed).
    #[arg(long, default_value_t = 3)]
    pub rounds: u32,
    /// Octree pruning cost (as `render --octree-prune`); the default 0 keeps every
    /// level, the supplement's plain octree.
    #[arg(long, default_value_t = 0.0, value_name = "LOOKUPS")]
    pub prune: f32,
    /// Shadow rays: `ratio` (delta's ratio tracking, decomposition's residual ratio
    /// tracking) or `tracking` (each tracker's own free-path sampler, the track-length
    /// estimator: the same estimator in distribution for both).
    #[arg(long, value_enum, default_value_t = Shadows::Ratio)]
    pub shadows: Shadows,
    /// Only the untimed renders: totals and counts, no time split.
    #[arg(long)]
    pub no_timers: bool,
    /// Write the tables (one line per depth and tracker, and the ratios) to this CSV.
    #[arg(long)]
    pub csv: Option<PathBuf>,
    /// Write every render (round, timed or not, seconds, load average) to this CSV.
    #[arg(long)]
    pub runs_csv: Option<PathBuf>,
}

pub fn run(a: TablesArgs) -> Result<()> {
    for p in a.csv.iter().chain(&a.runs_csv) {
        check_writable(p)?;
    }
    let mut overrides = a.sampling.overrides(&super::render::MajorantArgs {
        majorant_cell: None,
        octree_depth: a.depths.first().copied(),
    });
    overrides.octree_prune = Some(a.prune);
    // One thread by default: single-core seconds, as the supplement reports them.
    overrides.threads = Some(a.sampling.threads.unwrap_or(1));
    let mut session = Session::open(&a.stage, &overrides)?;
    for w in &session.warnings {
        eprintln!("nimbus: warning: {w}");
    }
    let pool = session.pool(1)?;
    let config = TablesConfig {
        depths: a.depths.clone(),
        rounds: a.rounds,
        timed: !a.no_timers,
        shadows: a.shadows,
    };
    let tables = octree_tables::measure(&mut session, &pool, &config, print_run)?;
    print_tables(&a.stage, &tables);
    if let Some(p) = &a.csv {
        write_text(p, &tables.csv())?;
    }
    if let Some(p) = &a.runs_csv {
        write_text(p, &tables.runs_csv())?;
    }
    Ok(())
}

fn write_text(path: &Path, text: &str) -> Result<()> {
    write_atomically(path, |f| {
        use std::io::Write;
        f.write_all(text.as_bytes()).map_err(|e| e.to_string())
    })?;
    Ok(())
}

fn print_run(r: &Run) {
    eprintln!(
        "nimbus: round {} depth {} {}{}: {:.2} CPU s ({:.2} s wall), load {:.2}, {} lookups",
        r.round,
        r.depth,
        r.tracker.name(),
        if r.timed { " (timed)" } else { "" },
        r.cpu_seconds,
        r.wall_seconds,
        r.load_average,
        r.counts.density_lookups
    );
}

/// The supplement's layout: a row per quantity, per depth a column for each tracker
/// and their ratio.
fn print_tables(stage: &Path, t: &Tables) {
    println!(
        "{}: {}x{} {} spp, seed {}, {} thread(s), {} interleaved rounds, {} shadow rays, octree {}",
        stage.display(),
        t.width,
        t.height,
        t.spp,
        t.seed,
        t.threads,
        t.rounds,
        t.shadows.name(),
        if t.prune > 0.0 {
            format!("pruned (cost {})", t.prune)
        } else {
            "not pruned".into()
        }
    );
    let mut depths: Vec<u32> = t.rows.iter().map(|r| r.depth).collect();
    depths.dedup();
    const W: usize = 14;
    let mut head = format!("{:<24}", "");
    let mut sub = format!("{:<24}", "");
    for d in &depths {
        head.push_str(&format!("{:>w$}", format!("depth {d}"), w = 3 * W));
        sub.push_str(&format!(
            "{:>W$}{:>W$}{:>W$}",
            "delta", "decomposition", "dec/delta"
        ));
    }
    println!("{head}\n{sub}");
    type Cell = fn(&Row) -> f64;
    let count = |v: f64| format!("{v:.0}");
    let secs = |v: f64| format!("{v:.3}");
    let lines: [(&str, Cell, &dyn Fn(f64) -> String); 11] = [
        (
            "octree leaves visited",
            |r| r.counts.cells_visited as f64,
            &count,
        ),
        ("lookups", |r| r.counts.density_lookups as f64, &count),
        (
            "  of them residual",
            |r| r.counts.residual_lookups as f64,
            &count,
        ),
        ("lookup s", |r| r.lookup_seconds, &secs),
        ("octree s", |r| r.traversal_seconds, &secs),
        ("other tracker s", |r| r.other_tracker_seconds, &secs),
        ("outside trackers s", |r| r.outside_seconds, &secs),
        ("total s (median)", |r| r.total.median, &secs),
        ("total s (min)", |r| r.total.min, &secs),
        ("total s (max)", |r| r.total.max, &secs),
        ("timed / untimed", |r| r.timer_overhead(), &secs),
    ];
    for (label, value, fmt) in lines {
        let mut line = format!("{label:<24}");
        for &d in &depths {
            for tracker in TRACKERS {
                let v = t.row(d, tracker).map_or(f64::NAN, value);
                line.push_str(&format!("{:>W$}", fmt(v)));
            }
            // A ratio over a zero (delta's residual lookups) is left blank.
            let ratio = t.ratio(d, value);
            if ratio.is_finite() {
                line.push_str(&format!("{ratio:>W$.3}"));
            } else {
                line.push_str(&format!("{:>W$}", "-"));
            }
        }
        println!("{line}");
    }
    let mut levels = format!("{:<24}", "levels (leaf voxels)");
    let mut load = format!("{:<24}", "load average (median)");
    for &d in &depths {
        for tracker in TRACKERS {
            let r = t.row(d, tracker);
            levels.push_str(&format!(
                "{:>W$}",
                r.map_or(String::new(), |r| format!(
                    "{} ({})",
                    r.levels, r.leaf_edge[0]
                ))
            ));
            load.push_str(&format!("{:>W$.2}", r.map_or(f64::NAN, |r| r.load_average)));
        }
        levels.push_str(&format!("{:>W$}", ""));
        load.push_str(&format!("{:>W$}", ""));
    }
    println!("{levels}\n{load}");
    println!(
        "times: process CPU seconds; totals from the untimed renders, the split from the timed ones ({:.2} GHz clock, {:.1} ns per empty timed region subtracted per event, scaled by CPU / wall seconds; 'outside trackers' is the rest of a timed render)",
        t.calibration.ticks_per_second / 1e9,
        t.calibration.empty_region_ticks / t.calibration.ticks_per_second * 1e9
    );
    if let (Some(d), Some(x)) = (
        t.best(TrackerKind::Delta),
        t.best(TrackerKind::Decomposition),
    ) {
        let same = t.row(x.depth, TrackerKind::Delta);
        println!(
            "fastest delta: depth {} ({:.3} s); fastest decomposition: depth {} ({:.3} s): {:.3}x delta's best, {:.3}x delta at depth {}; lookups {:.3}x delta's at that depth",
            d.depth,
            d.total.median,
            x.depth,
            x.total.median,
            x.total.median / d.total.median,
            same.map_or(f64::NAN, |s| x.total.median / s.total.median),
            x.depth,
            same.map_or(f64::NAN, |s| x.counts.density_lookups as f64
                / s.counts.density_lookups as f64),
        );
    }
}
