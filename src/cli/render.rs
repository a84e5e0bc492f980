//! `nimbus render`.

use crate::output::exr::{write_exr, ExrMetadata};
use crate::output::stats::{CodePathsUsed, RenderStats};
use crate::output::{check_writable, write_atomically};
use crate::render::analysis::Analysis;
use crate::render::analysis::{CodePaths, Given};
use crate::render::camera::CameraRays;
use crate::render::film::Aov;
use crate::render::job::{media_for_scene_with, RenderJob};
use crate::render::lights::Lights;
use crate::scene::{load_stage, LoadOptions, RenderSettings};
use crate::track::{
    scheme::SchemeOptions, SchemeKind, TrackerKind, TrackerSettings, TransmittanceKind,
};
use crate::volume::majorant::{MajorantSpec, MAX_DEPTH};
use crate::volume::ticks::Calibration;
use crate::volume::vdb;
use anyhow::{bail, Context, Result};
use clap::{Args, ValueEnum};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Instant;

use crate::render::film::Film;
use crate::render::progressive::{render_progressive, Budget, Clock, Progress};

#[derive(Args, Debug)]
pub struct RenderArgs {
    /// The USD stage (.usda, .usdc, .usdz).
    pub stage: PathBuf,
    /// Output EXR path. Replaces the path (`productName`) of the stage's first
    /// RenderProduct; needed when the stage has none.
    #[arg(short = 'o', long = "output")]
    pub output: Option<PathBuf>,
    #[command(flatten)]
    pub sampling: SamplingArgs,
    /// Camera prim path (overrides the render settings' camera).
    #[arg(long)]
    pub camera: Option<String>,
    /// Time code to evaluate the stage at.
    #[arg(long, conflicts_with = "frames")]
    pub frame: Option<f64>,
    /// Render the whole frames A to B (inclusive, e.g. 10-100), one EXR per frame: a
    /// run of `#` in the output file name becomes the zero-padded frame number, else
    /// `.NNNN` goes before the extension (`out.exr` → `out.0010.exr`); same for --stats.
    #[arg(long, value_name = "A-B", value_parser = parse_frame_range)]
    pub frames: Option<FrameRange>,
    /// Write render statistics as JSON to this file.
    #[arg(long)]
    pub stats: Option<PathBuf>,
    /// Maximum scattering depth (overrides nimbus:maxDepth).
    #[arg(long)]
    pub max_depth: Option<u32>,
    #[command(flatten)]
    pub majorants: MajorantArgs,
    /// Octree pruning: the cost of crossing a cell in density lookups. The walk stops
    /// higher in the octree wherever finer cells would cost more crossings than they
    /// save lookups (bounds stay valid, only cost changes); 0 keeps every level.
    #[arg(long, default_value_t = 1.0, value_name = "LOOKUPS")]
    pub octree_prune: f32,
    /// Free-path sampler (overrides nimbus:tracker). `auto` (the default) picks the
    /// tracker, scheme and options from the scene analysis; the stats say what and why.
    #[arg(long, value_parser = tracker_values())]
    pub tracker: Option<String>,
    /// Event probabilities for `spectral` and `spectral-decomposition` (overrides
    /// nimbus:scheme; default hist-avg).
    #[arg(long, value_enum)]
    pub scheme: Option<SchemeKind>,
    /// Shadow-ray transmittance estimator (overrides nimbus:transmittance; default ratio).
    #[arg(long, value_enum)]
    pub transmittance: Option<TransmittanceKind>,
    /// Control of `decomposition-weighted`, from 0 (cell minimum) to 1 (cell maximum)
    /// (overrides nimbus:control; default 0.05: higher controls make the signed residual weights
    /// grow geometrically, see the README).
    #[arg(long)]
    pub control: Option<f32>,
    /// Reduced termination rates: scattering and null take their maximum proportions,
    /// absorption the rest (spectral schemes).
    #[arg(long)]
    pub reduced_termination: bool,
    /// Never sample absorption events; absorption lives in the weights (non-emissive
    /// media only: an emissive medium is an error).
    #[arg(long)]
    pub no_absorption_events: bool,
    /// Multiplies every majorant; below 1 makes them non-bounding (for testing the
    /// weighted trackers: others report `majorant_violations`).
    #[arg(long, default_value_t = 1.0)]
    pub majorant_scale: f32,
    /// Time density lookups, majorant traversal and the rest of the trackers (stats
    /// keys lookup_seconds, traversal_seconds, other_tracker_seconds). Costs a clock
    /// read pair per lookup and per cell, which `nimbus bench octree` measures.
    #[arg(long)]
    pub profile: bool,
    /// Run the general RGB trackers even where the scene analysis allows a specialised
    /// one (single-channel tracking of grey media); for benchmarks and checks.
    #[arg(long)]
    pub no_specialise: bool,
    /// AOVs to write besides R, G, B, A (comma-separated): lookups, residual_lookups,
    /// real_collisions, null_collisions, control_collisions, max_throughput, variance.
    #[arg(long, value_delimiter = ',')]
    pub aovs: Vec<String>,
    /// Render in passes until this many seconds of rendering (loading excluded) are
    /// spent, then write; `--spp` caps the samples (without `--spp` there is no cap). The
    /// budget is kept to within one pass.
    #[arg(long, value_name = "SECONDS")]
    pub time_limit: Option<f64>,
    /// Write the EXR (and stats) every this many seconds of rendering, after the pass
    /// that crosses the interval, so a stopped render keeps its finished passes.
    #[arg(long, value_name = "SECONDS")]
    pub checkpoint: Option<f64>,
}

