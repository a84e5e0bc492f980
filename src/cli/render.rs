//! `nimbus render`: flags → [`Overrides`] and an [`OutputRequest`], then the library's
//! [`Session`] renders and [`Outputs`] writes; this file parses and prints.

use super::choice;
use crate::output::check_writable;
use crate::output::products::{frame_path, requested_outputs, OutputRequest, Outputs};
use crate::output::stats::RunFacts;
use crate::render::film::Region;
use crate::render::progressive::Clock;
use crate::render::sampler::SamplerKind;
use crate::render::session::{Overrides, Session};
use crate::render::tiles::{parse_region, Tile};
use crate::track::select::{
    LightSampling, ScatterGuiding, SchemeKind, TrackerKind, TransmittanceKind,
};
use anyhow::{bail, Result};
use clap::Args;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Instant;

#[derive(Args, Debug)]
pub struct RenderArgs {
    /// The USD stage (.usda, .usdc, .usdz), or a .vdb file to render directly (its
    /// first float grid as density, a default camera, sun and sky).
    pub stage: PathBuf,
    /// Output EXR path. Replaces the path (`productName`) of the stage's first
    /// RenderProduct; needed when the stage has none.
    #[arg(short = 'o', long = "output")]
    pub output: Option<PathBuf>,
    #[command(flatten)]
    pub sampling: SamplingArgs,
    /// The density grid when STAGE is a .vdb file rendered directly (default: its first
    /// float grid).
    #[arg(long)]
    pub grid: Option<String>,
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
    /// Also write a tone-mapped sRGB PNG of the beauty here (to look at without an EXR
    /// viewer); a RenderProduct asks for one with nimbus:previewName.
    #[arg(long, value_name = "OUT.png")]
    pub preview: Option<PathBuf>,
    /// Render only tile I of N (0-based; the frame split into an N-tile grid, as square
    /// as N allows) for a farm task: every output name gets `.tileI` before its
    /// extension, and `nimbus merge` assembles the tiles into the frame.
    #[arg(long, value_name = "I/N", value_parser = Tile::parse, conflicts_with = "region")]
    pub tile: Option<Tile>,
    /// Render only the pixels X0..X1 x Y0..Y1 of the full frame (the EXR's data window
    /// inside the full display window).
    #[arg(long, value_name = "X0,Y0,X1,Y1", value_parser = parse_region)]
    pub region: Option<Region>,
    /// Do nothing (exit 0) when every EXR of this tile or region already exists,
    /// complete and from the same settings: farm tasks are idempotent with it.
    #[arg(long)]
    pub skip_complete: bool,
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
    /// Default 1; 0.2 for the octree `auto` builds for a density shader graph, whose
    /// lookups cost about five brick reads.
    #[arg(long, value_name = "LOOKUPS")]
    pub octree_prune: Option<f32>,
    /// Free-path sampler (overrides nimbus:tracker). `auto` (the default) picks the
    /// tracker, scheme and options from the scene analysis; the stats say what and why.
    #[arg(long, value_parser = tracker_values())]
    pub tracker: Option<String>,
    /// Event probabilities for `spectral` and `spectral-decomposition` (overrides
    /// nimbus:scheme; default hist-avg).
    #[arg(long, value_parser = choice::parser::<SchemeKind>())]
    pub scheme: Option<SchemeKind>,
    /// Shadow-ray transmittance estimator (overrides nimbus:transmittance; default ratio).
    #[arg(long, value_parser = choice::parser::<TransmittanceKind>())]
    pub transmittance: Option<TransmittanceKind>,
    /// Control of `decomposition-weighted`, from 0 (cell minimum) to 1 (cell maximum)
    /// (overrides nimbus:control; default 0.05: higher controls make the signed residual weights
    /// grow geometrically, see docs/trackers.md).
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
    /// Scattering points near local lights: the trackers' collisions alone, or plus one
    /// per path segment sampled equiangularly towards a light (a spot's only inside its
    /// cone), combined by MIS; `auto` (default) takes the second for every local light
    /// where every medium is homogeneous (fog boxes, world fog) and for spots in grids,
    /// where it pays (docs/trackers.md). Stages with only distant and dome lights
    /// render the same either way.
    #[arg(long, value_parser = choice::parser::<LightSampling>())]
    pub light_sampling: Option<LightSampling>,
    /// Where a path goes after a scattering vertex: the phase function alone, or half
    /// the time a lobe towards a local light, weighted as one mixture; `auto`
    /// (default) guides towards point, sphere and spot lights on stages with no sun or
    /// dome (docs/trackers.md).
    /// Stages with only distant and dome lights render the same either way.
    #[arg(long, value_parser = choice::parser::<ScatterGuiding>())]
    pub scatter_guiding: Option<ScatterGuiding>,
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
    /// real_collisions, null_collisions, control_collisions, max_throughput, variance,
    /// samples (per pixel: adaptive sampling stops pixels early), beauty_variance.R, .G,
    /// .B (the variance of each pixel's value), albedo.R, albedo.G, albedo.B (the
    /// albedo at the first scattering event; --denoise adds these and samples);
    /// and the RGB splits of the beauty: emission (light reaching the camera unscattered),
    /// direct (scattered once), indirect (twice or more), lightgroup:GROUP (the lights,
    /// or emissive volumes, whose nimbus:lightGroup or prim path is GROUP).
    #[arg(long, value_delimiter = ',')]
    pub aovs: Vec<String>,
    /// Also write a deep scanline EXR of the beauty (Z, ZBack, premultiplied RGBA per
    /// sample): each path's radiance binned by the camera depth of its first real
    /// collision. A RenderProduct asks for one with productType = "deepRaster".
    #[arg(long, value_name = "OUT.exr")]
    pub deep: Option<PathBuf>,
    /// Deep samples per pixel at most (adjacent depth slabs are merged down to it).
    #[arg(long, value_name = "N", default_value_t = 32, value_parser = clap::value_parser!(u16).range(1..=32))]
    pub deep_samples: u16,
    /// Render in passes until this many seconds of rendering (loading excluded) are
    /// spent, then write; `--spp` caps the samples (without `--spp` there is no cap). The
    /// budget is kept to within one pass.
    #[arg(long, value_name = "SECONDS")]
    pub time_limit: Option<f64>,
    /// Adaptive sampling: each pixel stops once its noise estimate (what Cycles'
    /// measure estimates, from each channel's sample variance; 0.01 is Cycles' default) is below T,
    /// checked every 4 samples after --min-spp; 0 = off (overrides
    /// nimbus:noiseThreshold). The `samples` AOV shows where samples went.
    #[arg(long, value_name = "T")]
    pub noise_threshold: Option<f64>,
    /// Samples every pixel takes before adaptive sampling may stop it (default: the
    /// square root of the sample count, at least 16; overrides nimbus:minSamples).
    #[arg(long, value_name = "N")]
    pub min_spp: Option<u32>,
    /// Denoise with Open Image Denoise (its RT filter, guided by the albedo AOV, which
    /// is written too): R, G, B are the denoised beauty, mixed back towards the noisy
    /// one where the pixel's variance (beauty_variance, written too) says that is
    /// closer; the noisy one is kept as noisy.R/G/B, each split layer is denoised on
    /// its own and mixed with the beauty's weights; a --tile is not denoised
    /// (`merge` denoises the frame). As nimbus:denoise; --no-denoise turns it off.
    #[arg(long, conflicts_with = "no_denoise")]
    pub denoise: bool,
    /// Do not denoise, whatever nimbus:denoise says.
    #[arg(long)]
    pub no_denoise: bool,
    /// Write the EXR (and stats) every this many seconds of rendering, after the pass
    /// that crosses the interval, so a stopped render keeps its finished passes.
    #[arg(long, value_name = "SECONDS")]
    pub checkpoint: Option<f64>,
    /// Refuse to render anything the stage asks for that the render would not show as
    /// authored (each stage warning is an error), and refuse the default camera and
    /// lights; as nimbus:strict on the RenderSettings prim.
    #[arg(long)]
    pub strict: bool,
    /// Never add the default sun and sky to a stage that has no light prim and no
    /// emissive volume: render it unlit.
    #[arg(long)]
    pub no_default_lights: bool,
}

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
    /// Where each sample's random numbers come from (default sobol).
    #[arg(long, value_parser = choice::parser::<SamplerKind>())]
    pub sampler: Option<SamplerKind>,
}

