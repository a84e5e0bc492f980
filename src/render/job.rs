//! A render job: a medium, lights, a camera and settings, turned into a film by the
//! integrator instantiated for the selected estimators.

use crate::render::analysis::CodePaths;
use crate::render::camera::CameraRays;
use crate::render::equiangular::LocalLight;
use crate::render::film::{Film, Region};
use crate::render::guiding::LightLobes;
use crate::render::holdouts::Holdouts;
use crate::render::integrator::{Extras, Integrator, SelectSegments};
use crate::render::light_choice::LightChoice;
use crate::render::lights::Lights;
use crate::render::sampler::{pixel_sampler, SamplerKind};
use crate::scene::schema::tokens;
use crate::scene::{Field, FogMesh, Scene, Volume, VolumeShape};
use crate::track::free_path::{FreePathSampler, TransmittanceEstimator};
use crate::track::select::{Dispatch, LightSampling, ScatterGuiding, TrackerKind, TrackerSettings};
use crate::volume::albedo::Albedo;
use crate::volume::boundary::{Boundary, InsideRule, MediumRegion};
use crate::volume::color_graph::ColorGraph;
use crate::volume::convex::ConvexHull;
use crate::volume::counters::Counters;
use crate::volume::emission::{Emission, EmissionGrid};
use crate::volume::graph_density::DensityShader;
use crate::volume::grid::Grid;
use crate::volume::majorant::MajorantSpec;
use crate::volume::medium::Medium;
use crate::volume::vdb;
use crate::volume::velocity::VelocityGrid;
use anyhow::{bail, Context};
use glam::DVec3;
use std::sync::Arc;

/// How many mean free paths (at the largest extinction) the ball around a sphere light
/// in a grid reaches, whose chords `auto` samples equiangularly
/// ([`RenderJob::local_lights`]). A measured choice (docs/trackers.md, "A ball of three
/// mean free paths, and a roulette past it"), not a derived optimum.
pub const CHORD_FREE_PATHS: f64 = 3.0;

pub struct RenderJob<'a> {
    /// The stage's volumes, one medium each (at least one).
    pub media: &'a [Medium],
    pub lights: &'a Lights,
    pub camera: &'a CameraRays,
    pub width: u32,
    pub height: u32,
    pub spp: u32,
    pub max_depth: u32,
    pub seed: u64,
    /// Where each sample's random numbers come from.
    pub sampler: SamplerKind,
    pub tracking: TrackerSettings,
    /// Which specialised code paths run (counting, single-channel tracking).
    pub paths: CodePaths,
    /// Split layers and deep bins to fill beside the beauty.
    pub extras: Extras<'a>,
}

