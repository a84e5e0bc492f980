//! `nimbus bench octree`: the supplement's Tables 1 and 2 on a stage — delta and
//! decomposition tracking at several majorant octree depths, with cells visited,
//! density lookups and time. `delta` shadow rays use ratio tracking, `decomposition`
//! shadow rays residual ratio tracking.
//!
//! Each (depth, tracker) is rendered twice with the same seed: untimed, for
//! `total_seconds` (wall time), and with the tracker timers on (`--profile`), for the
//! split into lookup, traversal and other tracker time. Both runs make exactly the same
//! lookups and visit the same cells (timing changes no random decision); the timed
//! run's extra wall time is the timers' overhead, printed beside the table. The split
//! is in thread-seconds: with the default single worker thread it is comparable with
//! the wall time.

use crate::output::{check_writable, write_atomically};
use crate::render::analysis::CodePaths;
use crate::render::job::RenderJob;
use crate::render::session::Session;
use crate::track::select::{TrackerKind, TrackerSettings, TransmittanceKind};
use crate::volume::majorant::{MajorantSpec, MAX_DEPTH};
use crate::volume::ticks::{Calibration, TrackerTimes};
use anyhow::{bail, Result};
use clap::{Args, Subcommand};
use std::path::PathBuf;
use std::time::Instant;

#[derive(Subcommand, Debug)]
pub enum BenchCommand {
    /// Delta vs decomposition tracking at several majorant octree depths.
    Octree(OctreeArgs),
    /// Error against time: relMSE of each tracker at each time budget vs a reference.
    Error(super::bench_error::ErrorArgs),
    /// The specialised code paths (single-channel grey tracking, counting compiled
    /// out) against the general ones, with the tracker `auto` picks.
    Paths(super::bench_paths::PathsArgs),
    /// Production-size grids: `make` a large grid from a real VDB, `measure` its load
    /// time, memory per active voxel and ns per lookup.
    #[command(subcommand)]
    Grid(super::bench_grid::GridCommand),
    /// Write the production-size cumulus (the example cloud's field at ≥ 200 M active
    /// voxels) as OUT/cumulus.vdb with a thick and a thin stage, OUT/thick.usda and
    /// OUT/thin.usda, for `bench tables`.
    Cumulus(super::bench_tables::CumulusArgs),
    /// The supplement's Tables 1 and 2: delta and decomposition tracking at several
    /// octree depths, interleaved rounds, medians; counts, lookup, octree and other time.
    Tables(super::bench_tables::TablesArgs),
}

#[derive(Args, Debug)]
pub struct OctreeArgs {
    /// The USD stage.
    pub stage: PathBuf,
    /// Octree depths to compare (comma-separated).
    #[arg(long, value_delimiter = ',', default_value = "1,4,8,16")]
    pub depths: Vec<u32>,
    #[command(flatten)]
    pub sampling: super::render::SamplingArgs,
    /// Octree pruning cost (a cell crossing in lookups, as `render --octree-prune`);
    /// 0 keeps every level (the supplement's plain octree).
    #[arg(long, default_value_t = 1.0, value_name = "LOOKUPS")]
    pub prune: f32,
    /// Write one row per (depth, tracker) to this CSV file.
    #[arg(long)]
    pub csv: Option<PathBuf>,
}

pub const CSV_HEADER: &str = "depth,tracker,cells_visited,density_lookups,lookup_seconds,traversal_seconds,other_seconds,total_seconds";

pub fn run(cmd: BenchCommand) -> Result<()> {
    match cmd {
        BenchCommand::Octree(a) => octree(a),
        BenchCommand::Error(a) => super::bench_error::run(a),
        BenchCommand::Paths(a) => super::bench_paths::run(a),
        BenchCommand::Grid(c) => super::bench_grid::run(c),
        BenchCommand::Cumulus(a) => super::bench_tables::cumulus(a),
        BenchCommand::Tables(a) => super::bench_tables::run(a),
    }
}

