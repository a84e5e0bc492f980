//! A density-driven participating medium: μa(x,λ) = d(x)·σa(λ), μs(x,λ) = d(x)·σs(λ),
//! with d(x) the trilinearly reconstructed density field times the density scale.
//!
//! The medium owns the ray ↔ grid mapping: trackers work with a world-space distance
//! `t` along a world-space ray and index-space positions `o + t·d` (the index-space
//! direction is *not* normalised, so `t` keeps world units and the coefficients stay
//! per world unit length, whatever the grid's voxel size or the volume's transform).
//!
//! An optional albedo multiplier c(x) ∈ [0,1]³ ([`Albedo`]: a grid, `nimbus:albedoField`,
//! or a colour graph, `nimbus:albedo`) turns
//! μs into c·μs and μa into μa + (1 − c)·μs, leaving μt (hence majorants and trackers)
//! unchanged; the integrator applies it as a weight c(x) at scatter events (the model and
//! the unbiasedness argument are in [`crate::volume::albedo`]).

use crate::color::Spectrum;
use crate::motion::TransformMotion;
use crate::volume::albedo::Albedo;
use crate::volume::boundary::{convex_span, Inside, MediumRegion, MediumWalk};
use crate::volume::counters::Tally;
use crate::volume::emission::Emission;
use crate::volume::graph_density::{self, DensityShader};
use crate::volume::grid::{world_to_index, Grid, MediumError, RawGrid, RawLeaf};
use crate::volume::majorant::{MajorantSpec, MajorantTree, PruneCost, Segment};
use crate::volume::ticks;
use crate::volume::velocity::VelocityGrid;
use glam::{DMat4, DVec3, Vec3};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Arc;

/// A ray mapped into a medium's index space.
#[derive(Clone, Copy, Debug)]
pub struct IndexRay {
    pub o: Vec3,
    /// Index-space displacement per world unit of `t`.
    pub d: Vec3,
    /// Seconds the medium's velocity field advects its lookups by along this ray (the
    /// sample's time from the frame, scaled; 0 without velocity blur).
    pub advect: f32,
}

impl IndexRay {
    #[inline(always)]
    pub fn at(&self, t: f32) -> Vec3 {
        self.o + self.d * t
    }
}

/// Cross-sections per unit density: μ★(x, λ) = d(x)·σ★(λ).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sigma {
    pub a: Spectrum,
    pub s: Spectrum,
    pub t: Spectrum,
    /// max over channels of σt: turns a density majorant into an achromatic extinction
    /// majorant.
    pub t_max: f32,
}

impl Sigma {
    pub fn new(a: Spectrum, s: Spectrum) -> Sigma {
        let t = [a[0] + s[0], a[1] + s[1], a[2] + s[2]];
        Sigma {
            a,
            s,
            t,
            t_max: t[0].max(t[1]).max(t[2]),
        }
    }

    /// The grey medium of one channel (naive delta tracking tracks one channel per path).
    pub fn channel(&self, c: usize) -> Sigma {
        Sigma::new([self.a[c]; 3], [self.s[c]; 3])
    }

    /// All channels equal: grey tracking is exact with unit weights.
    #[inline]
    pub fn is_grey(&self) -> bool {
        self.t[0] == self.t[1]
            && self.t[1] == self.t[2]
            && self.s[0] == self.s[1]
            && self.s[1] == self.s[2]
    }
}

/// The world-space box around the majorant region's index box, its eight corners
/// boxed by `place` (into world space, where it is or wherever it goes), padded by
/// 1e-4 of its diagonal against rounding.
fn world_box(
    majorants: &MajorantTree,
    place: impl FnOnce(&[DVec3; 8]) -> (DVec3, DVec3),
) -> Option<(DVec3, DVec3)> {
    let (lo, hi) = majorants.index_region()?;
    let b = place(&crate::volume::grid::box_corners(
        lo.as_dvec3(),
        hi.as_dvec3(),
    ));
    let pad = DVec3::splat(1e-4 * (b.1 - b.0).length());
    Some((b.0 - pad, b.1 + pad))
}

