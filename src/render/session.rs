//! A render session: the one library entry point that turns a stage path and the
//! caller's overrides into a running render. `nimbus render`, `info`, every `bench`,
//! the reference renders (and the farm tasks and Python module after them) call it, so
//! each step — load, validate, analyse, `auto`, prune the octree, render — is written
//! once and a benchmark measures exactly what a user runs.
//!
//! Precedence lives here, once: an override (a CLI flag, a keyword argument) beats what
//! the stage authors, which beats the schema fallback.

use crate::render::adaptive::Adaptive;
use crate::render::analysis::{Analysis, CodePaths, Given};
use crate::render::camera::CameraRays;
use crate::render::film::{DepthBins, Film, Region};
use crate::render::holdouts::Holdouts;
use crate::render::integrator::{Extras, MEDIA_OVERFLOW};
use crate::render::job::{media_for_scene_with, RenderJob};
use crate::render::lights::Lights;
use crate::render::media_index::MediaIndex;
use crate::render::progressive::{render_progressive, Budget, Clock, Progress};
use crate::render::sampler::SamplerKind;
use crate::render::splits::{SplitLayer, SplitMap};
use crate::scene::defaults::{add_default_lights, frame_box, wants_default_lights, DEFAULT_CAMERA};
use crate::scene::{
    load_stage, Emitter, Field, LoadOptions, RenderSettings, Scene, Volume, VolumeEmission,
};
use crate::track::race::MAX_MEDIA;
use crate::track::scheme::SchemeOptions;
use crate::track::select::{
    Choice, LightSampling, ScatterGuiding, SchemeKind, TrackerKind, TrackerSettings,
    TransmittanceKind,
};
use crate::volume::asset::AssetLocation;
use crate::volume::grid::Grid;
use crate::volume::majorant::{MajorantSpec, MajorantTree, MAX_DEPTH};
use crate::volume::medium::Medium;
use crate::volume::vdb;
use anyhow::{anyhow, bail, Context, Result};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Instant;

/// The edge of a flat majorant grid's cells when no structure is named.
pub const DEFAULT_CELL_VOXELS: u32 = 8;

/// The octree pruning cost when none is given (one cell crossing = one lookup).
pub const DEFAULT_OCTREE_PRUNE: f32 = 1.0;

/// Memory Nimbus may use for the film (bytes per pixel of accumulators), checked before
/// rendering so an absurd resolution is refused with a message instead of an abort.
const MAX_FILM_BYTES: u64 = 8 << 30;

/// Camera-depth slabs per pixel of the deep output before merging to the sample limit.
pub const DEEP_BINS: usize = 32;

/// The split map and the deep bins a render's outputs need, owned beside the session
/// (the job borrows them through [`ExtraOutputs::extras`]).
#[derive(Debug, Default)]
pub struct ExtraOutputs {
    pub splits: SplitMap,
    pub depth_bins: Option<DepthBins>,
}

impl ExtraOutputs {
    /// Makes `job` fill them.
    pub fn apply<'a>(&'a self, job: &mut RenderJob<'a>) {
        job.extras.splits = (!self.splits.is_empty()).then_some(&self.splits);
        job.extras.depth_bins = self.depth_bins;
    }
}

/// What the caller asks for. `None` (and `false`) leave the choice to the stage, and
/// the stage's silence to the schema fallbacks.
#[derive(Clone, Debug, Default)]
pub struct Overrides {
    /// Time code to evaluate the stage at (`None`: the stage's default time).
    pub frame: Option<f64>,
    /// Camera prim path (overrides the render settings' camera).
    pub camera: Option<String>,
    /// Samples per pixel (`nimbus:samples`).
    pub spp: Option<u32>,
    /// Resolution (the render settings' `resolution`).
    pub res: Option<(u32, u32)>,
    pub seed: Option<u64>,
    /// Where samples' random numbers come from (default: `sobol`).
    pub sampler: Option<SamplerKind>,
    /// Worker threads (`None`: all cores). The image does not depend on it.
    pub threads: Option<usize>,
    pub max_depth: Option<u32>,
    /// Flat majorant grid cell edge in voxels (0: one global majorant).
    pub majorant_cell: Option<u32>,
    /// Majorant octree depth (beats `majorant_cell` and `nimbus:octreeDepth`).
    pub octree_depth: Option<u32>,
    /// Octree pruning cost in lookups per cell crossing (default
    /// [`DEFAULT_OCTREE_PRUNE`]; 0 keeps every level).
    pub octree_prune: Option<f32>,
    /// A tracker name or `auto` (`nimbus:tracker`).
    pub tracker: Option<String>,
    pub scheme: Option<SchemeKind>,
    pub transmittance: Option<TransmittanceKind>,
    /// Control of `decomposition-weighted`, in [0, 1] (`nimbus:control`).
    pub control: Option<f32>,
    pub reduced_termination: bool,
    pub no_absorption_events: bool,
    /// Multiplies every majorant (default 1).
    pub majorant_scale: Option<f32>,
    /// Scattering points towards local lights (default `auto`).
    pub light_sampling: Option<LightSampling>,
    /// Where paths go after scattering (default `auto`).
    pub scatter_guiding: Option<ScatterGuiding>,
    /// Adaptive sampling's noise threshold (`nimbus:noiseThreshold`; 0: off).
    pub noise_threshold: Option<f64>,
    /// Samples every pixel takes before adaptive sampling may stop it
    /// (`nimbus:minSamples`; 0: the default minimum).
    pub min_spp: Option<u32>,
    /// Denoise the frame with Open Image Denoise (`nimbus:denoise`).
    pub denoise: Option<bool>,
    /// Time lookups, traversal and the rest of the trackers.
    pub profile: bool,
    /// Run the general RGB trackers even where a specialised one applies.
    pub no_specialise: bool,
    /// Seconds of rendering to spend; without `spp` the budget alone decides.
    pub time_limit: Option<f64>,
    /// The density grid of a VDB file rendered directly (default: its first float
    /// grid); an error for a stage.
    pub grid: Option<String>,
    /// Refuse to render what the stage asks for and the render would not show as
    /// authored (as `nimbus:strict`): stage warnings and made-up defaults are errors.
    pub strict: bool,
    /// Never add the default sun and sky to a stage without lights.
    pub no_default_lights: bool,
}