struct Row {
    depth: u32,
    tracker: &'static str,
    cells_visited: u64,
    density_lookups: u64,
    total_seconds: f64,
    times: TrackerTimes,
    timed_seconds: f64,
    build_seconds: f64,
    memory_bytes: usize,
}

fn octree(args: OctreeArgs) -> Result<()> {
    if args.depths.is_empty() {
        bail!("--depths needs at least one depth");
    }
    for &d in &args.depths {
        if !(1..=MAX_DEPTH).contains(&d) {
            bail!("octree depths must lie in 1..={MAX_DEPTH}, got {d}");
        }
    }
    if let Some(p) = &args.csv {
        check_writable(p)?;
    }
    // The session renders as `nimbus render --octree-depth D` does: the same loading,
    // the same octree and the same pruning for each tracker.
    let mut overrides = args.sampling.overrides(&super::render::MajorantArgs {
        majorant_cell: None,
        octree_depth: Some(args.depths[0]),
    });
    overrides.octree_prune = Some(args.prune);
    // One thread by default: the timers measure thread-seconds, which then add up to
    // the wall time.
    overrides.threads = Some(args.sampling.threads.unwrap_or(1));
    let mut session = Session::open(&args.stage, &overrides)?;
    let (width, height, spp, seed) = (session.width, session.height, session.spp, session.seed);
    let pool = session.pool(1)?;
    let threads = pool.current_num_threads();
    let calibration = Calibration::measure();
    let mut rows = Vec::new();
    for &depth in &args.depths {
        for tracker in [TrackerKind::Delta, TrackerKind::Decomposition] {
            // Shadow rays pair with the free-path sampler: ratio tracking with delta,
            // residual ratio tracking (control + residual, lookups only for the
            // residual) with decomposition — otherwise most lookups of both rows would
            // be the same ratio-tracked shadow rays. Pruning depends on the tracker, so
            // each row gets a fresh octree.
            session.spec = MajorantSpec::Octree { depth };
            pool.install(|| {
                session.retrack(TrackerSettings {
                    tracker,
                    transmittance: match tracker {
                        TrackerKind::Decomposition => TransmittanceKind::ResidualRatio,
                        _ => TransmittanceKind::Ratio,
                    },
                    ..TrackerSettings::default()
                })
            });
            let job = session.job_with(CodePaths::default());
            let media = session.media();
            let start = Instant::now();
            let film = pool.install(|| job.render(&|| {}));
            let total_seconds = start.elapsed().as_secs_f64();
            let (c, _, _) = film.totals();
            let timed_job = RenderJob {
                paths: CodePaths::default(),
                tracking: TrackerSettings {
                    profile: true,
                    ..job.tracking
                },
                ..job
            };
            let start = Instant::now();
            let timed = pool.install(|| timed_job.render(&|| {}));
            let timed_seconds = start.elapsed().as_secs_f64();
            let (tc, _, _) = timed.totals();
            if (tc.density_lookups, tc.cells_visited) != (c.density_lookups, c.cells_visited) {
                bail!("internal error: the timed run made different lookups than the untimed one");
            }
            let row = Row {
                depth,
                tracker: tracker.name(),
                cells_visited: c.cells_visited,
                density_lookups: c.density_lookups,
                total_seconds,
                times: calibration.split(&tc),
                timed_seconds,
                build_seconds: media.iter().map(|m| m.majorants.build_seconds()).sum(),
                memory_bytes: media.iter().map(|m| m.majorants.memory_bytes()).sum(),
            };
            eprintln!(
                "nimbus: depth {depth} {}: {:.2} s ({} majorant cells after pruning)",
                row.tracker,
                row.total_seconds,
                media
                    .iter()
                    .map(|m| m.majorants.cell_count())
                    .sum::<usize>()
            );
            rows.push(row);
        }
    }
    print_table(
        &args,
        (width, height, spp, seed, threads),
        &calibration,
        &rows,
    );
    if let Some(path) = &args.csv {
        let mut text = String::from(CSV_HEADER);
        text.push('\n');
        for r in &rows {
            let t = &r.times;
            text.push_str(&format!(
                "{},{},{},{},{},{},{},{}\n",
                r.depth,
                r.tracker,
                r.cells_visited,
                r.density_lookups,
                t.lookup_seconds,
                t.traversal_seconds,
                t.other_tracker_seconds,
                r.total_seconds
            ));
        }
        write_atomically(path, |f| {
            use std::io::Write;
            f.write_all(text.as_bytes()).map_err(|e| e.to_string())
        })?;
    }
    Ok(())
}