/// The edge of a flat majorant grid's cells when no structure is named.
pub const DEFAULT_CELL_VOXELS: u32 = 8;

/// The majorant structure flags of `render` and the benchmarks.
#[derive(Args, Debug, Clone)]
pub struct MajorantArgs {
    /// Edge of a majorant cell in voxels; 0 = one global majorant for the volume
    /// (a flat grid; ignored when --octree-depth is given) [default: 8].
    #[arg(long)]
    pub majorant_cell: Option<u32>,
    /// Majorant octree depth: 1 = one cell for the volume, d = 2^(d-1) leaf cells per
    /// axis (capped at voxel resolution). Overrides --majorant-cell and nimbus:octreeDepth.
    #[arg(long)]
    pub octree_depth: Option<u32>,
}

/// Parses "WxH" with both sides positive.
/// Flags shared by every command that renders: samples, resolution, seed, threads.
#[derive(Args, Debug, Clone)]
pub struct SamplingArgs {
    /// Samples per pixel (overrides the stage's nimbus:samples).
    #[arg(long)]
    pub spp: Option<u32>,
    /// Resolution WxH (overrides the render settings).
    #[arg(long, value_parser = parse_resolution)]
    pub res: Option<(u32, u32)>,
    /// Random seed (overrides nimbus:seed).
    #[arg(long)]
    pub seed: Option<u64>,
    /// Worker threads (default: all cores). The image does not depend on it.
    #[arg(long)]
    pub threads: Option<usize>,
}

impl SamplingArgs {
    /// Loads a stage for a benchmark (default time, the settings' camera) and returns
    /// it with the resolution: `--res`, else the render settings'; a zero side is an
    /// error naming the stage.
    pub fn load_stage(&self, stage: &Path) -> Result<(crate::scene::Scene, u32, u32)> {
        let scene = load_stage(stage, &LoadOptions::default())?;
        let (width, height) = self.res.unwrap_or(scene.settings.resolution);
        if width == 0 || height == 0 {
            bail!(
                "{}: render resolution {width}x{height} has a zero side",
                stage.display()
            );
        }
        Ok((scene, width, height))
    }
}

pub fn parse_resolution(s: &str) -> Result<(u32, u32), String> {
    let (w, h) = s
        .split_once(['x', 'X'])
        .ok_or_else(|| format!("resolution '{s}' is not of the form WIDTHxHEIGHT, e.g. 640x480"))?;
    let parse = |v: &str| {
        v.trim()
            .parse::<u32>()
            .map_err(|_| format!("'{v}' in resolution '{s}' is not a whole number"))
    };
    let (w, h) = (parse(w)?, parse(h)?);
    if w == 0 || h == 0 {
        return Err(format!("resolution '{s}' has a zero side"));
    }
    Ok((w, h))
}

/// Memory Nimbus may use for the film (bytes per pixel of accumulators), checked before
/// rendering so an absurd resolution is refused with a message instead of an abort.
const MAX_FILM_BYTES: u64 = 8 << 30;

/// Memory the system can give a new allocation without swapping (`MemAvailable` of
/// /proc/meminfo, Linux); `None` where that is not known.
fn available_memory_bytes() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = text.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024)
}

