//! Free-path sampling and transmittance estimation: the null-collision family of
//! Kutz et al. 2017 (see `../shared/docs/tracking.md`).
//!
//! Every tracker walks the [`Segment`](crate::volume::majorant::Segment)s the majorant
//! structure hands out (the exponential is memoryless, so sampling restarts at every
//! cell boundary) and decides at each tentative collision between absorption,
//! scattering and a null collision. Trackers implement [`FreePathSampler`], shadow-ray
//! estimators [`TransmittanceEstimator`]; the integrator is generic over both and is
//! instantiated once per render, so the collision loops have no dynamic dispatch.

pub mod decomposition;
pub mod delta;
pub mod grey;
pub mod race;
pub mod ratio;
pub mod scheme;
pub mod spectral;

use crate::volume::majorant::Segment;
use crate::volume::medium::{IndexRay, Medium, Sigma, Tally};
use rand::Rng;
use std::ops::ControlFlow;

pub use crate::volume::medium::Spectrum;

/// The outcome of sampling a free path along a ray.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum FreePath {
    /// A real scattering collision at distance `t`.
    Scatter { t: f32 },
    /// A real absorption collision: the path ends. The throughput carries the
    /// absorption weight μa(λ)/(μ̄·Pa), so the integrator adds throughput × Le here.
    Absorb { t: f32 },
    /// The ray left the medium (or reached `tmax`) without a real collision.
    Escape,
}

/// What a tracker is handed for one free-path query.
pub struct Query<'a> {
    pub medium: &'a Medium,
    /// The cross-sections to track (the medium's, or one channel's for naive delta).
    pub sigma: &'a Sigma,
    pub ray: &'a IndexRay,
    pub tmin: f32,
    pub tmax: f32,
    /// Multiplies every majorant: 1 for the medium's bounds; below 1 to test trackers
    /// with non-bounding majorants.
    pub majorant_scale: f32,
}

/// Samples the first real collision, multiplying `throughput` by collision weights.
pub trait FreePathSampler: Sync {
    fn sample<R: Rng, C: Tally>(
        &self,
        q: &Query,
        throughput: &mut Spectrum,
        rng: &mut R,
        c: &mut C,
    ) -> FreePath;

    /// Samples the first real collision in the sum of several media overlapping along
    /// the ray (one query per medium, same ray and range; [`race`]), and returns the
    /// medium whose collision it was (0 on escape).
    fn sample_race<R: Rng, C: Tally>(
        &self,
        qs: &[Query],
        throughput: &mut Spectrum,
        rng: &mut R,
        c: &mut C,
    ) -> (FreePath, usize);
}

/// Estimates transmittance along a shadow ray.
pub trait TransmittanceEstimator: Sync {
    fn transmittance<R: Rng, C: Tally>(&self, q: &Query, rng: &mut R, c: &mut C) -> Spectrum;

    /// The transmittance of several media along one ray: the product of independent
    /// estimates of each medium's transmittance, which is unbiased for the product
    /// (the sum medium's transmittance). Stops once the product is 0.
    fn transmittance_race<R: Rng, C: Tally>(
        &self,
        qs: &[Query],
        rng: &mut R,
        c: &mut C,
    ) -> Spectrum {
        let mut tr = [1f32; 3];
        for q in qs {
            mul(&mut tr, self.transmittance(q, rng, c));
            if tr == [0.0; 3] {
                break;
            }
        }
        tr
    }
}

