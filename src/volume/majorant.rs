//! The majorant structure: a min/max hierarchy (an octree stored as a pyramid of grids)
//! over the density grid, each cell holding the minimum and maximum of the
//! *reconstructed* density inside it, and a walk that hands a ray out as segments of
//! constant bounds.
//!
//! Trackers never see the cells, only [`Segment`]s, so the structure is a parameter of
//! the tracking code rather than baked into it.
//!
//! Two shapes, one walk ([`MajorantSpec`]):
//! - `Uniform { cell_voxels }` (`--majorant-cell`): one level of cells of that edge
//!   (0 = one cell for the whole volume, a global majorant). Kept so renders without
//!   `--octree-depth` hand out exactly the segments they always did.
//! - `Octree { depth }` (`--octree-depth`): depth 1 is one cell for the volume, depth d
//!   has 2^(d−1) leaf cells per axis over the volume's bounds (capped at one voxel, and at
//!   [`MAX_LEAF_CELLS`] leaves), with every coarser level of the octree above them.
//!
//! Why a pyramid of dense levels rather than a pointer octree: the leaves are built in
//! parallel straight from the brick pool ([`Grid::value_range`] skips absent bricks in
//! O(1)), every coarser level is a parallel 2×2×2 min/max reduction of the one below (no
//! voxel is read twice), and a node's children are found by index arithmetic, so the
//! walk needs no pointers. Sparsity is in the *walk*: a node is marked terminal when its
//! whole subtree carries its own bounds (empty space, constant regions), so the walk
//! stops descending there and crosses the node in one step. Merging such nodes is
//! lossless: every segment still carries exactly the bounds of the leaf it covers.

use crate::volume::grid::Grid;
use glam::Vec3;
use rayon::prelude::*;
use std::time::Instant;

/// A stretch `[t0, t1)` of a ray over which the density lies in `[dmin, dmax]`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Segment {
    pub t0: f32,
    pub t1: f32,
    pub dmin: f32,
    pub dmax: f32,
}

/// The cost model of [`MajorantTree::prune`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PruneCost {
    /// κ: σt_max times the voxel length (world units), the optical depth of one voxel
    /// at unit density.
    pub optical_per_voxel: f32,
    /// The cost of crossing one cell, in density lookups (0 disables pruning).
    pub crossing_lookups: f32,
    /// The tracker pays for `dmax − dmin` (decomposition, residual ratio tracking)
    /// rather than `dmax`.
    pub residual: bool,
}

/// Which majorant structure to build.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MajorantSpec {
    /// One level of cells with this edge in voxels; 0 = one cell for the whole volume.
    Uniform { cell_voxels: u32 },
    /// An octree of this depth (≥ 1); depth 1 is one cell for the whole volume.
    Octree { depth: u32 },
}

/// Most leaf cells an octree may have (8 bytes of bounds and one flag each: ~300 MB).
/// Past it the leaves are made coarser, so a deep octree over a huge grid degrades to
/// fewer levels instead of exhausting memory.
pub const MAX_LEAF_CELLS: u64 = 1 << 25;

/// Deepest octree accepted: 2^30 cells per axis is beyond any grid's voxel resolution,
/// so deeper requests are capped at the voxel resolution anyway.
pub const MAX_DEPTH: u32 = 31;

/// One level of the pyramid: a dense grid of cells over the region.
#[derive(Clone)]
struct Level {
    /// Cell edge in index units (voxels), per axis.
    edge: Vec3,
    inv_edge: Vec3,
    dims: [i32; 3],
    /// Bricks per axis (see [`Level::index`]).
    bdims: [i32; 3],
    /// (min, max) density per cell, in brick order. The sign bit of the minimum (never
    /// negative otherwise) flags a *terminal* cell — the walk may stop there: every leaf
    /// below it has exactly its bounds (always set on the leaf level). One load gives
    /// the walk both the bounds and the flag.
    bounds: Vec<[f32; 2]>,
}

/// A cell's bounds with its terminal flag packed in (see [`Level::bounds`]).
#[inline(always)]
fn pack(b: [f32; 2], terminal: bool) -> [f32; 2] {
    [if terminal { -b[0] } else { b[0] }, b[1]]
}

#[inline(always)]
fn is_terminal(b: [f32; 2]) -> bool {
    b[0].is_sign_negative()
}

#[inline(always)]
fn unpack(b: [f32; 2]) -> [f32; 2] {
    [b[0].abs(), b[1]]
}

/// Cells are stored in bricks of 4×4×4, bricks x-fastest, cells Morton-ordered inside
/// a brick (each 2×2×2 block is one 64-byte cache line). A ray stepping through a deep
/// level then touches neighbouring memory on every axis, where a row-major layout would
/// jump a whole slab (hundreds of KB) per z step and miss the cache on most steps.
const BRICK_LOG2: i32 = 2;
const BRICK: i32 = 1 << BRICK_LOG2;
/// Bits 0 and 3 of a cell's Morton code inside a brick, from the two low bits of its
/// coordinate.
#[inline(always)]
fn spread(x: usize) -> usize {
    (x & 1) | ((x & 2) << 2)
}

/// Bricks per axis for `dims` cells.
fn brick_dims(dims: [i32; 3]) -> [i32; 3] {
    dims.map(|d| (d + BRICK - 1) >> BRICK_LOG2)
}

impl Level {
    #[inline(always)]
    fn index(&self, c: [i32; 3]) -> usize {
        slot(self.bdims, c)
    }
}

