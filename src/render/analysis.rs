//! The scene analysis: what a render needs, worked out once after loading, so the
//! render can skip the rest (issue "skip what a scene does not need"). It records facts
//! about the medium, the lights and the camera, and `--tracker auto` picks the tracker
//! and scheme from them.

use crate::render::camera::CameraRays;
use crate::render::lights::Lights;
use crate::track::select::{SchemeKind, TrackerKind, TrackerSettings, TransmittanceKind};
use crate::volume::majorant::MajorantSpec;
use crate::volume::medium::Medium;
use serde::Serialize;

/// Facts about a render, for `nimbus info`, the stats JSON and `--tracker auto`.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Analysis {
    /// The stage's volumes, one medium each (overlapping ones add; the facts below
    /// hold for all of them: `grey` means every medium is grey, `emissive` that some
    /// medium emits).
    pub volumes: usize,
    /// σa and σs equal in every channel: one channel's tracking is exact.
    pub grey: bool,
    /// The medium has an emission source (temperature or emission field): emission
    /// is collected at absorption events, so they must stay (no
    /// `no_absorption_events`).
    pub emissive: bool,
    /// σs/σt is the same everywhere (density-driven media with constant coefficients
    /// and no albedo grid): collisions need no albedo lookup.
    pub constant_albedo: bool,
    /// The albedo field (`nimbus:albedoField`) scatter events look up, if any.
    pub albedo_field: Option<String>,
    /// Every voxel of the active bounding box has the same, non-zero value.
    pub homogeneous: bool,
    /// Fraction of majorant leaf cells with maximum 0, crossed without lookups.
    pub empty_cell_fraction: f64,
    /// Henyey–Greenstein g = 0.
    pub isotropic: bool,
    /// Largest single-scattering albedo σs/σt over the channels (before an albedo
    /// grid's multiplier, which is at most 1).
    pub max_albedo: f64,
    /// Lights with non-zero emission, of all lights (suns, sphere, rect, dome).
    pub lights_emitting: usize,
    pub lights_total: usize,
    /// Some of a 16×16 grid of camera rays crosses a non-empty majorant cell.
    pub volume_visible: bool,
    /// The costliest density shader graph of the stage, if any (issue 47).
    pub density_graph: Option<GraphCost>,
    /// Majorant cells whose density graph has no usable bound, so that their majorant
    /// is an estimate (issue 47): `auto` then keeps to trackers with signed weights.
    pub estimated_majorants: Option<EstimatedMajorants>,
}

/// Where majorants are estimates, not bounds ([`crate::volume::graph_density`]).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct EstimatedMajorants {
    /// The first such medium.
    pub prim_path: String,
    /// Its density graph's shader.
    pub source: String,
    /// Leaf cells with an estimated majorant, and all leaf cells, over every medium.
    pub cells: usize,
    pub of: usize,
}

impl EstimatedMajorants {
    fn of(media: &[Medium]) -> Option<EstimatedMajorants> {
        let first = media.iter().find(|m| m.majorants.estimated_cells() > 0)?;
        Some(EstimatedMajorants {
            prim_path: first.prim_path.clone(),
            source: first
                .shader
                .as_ref()
                .map_or(String::new(), |s| s.source.clone()),
            cells: media.iter().map(|m| m.majorants.estimated_cells()).sum(),
            of: media.iter().map(|m| m.majorants.cell_count()).sum(),
        })
    }

    /// What `auto`'s reason says of the estimates (and `info` with it).
    pub fn reason(&self) -> String {
        format!(
            "the density graph of {} ({}) has no usable bound in {} of {} majorant cells (a division by a range holding 0, a negative power of a range reaching 0, an Exponent past float range): their majorants are estimates ({}x the largest of {} lookups in the cell), not bounds, so only trackers with signed weights stay unbiased where the density exceeds them (majorant_violations counts those collisions); grey media run on the general path",
            self.prim_path,
            self.source,
            self.cells,
            self.of,
            crate::volume::graph_density::ESTIMATE_MARGIN,
            crate::volume::graph_density::ESTIMATE_POINTS.pow(3) + 8,
        )
    }
}

/// What a density shader graph costs the trackers: measured time per lookup (reported
/// only: a choice made from a timing would differ between machines) and the counted
/// share of the majorants its minorants carry (what decomposition tracking can take
/// from the control without a lookup).
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct GraphCost {
    pub prim_path: String,
    pub instructions: usize,
    /// Median of 5 timings of 1,024 lookups at fixed points of the region.
    pub ns_per_lookup: f64,
    /// Σ minorant / Σ majorant over the leaf cells with a non-zero majorant.
    pub control_share: f64,
}