pub struct Medium {
    /// The prim this medium comes from (for messages).
    pub prim_path: String,
    /// The density grid and its majorant structure (both in index space) are shared
    /// by the instances of a volume ([`Medium::instance`]): one copy whatever the count.
    pub density: Arc<Grid>,
    /// World → index, the inverse of volume_to_world · index_to_world.
    world_to_index: DMat4,
    /// σa, σs, σt per unit density (density scale folded in).
    pub sigma: Sigma,
    /// Henyey–Greenstein asymmetry.
    pub g: f32,
    pub majorants: Arc<MajorantTree>,
    /// World-space box around the majorant region (padded), for culling the media a
    /// ray cannot meet; `None` for an empty grid, and for a medium that is everywhere.
    world_box: Option<(DVec3, DVec3)>,
    /// Emission (temperature and/or emission grids), collected at absorption events;
    /// `None` for a non-emissive medium. Set with [`Medium::set_emission`].
    pub emission: Option<Emission>,
    /// Albedo multiplier c(x) (`nimbus:albedoField`'s grid or `nimbus:albedo`'s colour
    /// graph), looked up at scatter events;
    /// `None` = constant albedo σs/σt. Set with [`Medium::set_albedo`].
    pub albedo: Option<Albedo>,
    /// Where the medium is: where its grid is, inside a closed surface (a fog box;
    /// walks are clipped to it) or everywhere (world fog).
    pub region: MediumRegion,
    /// The density is the same everywhere in the region ([`Medium::homogeneous`]):
    /// a clipped walk's segments then have equal bounds.
    pub constant: bool,
    /// Index → world, for mapping index rays back to the boundary's world space.
    index_to_world: DMat4,
    /// A shader graph the density goes through (issue 47): d(x) = graph(x, grid(x));
    /// `None` = the grid's value. Set with [`Medium::set_shader`].
    pub shader: Option<Arc<DensityShader>>,
    /// Whether trackers prefetch the next tentative collision's stencil
    /// ([`Grid::prefetch`]): only for grids whose bricks outgrow the caches
    /// ([`PREFETCH_BYTES`]), where a lookup waits on memory; below that the hint costs
    /// instructions and buys nothing.
    pub prefetch: bool,
    /// How the volume moves while the camera's shutter is open (`None`: it stays where
    /// `world_to_index` puts it). Set with [`Medium::set_motion`].
    motion: Option<Arc<MediumMotion>>,
    /// The velocity grid that advects the fields over the shutter, with the largest
    /// time from the frame (in time codes) a sample can have. Set with
    /// [`Medium::set_velocity`].
    pub velocity: Option<Arc<VelocityGrid>>,
    velocity_reach: f64,
}

/// A medium's transform motion: at frame-relative time τ its world → index map is
/// `index_from_volume · V(τ)⁻¹`, V the volume → world keys. Everything else placed in
/// world space at the frame (emission, albedo, colour graphs) is looked up at the
/// point's place at the frame, `V(0) · V(τ)⁻¹ · p`. The grid, its majorants and the
/// density graph live in index space and do not move.
#[derive(Debug)]
struct MediumMotion {
    volume_to_world: TransformMotion,
    /// Index ← volume (the VDB's own transform, inverted).
    index_from_volume: DMat4,
    /// Volume → world at the frame: where the medium's other lookups are placed.
    at_frame: DMat4,
}

impl MediumMotion {
    /// World → volume at `time`.
    #[inline]
    fn world_to_volume(&self, time: f64) -> DMat4 {
        self.volume_to_world.at(time).inverse()
    }
}

/// Grids holding more brick bytes than this get [`Medium::prefetch`]: the L3 of the
/// machines measured (docs/performance.md, "Prefetching the next lookup"). On
/// smoke_thick's 6.1 MiB grid the hint cost 17 % more instructions and 28 % more time;
/// on 74.5 MiB and 928 MiB grids it saved 6 % of the render time on each (medians of 6
/// interleaved rounds).
pub const PREFETCH_BYTES: usize = 32 << 20;

impl Medium {
    /// The world-space box around the majorant region (padded), `None` for an empty
    /// grid.
    pub fn world_bounds(&self) -> Option<(DVec3, DVec3)> {
        self.world_box
    }

