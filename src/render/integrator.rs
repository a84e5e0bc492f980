//! The volumetric path tracer: delta tracking for free paths, Henyey–Greenstein
//! scattering up to a maximum depth, next-event estimation to suns, sphere and rect
//! lights and the environment (domes, constant or textured) with ratio-tracking
//! transmittance, MIS between environment NEE and phase sampling, and volume emission
//! collected at absorption events; an albedo grid weights each scatter event by c(x).
//! With `ratio-select` a segment's free path is replaced by one ratio-tracking walk
//! ([`ratio_select`]) that weights the background by its transmittance and picks the
//! collision to scatter at.

use crate::color::Spectrum;
use crate::render::adaptive::Adaptive;
use crate::render::camera::CameraRays;
use crate::render::equiangular::{balance, tracker_density, LocalLight};
use crate::render::film::{DepthBins, Film, Pixel};
use crate::render::guiding::LightLobes;
use crate::render::holdouts::Holdouts;
use crate::render::light_choice::LightChoice;
use crate::render::lights::in_mask;
use crate::render::lights::{HoldoutSet, LightSample, Lights, Link};
use crate::render::media_index::MediaIndex;
use crate::render::phase::{hg, sample_hg};
use crate::render::sampler::{pixel_sampler, Sampler};
use crate::render::splits::{SplitMap, MAX_LAYERS};
use crate::track::collision_select::{ratio_select, SegmentEstimate};
use crate::track::free_path::{FreePath, FreePathSampler, Query, TransmittanceEstimator};
use crate::track::race::MAX_MEDIA;
use crate::volume::counters::{Counters, NoCounts, Tally};
use crate::volume::emission::EmissionKind;
use crate::volume::medium::{IndexRay, Medium, Sigma};
use glam::DVec3;
use rand::Rng;
use rayon::prelude::*;

/// Path Russian roulette starts after this many scattering events.
const RR_DEPTH: u32 = 3;

/// Paths whose largest channel throughput is at least this never take part in the
/// roulette; below it a path survives with probability throughput / this. Without
/// absorption events a chromatic path's throughput falls by the albedo at every
/// scattering event, and surviving with probability = throughput (a threshold of 1)
/// killed half the paths of an albedo-0.8 cloud by the fourth event: multiple
/// scattering, most of such a cloud's light and its variance, paid for that.
/// Measured in docs/performance.md ("Fewer, better estimates").
const RR_THROUGHPUT: f32 = 0.25;

/// The cross-sections a path tracks: every channel at once (the spectral trackers; a
/// grey medium's single-channel trackers are this too, with equal channels), or one
/// channel chosen per path (naive delta tracking).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Tracked {
    AllChannels,
    Channel(usize),
}

impl Tracked {
    /// The cross-sections of `medium` this path tracks.
    #[inline(always)]
    fn sigma(self, medium: &Medium) -> Sigma {
        match self {
            Tracked::AllChannels => medium.sigma,
            Tracked::Channel(c) => medium.sigma.channel(c),
        }
    }
}

/// What a query of the media needs of its path: the cross-sections it tracks and the
/// sample's time (where moving media are).
type At = (Tracked, f64);

/// What a path carries from vertex to vertex.
struct PathState {
    tracked: Tracked,
    /// Per-channel throughput (collision weights, albedo, roulette).
    throughput: [f32; 3],
    /// Scattering events so far.
    depth: u32,
    /// Henyey–Greenstein g of the medium of the last scattering vertex (its phase
    /// function, for MIS).
    g: f64,
    /// Cosine of the last phase-sampled turn, for the MIS weight of an escaping ray.
    last_cos: f64,
    /// The density the last turn was drawn from where it was guided towards the
    /// local lights (the mixture's; unused without guiding, where it is the phase
    /// function's, computed from `last_cos` only when an escaping ray needs it).
    last_pdf: f64,
    /// The camera sample's frame-relative time: where moving media and the camera are.
    time: f64,
}

/// What a render adds beside the beauty and the counters: split layers (light groups,
/// path splits) and deep bins. The default adds nothing and costs nothing.
#[derive(Clone, Copy, Default)]
pub struct Extras<'a> {
    /// The split layers every contribution is also added to (`None`: none).
    pub splits: Option<&'a SplitMap>,
    /// Bin each sample by the camera depth of its first real collision.
    pub depth_bins: Option<DepthBins>,
    /// Black matte occluders: camera, scattered and shadow rays end at them (`None`
    /// for a stage without geometry: no query at all).
    pub holdouts: Option<&'a Holdouts>,
    /// Which media a ray may meet, on stages with many ([`MediaIndex::build`]; `None`:
    /// every medium's box is tested).
    pub media_index: Option<&'a MediaIndex>,
    /// Stop each pixel once its noise is below a threshold (`None`: every pixel takes
    /// every sample).
    pub adaptive: Option<Adaptive>,
}

/// Ray segments that met more than [`MAX_MEDIA`] volumes since the process started:
/// the volumes past the 64th (in stage order) were left out of them. Counted off the
/// hot path (only then); the session reports it after a render.
pub static MEDIA_OVERFLOW: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);

/// A sample's radiance: the beauty sum, and the split layers it also feeds.
struct Radiance<'s> {
    total: [f64; 3],
    split: Option<(&'s SplitMap, &'s mut [[f64; 3]])>,
}

impl Radiance<'_> {
    /// Adds `v`, light of `source` after `events` scattering events.
    #[inline(always)]
    fn add(&mut self, source: usize, events: u32, v: [f64; 3]) {
        self.add_total(v);
        self.add_split(source, events, v);
    }

    /// Adds `v` to the beauty only; the caller feeds the layers ([`Self::add_split`]),
    /// as for the environment, whose radiance is split among its domes.
    #[inline(always)]
    fn add_total(&mut self, v: [f64; 3]) {
        for c in 0..3 {
            self.total[c] += v[c];
        }
    }

    #[inline(always)]
    fn splitting(&self) -> bool {
        self.split.is_some()
    }

    #[inline(always)]
    fn add_split(&mut self, source: usize, events: u32, v: [f64; 3]) {
        if let Some((map, layers)) = &mut self.split {
            map.add(layers, source, events, v);
        }
    }
}

pub struct Integrator<'a, F: FreePathSampler, E: TransmittanceEstimator> {
    pub free_path: F,
    pub transmittance: E,
    /// Naive delta tracking: each path tracks one channel, chosen uniformly, weighted
    /// 3× ([`Tracked::Channel`]); otherwise every path tracks all channels at once.
    pub channel_per_path: bool,
    /// Multiplies every majorant (1 = the medium's bounds).
    pub majorant_scale: f32,
    /// Count lookups, collisions and cells into each pixel's counters (for the cost
    /// AOVs and the stats); off, the counting is compiled out ([`NoCounts`]).
    pub count: bool,
    /// Time lookups, traversal and tracker queries into the counters (`--profile`;
    /// implies `count`).
    pub profile: bool,
    /// The stage's volumes (at least one, at most [`MAX_MEDIA`]); where they overlap
    /// their coefficients add ([`track::race`]).
    pub media: &'a [Medium],
    pub lights: &'a Lights,
    pub camera: &'a CameraRays,
    pub width: u32,
    pub height: u32,
    pub spp: u32,
    pub max_depth: u32,
    pub seed: u64,
    /// Dimensions of each sample drawn from scrambled Sobol' points (0: every number
    /// from the independent stream; [`Sampler::start_sample`]).
    pub qmc_dims: u32,
    pub extras: Extras<'a>,
    /// `ratio-select`: each path segment through one volume by one ratio-tracking walk
    /// that estimates the transmittance to its end and picks the collision the path
    /// scatters at ([`ratio_select`]); `free_path` runs where several volumes overlap
    /// along a ray.
    pub select_segments: SelectSegments,
    /// The local lights scattering points are also sampled towards, one equiangular
    /// sample per path segment combined with the trackers' collisions by MIS
    /// ([`crate::render::equiangular`]); empty: the collisions alone.
    pub locals: Vec<LocalLight>,
    /// The shutter interval (frame-relative `open`, `close`) each camera sample draws
    /// its time from, when something the render blurs moves while it is open; `None`:
    /// every sample is at the frame and draws no time (renders without motion are
    /// unchanged).
    pub shutter: Option<(f64, f64)>,
    /// The lobes towards the local lights scattered directions are partly drawn from
    /// ([`crate::render::guiding`]); `None`: the phase function alone.
    pub guide: Option<LightLobes>,
    /// Past [`crate::render::light_choice::MANY_LIGHTS`] local lights, the one light
    /// each vertex's next event samples is chosen by it; `None`: every light.
    pub light_choice: Option<LightChoice>,
}

