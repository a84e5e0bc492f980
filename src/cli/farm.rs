//! `nimbus farm`: job files for Slurm and Open Job Description, and the two task
//! commands they run (`farm task`: one tile of one frame; `farm merge`: one frame).

use super::render::{parse_frame_range, FrameRange, RenderArgs};
use crate::farm::{openjd, slurm, FarmJob};
use crate::output::merge::{merge, merge_frame_stats};
use crate::output::products::frame_path;
use crate::render::tiles::Tile;
use anyhow::{bail, Result};
use clap::{Args, Parser, Subcommand};
use std::path::PathBuf;

/// `nimbus render`'s flags on their own, to parse a task's render command.
#[derive(Parser, Debug)]
#[command(name = "nimbus render")]
struct RenderCommand {
    #[command(flatten)]
    args: RenderArgs,
}

/// Parses a job's render command (`render STAGE …`).
fn parse_render(command: &[String]) -> Result<RenderArgs> {
    RenderCommand::try_parse_from(command)
        .map(|c| c.args)
        .map_err(|e| anyhow::anyhow!("the render flags do not parse: {}", e.to_string().trim()))
}

#[derive(Subcommand, Debug)]
pub enum FarmCommand {
    /// Write (and with --submit, sbatch) a Slurm job array over frames x tiles plus a
    /// merge job per frame (afterany).
    Slurm(JobArgs),
    /// Write an Open Job Description template (render step over frames x tiles, merge
    /// step per frame).
    Openjd(JobArgs),
    /// Render task INDEX of a job (or --frame/--tile): one tile of one frame, skipped
    /// when its valid output exists.
    Task(TaskArgs),
    /// Merge one frame's tiles (task INDEX of the merge step, or --frame); fails, naming
    /// the tiles to re-run, when one is missing or partial.
    Merge(TaskArgs),
}

#[derive(Args, Debug)]
pub struct JobArgs {
    /// The USD stage.
    pub stage: PathBuf,
    /// Output pattern: a run of `#` becomes the frame number (added as `.####` when
    /// absent).
    #[arg(short = 'o', long = "output")]
    pub output: PathBuf,
    /// Frames A to B (inclusive).
    #[arg(long, value_name = "A-B", value_parser = parse_frame_range)]
    pub frames: FrameRange,
    /// Tiles per frame.
    #[arg(long, default_value_t = 1)]
    pub tiles: u32,
    /// Folder for the job files and logs (default: OUTPUT's folder/nimbus-job).
    #[arg(long)]
    pub dir: Option<PathBuf>,
    /// Submit with sbatch (Slurm only).
    #[arg(long)]
    pub submit: bool,
    /// Further `nimbus render` flags for every task, after `--` (e.g. `-- --spp 256`).
    #[arg(last = true)]
    pub render_args: Vec<String>,
}

#[derive(Args, Debug)]
pub struct TaskArgs {
    /// The job description (job.json in the job folder).
    #[arg(long)]
    pub job: PathBuf,
    /// The task's index in its step (Slurm's SLURM_ARRAY_TASK_ID).
    #[arg(long, conflicts_with = "frame")]
    pub index: Option<u32>,
    /// The frame (Open Job Description's task parameter).
    #[arg(long)]
    pub frame: Option<i64>,
    /// The tile (with --frame, for `farm task`).
    #[arg(long)]
    pub tile: Option<u32>,
}

pub fn run(cmd: FarmCommand) -> Result<()> {
    match cmd {
        FarmCommand::Slurm(a) => write_job(a, true),
        FarmCommand::Openjd(a) => write_job(a, false),
        FarmCommand::Task(a) => task(a),
        FarmCommand::Merge(a) => merge_frame(a),
    }
}