    /// Builds a medium. `cell_voxels` is the edge of a majorant cell in voxels
    /// (0 = one cell for the whole volume, i.e. a global majorant).
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        prim_path: &str,
        density: Grid,
        volume_to_world: DMat4,
        density_scale: f64,
        absorption: [f64; 3],
        scattering: [f64; 3],
        anisotropy: f64,
        cell_voxels: u32,
    ) -> Result<Medium, MediumError> {
        Self::with_majorants(
            prim_path,
            density,
            volume_to_world,
            density_scale,
            absorption,
            scattering,
            anisotropy,
            MajorantSpec::Uniform { cell_voxels },
        )
    }

    /// Builds a medium with the majorant structure `spec` (a flat grid or an octree).
    #[allow(clippy::too_many_arguments)]
    pub fn with_majorants(
        prim_path: &str,
        density: impl Into<Arc<Grid>>,
        volume_to_world: DMat4,
        density_scale: f64,
        absorption: [f64; 3],
        scattering: [f64; 3],
        anisotropy: f64,
        spec: MajorantSpec,
    ) -> Result<Medium, MediumError> {
        let density = density.into();
        let invalid = |message: String| MediumError::Invalid {
            prim: prim_path.to_string(),
            message,
        };
        let world_to_index = world_to_index(prim_path, "", volume_to_world, &density)?;
        let check = |name: &str, v: f64| -> Result<f32, MediumError> {
            if v.is_finite() && v >= 0.0 && v < f32::MAX as f64 {
                Ok(v as f32)
            } else {
                Err(invalid(format!(
                    "{name} must be finite and non-negative, got {v}"
                )))
            }
        };
        let scale = check("nimbus:densityScale", density_scale)?;
        let mut sigma_a = [0f32; 3];
        let mut sigma_s = [0f32; 3];
        for c in 0..3 {
            sigma_a[c] = check("nimbus:absorption", absorption[c])? * scale;
            sigma_s[c] = check("nimbus:scattering", scattering[c])? * scale;
        }
        if !(anisotropy.is_finite() && anisotropy > -1.0 && anisotropy < 1.0) {
            return Err(invalid(format!(
                "nimbus:anisotropy must lie in (-1, 1), got {anisotropy}"
            )));
        }
        let majorants = Arc::new(MajorantTree::build(&density, spec));
        // An infinite majorant would make every free-path step 0: tracking would never
        // advance along the ray. Finite voxels can still overflow once scaled.
        let sigma = Sigma::new(sigma_a, sigma_s);
        let mu_max = majorants.max_density() as f64 * sigma.t_max as f64;
        if !(mu_max < f32::MAX as f64) {
            return Err(invalid(format!(
                "the largest density ({}) times the extinction cross-section ({}) overflows 32-bit floats; rescale the grid or nimbus:densityScale",
                majorants.max_density(),
                sigma.t_max
            )));
        }
        Ok(Medium {
            prim_path: prim_path.to_string(),
            world_to_index,
            sigma,
            g: anisotropy as f32,
            world_box: world_box(&majorants, |c| {
                TransformMotion::box_of(&world_to_index.inverse(), c)
            }),
            majorants,
            emission: None,
            albedo: None,
            region: MediumRegion::Grid,
            constant: false,
            index_to_world: world_to_index.inverse(),
            prefetch: density.memory_bytes() > PREFETCH_BYTES,
            shader: None,
            density,
            motion: None,
            velocity: None,
            velocity_reach: 0.0,
        })
    }

    /// A homogeneous medium of density 1 in `region`: inside a fog box's surface, whose
    /// box is `[lo, hi]` (world space), or everywhere (any box). The coefficients are
    /// per world unit, times `density_scale`. The constant density is stored as one
    /// brick of ones over the box (everywhere, with a background of one), so the
    /// majorants, trackers, counters and AOVs treat it as they treat any grid (one
    /// cell, one lookup per collision; every tentative collision is real); walks are
    /// clipped to the region.
    #[allow(clippy::too_many_arguments)]
    pub fn homogeneous(
        prim_path: &str,
        region: MediumRegion,
        bounds: (DVec3, DVec3),
        density_scale: f64,
        absorption: [f64; 3],
        scattering: [f64; 3],
        anisotropy: f64,
    ) -> Result<Medium, MediumError> {
        Self::homogeneous_with(
            prim_path,
            region,
            bounds,
            CONSTANT_EDGE,
            (density_scale, absorption, scattering, anisotropy),
        )
    }

    /// [`homogeneous`](Self::homogeneous) with `edge` voxels along each side of the
    /// box: a fog box whose density a shader graph sets ([`Medium::set_shader`]) needs
    /// finer majorant cells than one brick gives.
    pub fn homogeneous_with(
        prim_path: &str,
        region: MediumRegion,
        (lo, hi): (DVec3, DVec3),
        edge: i32,
        (density_scale, absorption, scattering, anisotropy): (f64, [f64; 3], [f64; 3], f64),
    ) -> Result<Medium, MediumError> {
        let invalid = |message: String| MediumError::Invalid {
            prim: prim_path.to_string(),
            message,
        };
        let size = hi - lo;
        if !(lo.is_finite() && hi.is_finite() && size.min_element() >= 0.0) {
            return Err(invalid(format!(
                "its bounds ({lo} .. {hi}) are not a finite box"
            )));
        }
        // Padded, so a lookup rounding just outside the box still reads only ones; a
        // flat box (a plane) gets some thickness, as a zero scale would make the
        // transform singular. The walk is clipped to the region anyway.
        let pad = DVec3::splat(1e-4 * size.max_element().max(1e-6));
        let everywhere = matches!(region, MediumRegion::Everywhere);
        let background = if everywhere { 1.0 } else { 0.0 };
        let grid = constant_grid(prim_path, lo - pad, size + 2.0 * pad, background, edge)
            .map_err(|e| invalid(format!("constant density: {e}")))?;
        let mut medium = Medium::with_majorants(
            prim_path,
            grid,
            DMat4::IDENTITY,
            density_scale,
            absorption,
            scattering,
            anisotropy,
            MajorantSpec::Uniform { cell_voxels: 0 },
        )?;
        if everywhere {
            medium.world_box = None;
        }
        medium.region = region;
        medium.constant = true;
        Ok(medium)
    }

    /// The walk of the ray `ray`, `t` in `[tmin, tmax)`, over the majorant segments,
    /// clipped to the medium's region.
    #[inline(always)]
    pub fn walk(&self, ray: &IndexRay, tmin: f32, tmax: f32) -> MediumWalk<'_> {
        match &self.region {
            MediumRegion::Grid => MediumWalk::Cells(self.majorants.walk(ray.o, ray.d, tmin, tmax)),
            MediumRegion::Inside(boundary) => {
                let origin = self.index_to_world.transform_point3(ray.o.as_dvec3());
                let dir = self.index_to_world.transform_vector3(ray.d.as_dvec3());
                if boundary.is_convex() {
                    // One interval: walk only it (an empty walk where there is none).
                    let (a, b) = convex_span(boundary.as_ref(), origin, dir, tmin, tmax)
                        .unwrap_or((tmax, tmax));
                    let cells = self.majorants.walk(ray.o, ray.d, a, b);
                    return match self.constant {
                        true => MediumWalk::Constant(cells),
                        false => MediumWalk::Cells(cells),
                    };
                }
                MediumWalk::Clipped {
                    cells: self.majorants.walk(ray.o, ray.d, tmin, tmax),
                    inside: Inside::new(boundary.as_ref(), origin, dir, tmin, tmax),
                    pending: None,
                    constant: self.constant,
                }
            }
            MediumRegion::Everywhere => {
                let d = self.majorants.max_density();
                MediumWalk::Everywhere((tmin < tmax).then_some(Segment {
                    t0: tmin,
                    t1: tmax,
                    dmin: d,
                    dmax: d,
                }))
            }
        }
    }

    /// The density of a medium that fills all space with one value (world fog), whose
    /// optical depth along any stretch is that value times its length.
    #[inline]
    pub fn everywhere_density(&self) -> Option<f32> {
        match self.region {
            MediumRegion::Everywhere => Some(self.majorants.max_density()),
            _ => None,
        }
    }

    /// Whether the world-space point `p` lies in the medium's region (for a fog box, by
    /// the crossings of the ray from `p` along `dir`: one boundary query). A grid's
    /// region is wherever its density is, so every point is in it.
    pub fn contains(&self, p: DVec3, dir: DVec3) -> bool {
        match &self.region {
            MediumRegion::Inside(boundary) => {
                Inside::new(boundary.as_ref(), p, dir, 0.0, f32::MIN_POSITIVE)
                    .current()
                    .is_some()
            }
            MediumRegion::Grid | MediumRegion::Everywhere => true,
        }
    }

    /// Where a walk of the ray would start (`None` where it would yield nothing): the
    /// entry into the majorant region (a fog box's: its box's, before its surface).
    #[inline]
    pub fn entry(&self, ray: &IndexRay, tmin: f32, tmax: f32) -> Option<f32> {
        match self.region {
            MediumRegion::Everywhere => (tmin < tmax).then_some(tmin),
            _ => self.majorants.entry(ray.o, ray.d, tmin, tmax),
        }
    }

    /// The largest extinction anywhere in the medium (per world unit, the largest of
    /// the channels): the inverse of its shortest mean free path.
    pub fn max_extinction(&self) -> f64 {
        self.majorants.max_density() as f64 * self.sigma.t_max as f64
    }

    /// The optical depth of one voxel at unit density, κ = σt_max × voxel length (the
    /// cube root of a voxel's world volume, for the cost model of
    /// [`MajorantTree::prune`]).
    pub fn optical_per_voxel(&self) -> f32 {
        let voxel_volume = self.world_to_index.inverse().determinant().abs();
        self.sigma.t_max * voxel_volume.cbrt() as f32
    }

    /// Prunes the octree for a tracker: `crossing_lookups` is the cost of a cell
    /// crossing in lookups (0 = keep every level), `residual` whether the tracker pays
    /// for `dmax − dmin` rather than `dmax`. Returns the nodes made terminal.
    pub fn prune_majorants(&mut self, crossing_lookups: f32, residual: bool) -> usize {
        let cost = PruneCost {
            optical_per_voxel: self.optical_per_voxel(),
            crossing_lookups,
            residual,
        };
        // Copies the structure only if an instance shares it (the session prunes one
        // structure per grid and hands it to every instance instead).
        Arc::make_mut(&mut self.majorants).prune(cost)
    }

    /// Rebuilds the majorant structure (e.g. to compare octree depths on one grid).
    pub fn set_majorants(&mut self, spec: MajorantSpec) {
        self.majorants = Arc::new(self.tree(spec));
        self.world_box = self.bounding_box();
    }

    /// The same medium (grids and majorant structure shared, not copied) placed by
    /// another volume transform: an instance of it, named `prim_path`.
    pub fn instance(&self, prim_path: &str, volume_to_world: DMat4) -> Result<Medium, MediumError> {
        let world_to_index = world_to_index(prim_path, "", volume_to_world, &self.density)?;
        Ok(Medium {
            prim_path: prim_path.to_string(),
            density: self.density.clone(),
            world_to_index,
            sigma: self.sigma,
            g: self.g,
            majorants: self.majorants.clone(),
            shader: self.shader.clone(),
            world_box: world_box(&self.majorants, |c| {
                TransformMotion::box_of(&world_to_index.inverse(), c)
            }),
            emission: self
                .emission
                .as_ref()
                .map(|e| e.placed(prim_path, volume_to_world))
                .transpose()?,
            albedo: self
                .albedo
                .as_ref()
                .map(|a| a.placed(prim_path, volume_to_world))
                .transpose()?,
            region: MediumRegion::Grid,
            constant: false,
            index_to_world: world_to_index.inverse(),
            prefetch: self.prefetch,
            motion: None,
            velocity: self.velocity.clone(),
            velocity_reach: self.velocity_reach,
        })
    }

    /// Makes the medium move over the shutter: its volume → world transform follows
    /// `motion` (the medium was built with `at_frame`, the transform at the frame).
    /// Only a grid's region moves: a fog box's surface is in world space.
    pub fn set_motion(&mut self, motion: TransformMotion, at_frame: DMat4) {
        if !matches!(self.region, MediumRegion::Grid) {
            return;
        }
        self.motion = Some(Arc::new(MediumMotion {
            volume_to_world: motion,
            index_from_volume: self.world_to_index * at_frame,
            at_frame,
        }));
        self.world_box = self.bounding_box();
    }

    /// Whether the medium moves (or its fields flow) while the shutter is open.
    pub fn moves(&self) -> bool {
        self.motion.is_some() || self.velocity.is_some()
    }

    /// Advects the medium's fields by `velocity` over the shutter `(open, close)`
    /// (frame-relative time codes) and rebuilds the majorants over the widened region.
    /// Only a grid's density flows (fog has no grid to advect).
    pub fn set_velocity(&mut self, velocity: VelocityGrid, (open, close): (f64, f64)) {
        if !matches!(self.region, MediumRegion::Grid) {
            return;
        }
        self.velocity = Some(Arc::new(velocity));
        self.velocity_reach = open.abs().max(close.abs());
        self.set_majorants(self.majorants.spec());
    }

    /// The world box around the majorant region: where it is, or everywhere it goes
    /// over the shutter.
    fn bounding_box(&self) -> Option<(DVec3, DVec3)> {
        world_box(&self.majorants, |corners| match &self.motion {
            None => TransformMotion::box_of(&self.index_to_world, corners),
            Some(m) => {
                let to_volume = m.index_from_volume.inverse();
                m.volume_to_world
                    .swept_box(&corners.map(|c| to_volume.transform_point3(c)))
            }
        })
    }

    /// Where the world point `p` at frame-relative `time` is at the frame: the point
    /// the medium's world-placed lookups (emission, albedo) take. `p` itself for a
    /// medium that does not move.
    #[inline]
    pub fn at_frame<C: Tally>(&self, p: DVec3, time: f64, counters: &mut C) -> DVec3 {
        let p = match &self.motion {
            None => p,
            Some(m) => (m.at_frame * m.world_to_volume(time)).transform_point3(p),
        };
        let advect = self
            .velocity
            .as_ref()
            .map_or(0.0, |v| time as f32 * v.seconds_per_time_code);
        if advect == 0.0 {
            return p;
        }
        counters.density_lookup(0);
        let i = self.world_to_index.transform_point3(p).as_vec3();
        let moved = self.advected(i, advect);
        self.index_to_world.transform_point3(moved.as_dvec3())
    }

    /// The majorant structure `spec` over this medium's grid, pruned as
    /// [`prune_majorants`](Self::prune_majorants) prunes (`crossing_lookups` 0: not
    /// pruned), without installing it.
    pub fn build_majorants(
        &self,
        spec: MajorantSpec,
        crossing_lookups: f32,
        residual: bool,
    ) -> Arc<MajorantTree> {
        let mut tree = self.tree(spec);
        if matches!(spec, MajorantSpec::Octree { .. }) {
            tree.prune(PruneCost {
                optical_per_voxel: self.optical_per_voxel(),
                crossing_lookups,
                residual,
            });
        }
        Arc::new(tree)
    }

    /// The majorant structure `spec` over the density: the grid's values, or the
    /// shader graph's range over them.
    fn tree(&self, spec: MajorantSpec) -> MajorantTree {
        // Advected by a velocity grid, a cell's density comes from as far as the
        // largest displacement over the shutter: its bounds cover that much more.
        let w = match &self.velocity {
            Some(v) => v.widening(self.velocity_reach * v.seconds_per_time_code as f64),
            None => [0; 3],
        };
        let estimated = AtomicUsize::new(0);
        let mut tree = MajorantTree::build_widened(&self.density, spec, w, &|lo, hi| {
            let lo = [0, 1, 2].map(|a| lo[a].saturating_sub(w[a]));
            let hi = [0, 1, 2].map(|a| hi[a].saturating_add(w[a]));
            match &self.shader {
                None => self.density.value_range(lo, hi),
                Some(s) => {
                    // The range analysis does not read an attribute the graph never
                    // uses (a fog box's noise): no grid range there (8 % of the load of
                    // a stage of such boxes, `perf`).
                    let grid = match s.program.reads_attribute() {
                        true => self.density.value_range(lo, hi),
                        false => (0.0, 0.0),
                    };
                    let [lo, hi] =
                        [lo, hi].map(|v| DVec3::new(v[0] as f64, v[1] as f64, v[2] as f64));
                    let at = |p: Vec3| self.density.sample_trilinear(p.to_array());
                    let (bounds, is_estimate) =
                        graph_density::usable_bounds(s.cell_bounds(lo, hi, grid), || {
                            s.cell_estimate(lo.as_vec3(), hi.as_vec3(), &at)
                        });
                    if is_estimate {
                        estimated.fetch_add(1, Ordering::Relaxed);
                    }
                    bounds
                }
            }
        });
        tree.set_estimated_cells(estimated.into_inner());
        tree
    }

    /// Sends the density through `shader` (its position space placed in this medium's
    /// index space) and rebuilds the majorants `spec` from its range analysis. Fails,
    /// naming the prim and the shader, where the graph cannot be bounded or its bound
    /// overflows once scaled.
    pub fn set_shader(
        &mut self,
        shader: DensityShader,
        spec: MajorantSpec,
    ) -> Result<(), MediumError> {
        let source = shader.source.clone();
        self.shader = Some(Arc::new(shader));
        self.constant = false;
        self.set_majorants(spec);
        if !(self.max_extinction() < f32::MAX as f64) {
            return Err(MediumError::Invalid {
                prim: self.prim_path.clone(),
                message: format!(
                    "the density graph of {source} is infinite where it is looked up (a division by 0 or an overflow at a lookup point), so not even an estimated majorant can be built"
                ),
            });
        }
        Ok(())
    }

    /// Installs `tree` (from [`build_majorants`](Self::build_majorants) on this
    /// medium) and hands back the structure it replaces.
    pub fn replace_majorants(&mut self, tree: Arc<MajorantTree>) -> Arc<MajorantTree> {
        let old = std::mem::replace(&mut self.majorants, tree);
        // World fog has no box: its brick covers only the scene, the fog all space.
        if !matches!(self.region, MediumRegion::Everywhere) {
            self.world_box = self.bounding_box();
        }
        old
    }

    /// Whether the world-space ray `origin + t·dir`, `t` in [`tmin`, `tmax`], may meet
    /// the medium (conservative: a box around its majorant region). Lets a ray race
    /// only the volumes it crosses.
    #[inline]
    pub fn may_meet(&self, origin: DVec3, dir: DVec3, tmin: f64, tmax: f64) -> bool {
        self.span(origin, dir, tmin, tmax).is_some()
    }

    /// The part `[t0, t1]` of `[tmin, tmax]` where the ray `origin + t·dir` may meet
    /// the medium (the world box's slab test; the whole range for a medium that is
    /// everywhere), `None` where it cannot.
    #[inline]
    pub fn span(&self, origin: DVec3, dir: DVec3, tmin: f64, tmax: f64) -> Option<(f64, f64)> {
        let Some((lo, hi)) = self.world_box else {
            let everywhere = matches!(self.region, MediumRegion::Everywhere) && tmin < tmax;
            return everywhere.then_some((tmin, tmax));
        };
        let (mut t0, mut t1) = (tmin, tmax);
        for a in 0..3 {
            let inv = 1.0 / dir[a];
            let (mut ta, mut tb) = ((lo[a] - origin[a]) * inv, (hi[a] - origin[a]) * inv);
            if ta > tb {
                std::mem::swap(&mut ta, &mut tb);
            }
            // A zero direction component gives ±∞ (or NaN exactly on a face, which
            // the comparisons below ignore, keeping the medium: conservative).
            if ta > t0 {
                t0 = ta;
            }
            if tb < t1 {
                t1 = tb;
            }
        }
        (t0 <= t1).then_some((t0, t1))
    }

    /// Makes the medium emissive (or not, with `None`). Emission changes no majorant:
    /// it is looked up only at absorption events.
    pub fn set_emission(&mut self, emission: Option<Emission>) {
        self.emission = emission;
    }

    /// Sets (or with `None` removes) the albedo multiplier grid. It changes no majorant:
    /// extinction is unchanged, and the grid is looked up only at scatter events.
    pub fn set_albedo(&mut self, albedo: Option<Albedo>) {
        self.albedo = albedo;
    }

    /// Maps a world-space ray (any direction length; `t` is measured in units of it)
    /// at the frame.
    pub fn index_ray(&self, origin: DVec3, dir: DVec3) -> IndexRay {
        self.index_ray_with(&self.world_to_index, origin, dir)
    }

    /// Maps a world-space ray at frame-relative `time` (the medium where it is then,
    /// its fields advected to then). A medium that does not move maps it as
    /// [`index_ray`](Self::index_ray) does, with no other work.
    #[inline(always)]
    pub fn index_ray_at(&self, origin: DVec3, dir: DVec3, time: f64) -> IndexRay {
        if self.motion.is_none() && self.velocity.is_none() {
            return self.index_ray_with(&self.world_to_index, origin, dir);
        }
        self.moving_index_ray(origin, dir, time)
    }

    #[inline(never)]
    fn moving_index_ray(&self, origin: DVec3, dir: DVec3, time: f64) -> IndexRay {
        let mut ray = self.index_ray_with(&self.world_to_index_at(time), origin, dir);
        if let Some(v) = &self.velocity {
            ray.advect = time as f32 * v.seconds_per_time_code;
        }
        ray
    }

    /// Where the fields are read for index point `p` on a ray advecting by `advect`
    /// seconds: `p − v(p)·advect` ([`crate::volume::velocity`]). Only rays of a
    /// medium with a velocity grid advect (the trackers test `advect` first, so a still
    /// medium's lookups pay one comparison; `cold` keeps the call out of their loops,
    /// and it takes no counters, which would otherwise have to live in memory there:
    /// the callers count the velocity read).
    #[cold]
    #[inline(never)]
    fn advected(&self, p: Vec3, advect: f32) -> Vec3 {
        match &self.velocity {
            Some(v) => p - v.index_velocity(p) * advect,
            None => p,
        }
    }

    /// [`density`](Self::density) at `t` along `ray` (one density lookup, and one of
    /// the velocity grid on a ray that advects).
    #[inline(always)]
    pub fn density_on<C: Tally>(&self, ray: &IndexRay, t: f32, counters: &mut C) -> f32 {
        let mut p = ray.at(t);
        if ray.advect != 0.0 {
            p = self.advected(p, ray.advect);
            counters.density_lookup(0);
        }
        self.density(p, counters)
    }

    /// [`density_estimate`](Self::density_estimate) at `t` along `ray`.
    #[inline(always)]
    pub fn density_estimate_on<C: Tally>(
        &self,
        ray: &IndexRay,
        t: f32,
        u: u64,
        counters: &mut C,
    ) -> f32 {
        let mut p = ray.at(t);
        if ray.advect != 0.0 {
            p = self.advected(p, ray.advect);
            counters.density_lookup(0);
        }
        self.density_estimate(p, u, counters)
    }

    /// World → index at frame-relative `time`.
    #[inline]
    fn world_to_index_at(&self, time: f64) -> DMat4 {
        match &self.motion {
            None => self.world_to_index,
            Some(m) => m.index_from_volume * m.world_to_volume(time),
        }
    }

    #[inline(always)]
    fn index_ray_with(&self, world_to_index: &DMat4, origin: DVec3, dir: DVec3) -> IndexRay {
        let o = world_to_index.transform_point3(origin);
        let d = world_to_index.transform_vector3(dir);
        IndexRay {
            o: o.as_vec3(),
            d: d.as_vec3(),
            advect: 0.0,
        }
    }

    /// An unbiased one-voxel estimate of [`density`](Self::density) at `p` from the
    /// 63 random bits `u` ([`Grid::sample_stochastic`]); one density lookup. Through a
    /// shader graph it is the exact density: the one-voxel read is unbiased only for
    /// a density linear in the grid's value, and a graph need not be (a clamp, a
    /// product of the field with itself).
    #[inline(always)]
    pub fn density_estimate<C: Tally>(&self, p: Vec3, u: u64, counters: &mut C) -> f32 {
        lookup(counters, || match &self.shader {
            None => self.density.sample_stochastic(p.to_array(), u),
            Some(s) => self.shaded(s, p),
        })
    }

    /// The density through the graph `s` at `p`. A graph that never reads its
    /// attribute (a fog box's noise) gets no grid read: its value does not depend on
    /// it.
    #[inline(always)]
    fn shaded(&self, s: &DensityShader, p: Vec3) -> f32 {
        match s.program.reads_attribute() {
            true => s.density(p, self.density.sample_trilinear(p.to_array())),
            false => s.density(p, 0.0),
        }
    }

    /// [`density`](Self::density) at a world-space point at frame-relative `time`
    /// (one density lookup).
    #[inline]
    pub fn density_at_world<C: Tally>(&self, p: DVec3, time: f64, counters: &mut C) -> f32 {
        let ray = self.index_ray_at(p, DVec3::ZERO, time);
        self.density_on(&ray, 0.0, counters)
    }

    /// Density (already scaled into extinction units by σ) at an index-space point.
    /// Every call is one density lookup.
    #[inline(always)]
    pub fn density<C: Tally>(&self, p: Vec3, counters: &mut C) -> f32 {
        lookup(counters, || match &self.shader {
            None => self.density.sample_trilinear(p.to_array()),
            Some(s) => self.shaded(s, p),
        })
    }
}

