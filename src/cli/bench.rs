//! `nimbus bench octree`: the supplement's Tables 1 and 2 on a stage — delta and
//! decomposition tracking at several majorant octree depths, with cells visited,
//! density lookups and time. `delta` shadow rays use ratio tracking, `decomposition`
//! shadow rays residual ratio tracking.
//!
//! The time split (lookup / traversal / other) is not measured yet: those CSV columns
//! are left empty and only `total_seconds` (wall time of the render) is filled in.

use crate::output::{check_writable, write_atomically};
use crate::render::camera::CameraRays;
use crate::render::job::{medium_for_scene_with, RenderJob};
use crate::render::lights::Lights;
use crate::scene::{load_stage, LoadOptions};
use crate::track::{TrackerKind, TrackerSettings, TransmittanceKind};
use crate::volume::majorant::{MajorantSpec, MAX_DEPTH};
use anyhow::{bail, Context, Result};
use clap::{Args, Subcommand};
use std::path::PathBuf;
use std::time::Instant;

#[derive(Subcommand, Debug)]
pub enum BenchCommand {
    /// Delta vs decomposition tracking at several majorant octree depths.
    Octree(OctreeArgs),
    /// Error against time: relMSE of each tracker at each time budget vs a reference.
    Error(super::bench_error::ErrorArgs),
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
    /// Write one row per (depth, tracker) to this CSV file.
    #[arg(long)]
    pub csv: Option<PathBuf>,
}

pub const CSV_HEADER: &str = "depth,tracker,cells_visited,density_lookups,lookup_seconds,traversal_seconds,other_seconds,total_seconds";

pub fn run(cmd: BenchCommand) -> Result<()> {
    match cmd {
        BenchCommand::Octree(a) => octree(a),
        BenchCommand::Error(a) => super::bench_error::run(a),
    }
}

struct Row {
    depth: u32,
    tracker: &'static str,
    cells_visited: u64,
    density_lookups: u64,
    total_seconds: f64,
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
    let scene = load_stage(
        &args.stage,
        &LoadOptions {
            frame: None,
            camera: None,
        },
    )?;
    let s = &scene.settings;
    let (width, height) = args.sampling.res.unwrap_or(s.resolution);
    let spp = args.sampling.spp.unwrap_or(s.samples);
    if width == 0 || height == 0 || spp == 0 {
        bail!("resolution and samples per pixel must be positive");
    }
    let seed = args.sampling.seed.unwrap_or(s.seed);
    let mut medium = medium_for_scene_with(
        &scene,
        MajorantSpec::Octree {
            depth: args.depths[0],
        },
    )?;
    let lights = Lights::from_scene(&scene);
    let camera = CameraRays::new(&scene.camera, width, height);
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(args.sampling.threads.unwrap_or(0))
        .build()
        .context("cannot start worker threads")?;
    let mut rows = Vec::new();
    for &depth in &args.depths {
        let spec = MajorantSpec::Octree { depth };
        if medium.majorants.spec() != spec {
            pool.install(|| medium.set_majorants(spec));
        }
        for tracker in [TrackerKind::Delta, TrackerKind::Decomposition] {
            let job = RenderJob {
                medium: &medium,
                lights: &lights,
                camera: &camera,
                width,
                height,
                spp,
                max_depth: s.max_depth,
                seed,
                // Shadow rays pair with the free-path sampler: ratio tracking with
                // delta, residual ratio tracking (control + residual, lookups only for
                // the residual) with decomposition — otherwise most lookups of both rows
                // would be the same ratio-tracked shadow rays.
                tracking: TrackerSettings {
                    tracker,
                    transmittance: match tracker {
                        TrackerKind::Decomposition => TransmittanceKind::ResidualRatio,
                        _ => TransmittanceKind::Ratio,
                    },
                    ..TrackerSettings::default()
                },
            };
            let start = Instant::now();
            let film = pool.install(|| job.render(&|| {}));
            let total_seconds = start.elapsed().as_secs_f64();
            let (c, _, _) = film.totals();
            let row = Row {
                depth,
                tracker: tracker.name(),
                cells_visited: c.cells_visited,
                density_lookups: c.density_lookups,
                total_seconds,
                build_seconds: medium.majorants.build_seconds(),
                memory_bytes: medium.majorants.memory_bytes(),
            };
            eprintln!(
                "nimbus: depth {depth} {}: {:.2} s",
                row.tracker, row.total_seconds
            );
            rows.push(row);
        }
    }
    println!(
        "{} {width}x{height} {spp} spp, seed {seed}",
        args.stage.display()
    );
    println!(
        "{:>5} {:<14} {:>16} {:>16} {:>10} {:>10} {:>12} {:>10}",
        "depth",
        "tracker",
        "cells visited",
        "density lookups",
        "lookups×",
        "total s",
        "build s",
        "memory"
    );
    for r in &rows {
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
        println!(
            "{:>5} {:<14} {:>16} {:>16} {:>10.3} {:>10.3} {:>12.4} {:>8.1} MB",
            r.depth,
            r.tracker,
            r.cells_visited,
            r.density_lookups,
            ratio,
            r.total_seconds,
            r.build_seconds,
            r.memory_bytes as f64 / 1e6
        );
    }
    if let Some(path) = &args.csv {
        let mut text = String::from(CSV_HEADER);
        text.push('\n');
        for r in &rows {
            text.push_str(&format!(
                "{},{},{},{},,,,{}\n",
                r.depth, r.tracker, r.cells_visited, r.density_lookups, r.total_seconds
            ));
        }
        write_atomically(path, |f| {
            use std::io::Write;
            f.write_all(text.as_bytes()).map_err(|e| e.to_string())
        })?;
    }
    Ok(())
}
