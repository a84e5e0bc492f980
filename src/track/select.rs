//! Tracker selection: the [`TrackerKind`], [`SchemeKind`] and [`TransmittanceKind`] a
//! render asks for, the [`TrackerSettings`] that parameterise them, and [`dispatch`],
//! the one place where that choice becomes concrete estimator types (static dispatch:
//! the integrator is instantiated once per render, the collision loops see no enum).

use super::free_path::{FreePathSampler, TransmittanceEstimator};
use super::{
    decomposition, delta, grey, ratio, scheme, spectral, spectral_mis, telescoping, track_length,
};

/// A closed set of named options (a tracker, a scheme, a shadow-ray estimator, a clock):
/// the names the CLI, the schema's tokens and the stats share, with a line of help each.
pub trait Choice: Copy + PartialEq + 'static {
    /// Every option, in the order help lists them.
    const ALL: &'static [Self];
    /// The option's name (a CLI value, a schema token, a stats string).
    fn name(self) -> &'static str;
    /// One line saying what the option does.
    fn help(self) -> &'static str;

    /// The option called `name`, if any.
    fn from_name(name: &str) -> Option<Self> {
        Self::ALL.iter().copied().find(|k| k.name() == name)
    }

    /// Every name, comma-separated (for messages listing what is known).
    fn names() -> String {
        Self::ALL
            .iter()
            .map(|k| k.name())
            .collect::<Vec<_>>()
            .join(", ")
    }
}

/// The trackers a render can use (`--tracker`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
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
    /// Hero-channel free paths combined over the channels by one-sample MIS.
    SpectralMis,
    /// Ratio tracking over each path segment: transmittance and the scattering
    /// collision from one walk.
    RatioSelect,
}

impl Choice for TrackerKind {
    const ALL: &'static [Self] = &[
        TrackerKind::NaiveDelta,
        TrackerKind::Delta,
        TrackerKind::WeightedDelta,
        TrackerKind::Decomposition,
        TrackerKind::DecompositionWeighted,
        TrackerKind::Spectral,
        TrackerKind::SpectralDecomposition,
        TrackerKind::SpectralMis,
        TrackerKind::RatioSelect,
    ];

    fn help(self) -> &'static str {
        match self {
            TrackerKind::NaiveDelta => "One channel per path, analog delta tracking in it, 3× that channel (the paper's ND)",
            TrackerKind::Delta => "Delta tracking, achromatic majorant, avg event probabilities",
            TrackerKind::WeightedDelta => "Delta tracking tolerating non-bounding majorants (signed weights)",
            TrackerKind::Decomposition => "Analog decomposition tracking: control = the cell's minimum",
            TrackerKind::DecompositionWeighted => "Decomposition with the control above the minimum (`--control`), weighted residual",
            TrackerKind::Spectral => "Spectral tracking with `--scheme`",
            TrackerKind::SpectralDecomposition => "Spectral tracking of an achromatic control and a chromatic residual",
            TrackerKind::SpectralMis => "Hero-channel delta tracking, channels combined by one-sample MIS (balance heuristic)",
            TrackerKind::RatioSelect => "Ratio tracking along each path segment: transmittance to its end and one collision, chosen by weight, to scatter at",
        }
    }

    fn name(self) -> &'static str {
        TrackerKind::name(self)
    }
}

impl TrackerKind {
    /// The option's name (a CLI value, a schema token, a stats string).
    pub fn name(self) -> &'static str {
        match self {
            TrackerKind::NaiveDelta => "naive-delta",
            TrackerKind::Delta => "delta",
            TrackerKind::WeightedDelta => "weighted-delta",
            TrackerKind::Decomposition => "decomposition",
            TrackerKind::DecompositionWeighted => "decomposition-weighted",
            TrackerKind::Spectral => "spectral",
            TrackerKind::SpectralDecomposition => "spectral-decomposition",
            TrackerKind::SpectralMis => "spectral-mis",
            TrackerKind::RatioSelect => "ratio-select",
        }
    }
}