impl RenderJob<'_> {
    /// Renders `spp` samples per pixel in one pass on the current rayon pool; `progress`
    /// is called once per finished row.
    pub fn render(&self, progress: &(dyn Fn() + Sync)) -> Film {
        let mut film = self.new_film(None);
        self.render_pass(&mut film, self.spp, progress);
        film
    }

    /// The shutter interval camera samples draw their time from: the camera's, when
    /// the camera, a medium or a local light moves while it is open (else `None`: no time is drawn).
    pub fn shutter(&self) -> Option<(f64, f64)> {
        let moves =
            self.camera.moves() || self.media.iter().any(Medium::moves) || self.lights.moves();
        self.camera.shutter().filter(|_| moves)
    }

    /// Whether the media are tracked as grey (the analysis' test, on the
    /// cross-sections of every medium).
    fn grey(&self) -> bool {
        self.paths.specialise && self.media.iter().all(|m| m.sigma.is_grey())
    }

    /// The local lights path segments also sample scattering points towards
    /// (`--light-sampling`), in [`Lights::locals`]' order; a light left to the
    /// collisions has power 0, and none at all is an empty list (nothing is drawn).
    /// `auto`: every local light where every medium is homogeneous (fog boxes, world
    /// fog); in a heterogeneous medium spots, whose cones the collisions' light
    /// samples mostly miss (measured: docs/trackers.md), and sphere lights that light
    /// their interior, on the chord through a ball around them alone
    /// ([`Self::chord_radius`]): near such a light a collision's next-event estimate
    /// grows as 1/r² up to the light's whole radiance from every direction, and the
    /// few collisions that land there are the render's fireflies; farther out the
    /// collisions do as well for less. The other unshaped lights lose there and are
    /// left to the collisions.
    pub fn local_lights(&self) -> Vec<LocalLight> {
        let mut locals = match self.tracking.light_sampling {
            LightSampling::Collisions => return Vec::new(),
            _ => self.lights.locals(),
        };
        if self.tracking.light_sampling == LightSampling::Auto && !self.every_medium_constant() {
            let ball = self.chord_radius();
            // `locals` lists the sphere lights first.
            let lit_inside = |i: usize| self.lights.spheres.get(i).is_some_and(|s| s.interior);
            for (i, l) in locals
                .iter_mut()
                .enumerate()
                .filter(|(_, l)| l.cone.is_none())
            {
                match lit_inside(i) {
                    true => l.chord = Some(ball.max(l.radius)),
                    false => l.power = 0.0,
                }
            }
        }
        if locals.iter().all(|l| l.power <= 0.0) {
            locals.clear();
        }
        locals
    }

    /// The radius of the ball around a sphere light in a grid whose chords get
    /// equiangular points under `auto` (never less than the light's own):
    /// [`CHORD_FREE_PATHS`] mean free paths at the densest medium's largest extinction.
    /// A collision's light estimate at distance r has a second moment
    /// ∝ ∫ (1/r²)² r² dr past the ball, ∝ 1/radius; inside it the equiangular points
    /// bound it, at the price of a transmittance estimate per segment that crosses it.
    fn chord_radius(&self) -> f64 {
        let densest = self
            .media
            .iter()
            .map(Medium::max_extinction)
            .fold(0.0, f64::max);
        match densest > 0.0 {
            true => CHORD_FREE_PATHS / densest,
            false => 0.0,
        }
    }

    /// The lobes scattered directions are guided towards (`--scatter-guiding`):
    /// every local light under `lights`; under `auto` the point, sphere and spot lights
    /// of a stage lit by nothing else (a large rect beside a thin cloud lost: its lobe
    /// sends paths out of the medium; and lobes towards a spot take half the paths
    /// from the sun that lights most of a cloud: docs/trackers.md); none under
    /// `phase` or on a stage without them (whose renders are then unchanged).
    pub fn light_lobes(&self) -> Option<LightLobes> {
        let mut locals = self.lights.locals();
        match self.tracking.scatter_guiding {
            ScatterGuiding::Phase => return None,
            ScatterGuiding::Lights => {}
            ScatterGuiding::Auto if self.lights.has_distant_light() => return None,
            // `locals` lists the sphere lights (spots among them) first.
            ScatterGuiding::Auto => locals.truncate(self.lights.spheres.len()),
        }
        LightLobes::new(&locals)
    }

    /// Whether every medium is homogeneous (fog boxes, world fog): where `auto`
    /// samples every local light equiangularly.
    fn every_medium_constant(&self) -> bool {
        self.media.iter().all(|m| m.constant)
    }

    /// What [`Self::local_lights`] decided, in one line for `nimbus info`: how many
    /// local lights get equiangular points, and why.
    pub fn light_sampling_summary(&self) -> String {
        let total = self.lights.locals().len();
        if total == 0 {
            return "no local lights: next events at the collisions only".into();
        }
        let sampled = self.local_lights().iter().filter(|l| l.power > 0.0).count();
        let why = match self.tracking.light_sampling {
            LightSampling::Collisions => "--light-sampling collisions".to_string(),
            LightSampling::EquiangularMis => "--light-sampling equiangular-mis".to_string(),
            LightSampling::Auto if self.every_medium_constant() => {
                "auto: every medium is homogeneous".to_string()
            }
            LightSampling::Auto => format!(
                "auto: in a heterogeneous medium spots, whose cones the collisions' light samples mostly miss, and sphere lights that light their interior, on the chord through a ball of {CHORD_FREE_PATHS} mean free paths around them; the others lose there and are left to the collisions (docs/trackers.md)"
            ),
        };
        let guided = match self.light_lobes() {
            Some(_) => "; scattered directions guided towards the local lights",
            None => "; scattered directions from the phase function",
        };
        let chosen = match total > crate::render::light_choice::MANY_LIGHTS {
            true => "; each vertex's next event samples one of them, chosen by power over squared distance",
            false => "",
        };
        format!(
            "{} {sampled} of {total} local light{} sampled equiangularly with MIS ({why}){guided}{chosen}",
            if sampled > 0 {
                "equiangular-mis:"
            } else {
                "collisions:"
            },
            if total == 1 { "" } else { "s" }
        )
    }

    /// Whether the render runs the single-channel trackers of grey media.
    pub fn grey_tracking(&self) -> bool {
        crate::track::select::grey_tracking(&self.tracking, self.grey())
    }

    /// An empty film for this job (its size, pixel streams seeded from its seed), of
    /// the whole frame or of `region` of it.
    pub fn new_film(&self, region: Option<Region>) -> Film {
        let region = region.unwrap_or(Region::full(self.width, self.height));
        let layers = self.extras.splits.map_or(0, |m| m.len());
        Film::of_region(self.width, self.height, region, self.seed)
            .with_extras(layers, self.extras.depth_bins)
    }

    /// Adds `n` samples per pixel to `film` (progressive rendering: any split of N
    /// samples into passes gives the same film as one pass of N).
    pub fn render_pass(&self, film: &mut Film, n: u32, progress: &(dyn Fn() + Sync)) {
        self.dispatch(Work::Pass { film, n, progress });
    }

    /// `n` paths through each film position of `at` (in pixels), in that order, each
    /// with its own counters: per-path statistics (variance, cost per path) that a
    /// film's sums hide. All draw from one random stream, pixel 0's of the job's seed.
    pub fn paths(&self, at: &[(f64, f64)], n: usize) -> Vec<([f64; 3], Counters)> {
        let mut out = Vec::with_capacity(at.len() * n);
        self.dispatch(Work::Paths {
            at,
            n,
            out: &mut out,
        });
        out
    }

    /// Runs `work` with the integrator instantiated for the job's estimators. Every
    /// caller goes through this one [`Dispatch`] impl, so each estimator pair is
    /// compiled once, here, and not again in each crate that renders (a test crate
    /// instantiating its own took minutes of build).
    fn dispatch(&self, work: Work) {
        struct Run<'j, 'w> {
            job: &'j RenderJob<'j>,
            work: Work<'w>,
        }
        impl Dispatch<()> for Run<'_, '_> {
            fn run<F: FreePathSampler, E: TransmittanceEstimator>(
                self,
                free_path: F,
                transmittance: E,
            ) {
                let j = self.job;
                let spp = match &self.work {
                    Work::Pass { n, .. } => *n,
                    Work::Paths { .. } => j.spp,
                };
                let it = j.integrator(free_path, transmittance, spp);
                match self.work {
                    Work::Pass { film, n, progress } => it.render_pass(film, n, progress),
                    Work::Paths { at, n, out } => {
                        let mut rng = pixel_sampler(j.seed, 0);
                        for &(fx, fy) in at {
                            for _ in 0..n {
                                let mut c = Counters::default();
                                let rgb = it.sample(fx, fy, &mut rng, &mut c).rgb;
                                out.push((rgb, c));
                            }
                        }
                    }
                }
            }
        }
        crate::track::select::dispatch_specialised(
            &self.tracking,
            self.grey(),
            Run { job: self, work },
        )
    }

    /// The integrator of this job with the estimators `free_path` and
    /// `transmittance`, taking `spp` samples per pixel.
    fn integrator<F: FreePathSampler, E: TransmittanceEstimator>(
        &self,
        free_path: F,
        transmittance: E,
        spp: u32,
    ) -> Integrator<'_, F, E> {
        Integrator {
            free_path,
            transmittance,
            channel_per_path: self.tracking.tracker == TrackerKind::NaiveDelta,
            majorant_scale: self.tracking.majorant_scale,
            count: self.paths.count,
            profile: self.tracking.profile,
            media: self.media,
            lights: self.lights,
            camera: self.camera,
            width: self.width,
            height: self.height,
            spp,
            max_depth: self.max_depth,
            seed: self.seed,
            qmc_dims: self.sampler.qmc_dims(),
            extras: self.extras,
            select_segments: match self.tracking.tracker {
                TrackerKind::RatioSelect if self.grey_tracking() => SelectSegments::Grey,
                TrackerKind::RatioSelect => SelectSegments::Rgb,
                _ => SelectSegments::Off,
            },
            locals: self.local_lights(),
            shutter: self.shutter(),
            guide: self.light_lobes(),
            light_choice: LightChoice::new(&self.lights.locals()),
        }
    }
}