fn write_job(a: JobArgs, slurm: bool) -> Result<()> {
    if a.submit && !slurm {
        bail!("--submit is for `farm slurm`; submit an Open Job Description template with your Deadline tools");
    }
    let job = FarmJob::new(
        &a.stage,
        &a.output,
        (a.frames.first, a.frames.last),
        a.tiles,
        a.render_args.clone(),
    )?;
    // The render flags must parse now, not on the farm.
    let (frame, tile) = job.task(0)?;
    parse_render(&job.render_command(frame, tile))?;
    let dir = a.dir.clone().unwrap_or_else(|| {
        job.output
            .parent()
            .map_or_else(|| PathBuf::from("nimbus-job"), |p| p.join("nimbus-job"))
    });
    let job_file = job.write(&dir)?;
    if slurm {
        let files = slurm::write(&job, &job_file, &dir)?;
        eprintln!(
            "nimbus: wrote {} ({} render tasks) and {} ({} merge tasks)",
            files.render.display(),
            job.task_count(),
            files.merge.display(),
            job.frames()
        );
        if a.submit {
            let (render, merge) = slurm::submit(&files)?;
            println!("{render} {merge}");
            eprintln!("nimbus: submitted render array {render} and merge array {merge} (afterany:{render})");
        }
    } else {
        let template = openjd::write(&job, &job_file, &dir)?;
        eprintln!(
            "nimbus: wrote {} ({} render tasks, {} merge tasks)",
            template.display(),
            job.task_count(),
            job.frames()
        );
    }
    Ok(())
}

fn task(a: TaskArgs) -> Result<()> {
    let job = FarmJob::read(&a.job)?;
    let (frame, tile) = match (a.index, a.frame, a.tile) {
        (Some(i), None, None) => job.task(i)?,
        (None, Some(f), Some(t)) => {
            let i = (f - job.first_frame) * job.tiles as i64 + t as i64;
            if !(job.first_frame..=job.last_frame).contains(&f) || t >= job.tiles || i < 0 {
                bail!("frame {f} tile {t} is not a task of {}", a.job.display());
            }
            job.task(i as u32)?
        }
        _ => bail!("give --index, or --frame and --tile"),
    };
    super::render::run(parse_render(&job.render_command(frame, tile))?)
}

fn merge_frame(a: TaskArgs) -> Result<()> {
    let job = FarmJob::read(&a.job)?;
    if a.tile.is_some() {
        bail!("`farm merge` takes no --tile");
    }
    let frame = match (a.index, a.frame) {
        (Some(i), None) => job.frame(i)?,
        (None, Some(f)) if (job.first_frame..=job.last_frame).contains(&f) => f,
        (None, Some(f)) => bail!("frame {f} is not in {}", a.job.display()),
        _ => bail!("give --index or --frame"),
    };
    let (out, tiles) = job.frame_files(frame);
    let m = merge(&out, &tiles)?;
    eprintln!(
        "nimbus: frame {frame}: wrote {} ({}x{}, {} tiles{})",
        out.display(),
        m.width,
        m.height,
        m.tiles,
        m.denoise_seconds
            .map_or(String::new(), |s| format!(", denoised in {s:.2} s"))
    );
    // With --stats among the render flags, the frame's stats too, from its tiles'
    // (named as `render --frame F --tile T/N` names them), with the merge's denoising.
    let first = Tile {
        index: 0,
        count: job.tiles,
    };
    let args = parse_render(&job.render_command(frame, first))?;
    if let Some(stats) = &args.stats {
        let stats = if stats.to_string_lossy().contains('#') {
            frame_path(stats, frame)
        } else {
            stats.clone()
        };
        let name = stats
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        let tiles: Vec<PathBuf> = (0..job.tiles)
            .map(|index| {
                stats.with_file_name(
                    Tile {
                        index,
                        count: job.tiles,
                    }
                    .file_name(&name),
                )
            })
            .collect();
        merge_frame_stats(&stats, &tiles, m.denoise_seconds)?;
        eprintln!("nimbus: frame {frame}: wrote {}", stats.display());
    }
    Ok(())
}