/// A path segment's equiangular side: its unit-speed line `o + s·ω` (s = t·speed),
/// the stretch `[a, b]` of it the media's boxes cover, and the local lights' total
/// mass M = Σ Φ_k ∫_a^b ds / r_k².
struct LightSegment {
    o: DVec3,
    omega: DVec3,
    /// World length per unit of the segment's `t`.
    speed: f64,
    a: f64,
    b: f64,
    total: f64,
}

/// Whether path segments are walked by [`ratio_select`] (`ratio-select`), and with
/// which transmittance estimate: per channel, or one scalar for grey media (the
/// same choices from the same numbers, [`grey`](crate::track::grey)).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SelectSegments {
    /// Free-path sampling only (every other tracker).
    Off,
    Rgb,
    Grey,
}

/// One sample's result: radiance and alpha (1 − camera-ray transmittance estimate).
pub struct SampleResult {
    pub rgb: [f64; 3],
    pub alpha: f64,
    /// Camera depth of the first real collision on the camera ray (of a ratio-select
    /// walk: the collision it scatters at, else the one its emission was taken at);
    /// NaN when there was none (deep output bins the sample by it).
    pub depth: f64,
    /// The single-scattering albedo (σs/σt, times the albedo field) at the camera
    /// path's first scattering event; 0 when it had none (escaped, or absorbed: the
    /// emission of a fire is not scattered light). The denoiser's auxiliary image.
    pub albedo: [f64; 3],
}