/// What [`RenderJob::dispatch`] runs: a pass over a film, or paths through points.
enum Work<'w> {
    Pass {
        film: &'w mut Film,
        n: u32,
        progress: &'w (dyn Fn() + Sync),
    },
    Paths {
        at: &'w [(f64, f64)],
        n: usize,
        out: &'w mut Vec<([f64; 3], Counters)>,
    },
}

/// Loads the density grid (and emission grids) of every volume of the scene and
/// builds one medium per volume, each with its own majorant structure `spec`. Where
/// volumes overlap their coefficients add: the trackers race the media's collision
/// processes ([`track::race`]).
pub fn media_for_scene_with(scene: &Scene, spec: MajorantSpec) -> anyhow::Result<Vec<Medium>> {
    if scene.volumes.is_empty() {
        bail!(
            "{}: the stage has no visible UsdVolVolume prim to render",
            scene.stage_path.display()
        );
    }
    // World fog is bounded by everything else, so it is built last (in its place).
    // A volume that differs from an earlier one only by its transform (an instance of
    // a PointInstancer prototype, or the same asset placed twice) shares its grids and
    // majorant structure: each is loaded once whatever the count.
    let mut media: Vec<Option<Medium>> = Vec::with_capacity(scene.volumes.len());
    let shutter = scene.camera.shutter;
    for (i, volume) in scene.volumes.iter().enumerate() {
        let prototype = scene.volumes[..i]
            .iter()
            .position(|earlier| same_medium(earlier, volume));
        let mut medium = match (&volume.shape, prototype) {
            (VolumeShape::World, _) => None,
            // Its prototype's grids, majorants and velocity grid, placed anew.
            (VolumeShape::Field(_), Some(j)) => {
                let Some(p) = &media[j] else {
                    unreachable!("a field volume's prototype is built")
                };
                Some(p.instance(&volume.prim_path, volume.volume_to_world)?)
            }
            _ => {
                let mut m = medium_for_volume(volume, spec)?;
                if let (Some(v), Some(shutter)) = (velocity_for_volume(volume, &m)?, shutter) {
                    m.set_velocity(v, shutter);
                }
                Some(m)
            }
        };
        if let (Some(m), Some(motion)) = (&mut medium, &volume.motion) {
            m.set_motion(motion.clone(), volume.volume_to_world);
        }
        media.push(medium);
    }
    for (slot, volume) in media.iter_mut().zip(&scene.volumes) {
        if slot.is_none() {
            // Everywhere: the box only places the constant brick.
            let unit = (DVec3::splat(-1.0), DVec3::splat(1.0));
            *slot = Some(fog_medium(volume, MediumRegion::Everywhere, unit)?);
        }
    }
    Ok(media.into_iter().flatten().collect())
}