/// A loaded, validated, analysed stage ready to render, with every setting resolved.
pub struct Session {
    pub stage_path: PathBuf,
    /// The time code rendered (`None`: the stage's default time).
    pub frame: Option<f64>,
    pub scene: Scene,
    media: Vec<Medium>,
    lights: Lights,
    camera: CameraRays,
    pub width: u32,
    pub height: u32,
    /// Samples per pixel at most (`u32::MAX`: a time limit alone bounds the render).
    pub spp: u32,
    pub max_depth: u32,
    pub seed: u64,
    pub sampler: SamplerKind,
    pub time_limit: Option<f64>,
    /// Adaptive sampling (`None`: every pixel takes `spp` samples).
    pub adaptive: Option<Adaptive>,
    /// Denoise the finished frame (a farm's tiles are not: their merge is).
    pub denoise: bool,
    pub tracking: TrackerSettings,
    /// The majorant structure the media carry (after `auto`).
    pub spec: MajorantSpec,
    /// Why `auto` chose what it chose; `None` when the tracker was named.
    pub auto_reason: Option<String>,
    pub analysis: Analysis,
    /// Seconds spent loading the stage and its grids.
    pub load_seconds: f64,
    octree_prune: f32,
    specialise: bool,
    threads: Option<usize>,
    /// Things the user should hear about (printed by the caller).
    pub warnings: Vec<String>,
    /// The stage's holdout geometry, in a BVH (empty: none).
    pub holdouts: Holdouts,
    /// Which media a ray may meet, for stages with many.
    media_index: Option<MediaIndex>,
}

impl Session {
    /// Loads `stage` with `overrides`: the scene, every volume's grids, the lights and
    /// the camera; checks the settings; analyses the scene, lets `auto` decide, and
    /// prunes the majorant octree for the chosen tracker.
    pub fn open(stage: &Path, overrides: &Overrides) -> Result<Session> {
        let start = Instant::now();
        let o = overrides;
        let opts = LoadOptions {
            frame: o.frame,
            camera: o.camera.clone(),
        };
        let mut warnings = Vec::new();
        let scene = if is_vdb(stage) {
            warnings.push(format!(
                "{}: a VDB file, not a stage: rendering its grid as the density of one volume with the schema's fallback coefficients",
                stage.display()
            ));
            scene_for_vdb(stage, o.grid.as_deref())?
        } else {
            if let Some(g) = &o.grid {
                bail!(
                    "--grid {g}: only for a VDB file rendered directly; a stage names its fields"
                );
            }
            load_stage(stage, &opts)?
        };
        Session::build(stage, scene, o, start, warnings)
    }

    /// A session of a scene already read from `stage` (with `overrides`' frame and
    /// camera): what [`Session::open`] does after reading it. `nimbus info` describes
    /// the scene and analyses it from one read of the stage.
    pub fn from_scene(stage: &Path, scene: Scene, overrides: &Overrides) -> Result<Session> {
        Session::build(stage, scene, overrides, Instant::now(), Vec::new())
    }