/// An inclusive range of whole frames (`--frames A-B`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FrameRange {
    pub first: i64,
    pub last: i64,
}

pub fn parse_frame_range(s: &str) -> Result<FrameRange, String> {
    let bad = || {
        format!("frame range '{s}' is not of the form A-B with whole frames A <= B, e.g. 10-100")
    };
    let (a, b) = match s.trim().split_once('-') {
        Some((a, b)) => (a, b),
        None => (s, s),
    };
    let parse = |v: &str| v.trim().parse::<i64>().map_err(|_| bad());
    let range = FrameRange {
        first: parse(a)?,
        last: parse(b)?,
    };
    if range.first > range.last {
        return Err(bad());
    }
    Ok(range)
}

/// The output path of `frame` in a sequence: the first run of `#` in the file name
/// becomes the frame number zero-padded to the run's length; without one, `.NNNN`
/// (four digits at least) goes before the extension.
pub fn frame_path(path: &Path, frame: i64) -> PathBuf {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let number = |width: usize| {
        if frame < 0 {
            format!(
                "-{:0width$}",
                frame.unsigned_abs(),
                width = width.saturating_sub(1)
            )
        } else {
            format!("{frame:0width$}")
        }
    };
    let new_name = match name.find('#') {
        Some(start) => {
            let len = name[start..].chars().take_while(|&c| c == '#').count();
            format!("{}{}{}", &name[..start], number(len), &name[start + len..])
        }
        None => match name.rfind('.').filter(|&i| i > 0) {
            Some(dot) => format!("{}.{}{}", &name[..dot], number(4), &name[dot..]),
            None => format!("{name}.{}", number(4)),
        },
    };
    path.with_file_name(new_name)
}

pub fn run(args: RenderArgs) -> Result<()> {
    let interrupted = install_interrupt_handler();
    let Some(range) = args.frames else {
        return render_frame(&args, args.frame, None, &interrupted);
    };
    // A folder that takes no files fails every frame the same way: stop at once.
    if let Some(output) = &args.output {
        check_writable(&frame_path(output, range.first))?;
    }
    if let Some(s) = &args.stats {
        check_writable(&frame_path(s, range.first))?;
    }
    // Frames are independent renders: a failing frame is reported and the others are
    // still rendered; each file is written atomically, so earlier good frames (and
    // files from a previous run) are never clobbered by a failure.
    let count = range.last - range.first + 1;
    let mut failed = Vec::new();
    for (i, frame) in (range.first..=range.last).enumerate() {
        eprintln!("nimbus: frame {frame} ({}/{count})", i + 1);
        if let Err(e) = render_frame(&args, Some(frame as f64), Some(frame), &interrupted) {
            eprintln!("nimbus: error: frame {frame}: {e:#}");
            failed.push(frame);
        }
        if interrupted.load(Ordering::SeqCst) {
            bail!("interrupted at frame {frame}; frames after it were not rendered");
        }
    }
    if !failed.is_empty() {
        let list: Vec<String> = failed.iter().map(|f| f.to_string()).collect();
        bail!(
            "{} of {count} frames failed: {}",
            failed.len(),
            list.join(", ")
        );
    }
    Ok(())
}