/// Whether `b` is `a` but for its name, transform and light group: the same grids,
/// coefficients and emission (a fog box is never shared: its surface is placed).
fn same_medium(a: &Volume, b: &Volume) -> bool {
    let (VolumeShape::Field(fa), VolumeShape::Field(fb)) = (&a.shape, &b.shape) else {
        return false;
    };
    let (ea, eb) = (&a.emission, &b.emission);
    same_grid(fa, fb)
        && a.density_scale == b.density_scale
        && a.absorption == b.absorption
        && a.scattering == b.scattering
        && a.anisotropy == b.anisotropy
        && ea.params() == eb.params()
        && same_named(&ea.temperature, &eb.temperature)
        && same_named(&ea.emission, &eb.emission)
        && ea.color_graph.as_ref().map(|g| &g.program)
            == eb.color_graph.as_ref().map(|g| &g.program)
        && same_named(&a.albedo, &b.albedo)
        && a.albedo_graph.as_ref().map(|g| &g.program)
            == b.albedo_graph.as_ref().map(|g| &g.program)
        && a.velocity
            .as_ref()
            .map(|v| (&v.field.1, v.seconds_per_time_code))
            == b.velocity
                .as_ref()
                .map(|v| (&v.field.1, v.seconds_per_time_code))
        && a.density_graph.as_ref().map(|g| &g.program)
            == b.density_graph.as_ref().map(|g| &g.program)
}