impl GraphCost {
    fn of(m: &Medium) -> Option<GraphCost> {
        let shader = m.shader.as_ref()?;
        let (lo, hi) = m.majorants.index_region()?;
        // Fixed points (a Weyl sequence): the same lookups on every run.
        let points: Vec<glam::Vec3> = (0..1024)
            .map(|k| {
                let f = |a: f32| (k as f32 * a).fract();
                lo + (hi - lo) * glam::Vec3::new(f(0.618_034), f(0.754_878), f(0.569_840))
            })
            .collect();
        let mut c = crate::volume::counters::Counters::default();
        let mut times: Vec<f64> = (0..5)
            .map(|_| {
                let t = std::time::Instant::now();
                let s: f32 = points.iter().map(|&p| m.density(p, &mut c)).sum();
                std::hint::black_box(s);
                t.elapsed().as_secs_f64() * 1e9 / points.len() as f64
            })
            .collect();
        times.sort_by(f64::total_cmp);
        Some(GraphCost {
            prim_path: m.prim_path.clone(),
            instructions: shader.program.len(),
            ns_per_lookup: times[2],
            control_share: Self::control_share(m),
        })
    }

    /// Σ minorant / Σ majorant over `m`'s leaf majorant cells with a non-zero majorant.
    fn control_share(m: &Medium) -> f64 {
        let dims = m.majorants.dims();
        let (mut dmin, mut dmax) = (0.0f64, 0.0f64);
        for x in 0..dims[0] {
            for y in 0..dims[1] {
                for z in 0..dims[2] {
                    if let Some((a, b)) = m.majorants.leaf_bounds([x, y, z]) {
                        if b > 0.0 {
                            dmin += a as f64;
                            dmax += b as f64;
                        }
                    }
                }
            }
        }
        if dmax > 0.0 {
            dmin / dmax
        } else {
            0.0
        }
    }
}

impl Analysis {
    /// Counts what depends on the majorant cells again over `media`'s: `auto` builds
    /// the structure the render walks after the analysis, and until then a medium holds
    /// a coarse placeholder. Its minorants are near 0 (the smoke of issue 47's scene
    /// (b): a control share of 0 % over the placeholder, 38 % over the octree it renders
    /// with); the estimated cells are counted again with it (the octree is built only
    /// where the placeholder has none, but a finer cell's range analysis may differ).
    pub fn recount_majorants(&mut self, media: &[Medium]) {
        self.estimated_majorants = EstimatedMajorants::of(media);
        if let Some(g) = &mut self.density_graph {
            if let Some(m) = media.iter().find(|m| m.prim_path == g.prim_path) {
                g.control_share = GraphCost::control_share(m);
            }
        }
    }

    /// The analysis of a stage with several volumes (one medium each).
    pub fn of_media(
        media: &[Medium],
        lights: &Lights,
        camera: &CameraRays,
        size: (u32, u32),
    ) -> Self {
        let albedo = |m: &Medium| {
            let s = &m.sigma;
            (0..3)
                .map(|c| {
                    if s.t[c] > 0.0 {
                        (s.s[c] / s.t[c]) as f64
                    } else {
                        0.0
                    }
                })
                .fold(0.0, f64::max)
        };
        let cells: usize = media.iter().map(|m| m.majorants.cell_count()).sum();
        let empty: f64 = media
            .iter()
            .map(|m| m.majorants.empty_leaf_fraction() * m.majorants.cell_count() as f64)
            .sum();
        let (emitting, total) = count_lights(lights);
        Analysis {
            volumes: media.len(),
            grey: media.iter().all(|m| m.sigma.is_grey()),
            emissive: media.iter().any(|m| m.emission.is_some()),
            constant_albedo: media.iter().all(|m| m.albedo.is_none()),
            albedo_field: media
                .iter()
                .find_map(|m| m.albedo.as_ref().map(|a| a.field.clone())),
            homogeneous: !media.is_empty() && media.iter().all(homogeneous),
            empty_cell_fraction: if cells > 0 { empty / cells as f64 } else { 0.0 },
            isotropic: media.iter().all(|m| m.g == 0.0),
            max_albedo: media.iter().map(albedo).fold(0.0, f64::max),
            lights_emitting: emitting,
            lights_total: total,
            volume_visible: media.iter().any(|m| visible(m, camera, size)),
            density_graph: media
                .iter()
                .filter_map(GraphCost::of)
                .max_by(|a, b| a.ns_per_lookup.total_cmp(&b.ns_per_lookup)),
            estimated_majorants: EstimatedMajorants::of(media),
        }
    }