/// Walks the tentative collisions of the null-collision process whose majorant is
/// μ̄ = d_max·max σt (times `q.majorant_scale`) in each cell along the query's ray,
/// restarting the exponential at every cell boundary and skipping empty cells without
/// a lookup. `at(t, μ̄, rng, counters)` decides each collision; breaking returns its
/// value, running off the end returns `None`. (pbrt-v4's `SampleT_maj`, monomorphised.)
#[inline(always)]
pub fn walk_collisions<R: Rng, C: Tally, T>(
    q: &Query,
    rng: &mut R,
    c: &mut C,
    mut at: impl FnMut(f32, f32, &mut R, &mut C) -> ControlFlow<T>,
) -> Option<T> {
    let mut walk = q.medium.majorants.walk(q.ray.o, q.ray.d, q.tmin, q.tmax);
    let mut tau = OpticalDepth::sample(rng);
    while let Some(seg) = c.next_segment(&mut walk) {
        let mu_bar = majorant(q, &seg);
        if !(mu_bar > 0.0) {
            continue; // empty cell: skipped without a lookup
        }
        let mut t = seg.t0;
        loop {
            let Some(tc) = tau.collide(t, seg.t1, mu_bar) else {
                break;
            };
            t = tc;
            tau = OpticalDepth::sample(rng);
            if let ControlFlow::Break(v) = at(t, mu_bar, rng, c) {
                return Some(v);
            }
        }
    }
    None
}

/// The achromatic majorant μ̄ = d_max·max σt (times the query's majorant scale) of a
/// majorant segment.
#[inline(always)]
pub fn majorant(q: &Query, seg: &Segment) -> f32 {
    seg.dmax * q.sigma.t_max * q.majorant_scale
}

/// The optical depth left to the next tentative collision of a null-collision process
/// with a piecewise-constant majorant. Sampled once per collision (Exp(1)) and spent
/// across cell boundaries, which is the same process as restarting the exponential at
/// every boundary (memorylessness) but costs no random number and no logarithm per
/// cell crossed — at deep octree levels most cells are crossed without a collision.
#[derive(Clone, Copy, Debug)]
pub struct OpticalDepth(f32);

impl OpticalDepth {
    #[inline(always)]
    pub fn sample<R: Rng>(rng: &mut R) -> OpticalDepth {
        OpticalDepth(exp_step(rng, 1.0))
    }

    /// The collision distance from `t` at rate `mu` (infinite when `mu` is 0).
    #[inline(always)]
    pub fn time(self, t: f32, mu: f32) -> f32 {
        if mu > 0.0 {
            t + self.0 / mu
        } else {
            f32::INFINITY
        }
    }

    /// The optical depth left at `t1` of a collision pending at `tc ≥ t1` at rate `mu`
    /// (unchanged when `mu` is 0: nothing was spent).
    #[inline(always)]
    pub fn left(self, tc: f32, t1: f32, mu: f32) -> OpticalDepth {
        if mu > 0.0 {
            OpticalDepth(((tc - t1) * mu).max(0.0))
        } else {
            self
        }
    }

    /// With rate `mu > 0` from `t` to `t1`: the collision distance if it falls before
    /// `t1`, else `None` after spending the stretch's optical depth.
    #[inline(always)]
    pub fn collide(&mut self, t: f32, t1: f32, mu: f32) -> Option<f32> {
        let tc = t + self.0 / mu;
        if tc < t1 {
            Some(tc)
        } else {
            self.0 = (self.0 - (t1 - t) * mu).max(0.0);
            None
        }
    }
}

/// An exponential step with rate `mu` (`mu > 0`): −ln(1 − u)/μ. `1 − u` lies in (0, 1],
/// so the logarithm is finite.
#[inline(always)]
pub fn exp_step<R: Rng>(rng: &mut R, mu: f32) -> f32 {
    let u: f32 = rng.gen();
    -(1.0 - u).ln() / mu
}

#[inline(always)]
pub fn avg(s: Spectrum) -> f32 {
    (s[0] + s[1] + s[2]) * (1.0 / 3.0)
}

#[inline(always)]
pub fn max3(s: Spectrum) -> f32 {
    s[0].max(s[1]).max(s[2])
}

#[inline(always)]
pub fn mul(a: &mut Spectrum, w: Spectrum) {
    a[0] *= w[0];
    a[1] *= w[1];
    a[2] *= w[2];
}