    fn build(
        stage: &Path,
        mut scene: Scene,
        o: &Overrides,
        start: Instant,
        mut warnings: Vec<String>,
    ) -> Result<Session> {
        let strict = o.strict || scene.settings.strict;
        if strict {
            refuse_warnings(stage, &scene)?;
        }
        warnings.extend(scene.warnings.lines());
        if !o.no_default_lights && wants_default_lights(&scene) {
            if strict {
                bail!(
                    "{}: the stage has no lights and no emissive volume (--strict refuses to add the default sun and sky; --no-default-lights renders it unlit)",
                    stage.display()
                );
            }
            add_default_lights(&mut scene);
            warnings.push(
                "the stage has no lights: lighting it with a default sun and sky (--no-default-lights leaves it unlit)".to_string(),
            );
        }
        let settings = &scene.settings;
        let request = tracker_request(o, settings)?;
        let (width, height) = o.res.unwrap_or(settings.resolution);
        if width == 0 || height == 0 {
            bail!(
                "{}: render resolution {width}x{height} has a zero side",
                stage.display()
            );
        }
        let spp = o.spp.unwrap_or(settings.samples);
        if spp == 0 {
            bail!("samples per pixel must be at least 1");
        }
        if let Some(v) = o.time_limit {
            if !(v.is_finite() && v > 0.0) {
                bail!("--time-limit must be a positive number of seconds, got {v}");
            }
        }
        let threshold = o.noise_threshold.unwrap_or(settings.noise_threshold);
        if !(threshold.is_finite() && threshold >= 0.0) {
            bail!("--noise-threshold must be 0 (off) or a positive number, got {threshold}");
        }
        let min_spp = o.min_spp.unwrap_or(settings.min_samples);
        // The default minimum follows the sample count asked for (the stage's, also
        // under a time budget).
        let adaptive = (threshold > 0.0).then(|| Adaptive::new(threshold, min_spp, spp));
        // With a time budget and no explicit spp, the budget alone decides.
        let spp = match (o.time_limit, o.spp) {
            (Some(_), None) => u32::MAX,
            _ => spp,
        };
        // Name where the resolution came from: a refusal read in a farm log must say
        // which file and prim (or flag) to fix.
        check_film_memory(width, height).map_err(|e| {
            let source = match (o.res, &settings.prim_path) {
                (Some(_), _) => "--res".to_string(),
                (None, Some(prim)) => format!("{prim}.resolution"),
                (None, None) => "the default resolution".to_string(),
            };
            anyhow!("{}: {source}: {e}", stage.display())
        })?;
        let mut prune = o.octree_prune.unwrap_or(DEFAULT_OCTREE_PRUNE);
        if !(prune.is_finite() && prune >= 0.0) {
            bail!("the octree pruning cost must be a non-negative number, got {prune}");
        }
        let mut spec = majorant_spec(o, settings)?;
        let mut media = media_for_scene_with(&scene, spec)?;
        let load_seconds = start.elapsed().as_secs_f64();
        if scene.camera.prim_path == DEFAULT_CAMERA {
            if strict {
                bail!(
                    "{}: no camera named and none on the stage (--strict refuses the default camera; name one with --camera)",
                    stage.display()
                );
            }
            let bounds = media
                .iter()
                .filter_map(|m| m.world_bounds())
                .reduce(|a, b| (a.0.min(b.0), a.1.max(b.1)));
            let (lo, hi) = bounds.unwrap_or((glam::DVec3::splat(-1.0), glam::DVec3::splat(1.0)));
            scene.camera = frame_box(lo, hi, width as f64 / height as f64);
            warnings.push(format!(
                "no camera named and none on the stage: framing the volumes ({:.3?} to {:.3?}) with a default camera looking down -Z",
                lo.to_array(),
                hi.to_array()
            ));
        }
        let lights = Lights::from_scene(&scene)?;
        check_camera(&scene).map_err(|e| anyhow!("{}: {e}", stage.display()))?;
        let holdouts = match scene.holdouts.is_empty() {
            true => Holdouts::empty(),
            false => Holdouts::build(&scene.holdouts),
        };
        let camera = CameraRays::new(&scene.camera, width, height);
        let mut analysis = Analysis::of_media(&media, &lights, &camera, (width, height));
        let mut tracking = request.settings;
        if analysis.emissive && tracking.options.no_absorption_events {
            bail!(
                "--no-absorption-events: volume {} emits light (nimbus:temperatureField / nimbus:emissionField), and emission is collected at absorption events; drop the flag",
                media.iter().find(|m| m.emission.is_some()).map_or("", |m| &m.prim_path)
            );
        }
        let mut auto_reason = None;
        if request.auto {
            if let Some(majorants) = analysis.majorants(request.given) {
                let trees = per_grid(&media, |m| m.build_majorants(majorants, 0.0, false));
                for (medium, tree) in media.iter_mut().zip(trees) {
                    medium.replace_majorants(tree);
                }
                spec = majorants;
                analysis.recount_majorants(&media);
            }
            let (t, reason) = analysis.choose(tracking, request.given);
            tracking = t;
            auto_reason = Some(reason);
            if let Some(cost) = analysis.majorant_prune(request.given) {
                prune = o.octree_prune.unwrap_or(cost);
            }
        }
        if let Some(e) = analysis
            .estimated_majorants
            .as_ref()
            .filter(|_| !request.auto)
        {
            if !tracking.tracker.tolerates_estimated_majorants() {
                warnings.push(format!(
                    "{}: the density graph of {} has no usable bound in {} of {} majorant cells, whose majorants are estimates; --tracker {} is biased where the density exceeds them (auto, ratio-select, weighted-delta and spectral-mis are not)",
                    e.prim_path,
                    e.source,
                    e.cells,
                    e.of,
                    tracking.tracker.name()
                ));
            }
        }
        if !analysis.volume_visible {
            warnings.push(format!(
                "no camera ray of a 16x16 probe grid reaches the volume {}: only light it scatters or shadows could show",
                media
                    .iter()
                    .map(|m| m.prim_path.as_str())
                    .collect::<Vec<_>>()
                    .join(", ")
            ));
        }
        let specialise = !o.no_specialise && analysis.specialise();
        let mut session = Session {
            stage_path: stage.to_path_buf(),
            frame: o.frame,
            width,
            height,
            spp,
            max_depth: o.max_depth.unwrap_or(settings.max_depth),
            seed: o.seed.unwrap_or(settings.seed),
            sampler: o.sampler.unwrap_or_default(),
            time_limit: o.time_limit,
            adaptive,
            denoise: o.denoise.unwrap_or(settings.denoise),
            scene,
            media,
            lights,
            camera,
            tracking,
            spec,
            auto_reason,
            analysis,
            load_seconds,
            octree_prune: prune,
            specialise,
            threads: o.threads,
            warnings,
            holdouts,
            media_index: None,
        };
        session.prune();
        session.media_index = MediaIndex::build(&session.media);
        Ok(session)
    }