/// Parses "WxH" with both sides positive.
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

impl SamplingArgs {
    /// These flags as session overrides.
    pub fn overrides(&self, majorants: &MajorantArgs) -> Overrides {
        Overrides {
            spp: self.spp,
            res: self.res,
            seed: self.seed,
            sampler: self.sampler,
            threads: self.threads,
            majorant_cell: majorants.majorant_cell,
            octree_depth: majorants.octree_depth,
            ..Overrides::default()
        }
    }
}

impl RenderArgs {
    /// The session overrides these flags ask for, at `frame`.
    pub fn overrides(&self, frame: Option<f64>) -> Overrides {
        Overrides {
            frame,
            camera: self.camera.clone(),
            max_depth: self.max_depth,
            octree_prune: self.octree_prune,
            tracker: self.tracker.clone(),
            scheme: self.scheme,
            transmittance: self.transmittance,
            control: self.control,
            reduced_termination: self.reduced_termination,
            no_absorption_events: self.no_absorption_events,
            majorant_scale: Some(self.majorant_scale),
            light_sampling: self.light_sampling,
            scatter_guiding: self.scatter_guiding,
            profile: self.profile,
            no_specialise: self.no_specialise,
            time_limit: self.time_limit,
            noise_threshold: self.noise_threshold,
            min_spp: self.min_spp,
            denoise: match (self.denoise, self.no_denoise) {
                (true, _) => Some(true),
                (_, true) => Some(false),
                _ => None,
            },
            grid: self.grid.clone(),
            strict: self.strict,
            no_default_lights: self.no_default_lights,
            ..self.sampling.overrides(&self.majorants)
        }
    }
}