    /// `--tracker auto`: the tracker, scheme and options for this scene, and why.
    /// Each rule is measured with `nimbus bench error`; the figures are in
    /// `docs/trackers.md` ("Scene analysis and `--tracker auto`") and the CSVs in `benches/auto/`:
    /// - heterogeneous media: `ratio-select` ([`crate::track::collision_select`]):
    ///   1.05–1.96× the efficiency of `delta` on the grey stages, 1.09–2.47× that of
    ///   spectral decomposition on the chromatic ones, 3.5–3.6× on the emissive fire and
    ///   a chromatic copy of it (`docs/performance.md`, "One walk for both terms"). On
    ///   grey media it runs single-channel ([`CodePaths::specialise`]) with analog
    ///   decomposition as its fallback where volumes overlap; on chromatic media the
    ///   fallback is spectral decomposition with history-aware avg, without absorption
    ///   events unless the medium emits (they collect its emission);
    /// - homogeneous media with no majorant structure named: one global majorant
    ///   ([`Analysis::majorants`]) and the tracker of their colour below;
    /// - homogeneous media in a named structure of cells: the decomposition family with
    ///   residual ratio tracking — inside the volume a majorant cell's minimum equals
    ///   its maximum, so the control carries the whole density: free paths and
    ///   transmittance come in closed form and only the rim cells, where the field
    ///   falls off, need lookups; for grey media analog `decomposition`, which runs
    ///   single-channel;
    /// - other (homogeneous, global majorant) grey media: `delta` — every spectral
    ///   scheme reduces to it, and it ties spectral tracking without absorption events
    ///   while beating decomposition with the default flat majorant grid
    ///   (`benches/auto/cloud.csv`); it runs single-channel;
    /// - other chromatic media: `spectral-decomposition` with history-aware avg
    ///   (throughput bounded by Theorem 2 at any albedo) and no absorption events (the
    ///   absorption lives in the weights; legal only without emission), the best at equal
    ///   time on both chromatic benchmarks (`benches/error/chromatic.csv`,
    ///   `benches/error/smoke_chromatic.csv`).
    ///
    /// `given`: what the user set (a named scheme or shadow-ray estimator is kept).
    pub fn choose(&self, base: TrackerSettings, given: Given) -> (TrackerSettings, String) {
        let mut t = base;
        if let Some(e) = &self.estimated_majorants {
            // Analog trackers clamp a negative null probability where the density
            // exceeds the majorant, which biases the image. ratio-select's walk and
            // shadow rays take signed weights (tests/agreement.rs, majorant × 0.5), and
            // so does its spectral-decomposition fallback; the session runs grey media
            // on the general path here ([`Analysis::specialise`]), whose fallback is
            // that one too, not the analog single-channel decomposition.
            let mut reason = self.ratio_select(&mut t, given).to_string();
            if !given.transmittance {
                t.transmittance = TransmittanceKind::Ratio;
            }
            reason.push_str("; ");
            reason.push_str(&e.reason());
            return (t, reason);
        }
        if !self.homogeneous {
            let mut reason = self.ratio_select(&mut t, given).to_string();
            if let Some(g) = &self.density_graph {
                // Measured on benches/shader_graph (docs/shaders.md): with minorants
                // near 0 (4 % on the fractal box), decomposition took 0.95-1.06x
                // delta's lookups and no less time; with a floor (60-67 %) 0.41x the
                // lookups but 2.7-3.7x ratio-select's error in equal time. So the
                // graph's cost does not change the choice.
                reason.push_str(&format!(
                    "; density graph of {} ({} instructions, {:.0} ns per lookup measured at load): its minorants carry {:.0}% of its majorants, the most decomposition could take from the control without a lookup, so the graph's cost does not change the choice",
                    g.prim_path,
                    g.instructions,
                    g.ns_per_lookup,
                    100.0 * g.control_share
                ));
                if !given.majorants && self.graph_octree() {
                    reason.push_str(&format!("; {GRAPH_MAJORANT_REASON}"));
                }
            }
            return (t, reason);
        }
        // Homogeneous from here on.
        let mut reason = Vec::new();
        // The closed form needs majorant cells inside the volume: with the global
        // majorant `auto` builds when no structure is named (see `majorants`), the one
        // cell's minimum is the rim's 0 and decomposition would be delta tracking.
        let closed_form = given.majorants;
        if !closed_form {
            reason.push(GLOBAL_MAJORANT_REASON);
        }
        if self.grey && !closed_form {
            t.tracker = TrackerKind::Delta;
            reason.push("grey medium: delta tracking is exact with unit weights (spectral schemes reduce to it), run single-channel");
            return (t, reason.join("; "));
        }
        if closed_form {
            if !given.transmittance {
                t.transmittance = TransmittanceKind::ResidualRatio;
            }
            reason.push("homogeneous medium: the cells' minimum is their maximum, so the decomposition control carries the density and free paths and transmittance come in closed form (lookups only where the field falls off at the rim)");
        }
        if self.grey {
            t.tracker = TrackerKind::Decomposition;
            reason.push("grey: analog decomposition tracking, run single-channel");
            return (t, reason.join("; "));
        }
        t.tracker = TrackerKind::SpectralDecomposition;
        if !given.scheme {
            t.scheme = SchemeKind::HistAvg;
        }
        reason.push(
            "chromatic medium: spectral decomposition tracking with history-aware avg (bounded throughput)",
        );
        if !self.emissive {
            t.options.no_absorption_events = true;
            reason.push("no emission, so absorption lives in the weights (no absorption events)");
        }
        (t, reason.join("; "))
    }