    /// Opens the session of every frame of `first..=last` in turn (a frame that fails
    /// to load is an `Err` in its place; the others still come).
    pub fn frames<'a>(
        stage: &'a Path,
        overrides: &'a Overrides,
        first: i64,
        last: i64,
    ) -> impl Iterator<Item = (i64, Result<Session>)> + 'a {
        (first..=last).map(move |frame| {
            let o = Overrides {
                frame: Some(frame as f64),
                ..overrides.clone()
            };
            (frame, Session::open(stage, &o))
        })
    }

    /// The media, one per visible volume.
    pub fn media(&self) -> &[Medium] {
        &self.media
    }

    /// The octree pruning cost (`--octree-prune`; 0: not pruned).
    pub fn octree_prune(&self) -> f32 {
        self.octree_prune
    }

    /// Switches to other tracker settings (a benchmark's next tracker), with the
    /// majorant structure rebuilt and pruned as a render with those settings prunes it.
    pub fn retrack(&mut self, tracking: TrackerSettings) {
        self.tracking = tracking;
        self.auto_reason = None;
        self.rebuild_majorants();
    }

    /// Switches to another majorant structure (a benchmark's next octree depth),
    /// pruned as a render with it prunes it.
    pub fn set_majorants(&mut self, spec: MajorantSpec) {
        self.spec = spec;
        self.rebuild_majorants();
    }

    /// The majorant structures (one per medium) a render with `tracking` uses at the
    /// session's `spec`, built and pruned as [`retrack`](Self::retrack) would, without
    /// switching to them: a benchmark that alternates trackers builds each once.
    pub fn majorants_for(&self, tracking: &TrackerSettings) -> Vec<Arc<MajorantTree>> {
        let residual = tracking.pays_residual();
        per_grid(&self.media, |m| {
            m.build_majorants(self.spec, self.octree_prune, residual)
        })
    }

    /// Switches to `tracking` with `trees` from [`majorants_for`](Self::majorants_for)
    /// (same `spec`, same settings) in place of the media's structures, which are
    /// handed back: the same render as after [`retrack`](Self::retrack), without the
    /// rebuild.
    pub fn switch_tracking(
        &mut self,
        tracking: TrackerSettings,
        trees: Vec<Arc<MajorantTree>>,
    ) -> Vec<Arc<MajorantTree>> {
        assert_eq!(
            trees.len(),
            self.media.len(),
            "one majorant structure per medium"
        );
        self.tracking = tracking;
        self.auto_reason = None;
        self.media
            .iter_mut()
            .zip(trees)
            .map(|(m, t)| m.replace_majorants(t))
            .collect()
    }

    fn rebuild_majorants(&mut self) {
        let trees = per_grid(&self.media, |m| m.build_majorants(self.spec, 0.0, false));
        for (medium, tree) in self.media.iter_mut().zip(trees) {
            medium.replace_majorants(tree);
        }
        self.prune();
        self.media_index = MediaIndex::build(&self.media);
    }

    /// Prunes an octree where finer cells cost more crossings than they save lookups
    /// (the saving depends on whether the tracker pays lookups for residuals).
    fn prune(&mut self) -> usize {
        if !matches!(self.spec, MajorantSpec::Octree { .. }) {
            return 0;
        }
        let residual = self.tracking.pays_residual();
        let cost = self.octree_prune;
        // Once per grid: the instances of a volume share the pruned structure.
        let mut pruned: Vec<(*const Grid, Arc<MajorantTree>)> = Vec::new();
        let mut nodes = 0;
        for m in &mut self.media {
            let key = Arc::as_ptr(&m.density);
            if let Some((_, tree)) = pruned.iter().find(|(k, _)| *k == key) {
                m.replace_majorants(tree.clone());
                continue;
            }
            nodes += m.prune_majorants(cost, residual);
            pruned.push((key, m.majorants.clone()));
        }
        nodes
    }

    /// The render job of this session; `count` turns the per-pixel counters on.
    pub fn job(&self, count: bool) -> RenderJob<'_> {
        self.job_with(CodePaths {
            count: count || self.tracking.profile,
            specialise: self.specialise,
        })
    }

    /// The render job with the code paths named (benchmarks compare them).
    pub fn job_with(&self, paths: CodePaths) -> RenderJob<'_> {
        RenderJob {
            media: &self.media,
            lights: &self.lights,
            camera: &self.camera,
            width: self.width,
            height: self.height,
            spp: self.spp,
            max_depth: self.max_depth,
            seed: self.seed,
            sampler: self.sampler,
            tracking: self.tracking,
            paths,
            extras: Extras {
                holdouts: (!self.holdouts.is_empty()).then_some(&self.holdouts),
                media_index: self.media_index.as_ref(),
                adaptive: self.adaptive,
                ..Extras::default()
            },
        }
    }

    /// What `layers` (split AOVs) and deep output (`deep`) need from a render of this
    /// session: the split map over the scene's lights and volumes, and the camera-depth
    /// bins of the volumes' bounds. Errors name a light group that matches nothing, or
    /// a film that no longer fits in memory.
    pub fn extra_outputs(&self, layers: Vec<SplitLayer>, deep: bool) -> Result<ExtraOutputs> {
        let lights = self.scene.lights();
        let volumes: Vec<Emitter> = self
            .scene
            .volumes
            .iter()
            .map(|v| Emitter {
                prim_path: &v.prim_path,
                light_group: v.light_group.as_deref(),
            })
            .collect();
        let splits = SplitMap::new(layers, &lights, &volumes)
            .map_err(|e| anyhow!("{}: {e}", self.stage_path.display()))?;
        let depth_bins = deep.then(|| self.depth_bins(DEEP_BINS));
        check_film_bytes(
            self.width,
            self.height,
            Film::BYTES_PER_PIXEL + Film::extra_bytes_per_pixel(splits.len(), depth_bins),
        )?;
        Ok(ExtraOutputs { splits, depth_bins })
    }

    /// `bins` camera-depth slabs over the part of the volumes' world bounds in front
    /// of the camera.
    fn depth_bins(&self, bins: usize) -> DepthBins {
        let (origin, axis) = (self.camera.origin(), self.camera.view_axis());
        let (mut z0, mut z1) = (f64::INFINITY, f64::NEG_INFINITY);
        for (lo, hi) in self.media.iter().filter_map(|m| m.world_bounds()) {
            for corner in crate::volume::grid::box_corners(lo, hi) {
                let z = (corner - origin).dot(axis);
                z0 = z0.min(z);
                z1 = z1.max(z);
            }
        }
        let z0 = z0.max(0.0);
        // A volume behind the camera (nothing to bin) still gets a valid range.
        let z1 = if z1 > z0 { z1 } else { z0 + 1.0 };
        DepthBins { z0, z1, bins }
    }

    /// A worker pool of the requested size (`default` threads when none was asked for;
    /// 0 means all cores).
    pub fn pool(&self, default: usize) -> Result<rayon::ThreadPool> {
        rayon::ThreadPoolBuilder::new()
            .num_threads(self.threads.unwrap_or(default))
            .build()
            .context("cannot start worker threads")
    }

    /// Renders the whole frame, or `region` of it, progressively on `pool`: passes
    /// until the session's samples or time limit (or `budget`'s checkpoints) are
    /// spent, or `stop` is set. `on_samples(n)` is called per finished row of a pass of
    /// `n` samples (progress); `after_pass` after every pass (checkpoints).
    #[allow(clippy::too_many_arguments)]
    pub fn render<E>(
        &self,
        job: &RenderJob,
        region: Option<Region>,
        pool: &rayon::ThreadPool,
        clock: Clock,
        checkpoint: Option<f64>,
        stop: &AtomicBool,
        on_samples: &(dyn Fn(u32) + Sync),
        after_pass: impl FnMut(&Film, &Progress) -> Result<(), E>,
    ) -> Result<(Film, Progress), E> {
        let budget = Budget {
            clock,
            spp_cap: job.spp,
            time_limit: self.time_limit,
            checkpoint,
        };
        let overflow = MEDIA_OVERFLOW.load(Ordering::Relaxed);
        let result = render_progressive(job, region, pool, &budget, stop, on_samples, after_pass);
        let more = MEDIA_OVERFLOW.load(Ordering::Relaxed) - overflow;
        if more > 0 {
            eprintln!(
                "nimbus: warning: {}: {more} ray segments met more than {MAX_MEDIA} volumes; the volumes past the {MAX_MEDIA}th (in stage order) were left out of them",
                self.stage_path.display()
            );
        }
        result
    }

    /// A hash of everything that decides the image: the stage file's bytes, the scene
    /// as evaluated (this covers sublayers, references and resolved asset paths), the
    /// resolved settings and the Nimbus version — not the thread count or the tile.
    /// Tiles of one frame carry it so `merge` can refuse tiles of another render.
    pub fn settings_hash(&self) -> u64 {
        use std::hash::Hasher;
        let mut h = fnv::FnvHasher::default();
        let mut put = |s: &str| {
            h.write(s.as_bytes());
            h.write(&[0xff]);
        };
        match std::fs::read(&self.stage_path) {
            Ok(bytes) => put(&String::from_utf8_lossy(&bytes)),
            Err(e) => put(&format!("unreadable stage: {e}")),
        }
        put(&format!("{:?}", self.scene));
        // Tiles of a denoised frame carry what its merge needs (the albedo AOV): they
        // do not merge with tiles of a frame that is not denoised.
        if self.denoise {
            put("denoise");
        }
        put(&format!(
            "{}x{} spp {} adaptive {:?} depth {} seed {} sampler {:?} time limit {:?} {:?} {:?} prune {} specialise {} nimbus {}",
            self.width,
            self.height,
            self.spp,
            self.adaptive,
            self.max_depth,
            self.seed,
            self.sampler,
            self.time_limit,
            self.tracking,
            self.spec,
            self.octree_prune,
            self.specialise,
            env!("CARGO_PKG_VERSION")
        ));
        h.finish()
    }

    /// Whether the stage has local lights (point, spot, sphere, rect, disk, cylinder):
    /// then `render` says what `--light-sampling` does with them.
    pub fn has_local_lights(&self) -> bool {
        !self.lights.locals().is_empty()
    }

    /// One line saying what `auto` chose and why (`None` when the tracker was named).
    pub fn auto_summary(&self) -> Option<String> {
        let reason = self.auto_reason.as_ref()?;
        let t = &self.tracking;
        Some(format!(
            "tracker auto: {} (scheme {}, transmittance {}{}): {reason}",
            t.tracker.name(),
            t.scheme.name(),
            t.transmittance.name(),
            if t.options.no_absorption_events {
                ", no absorption events"
            } else {
                ""
            }
        ))
    }
}

