//! The stats JSON written by `--stats`.

use crate::track::select::Choice;
use serde::Serialize;

#[derive(Serialize, Debug, Clone)]
pub struct RenderStats {
    pub stage: String,
    /// Samples per pixel of the passes run (every pixel's count, or with adaptive
    /// sampling the most any pixel took).
    pub samples_per_pixel: u32,
    /// Samples taken over all pixels, and their mean per pixel (below
    /// `samples_per_pixel` where adaptive sampling stopped pixels early).
    pub samples_taken: u64,
    pub mean_samples_per_pixel: f64,
    /// Adaptive sampling's noise threshold and minimum samples (null: off).
    pub noise_threshold: Option<f64>,
    pub min_samples: Option<u32>,
    /// The mean over pixels of the noise estimate adaptive sampling stops on (Cycles'
    /// measure: docs/sampling.md), and the share of pixels adaptive sampling stopped
    /// (null without it).
    pub estimated_noise: f64,
    pub converged_pixels: Option<f64>,
    /// Denoising, as the EXR's `nimbus:denoise` says: `"denoised"` (the EXRs'
    /// beauty and split layers are), `"merge"` (a tile: the merge of the frame
    /// denoises it), null (not asked for); and the seconds the denoising took.
    pub denoise: Option<&'static str>,
    pub denoise_seconds: f64,
    /// Progressive passes the samples were taken in.
    pub passes: u32,
    pub max_pass_seconds: f64,
    /// The `--spp` cap (absent when only a time limit bounds the render).
    pub spp_cap: Option<u32>,
    pub time_limit_seconds: Option<f64>,
    /// Stopped by Ctrl-C / SIGTERM before the cap or budget was reached.
    pub interrupted: bool,
    /// The pixels rendered: the frame's, or the tile's.
    pub width: u32,
    pub height: u32,
    /// The frame's resolution (a tile's stats hold the tile's width and height above).
    pub full_resolution: (u32, u32),
    /// The tile rendered, `I/N` (null for a whole frame).
    pub tile: Option<String>,
    /// The session's settings hash (`Session::settings_hash`, hex), which `merge` checks.
    pub settings_hash: String,
    /// The holdout geometry: meshes, triangles, degenerate triangles skipped, BVH build
    /// seconds and bytes (all 0 for a stage without geometry).
    pub holdouts: crate::render::holdouts::HoldoutStats,
    pub wall_seconds: f64,
    pub load_seconds: f64,
    pub render_seconds: f64,
    pub threads: usize,
    pub seed: u64,
    /// Where the samples' random numbers came from (`sobol`, `independent`).
    pub sampler: String,
    pub tracker: String,
    pub scheme: String,
    pub transmittance: String,
    pub residual_lookups: u64,
    pub control_collisions: u64,
    /// Mean over samples of the largest channel throughput along the path.
    pub max_throughput_mean: f64,
    /// Largest channel throughput of any path (colour explosion shows here).
    pub max_throughput_peak: f64,
    pub density_lookups: u64,
    /// Emission grid lookups (at absorption events of an emissive medium).
    pub emission_lookups: u64,
    /// Albedo grid lookups (one per scatter event when `nimbus:albedoField` is set).
    pub albedo_lookups: u64,
    /// Albedo grid component values clamped into [0,1] (0 without an albedo grid).
    pub clamped_albedo_values: u64,
    pub real_collisions: u64,
    pub null_collisions: u64,
    pub cells_visited: u64,
    pub majorant_violations: u64,
    pub nonfinite_samples: u64,
    pub sanitized_voxels: u64,
    /// Leaf cells of the majorant structure.
    pub majorant_cells: usize,
    /// `--octree-depth` as requested (null for the flat `--majorant-cell` grid).
    pub octree_depth: Option<u32>,
    /// Levels actually built (depth capped at voxel resolution; 1 for a flat grid).
    pub octree_levels: usize,
    pub octree_build_seconds: f64,
    pub octree_memory_bytes: usize,
    pub vdb_reader: String,
    /// `--profile` only (else null): thread-seconds inside density lookups, inside the
    /// majorant walk, and in the rest of the trackers, each with the clock's empty-region
    /// bias removed per timed event (`timer_empty_region_ns`).
    pub lookup_seconds: Option<f64>,
    pub traversal_seconds: Option<f64>,
    pub other_tracker_seconds: Option<f64>,
    pub timer_empty_region_ns: Option<f64>,
    /// Scheme options in effect.
    pub no_absorption_events: bool,
    pub reduced_termination: bool,
    /// Why `--tracker auto` chose the tracker (null when one was named).
    pub tracker_auto_reason: Option<String>,
    /// What `--light-sampling` did with the local lights, and why (as `nimbus info`).
    pub light_sampling: String,
    /// The scene analysis the render was planned from.
    pub analysis: crate::render::analysis::Analysis,
    /// The specialised code paths the render ran (`grey_tracking`: grey media tracked
    /// with one channel).
    pub code_paths: CodePathsUsed,
    /// Everything on the stage the render does not show as authored, one entry per
    /// prim and attribute (`kind`, `prim`, `attribute`, `message`).
    pub stage_warnings: crate::scene::Diagnostics,
}