impl TrackerKind {
    /// Whether `--scheme` matters for this tracker.
    pub fn uses_scheme(self) -> bool {
        matches!(
            self,
            TrackerKind::Spectral | TrackerKind::SpectralDecomposition
        )
    }
}

/// Spectral probability schemes (`--scheme`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum SchemeKind {
    Max,
    Avg,
    HistMax,
    HistAvg,
}

impl Choice for SchemeKind {
    const ALL: &'static [Self] = &[
        SchemeKind::Max,
        SchemeKind::Avg,
        SchemeKind::HistMax,
        SchemeKind::HistAvg,
    ];

    fn help(self) -> &'static str {
        match self {
            SchemeKind::Max => "Event probabilities from the largest channel",
            SchemeKind::Avg => "Event probabilities from the channel average",
            SchemeKind::HistMax => {
                "History-aware: the largest channel of throughput × coefficients"
            }
            SchemeKind::HistAvg => "History-aware: the average of throughput × coefficients",
        }
    }

    fn name(self) -> &'static str {
        SchemeKind::name(self)
    }
}

impl SchemeKind {
    /// The option's name (a CLI value, a schema token, a stats string).
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
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum TransmittanceKind {
    Ratio,
    ResidualRatio,
    Telescoping,
    Tracking,
}

impl Choice for TransmittanceKind {
    const ALL: &'static [Self] = &[
        TransmittanceKind::Ratio,
        TransmittanceKind::ResidualRatio,
        TransmittanceKind::Telescoping,
        TransmittanceKind::Tracking,
    ];

    fn help(self) -> &'static str {
        match self {
            TransmittanceKind::Ratio => "Ratio tracking: the product of null-collision probabilities",
            TransmittanceKind::ResidualRatio => "Residual ratio tracking: a control's closed form times ratio tracking of the residual",
            TransmittanceKind::Telescoping => "Telescoping ray marching (Misso et al. 2022, as Cycles 5's shadow rays): a jittered march of each cell's residual, unbiased by one randomly drawn finer-march correction",
            TransmittanceKind::Tracking => "The tracker's own free-path sampler: its throughput if the shadow ray escapes, 0 at a real collision (the track-length estimator)",
        }
    }

    fn name(self) -> &'static str {
        TransmittanceKind::name(self)
    }
}

impl TransmittanceKind {
    /// The option's name (a CLI value, a schema token, a stats string).
    pub fn name(self) -> &'static str {
        match self {
            TransmittanceKind::Ratio => "ratio",
            TransmittanceKind::ResidualRatio => "residual-ratio",
            TransmittanceKind::Telescoping => "telescoping",
            TransmittanceKind::Tracking => "tracking",
        }
    }
}

/// Where scattering points near local lights come from (`--light-sampling`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum LightSampling {
    /// `equiangular-mis` towards every local light where every medium is homogeneous
    /// (fog boxes, world fog), towards spots only in heterogeneous media: where it
    /// was measured to pay; `collisions` elsewhere (docs/trackers.md).
    Auto,
    /// The trackers' collisions, plus one point per path segment sampled
    /// equiangularly towards a local light, combined by MIS.
    EquiangularMis,
    /// The trackers' collisions alone.
    Collisions,
}

impl Choice for LightSampling {
    const ALL: &'static [Self] = &[
        LightSampling::Auto,
        LightSampling::EquiangularMis,
        LightSampling::Collisions,
    ];

    fn help(self) -> &'static str {
        match self {
            LightSampling::EquiangularMis => "Collisions plus one scattering point per path segment sampled equiangularly towards a point, spot, sphere, rect, disk or cylinder light, combined by MIS (Kulla and Fajardo 2012)",
            LightSampling::Collisions => "The trackers' collisions alone",
            LightSampling::Auto => "equiangular-mis towards every local light where every medium is homogeneous (fog boxes, world fog), towards spot lights only where a medium is a grid; collisions for the rest (the default)",
        }
    }

    fn name(self) -> &'static str {
        LightSampling::name(self)
    }
}