/// The storage slot of cell `c` in a level of `bdims` bricks per axis.
#[inline(always)]
fn slot(bdims: [i32; 3], c: [i32; 3]) -> usize {
    let b = c.map(|x| x >> BRICK_LOG2);
    let brick = ((b[2] * bdims[1] + b[1]) * bdims[0] + b[0]) as usize;
    let m = c.map(|x| spread(x as usize));
    (brick << (3 * BRICK_LOG2)) | m[0] | (m[1] << 1) | (m[2] << 2)
}

impl Level {
    /// The packed bounds of the (up to 8) cells of this level under cell `p` of the
    /// level above.
    fn children(&self, p: [i32; 3]) -> impl Iterator<Item = [f32; 2]> + '_ {
        (0..8).filter_map(move |k| {
            let c = [
                2 * p[0] + (k & 1),
                2 * p[1] + ((k >> 1) & 1),
                2 * p[2] + (k >> 2),
            ];
            (0..3)
                .all(|a| c[a] < self.dims[a])
                .then(|| self.bounds[self.index(c)])
        })
    }
}

/// The row-major (x fastest) index of cell `c` among `dims`.
#[inline(always)]
fn row_major(dims: [i32; 3], c: [i32; 3]) -> usize {
    ((c[2] * dims[1] + c[1]) * dims[0] + c[0]) as usize
}

/// Storage slots of a level of `dims` cells (padded to whole bricks).
fn storage_len(dims: [i32; 3]) -> usize {
    brick_dims(dims)
        .iter()
        .map(|&b| b as usize)
        .product::<usize>()
        << (3 * BRICK_LOG2)
}

/// The cell stored in slot `s` of a level of `dims` cells, or `None` for padding.
fn cell_of(dims: [i32; 3], s: usize) -> Option<[i32; 3]> {
    let bd = brick_dims(dims);
    let brick = (s >> (3 * BRICK_LOG2)) as i32;
    let m = s & ((1 << (3 * BRICK_LOG2)) - 1);
    let local = [
        (m & 1) | ((m >> 2) & 2),
        ((m >> 1) & 1) | ((m >> 3) & 2),
        ((m >> 2) & 1) | ((m >> 4) & 2),
    ];
    let b = [
        brick % bd[0],
        (brick / bd[0]) % bd[1],
        brick / (bd[0] * bd[1]),
    ];
    let c = [0, 1, 2].map(|a| (b[a] << BRICK_LOG2) + local[a] as i32);
    (0..3).all(|a| c[a] < dims[a]).then_some(c)
}

#[derive(Clone)]
pub struct MajorantTree {
    /// Continuous index-space corner of cell (0,0,0) on every level.
    origin: Vec3,
    /// Finest (leaf) level first, root last.
    levels: Vec<Level>,
    /// A one-level structure's bounds again, row-major (x fastest): the flat walk steps
    /// through them by adding a stride, where the brick order needs the cell's slot
    /// recomputed. Empty for a hierarchy.
    flat_bounds: Vec<[f32; 2]>,
    /// The continuous index-space box the leaves cover ([`MajorantTree::index_region`]),
    /// kept for the slab test every walk starts with.
    region: Option<(Vec3, Vec3)>,
    spec: MajorantSpec,
    /// See [`MajorantTree::margin`].
    margin: f32,
    build_seconds: f64,
    /// See [`MajorantTree::estimated_cells`].
    estimated_cells: usize,
}

impl MajorantTree {
    /// Builds the structure over `grid`'s active region. Octree leaves take the min/max
    /// over the exact support of the trilinear reconstruction in the cell (voxels
    /// `a..=b` of the closed cell `[a, b]`), widened by a margin δ for rounding; flat-grid
    /// cells keep the historical one-voxel dilation on each side. Coarser levels are
    /// unions of their children, so they bound the reconstruction too.
    pub fn build(grid: &Grid, spec: MajorantSpec) -> MajorantTree {
        Self::build_bounded(grid, spec, &|lo, hi| grid.value_range(lo, hi))
    }

    /// [`build`](Self::build) with each leaf's bounds from `bound(vlo, vhi)`, the
    /// density's (min, max) over the voxels `vlo..=vhi` (whose box holds the cell): a
    /// shader graph's range analysis over the grid's range there
    /// ([`crate::volume::graph_density`]).
    pub fn build_bounded(
        grid: &Grid,
        spec: MajorantSpec,
        bound: &(dyn Fn([i32; 3], [i32; 3]) -> (f32, f32) + Sync),
    ) -> MajorantTree {
        Self::build_widened(grid, spec, [0; 3], bound)
    }