    /// [`Self::choose`]'s rule for heterogeneous media: `ratio-select` in `t`, with its
    /// fallback's scheme and options; returns why.
    fn ratio_select(&self, t: &mut TrackerSettings, given: Given) -> &'static str {
        t.tracker = TrackerKind::RatioSelect;
        if self.grey {
            return "grey, heterogeneous medium: ratio-select (each segment's transmittance and scattering collision from one ratio-tracking walk: no coin flip between the background and the cloud), run single-channel; where volumes overlap, analog decomposition tracking";
        }
        if !given.scheme {
            t.scheme = SchemeKind::HistAvg;
        }
        if self.emissive {
            return "chromatic, heterogeneous, emissive medium: ratio-select (each segment's transmittance, scattering collision and emission point from one ratio-tracking walk); where volumes overlap, spectral decomposition tracking with history-aware avg (absorption events collect the emission)";
        }
        t.options.no_absorption_events = true;
        "chromatic, non-emissive, heterogeneous medium: ratio-select (each segment's transmittance and scattering collision from one ratio-tracking walk: no coin flip between the background and the cloud); where volumes overlap, spectral decomposition tracking with history-aware avg and no absorption events"
    }

    /// Whether grey media may run the single-channel trackers: not where a majorant is
    /// an estimate, since the single-channel decomposition (ratio-select's fallback
    /// where volumes overlap) is analog and would clamp where the density exceeds it.
    pub fn specialise(&self) -> bool {
        self.estimated_majorants.is_none()
    }

    /// The majorant structure `auto` builds in place of the one the media were loaded
    /// with, `None` to keep that: for homogeneous media, when the user named no
    /// structure (`given.majorants`), one global majorant. It is tight everywhere but
    /// at the rim, so every tentative collision inside is real and no cell is crossed;
    /// measured against the default flat grid of 8-voxel cells (with the closed-form
    /// decomposition there) on cubes of optical thickness 0.6, 6 and 60 across
    /// (`docs/trackers.md`, "Scene analysis and `--tracker auto`").
    ///
    /// And where a density is a shader graph (and every cell of it bounded), an octree
    /// of depth [`GRAPH_OCTREE_DEPTH`], pruned at [`GRAPH_OCTREE_PRUNE`] unless a cost
    /// is named: a graph's lookup costs several brick reads (a Perlin octave alone
    /// about as much as one), so finer cells pay for their crossings sooner than on a
    /// grid. Measured with equal-sample relMSE and time on issue 47's scenes (a) and
    /// (b) (`docs/shaders.md`, "Majorants for graphs"). Not where some majorants are
    /// estimates: each estimated leaf costs 133 lookups at load.
    pub fn majorants(&self, given: Given) -> Option<MajorantSpec> {
        if given.majorants {
            return None;
        }
        if self.homogeneous {
            return Some(MajorantSpec::Uniform { cell_voxels: 0 });
        }
        self.graph_octree().then_some(MajorantSpec::Octree {
            depth: GRAPH_OCTREE_DEPTH,
        })
    }

    /// The octree pruning cost `auto` gives the structure [`majorants`](Self::majorants)
    /// builds, `None` to keep the session's: [`GRAPH_OCTREE_PRUNE`] for a graph's octree.
    pub fn majorant_prune(&self, given: Given) -> Option<f32> {
        (!given.majorants && !self.homogeneous && self.graph_octree()).then_some(GRAPH_OCTREE_PRUNE)
    }

    /// Whether [`majorants`](Self::majorants) builds the graph octree (no structure
    /// named aside).
    fn graph_octree(&self) -> bool {
        self.density_graph.is_some() && self.estimated_majorants.is_none()
    }
}