/// Under `--strict` (or `nimbus:strict`): an error listing every stage warning.
fn refuse_warnings(stage: &Path, scene: &Scene) -> Result<()> {
    if scene.warnings.is_empty() {
        return Ok(());
    }
    let list: Vec<String> = scene
        .warnings
        .iter()
        .map(|w| format!("  {}: {}", w.location(), w.message))
        .collect();
    bail!(
        "{}: {} thing(s) on the stage would not render as authored (strict mode: --strict or nimbus:strict):\n{}",
        stage.display(),
        scene.warnings.len(),
        list.join("\n")
    )
}

/// The tracker settings the overrides and the stage ask for: `auto` (no tracker named,
/// or `auto`) leaves the tracker to [`Analysis::choose`].
struct TrackerRequest {
    settings: TrackerSettings,
    auto: bool,
    given: Given,
}

/// A stage token naming one of `K`'s options, checked (an error names the prim).
fn from_stage<K: Choice>(
    stage: &RenderSettings,
    attr: &str,
    value: &Option<String>,
) -> Result<Option<K>> {
    let Some(v) = value else { return Ok(None) };
    K::from_name(v).map(Some).ok_or_else(|| {
        anyhow!(
            "{}: {attr} = \"{v}\" is not one of {}",
            stage.prim_path.as_deref().unwrap_or("render settings"),
            K::names()
        )
    })
}