    /// [`build_bounded`](Self::build_bounded) over the grid's region widened by `widen`
    /// voxels on each side per axis: where a field advected by a velocity grid can
    /// carry density ([`crate::volume::velocity`]; `bound` then widens each cell's
    /// voxel range by as much).
    pub fn build_widened(
        grid: &Grid,
        spec: MajorantSpec,
        widen: [i32; 3],
        bound: &(dyn Fn([i32; 3], [i32; 3]) -> (f32, f32) + Sync),
    ) -> MajorantTree {
        let start = Instant::now();
        let Some((lo, hi)) = grid.index_bounds else {
            return MajorantTree {
                origin: Vec3::ZERO,
                levels: Vec::new(),
                flat_bounds: Vec::new(),
                region: None,
                spec,
                margin: 0.0,
                build_seconds: start.elapsed().as_secs_f64(),
                estimated_cells: 0,
            };
        };
        // The region where the field can differ from the background: the active voxel
        // centres, widened by one voxel (where interpolation falls off to background).
        let rlo = [0, 1, 2].map(|a| lo[a].saturating_sub(1 + widen[a]));
        let rhi = [0, 1, 2].map(|a| hi[a].saturating_add(1 + widen[a]));
        let extent = [0, 1, 2].map(|a| (rhi[a] as i64 - rlo[a] as i64).max(1));
        let (leaf_edge, hierarchical) = match spec {
            MajorantSpec::Uniform { cell_voxels: 0 } => (extent, false),
            MajorantSpec::Uniform { cell_voxels } => ([cell_voxels as i64; 3], false),
            MajorantSpec::Octree { depth } => {
                let n = 1i64 << (depth.clamp(1, MAX_DEPTH) - 1);
                let mut edge = extent.map(|e| ((e + n - 1) / n).max(1));
                while cells(extent, edge) > MAX_LEAF_CELLS {
                    edge = edge.map(|e| e * 2);
                }
                (edge, true)
            }
        };
        let dims = [0, 1, 2].map(|a| ((extent[a] + leaf_edge[a] - 1) / leaf_edge[a]).max(1) as i32);
        // Voxels read beyond a leaf's own support. The exact support of the trilinear
        // reconstruction over the closed cell [a, b] is voxels a..=b; the flat grid keeps
        // its historical extra voxel on each side (identical renders), the octree takes
        // the exact support and covers rounding with the margin `delta` below instead —
        // at one-voxel leaves that is 2³ voxels per bound instead of 4³.
        let pad = if hierarchical { 0 } else { 1 };
        let bounds: Vec<[f32; 2]> = (0..storage_len(dims))
            .into_par_iter()
            .map(|s| {
                let Some(c) = cell_of(dims, s) else {
                    return [0.0; 2];
                };
                let c = c.map(|x| x as i64);
                let vlo = [0, 1, 2].map(|a| (rlo[a] as i64 + c[a] * leaf_edge[a] - pad) as i32);
                let vhi = [0, 1, 2].map(|a| {
                    (rlo[a] as i64 + (c[a] + 1) * leaf_edge[a] + pad).min(i32::MAX as i64) as i32
                });
                let (mn, mx) = bound(vlo, vhi);
                [mn, mx]
            })
            .collect();
        let mut bounds = bounds;
        let mut margin = 0.0;
        if hierarchical {
            // Trilinear reconstruction changes by at most (largest voxel difference ≤
            // global max) per voxel moved along an axis, so bounds widened by
            // δ = 2⁻¹⁰·max hold for points within an L1 distance of 2⁻¹⁰ voxels of the
            // cell: enough for f32 rounding of `o + t·d` (index coordinates up to a few
            // thousand) and for the walk's 1e-4-voxel slivers. Empty leaves stay exactly
            // empty, so they still cost no lookup.
            margin = bounds.iter().fold(0f32, |m, b| m.max(b[1])) * (1.0 / 1024.0);
            let delta = margin;
            bounds.par_iter_mut().for_each(|b| {
                if b[1] > 0.0 {
                    *b = [(b[0] - delta).max(0.0), b[1] + delta];
                }
            });
        }
        let edge = Vec3::new(
            leaf_edge[0] as f32,
            leaf_edge[1] as f32,
            leaf_edge[2] as f32,
        );
        bounds.par_iter_mut().for_each(|b| *b = pack(*b, true));
        let mut levels = vec![Level {
            edge,
            inv_edge: edge.recip(),
            dims,
            bdims: brick_dims(dims),
            bounds,
        }];
        while hierarchical && levels.last().is_some_and(|l| l.dims != [1, 1, 1]) {
            let parent = reduce(levels.last().expect("non-empty"));
            levels.push(parent);
        }
        let flat_bounds = match &levels[..] {
            [leaf] => {
                let n = dims.iter().map(|&d| d as usize).product();
                let mut rows = vec![[0f32; 2]; n];
                for (s, b) in leaf.bounds.iter().enumerate() {
                    if let Some(c) = cell_of(dims, s) {
                        rows[row_major(dims, c)] = *b;
                    }
                }
                rows
            }
            _ => Vec::new(),
        };
        let origin = Vec3::new(rlo[0] as f32, rlo[1] as f32, rlo[2] as f32);
        let d = Vec3::new(dims[0] as f32, dims[1] as f32, dims[2] as f32);
        MajorantTree {
            origin,
            levels,
            flat_bounds,
            region: Some((origin, origin + d * edge)),
            spec,
            margin,
            build_seconds: start.elapsed().as_secs_f64(),
            estimated_cells: 0,
        }
    }

