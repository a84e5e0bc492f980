//! Command-line subcommands: `render`, `info` and `bench`.

mod bench;
// `bench error` lives apart from bench.rs (error vs time, its reference and plot) to
// keep merges with parallel branches conflict-free.
mod bench_error;
mod bench_grid;
mod bench_paths;
// `bench cumulus` and `bench tables` (the supplement's Tables 1 and 2) apart from
// bench.rs, to keep merges with parallel branches conflict-free.
mod bench_tables;
mod choice;
mod error_plot;
mod farm;
mod info;
mod merge;
mod render;
// `compare` is declared apart from the other modules to keep merges with parallel
// branches conflict-free.
mod compare;

use clap::{Parser, Subcommand};
use std::process::ExitCode;

#[derive(Parser, Debug)]
#[command(
    name = "nimbus",
    version,
    about = "Render heterogeneous volumes from USD stages with OpenVDB fields"
)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Subcommand, Debug)]
pub enum Command {
    /// Render a USD stage to an EXR.
    Render(render::RenderArgs),
    /// Compare two EXRs per channel: MSE, relative MSE (second image = reference), RMSE.
    Compare(compare::CompareArgs),
    /// Assemble the tiles of a frame (`render --tile I/N`) into the frame, or their
    /// stats JSONs into one; refuses missing, duplicated, partial or mismatched tiles.
    Merge(merge::MergeArgs),
    /// Render farms: Slurm job arrays and Open Job Description templates over frames x
    /// tiles, and the task commands they run.
    #[command(subcommand)]
    Farm(farm::FarmCommand),
    /// Describe a stage (volumes, fields, grids, camera, lights, render settings, the
    /// scene analysis), a VDB file or a deep EXR; `--json` for the data.
    Info(info::InfoArgs),
    /// Benchmarks (`bench octree`: trackers at several majorant octree depths; `bench
    /// error`: error against time per tracker).
    #[command(subcommand)]
    Bench(bench::BenchCommand),
}

/// Runs the CLI; errors are printed as `nimbus: error: …` with a non-zero exit.
pub fn main() -> ExitCode {
    let cli = match Cli::try_parse() {
        Ok(c) => c,
        Err(e) => {
            let _ = e.print();
            return if e.use_stderr() {
                ExitCode::from(2)
            } else {
                ExitCode::SUCCESS
            };
        }
    };
    if matches!(cli.command, Command::Info(_) | Command::Compare(_)) {
        // These only print: like other Unix tools they end quietly when their reader
        // goes away (`nimbus info … | head`) instead of panicking on a broken pipe.
        // Renders and benches keep the default, so a closed pipe cannot kill them.
        // SAFETY: setting a signal disposition to the default before any thread runs.
        unsafe {
            libc::signal(libc::SIGPIPE, libc::SIG_DFL);
        }
    }
    let result = match cli.command {
        Command::Render(a) => render::run(a),
        Command::Compare(a) => compare::run(a),
        Command::Info(a) => info::run(a),
        Command::Merge(a) => merge::run(a),
        Command::Farm(c) => farm::run(c),
        Command::Bench(c) => bench::run(c),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("nimbus: error: {e:#}");
            ExitCode::FAILURE
        }
    }
}