/// Tracker settings: overrides beat the stage's render settings, which beat the
/// defaults.
fn tracker_request(o: &Overrides, stage: &RenderSettings) -> Result<TrackerRequest> {
    let d = TrackerSettings::default();
    let named = o.tracker.clone().or_else(|| stage.tracker.clone());
    let auto = named.as_deref().is_none_or(|t| t == "auto");
    let tracker = if auto {
        d.tracker
    } else if let Some(t) = &o.tracker {
        TrackerKind::from_name(t).ok_or_else(|| {
            anyhow!(
                "--tracker {t}: not a tracker; known: auto, {}",
                TrackerKind::names()
            )
        })?
    } else {
        from_stage(stage, "nimbus:tracker", &stage.tracker)?.unwrap_or(d.tracker)
    };
    let scheme = o
        .scheme
        .or(from_stage(stage, "nimbus:scheme", &stage.scheme)?)
        .unwrap_or(d.scheme);
    let transmittance = o
        .transmittance
        .or(from_stage(
            stage,
            "nimbus:transmittance",
            &stage.transmittance,
        )?)
        .unwrap_or(d.transmittance);
    let control = o
        .control
        .or(stage.control.map(|c| c as f32))
        .unwrap_or(d.control);
    if !(control.is_finite() && (0.0..=1.0).contains(&control)) {
        bail!("the decomposition control must lie in [0, 1], got {control}");
    }
    let majorant_scale = o.majorant_scale.unwrap_or(1.0);
    if !(majorant_scale.is_finite() && majorant_scale > 0.0) {
        bail!("--majorant-scale must be positive, got {majorant_scale}");
    }
    let settings = TrackerSettings {
        tracker,
        scheme,
        transmittance,
        control,
        options: SchemeOptions {
            reduced_termination: o.reduced_termination,
            no_absorption_events: o.no_absorption_events,
        },
        majorant_scale,
        profile: o.profile,
        light_sampling: o.light_sampling.unwrap_or(d.light_sampling),
        scatter_guiding: o.scatter_guiding.unwrap_or(d.scatter_guiding),
    };
    Ok(TrackerRequest {
        settings,
        auto,
        given: Given {
            scheme: o.scheme.is_some() || stage.scheme.is_some(),
            transmittance: o.transmittance.is_some() || stage.transmittance.is_some(),
            majorants: majorants_named(o, stage),
        },
    })
}