/// The trackers a render can use (`--tracker`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum TrackerKind {
    /// One channel per path, analog delta tracking in it, 3× that channel (the paper's ND).
    NaiveDelta,
    /// Delta tracking, achromatic majorant, avg event probabilities.
    Delta,
    /// Delta tracking tolerating non-bounding majorants (signed weights).
    WeightedDelta,
    /// Analog decomposition tracking: control = the cell's minimum.
    Decomposition,
    /// Decomposition with the control above the minimum (`--control`), weighted residual.
    DecompositionWeighted,
    /// Spectral tracking with `--scheme`.
    Spectral,
    /// Spectral tracking of an achromatic control and a chromatic residual.
    SpectralDecomposition,
}

impl TrackerKind {
    pub fn name(self) -> &'static str {
        match self {
            TrackerKind::NaiveDelta => "naive-delta",
            TrackerKind::Delta => "delta",
            TrackerKind::WeightedDelta => "weighted-delta",
            TrackerKind::Decomposition => "decomposition",
            TrackerKind::DecompositionWeighted => "decomposition-weighted",
            TrackerKind::Spectral => "spectral",
            TrackerKind::SpectralDecomposition => "spectral-decomposition",
        }
    }

    /// Whether `--scheme` matters for this tracker.
    pub fn uses_scheme(self) -> bool {
        matches!(
            self,
            TrackerKind::Spectral | TrackerKind::SpectralDecomposition
        )
    }
}

/// Spectral probability schemes (`--scheme`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum SchemeKind {
    Max,
    Avg,
    HistMax,
    HistAvg,
}

impl SchemeKind {
    pub fn name(self) -> &'static str {
        match self {
            SchemeKind::Max => "max",
            SchemeKind::Avg => "avg",
            SchemeKind::HistMax => "hist-max",
            SchemeKind::HistAvg => "hist-avg",
        }
    }
}

/// Shadow-ray estimators (`--transmittance`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum TransmittanceKind {
    Ratio,
    ResidualRatio,
}

impl TransmittanceKind {
    pub fn name(self) -> &'static str {
        match self {
            TransmittanceKind::Ratio => "ratio",
            TransmittanceKind::ResidualRatio => "residual-ratio",
        }
    }
}

/// Everything that selects and parameterises the estimators of a render.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TrackerSettings {
    pub tracker: TrackerKind,
    pub scheme: SchemeKind,
    pub transmittance: TransmittanceKind,
    /// Control position for `decomposition-weighted`: 0 = cell minimum, 1 = maximum.
    pub control: f32,
    pub options: scheme::SchemeOptions,
    pub majorant_scale: f32,
    /// Time density lookups, majorant traversal and tracker queries (`--profile`).
    pub profile: bool,
}

impl TrackerSettings {
    /// Whether the trackers pay lookups for the residual `dmax − dmin` of a cell (the
    /// decomposition family, residual ratio tracking) rather than for `dmax`.
    pub fn pays_residual(&self) -> bool {
        matches!(
            self.tracker,
            TrackerKind::Decomposition
                | TrackerKind::DecompositionWeighted
                | TrackerKind::SpectralDecomposition
        ) || self.transmittance == TransmittanceKind::ResidualRatio
    }
}

impl Default for TrackerSettings {
    fn default() -> Self {
        TrackerSettings {
            tracker: TrackerKind::Delta,
            scheme: SchemeKind::HistAvg,
            transmittance: TransmittanceKind::Ratio,
            control: 0.05,
            options: scheme::SchemeOptions::default(),
            majorant_scale: 1.0,
            profile: false,
        }
    }
}

/// Calls `f` with the free-path sampler and transmittance estimator the settings
/// select, as concrete types: the one place where the choice is turned into a type.
pub fn dispatch<T>(s: &TrackerSettings, f: impl Dispatch<T>) -> T {
    let o = s.options;
    match s.transmittance {
        TransmittanceKind::Ratio => dispatch_free_path(s, o, ratio::Ratio, f),
        TransmittanceKind::ResidualRatio => dispatch_free_path(s, o, ratio::ResidualRatio, f),
    }
}