/// Whether two fields read the same grid: the same file, grid name and index, whichever
/// OpenVDBAsset prims name them.
fn same_grid(a: &Field, b: &Field) -> bool {
    a.file == b.file && a.field_name == b.field_name && a.field_index == b.field_index
}

fn same_named(a: &Option<(String, Field)>, b: &Option<(String, Field)>) -> bool {
    match (a, b) {
        (None, None) => true,
        (Some((_, a)), Some((_, b))) => same_grid(a, b),
        _ => false,
    }
}

/// The homogeneous medium of fog (a fog box or world fog) in `region`, whose box is
/// `bounds`.
fn fog_medium(
    volume: &Volume,
    region: MediumRegion,
    bounds: (DVec3, DVec3),
) -> anyhow::Result<Medium> {
    let mut medium = Medium::homogeneous(
        &volume.prim_path,
        region,
        bounds,
        volume.density_scale,
        volume.absorption,
        volume.scattering,
        volume.anisotropy,
    )?;
    medium.set_emission(emission_for_volume(volume)?);
    medium.set_albedo(albedo_for_volume(volume)?);
    Ok(medium)
}

/// A fog box's surface for clipping rays: its face planes when it is closed, convex and
/// has few ([`ConvexHull`]: most boxes users make), else a BVH over its triangles.
fn fog_surface(fog: &FogMesh) -> Arc<dyn Boundary> {
    if fog.closed {
        if let Some(hull) = ConvexHull::from_triangles(&fog.mesh.points, &fog.mesh.triangles) {
            return Arc::new(hull);
        }
    }
    let rule = match fog.closed {
        true => InsideRule::Orientation,
        false => InsideRule::Parity,
    };
    Arc::new(Holdouts::build(std::slice::from_ref(&fog.mesh)).with_rule(rule))
}