/// The code paths of a render, as the stats report them.
#[derive(Clone, Debug, Serialize)]
pub struct CodePathsUsed {
    /// Lookups and collisions were counted (always, when stats are written).
    pub counting: bool,
    /// Grey medium tracked single-channel (`track::grey`).
    pub grey_tracking: bool,
}

impl RenderStats {
    /// The stats of `session` after the samples in `film` (`p` says how they went).
    pub fn new(
        session: &crate::render::session::Session,
        film: &crate::render::film::Film,
        p: &crate::render::progressive::Progress,
        run: &RunFacts,
    ) -> RenderStats {
        use crate::volume::majorant::MajorantSpec;
        let (totals, taken, nonfinite) = film.totals();
        let samples = (taken as f64).max(1.0);
        let media = session.media();
        // Instances share grids and majorant structures: each is counted once.
        let grids = distinct(media, |m| std::sync::Arc::as_ptr(&m.density) as usize);
        let trees = distinct(media, |m| std::sync::Arc::as_ptr(&m.majorants) as usize);
        let t = &session.tracking;
        let calibration = t.profile.then(crate::volume::ticks::Calibration::measure);
        let times = calibration.map(|c| c.split(&totals));
        let job = session.job(run.counting);
        RenderStats {
            stage: session.stage_path.display().to_string(),
            samples_per_pixel: p.spp,
            samples_taken: taken,
            mean_samples_per_pixel: taken as f64 / (film.width as f64 * film.height as f64),
            noise_threshold: session.adaptive.map(|a| a.threshold),
            min_samples: session.adaptive.map(|a| a.min_spp),
            estimated_noise: p.convergence.mean_error,
            converged_pixels: p.convergence.stopped,
            denoise: None,
            denoise_seconds: 0.0,
            passes: p.passes,
            max_pass_seconds: p.max_pass_seconds,
            spp_cap: (session.spp != u32::MAX).then_some(session.spp),
            time_limit_seconds: session.time_limit,
            interrupted: p.interrupted,
            width: film.width,
            height: film.height,
            full_resolution: film.full,
            tile: run.tile.map(|t| format!("{}/{}", t.index, t.count)),
            settings_hash: format!("{:016x}", session.settings_hash()),
            holdouts: session.holdouts.stats(),
            wall_seconds: run.wall_seconds,
            load_seconds: session.load_seconds,
            render_seconds: p.seconds,
            threads: run.threads,
            seed: session.seed,
            sampler: session.sampler.name().into(),
            tracker: t.tracker.name().into(),
            scheme: t.scheme.name().into(),
            transmittance: t.transmittance.name().into(),
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
            sanitized_voxels: grids.iter().map(|m| m.density.sanitized_voxels).sum(),
            majorant_cells: trees.iter().map(|m| m.majorants.cell_count()).sum(),
            octree_depth: match session.spec {
                MajorantSpec::Octree { depth } => Some(depth),
                MajorantSpec::Uniform { .. } => None,
            },
            octree_levels: media
                .iter()
                .map(|m| m.majorants.levels())
                .max()
                .unwrap_or(0),
            octree_build_seconds: trees.iter().map(|m| m.majorants.build_seconds()).sum(),
            octree_memory_bytes: trees.iter().map(|m| m.majorants.memory_bytes()).sum(),
            vdb_reader: crate::volume::vdb::active_reader().name().into(),
            lookup_seconds: times.map(|t| t.lookup_seconds),
            traversal_seconds: times.map(|t| t.traversal_seconds),
            other_tracker_seconds: times.map(|t| t.other_tracker_seconds),
            timer_empty_region_ns: calibration
                .map(|c| c.empty_region_ticks / c.ticks_per_second * 1e9),
            no_absorption_events: t.options.no_absorption_events,
            reduced_termination: t.options.reduced_termination,
            tracker_auto_reason: session.auto_reason.clone(),
            light_sampling: job.light_sampling_summary(),
            analysis: session.analysis.clone(),
            code_paths: CodePathsUsed {
                counting: job.paths.count,
                grey_tracking: job.grey_tracking(),
            },
            stage_warnings: session.scene.warnings.clone(),
        }
    }
}

/// Facts of the run the stats report that the session and the film do not hold.
#[derive(Clone, Copy, Debug)]
pub struct RunFacts {
    /// Seconds since the render was asked for (loading included).
    pub wall_seconds: f64,
    pub threads: usize,
    /// Whether counting ran (the counters are zero otherwise).
    pub counting: bool,
    /// The tile rendered, if any.
    pub tile: Option<crate::render::tiles::Tile>,
}

/// The media with a distinct `key` (the first of each), in order.
fn distinct(
    media: &[crate::volume::medium::Medium],
    key: impl Fn(&crate::volume::medium::Medium) -> usize,
) -> Vec<&crate::volume::medium::Medium> {
    let mut seen = std::collections::HashSet::new();
    media.iter().filter(|m| seen.insert(key(m))).collect()
}