/// The majorant structure: the octree depth override, else the stage's
/// `nimbus:octreeDepth` (0 there means the flat grid), else the flat grid of
/// `majorant_cell` (default [`DEFAULT_CELL_VOXELS`]) cells.
pub fn majorant_spec(o: &Overrides, stage: &RenderSettings) -> Result<MajorantSpec> {
    let from_stage = match stage.octree_depth {
        None | Some(0) => None,
        Some(d) => Some(u32::try_from(d).map_err(|_| {
            anyhow!(
                "{}: nimbus:octreeDepth = {d} must lie in 0..={MAX_DEPTH}",
                stage.prim_path.as_deref().unwrap_or("render settings")
            )
        })?),
    };
    match o.octree_depth.or(from_stage) {
        Some(depth) if !(1..=MAX_DEPTH).contains(&depth) => {
            bail!("the octree depth must lie in 1..={MAX_DEPTH}, got {depth}")
        }
        Some(depth) => Ok(MajorantSpec::Octree { depth }),
        None => Ok(MajorantSpec::Uniform {
            cell_voxels: o.majorant_cell.unwrap_or(DEFAULT_CELL_VOXELS),
        }),
    }
}

/// Whether the overrides or the stage name a majorant structure (else `auto` may pick
/// one).
fn majorants_named(o: &Overrides, stage: &RenderSettings) -> bool {
    o.majorant_cell.is_some() || o.octree_depth.is_some() || stage.octree_depth.is_some()
}

/// A camera the renderer can shoot rays from: positive focal length and apertures,
/// a non-empty clipping range.
fn check_camera(scene: &Scene) -> Result<()> {
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
    // A zero scale anywhere above the camera collapses its ray directions to zero
    // (NaN once normalised): every ray would miss everything. The stage reader has
    // already refused a non-finite transform.
    let det = glam::DMat3::from_mat4(c.camera_to_world).determinant();
    if !(det != 0.0 && det.is_finite()) {
        bail!(
            "camera {}: its transform is singular (a zero scale in its xformOps or an ancestor's), so its rays have no direction",
            c.prim_path
        );
    }
    if !(c.clipping_range.0.is_finite() && c.clipping_range.1 > c.clipping_range.0) {
        bail!(
            "camera {}: clipping range {:?} is empty",
            c.prim_path,
            c.clipping_range
        );
    }
    Ok(())
}

/// Refuses a film larger than [`MAX_FILM_BYTES`] or than the memory available.
fn check_film_memory(width: u32, height: u32) -> Result<()> {
    check_film_bytes(width, height, Film::BYTES_PER_PIXEL)
}