impl<F: FreePathSampler, E: TransmittanceEstimator> Integrator<'_, F, E> {
    /// Renders all pixels with `self.spp` samples in one pass; `progress` is called once
    /// per finished row (from any thread).
    pub fn render(&self, progress: &(dyn Fn() + Sync)) -> Film {
        let mut film = Film::new(self.width, self.height, self.seed);
        self.render_pass(&mut film, self.spp, progress);
        film
    }

    /// Adds `n` samples to every pixel of `film` (a film from [`Film::new`] or
    /// [`Film::of_region`] with this integrator's size and seed), continuing each
    /// pixel's random stream.
    pub fn render_pass(&self, film: &mut Film, n: u32, progress: &(dyn Fn() + Sync)) {
        assert_eq!(film.full, (self.width, self.height), "film size");
        let (region, w) = (film.region, film.width as usize);
        let (nl, nd) = (film.layer_count, film.depth_bins.map_or(0, |d| d.stride()));
        let splits = self
            .extras
            .splits
            .filter(|m| !m.is_empty() && nl == m.len());
        let depth_bins = self.extras.depth_bins.filter(|_| nd > 0);
        // Rows of the extra accumulators (empty slices when a render has none).
        let layer_rows = rows(&mut film.layers, w * nl, film.height as usize);
        let deep_rows = rows(&mut film.deep, w * nd, film.height as usize);
        film.pixels
            .par_chunks_mut(w)
            .zip(film.samplers.par_chunks_mut(w))
            .zip(layer_rows)
            .zip(deep_rows)
            .enumerate()
            // One row per job: rayon otherwise stops splitting at about two chunks per
            // thread unless one is stolen, and the rows a cloud covers cost many times
            // the sky's, so one thread was left with a quarter of the frame (measured:
            // the smoke scene of issue 47 kept 2 threads 1.5 busy, not 2).
            .with_max_len(1)
            .for_each(|(y, (((row, rngs), layers), deep))| {
                let y = region.y0 + y as u32;
                for (x, (px, rng)) in row.iter_mut().zip(rngs).enumerate() {
                    let extra = PixelExtras {
                        splits: splits.map(|m| (m, &mut layers[x * nl..(x + 1) * nl])),
                        deep: depth_bins.map(|d| (d, &mut deep[x * nd..(x + 1) * nd])),
                    };
                    self.add_samples(px, extra, rng, region.x0 + x as u32, y, n);
                }
                progress();
            });
    }

    /// Renders one pixel with `self.spp` samples from the start of its stream.
    pub fn render_pixel(&self, x: u32, y: u32) -> Pixel {
        let index = y as u64 * self.width as u64 + x as u64;
        let mut rng = pixel_sampler(self.seed, index);
        let mut px = Pixel::default();
        self.add_samples(&mut px, PixelExtras::default(), &mut rng, x, y, self.spp);
        px
    }

    fn add_samples(
        &self,
        px: &mut Pixel,
        mut extra: PixelExtras,
        rng: &mut Sampler,
        x: u32,
        y: u32,
        n: u32,
    ) {
        let count = self.count || self.profile;
        // One sample's split layers, added to the pixel's when the sample is finite.
        let mut scratch = [[0f64; 3]; MAX_LAYERS];
        let nl = extra.splits.as_ref().map_or(0, |(m, _)| m.len());
        let dims = self.sample_dims();
        for _ in 0..n {
            // A converged pixel takes no more samples, in this pass or a later one
            // (the check depends only on its own samples so far).
            if self.extras.adaptive.is_some_and(|a| a.converged(px)) {
                break;
            }
            rng.start_sample(dims);
            let fx = x as f64 + rng.gen::<f64>();
            let fy = y as f64 + rng.gen::<f64>();
            let sample_layers = &mut scratch[..nl];
            sample_layers.fill([0.0; 3]);
            let split = extra
                .splits
                .as_ref()
                .map(|(m, _)| (*m, &mut *sample_layers));
            // One branch per sample picks the instantiation; the paths below it are
            // monomorphised with or without counting.
            let s = if count {
                let mut counters = Counters {
                    timing: self.profile,
                    ..Counters::default()
                };
                let s = self.sample_split(fx, fy, rng, &mut counters, split);
                px.counters.add(&counters);
                s
            } else {
                self.sample_split(fx, fy, rng, &mut NoCounts, split)
            };
            let finite = px.add_sample(s.rgb, s.alpha);
            if !finite {
                continue;
            }
            for c in 0..3 {
                px.albedo[c] += s.albedo[c];
            }
            if let Some((_, layers)) = &mut extra.splits {
                for (acc, v) in layers.iter_mut().zip(&scratch[..nl]) {
                    for c in 0..3 {
                        acc[c] += v[c];
                    }
                }
            }
            if let Some((bins, deep)) = &mut extra.deep {
                let b = &mut deep[bins.index(s.depth)];
                for c in 0..3 {
                    b[c] += s.rgb[c];
                }
                b[3] += s.alpha;
            }
        }
    }

    /// Dimensions of each sample drawn from Sobol' points: `qmc_dims`, plus the lens's
    /// two when the camera has depth of field. The lens point is drawn right after the
    /// pixel position (dimensions 2 and 3): it decides the camera ray as much as the
    /// pixel position does, so it gets a stratified pair of its own, and the numbers the
    /// path draws next keep the `qmc_dims − 2` Sobol' dimensions they had. A camera
    /// without depth of field draws no lens numbers at all: its renders are unchanged.
    fn sample_dims(&self) -> u32 {
        match self.qmc_dims {
            0 => 0,
            d => d + self.camera.lens_dims() + self.shutter.is_some() as u32,
        }
    }

    /// One path through image position (`fx`, `fy`).
    pub fn sample<C: Tally>(
        &self,
        fx: f64,
        fy: f64,
        rng: &mut Sampler,
        counters: &mut C,
    ) -> SampleResult {
        self.sample_split(fx, fy, rng, counters, None)
    }

    /// [`Self::sample`], also adding each contribution to the split layers `split`.
    fn sample_split<C: Tally>(
        &self,
        fx: f64,
        fy: f64,
        rng: &mut Sampler,
        counters: &mut C,
        split: Option<(&SplitMap, &mut [[f64; 3]])>,
    ) -> SampleResult {
        let lens: Option<(f64, f64)> = match self.camera.lens_dims() {
            0 => None,
            _ => Some((rng.gen(), rng.gen())),
        };
        // The sample's time, uniform over the shutter (a box shutter, as UsdGeomCamera
        // describes it): its own dimension, after the pixel and lens ones.
        let time = match self.shutter {
            None => 0.0,
            Some((open, close)) => open + (close - open) * rng.gen::<f64>(),
        };
        let ray = match lens {
            None => self.camera.ray_at(fx, fy, time),
            Some((u1, u2)) => self.camera.ray_through_lens_at(fx, fy, u1, u2, time),
        };
        let mut origin = ray.origin;
        let mut dir = ray.dir;
        let (mut tmin, mut tmax) = (ray.tmin as f32, ray.tmax as f32);
        // A holdout in front of the camera ends the camera ray: the trackers sample free
        // paths only up to it, and what passes the volume finds black, with alpha 0.
        let mut blocked = false;
        if let Some(h) = self.extras.holdouts {
            if let Some(d) = h.hit(ray.origin, ray.dir, ray.tmin, ray.tmax) {
                tmax = d as f32;
                blocked = true;
            }
        }
        // Start the camera ray just before it enters the majorant region: trackers add
        // free-path steps to `t` in f32, and far from the origin (f32 spacing 6e-5 at
        // t = 1e3) the steps of a dense medium would round away and stall the walk.
        let entry = self
            .media
            .iter()
            .filter_map(|m| {
                let r = m.index_ray_at(origin, dir, time);
                m.entry(&r, tmin, tmax)
            })
            .fold(f32::INFINITY, f32::min);
        // Distance from the camera to `origin`, for the depth of the first collision.
        let mut camera_shift = 0.0;
        if entry.is_finite() {
            let shift = entry as f64 * (1.0 - 1e-6);
            if shift > 0.0 {
                camera_shift = shift;
                origin += dir * shift;
                tmin = (tmin as f64 - shift).max(0.0) as f32;
                tmax = (tmax as f64 - shift) as f32;
            }
        }
        // Naive delta: track one channel's grey medium, and carry 3× in that channel only.
        let (tracked, throughput) = if self.channel_per_path {
            let ch = ((rng.gen::<u32>() as u64 * 3) >> 32) as usize;
            let mut w = [0f32; 3];
            w[ch] = 3.0;
            (Tracked::Channel(ch), w)
        } else {
            (Tracked::AllChannels, [1f32; 3])
        };
        let mut path = PathState {
            tracked,
            throughput,
            depth: 0,
            g: 0.0,
            last_cos: 1.0,
            last_pdf: 0.0,
            time,
        };
        let mut radiance = Radiance {
            total: [0f64; 3],
            split,
        };
        let mut alpha = 0.0;
        let mut depth = f64::NAN;
        let mut first_albedo = [0f64; 3];
        loop {
            // Scattering points towards the local lights, beside the tracker's: drawn
            // before the walk, with the throughput the segment starts with.
            let segment = self.light_segment(origin, dir, tmin, tmax);
            if let Some(seg) = &segment {
                self.add_equiangular(seg, &path, &mut radiance, rng, counters);
            }
            let t0 = counters.tracker_start();
            // The outputs asked for (deep bins among them) never change which walk
            // runs: the samples, and so the beauty, are the same with or without them.
            let selecting = self.select_segments != SelectSegments::Off;
            let step = self.with_queries(
                origin,
                dir,
                (tmin, tmax),
                (path.tracked, path.time),
                |qs, ids, whole| match qs {
                    [] => Step::Tracked(FreePath::Escape, 0),
                    // A ratio-select walk estimates what lies past the segment's end:
                    // only over the whole ray, not over a span of it.
                    [q] if selecting && whole => {
                        let emissive = self.media[ids[0]].emission.is_some();
                        let beta = path.throughput;
                        let s = match self.select_segments {
                            SelectSegments::Grey => {
                                ratio_select::<f32, _, _>(q, beta, emissive, rng, counters)
                            }
                            SelectSegments::Rgb | SelectSegments::Off => {
                                ratio_select::<Spectrum, _, _>(q, beta, emissive, rng, counters)
                            }
                        };
                        Step::Selected(s, ids[0])
                    }
                    [q] => Step::Tracked(
                        self.free_path
                            .sample(q, &mut path.throughput, rng, counters),
                        ids[0],
                    ),
                    _ => {
                        let (event, lane) =
                            self.free_path
                                .sample_race(qs, &mut path.throughput, rng, counters);
                        Step::Tracked(event, ids[lane])
                    }
                },
                // Over a span: no collision yet, on to the next one.
                |s| matches!(s, Step::Tracked(FreePath::Escape, _)),
            );
            counters.tracker_stop(t0);
            let (event, id, selected) = match step {
                Step::Tracked(event, id) => (event, id, false),
                Step::Selected(s, id) => {
                    if path.depth == 0 {
                        alpha = 1.0 - crate::track::free_path::avg(s.transmittance) as f64;
                        // A ratio-tracking walk has no first real collision: deep
                        // output bins the sample at the collision it scatters at
                        // (set below), else at the one its emission was taken at.
                        if let (None, Some((t, _))) = (s.scatter, s.emit) {
                            depth = (camera_shift + t as f64) * ray.depth_per_t;
                        }
                    }
                    let ray = (origin, dir, blocked);
                    self.add_walk_light(&s, id, &path, ray, &mut radiance, counters);
                    let Some((t, w)) = s.scatter else {
                        break;
                    };
                    path.throughput = w;
                    (FreePath::Scatter { t }, id, true)
                }
            };
            // The medium whose collision it was (its phase function, emission, albedo).
            let medium = &self.media[id];
            match event {
                FreePath::Escape => {
                    if path.depth == 0 {
                        alpha = 1.0 - crate::track::free_path::avg(path.throughput) as f64;
                    }
                    self.add_escape(path.throughput, &path, dir, blocked, &mut radiance);
                    break;
                }
                FreePath::Absorb { t } => {
                    if path.depth == 0 {
                        alpha = 1.0;
                        depth = (camera_shift + t as f64) * ray.depth_per_t;
                    }
                    // Emission is collected at absorption events: the tracker has
                    // applied the absorption weight μa(λ)/(μ̄·Pa), so path.throughput × Le is
                    // the collision estimate of ∫ T·μa·Le (the source term μa·Le).
                    let p = origin + dir * t as f64;
                    let (w, depth) = (path.throughput, path.depth);
                    self.add_emission(id, p, path.time, w, depth, &mut radiance, counters);
                    break;
                }
                FreePath::Scatter { t } => {
                    if path.depth == 0 {
                        if !selected {
                            alpha = 1.0;
                        }
                        depth = (camera_shift + t as f64) * ray.depth_per_t;
                    }
                    path.depth += 1;
                    let p = origin + dir * t as f64;
                    // Albedo multiplier c(x) (nimbus:albedoField): the trackers ran
                    // with c = 1 (μt is unchanged); weighting the scatter event by
                    // c(x) turns its estimate of ∫T·μs·Ls into ∫T·c·μs·Ls, and the
                    // (1 − c) part is absorbed (see volume::albedo).
                    let c = match &medium.albedo {
                        Some(albedo) => {
                            let at_frame = medium.at_frame(p, path.time, counters);
                            albedo.sample(at_frame, counters)
                        }
                        None => [1.0; 3],
                    };
                    if medium.albedo.is_some() {
                        for (w, c) in path.throughput.iter_mut().zip(c) {
                            *w *= c;
                        }
                    }
                    if path.depth == 1 {
                        first_albedo = single_scattering_albedo(medium, c);
                    }
                    path.g = medium.g as f64;
                    let last = path.depth >= self.max_depth;
                    let seg = segment.as_ref();
                    let chosen =
                        self.next_event(p, id, dir, &path, last, seg, &mut radiance, rng, counters);
                    if last {
                        break;
                    }
                    if path.depth >= RR_DEPTH {
                        // Weighted trackers make throughputs signed: survive by magnitude.
                        let m = crate::track::free_path::max3(path.throughput.map(f32::abs));
                        let q = (m / RR_THROUGHPUT).min(1.0);
                        if !(rng.gen::<f32>() < q) {
                            break;
                        }
                        path.throughput = path.throughput.map(|v| v / q);
                    }
                    let new_dir = match &self.guide {
                        None => sample_hg(path.g, dir, rng.gen(), rng.gen()),
                        Some(lobes) => {
                            let u = [rng.gen(), rng.gen(), rng.gen()];
                            let (omega, weight, pdf) = match lobes.one_lobe() {
                                true => lobes.sample_towards(p, dir, path.g, chosen, u),
                                false => lobes.sample(p, dir, path.g, u),
                            };
                            for w in path.throughput.iter_mut() {
                                *w *= weight as f32;
                            }
                            path.last_pdf = pdf;
                            omega
                        }
                    };
                    path.last_cos = dir.dot(new_dir);
                    origin = p;
                    dir = new_dir;
                    tmin = 0.0;
                    tmax = f32::INFINITY;
                    if let Some(h) = self.extras.holdouts {
                        let hit = h.hit(origin, dir, 0.0, f64::INFINITY);
                        blocked = hit.is_some();
                        tmax = hit.map_or(f32::INFINITY, |d| d as f32);
                    }
                }
            }
        }
        SampleResult {
            rgb: radiance.total,
            alpha,
            depth,
            albedo: first_albedo,
        }
    }

    /// Adds what a ratio-select walk along `ray` (origin, direction, whether a holdout
    /// ends it) through medium `id` estimated besides its scattering collision: the
    /// environment behind it through the transmittance, and the emission at the
    /// collision chosen for it.
    fn add_walk_light<C: Tally>(
        &self,
        s: &SegmentEstimate,
        id: usize,
        path: &PathState,
        ray: (DVec3, DVec3, bool),
        radiance: &mut Radiance,
        counters: &mut C,
    ) {
        let (origin, dir, blocked) = ray;
        let mut tr = s.transmittance;
        crate::track::free_path::mul(&mut tr, path.throughput);
        self.add_escape(tr, path, dir, blocked, radiance);
        if let Some((t, w)) = s.emit {
            let p = origin + dir * t as f64;
            self.add_emission(id, p, path.time, w, path.depth, radiance, counters);
        }
    }

    /// Adds the environment seen along `dir` past the path's last vertex with
    /// `throughput` (nothing past a holdout, which `blocked` says ended the ray).
    fn add_escape(
        &self,
        throughput: Spectrum,
        path: &PathState,
        dir: DVec3,
        blocked: bool,
        radiance: &mut Radiance,
    ) {
        if !blocked && self.lights.has_environment() {
            let w = self.escape_weight(path, dir);
            self.add_environment(radiance, throughput, path.depth, dir, w);
        }
        // Camera rays see linked domes as they see any dome; scattered rays reach them
        // by next-event estimation only.
        if !blocked && path.depth == 0 {
            for (i, dome) in self.lights.linked_domes.iter().enumerate() {
                let source = self.lights.sources.linked_dome(i);
                radiance.add(source, 0, scaled(throughput, dome.radiance(dir), 1.0));
            }
        }
    }

    /// Adds the emission of medium `id` at `p` with `weight`, the estimate of the
    /// source term ∫ T·μa·Le the tracker's event made (an absorption event's weight, or
    /// ratio-select's emission collision).
    #[allow(clippy::too_many_arguments)]
    fn add_emission<C: Tally>(
        &self,
        id: usize,
        p: DVec3,
        time: f64,
        weight: Spectrum,
        depth: u32,
        radiance: &mut Radiance,
        counters: &mut C,
    ) {
        let medium = &self.media[id];
        if let Some(emission) = &medium.emission {
            let at_frame = medium.at_frame(p, time, counters);
            let mut le = emission.radiance(at_frame, counters);
            if emission.params.kind == EmissionKind::Source {
                // The model gives the source term S itself; the event's weight estimates
                // ∫T·μa·(·), so S/μa(λ, x) makes it an estimate of ∫T·S. One more density
                // lookup (the trackers do not hand the event's density over). Where
                // μa(λ, x) = 0 the event cannot happen in that channel: nothing emits.
                let d = medium.density_at_world(p, time, counters) as f64;
                for (l, a) in le.iter_mut().zip(medium.sigma.a) {
                    let mu_a = d * a as f64;
                    *l = if mu_a > 0.0 { *l / mu_a } else { 0.0 };
                }
            }
            let source = self.extras.splits.map_or(0, |m| m.emission_source(id));
            radiance.add(source, depth, scaled(weight, le, 1.0));
        }
    }

    /// The MIS weight of environment light reached along `dir` by the path's last
    /// phase-sampled ray (1 for a camera ray, and without environment NEE); the phase
    /// sample's weight phase/pdf is 1.
    fn escape_weight(&self, path: &PathState, dir: DVec3) -> f64 {
        if path.depth == 0 || !self.lights.environment_nee() {
            return 1.0;
        }
        let continuation = match self.guide {
            None => hg(path.g, path.last_cos),
            Some(_) => path.last_pdf,
        };
        power_heuristic(continuation, self.lights.environment_pdf(dir))
    }

    /// Adds environment light arriving along `dir` with MIS weight `w`; the split
    /// layers get each dome's share.
    fn add_environment(
        &self,
        radiance: &mut Radiance,
        throughput: [f32; 3],
        events: u32,
        dir: DVec3,
        w: f64,
    ) {
        let le = self.lights.environment_radiance(dir);
        radiance.add_total(scaled(throughput, le, w));
        if radiance.splitting() {
            self.lights.environment_parts(dir, |source, part| {
                radiance.add_split(source, events, scaled(throughput, part, w));
            });
        }
    }

    /// Next-event estimation from scattering vertex `p` in medium `id` (arrived along
    /// `dir`; the path's phase function, tracked channels and throughput); `last`: the
    /// path ends here (maximum depth), so no phase-sampled ray will reach the
    /// environment. A light whose `collection:lightLink` leaves medium `id` out adds
    /// nothing here (its [`Link`]). On a `segment` that also sampled a scattering
    /// point towards the local lights, each local light's estimate here carries the
    /// tracker's MIS weight. Returns the local light chosen to stand for all of them
    /// where a stage has many ([`LightChoice`]; `None` otherwise).
    #[allow(clippy::too_many_arguments)]
    fn next_event<C: Tally>(
        &self,
        p: DVec3,
        id: usize,
        dir: DVec3,
        path: &PathState,
        last: bool,
        segment: Option<&LightSegment>,
        radiance: &mut Radiance,
        rng: &mut Sampler,
        counters: &mut C,
    ) -> Option<usize> {
        let (g, throughput) = (path.g, path.throughput);
        let tracked = (path.tracked, path.time);
        let (events, sources) = (path.depth, &self.lights.sources);
        // The tracker's collision density here (its stand-in) against each light's
        // equiangular one: the balance heuristic.
        // Outside the stretch [a, b] equiangular sampling never lands: the collision
        // keeps its whole weight there (the weights must sum to 1 at every point).
        let collision = segment
            .map(|seg| (seg, (p - seg.o).dot(seg.omega)))
            .filter(|&(seg, s)| s >= seg.a && s <= seg.b)
            .map(|(seg, s)| {
                let sigma_t = self.extinction_at(p, seg.omega, id, tracked, counters);
                let tau = self.optical_depth_guess(seg, s, tracked);
                (seg, s, tracker_density(sigma_t, tau))
            });
        // A light never sampled equiangularly here (no power, or `p` outside its
        // cone's stretch) keeps weight 1.
        let weight = |k: usize| match collision {
            Some((seg, s, pd)) => {
                let line = (seg.o, seg.omega, seg.a, seg.b);
                balance(pd, self.locals[k].density_at(line, s, p, seg.total))
            }
            None => 1.0,
        };
        // Many local lights: one, chosen by power over squared distance, stands for
        // all of them, its estimate divided by its probability (`scale(k)`: `None`
        // for the lights not chosen).
        let chosen = self
            .light_choice
            .as_ref()
            .map(|c| c.pick(p, rng.gen::<f64>()));
        let scale = |k: usize| match chosen {
            None => Some(1.0),
            Some(Some((c, prob))) if c == k => Some(1.0 / prob),
            Some(_) => None,
        };
        let mut k = 0;
        for (i, sun) in self.lights.suns.iter().enumerate() {
            if !sun.link.lights(id) {
                continue;
            }
            let wi = sun.sample_direction(rng.gen(), rng.gen());
            let mut irradiance = sun.irradiance;
            if let Some(shaping) = &sun.shaping {
                // The light leaves the sun along −wi.
                let f = shaping.factor(-wi);
                if f == [0.0; 3] {
                    continue;
                }
                irradiance = std::array::from_fn(|c| irradiance[c] * f[c]);
            }
            let tr = self.shadow(
                p,
                wi,
                f32::INFINITY,
                tracked,
                (&sun.link, false),
                rng,
                counters,
            );
            let f = hg(g, dir.dot(wi));
            let v = std::array::from_fn(|c| (throughput[c] * tr[c]) as f64 * irradiance[c] * f);
            radiance.add(sources.sun(i), events, v);
        }
        for (i, sphere) in self.lights.spheres.iter().enumerate() {
            let Some(scale) = scale(k + i).filter(|_| sphere.link.lights(id)) else {
                continue;
            };
            let Some(survival) = self.far_roulette(k + i, p, throughput, rng) else {
                continue;
            };
            let s = sphere.sample_at(p, path.time, rng.gen(), rng.gen());
            let light = (
                sources.sphere(i),
                &sphere.link,
                weight(k + i) * scale / survival,
            );
            self.add_light_sample(s, light, p, dir, path, radiance, rng, counters);
        }
        k += self.lights.spheres.len();
        for (i, rect) in self.lights.rects.iter().enumerate() {
            let Some(scale) = scale(k + i).filter(|_| rect.link.lights(id)) else {
                continue;
            };
            let s = rect.sample_at(p, path.time, rng.gen(), rng.gen());
            let light = (sources.rect(i), &rect.link, weight(k + i) * scale);
            self.add_light_sample(s, light, p, dir, path, radiance, rng, counters);
        }
        k += self.lights.rects.len();
        for (i, disk) in self.lights.disks.iter().enumerate() {
            let Some(scale) = scale(k + i).filter(|_| disk.link.lights(id)) else {
                continue;
            };
            let s = disk.sample_at(p, path.time, rng.gen(), rng.gen());
            let light = (sources.disk(i), &disk.link, weight(k + i) * scale);
            self.add_light_sample(s, light, p, dir, path, radiance, rng, counters);
        }
        k += self.lights.disks.len();
        for (i, cylinder) in self.lights.cylinders.iter().enumerate() {
            let Some(scale) = scale(k + i).filter(|_| cylinder.link.lights(id)) else {
                continue;
            };
            let s = cylinder.sample_at(p, path.time, rng.gen(), rng.gen());
            let light = (sources.cylinder(i), &cylinder.link, weight(k + i) * scale);
            self.add_light_sample(s, light, p, dir, path, radiance, rng, counters);
        }
        // A constant environment is reached by the phase-sampled continuation, whose
        // density is the phase function itself: the ideal strategy for light of the
        // same radiance from every direction, and free (the path is traced anyway).
        // A shadow ray towards it only pays off at the path's last vertex.
        let nee = self.lights.environment_nee();
        if self.lights.has_environment() && (nee || last) {
            let (wi, le, pdf) = self.lights.sample_environment(rng.gen(), rng.gen());
            if pdf > 0.0 {
                let f = hg(g, dir.dot(wi));
                // Against the density the continuation is drawn from: the phase
                // function, or the mixture where it is guided.
                let w = match (nee && !last, &self.guide) {
                    (false, _) => 1.0,
                    (true, None) => power_heuristic(pdf, f),
                    (true, Some(lobes)) => power_heuristic(pdf, lobes.pdf(p, dir, g, wi)),
                };
                let tr = self.shadow(
                    p,
                    wi,
                    f32::INFINITY,
                    tracked,
                    (&Link::ALL, false),
                    rng,
                    counters,
                );
                let v = |l: [f64; 3]| -> [f64; 3] {
                    std::array::from_fn(|c| (throughput[c] * tr[c]) as f64 * l[c] * f / pdf * w)
                };
                radiance.add_total(v(le));
                if radiance.splitting() {
                    self.lights.environment_parts(wi, |source, part| {
                        radiance.add_split(source, events, v(part));
                    });
                }
            }
        }
        // Linked domes are not part of the environment scattered rays find: next-event
        // estimation alone reaches them, at every vertex (no MIS weight).
        for (i, dome) in self.lights.linked_domes.iter().enumerate() {
            if !dome.link.lights(id) {
                continue;
            }
            let (wi, le, pdf) = dome.sample(rng.gen(), rng.gen());
            if pdf > 0.0 {
                let f = hg(g, dir.dot(wi));
                let tr = self.shadow(
                    p,
                    wi,
                    f32::INFINITY,
                    tracked,
                    (&dome.link, false),
                    rng,
                    counters,
                );
                let v = std::array::from_fn(|c| (throughput[c] * tr[c]) as f64 * le[c] * f / pdf);
                radiance.add(sources.linked_dome(i), events, v);
            }
        }
        chosen.flatten().map(|(k, _)| k)
    }

    /// Russian roulette on the next event towards local light `k` from a vertex `p`
    /// beyond the ball of its [`LocalLight::chord`] (or nearer, on a path whose
    /// throughput has fallen): the event survives with probability
    /// q = (R / d)² · max throughput (R the ball's radius, d the distance to the
    /// light), when that is below 1, and its estimate is divided by q; `None` when it
    /// is killed. Unbiased for any q; a light without a chord keeps every
    /// event, with no random number drawn. A light's next-event estimate falls as
    /// 1/d², so past the ball a survivor weighs what an event on the ball's surface
    /// would: those far events are a small part of the light that reaches a pixel
    /// (the ones near the light make it), and each costs a shadow ray through the
    /// medium towards the light, the dearest part of a vertex.
    #[inline]
    fn far_roulette(
        &self,
        k: usize,
        p: DVec3,
        throughput: Spectrum,
        rng: &mut Sampler,
    ) -> Option<f64> {
        let Some(light) = self.locals.get(k).filter(|l| l.power > 0.0) else {
            return Some(1.0);
        };
        let Some(radius) = light.chord else {
            return Some(1.0);
        };
        let d2 = (p - light.center).length_squared();
        let beta = crate::track::free_path::max3(throughput.map(f32::abs)) as f64;
        let q = radius * radius / d2 * beta;
        if !(q < 1.0) {
            return Some(1.0);
        }
        (rng.gen::<f64>() < q).then_some(q)
    }

    /// Adds a sphere, rect, disk or cylinder light sample (scattered rays never hit
    /// these lights) of `light` = (source, link, MIS weight against equiangular
    /// sampling), its shadow ray stopping at the light and shadowed as `link` says.
    #[allow(clippy::too_many_arguments)]
    fn add_light_sample<C: Tally>(
        &self,
        sample: Option<LightSample>,
        light: (usize, &Link, f64),
        p: DVec3,
        dir: DVec3,
        path: &PathState,
        radiance: &mut Radiance,
        rng: &mut Sampler,
        counters: &mut C,
    ) {
        let Some(s) = sample else {
            return;
        };
        let (source, link, w) = light;
        let (g, throughput) = (path.g, path.throughput);
        let f = hg(g, dir.dot(s.wi));
        let tr = self.shadow(
            p,
            s.wi,
            s.distance as f32,
            (path.tracked, path.time),
            (link, true),
            rng,
            counters,
        );
        let v = std::array::from_fn(|c| (throughput[c] * tr[c]) as f64 * s.weight[c] * f * w);
        radiance.add(source, path.depth, v);
    }

    /// The equiangular side of the segment `origin + t·dir`, `t` in [`tmin`, `tmax`]:
    /// `None` on a stage without local lights (nothing is drawn: such renders are
    /// unchanged) and where the ray meets no medium's box.
    #[inline(always)]
    fn light_segment(
        &self,
        origin: DVec3,
        dir: DVec3,
        tmin: f32,
        tmax: f32,
    ) -> Option<LightSegment> {
        if self.locals.is_empty() {
            return None;
        }
        self.light_segment_of_media(origin, dir, tmin, tmax)
    }

    #[inline(never)]
    fn light_segment_of_media(
        &self,
        origin: DVec3,
        dir: DVec3,
        tmin: f32,
        tmax: f32,
    ) -> Option<LightSegment> {
        let speed = dir.length();
        if !(speed > 0.0) {
            return None;
        }
        let (mut a, mut b) = (f64::INFINITY, f64::NEG_INFINITY);
        self.media_met(origin, dir, tmin, tmax, u64::MAX, |_, (t0, t1)| {
            a = a.min(t0);
            b = b.max(t1);
        });
        if !(a < b) {
            return None;
        }
        let omega = dir / speed;
        let (a, b) = (a * speed, b * speed);
        let total: f64 = self
            .locals
            .iter()
            .map(|l| {
                l.equiangular(origin, omega, a, b)
                    .map_or(0.0, |e| l.power * e.mass())
            })
            .sum();
        (total > 0.0 && total.is_finite()).then_some(LightSegment {
            o: origin,
            omega,
            speed,
            a,
            b,
            total,
        })
    }

    /// One scattering point of `seg` sampled towards a local light (chosen by its
    /// share of the mass), its next-event estimate weighted against the tracker's
    /// collisions ([`crate::render::equiangular`]): T̂(a, s) · σs(s) · phase · light /
    /// (Q_ℓ p_ℓ(s)), T̂ by the transmittance estimator.
    #[inline(never)]
    fn add_equiangular<C: Tally>(
        &self,
        seg: &LightSegment,
        path: &PathState,
        radiance: &mut Radiance,
        rng: &mut Sampler,
        counters: &mut C,
    ) {
        let (u, v): (f64, f64) = (rng.gen(), rng.gen());
        let (u1, u2): (f64, f64) = (rng.gen(), rng.gen());
        // The light whose cumulative share of M passes u·M.
        let target = u * seg.total;
        let mut acc = 0.0;
        let mut chosen = None;
        for (k, l) in self.locals.iter().enumerate() {
            if let Some(e) = l.equiangular(seg.o, seg.omega, seg.a, seg.b) {
                acc += l.power * e.mass();
                chosen = Some((k, e));
                if acc > target {
                    break;
                }
            }
        }
        let Some((k, e)) = chosen else {
            return;
        };
        let s = e.sample(v);
        // Rounding can put s a hair outside the light's stretch, where the collision
        // side would give it weight 0: drop it there too.
        let line = (seg.o, seg.omega, seg.a, seg.b);
        let x = seg.o + seg.omega * s;
        let pdf = self.locals[k].density_at(line, s, x, seg.total);
        if !(s > seg.a && s < seg.b && pdf > 0.0) {
            return;
        }
        let (sample, link, source) = self.lights.sample_local(k, x, path.time, (u1, u2));
        let Some(ls) = sample else {
            return;
        };
        // σs × phase of the media light k lights at x, and the extinction there.
        let mut f = [0f64; 3];
        let mut sigma_t = 0.0;
        let cos = seg.omega.dot(ls.wi);
        let time = path.time;
        self.media_at(x, seg.omega, None, time, counters, |id, m, d, counters| {
            sigma_t += d * crate::track::free_path::avg(path.tracked.sigma(m).t) as f64;
            if link.lights(id) {
                let phase = hg(m.g as f64, cos);
                let c = m.albedo.as_ref().map_or([1.0; 3], |a| {
                    let at_frame = m.at_frame(x, time, counters);
                    a.sample(at_frame, counters)
                });
                for ch in 0..3 {
                    f[ch] += d * m.sigma.s[ch] as f64 * c[ch] as f64 * phase;
                }
            }
        });
        if f == [0.0; 3] {
            return;
        }
        let w = balance(
            pdf,
            tracker_density(
                sigma_t,
                self.optical_depth_guess(seg, s, (path.tracked, time)),
            ),
        );
        // Transmittance from where the media begin to x, then from x to the light.
        let (ta, tx) = (seg.a / seg.speed, s / seg.speed);
        let dir = seg.omega * seg.speed;
        let start = seg.o + dir * ta;
        let tr_in = self.shadow(
            start,
            dir,
            (tx - ta) as f32,
            (path.tracked, time),
            (&Link::ALL, true),
            rng,
            counters,
        );
        if tr_in == [0.0; 3] {
            return;
        }
        let tr_out = self.shadow(
            x,
            ls.wi,
            ls.distance as f32,
            (path.tracked, time),
            (link, true),
            rng,
            counters,
        );
        let value = std::array::from_fn(|c| {
            (path.throughput[c] * tr_in[c] * tr_out[c]) as f64 * f[c] * ls.weight[c] * w / pdf
        });
        radiance.add(source, path.depth + 1, value);
    }

    /// τ̃(a, s), the stand-in for the optical depth along `seg` from its start to `s`
    /// (mean over the tracked channels) that the MIS weights use: each majorant
    /// segment's length times the midpoint of its density bounds. Exact where the
    /// bounds are equal (fog boxes, world fog); a deterministic function of `s`
    /// everywhere, which is all the weights need to keep the sum unbiased.
    fn optical_depth_guess(&self, seg: &LightSegment, s: f64, (tracked, time): At) -> f64 {
        let dir = seg.omega * seg.speed;
        let (t0, t1) = ((seg.a / seg.speed) as f32, (s / seg.speed) as f32);
        let mut tau = 0.0;
        self.media_met(seg.o, dir, t0, t1, u64::MAX, |i, (ta, tb)| {
            let m = &self.media[i];
            let depth = match m.everywhere_density() {
                // World fog: no cells to walk.
                Some(d) => d as f64 * (tb - ta),
                None => {
                    let ray = m.index_ray_at(seg.o, dir, time);
                    m.walk(&ray, ta as f32, tb as f32)
                        .map(|g| 0.5 * (g.dmin + g.dmax) as f64 * (g.t1 - g.t0) as f64)
                        .sum()
                }
            };
            tau += depth * crate::track::free_path::avg(tracked.sigma(m).t) as f64;
        });
        tau * seg.speed
    }

    /// The extinction (mean over the tracked channels) of every medium at `p`, a
    /// collision of medium `known` (which holds it: no boundary query for it).
    fn extinction_at<C: Tally>(
        &self,
        p: DVec3,
        dir: DVec3,
        known: usize,
        (tracked, time): At,
        counters: &mut C,
    ) -> f64 {
        let mut sigma_t = 0.0;
        self.media_at(p, dir, Some(known), time, counters, |_, m, d, _| {
            sigma_t += d * crate::track::free_path::avg(tracked.sigma(m).t) as f64;
        });
        sigma_t
    }

    /// Calls `f(id, medium, density, counters)` for every medium whose region holds
    /// `p` with a positive density there (one lookup per medium whose box holds `p`;
    /// a fog box's region asks its boundary, with a ray along `dir`, unless it is
    /// `known` to hold `p`).
    fn media_at<C: Tally>(
        &self,
        p: DVec3,
        dir: DVec3,
        known: Option<usize>,
        time: f64,
        counters: &mut C,
        mut f: impl FnMut(usize, &Medium, f64, &mut C),
    ) {
        let mut take = |i: usize| {
            let m = &self.media[i];
            if known == Some(i) || m.contains(p, dir) {
                let d = m.density_at_world(p, time, counters) as f64;
                if d > 0.0 {
                    f(i, m, d, counters);
                }
            }
        };
        match self.media {
            [_] => take(0),
            _ => self.media_met(p, dir, 0.0, 0.0, u64::MAX, |i, _| take(i)),
        }
    }

    /// The transmittance estimate along the shadow ray `p + t·wi`, t < `tmax`, through
    /// the holdouts and media that shadow a light linked by `link` (every one without
    /// shadow linking). `local`: the ray serves a local light's estimate, whose
    /// majorants the estimator may loosen
    /// ([`TransmittanceEstimator::LOCAL_LIGHT_MAJORANT_SCALE`]).
    #[allow(clippy::too_many_arguments)]
    fn shadow<C: Tally>(
        &self,
        p: DVec3,
        wi: DVec3,
        tmax: f32,
        at: At,
        (link, local): (&Link, bool),
        rng: &mut Sampler,
        counters: &mut C,
    ) -> Spectrum {
        // The set shadows the volume: a blocked shadow ray needs no tracking.
        let holdouts = match link.holdouts {
            HoldoutSet::All => self.extras.holdouts,
            HoldoutSet::None => None,
            HoldoutSet::Subset(k) => self.lights.holdout_sets.get(k),
        };
        if let Some(h) = holdouts {
            if h.occluded(p, wi, 0.0, tmax as f64) {
                return [0.0; 3];
            }
        }
        let t0 = counters.tracker_start();
        // Spans of a ray meeting very many volumes multiply (independent estimates).
        let mut product = [1f32; 3];
        let scale = match local {
            true => self.majorant_scale * E::LOCAL_LIGHT_MAJORANT_SCALE,
            false => self.majorant_scale,
        };
        let tr = self.with_queries_in(
            p,
            wi,
            (0.0, tmax),
            at,
            (link.shadowing, scale),
            |qs, _, _| {
                let t = if let [q] = qs {
                    self.transmittance.transmittance(q, rng, counters)
                } else {
                    self.transmittance.transmittance_race(qs, rng, counters)
                };
                crate::track::free_path::mul(&mut product, t);
                product
            },
            |t| *t != [0.0; 3],
        );
        counters.tracker_stop(t0);
        tr
    }

    /// [`Self::with_queries_in`] over every medium.
    #[inline(always)]
    fn with_queries<T>(
        &self,
        origin: DVec3,
        dir: DVec3,
        range: (f32, f32),
        at: At,
        f: impl FnMut(&[Query], &[usize], bool) -> T,
        go_on: impl Fn(&T) -> bool,
    ) -> T {
        self.with_queries_in(
            origin,
            dir,
            range,
            at,
            (u64::MAX, self.majorant_scale),
            f,
            go_on,
        )
    }

    /// Calls `f(queries, ids, true)` with one tracker query per medium in `mask` (bit
    /// i: medium i; shadow linking leaves media out) that the world-space ray
    /// `origin + t·dir`, `t` in [`tmin`, `tmax`], may meet (each medium's index-space
    /// ray and cross-sections: one channel's, for naive delta), and with each query's
    /// index in `self.media`. Built on the stack; a stage with one volume skips the
    /// culling, which its majorant walk does anyway. A ray that meets more than
    /// [`MAX_MEDIA`] volumes is cut into spans ([`Self::spans`]): `f(queries, ids,
    /// false)` per span, in order, while `go_on(&result)`; the last result is returned.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn with_queries_in<T>(
        &self,
        origin: DVec3,
        dir: DVec3,
        (tmin, tmax): (f32, f32),
        at: At,
        (mask, scale): (u64, f32),
        mut f: impl FnMut(&[Query], &[usize], bool) -> T,
        go_on: impl Fn(&T) -> bool,
    ) -> T {
        let (tracked, time) = at;
        if let [m] = self.media {
            // One volume (the common stage): its query built directly.
            if mask & 1 == 0 {
                return f(&[], &[], true);
            }
            let (ray, sigma) = (m.index_ray_at(origin, dir, time), tracked.sigma(m));
            let q = [Query {
                medium: m,
                sigma: &sigma,
                ray: &ray,
                tmin,
                tmax,
                majorant_scale: scale,
            }];
            return f(&q, &[0], true);
        }
        let mut ids = [0usize; MAX_MEDIA];
        let mut k = 0;
        let mut overflow = false;
        self.media_met(origin, dir, tmin, tmax, mask, |i, _| {
            if k < MAX_MEDIA {
                ids[k] = i;
                k += 1;
            } else {
                overflow = true;
            }
        });
        if overflow {
            return self.spans(origin, dir, tmin, tmax, at, (mask, scale), &mut f, &go_on);
        }
        // Media order, whatever order the index found them in: the race draws each
        // lane's random numbers in lane order, so the image depends on it.
        if self.extras.media_index.is_some() {
            ids[..k].sort_unstable();
        }
        self.queries_sized(origin, dir, (tmin, tmax), at, (&ids[..k], scale), |q, i| {
            f(q, i, true)
        })
    }

    /// A ray meeting more than [`MAX_MEDIA`] volumes (a cloudscape seen edge-on), cut
    /// into consecutive spans each meeting at most that many: a span ends where the
    /// next volume's box begins. Tracking the spans one after another is the same
    /// process as tracking the whole ray (the collisions of disjoint stretches are
    /// independent, and a transmittance is the product of its stretches'), so every
    /// estimator stays exact. Only where more than [`MAX_MEDIA`] boxes overlap at one
    /// point are the volumes past that many left out of the stretch (counted in
    /// [`MEDIA_OVERFLOW`], a warning after the render). Off the hot path: a few KiB of
    /// stack, no allocation.
    #[allow(clippy::too_many_arguments)]
    #[cold]
    #[inline(never)]
    fn spans<T>(
        &self,
        origin: DVec3,
        dir: DVec3,
        tmin: f32,
        tmax: f32,
        at: At,
        (mask, scale): (u64, f32),
        f: &mut impl FnMut(&[Query], &[usize], bool) -> T,
        go_on: &impl Fn(&T) -> bool,
    ) -> T {
        const CANDIDATES: usize = 2048;
        // (box entry, box exit, medium) of every volume the ray meets.
        let mut c = [(0f32, 0f32, 0u32); CANDIDATES];
        let mut n = 0;
        let mut dropped = false;
        self.media_met(origin, dir, tmin, tmax, mask, |i, (a, b)| {
            if n < CANDIDATES {
                c[n] = (a as f32, b as f32, i as u32);
                n += 1;
            } else {
                dropped = true;
            }
        });
        let c = &mut c[..n];
        c.sort_unstable_by(|x, y| x.0.total_cmp(&y.0).then(x.2.cmp(&y.2)));
        let mut s = tmin;
        loop {
            // The first MAX_MEDIA volumes (by entry) still ahead at s; the span ends
            // where the next one enters.
            let mut ids = [0usize; MAX_MEDIA];
            let mut k = 0;
            let mut e = tmax;
            for &(a, b, i) in c.iter() {
                if b <= s {
                    continue;
                }
                if k == MAX_MEDIA {
                    e = a;
                    break;
                }
                ids[k] = i as usize;
                k += 1;
            }
            if !(e > s) {
                // More than MAX_MEDIA boxes overlap at s: up to the next box face.
                dropped = true;
                e = c
                    .iter()
                    .flat_map(|&(a, b, _)| [a, b])
                    .filter(|&t| t > s)
                    .fold(tmax, f32::min);
            }
            ids[..k].sort_unstable();
            let r = self.queries_sized(origin, dir, (s, e), at, (&ids[..k], scale), |q, i| {
                f(q, i, false)
            });
            if e >= tmax || !go_on(&r) {
                if dropped {
                    MEDIA_OVERFLOW.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                }
                return r;
            }
            s = e;
        }
    }

    /// Calls `f(i, (t0, t1))` for every medium i in `mask` whose box the ray
    /// `origin + t·dir` meets in [`tmin`, `tmax`] (over `[t0, t1]`): the media index's
    /// candidates on stages with many volumes, else every medium, each tested exactly.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn media_met(
        &self,
        origin: DVec3,
        dir: DVec3,
        tmin: f32,
        tmax: f32,
        mask: u64,
        mut f: impl FnMut(usize, (f64, f64)),
    ) {
        let mut take = |i: usize| {
            if in_mask(mask, i) {
                if let Some(span) = self.media[i].span(origin, dir, tmin as f64, tmax as f64) {
                    f(i, span);
                }
            }
        };
        match self.extras.media_index {
            None => (0..self.media.len()).for_each(&mut take),
            Some(index) => index.candidates(origin, dir, tmin, tmax, &mut take),
        }
    }

    /// [`Self::queries`] with arrays just large enough for the media `ids` (the unused
    /// tail repeats one of them), so a ray through two volumes of a large stage does
    /// not build sixty-four queries.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn queries_sized<T>(
        &self,
        origin: DVec3,
        dir: DVec3,
        (tmin, tmax): (f32, f32),
        at: At,
        (ids, scale): (&[usize], f32),
        f: impl FnOnce(&[Query], &[usize]) -> T,
    ) -> T {
        let range = (tmin, tmax);
        match ids.len() {
            0..=2 => self.queries::<2, T>(origin, dir, range, at, (ids, scale), f),
            3..=4 => self.queries::<4, T>(origin, dir, range, at, (ids, scale), f),
            5..=8 => self.queries::<8, T>(origin, dir, range, at, (ids, scale), f),
            9..=16 => self.queries::<16, T>(origin, dir, range, at, (ids, scale), f),
            _ => self.queries::<MAX_MEDIA, T>(origin, dir, range, at, (ids, scale), f),
        }
    }

    /// [`Self::with_queries`] for the media `ids` (at most `N`), with stack arrays of
    /// `N`.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn queries<const N: usize, T>(
        &self,
        origin: DVec3,
        dir: DVec3,
        (tmin, tmax): (f32, f32),
        (tracked, time): At,
        (ids, scale): (&[usize], f32),
        f: impl FnOnce(&[Query], &[usize]) -> T,
    ) -> T {
        let k = ids.len().min(N);
        let medium = |i: usize| &self.media[if i < k { ids[i] } else { 0 }];
        let rays: [IndexRay; N] =
            std::array::from_fn(|i| medium(i).index_ray_at(origin, dir, time));
        let sigmas: [Sigma; N] = std::array::from_fn(|i| tracked.sigma(medium(i)));
        let qs: [Query; N] = std::array::from_fn(|i| Query {
            medium: medium(i),
            sigma: &sigmas[i],
            ray: &rays[i],
            tmin,
            tmax,
            majorant_scale: scale,
        });
        f(&qs[..k], &ids[..k])
    }
}