/// The supplement's layout: per depth and tracker, cells (leaves) visited, density
/// lookups, and the time split, then the three ratios.
fn print_table(
    args: &OctreeArgs,
    (width, height, spp, seed, threads): (u32, u32, u32, u64, usize),
    cal: &Calibration,
    rows: &[Row],
) {
    println!(
        "{} {width}x{height} {spp} spp, seed {seed}, {threads} thread(s)",
        args.stage.display()
    );
    println!(
        "{:>5} {:<14} {:>14} {:>14} {:>8} {:>9} {:>9} {:>9} {:>9} {:>8} {:>9} {:>8} {:>8}",
        "depth",
        "tracker",
        "cells visited",
        "lookups",
        "lookups×",
        "lookup s",
        "travers s",
        "other s",
        "total s",
        "travers%",
        "timed s",
        "build s",
        "memory"
    );
    for r in rows {
        // Lookups relative to delta tracking at the same depth.
        let delta = rows
            .iter()
            .find(|d| d.depth == r.depth && d.tracker == "delta")
            .map_or(0, |d| d.density_lookups);
        let ratio = if delta > 0 {
            r.density_lookups as f64 / delta as f64
        } else {
            f64::NAN
        };
        let t = &r.times;
        println!(
            "{:>5} {:<14} {:>14} {:>14} {:>8.3} {:>9.3} {:>9.3} {:>9.3} {:>9.3} {:>7.1}% {:>9.3} {:>8.4} {:>5.1} MB",
            r.depth,
            r.tracker,
            r.cells_visited,
            r.density_lookups,
            ratio,
            t.lookup_seconds,
            t.traversal_seconds,
            t.other_tracker_seconds,
            r.total_seconds,
            100.0 * t.traversal_seconds / r.timed_seconds,
            r.timed_seconds,
            r.build_seconds,
            r.memory_bytes as f64 / 1e6
        );
    }
    println!(
        "timers: {:.2} GHz clock, an empty timed region reads {:.1} ns (subtracted per event); \
         'timed s' is the wall time of the timed run, 'travers%' its traversal share",
        cal.ticks_per_second / 1e9,
        cal.empty_region_ticks / cal.ticks_per_second * 1e9
    );
    let best = |tracker: &str| {
        rows.iter()
            .filter(|r| r.tracker == tracker)
            .min_by(|a, b| a.total_seconds.total_cmp(&b.total_seconds))
    };
    let shallowest_delta = rows
        .iter()
        .filter(|r| r.tracker == "delta")
        .min_by_key(|r| r.depth);
    if let (Some(dec), Some(delta0)) = (best("decomposition"), shallowest_delta) {
        let delta_same = rows
            .iter()
            .find(|r| r.tracker == "delta" && r.depth == dec.depth);
        println!(
            "fastest decomposition: depth {}; lookups vs delta at that depth {:.3}×; time vs delta at depth {} {:.3}×; traversal share {:.1}%",
            dec.depth,
            delta_same.map_or(f64::NAN, |d| dec.density_lookups as f64 / d.density_lookups as f64),
            delta0.depth,
            dec.total_seconds / delta0.total_seconds,
            100.0 * dec.times.traversal_seconds / dec.timed_seconds
        );
    }
}