impl LightSampling {
    /// The option's name (a CLI value, a schema token, a stats string).
    pub fn name(self) -> &'static str {
        match self {
            LightSampling::Auto => "auto",
            LightSampling::EquiangularMis => "equiangular-mis",
            LightSampling::Collisions => "collisions",
        }
    }
}

/// Where a path goes after a scattering vertex (`--scatter-guiding`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum ScatterGuiding {
    /// `lights` towards the point, sphere and spot lights of a stage with no sun or
    /// dome (measured to pay on every such issue-44 stage; a large rect beside a thin
    /// cloud lost, and so did a sun-lit cloud with a spot: docs/trackers.md), `phase`
    /// on the rest.
    Auto,
    /// Half the continuations drawn from lobes towards the local lights, combined
    /// with the phase function as one mixture ([`crate::render::guiding`]).
    Lights,
    /// The phase function alone.
    Phase,
}

impl Choice for ScatterGuiding {
    const ALL: &'static [Self] = &[
        ScatterGuiding::Auto,
        ScatterGuiding::Lights,
        ScatterGuiding::Phase,
    ];

    fn help(self) -> &'static str {
        match self {
            ScatterGuiding::Auto => "lights towards the point, sphere and spot lights of a stage lit by no sun or dome; phase on the rest (the default)",
            ScatterGuiding::Lights => "Half the scattered directions drawn from lobes towards the local lights (von Mises-Fisher, chosen by power over squared distance), weighted against the phase function as one mixture",
            ScatterGuiding::Phase => "Scattered directions from the phase function alone",
        }
    }

    fn name(self) -> &'static str {
        ScatterGuiding::name(self)
    }
}

impl ScatterGuiding {
    /// The option's name (a CLI value, a stats string).
    pub fn name(self) -> &'static str {
        match self {
            ScatterGuiding::Auto => "auto",
            ScatterGuiding::Lights => "lights",
            ScatterGuiding::Phase => "phase",
        }
    }
}

impl TrackerKind {
    /// Whether the tracker stays unbiased where the density exceeds the majorant
    /// (signed weights; ratio-select's fallback where volumes overlap too, off the
    /// single-channel path, which the session leaves then): tested in
    /// tests/agreement.rs with every majorant halved.
    pub fn tolerates_estimated_majorants(self) -> bool {
        matches!(
            self,
            TrackerKind::WeightedDelta | TrackerKind::SpectralMis | TrackerKind::RatioSelect
        )
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
    /// Scattering points towards local lights (only stages with local lights differ;
    /// default `auto`).
    pub light_sampling: LightSampling,
    /// Where paths go after scattering (only stages with local lights differ;
    /// default `auto`).
    pub scatter_guiding: ScatterGuiding,
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
        ) || matches!(
            self.transmittance,
            TransmittanceKind::ResidualRatio | TransmittanceKind::Telescoping
        )
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
            light_sampling: LightSampling::Auto,
            scatter_guiding: ScatterGuiding::Auto,
        }
    }
}

/// Calls `f` with the free-path sampler and transmittance estimator the settings
/// select, as concrete types: the one place where the choice is turned into a type.
pub fn dispatch<T>(s: &TrackerSettings, f: impl Dispatch<T>) -> T {
    let o = s.options;
    // ratio-select's shadow rays read one voxel per collision, as its walks do.
    if s.tracker == TrackerKind::RatioSelect && s.transmittance == TransmittanceKind::Ratio {
        return dispatch_free_path(s, o, ratio::StochasticRatio, f);
    }
    match s.transmittance {
        TransmittanceKind::Ratio => dispatch_free_path(s, o, ratio::Ratio, f),
        TransmittanceKind::ResidualRatio => dispatch_free_path(s, o, ratio::ResidualRatio, f),
        TransmittanceKind::Telescoping => dispatch_free_path(s, o, telescoping::Telescoping, f),
        TransmittanceKind::Tracking => dispatch_free_path(s, o, ratio::Ratio, TrackShadows(f)),
    }
}