/// One path segment's outcome: a free-path sampler's event in medium `.1`, or the
/// estimates of a ratio-select walk through medium `.1`.
enum Step {
    Tracked(FreePath, usize),
    Selected(SegmentEstimate, usize),
}

/// σs/σt of `medium` per channel, times the albedo field's multiplier `c` there (1
/// without one); 0 in a channel without extinction.
fn single_scattering_albedo(medium: &Medium, c: [f32; 3]) -> [f64; 3] {
    let (s, t) = (medium.sigma.s, medium.sigma.t);
    std::array::from_fn(|i| match t[i] > 0.0 {
        true => (s[i] / t[i] * c[i]) as f64,
        false => 0.0,
    })
}

/// Per-pixel slices of a film's extra accumulators, for [`Integrator::add_samples`].
#[derive(Default)]
struct PixelExtras<'f> {
    splits: Option<(&'f SplitMap, &'f mut [[f64; 3]])>,
    deep: Option<(DepthBins, &'f mut [[f64; 4]])>,
}

/// `len`-long rows of `buf` (`height` of them), or `height` empty rows when `len` is 0.
fn rows<T: Send>(buf: &mut [T], len: usize, height: usize) -> Vec<&mut [T]> {
    if len == 0 {
        return (0..height).map(|_| &mut [][..]).collect();
    }
    buf.chunks_mut(len).collect()
}

/// `throughput × l × w`, per channel, as the beauty adds it.
#[inline(always)]
fn scaled(throughput: [f32; 3], l: [f64; 3], w: f64) -> [f64; 3] {
    std::array::from_fn(|c| throughput[c] as f64 * l[c] * w)
}

/// Power heuristic (β = 2) weight of the strategy with density `a` against `b`.
#[inline]
pub fn power_heuristic(a: f64, b: f64) -> f64 {
    let (a2, b2) = (a * a, b * b);
    if a2 + b2 == 0.0 {
        0.0
    } else {
        a2 / (a2 + b2)
    }
}