/// The octree pruning cost `auto` gives a density graph's octree when none is named
/// (`--octree-prune`): a cell crossing priced at a fifth of a lookup, since a graph's
/// lookup costs about five brick reads (200-320 ns against 30-70 on issue 47's scenes).
/// Measured against the default cost of 1 in docs/shaders.md ("Majorants for graphs").
pub const GRAPH_OCTREE_PRUNE: f32 = 0.2;

/// The octree depth `auto` builds for a density graph: leaves of one voxel up to 128
/// voxels across (a fog box's 64), at most 128³ leaves on larger grids, whose range
/// analysis at load stays under a few seconds.
pub const GRAPH_OCTREE_DEPTH: u32 = 8;

/// Why [`Analysis::majorants`] builds a global majorant.
const GLOBAL_MAJORANT_REASON: &str = "homogeneous medium and no majorant structure named: one global majorant, tight inside the volume (every tentative collision there is real, no cell is crossed)";

/// Why [`Analysis::majorants`] builds an octree for a density graph.
const GRAPH_MAJORANT_REASON: &str = "no majorant structure named: an octree of depth 8 over the graph's range analysis, pruned at a crossing cost of 0.2 lookups unless --octree-prune names one, in place of the flat grid of 8-voxel cells (a graph's lookup costs about five brick reads, so finer cells pay for their crossings)";

/// What the user set explicitly, which `--tracker auto` keeps.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Given {
    pub scheme: bool,
    pub transmittance: bool,
    /// A majorant structure (`--majorant-cell`, `--octree-depth`, `nimbus:octreeDepth`).
    pub majorants: bool,
}

impl Given {
    /// Only the majorant structure is set: the benches' case, whose one structure
    /// serves every tracker, `auto` included.
    pub const MAJORANTS: Given = Given {
        scheme: false,
        transmittance: false,
        majorants: true,
    };
}

/// The specialised code paths a render runs, chosen once before it starts: each is
/// a separate instantiation of the integrator and trackers, not a branch per collision.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub struct CodePaths {
    /// Count lookups, collisions and cells per pixel (the cost AOVs, the stats,
    /// `--profile`); off, the counting is compiled out.
    pub count: bool,
    /// Run the single-channel trackers on grey media (`--no-specialise` turns this
    /// off to force the general RGB path, for benchmarks and checks).
    pub specialise: bool,
}

impl Default for CodePaths {
    /// Counting on, specialisations on.
    fn default() -> Self {
        CodePaths {
            count: true,
            specialise: true,
        }
    }
}

fn count_lights(l: &Lights) -> (usize, usize) {
    let nonzero = |c: [f64; 3]| c.iter().any(|&x| x > 0.0);
    let emits = l
        .suns
        .iter()
        .map(|s| nonzero(s.irradiance))
        .chain(l.spheres.iter().map(|s| nonzero(s.radiance)))
        .chain(l.rects.iter().map(|r| nonzero(r.radiance)))
        .chain(l.disks.iter().map(|d| nonzero(d.radiance)))
        .chain(
            l.cylinders
                .iter()
                .map(|c| nonzero(c.radiance) || nonzero(c.line_intensity)),
        )
        .chain(
            l.linked_domes
                .iter()
                .map(|d| d.map.is_some() || nonzero(d.constant)),
        )
        .chain(l.env_maps.iter().map(|_| true))
        .chain([nonzero(l.environment)]);
    emits.fold((0, 0), |(e, n), x| (e + x as usize, n + 1))
}

fn homogeneous(m: &Medium) -> bool {
    // A shader graph varies over the grid, whatever the grid holds.
    if m.shader.is_some() {
        return false;
    }
    let Some((lo, hi)) = m.density.index_bounds else {
        return false;
    };
    let (mn, mx) = m.density.value_range(lo, hi);
    mn == mx && mx > 0.0
}

fn visible(m: &Medium, camera: &CameraRays, (w, h): (u32, u32)) -> bool {
    const N: u32 = 16;
    (0..N * N).any(|i| {
        let fx = (i % N) as f64 + 0.5;
        let fy = (i / N) as f64 + 0.5;
        let r = camera.ray(fx / N as f64 * w as f64, fy / N as f64 * h as f64);
        let ray = m.index_ray(r.origin, r.dir);
        // The medium's own walk: clipped to a fog box's inside, everywhere for world
        // fog (whose constant brick covers only a box around the scene).
        m.walk(&ray, r.tmin as f32, r.tmax as f32)
            .any(|s| s.dmax > 0.0)
    })
}