/// Loads one volume's grids and builds its medium (a fog box's: its surface, [`fog_surface`]).
fn medium_for_volume(volume: &Volume, spec: MajorantSpec) -> anyhow::Result<Medium> {
    let field = match &volume.shape {
        VolumeShape::Field(field) => field,
        VolumeShape::Mesh(fog) => {
            let surface = fog_surface(fog);
            let Some(bounds) = mesh_bounds(&fog.mesh) else {
                bail!(
                    "volume {}: the fog box's surface has no triangle to bound it",
                    volume.prim_path
                );
            };
            let region = MediumRegion::Inside(surface);
            return match &volume.density_graph {
                None => fog_medium(volume, region, bounds),
                Some(graph) => graph_fog_medium(volume, graph, region, bounds, spec),
            };
        }
        VolumeShape::World => unreachable!("world fog is built after the other media"),
    };
    let grid = load_grid(volume, "density", field)?;
    let mut medium = Medium::with_majorants(
        &volume.prim_path,
        grid,
        volume.volume_to_world,
        volume.density_scale,
        volume.absorption,
        volume.scattering,
        volume.anisotropy,
        spec,
    )?;
    if let Some(graph) = &volume.density_graph {
        // The grid's index space → the volume's local space (the graph's positions):
        // the VDB's own transform.
        let index_to_object = medium.density.index_to_world;
        let shading_to_object = volume.volume_to_world.inverse() * graph.shading_to_world;
        let shader = DensityShader::new(
            graph.program.clone(),
            shading_to_object.inverse() * index_to_object,
            &graph.source,
        );
        medium.set_shader(shader, spec)?;
    }
    medium.set_emission(emission_for_volume(volume)?);
    medium.set_albedo(albedo_for_volume(volume)?);
    Ok(medium)
}

/// Voxels along each side of the box of a fog box whose density is a shader graph: the
/// majorant cells are cut from them (the graph's range analysis bounds each cell), and a
/// box of constant density needs one brick where a graph needs finer cells.
const GRAPH_FOG_EDGE: i32 = 64;

/// A fog box whose density is a shader graph over its box.
fn graph_fog_medium(
    volume: &Volume,
    graph: &crate::scene::DensityGraph,
    region: MediumRegion,
    bounds: (DVec3, DVec3),
    spec: MajorantSpec,
) -> anyhow::Result<Medium> {
    let mut medium = Medium::homogeneous_with(
        &volume.prim_path,
        region,
        bounds,
        GRAPH_FOG_EDGE,
        (
            volume.density_scale,
            volume.absorption,
            volume.scattering,
            volume.anisotropy,
        ),
    )?;
    // The constant grid sits in world space.
    let index_to_shading = graph.shading_to_world.inverse() * medium.density.index_to_world;
    medium.set_shader(
        DensityShader::new(graph.program.clone(), index_to_shading, &graph.source),
        spec,
    )?;
    medium.set_emission(emission_for_volume(volume)?);
    medium.set_albedo(albedo_for_volume(volume)?);
    Ok(medium)
}

/// A colour graph as read (its position space → world) placed for lookups at world
/// points.
fn placed_color_graph(g: &crate::scene::DensityGraph) -> ColorGraph {
    ColorGraph {
        program: g.program.clone(),
        world_to_shading: g.shading_to_world.inverse(),
    }
}

/// The albedo multiplier of a volume: the colour graph `nimbus:albedo` is connected
/// to, or the grid `nimbus:albedoField` names (a Vec3s grid, or a float grid as grey),
/// loaded only then. A grid's values outside [0,1] are clamped, with one warning
/// naming the file, the grid and the count.
pub fn albedo_for_volume(volume: &Volume) -> anyhow::Result<Option<Albedo>> {
    if let Some(g) = &volume.albedo_graph {
        return Ok(Some(Albedo::graph(&g.source, placed_color_graph(g))));
    }
    let Some((name, field)) = &volume.albedo else {
        return Ok(None);
    };
    let role = format!("{} `{name}`", tokens::ALBEDO_FIELD);
    let raw = vdb::read_color_grid(&field.file, &field.field_name, field.field_index)
        .with_context(|| {
            format!(
                "volume {}: {role} field {}",
                volume.prim_path, field.prim_path
            )
        })?;
    let grid_name = raw[0].name.clone();
    let albedo = Albedo::new(&volume.prim_path, &role, name, raw, volume.volume_to_world)
        .with_context(|| format!("{}: {}", field.file, field.prim_path))?;
    if albedo.clamped_values > 0 {
        eprintln!(
            "nimbus: warning: {}: albedo grid '{}' has {} component values outside [0, 1] or not finite; they are clamped to [0, 1]",
            field.file, grid_name, albedo.clamped_values
        );
    }
    Ok(Some(albedo))
}