/// [`dispatch`] with the specialised trackers of the scene analysis: for a grey medium
/// (`grey`, checked against the cross-sections by the caller) delta tracking and
/// analog decomposition tracking, with ratio or residual ratio tracking for shadow
/// rays, run single-channel ([`grey`]); every other choice runs as [`dispatch`].
pub fn dispatch_specialised<T>(s: &TrackerSettings, grey: bool, f: impl Dispatch<T>) -> T {
    if !single_channel(s, grey) {
        return dispatch(s, f);
    }
    use grey::{GreyDecomposition, GreyDelta, GreyRatio, GreyResidualRatio};
    use TransmittanceKind::{Ratio, ResidualRatio};
    match (s.tracker == TrackerKind::Delta, s.transmittance) {
        (true, Ratio) => f.run(GreyDelta, GreyRatio),
        (true, ResidualRatio) => f.run(GreyDelta, GreyResidualRatio),
        (false, Ratio) => f.run(GreyDecomposition, GreyRatio),
        (false, ResidualRatio) => f.run(GreyDecomposition, GreyResidualRatio),
    }
}

/// Whether [`dispatch_specialised`] runs the single-channel trackers: on grey media,
/// for the trackers that are analog there and have a single-channel twin — delta
/// tracking, and decomposition tracking with the cell minimum as control and the avg
/// scheme (`decomposition`, or `spectral-decomposition --scheme avg`) without the
/// scheme options, which put weights other than 1 into the throughput.
pub fn single_channel(s: &TrackerSettings, grey: bool) -> bool {
    let analog = s.options == scheme::SchemeOptions::default();
    grey && match s.tracker {
        TrackerKind::Delta => true,
        TrackerKind::Decomposition => analog,
        TrackerKind::SpectralDecomposition => analog && s.scheme == SchemeKind::Avg,
        _ => false,
    }
}

fn dispatch_free_path<T, E: TransmittanceEstimator>(
    s: &TrackerSettings,
    o: scheme::SchemeOptions,
    e: E,
    f: impl Dispatch<T>,
) -> T {
    use decomposition::Decomposition;
    use scheme::{Avg, HistAvg, HistMax, Max};
    use spectral::Spectral;
    match s.tracker {
        TrackerKind::NaiveDelta | TrackerKind::Delta => f.run(delta::Delta, e),
        TrackerKind::WeightedDelta => f.run(Spectral::<Avg>::new(o), e),
        TrackerKind::Decomposition => f.run(Decomposition::<Avg>::new(0.0, o), e),
        TrackerKind::DecompositionWeighted => f.run(Decomposition::<Avg>::new(s.control, o), e),
        TrackerKind::Spectral => match s.scheme {
            SchemeKind::Max => f.run(Spectral::<Max>::new(o), e),
            SchemeKind::Avg => f.run(Spectral::<Avg>::new(o), e),
            SchemeKind::HistMax => f.run(Spectral::<HistMax>::new(o), e),
            SchemeKind::HistAvg => f.run(Spectral::<HistAvg>::new(o), e),
        },
        TrackerKind::SpectralDecomposition => match s.scheme {
            SchemeKind::Max => f.run(Decomposition::<Max>::new(0.0, o), e),
            SchemeKind::Avg => f.run(Decomposition::<Avg>::new(0.0, o), e),
            SchemeKind::HistMax => f.run(Decomposition::<HistMax>::new(0.0, o), e),
            SchemeKind::HistAvg => f.run(Decomposition::<HistAvg>::new(0.0, o), e),
        },
    }
}

/// A computation generic over the estimators (a closure cannot be generic).
pub trait Dispatch<T> {
    fn run<F: FreePathSampler, E: TransmittanceEstimator>(
        self,
        free_path: F,
        transmittance: E,
    ) -> T;
}