pub fn run(args: RenderArgs) -> Result<()> {
    if let Some(v) = args.checkpoint {
        if !(v.is_finite() && v > 0.0) {
            bail!("--checkpoint must be a positive number of seconds, got {v}");
        }
    }
    let (aovs, layers) = requested_outputs(&args.aovs)?;
    let request = OutputRequest {
        output: args.output.clone(),
        aovs,
        layers,
        deep: args.deep.clone(),
        deep_samples: args.deep_samples as usize,
        stats: args.stats.clone(),
        preview: args.preview.clone(),
        tile: args.tile,
        region: args.region.is_some(),
    };
    let interrupted = install_interrupt_handler();
    let Some(range) = args.frames else {
        return render_frame(&args, &request, args.frame, false, &interrupted);
    };
    // A folder that takes no files fails every frame the same way: stop at once.
    for p in [&args.output, &args.stats, &args.preview, &args.deep]
        .into_iter()
        .flatten()
    {
        check_writable(&frame_path(p, range.first))?;
    }
    // Frames are independent renders: a failing frame is reported and the others are
    // still rendered; each file is written atomically, so earlier good frames (and
    // files from a previous run) are never clobbered by a failure.
    let count = range.last - range.first + 1;
    let mut failed = Vec::new();
    for (i, frame) in (range.first..=range.last).enumerate() {
        eprintln!("nimbus: frame {frame} ({}/{count})", i + 1);
        if let Err(e) = render_frame(&args, &request, Some(frame as f64), true, &interrupted) {
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

/// Renders the stage at `frame` to its outputs; `sequence` names the files for the
/// frame (a `--frames` sequence).
fn render_frame(
    args: &RenderArgs,
    request: &OutputRequest,
    frame: Option<f64>,
    sequence: bool,
    interrupted: &Arc<AtomicBool>,
) -> Result<()> {
    let wall = Instant::now();
    let session = Session::open(&args.stage, &args.overrides(frame))?;
    let mut outputs = Outputs::resolve(
        &args.stage,
        &session.scene.settings,
        request,
        frame,
        sequence,
    )?;
    outputs.set_denoise(session.denoise)?;
    if let Some(line) = session.auto_summary() {
        eprintln!("nimbus: {line}");
    }
    if session.has_local_lights() {
        eprintln!(
            "nimbus: light sampling {}",
            session.job(false).light_sampling_summary()
        );
    }
    for w in &session.warnings {
        eprintln!("nimbus: warning: {w}");
    }
    let region = match (args.tile, args.region) {
        (Some(t), _) => Some(
            t.region(session.width, session.height)
                .map_err(|e| anyhow::anyhow!("--tile {}/{}: {e}", t.index, t.count))?,
        ),
        (None, Some(r)) if !r.fits(session.width, session.height) => bail!(
            "--region {},{},{},{} does not lie inside the {}x{} frame",
            r.x0,
            r.y0,
            r.x1,
            r.y1,
            session.width,
            session.height
        ),
        (None, r) => r,
    };
    if args.skip_complete && outputs.complete(&session) {
        eprintln!(
            "nimbus: {} complete with these settings; not rendered",
            outputs.list()
        );
        return Ok(());
    }
    let extra = session.extra_outputs(outputs.split_layers(), outputs.deep())?;
    let mut job = session.job(outputs.need_counts());
    extra.apply(&mut job);
    let pool = session.pool(0)?;
    let (width, height, spp) = (session.width, session.height, session.spp);
    let bar = if spp == u32::MAX {
        indicatif::ProgressBar::new_spinner()
    } else {
        indicatif::ProgressBar::new(spp as u64 * region.map_or(height, |r| r.height()) as u64)
    };
    bar.set_style(
        indicatif::ProgressStyle::with_template(
            "{spinner} rendering [{bar:40}] {msg}, {elapsed} elapsed, ETA {eta}",
        )
        .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    let facts = || RunFacts {
        wall_seconds: wall.elapsed().as_secs_f64(),
        threads: pool.current_num_threads(),
        counting: job.paths.count,
        tile: args.tile,
    };
    let (film, p) = session.render(
        &job,
        region,
        &pool,
        Clock::Wall,
        args.checkpoint,
        interrupted,
        &|n| bar.inc(n as u64),
        |film, p| {
            bar.set_message(format!(
                "{} spp in {} passes, {}",
                p.spp,
                p.passes,
                p.convergence.describe()
            ));
            if p.checkpoint_due {
                use anyhow::Context;
                outputs
                    .write(&session, film, &facts(), p)
                    .context("writing a checkpoint")?;
            }
            Ok::<(), anyhow::Error>(())
        },
    )?;
    bar.finish_and_clear();
    if p.spp == 0 {
        // Nothing rendered: keep whatever file is there rather than write a black image.
        bail!(
            "interrupted before the first pass finished; {} was not written",
            outputs.list()
        );
    }
    outputs.write(&session, &film, &facts(), &p)?;
    let (totals, taken, nonfinite) = film.totals();
    let (first_dropped, overflowing) = film.out_of_range();
    if let (true, Some((x, y))) = (nonfinite > 0, first_dropped) {
        eprintln!(
            "nimbus: warning: {}: {nonfinite} samples were NaN or infinite and were dropped (the first in pixel {x},{y}); stage warnings above name light or volume values that can cause it",
            args.stage.display()
        );
    }
    if overflowing > 0 {
        eprintln!(
            "nimbus: warning: {}: {overflowing} pixels are brighter than a 32-bit float holds (3.4e38) and were written clamped to it; check the lights' intensity and exposure",
            args.stage.display()
        );
    }
    if p.interrupted {
        bail!(
            "interrupted: wrote {} with the {} samples per pixel finished in {} passes",
            outputs.list(),
            p.spp,
            p.passes
        );
    }
    // Without counting (no cost AOV, no stats) there are no lookups to report.
    let lookups = match job.paths.count {
        true => format!(
            ", {:.1} lookups/sample",
            totals.density_lookups as f64 / taken.max(1) as f64
        ),
        false => String::new(),
    };
    let tile = match (args.tile, region) {
        (Some(t), Some(r)) => format!(
            ", tile {}/{} = pixels {},{}..{},{} of {width}x{height}",
            t.index, t.count, r.x0, r.y0, r.x1, r.y1
        ),
        (None, Some(r)) => format!(
            ", region {},{}..{},{} of {width}x{height}",
            r.x0, r.y0, r.x1, r.y1
        ),
        _ => String::new(),
    };
    let adaptive = match session.adaptive {
        Some(_) => format!(
            ", mean {:.1} spp, {}",
            taken as f64 / (film.width as f64 * film.height as f64),
            p.convergence.describe()
        ),
        None => String::new(),
    };
    let denoised = match (outputs.denoise, args.tile) {
        (false, _) => "",
        (true, Some(_)) => ", not denoised: merge denoises the frame",
        (true, None) => ", denoised",
    };
    eprintln!(
        "nimbus: wrote {} ({}x{}, {} spp in {} passes, {:.2} s{lookups}{adaptive}{denoised}{tile})",
        outputs.list(),
        film.width,
        film.height,
        p.spp,
        p.passes,
        p.seconds,
    );
    Ok(())
}

/// `auto` and every tracker name.
fn tracker_values() -> clap::builder::PossibleValuesParser {
    let mut v = vec![clap::builder::PossibleValue::new("auto")
        .help("Pick the tracker, scheme and options from the scene analysis")];
    v.extend(choice::possible_values::<TrackerKind>());
    clap::builder::PossibleValuesParser::new(v)
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