/// Renders the stage at `time` to the output (and stats); `sequence_frame` is the frame
/// number to put in the file names when rendering a `--frames` sequence.
fn render_frame(
    args: &RenderArgs,
    time: Option<f64>,
    sequence_frame: Option<i64>,
    interrupted: &Arc<AtomicBool>,
) -> Result<()> {
    let wall = Instant::now();
    // In a sequence every name gets the frame; for a single whole `--frame`, only
    // names with a `#` run (a productName written for sequences) do.
    let single_frame = time.filter(|t| t.fract() == 0.0 && t.abs() < 1e15);
    let name = |p: &PathBuf| match (sequence_frame, single_frame) {
        (Some(f), _) => frame_path(p, f),
        (None, Some(t)) if p.to_string_lossy().contains('#') => frame_path(p, t as i64),
        _ => p.clone(),
    };
    let stats_path = args.stats.as_ref().map(name);
    let extra_aovs = requested_aovs(&args.aovs)?;
    if let Some(s) = &stats_path {
        check_writable(s)?;
    }
    let opts = LoadOptions {
        frame: time,
        camera: args.camera.clone(),
    };
    let scene = load_stage(&args.stage, &opts)?;
    let settings = &scene.settings;
    let request = tracker_settings(args, settings)?;
    let mut tracking = request.settings;
    let outputs: Vec<ProductOutput> =
        product_outputs(args.output.as_deref(), settings, &extra_aovs)
            .with_context(|| format!("{}", args.stage.display()))?
            .into_iter()
            .map(|o| ProductOutput {
                path: name(&o.path),
                ..o
            })
            .collect();
    check_distinct(&outputs)?;
    for o in &outputs {
        check_writable(&o.path)?;
    }
    let (width, height) = args.sampling.res.unwrap_or(settings.resolution);
    let spp = args.sampling.spp.unwrap_or(settings.samples);
    let max_depth = args.max_depth.unwrap_or(settings.max_depth);
    let seed = args.sampling.seed.unwrap_or(settings.seed);
    if width == 0 || height == 0 {
        bail!(
            "{}: render resolution {width}x{height} has a zero side",
            args.stage.display()
        );
    }
    if spp == 0 {
        bail!("samples per pixel must be at least 1");
    }
    for (flag, v) in [
        ("--time-limit", args.time_limit),
        ("--checkpoint", args.checkpoint),
    ] {
        if let Some(v) = v {
            if !(v.is_finite() && v > 0.0) {
                bail!("{flag} must be a positive number of seconds, got {v}");
            }
        }
    }
    // With a time budget and no explicit --spp, the budget alone decides.
    let spp = match (args.time_limit, args.sampling.spp) {
        (Some(_), None) => u32::MAX,
        _ => spp,
    };
    let film_bytes = width as u64 * height as u64 * Film::BYTES_PER_PIXEL as u64;
    if film_bytes > MAX_FILM_BYTES {
        bail!(
            "resolution {width}x{height} needs {:.1} GiB of film memory, more than the {} GiB limit",
            film_bytes as f64 / (1u64 << 30) as f64,
            MAX_FILM_BYTES >> 30
        );
    }
    if let Some(available) = available_memory_bytes() {
        if film_bytes > available {
            bail!(
                "resolution {width}x{height} needs {:.2} GiB of film memory, more than the {:.2} GiB this machine has available",
                film_bytes as f64 / (1u64 << 30) as f64,
                available as f64 / (1u64 << 30) as f64
            );
        }
    }
    let mut spec = args.majorants.spec(settings)?;
    let mut media = media_for_scene_with(&scene, spec)?;
    let load_seconds = wall.elapsed().as_secs_f64();

    let lights = Lights::from_scene(&scene)?;
    let c = &scene.camera;
    let positive = |v: f64| v.is_finite() && v > 0.0;
    if !(positive(c.focal_length)
        && positive(c.horizontal_aperture)
        && positive(c.vertical_aperture))
    {
        bail!(
            "camera {}: focal length {} and apertures {}x{} must be positive",
            c.prim_path,
            c.focal_length,
            c.horizontal_aperture,
            c.vertical_aperture
        );
    }
    if !(c.clipping_range.0.is_finite() && c.clipping_range.1 > c.clipping_range.0) {
        bail!(
            "camera {}: clipping range {:?} is empty",
            c.prim_path,
            c.clipping_range
        );
    }
    let camera = CameraRays::new(c, width, height);
    let analysis = Analysis::of_media(&media, &lights, &camera, (width, height));
    if analysis.emissive && tracking.options.no_absorption_events {
        bail!(
            "--no-absorption-events: volume {} emits light (nimbus:temperatureField / nimbus:emissionField), and emission is collected at absorption events; drop the flag",
            media.iter().find(|m| m.emission.is_some()).map_or("", |m| &m.prim_path)
        );
    }
    let mut auto_reason = None;
    if request.auto {
        let (t, reason) = analysis.choose(tracking, request.given);
        tracking = t;
        auto_reason = Some(reason);
        if let Some(majorants) = analysis.majorants(request.given) {
            for medium in &mut media {
                medium.set_majorants(majorants);
            }
            spec = majorants;
        }
    }
    if let Some(reason) = &auto_reason {
        eprintln!(
            "nimbus: tracker auto: {} (scheme {}, transmittance {}{}): {reason}",
            tracking.tracker.name(),
            tracking.scheme.name(),
            tracking.transmittance.name(),
            if tracking.options.no_absorption_events {
                ", no absorption events"
            } else {
                ""
            }
        );
    }
    if !analysis.volume_visible {
        eprintln!(
            "nimbus: warning: no camera ray of a 16x16 probe grid reaches the volume {}: only light it scatters or shadows could show",
            media
                .iter()
                .map(|m| m.prim_path.as_str())
                .collect::<Vec<_>>()
                .join(", ")
        );
    }
    if matches!(spec, MajorantSpec::Octree { .. }) {
        for medium in &mut media {
            medium.prune_majorants(args.octree_prune, tracking.pays_residual());
        }
    }
    let job = RenderJob {
        media: &media,
        lights: &lights,
        camera: &camera,
        width,
        height,
        spp,
        max_depth,
        seed,
        tracking,
        paths: CodePaths {
            // Counting is compiled out unless something reads the counts.
            count: stats_path.is_some()
                || args.profile
                || outputs
                    .iter()
                    .any(|o| o.aovs.iter().any(|a| a.uses_counters())),
            specialise: !args.no_specialise,
        },
    };

    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(args.sampling.threads.unwrap_or(0))
        .build()
        .context("cannot start worker threads")?;
    let bar = if spp == u32::MAX {
        indicatif::ProgressBar::new_spinner()
    } else {
        indicatif::ProgressBar::new(spp as u64 * height as u64)
    };
    bar.set_style(
        indicatif::ProgressStyle::with_template(
            "{spinner} rendering [{bar:40}] {msg}, {elapsed} elapsed, ETA {eta}",
        )
        .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    let tracker = tracking.tracker.name().to_string();
    // Writes the EXR and the stats for the samples done so far (every pixel has the
    // same count after each pass).
    let calibration = tracking.profile.then(Calibration::measure);
    let write_outputs = |film: &Film, p: &Progress| -> Result<()> {
        let (totals, _samples, nonfinite) = film.totals();
        for o in &outputs {
            write_exr(
                &o.path,
                film,
                &o.aovs,
                &ExrMetadata {
                    stage: args.stage.display().to_string(),
                    tracker: tracker.clone(),
                    scheme: tracking.scheme.name().into(),
                    transmittance: tracking.transmittance.name().into(),
                    spp: p.spp,
                    render_seconds: p.seconds,
                    time: time.unwrap_or(f64::NAN),
                    product: o.prim_path.clone(),
                },
            )?;
        }
        let Some(path) = &stats_path else {
            return Ok(());
        };
        let samples = width as f64 * height as f64 * p.spp as f64;
        let times = calibration.map(|c| c.split(&totals));
        let stats = RenderStats {
            stage: args.stage.display().to_string(),
            samples_per_pixel: p.spp,
            passes: p.passes,
            max_pass_seconds: p.max_pass_seconds,
            spp_cap: (spp != u32::MAX).then_some(spp),
            time_limit_seconds: args.time_limit,
            interrupted: p.interrupted,
            width,
            height,
            wall_seconds: wall.elapsed().as_secs_f64(),
            load_seconds,
            render_seconds: p.seconds,
            threads: pool.current_num_threads(),
            seed,
            tracker: tracker.clone(),
            scheme: tracking.scheme.name().into(),
            transmittance: tracking.transmittance.name().into(),
            residual_lookups: totals.residual_lookups,
            control_collisions: totals.control_collisions,
            max_throughput_mean: totals.max_throughput / samples,
            max_throughput_peak: totals.peak_throughput,
            density_lookups: totals.density_lookups,
            emission_lookups: totals.emission_lookups,
            albedo_lookups: totals.albedo_lookups,
            clamped_albedo_values: media
                .iter()
                .map(|m| m.albedo.as_ref().map_or(0, |a| a.clamped_values))
                .sum(),
            real_collisions: totals.real_collisions,
            null_collisions: totals.null_collisions,
            cells_visited: totals.cells_visited,
            majorant_violations: totals.majorant_violations,
            nonfinite_samples: nonfinite,
            sanitized_voxels: media.iter().map(|m| m.density.sanitized_voxels).sum(),
            majorant_cells: media.iter().map(|m| m.majorants.cell_count()).sum(),
            octree_depth: match spec {
                MajorantSpec::Octree { depth } => Some(depth),
                MajorantSpec::Uniform { .. } => None,
            },
            octree_levels: media
                .iter()
                .map(|m| m.majorants.levels())
                .max()
                .unwrap_or(0),
            octree_build_seconds: media.iter().map(|m| m.majorants.build_seconds()).sum(),
            octree_memory_bytes: media.iter().map(|m| m.majorants.memory_bytes()).sum(),
            vdb_reader: vdb::active_reader().name().into(),
            lookup_seconds: times.map(|t| t.lookup_seconds),
            traversal_seconds: times.map(|t| t.traversal_seconds),
            other_tracker_seconds: times.map(|t| t.other_tracker_seconds),
            timer_empty_region_ns: calibration
                .map(|c| c.empty_region_ticks / c.ticks_per_second * 1e9),
            no_absorption_events: tracking.options.no_absorption_events,
            reduced_termination: tracking.options.reduced_termination,
            tracker_auto_reason: auto_reason.clone(),
            analysis: analysis.clone(),
            code_paths: CodePathsUsed {
                counting: job.paths.count,
                single_channel: job.single_channel(),
            },
        };
        let json = serde_json::to_string_pretty(&stats)?;
        write_atomically(path, |f| {
            use std::io::Write;
            f.write_all(json.as_bytes()).map_err(|e| e.to_string())
        })?;
        Ok(())
    };

    let budget = Budget {
        clock: Clock::Wall,
        spp_cap: spp,
        time_limit: args.time_limit,
        checkpoint: args.checkpoint,
    };
    let (film, p) = render_progressive(
        &job,
        &pool,
        &budget,
        interrupted,
        &|n| bar.inc(n as u64),
        |film, p| {
            bar.set_message(format!("{} spp in {} passes", p.spp, p.passes));
            if p.checkpoint_due {
                write_outputs(film, p).context("writing a checkpoint")?;
            }
            Ok::<(), anyhow::Error>(())
        },
    )?;
    bar.finish_and_clear();
    if p.spp == 0 {
        // Nothing rendered: keep whatever file is there rather than write a black image.
        bail!(
            "interrupted before the first pass finished; {} was not written",
            list_paths(&outputs)
        );
    }
    write_outputs(&film, &p)?;
    let (totals, _samples, nonfinite) = film.totals();
    if nonfinite > 0 {
        eprintln!("nimbus: warning: {nonfinite} samples were NaN or infinite and were dropped");
    }
    if p.interrupted {
        bail!(
            "interrupted: wrote {} with the {} samples per pixel finished in {} passes",
            list_paths(&outputs),
            p.spp,
            p.passes
        );
    }
    // Without counting (no cost AOV, no stats) there are no lookups to report.
    let lookups = match job.paths.count {
        true => format!(
            ", {:.1} lookups/sample",
            totals.density_lookups as f64 / (width as f64 * height as f64 * p.spp as f64)
        ),
        false => String::new(),
    };
    eprintln!(
        "nimbus: wrote {} ({width}x{height}, {} spp in {} passes, {:.2} s{lookups})",
        list_paths(&outputs),
        p.spp,
        p.passes,
        p.seconds,
    );
    Ok(())
}

impl MajorantArgs {
    /// The majorant structure: `--octree-depth`, else the stage's `nimbus:octreeDepth`
    /// (0 there means the flat grid), else the flat `--majorant-cell` grid.
    pub fn spec(&self, stage: &RenderSettings) -> Result<MajorantSpec> {
        let from_stage = match stage.octree_depth {
            None | Some(0) => None,
            Some(d) => Some(u32::try_from(d).map_err(|_| {
                anyhow::anyhow!(
                    "{}: nimbus:octreeDepth = {d} must lie in 0..={MAX_DEPTH}",
                    stage.prim_path.as_deref().unwrap_or("render settings")
                )
            })?),
        };
        match self.octree_depth.or(from_stage) {
            Some(depth) if !(1..=MAX_DEPTH).contains(&depth) => {
                bail!("the octree depth must lie in 1..={MAX_DEPTH}, got {depth}")
            }
            Some(depth) => Ok(MajorantSpec::Octree { depth }),
            None => Ok(MajorantSpec::Uniform {
                cell_voxels: self.majorant_cell.unwrap_or(DEFAULT_CELL_VOXELS),
            }),
        }
    }

    /// Whether the flags or the stage name a majorant structure (else `auto` may pick
    /// one).
    pub fn named(&self, stage: &RenderSettings) -> bool {
        self.majorant_cell.is_some() || self.octree_depth.is_some() || stage.octree_depth.is_some()
    }
}

/// `auto` and every tracker name.
fn tracker_values() -> clap::builder::PossibleValuesParser {
    let mut v = vec![clap::builder::PossibleValue::new("auto")];
    v.extend(
        TrackerKind::value_variants()
            .iter()
            .filter_map(|k| k.to_possible_value()),
    );
    clap::builder::PossibleValuesParser::new(v)
}

/// The tracker settings the flags and the stage ask for: `auto` (no tracker named, or
/// `auto`) leaves the tracker to [`Analysis::choose`].
struct TrackerRequest {
    settings: TrackerSettings,
    auto: bool,
    given: Given,
}

/// Tracker settings: flags override the stage's render settings, which override the
/// defaults.
fn tracker_settings(args: &RenderArgs, stage: &RenderSettings) -> Result<TrackerRequest> {
    fn from_stage<T: ValueEnum>(
        stage: &RenderSettings,
        attr: &str,
        value: &Option<String>,
    ) -> Result<Option<T>> {
        let Some(v) = value else { return Ok(None) };
        T::from_str(v, false).map(Some).map_err(|_| {
            let known: Vec<String> = T::value_variants()
                .iter()
                .filter_map(|x| x.to_possible_value())
                .map(|p| p.get_name().to_string())
                .collect();
            anyhow::anyhow!(
                "{}: {attr} = \"{v}\" is not one of {}",
                stage.prim_path.as_deref().unwrap_or("render settings"),
                known.join(", ")
            )
        })
    }
    let d = TrackerSettings::default();
    let named = match &args.tracker {
        Some(t) => Some(t.clone()),
        None => stage.tracker.clone(),
    };
    let auto = named.as_deref().is_none_or(|t| t == "auto");
    let tracker = if auto {
        d.tracker
    } else if let Some(t) = &args.tracker {
        TrackerKind::from_str(t, false).map_err(|e| anyhow::anyhow!("--tracker {t}: {e}"))?
    } else {
        from_stage(stage, "nimbus:tracker", &stage.tracker)?.unwrap_or(d.tracker)
    };
    let scheme_given = args.scheme.is_some() || stage.scheme.is_some();
    let scheme = args
        .scheme
        .or(from_stage(stage, "nimbus:scheme", &stage.scheme)?)
        .unwrap_or(d.scheme);
    let transmittance = args
        .transmittance
        .or(from_stage(
            stage,
            "nimbus:transmittance",
            &stage.transmittance,
        )?)
        .unwrap_or(d.transmittance);
    let control = args
        .control
        .or(stage.control.map(|c| c as f32))
        .unwrap_or(d.control);
    if !(control.is_finite() && (0.0..=1.0).contains(&control)) {
        bail!("the decomposition control must lie in [0, 1], got {control}");
    }
    if !(args.majorant_scale.is_finite() && args.majorant_scale > 0.0) {
        bail!(
            "--majorant-scale must be positive, got {}",
            args.majorant_scale
        );
    }
    let settings = TrackerSettings {
        tracker,
        scheme,
        transmittance,
        control,
        options: SchemeOptions {
            reduced_termination: args.reduced_termination,
            no_absorption_events: args.no_absorption_events,
        },
        majorant_scale: args.majorant_scale,
        profile: args.profile,
    };
    Ok(TrackerRequest {
        settings,
        auto,
        given: Given {
            scheme: scheme_given,
            transmittance: args.transmittance.is_some() || stage.transmittance.is_some(),
            majorants: args.majorants.named(stage),
        },
    })
}

/// The AOVs `--aovs` names.
fn requested_aovs(names: &[String]) -> Result<Vec<Aov>> {
    let mut aovs = Vec::new();
    for n in names.iter().map(|n| n.trim()).filter(|n| !n.is_empty()) {
        let Some(a) = Aov::from_name(n) else {
            let known: Vec<_> = Aov::ALL.iter().map(|a| a.channel_name()).collect();
            bail!("unknown AOV '{n}'; known AOVs: {}", known.join(", "));
        };
        if !aovs.contains(&a) {
            aovs.push(a);
        }
    }
    Ok(aovs)
}

/// One EXR to write: a RenderProduct (or the `-o` image of a stage without one) and
/// its channels.
#[derive(Clone, Debug)]
struct ProductOutput {
    path: PathBuf,
    /// The RenderProduct prim, `None` for the `-o` image of a stage without products.
    prim_path: Option<String>,
    aovs: Vec<Aov>,
}

/// The EXRs to write. Without RenderProducts: `-o` with R, G, B, A, lookups and the
/// `--aovs`. With them: one EXR per product at its `productName` (relative names are
/// relative to the working directory, as for `-o`), `-o` replacing the first product's;
/// each holds R, G, B, A and the channels of its own RenderVars, and the first also the
/// `--aovs`.
fn product_outputs(
    output: Option<&Path>,
    settings: &RenderSettings,
    extra_aovs: &[Aov],
) -> Result<Vec<ProductOutput>> {
    if settings.products.is_empty() {
        let Some(path) = output else {
            bail!("no output: the stage has no RenderProduct, so give one with -o OUT.exr");
        };
        let mut aovs = Aov::DEFAULT.to_vec();
        add_aovs(&mut aovs, extra_aovs);
        return Ok(vec![ProductOutput {
            path: path.to_path_buf(),
            prim_path: None,
            aovs,
        }]);
    }
    let mut outputs = Vec::new();
    for (i, product) in settings.products.iter().enumerate() {
        let path = match (i, output, &product.product_name) {
            (0, Some(o), _) => o.to_path_buf(),
            (_, _, Some(name)) => PathBuf::from(name),
            (_, _, None) => bail!(
                "{}: RenderProduct has no productName{}",
                product.prim_path,
                if i == 0 {
                    "; give the output with -o"
                } else {
                    ""
                }
            ),
        };
        let mut aovs = vec![Aov::R, Aov::G, Aov::B, Aov::A];
        for var in &product.vars {
            add_aovs(&mut aovs, &render_var_aovs(var)?);
        }
        if i == 0 {
            add_aovs(&mut aovs, extra_aovs);
        }
        outputs.push(ProductOutput {
            path,
            prim_path: Some(product.prim_path.clone()),
            aovs,
        });
    }
    Ok(outputs)
}

fn add_aovs(aovs: &mut Vec<Aov>, more: &[Aov]) {
    for &a in more {
        if !aovs.contains(&a) {
            aovs.push(a);
        }
    }
}

/// The channels a RenderVar names: `color` (also `C`, `Ci`, `rgb`) is R, G, B;
/// `alpha`/`a` is A; the other AOVs go by their channel names.
fn render_var_aovs(var: &crate::scene::RenderVar) -> Result<Vec<Aov>> {
    let name = var.source_name.trim();
    Ok(match name {
        "color" | "C" | "Ci" | "rgb" | "RGB" => vec![Aov::R, Aov::G, Aov::B],
        "alpha" | "a" | "A" => vec![Aov::A],
        other => match Aov::from_name(other) {
            Some(a) => vec![a],
            None => {
                let known: Vec<_> = Aov::ALL.iter().map(|a| a.channel_name()).collect();
                bail!(
                    "{}: sourceName \"{other}\" is not an AOV Nimbus knows; known: color, alpha, {}",
                    var.prim_path,
                    known.join(", ")
                );
            }
        },
    })
}

/// Two products writing one file would overwrite each other.
fn check_distinct(outputs: &[ProductOutput]) -> Result<()> {
    for (i, a) in outputs.iter().enumerate() {
        if let Some(b) = outputs[..i].iter().find(|b| b.path == a.path) {
            bail!(
                "{} and {} both write {}",
                b.prim_path.as_deref().unwrap_or("-o"),
                a.prim_path.as_deref().unwrap_or("-o"),
                a.path.display()
            );
        }
    }
    Ok(())
}

fn list_paths(outputs: &[ProductOutput]) -> String {
    outputs
        .iter()
        .map(|o| o.path.display().to_string())
        .collect::<Vec<_>>()
        .join(", ")
}

/// Installs a Ctrl-C / SIGTERM handler: the first signal asks the render to stop after
/// the current pass and write what it has; a second one exits at once (the last
/// checkpoint, written atomically, stays valid).
fn install_interrupt_handler() -> Arc<AtomicBool> {
    let flag = Arc::new(AtomicBool::new(false));
    let f = flag.clone();
    let r = ctrlc::set_handler(move || {
        if f.swap(true, Ordering::SeqCst) {
            eprintln!("\nnimbus: stopped at once; the last written file is intact");
            std::process::exit(130);
        }
        eprintln!("\nnimbus: stopping after the current pass (signal again to quit at once)");
    });
    if let Err(e) = r {
        eprintln!("nimbus: warning: cannot catch Ctrl-C/SIGTERM ({e}); a stopped render loses its unwritten passes");
    }
    flag
}