/// Voxels per edge of the constant grid: index [0, 7] spans the box, and the trilinear
/// stencil of any point in it reads only stored ones.
pub const CONSTANT_EDGE: i32 = 8;

/// Ones at voxels `0..n` along each axis (whole bricks of ones, so `n` is rounded up to
/// a multiple of 8 stored voxels; the box spans index [0, n − 1]), whose voxel centres
/// 0 and n − 1 lie on the faces of the box at `lo` of size `edge`.
fn constant_grid(
    name: &str,
    lo: DVec3,
    edge: DVec3,
    background: f32,
    n: i32,
) -> Result<Grid, crate::volume::grid::GridError> {
    let n = n.max(2);
    let voxel = edge / (n - 1) as f64;
    let index_to_world = DMat4::from_translation(lo) * DMat4::from_scale(voxel);
    let bricks = (n + 7) / 8;
    let mut leaves = Vec::with_capacity((bricks * bricks * bricks) as usize);
    for x in 0..bricks {
        for y in 0..bricks {
            for z in 0..bricks {
                leaves.push(RawLeaf {
                    origin: [x * 8, y * 8, z * 8],
                    values: vec![1.0; 512],
                    active: [u64::MAX; 8],
                });
            }
        }
    }
    Grid::from_raw(&RawGrid {
        name: name.to_string(),
        class: "fog volume".to_string(),
        background,
        leaves,
        tiles: Vec::new(),
        index_to_world,
    })
}