    /// Stops the walk higher up wherever finer cells would cost more traversal than
    /// they save in lookups (a cost model, applied bottom-up after [`build`](Self::build)).
    /// Along a unit of ray length in index space, a cell of edge e costs about
    /// `1.5/e` cell crossings (the mean L1 length of a unit direction) and
    /// `κ·w` lookups, where κ = σt_max × voxel length is the optical depth of one voxel at
    /// unit density and w the density bound the tracker pays for (`dmax` for delta-type
    /// trackers, `dmax − dmin` for residual ones). A node whose children are all
    /// terminal becomes terminal when
    /// `κ·(w_node − mean w_child) ≤ c·1.5/(2e_child)`, c being the cost of a cell crossing
    /// in lookups. Merging keeps every bound valid (a node's bounds contain its
    /// children's), so only cost changes, never the estimate. Returns the number of
    /// nodes made terminal.
    pub fn prune(&mut self, cost: PruneCost) -> usize {
        if !(cost.crossing_lookups > 0.0 && cost.optical_per_voxel > 0.0) {
            return 0;
        }
        let mut merged = 0;
        for k in 1..self.levels.len() {
            let (lower, upper) = self.levels.split_at_mut(k);
            let child = &lower[k - 1];
            let parent = &mut upper[0];
            let e = (child.edge.x + child.edge.y + child.edge.z) / 3.0;
            let threshold = cost.crossing_lookups * 0.75 / e / cost.optical_per_voxel;
            let dims = parent.dims;
            merged += parent
                .bounds
                .par_iter_mut()
                .enumerate()
                .map(|(s, b)| {
                    if is_terminal(*b) {
                        return 0;
                    }
                    let Some(p) = cell_of(dims, s) else {
                        return 0;
                    };
                    let w = |b: [f32; 2]| if cost.residual { b[1] - b[0] } else { b[1] };
                    let (mut sum, mut n) = (0.0f32, 0);
                    for cb in child.children(p) {
                        if !is_terminal(cb) {
                            return 0;
                        }
                        sum += w(unpack(cb));
                        n += 1;
                    }
                    if w(unpack(*b)) - sum / n as f32 <= threshold {
                        *b = pack(unpack(*b), true);
                        1
                    } else {
                        0
                    }
                })
                .sum::<usize>();
        }
        merged
    }

    /// The rounding margin δ added to every non-empty octree leaf's bounds (0 for the
    /// flat grid).
    pub fn margin(&self) -> f32 {
        self.margin
    }

    pub fn spec(&self) -> MajorantSpec {
        self.spec
    }

    /// Number of leaf cells.
    pub fn cell_count(&self) -> usize {
        self.levels
            .first()
            .map_or(0, |l| l.dims.iter().map(|&d| d as usize).product())
    }

    /// Leaf cells per axis.
    pub fn dims(&self) -> [i32; 3] {
        self.levels.first().map_or([0; 3], |l| l.dims)
    }

    /// Leaf cell edge in voxels, per axis.
    pub fn leaf_edge(&self) -> [f32; 3] {
        self.levels.first().map_or([0.0; 3], |l| l.edge.to_array())
    }

    /// Levels of the hierarchy (1 for a flat grid): the effective octree depth.
    pub fn levels(&self) -> usize {
        self.levels.len()
    }

    /// Wall time of [`MajorantTree::build`].
    pub fn build_seconds(&self) -> f64 {
        self.build_seconds
    }

    /// Leaf cells whose majorant is an estimate, not a bound (a density graph with no
    /// usable bound there, [`crate::volume::graph_density`]): 0 unless the trackers
    /// must tolerate a density above the majorant.
    pub fn estimated_cells(&self) -> usize {
        self.estimated_cells
    }

    /// Records [`estimated_cells`](Self::estimated_cells) (set by the builder's caller,
    /// which made the estimates).
    pub fn set_estimated_cells(&mut self, n: usize) {
        self.estimated_cells = n;
    }

    /// Bytes held by the bounds and flags of every level (and the flat walk's copy).
    pub fn memory_bytes(&self) -> usize {
        let cells: usize = self.levels.iter().map(|l| l.bounds.len()).sum();
        (cells + self.flat_bounds.len()) * std::mem::size_of::<[f32; 2]>()
    }

    /// Largest density anywhere (the global majorant).
    pub fn max_density(&self) -> f32 {
        self.levels
            .last()
            .map_or(0.0, |l| l.bounds.iter().fold(0f32, |m, b| m.max(b[1])))
    }

    /// Continuous index-space box covered by the leaves.
    pub fn index_region(&self) -> Option<(Vec3, Vec3)> {
        self.region
    }

    /// Fraction of the leaf cells whose maximum is 0 (crossed without any lookup).
    pub fn empty_leaf_fraction(&self) -> f64 {
        let Some(l) = self.levels.first() else {
            return 1.0;
        };
        let (mut empty, mut cells) = (0u64, 0u64);
        for (s, b) in l.bounds.iter().enumerate() {
            if cell_of(l.dims, s).is_some() {
                cells += 1;
                empty += (b[1] == 0.0) as u64;
            }
        }
        empty as f64 / cells.max(1) as f64
    }

    /// Bounds of leaf cell `c` (for tests and tools).
    pub fn leaf_bounds(&self, c: [i32; 3]) -> Option<(f32, f32)> {
        let l = self.levels.first()?;
        if (0..3).any(|a| c[a] < 0 || c[a] >= l.dims[a]) {
            return None;
        }
        let b = unpack(l.bounds[l.index(c)]);
        Some((b[0], b[1]))
    }

    /// Continuous index-space box of leaf cell `c` (not clamped to the region).
    pub fn leaf_box(&self, c: [i32; 3]) -> Option<(Vec3, Vec3)> {
        let l = self.levels.first()?;
        let lo = self.origin + Vec3::new(c[0] as f32, c[1] as f32, c[2] as f32) * l.edge;
        Some((lo, lo + l.edge))
    }

    /// The leaf cell containing the index-space point `p`, if it lies in the region.
    pub fn leaf_at(&self, p: Vec3) -> Option<[i32; 3]> {
        let l = self.levels.first()?;
        let rel = (p - self.origin) * l.inv_edge;
        let c = [0, 1, 2].map(|a| rel[a].floor());
        (0..3)
            .all(|a| c[a] >= 0.0 && c[a] < l.dims[a] as f32)
            .then(|| c.map(|x| x as i32))
    }