/// The velocity grid (issue 45) of a volume whose medium is `medium`, placed in its
/// density grid's index space; `None` when the volume has none.
fn velocity_for_volume(volume: &Volume, medium: &Medium) -> anyhow::Result<Option<VelocityGrid>> {
    let Some(v) = &volume.velocity else {
        return Ok(None);
    };
    let (name, field) = &v.field;
    let what = || {
        format!(
            "volume {}: velocity field `{name}` ({})",
            volume.prim_path, field.prim_path
        )
    };
    let raw = vdb::read_vec3s_grid(&field.file, &field.field_name, field.field_index)
        .with_context(what)?;
    let density_index_to_volume = medium.density.index_to_world;
    let grid = VelocityGrid::new(name, raw, density_index_to_volume, v.seconds_per_time_code)
        .with_context(|| format!("{}: {}", field.file, field.prim_path))?;
    if grid.sanitized > 0 {
        eprintln!(
            "nimbus: warning: {}: velocity grid '{}' has {} NaN or infinite component values; they are treated as 0",
            field.file, field.field_name, grid.sanitized
        );
    }
    Ok(Some(grid))
}

/// The box around a mesh's points, `None` without a triangle.
fn mesh_bounds(mesh: &crate::scene::HoldoutMesh) -> Option<(DVec3, DVec3)> {
    let mut b = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
    for t in &mesh.triangles {
        for &i in t {
            let p = DVec3::from_array(*mesh.points.get(i as usize)?);
            b = (b.0.min(p), b.1.max(p));
        }
    }
    (b.0.cmple(b.1).all()).then_some(b)
}

/// Loads one float grid of a volume's field; `role` names what it is for in errors.
fn load_grid(volume: &Volume, role: &str, field: &Field) -> anyhow::Result<Grid> {
    let raw = vdb::read_float_grid(&field.file, &field.field_name, field.field_index)
        .with_context(|| {
            format!(
                "volume {}: {role} field {}",
                volume.prim_path, field.prim_path
            )
        })?;
    let grid =
        Grid::from_raw(&raw).with_context(|| format!("{}: {}", field.file, field.prim_path))?;
    if grid.sanitized_voxels > 0 {
        eprintln!(
            "nimbus: warning: {}: grid '{}' has {} NaN, infinite or negative voxels; they are treated as 0",
            field.file, grid.name, grid.sanitized_voxels
        );
    }
    Ok(grid)
}

/// The emission of a volume: loads only the grids `nimbus:temperatureField` and
/// `nimbus:emissionField` name (none when both are empty) and checks the parameters.
pub fn emission_for_volume(volume: &Volume) -> anyhow::Result<Option<Emission>> {
    let e = &volume.emission;
    let params = e.params();
    // Bad numbers are reported before any grid is read.
    params.check(&volume.prim_path)?;
    let load = |attr: &str, named: &Option<(String, Field)>| -> anyhow::Result<_> {
        let Some((name, field)) = named else {
            return Ok(None);
        };
        let role = format!("{attr} `{name}`");
        let grid = load_grid(volume, &role, field)?;
        Ok(Some(EmissionGrid::new(
            &volume.prim_path,
            &role,
            grid,
            volume.volume_to_world,
        )?))
    };
    let temperature = load(tokens::TEMPERATURE_FIELD, &e.temperature)?;
    let field = load(tokens::EMISSION_FIELD, &e.emission)?;
    let color_graph = e.color_graph.as_ref().map(placed_color_graph);
    Ok(Emission::new(
        &volume.prim_path,
        temperature,
        field,
        params,
        color_graph,
    )?)
}