/// Runs the density lookup `read`, counted (and timed when the counters time).
#[inline(always)]
fn lookup<C: Tally>(counters: &mut C, read: impl FnOnce() -> f32) -> f32 {
    if counters.timing() {
        let t0 = ticks::now();
        let d = read();
        counters.density_lookup(ticks::now() - t0);
        d
    } else {
        counters.density_lookup(0);
        read()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// World fog keeps no box when its majorants are rebuilt (as `auto` does for
    /// homogeneous stages): rays far from the scene still meet it, and with several
    /// media the culling does not leave it out there.
    #[test]
    fn world_fog_has_no_box_after_its_majorants_are_rebuilt() {
        let mut fog = Medium::homogeneous(
            "/fog",
            MediumRegion::Everywhere,
            (DVec3::splat(-1.0), DVec3::splat(1.0)),
            0.1,
            [0.0; 3],
            [1.0; 3],
            0.0,
        )
        .unwrap();
        let far = DVec3::new(0.0, 1e3, 0.0);
        assert_eq!(fog.span(far, DVec3::X, 0.0, 5.0), Some((0.0, 5.0)));
        let tree = fog.build_majorants(MajorantSpec::Uniform { cell_voxels: 0 }, 0.0, false);
        fog.replace_majorants(tree);
        assert_eq!(fog.span(far, DVec3::X, 0.0, 5.0), Some((0.0, 5.0)));
    }

    use crate::volume::convex::ConvexHull;

    /// A boundary that hides that it is convex: its walk takes the general clipped path.
    struct Opaque(ConvexHull);

    impl crate::volume::boundary::Boundary for Opaque {
        fn crossings(
            &self,
            origin: DVec3,
            dir: DVec3,
            tmin: f64,
            out: &mut [crate::volume::boundary::Crossing],
        ) -> (usize, u64) {
            self.0.crossings(origin, dir, tmin, out)
        }
        fn rule(&self) -> crate::volume::boundary::InsideRule {
            self.0.rule()
        }
    }

    /// A convex fog box's walk (the cells over its one interval, [`convex_span`]) hands
    /// out the general clipped walk's segments bit for bit: 20,000 random rays (from
    /// outside and inside, a fifth axis-parallel, random `[tmin, tmax)`) through a
    /// rotated, stretched cube over 16³ majorant cells, the medium constant and not,
    /// its boundary given once as the hull and once hiding that it is convex.
    #[test]
    fn a_convex_walk_is_the_clipped_walk() {
        use crate::volume::boundary::Boundary;
        use rand::{Rng, SeedableRng};
        let (points, triangles) = crate::volume::convex::tests::cube();
        let turn = glam::DQuat::from_euler(glam::EulerRot::XYZ, 0.3, -0.5, 0.9);
        let points: Vec<[f64; 3]> = points
            .iter()
            .map(|p| (turn * (DVec3::from_array(*p) * DVec3::new(1.5, 0.7, 1.0))).to_array())
            .collect();
        let lo = points
            .iter()
            .fold(DVec3::INFINITY, |m, p| m.min(DVec3::from_array(*p)));
        let hi = points
            .iter()
            .fold(DVec3::NEG_INFINITY, |m, p| m.max(DVec3::from_array(*p)));
        let hull = || ConvexHull::from_triangles(&points, &triangles).expect("convex");
        assert!(hull().is_convex() && !Opaque(hull()).is_convex());
        let media = |region: MediumRegion| {
            let coefficients = (1.0, [0.2; 3], [0.7; 3], 0.0);
            let mut m =
                Medium::homogeneous_with("/box", region, (lo, hi), 16, coefficients).unwrap();
            // Cells of 2 voxels: 8 per axis (the box's own majorants are one brick).
            let cells = m.build_majorants(MajorantSpec::Uniform { cell_voxels: 2 }, 0.0, false);
            m.replace_majorants(cells);
            m
        };
        let mut convex = media(MediumRegion::Inside(Arc::new(hull())));
        let mut general = media(MediumRegion::Inside(Arc::new(Opaque(hull()))));
        let mut rng = rand_pcg::Pcg32::seed_from_u64(47);
        let mut segments = 0usize;
        for n in 0..20_000 {
            let constant = n % 2 == 0;
            (convex.constant, general.constant) = (constant, constant);
            let o = DVec3::new(
                rng.gen_range(-3.0..3.0),
                rng.gen_range(-3.0..3.0),
                rng.gen_range(-3.0..3.0),
            );
            // Towards a point of the box's bounds, at random speed.
            let target = lo + (hi - lo) * DVec3::new(rng.gen(), rng.gen(), rng.gen());
            let mut d = (target - o) * rng.gen_range(0.3..3.0);
            if n % 5 == 0 {
                d[n % 3] = 0.0;
            }
            let (tmin, tmax) = (rng.gen_range(0.0..0.5), rng.gen_range(0.5..4.0));
            let walk = |m: &Medium| -> Vec<[u32; 4]> {
                let ray = m.index_ray(o, d);
                m.walk(&ray, tmin, tmax)
                    .map(|s| [s.t0, s.t1, s.dmin, s.dmax].map(f32::to_bits))
                    .collect()
            };
            let (a, b) = (walk(&convex), walk(&general));
            assert_eq!(a, b, "ray {n}: {o} {d} [{tmin}, {tmax})");
            segments += a.len();
        }
        // Most rays meet the box, and over several cells (45,826 segments).
        assert!(segments > 40_000, "{segments} segments");
    }
}