    /// Starts a walk along `o + t·d` for `t` in `[tmin, tmax)`.
    pub fn walk(&self, o: Vec3, d: Vec3, tmin: f32, tmax: f32) -> TreeWalk<'_> {
        TreeWalk::new(self, o, d, tmin, tmax)
    }

    /// Where a walk of the ray would start: the `t0` of its first segment, without
    /// setting the walk up (`None` where it would yield none).
    #[inline]
    pub fn entry(&self, o: Vec3, d: Vec3, tmin: f32, tmax: f32) -> Option<f32> {
        let inv_d = d.recip().to_array();
        self.span(o.to_array(), d.to_array(), inv_d, tmin, tmax)
            .map(|(t0, _)| t0)
    }

    /// The part `[t0, t1)` of `[tmin, tmax)` where the ray lies in the region: what a
    /// walk covers ([`TreeWalk::new`] and [`Self::entry`] both take it from here).
    #[inline(always)]
    fn span(
        &self,
        o: [f32; 3],
        d: [f32; 3],
        inv_d: [f32; 3],
        tmin: f32,
        tmax: f32,
    ) -> Option<(f32, f32)> {
        let (lo, hi) = self.region?;
        clip(lo.to_array(), hi.to_array(), o, d, inv_d, tmin, tmax)
    }
}

fn cells(extent: [i64; 3], edge: [i64; 3]) -> u64 {
    (0..3)
        .map(|a| ((extent[a] + edge[a] - 1) / edge[a]).max(1) as u64)
        .product()
}

/// The parent level of `child`: each cell the min/max of its (up to) 2×2×2 children,
/// terminal when every child is terminal with the same bounds (nothing is lost by
/// stopping there).
fn reduce(child: &Level) -> Level {
    let dims = child.dims.map(|d| (d + 1) / 2);
    let bounds: Vec<[f32; 2]> = (0..storage_len(dims))
        .into_par_iter()
        .map(|s| {
            let Some(p) = cell_of(dims, s) else {
                return pack([0.0; 2], true);
            };
            let mut b = [f32::INFINITY, f32::NEG_INFINITY];
            let mut kids = [[0f32; 2]; 8];
            let mut nk = 0;
            let mut all_terminal = true;
            for packed in child.children(p) {
                let cb = unpack(packed);
                b[0] = b[0].min(cb[0]);
                b[1] = b[1].max(cb[1]);
                all_terminal &= is_terminal(packed);
                kids[nk] = cb;
                nk += 1;
            }
            let uniform = kids[..nk].iter().all(|k| *k == b);
            pack(b, all_terminal && uniform)
        })
        .collect();
    let edge = child.edge * 2.0;
    Level {
        edge,
        inv_edge: edge.recip(),
        dims,
        bdims: brick_dims(dims),
        bounds,
    }
}

/// Walks a ray through the hierarchy, yielding one segment per terminal node in order
/// along the ray: a hierarchical DDA (as in NanoVDB's HDDA or pbrt-v4's majorant grid,
/// with levels). Within a level it steps from cell to neighbouring cell, recomputing
/// only the crossed axis' exit; when it crosses into another parent whose subtree is
/// uniform (terminal) it climbs to the parent and crosses it in one step, and when it
/// enters a non-terminal cell it descends, locating the entry point level by level.
/// Restartable: callers keep their own `t` and move on to the next segment.
///
/// A flat grid (one level, every cell terminal) takes a short path through the same
/// arithmetic: no climbing or descending, the cells in row-major order so that a step
/// adds a stride to the index, the level's data held in the walk instead of behind the
/// tree's pointers, and the crossed axis picked without a branch. It is inlined into
/// the trackers' loops; the general walk is not. Its segments are the general walk's,
/// bit for bit (`flat_walk_is_the_general_walk`).
///
/// A point computed exactly on a face can round into the node behind it (its exit is
/// then not ahead of the point); the walk then locates the point 1e-4 voxels further on
/// and hands out that node from the face: the sliver lies within 1e-4 voxels of the
/// node, where its bounds still hold (octree bounds hold within 2⁻¹⁰ voxels of a cell,
/// flat-grid bounds within one voxel, see [`MajorantTree::build`]).
pub struct TreeWalk<'a> {
    tree: &'a MajorantTree,
    /// The flat path's data, copied out of the tree once per walk: the row-major
    /// bounds (empty for a hierarchy: take the general path), cells per axis, cell
    /// edge, and the index step of a move along each axis.
    flat_bounds: &'a [[f32; 2]],
    flat_dims: [i32; 3],
    flat_edge: [f32; 3],
    flat_stride: [isize; 3],
    // Arrays, not `Vec3`s: the walk indexes them by the axis it crosses, a run-time
    // value, and `Vec3` indexing is a match.
    origin: [f32; 3],
    o: [f32; 3],
    d: [f32; 3],
    inv_d: [f32; 3],
    /// +1 or −1 per axis: the direction the walk steps cells in.
    step: [i32; 3],
    /// Smallest step in `t` when rounding stalls the walk (1e-4 voxels along the ray).
    min_step: f32,
    t: f32,
    t_end: f32,
    /// The current node: its level, cell and index, and where the ray crosses its far
    /// face on each axis.
    level: usize,
    cell: [i32; 3],
    idx: usize,
    t_face: [f32; 3],
    /// The node at `t` must be located (descending from `level`) before the next step.
    relocate: bool,
}