/// Hands `f` the free-path sampler it is given twice: as the free-path sampler and, in
/// [`Tracking`](track_length::Tracking), as the shadow rays' estimator (the placeholder
/// estimator is dropped).
struct TrackShadows<D>(D);

impl<T, D: Dispatch<T>> Dispatch<T> for TrackShadows<D> {
    fn run<F: FreePathSampler, E: TransmittanceEstimator>(self, free_path: F, _: E) -> T {
        self.0.run(free_path, track_length::Tracking(free_path))
    }
}

/// [`dispatch`] with the specialised trackers of the scene analysis: for a grey medium
/// (`grey`, checked against the cross-sections by the caller) delta tracking and
/// analog decomposition tracking, with ratio or residual ratio tracking for shadow
/// rays, run single-channel ([`grey`]); every other choice runs as [`dispatch`].
pub fn dispatch_specialised<T>(s: &TrackerSettings, grey: bool, f: impl Dispatch<T>) -> T {
    if !grey_tracking(s, grey) {
        return dispatch(s, f);
    }
    use grey::{GreyDecomposition, GreyDelta, GreyRatio, GreyResidualRatio, GreyStochasticRatio};
    use telescoping::GreyTelescoping;
    use track_length::Tracking;
    use TransmittanceKind::{Ratio, ResidualRatio, Telescoping};
    // ratio-select: the integrator walks segments single-channel; its fallback free
    // path is analog decomposition, its shadow rays read one voxel per collision.
    if s.tracker == TrackerKind::RatioSelect {
        return match s.transmittance {
            Ratio => f.run(GreyDecomposition, GreyStochasticRatio),
            ResidualRatio => f.run(GreyDecomposition, GreyResidualRatio),
            Telescoping => f.run(GreyDecomposition, GreyTelescoping),
            TransmittanceKind::Tracking => f.run(GreyDecomposition, Tracking(GreyDecomposition)),
        };
    }
    match (s.tracker == TrackerKind::Delta, s.transmittance) {
        (true, Ratio) => f.run(GreyDelta, GreyRatio),
        (true, ResidualRatio) => f.run(GreyDelta, GreyResidualRatio),
        (true, Telescoping) => f.run(GreyDelta, GreyTelescoping),
        (true, TransmittanceKind::Tracking) => f.run(GreyDelta, Tracking(GreyDelta)),
        (false, Ratio) => f.run(GreyDecomposition, GreyRatio),
        (false, ResidualRatio) => f.run(GreyDecomposition, GreyResidualRatio),
        (false, Telescoping) => f.run(GreyDecomposition, GreyTelescoping),
        (false, TransmittanceKind::Tracking) => {
            f.run(GreyDecomposition, Tracking(GreyDecomposition))
        }
    }
}

/// Whether [`dispatch_specialised`] runs the single-channel trackers: on grey media,
/// for the trackers that are analog there and have a single-channel twin — delta
/// tracking, and decomposition tracking with the cell minimum as control and the avg
/// scheme (`decomposition`, or `spectral-decomposition --scheme avg`) without the
/// scheme options, which put weights other than 1 into the throughput; and
/// `ratio-select`, whose walk keeps one scalar T̂ (its fallback free path is then
/// analog decomposition, hence also without the options).
pub fn grey_tracking(s: &TrackerSettings, grey: bool) -> bool {
    let analog = s.options == scheme::SchemeOptions::default();
    grey && match s.tracker {
        TrackerKind::Delta => true,
        TrackerKind::RatioSelect => analog,
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
        TrackerKind::SpectralMis => f.run(spectral_mis::SpectralMis::new(o), e),
        // The integrator walks each segment through one volume itself
        // (track::collision_select); segments where volumes overlap, and the camera
        // rays of deep renders, take spectral decomposition tracking with hist-avg.
        TrackerKind::RatioSelect => f.run(Decomposition::<HistAvg>::new(0.0, o), e),
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
