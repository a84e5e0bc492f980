//! `nimbus render`.

use crate::output::exr::{write_exr, ExrMetadata};
use crate::output::stats::RenderStats;
use crate::output::{check_writable, write_atomically};
use crate::render::camera::CameraRays;
use crate::render::film::Aov;
use crate::render::job::{medium_for_scene_with, RenderJob};
use crate::render::lights::Lights;
use crate::scene::{load_stage, LoadOptions, RenderSettings};
use crate::track::{
    scheme::SchemeOptions, SchemeKind, TrackerKind, TrackerSettings, TransmittanceKind,
};
use crate::volume::majorant::{MajorantSpec, MAX_DEPTH};
use crate::volume::vdb;
use anyhow::{bail, Context, Result};
use clap::{Args, ValueEnum};
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Instant;

use crate::render::film::Film;
use crate::render::progressive::{render_progressive, Budget, Progress};

#[derive(Args, Debug)]
pub struct RenderArgs {
    /// The USD stage (.usda, .usdc, .usdz).
    pub stage: PathBuf,
    /// Output EXR path.
    #[arg(short = 'o', long = "output")]
    pub output: PathBuf,
    #[command(flatten)]
    pub sampling: SamplingArgs,
    /// Camera prim path (overrides the render settings' camera).
    #[arg(long)]
    pub camera: Option<String>,
    /// Time code to evaluate the stage at.
    #[arg(long)]
    pub frame: Option<f64>,
    /// Write render statistics as JSON to this file.
    #[arg(long)]
    pub stats: Option<PathBuf>,
    /// Maximum scattering depth (overrides nimbus:maxDepth).
    #[arg(long)]
    pub max_depth: Option<u32>,
    /// Edge of a majorant cell in voxels; 0 = one global majorant for the volume
    /// (a flat grid; ignored when --octree-depth is given).
    #[arg(long, default_value_t = 8)]
    pub majorant_cell: u32,
    /// Majorant octree depth: 1 = one cell for the volume, d = 2^(d-1) leaf cells per
    /// axis (capped at voxel resolution). Overrides --majorant-cell and nimbus:octreeDepth.
    #[arg(long)]
    pub octree_depth: Option<u32>,
    /// Free-path sampler (overrides nimbus:tracker; default delta).
    #[arg(long, value_enum)]
    pub tracker: Option<TrackerKind>,
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
    /// media only).
    #[arg(long)]
    pub no_absorption_events: bool,
    /// Multiplies every majorant; below 1 makes them non-bounding (for testing the
    /// weighted trackers: others report `majorant_violations`).
    #[arg(long, default_value_t = 1.0)]
    pub majorant_scale: f32,
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

pub fn run(args: RenderArgs) -> Result<()> {
    let wall = Instant::now();
    let mut aovs = requested_aovs(&args.aovs)?;
    check_writable(&args.output)?;
    if let Some(s) = &args.stats {
        check_writable(s)?;
    }
    let opts = LoadOptions {
        frame: args.frame,
        camera: args.camera.clone(),
    };
    let scene = load_stage(&args.stage, &opts)?;
    let settings = &scene.settings;
    let tracking = tracker_settings(&args, settings)?;
    add_render_var_aovs(settings, &mut aovs)?;
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
    let spec = majorant_spec(args.octree_depth, settings, args.majorant_cell)?;
    let medium = medium_for_scene_with(&scene, spec)?;
    let load_seconds = wall.elapsed().as_secs_f64();

    let lights = Lights::from_scene(&scene);
    for d in &scene.dome_lights {
        if let Some(tex) = &d.texture_file {
            eprintln!(
                "nimbus: warning: {}: dome texture '{tex}' is not supported yet; using its constant colour",
                d.prim_path
            );
        }
    }
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
    let job = RenderJob {
        medium: &medium,
        lights: &lights,
        camera: &camera,
        width,
        height,
        spp,
        max_depth,
        seed,
        tracking,
    };

    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(args.sampling.threads.unwrap_or(0))
        .build()
        .context("cannot start worker threads")?;
    let interrupted = install_interrupt_handler();
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
    let write_outputs = |film: &Film, p: &Progress| -> Result<()> {
        let (totals, _samples, nonfinite) = film.totals();
        write_exr(
            &args.output,
            film,
            &aovs,
            &ExrMetadata {
                stage: args.stage.display().to_string(),
                tracker: tracker.clone(),
                spp: p.spp,
                render_seconds: p.seconds,
            },
        )?;
        let Some(path) = &args.stats else {
            return Ok(());
        };
        let samples = width as f64 * height as f64 * p.spp as f64;
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
            real_collisions: totals.real_collisions,
            null_collisions: totals.null_collisions,
            cells_visited: totals.cells_visited,
            majorant_violations: totals.majorant_violations,
            nonfinite_samples: nonfinite,
            sanitized_voxels: medium.density.sanitized_voxels,
            majorant_cells: medium.majorants.cell_count(),
            octree_depth: match medium.majorants.spec() {
                MajorantSpec::Octree { depth } => Some(depth),
                MajorantSpec::Uniform { .. } => None,
            },
            octree_levels: medium.majorants.levels(),
            octree_build_seconds: medium.majorants.build_seconds(),
            octree_memory_bytes: medium.majorants.memory_bytes(),
            vdb_reader: vdb::active_reader().name().into(),
        };
        let json = serde_json::to_string_pretty(&stats)?;
        write_atomically(path, |f| {
            use std::io::Write;
            f.write_all(json.as_bytes()).map_err(|e| e.to_string())
        })?;
        Ok(())
    };