impl<'a> TreeWalk<'a> {
    fn new(tree: &'a MajorantTree, o: Vec3, d: Vec3, tmin: f32, tmax: f32) -> TreeWalk<'a> {
        let min_step = 1e-4 / d.abs().max_element();
        let inv_d = d.recip().to_array();
        let (o, d) = (o.to_array(), d.to_array());
        let step = d.map(|x| if x < 0.0 { -1 } else { 1 });
        let (flat_dims, flat_edge) = match &tree.levels[..] {
            [leaf] => (leaf.dims, leaf.edge.to_array()),
            _ => ([0; 3], [1.0; 3]),
        };
        let row = [
            1,
            flat_dims[0] as isize,
            (flat_dims[0] * flat_dims[1]) as isize,
        ];
        let mut walk = TreeWalk {
            tree,
            flat_bounds: &tree.flat_bounds,
            flat_dims,
            flat_edge,
            flat_stride: [0, 1, 2].map(|a| row[a] * step[a] as isize),
            origin: tree.origin.to_array(),
            o,
            d,
            inv_d,
            step,
            min_step,
            t: 0.0,
            t_end: -1.0,
            level: tree.levels.len().saturating_sub(1),
            cell: [0; 3],
            idx: 0,
            t_face: [f32::INFINITY; 3],
            relocate: true,
        };
        if let Some((t0, t1)) = tree.span(o, d, inv_d, tmin, tmax) {
            walk.t = t0;
            walk.t_end = t1;
        }
        walk
    }
}

/// The part `[t0, t1)` of `[tmin, tmax)` where the ray `o + t·d` lies in the box
/// `[lo, hi)` (a slab test), if any.
#[inline(always)]
fn clip(
    lo: [f32; 3],
    hi: [f32; 3],
    o: [f32; 3],
    d: [f32; 3],
    inv_d: [f32; 3],
    tmin: f32,
    tmax: f32,
) -> Option<(f32, f32)> {
    let (mut t0, mut t1) = (tmin, tmax);
    for a in 0..3 {
        if d[a] == 0.0 {
            if !(o[a] >= lo[a] && o[a] < hi[a]) {
                return None;
            }
            continue;
        }
        let (mut ta, mut tb) = ((lo[a] - o[a]) * inv_d[a], (hi[a] - o[a]) * inv_d[a]);
        if ta > tb {
            std::mem::swap(&mut ta, &mut tb);
        }
        t0 = t0.max(ta);
        t1 = t1.min(tb);
    }
    (t0 < t1).then_some((t0, t1))
}

impl Iterator for TreeWalk<'_> {
    type Item = Segment;

    #[inline(always)]
    fn next(&mut self) -> Option<Segment> {
        if self.flat_bounds.is_empty() {
            self.next_general()
        } else {
            self.next_on(true)
        }
    }
}

/// The cell of level `l` holding the point `rel` (index space, relative to the
/// region's corner) for a ray stepping cells in directions `step`: on a face, the cell
/// the ray is entering; x ≥ 0 inside the region, and a negative x from rounding
/// clamps to cell 0 (as one beyond the far side clamps to the last cell).
#[inline(always)]
fn cell_at(l: &Level, rel: [f32; 3], step: [i32; 3]) -> [i32; 3] {
    let inv_edge = l.inv_edge.to_array();
    let axis = |a: usize| {
        let x = rel[a] * inv_edge[a];
        let mut i = x as i32;
        if step[a] < 0 && i as f32 == x {
            i -= 1;
        }
        i.clamp(0, l.dims[a] - 1)
    };
    // Written out: `std::array::from_fn` here was left an outlined call in the
    // trackers' walks (1.4 % of a cloud render's samples, `perf`).
    [axis(0), axis(1), axis(2)]
}

#[inline(always)]
fn segment(t0: f32, t1: f32, b: [f32; 2]) -> Segment {
    let b = unpack(b);
    Segment {
        t0,
        t1,
        dmin: b[0],
        dmax: b[1],
    }
}