/// Refuses a film of `per_pixel` bytes per pixel that does not fit in memory.
fn check_film_bytes(width: u32, height: u32, per_pixel: usize) -> Result<()> {
    let film_bytes = width as u64 * height as u64 * per_pixel as u64;
    let gib = |b: u64| b as f64 / (1u64 << 30) as f64;
    if film_bytes > MAX_FILM_BYTES {
        bail!(
            "resolution {width}x{height} needs {:.1} GiB of film memory, more than the {} GiB limit",
            gib(film_bytes),
            MAX_FILM_BYTES >> 30
        );
    }
    if let Some(available) = available_memory_bytes() {
        if film_bytes > available {
            bail!(
                "resolution {width}x{height} needs {:.2} GiB of film memory, more than the {:.2} GiB this machine has available",
                gib(film_bytes),
                gib(available)
            );
        }
    }
    Ok(())
}

/// Memory the system can give a new allocation without swapping (`MemAvailable` of
/// /proc/meminfo, Linux); `None` where that is not known.
pub fn available_memory_bytes() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = text.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024)
}

/// Whether `path` names a VDB file (rendered directly) rather than a stage.
fn is_vdb(path: &Path) -> bool {
    path.extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("vdb"))
}

/// The scene of a VDB file rendered directly: one volume whose density is the grid
/// `grid` (default: the file's first float grid) with the schema's fallback
/// coefficients, the default render settings, and no camera or light (the session adds
/// its defaults).
fn scene_for_vdb(path: &Path, grid: Option<&str>) -> Result<Scene> {
    let loc = AssetLocation::File(path.to_path_buf());
    let grids = vdb::list_grids(&loc)?;
    let is_float = |t: &str| t.contains("float") && !t.contains("vec3");
    let chosen = match grid {
        Some(name) => grids.iter().find(|g| g.name == name).ok_or_else(|| {
            anyhow!(
                "{}: no grid named '{name}'; grids: {}",
                path.display(),
                grids
                    .iter()
                    .map(|g| format!("{} ({})", g.name, g.value_type))
                    .collect::<Vec<_>>()
                    .join(", ")
            )
        })?,
        None => grids
            .iter()
            .find(|g| is_float(&g.value_type.to_ascii_lowercase()))
            .ok_or_else(|| {
                anyhow!(
                    "{}: no float grid to render as density (grids: {}); name one with --grid",
                    path.display(),
                    grids
                        .iter()
                        .map(|g| format!("{} ({})", g.name, g.value_type))
                        .collect::<Vec<_>>()
                        .join(", ")
                )
            })?,
    };
    let field = Field {
        prim_path: format!("{}:{}", path.display(), chosen.name),
        file: loc,
        field_name: chosen.name.clone(),
        field_index: None,
    };
    let volume = Volume {
        prim_path: format!("/{}", chosen.name),
        light_group: None,
        volume_to_world: glam::DMat4::IDENTITY,
        motion: None,
        shape: crate::scene::VolumeShape::Field(field.clone()),
        // NimbusVolumeAPI's fallbacks (schemas/schema.usda).
        density_scale: 1.0,
        absorption: [0.1; 3],
        scattering: [0.9; 3],
        anisotropy: 0.0,
        fields: vec![(chosen.name.clone(), field)],
        emission: VolumeEmission::default(),
        albedo: None,
        albedo_graph: None,
        velocity: None,
        material_shader: None,
        density_graph: None,
    };
    Ok(Scene {
        stage_path: path.to_path_buf(),
        time: f64::NAN,
        camera: crate::scene::defaults::placeholder_camera(),
        distant_lights: Vec::new(),
        dome_lights: Vec::new(),
        sphere_lights: Vec::new(),
        rect_lights: Vec::new(),
        disk_lights: Vec::new(),
        cylinder_lights: Vec::new(),
        volumes: vec![volume],
        holdouts: Vec::new(),
        settings: RenderSettings::default(),
        light_prims: 0,
        warnings: Default::default(),
    })
}

/// One majorant structure per distinct density grid, built by `build` on the first
/// medium that has the grid and shared by the others (the instances of a volume): the
/// structure for each medium, in order.
fn per_grid(
    media: &[Medium],
    build: impl Fn(&Medium) -> Arc<MajorantTree>,
) -> Vec<Arc<MajorantTree>> {
    let mut built: Vec<(*const Grid, Arc<MajorantTree>)> = Vec::new();
    media
        .iter()
        .map(|m| {
            let key = Arc::as_ptr(&m.density);
            if let Some((_, tree)) = built.iter().find(|(k, _)| *k == key) {
                return tree.clone();
            }
            let tree = build(m);
            built.push((key, tree.clone()));
            tree
        })
        .collect()
}