    let budget = Budget {
        spp_cap: spp,
        time_limit: args.time_limit,
        checkpoint: args.checkpoint,
    };
    let (film, p) = render_progressive(
        &job,
        &pool,
        &budget,
        &interrupted,
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
            args.output.display()
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
            args.output.display(),
            p.spp,
            p.passes
        );
    }
    eprintln!(
        "nimbus: wrote {} ({width}x{height}, {} spp in {} passes, {:.2} s, {:.1} lookups/sample)",
        args.output.display(),
        p.spp,
        p.passes,
        p.seconds,
        totals.density_lookups as f64 / (width as f64 * height as f64 * p.spp as f64)
    );
    Ok(())
}

/// The majorant structure: `--octree-depth`, else the stage's `nimbus:octreeDepth`
/// (0 there means the flat grid), else the flat `--majorant-cell` grid.
pub fn majorant_spec(
    octree_depth: Option<u32>,
    stage: &RenderSettings,
    majorant_cell: u32,
) -> Result<MajorantSpec> {
    let from_stage = match stage.octree_depth {
        None | Some(0) => None,
        Some(d) => Some(u32::try_from(d).map_err(|_| {
            anyhow::anyhow!(
                "{}: nimbus:octreeDepth = {d} must lie in 0..={MAX_DEPTH}",
                stage.prim_path.as_deref().unwrap_or("render settings")
            )
        })?),
    };
    match octree_depth.or(from_stage) {
        Some(depth) if !(1..=MAX_DEPTH).contains(&depth) => {
            bail!("the octree depth must lie in 1..={MAX_DEPTH}, got {depth}")
        }
        Some(depth) => Ok(MajorantSpec::Octree { depth }),
        None => Ok(MajorantSpec::Uniform {
            cell_voxels: majorant_cell,
        }),
    }
}

/// Tracker settings: flags override the stage's render settings, which override the
/// defaults.
fn tracker_settings(args: &RenderArgs, stage: &RenderSettings) -> Result<TrackerSettings> {
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
    let tracker = args
        .tracker
        .or(from_stage(stage, "nimbus:tracker", &stage.tracker)?)
        .unwrap_or(d.tracker);
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
    Ok(TrackerSettings {
        tracker,
        scheme,
        transmittance,
        control,
        options: SchemeOptions {
            reduced_termination: args.reduced_termination,
            no_absorption_events: args.no_absorption_events,
        },
        majorant_scale: args.majorant_scale,
    })
}

/// R, G, B, A and `lookups` always, plus what `--aovs` names.
fn requested_aovs(names: &[String]) -> Result<Vec<Aov>> {
    let mut aovs = Aov::DEFAULT.to_vec();
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

/// Adds the AOVs the stage's render vars name. `color` (also `C`, `Ci`, `rgb`) is R, G, B;
/// `alpha`/`a` is A; the other AOVs go by their channel names.
fn add_render_var_aovs(settings: &RenderSettings, aovs: &mut Vec<Aov>) -> Result<()> {
    for product in &settings.products {
        for var in &product.vars {
            let name = var.source_name.trim();
            let wanted: Vec<Aov> = match name {
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
            };
            for a in wanted {
                if !aovs.contains(&a) {
                    aovs.push(a);
                }
            }
        }
    }
    Ok(())
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