impl TreeWalk<'_> {
    /// The next segment of a hierarchy.
    #[inline(never)]
    fn next_general(&mut self) -> Option<Segment> {
        self.next_on(false)
    }

    /// The next segment, on the flat path or the general one (`flat` is a constant at
    /// each call, so each path compiles to its own straight-line code).
    #[inline(always)]
    fn next_on(&mut self, flat: bool) -> Option<Segment> {
        if !(self.t < self.t_end) {
            return None;
        }
        let t0 = self.t;
        if self.relocate {
            if flat {
                self.locate_flat(t0);
            } else {
                self.locate(t0);
            }
        }
        let t1 = self.exit();
        if !(t1 > t0) {
            return Some(self.sliver(t0));
        }
        self.t = t1;
        let b = if flat {
            self.flat_bounds[self.idx]
        } else {
            self.tree.levels[self.level].bounds[self.idx]
        };
        if flat {
            self.advance_flat();
        } else {
            self.advance();
        }
        Some(segment(t0, t1, b))
    }

    /// Where the ray leaves the current node (clipped to the walk's end).
    #[inline(always)]
    fn exit(&self) -> f32 {
        self.t_face[0]
            .min(self.t_face[1])
            .min(self.t_face[2])
            .min(self.t_end)
    }

    /// Rounding put the point at `t0` behind the face it just crossed: hands out the
    /// node a sliver further on instead (see the type's doc), and locates afresh after
    /// it.
    #[cold]
    fn sliver(&mut self, t0: f32) -> Segment {
        let t = (t0 + self.min_step).max(t0.next_up());
        self.locate(t);
        let mut t1 = self.exit();
        if !(t1 > t0) {
            t1 = t.min(self.t_end);
        }
        self.t = t1;
        self.relocate = true;
        segment(t0, t1, self.tree.levels[self.level].bounds[self.idx])
    }

    /// The index-space point at `t` relative to the region's corner.
    #[inline(always)]
    fn point(&self, t: f32) -> [f32; 3] {
        std::array::from_fn(|a| self.o[a] + self.d[a] * t - self.origin[a])
    }

    /// Where the ray crosses the far face of cell `c` on axis `a`, cells of edge `edge`.
    #[inline(always)]
    fn face(&self, edge: f32, c: i32, a: usize) -> f32 {
        if self.d[a] == 0.0 {
            return f32::INFINITY;
        }
        let side = (self.step[a] > 0) as i32;
        let face = self.origin[a] + (c + side) as f32 * edge;
        (face - self.o[a]) * self.inv_d[a]
    }

    /// The axis whose far face the ray reaches first (x before y before z on ties).
    #[inline(always)]
    fn exit_axis(&self) -> usize {
        let f = self.t_face;
        // Branch-free: which axis a ray leaves by is a coin toss the predictor loses.
        let not_x = !(f[0] <= f[1] && f[0] <= f[2]) as usize;
        not_x * (1 + !(f[1] <= f[2]) as usize)
    }

    /// Makes the first terminal node containing the point at `t`, at or below the
    /// current level, the current node.
    #[inline(always)]
    fn locate(&mut self, t: f32) {
        let tree = self.tree;
        let rel = self.point(t);
        // The leaf cell once; the cell of level k is it shifted right by k, the cell
        // `cell_at` would compute on that level (`cell_at_level_is_the_leaf_cell_shifted`):
        // edges double from level to level, so x scales by exact powers of two.
        let leaf = cell_at(&tree.levels[0], rel, self.step);
        let mut k = self.level.min(tree.levels.len() - 1);
        loop {
            let l = &tree.levels[k];
            let c = leaf.map(|x| x >> k);
            let idx = l.index(c);
            if k == 0 || is_terminal(l.bounds[idx]) {
                self.level = k;
                self.cell = c;
                self.idx = idx;
                let edge = l.edge.to_array();
                self.t_face = [0, 1, 2].map(|a| self.face(edge[a], c[a], a));
                self.relocate = false;
                return;
            }
            k -= 1;
        }
    }

    /// [`locate`](Self::locate) on a flat grid: the same cell, its row-major index.
    #[inline(always)]
    fn locate_flat(&mut self, t: f32) {
        let rel = self.point(t);
        let c = cell_at(&self.tree.levels[0], rel, self.step);
        self.cell = c;
        self.idx = row_major(self.flat_dims, c);
        // Written out, as in `cell_at`: `[0, 1, 2].map` stayed an outlined call.
        self.t_face = [
            self.face(self.flat_edge[0], c[0], 0),
            self.face(self.flat_edge[1], c[1], 1),
            self.face(self.flat_edge[2], c[2], 2),
        ];
        self.relocate = false;
    }

    /// [`advance`](Self::advance) on a flat grid: the next cell of the one level.
    #[inline(always)]
    fn advance_flat(&mut self) {
        let a = self.exit_axis();
        let new = self.cell[a] + self.step[a];
        if new as u32 >= self.flat_dims[a] as u32 {
            // Out of the region: the walk is over (up to rounding of the slab test).
            self.t = self.t_end;
            return;
        }
        self.cell[a] = new;
        self.idx = self.idx.wrapping_add_signed(self.flat_stride[a]);
        self.t_face[a] = self.face(self.flat_edge[a], new, a);
    }

    /// Moves to the node after the current one, through the face the ray leaves by.
    #[inline(always)]
    fn advance(&mut self) {
        let tree = self.tree;
        let k = self.level;
        let l = &tree.levels[k];
        let a = self.exit_axis();
        let old = self.cell[a];
        let new = old + self.step[a];
        if new < 0 || new >= l.dims[a] {
            // Out of the region: the walk is over (up to rounding of the slab test).
            self.t = self.t_end;
            return;
        }
        self.cell[a] = new;
        if k + 1 < tree.levels.len() && (new >> 1) != (old >> 1) {
            // Into another parent: climb if its subtree is uniform.
            let p = &tree.levels[k + 1];
            let pc = self.cell.map(|c| c >> 1);
            let pidx = p.index(pc);
            if is_terminal(p.bounds[pidx]) {
                self.level = k + 1;
                self.cell = pc;
                self.idx = pidx;
                let edge = p.edge.to_array();
                self.t_face = [0, 1, 2].map(|a| self.face(edge[a], pc[a], a));
                return;
            }
        }
        self.idx = l.index(self.cell);
        self.t_face[a] = self.face(l.edge.to_array()[a], new, a);
        if !is_terminal(l.bounds[self.idx]) {
            self.relocate = true;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::volume::grid::Grid;
    use crate::volume::procedural::grid_from_fn;
    use glam::DVec3;
    use rand::{Rng, SeedableRng};

    /// The flat path hands out the general walk's segments bit for bit: 20,000 random
    /// rays (axis-parallel ones and ones starting inside included) through flat grids
    /// of 1-, 3- and 8-voxel cells over a sparse blob, each walked twice, once with the
    /// flat path switched off; [`MajorantTree::entry`] is the first segment's start.
    #[test]
    fn flat_walk_is_the_general_walk() {
        let raw = grid_from_fn("density", [37, 29, 41], DVec3::ZERO, 1.0, |p| {
            let r = (p - DVec3::new(18.0, 14.0, 20.0)).length();
            (1.0 - r / 14.0).max(0.0) * (1.0 + (p.x * 0.7).sin() * 0.5)
        });
        let grid = Grid::from_raw(&raw).unwrap();
        let mut rng = rand_pcg::Pcg32::seed_from_u64(3);
        let mut segments = 0usize;
        for cell_voxels in [1, 3, 8] {
            let tree = MajorantTree::build(&grid, MajorantSpec::Uniform { cell_voxels });
            assert_eq!(tree.levels(), 1);
            for n in 0..20_000 / 3 {
                let o = Vec3::new(
                    rng.gen_range(-10.0..50.0),
                    rng.gen_range(-10.0..40.0),
                    rng.gen_range(-10.0..50.0),
                );
                let mut d = Vec3::new(
                    rng.gen_range(-1.0..1.0),
                    rng.gen_range(-1.0..1.0),
                    rng.gen_range(-1.0..1.0),
                );
                if n % 5 == 0 {
                    d[n % 3] = 0.0;
                }
                let (tmin, tmax) = (rng.gen_range(0.0..5.0), rng.gen_range(5.0..200.0));
                let fast: Vec<Segment> = tree.walk(o, d, tmin, tmax).collect();
                let entry = tree.entry(o, d, tmin, tmax).map(f32::to_bits);
                assert_eq!(
                    entry,
                    fast.first().map(|s| s.t0.to_bits()),
                    "entry, ray {n}"
                );
                let mut general = tree.walk(o, d, tmin, tmax);
                assert!(!general.flat_bounds.is_empty());
                general.flat_bounds = &[];
                let general: Vec<Segment> = general.collect();
                assert_eq!(fast.len(), general.len(), "ray {n}: {o} {d}");
                for (a, b) in fast.iter().zip(&general) {
                    let bits = |s: &Segment| [s.t0, s.t1, s.dmin, s.dmax].map(f32::to_bits);
                    assert_eq!(bits(a), bits(b), "ray {n}: {o} {d}");
                }
                segments += fast.len();
            }
        }
        assert!(
            segments > 40_000,
            "{segments} segments: the rays must cross the grid"
        );
    }

    /// The walk locates a point's cell on every level by shifting its leaf cell:
    /// the same cell as computing it on that level, for 200,000 points (on faces,
    /// beyond the region and at tiny negative offsets included) in octrees of odd and
    /// even leaf counts, both stepping directions.
    #[test]
    fn cell_at_level_is_the_leaf_cell_shifted() {
        let mut rng = rand_pcg::Pcg32::seed_from_u64(5);
        for dims in [[37, 29, 41], [13, 64, 5], [300, 3, 77]] {
            let raw = grid_from_fn("density", dims, DVec3::ZERO, 1.0, |p| {
                0.1 + (p.x * 0.3).sin().abs() * (p.y * 0.2).cos().abs()
            });
            let grid = Grid::from_raw(&raw).unwrap();
            let tree = MajorantTree::build(&grid, MajorantSpec::Octree { depth: 8 });
            assert!(tree.levels() >= 5, "{} levels", tree.levels());
            let (lo, hi) = tree.index_region().unwrap();
            let edge = tree.leaf_edge();
            for n in 0..200_000 / 3 {
                let mut rel = Vec3::new(
                    rng.gen_range(-2.0..(hi.x - lo.x) + 2.0),
                    rng.gen_range(-2.0..(hi.y - lo.y) + 2.0),
                    rng.gen_range(-2.0..(hi.z - lo.z) + 2.0),
                );
                // Onto faces of the cells of some level, and tiny negative offsets.
                for a in 0..3 {
                    let e = edge[a] * (1 << rng.gen_range(0..4)) as f32;
                    match rng.gen_range(0..6) {
                        0 => rel[a] = (rel[a] / e).round() * e,
                        1 => rel[a] = -rng.gen::<f32>() * 1e-6,
                        _ => {}
                    }
                }
                let step = [0, 1, 2].map(|_| if rng.gen::<bool>() { 1 } else { -1 });
                let leaf = cell_at(&tree.levels[0], rel.to_array(), step);
                for (k, l) in tree.levels.iter().enumerate() {
                    let shifted = leaf.map(|x| x >> k);
                    let at_level = cell_at(l, rel.to_array(), step);
                    assert_eq!(shifted, at_level, "point {n} {rel} level {k}");
                }
            }
        }
    }

    /// The brick layout is a bijection between the cells and the non-padding slots.
    #[test]
    fn brick_layout_is_a_bijection() {
        for dims in [[1, 1, 1], [5, 3, 9], [8, 8, 8], [13, 1, 6]] {
            let l = Level {
                edge: Vec3::ONE,
                inv_edge: Vec3::ONE,
                dims,
                bdims: brick_dims(dims),
                bounds: Vec::new(),
            };
            let mut seen = vec![false; storage_len(dims)];
            for z in 0..dims[2] {
                for y in 0..dims[1] {
                    for x in 0..dims[0] {
                        let s = l.index([x, y, z]);
                        assert!(!seen[s], "slot {s} used twice");
                        seen[s] = true;
                        assert_eq!(cell_of(dims, s), Some([x, y, z]));
                    }
                }
            }
            let cells = (dims[0] * dims[1] * dims[2]) as usize;
            let mapped = (0..storage_len(dims)).filter(|&s| cell_of(dims, s).is_some());
            assert_eq!(mapped.count(), cells);
        }
    }
}
