//! Sparse voxel grids owned by Rust.
//!
//! Readers (the OpenVDB bridge, Nimbus' own Rust reader) hand over a [`RawGrid`]: OpenVDB's leaf nodes
//! (8³ bricks) and active tiles as plain data. [`Grid`] turns that into the layout the
//! hot loop wants: a dense top-level index over brick coordinates pointing into a
//! contiguous brick pool, so a lookup is index → brick → 8 loads → lerp.

use glam::{DMat4, DVec3};
use std::sync::atomic::{AtomicU64, Ordering};

/// Edge length of a brick (OpenVDB leaf node) in voxels.
pub const BRICK: i32 = 8;
/// Voxels per brick.
pub const BRICK_VOXELS: usize = 512;

/// One OpenVDB leaf node: 8³ values starting at `origin` (a multiple of 8), x-major
/// like OpenVDB (`offset = x*64 + y*8 + z`), and its active-voxel mask.
#[derive(Clone, Debug)]
pub struct RawLeaf {
    pub origin: [i32; 3],
    pub values: Vec<f32>,
    /// Bit `offset` of the mask, 64 bits per word.
    pub active: [u64; 8],
}

/// A constant region of the tree above leaf level (a tile of an internal or root node):
/// the cube `[origin, origin + dim)` in index space holds `value`.
#[derive(Clone, Debug, PartialEq)]
pub struct RawTile {
    pub origin: [i32; 3],
    pub dim: i32,
    pub value: f32,
    pub active: bool,
}

/// A float grid as a reader delivers it, before any resampling.
#[derive(Clone, Debug)]
pub struct RawGrid {
    pub name: String,
    /// OpenVDB grid class ("fog volume", "level set", "unknown").
    pub class: String,
    pub background: f32,
    pub leaves: Vec<RawLeaf>,
    pub tiles: Vec<RawTile>,
    /// Index → world as a column-vector matrix: `world = M * (i, j, k, 1)`.
    /// (OpenVDB stores the transpose, row-vector convention; readers convert.)
    pub index_to_world: DMat4,
}

impl RawGrid {
    /// Number of active voxels, counting active tiles by their volume.
    pub fn active_voxel_count(&self) -> u64 {
        let leaf: u64 = self
            .leaves
            .iter()
            .map(|l| l.active.iter().map(|w| w.count_ones() as u64).sum::<u64>())
            .sum();
        let tiles: u64 = self
            .tiles
            .iter()
            .filter(|t| t.active)
            .map(|t| (t.dim as u64).pow(3))
            .sum();
        leaf + tiles
    }

    /// Order-independent checksum over every active voxel (position and value bits) and
    /// every active tile. Two readers agree on a file iff their checksums agree.
    pub fn checksum(&self) -> u64 {
        fn mix(mut x: u64) -> u64 {
            // splitmix64 finaliser: a cheap, well-distributed hash of one record.
            x = x.wrapping_add(0x9E37_79B9_7F4A_7C15);
            x = (x ^ (x >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
            x = (x ^ (x >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
            x ^ (x >> 31)
        }
        fn key(p: [i32; 3]) -> u64 {
            ((p[0] as u32 as u64) << 42) ^ ((p[1] as u32 as u64) << 21) ^ (p[2] as u32 as u64)
        }
        let mut sum = 0u64;
        for leaf in &self.leaves {
            for off in 0..BRICK_VOXELS {
                if leaf.active[off / 64] >> (off % 64) & 1 == 1 {
                    let (x, y, z) = ((off >> 6) as i32, ((off >> 3) & 7) as i32, (off & 7) as i32);
                    let p = [leaf.origin[0] + x, leaf.origin[1] + y, leaf.origin[2] + z];
                    sum = sum.wrapping_add(mix(key(p) ^ mix(leaf.values[off].to_bits() as u64)));
                }
            }
        }
        for t in self.tiles.iter().filter(|t| t.active) {
            sum = sum.wrapping_add(mix(key(t.origin)
                ^ mix(((t.dim as u64) << 32) | t.value.to_bits() as u64)
                ^ 0xA5A5));
        }
        sum
    }

    /// Index-space bounding box of the active voxels (inclusive min, inclusive max),
    /// or `None` for an empty grid.
    pub fn active_index_bounds(&self) -> Option<([i32; 3], [i32; 3])> {
        let mut lo = [i32::MAX; 3];
        let mut hi = [i32::MIN; 3];
        let mut any = false;
        for leaf in &self.leaves {
            // Mask word x holds the voxels (x, y, z) at bit y*8 + z: the x range comes
            // from the non-zero words, y from the non-zero bytes of their union, z
            // from the union of those bytes.
            let words = leaf.active;
            let union = words.iter().fold(0u64, |a, &w| a | w);
            if union == 0 {
                continue;
            }
            let xs = words
                .iter()
                .enumerate()
                .fold(0u8, |m, (x, &w)| m | (((w != 0) as u8) << x));
            let ys = (0..8).fold(0u8, |m, y| {
                m | ((((union >> (8 * y)) & 0xFF != 0) as u8) << y)
            });
            let zs = (0..8).fold(0u8, |m, y| m | (union >> (8 * y)) as u8);
            for (a, bits) in [xs, ys, zs].into_iter().enumerate() {
                lo[a] = lo[a].min(leaf.origin[a] + bits.trailing_zeros() as i32);
                hi[a] = hi[a].max(leaf.origin[a] + 7 - bits.leading_zeros() as i32);
            }
            any = true;
        }
        for t in self.tiles.iter().filter(|t| t.active) {
            for a in 0..3 {
                lo[a] = lo[a].min(t.origin[a]);
                hi[a] = hi[a].max(t.origin[a] + t.dim - 1);
            }
            any = true;
        }
        any.then_some((lo, hi))
    }

    /// World-space axis-aligned bounds of the active voxel centres under
    /// `volume_to_world · index_to_world` (the box around the eight transformed corners),
    /// or `None` for an empty grid.
    pub fn world_bounds(&self, volume_to_world: DMat4) -> Option<(DVec3, DVec3)> {
        let (lo, hi) = self.active_index_bounds()?;
        let to_world = volume_to_world * self.index_to_world;
        let (lo, hi) = (lo.map(|v| v as f64), hi.map(|v| v as f64));
        let corners = box_corners(DVec3::from_array(lo), DVec3::from_array(hi));
        Some(corners.into_iter().fold(
            (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
            |(wlo, whi), p| {
                let w = to_world.transform_point3(p);
                (wlo.min(w), whi.max(w))
            },
        ))
    }
}

/// Marker in the brick index for "no brick here: the background value".
const NO_BRICK: u32 = u32::MAX;

/// Largest dense brick index we accept (entries). 2^27 entries = 512 MiB of index,
/// far beyond any grid a CPU renderer should see; beyond it the grid is refused with
/// a clear error rather than exhausting memory.
const MAX_INDEX_ENTRIES: u64 = 1 << 27;

/// Errors turning a [`RawGrid`] into a renderable [`Grid`].
#[derive(Debug, thiserror::Error)]
pub enum GridError {
    #[error("grid '{grid}': {message}")]
    Unsupported { grid: String, message: String },
}

/// A sparse float grid laid out for lookups: a dense index over brick coordinates
/// (covering the active bounds plus one brick of apron) into a pool of 8³ bricks.
///
/// Non-finite and negative voxel values are replaced by 0 when the grid is built (a
/// density must be a finite non-negative number; the count is kept in
/// [`Grid::sanitized_voxels`]) so that nothing downstream can propagate NaN.
pub struct Grid {
    pub name: String,
    pub background: f32,
    /// Brick coordinate of index entry 0.
    brick_min: [i32; 3],
    brick_dims: [i32; 3],
    index: Vec<u32>,
    bricks: Vec<[f32; BRICK_VOXELS]>,
    /// Index → world (column-vector convention).
    pub index_to_world: DMat4,
    /// Inclusive index-space bounds of the stored data (voxel centres), or `None` if empty.
    pub index_bounds: Option<([i32; 3], [i32; 3])>,
    /// Number of voxels whose value was NaN, ±Inf or negative and was replaced by 0.
    pub sanitized_voxels: u64,
    pub active_voxels: u64,
}

/// `v`, or 0 (counted) where it is not finite or, unless `signed`, negative.
#[inline]
fn sanitize_as(v: f32, count: &mut u64, signed: bool) -> f32 {
    if v.is_finite() && (signed || v >= 0.0) {
        v
    } else {
        *count += 1;
        0.0
    }
}

impl Grid {
    /// Builds the lookup layout from a reader's grid; the bricks are filled in
    /// parallel on the current rayon pool.
    pub fn from_raw(raw: &RawGrid) -> Result<Grid, GridError> {
        Self::from_raw_with(raw, true, false)
    }

    /// As [`Grid::from_raw`] for a signed field (a velocity component): negative
    /// values are kept; only non-finite ones become 0.
    pub fn from_raw_signed(raw: &RawGrid) -> Result<Grid, GridError> {
        Self::from_raw_with(raw, true, true)
    }

    /// The largest |value| stored (the background included).
    pub fn max_abs(&self) -> f32 {
        self.bricks
            .iter()
            .flat_map(|b| b.iter())
            .fold(self.background.abs(), |m, v| m.max(v.abs()))
    }

    /// As [`Grid::from_raw`] on one thread (the reference the parallel build is
    /// tested and benchmarked against); the result is the same.
    pub fn from_raw_serial(raw: &RawGrid) -> Result<Grid, GridError> {
        Self::from_raw_with(raw, false, false)
    }

    fn from_raw_with(raw: &RawGrid, parallel: bool, signed: bool) -> Result<Grid, GridError> {
        let mut sanitized = 0u64;
        let background = sanitize_as(raw.background, &mut sanitized, signed);
        let bounds = raw.active_index_bounds();
        let (brick_min, brick_dims) = match bounds {
            Some((lo, hi)) => {
                // One brick of apron on each side: trilinear reconstruction reads one
                // voxel beyond the active region.
                let bmin = [0, 1, 2].map(|a| lo[a].div_euclid(BRICK) - 1);
                let bmax = [0, 1, 2].map(|a| hi[a].div_euclid(BRICK) + 1);
                (bmin, [0, 1, 2].map(|a| bmax[a] - bmin[a] + 1))
            }
            None => ([0; 3], [0; 3]),
        };
        let entries = brick_dims.iter().map(|&d| d.max(0) as u64).product::<u64>();
        if entries > MAX_INDEX_ENTRIES {
            return Err(GridError::Unsupported {
                grid: raw.name.clone(),
                message: format!(
                    "active region spans {}x{}x{} bricks of 8³ voxels; more than Nimbus' limit of {} bricks",
                    brick_dims[0], brick_dims[1], brick_dims[2], MAX_INDEX_ENTRIES
                ),
            });
        }
        let mut grid = Grid {
            name: raw.name.clone(),
            background,
            brick_min,
            brick_dims,
            index: Vec::new(),
            bricks: Vec::new(),
            index_to_world: raw.index_to_world,
            index_bounds: bounds,
            sanitized_voxels: 0,
            active_voxels: raw.active_voxel_count(),
        };
        grid.index = Vec::with_capacity(entries as usize);
        grid.index.resize(entries as usize, NO_BRICK);
        if entries == 0 {
            grid.sanitized_voxels = sanitized;
            return Ok(grid);
        }
        // Tiles first (largest regions), then leaves overwrite: in OpenVDB a leaf and a
        // tile never overlap, so the order only matters for robustness against odd input.
        for tile in &raw.tiles {
            let value = sanitize_as(tile.value, &mut sanitized, signed);
            if value == background {
                continue;
            }
            let brick = grid.bricks.len() as u32;
            grid.bricks.push([value; BRICK_VOXELS]);
            let tdim_b = (tile.dim / BRICK).max(1);
            let tb = tile.origin.map(|c| c.div_euclid(BRICK));
            for bz in tb[2].max(brick_min[2])..(tb[2] + tdim_b).min(brick_min[2] + brick_dims[2]) {
                for by in
                    tb[1].max(brick_min[1])..(tb[1] + tdim_b).min(brick_min[1] + brick_dims[1])
                {
                    for bx in
                        tb[0].max(brick_min[0])..(tb[0] + tdim_b).min(brick_min[0] + brick_dims[0])
                    {
                        let e = grid
                            .entry([bx, by, bz])
                            .expect("clamped to the index range");
                        grid.index[e] = brick;
                    }
                }
            }
        }
        // Leaves: each brick is filled and sanitised independently (in parallel unless
        // `parallel` is off), then the bricks that hold only the background are dropped
        // and the index is set in leaf order, exactly as a serial pass would.
        let first = grid.bricks.len();
        // The pool is allocated once and filled in place (rayon's indexed `par_extend` writes each
        // brick straight into its slot).
        let mut bricks = Vec::with_capacity(first + raw.leaves.len());
        bricks.extend_from_slice(&grid.bricks);
        grid.bricks = bricks;
        // Per leaf: sanitised-value count << 1 | "holds only the background".
        let flags: Vec<AtomicU64> = (0..raw.leaves.len()).map(|_| AtomicU64::new(0)).collect();
        let fill = |(leaf, flag): (&RawLeaf, &AtomicU64)| -> [f32; BRICK_VOXELS] {
            let mut dst = [background; BRICK_VOXELS];
            let mut count = 0u64;
            // Fewer than 512 values means a reader bug; the missing ones read as background.
            for (d, &src) in dst.iter_mut().zip(leaf.values.iter()) {
                *d = sanitize_as(src, &mut count, signed);
            }
            // A leaf that holds only the background (sims often keep such leaves
            // active) reads the same as no brick: it is not stored.
            let background_only = dst.iter().all(|&v| v == background);
            flag.store(count << 1 | background_only as u64, Ordering::Relaxed);
            dst
        };
        if parallel {
            use rayon::prelude::*;
            grid.bricks.par_extend(
                raw.leaves
                    .par_iter()
                    .zip(flags.par_iter())
                    .with_min_len(64)
                    .map(fill),
            );
        } else {
            grid.bricks
                .extend(raw.leaves.iter().zip(flags.iter()).map(fill));
        }
        let filled = flags.into_iter().map(|f| {
            let f = f.into_inner();
            (f >> 1, f & 1 == 1)
        });
        let mut kept = first;
        for (n, (leaf, (count, background_only))) in raw.leaves.iter().zip(filled).enumerate() {
            let b = leaf.origin.map(|c| c.div_euclid(BRICK));
            let Some(e) = grid.entry(b) else { continue };
            sanitized += count;
            if background_only {
                grid.index[e] = NO_BRICK;
                continue;
            }
            grid.index[e] = kept as u32;
            if kept != first + n {
                grid.bricks[kept] = grid.bricks[first + n];
            }
            kept += 1;
        }
        grid.bricks.truncate(kept);
        grid.bricks.shrink_to_fit();
        grid.sanitized_voxels = sanitized;
        Ok(grid)
    }

    #[inline(always)]
    fn entry(&self, b: [i32; 3]) -> Option<usize> {
        let r = [
            b[0] - self.brick_min[0],
            b[1] - self.brick_min[1],
            b[2] - self.brick_min[2],
        ];
        if (r[0] as u32) < self.brick_dims[0] as u32
            && (r[1] as u32) < self.brick_dims[1] as u32
            && (r[2] as u32) < self.brick_dims[2] as u32
        {
            Some(((r[2] * self.brick_dims[1] + r[1]) * self.brick_dims[0] + r[0]) as usize)
        } else {
            None
        }
    }

    /// The value of voxel `ijk`.
    #[inline(always)]
    pub fn voxel(&self, ijk: [i32; 3]) -> f32 {
        match self.entry([ijk[0] >> 3, ijk[1] >> 3, ijk[2] >> 3]) {
            Some(e) => {
                let b = self.index[e];
                if b == NO_BRICK {
                    self.background
                } else {
                    let off = in_brick(ijk);
                    self.bricks[b as usize][off]
                }
            }
            None => self.background,
        }
    }

    /// Trilinear reconstruction at a continuous index-space point (voxel centres at
    /// integer coordinates, as in OpenVDB's `BoxSampler`).
    #[inline]
    pub fn sample_trilinear(&self, p: [f32; 3]) -> f32 {
        let Some(i) = base_voxel(p) else {
            return self.background;
        };
        let f = [0, 1, 2].map(|a| p[a] - i[a] as f32);
        // Fast path: the 2×2×2 stencil lies inside one brick (7 of 8 positions per axis).
        // (Tested first on its own: folding it into the match below as `cross == 0`
        // cost 0.5–1.2 % more instructions per sample.)
        let c = if (i[0] & 7) != 7 && (i[1] & 7) != 7 && (i[2] & 7) != 7 {
            let Some(v) = self.brick_at([i[0] >> 3, i[1] >> 3, i[2] >> 3]) else {
                return self.background;
            };
            let o = in_brick(i);
            // One bounds check for the stencil's span (o + 73 ≤ 511 here).
            let v = &v[o..o + 74];
            [v[0], v[1], v[8], v[9], v[64], v[65], v[72], v[73]]
        } else {
            // The axes (x = 4, y = 2, z = 1) on which the stencil leaves its brick: one
            // (a face) in 86 % of these, so that case has its own straight-line path.
            let cross = ((i[0] & 7) == 7) as u32 * 4
                | ((i[1] & 7) == 7) as u32 * 2
                | ((i[2] & 7) == 7) as u32;
            match cross {
                4 => self.straddling_face::<0>(i),
                2 => self.straddling_face::<1>(i),
                1 => self.straddling_face::<2>(i),
                _ => self.straddling_corners(i),
            }
        };
        // c[n] with n = dx*4 + dy*2 + dz.
        let lz = |a: f32, b: f32| a + (b - a) * f[2];
        let c00 = lz(c[0], c[1]);
        let c01 = lz(c[2], c[3]);
        let c10 = lz(c[4], c[5]);
        let c11 = lz(c[6], c[7]);
        let c0 = c00 + (c01 - c00) * f[1];
        let c1 = c10 + (c11 - c10) * f[1];
        c0 + (c1 - c0) * f[0]
    }

    /// Starts loading the cache lines of the trilinear stencil at `p` without waiting
    /// for them: a hint, no value, no effect on any result. Trackers call it for the
    /// next tentative collision while the current one's lookup is still in flight, so
    /// on a grid far larger than the caches the two misses overlap instead of queueing
    /// (the next position depends only on random numbers already drawn). Covers the
    /// stencil's part in its own brick only: where the stencil crosses a brick face
    /// (rare) the rest is simply not prefetched.
    #[inline(always)]
    pub fn prefetch(&self, p: [f32; 3]) {
        let Some(i) = base_voxel(p) else {
            return;
        };
        let Some(v) = self.brick_at([i[0] >> 3, i[1] >> 3, i[2] >> 3]) else {
            return;
        };
        let o = in_brick(i);
        // x-major slots: the stencil's rows start at o, o + 8, o + 64 and o + 72 and
        // hold two voxels each; the lines of o, o + 9, o + 64 and o + 73 cover them
        // (min keeps the hint inside the brick where the stencil leaves it at x = 7).
        for k in [o, o + 9, o + 64, o + 73] {
            prefetch_line(&v[k.min(BRICK_VOXELS - 1)]);
        }
    }

    /// One corner of the trilinear stencil at `p`, corner `d` on each axis chosen with
    /// probability `f` (`d` = 1) or 1 − `f` (`d` = 0) from 21 bits of `u` per axis: an
    /// unbiased estimate of [`sample_trilinear`](Self::sample_trilinear) (its weights
    /// are these probabilities) from one voxel read instead of eight, for estimators
    /// that use the density linearly. The probabilities are the fractions rounded up
    /// to a multiple of 2⁻²¹ (an error of at most 4.8e-7 in each weight).
    #[inline(always)]
    pub fn sample_stochastic(&self, p: [f32; 3], u: u64) -> f32 {
        let Some(i) = base_voxel(p) else {
            return self.background;
        };
        let corner = |a: usize| {
            let f = p[a] - i[a] as f32;
            let v = ((u >> (21 * a)) & 0x1F_FFFF) as f32 * (1.0 / 2_097_152.0);
            i[a] + (v < f) as i32
        };
        self.voxel([corner(0), corner(1), corner(2)])
    }

    /// The brick holding brick coordinate `b`, `None` where the background answers.
    #[inline(always)]
    fn brick_at(&self, b: [i32; 3]) -> Option<&[f32; BRICK_VOXELS]> {
        let e = self.entry(b)?;
        let brick = self.index[e];
        (brick != NO_BRICK).then(|| &self.bricks[brick as usize])
    }

    /// The 2×2×2 stencil at voxel `i` when it crosses the brick face on axis `A` only
    /// (`i` is the last voxel of its brick on `A` and not on the others): the four
    /// corners at offset 0 on `A` from `i`'s brick, the four at offset 1 from the next
    /// brick along `A`, where the in-brick coordinate on `A` wraps from 7 to 0. The
    /// values [`voxel`](Self::voxel) gives; `c[n]` with n = dx*4 + dy*2 + dz.
    #[inline(always)]
    fn straddling_face<const A: usize>(&self, i: [i32; 3]) -> [f32; 8] {
        let b0 = [i[0] >> 3, i[1] >> 3, i[2] >> 3];
        let mut b1 = b0;
        b1[A] += 1;
        let (near, far) = (self.brick_at(b0), self.brick_at(b1));
        let o = in_brick(i);
        // Stride of axis A in a brick; the far brick's voxels sit 8 strides back.
        let stride = [64, 8, 1][A];
        std::array::from_fn(|n| {
            let d = [n >> 2, (n >> 1) & 1, n & 1];
            let off = o + d[0] * 64 + d[1] * 8 + d[2];
            let (brick, off) = if d[A] == 0 {
                (near, off)
            } else {
                (far, off - 8 * stride)
            };
            // `& 511` is the identity here (off < 512) and spares the bounds check.
            brick.map_or(self.background, |v| v[off & (BRICK_VOXELS - 1)])
        })
    }

    /// The 2×2×2 stencil at voxel `i` when it crosses a brick face (on the axes where
    /// `i` is the last voxel of its brick): the values [`voxel`](Self::voxel) gives,
    /// with one brick lookup per brick touched (2 for a face, 4 for an edge, 8 for a
    /// corner) instead of one per voxel. `c[n]` with n = dx*4 + dy*2 + dz.
    #[inline(never)]
    fn straddling_corners(&self, i: [i32; 3]) -> [f32; 8] {
        let b0 = [i[0] >> 3, i[1] >> 3, i[2] >> 3];
        let cross = [0, 1, 2].map(|a| ((i[a] & 7) == 7) as usize);
        // The brick of corner offset d: key (dx & cross x, dy & cross y, dz & cross z).
        let key =
            |d: [usize; 3]| ((d[0] & cross[0]) << 2) | ((d[1] & cross[1]) << 1) | (d[2] & cross[2]);
        let mut bricks: [Option<&[f32; BRICK_VOXELS]>; 8] = [None; 8];
        for (k, brick) in bricks.iter_mut().enumerate() {
            let d = [k >> 2, (k >> 1) & 1, k & 1];
            if key(d) == k {
                *brick = self.brick_at([0, 1, 2].map(|a| b0[a] + d[a] as i32));
            }
        }
        // In-brick coordinate of corner offset 0 and 1 on each axis.
        let local = [0, 1, 2].map(|a| [(i[a] & 7) as usize, ((i[a] + 1) & 7) as usize]);
        std::array::from_fn(|n| {
            let d = [n >> 2, (n >> 1) & 1, n & 1];
            match bricks[key(d)] {
                Some(v) => v[(local[0][d[0]] << 6) | (local[1][d[1]] << 3) | local[2][d[2]]],
                None => self.background,
            }
        })
    }

    /// Minimum and maximum voxel value over the inclusive voxel box `[lo, hi]`: the
    /// bounds of the trilinear reconstruction over the box `[lo, hi - 1]` of cells.
    /// Whole-brick shortcuts keep this fast for majorant construction.
    pub fn value_range(&self, lo: [i32; 3], hi: [i32; 3]) -> (f32, f32) {
        let mut mn = f32::INFINITY;
        let mut mx = f32::NEG_INFINITY;
        for bz in lo[2] >> 3..=hi[2] >> 3 {
            for by in lo[1] >> 3..=hi[1] >> 3 {
                for bx in lo[0] >> 3..=hi[0] >> 3 {
                    let brick = self.entry([bx, by, bz]).map(|e| self.index[e]);
                    let v = match brick {
                        Some(b) if b != NO_BRICK => &self.bricks[b as usize],
                        _ => {
                            mn = mn.min(self.background);
                            mx = mx.max(self.background);
                            continue;
                        }
                    };
                    let base = [bx << 3, by << 3, bz << 3];
                    let r0 = [0, 1, 2].map(|a| (lo[a] - base[a]).max(0));
                    let r1 = [0, 1, 2].map(|a| (hi[a] - base[a]).min(7));
                    for x in r0[0]..=r1[0] {
                        for y in r0[1]..=r1[1] {
                            for z in r0[2]..=r1[2] {
                                let s = v[((x << 6) | (y << 3) | z) as usize];
                                mn = mn.min(s);
                                mx = mx.max(s);
                            }
                        }
                    }
                }
            }
        }
        (mn, mx)
    }

    /// Whether brick coordinate `b` (voxel `b * 8`) has a stored brick.
    pub fn has_brick(&self, b: [i32; 3]) -> bool {
        self.entry(b).is_some_and(|e| self.index[e] != NO_BRICK)
    }

    /// Number of bricks held (leaves plus one per distinct non-background tile).
    pub fn brick_count(&self) -> usize {
        self.bricks.len()
    }

    /// Bytes used by the lookup layout.
    pub fn memory_bytes(&self) -> usize {
        self.index.len() * 4 + self.bricks.len() * BRICK_VOXELS * 4
    }
}

/// A software prefetch of the cache line holding `x` into every cache level.
#[inline(always)]
fn prefetch_line(x: &f32) {
    #[cfg(target_arch = "x86_64")]
    // SAFETY: a prefetch is a hint: it never faults and reads nothing into the
    // program's state; the pointer comes from a live reference anyway.
    unsafe {
        use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
        _mm_prefetch::<_MM_HINT_T0>((x as *const f32).cast::<i8>());
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = x;
}

/// The slot of voxel `ijk` in its brick (x-major: x·64 + y·8 + z).
#[inline(always)]
fn in_brick(ijk: [i32; 3]) -> usize {
    (((ijk[0] & 7) << 6) | ((ijk[1] & 7) << 3) | (ijk[2] & 7)) as usize
}

/// The voxel at the low corner of the trilinear stencil at `p` (the floor per axis),
/// `None` far outside the index range, where a cast would saturate and the background
/// answers (NaN coordinates too).
#[inline(always)]
fn base_voxel(p: [f32; 3]) -> Option<[i32; 3]> {
    (p[0].abs() < 1.0e9 && p[1].abs() < 1.0e9 && p[2].abs() < 1.0e9).then(|| p.map(floor_small))
}

/// `x.floor() as i32` for finite |x| < 1e9 (callers check): [`floor_i32`] without the
/// saturating cast's range checks.
#[inline(always)]
fn floor_small(x: f32) -> i32 {
    debug_assert!(x.abs() < 1.0e9);
    // SAFETY: x is finite and |x| < 1e9 < 2³¹ (checked by the caller), so its
    // truncation is representable as an i32.
    let i: i32 = unsafe { x.to_int_unchecked() };
    i - (x < i as f32) as i32
}

/// `x.floor() as i32` for |x| < 2³¹ without a libm call: `floorf` is not inlined on
/// baseline x86-64 (no SSE4.1 `roundss`), and it sits on the lookup's hot path.
#[inline(always)]
pub fn floor_i32(x: f32) -> i32 {
    let i = x as i32;
    i - (x < i as f32) as i32
}

#[derive(Debug, thiserror::Error)]
pub enum MediumError {
    #[error("volume {prim}: {message}")]
    Invalid { prim: String, message: String },
}

/// The world → index transform of `grid` under a volume's `volume_to_world`: the
/// inverse of volume_to_world · index_to_world. A singular product is an error naming
/// the prim (and `what`, a prefix such as "nimbus:emissionField `flames`: ").
pub fn world_to_index(
    prim: &str,
    what: &str,
    volume_to_world: DMat4,
    grid: &Grid,
) -> Result<DMat4, MediumError> {
    let index_to_world = volume_to_world * grid.index_to_world;
    let det = index_to_world.determinant();
    if !det.is_finite() || det.abs() < 1e-300 {
        return Err(MediumError::Invalid {
            prim: prim.to_string(),
            message: format!(
                "{what}the volume's transform times the grid's index-to-world transform is singular (determinant {det:e}); cannot map rays into the grid"
            ),
        });
    }
    Ok(index_to_world.inverse())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn leaf(origin: [i32; 3], value: impl Fn(usize) -> f32) -> RawLeaf {
        RawLeaf {
            origin,
            values: (0..BRICK_VOXELS).map(value).collect(),
            active: [u64::MAX; 8],
        }
    }

    /// A grid of leaves at `origins` (background 0.25), leaf n's voxel i holding a value
    /// of 0.1–1.22 that varies from voxel to voxel and from leaf to leaf.
    fn patterned_grid(origins: &[[i32; 3]]) -> Grid {
        let leaves = origins
            .iter()
            .enumerate()
            .map(|(n, &o)| leaf(o, |i| ((i * 37 + n * 101) % 113) as f32 * 0.01 + 0.1))
            .collect();
        let raw = RawGrid {
            name: "density".into(),
            class: "fog volume".into(),
            background: 0.25,
            leaves,
            tiles: vec![],
            index_to_world: DMat4::IDENTITY,
        };
        Grid::from_raw(&raw).unwrap()
    }

    /// Trilinear lookups read the stencil `voxel` gives, bit for bit, wherever it lies:
    /// inside a brick, across a face, an edge or a corner of bricks, next to absent
    /// bricks and outside the index range. 200,000 random points, a quarter of them
    /// snapped onto the last voxel of a brick on random axes.
    #[test]
    fn trilinear_reads_the_voxel_stencil_across_bricks() {
        use rand::{Rng, SeedableRng};
        let g = patterned_grid(&[
            [0, 0, 0],
            [8, 0, 0],
            [0, 8, 0],
            [8, 8, 8],
            [16, 0, 8],
            [-8, 0, 0],
        ]);
        let reference = |p: [f32; 3]| {
            let i = p.map(floor_i32);
            let f = [0, 1, 2].map(|a| p[a] - i[a] as f32);
            let c: [f32; 8] = std::array::from_fn(|n| {
                let d = [(n >> 2) as i32, ((n >> 1) & 1) as i32, (n & 1) as i32];
                g.voxel([i[0] + d[0], i[1] + d[1], i[2] + d[2]])
            });
            let lz = |a: f32, b: f32| a + (b - a) * f[2];
            let (c00, c01, c10, c11) = (
                lz(c[0], c[1]),
                lz(c[2], c[3]),
                lz(c[4], c[5]),
                lz(c[6], c[7]),
            );
            let c0 = c00 + (c01 - c00) * f[1];
            let c1 = c10 + (c11 - c10) * f[1];
            c0 + (c1 - c0) * f[0]
        };
        let mut rng = rand_pcg::Pcg32::seed_from_u64(11);
        let mut straddles = 0;
        for n in 0..200_000 {
            let mut p: [f32; 3] = std::array::from_fn(|_| rng.gen_range(-20.0f32..36.0));
            if n % 4 == 0 {
                for x in p.iter_mut() {
                    if rng.gen::<bool>() {
                        *x = (floor_i32(*x) | 7) as f32 + rng.gen::<f32>() * 0.999;
                    }
                }
            }
            straddles += p.iter().any(|&x| floor_i32(x) & 7 == 7) as u32;
            let (a, b) = (g.sample_trilinear(p), reference(p));
            assert_eq!(a.to_bits(), b.to_bits(), "at {p:?}: {a} vs {b}");
        }
        assert!(straddles > 50_000, "{straddles} straddling points");
    }

    /// The stochastic lookup is an unbiased estimate of the trilinear one. Estimator: the
    /// mean of N = 20,000 one-voxel reads (random bits from PCG32, seed 12) at each of
    /// 300 points (a quarter on brick borders, seed 11), against `sample_trilinear`;
    /// z = (mean − trilinear) / (sample sd / √N); |z| < 4.5 at every point (the largest
    /// of 300 standard normals exceeds 4.5 with probability 0.2 %). Every read is one of
    /// the stencil's 8 voxels, and an axis with fraction 0 never reads its far corner.
    #[test]
    fn stochastic_lookup_estimates_the_trilinear_value() {
        use rand::{Rng, SeedableRng};
        let g = patterned_grid(&[[0, 0, 0], [8, 0, 0], [0, 8, 0], [8, 8, 8], [-8, 0, 0]]);
        let mut points = rand_pcg::Pcg32::seed_from_u64(11);
        let mut bits = rand_pcg::Pcg32::seed_from_u64(12);
        const N: usize = 20_000;
        for n in 0..300 {
            let mut p: [f32; 3] = std::array::from_fn(|_| points.gen_range(-10.0f32..18.0));
            if n % 4 == 0 {
                p[n % 3] = (floor_i32(p[n % 3]) | 7) as f32 + points.gen::<f32>();
            }
            let i = p.map(floor_i32);
            let corners: Vec<f32> = (0..8)
                .map(|c| g.voxel([i[0] + (c >> 2), i[1] + ((c >> 1) & 1), i[2] + (c & 1)]))
                .collect();
            let (mut sum, mut sq) = (0f64, 0f64);
            for _ in 0..N {
                let v = g.sample_stochastic(p, bits.gen::<u64>());
                assert!(corners.contains(&v), "at {p:?}: {v} is no stencil voxel");
                sum += v as f64;
                sq += (v as f64).powi(2);
            }
            let mean = sum / N as f64;
            let sd = (sq / N as f64 - mean * mean).max(0.0).sqrt();
            let exact = g.sample_trilinear(p) as f64;
            let z = (mean - exact) / (sd / (N as f64).sqrt()).max(1e-9);
            assert!(
                z.abs() < 4.5,
                "at {p:?}: mean {mean} vs trilinear {exact}, z = {z:.2}"
            );
        }
        // At a voxel centre the only voxel read is that one.
        let centre = [3.0f32, 4.0, 5.0];
        for _ in 0..1000 {
            assert_eq!(
                g.sample_stochastic(centre, bits.gen::<u64>()),
                g.voxel([3, 4, 5])
            );
        }
    }

    /// Active leaves that hold only the background (here 0, after negative values are
    /// sanitised to it) get no brick, and every lookup reads as it did with the brick.
    #[test]
    fn background_only_leaves_are_not_stored() {
        let raw = RawGrid {
            name: "density".into(),
            class: "fog volume".into(),
            background: 0.0,
            leaves: vec![
                leaf([0, 0, 0], |i| (i % 7) as f32 * 0.25),
                leaf([8, 0, 0], |_| 0.0),
                leaf([0, 8, 0], |_| -1.0),
            ],
            tiles: vec![],
            index_to_world: DMat4::IDENTITY,
        };
        let g = Grid::from_raw(&raw).unwrap();
        assert_eq!(g.brick_count(), 1);
        assert_eq!(g.active_voxels, 3 * 512);
        assert_eq!(g.sanitized_voxels, 512);
        for (i, &v) in raw.leaves[0].values.iter().enumerate() {
            let ijk = [(i >> 6) as i32, ((i >> 3) & 7) as i32, (i & 7) as i32];
            assert_eq!(g.voxel(ijk), v);
            assert_eq!(g.voxel([ijk[0] + 8, ijk[1], ijk[2]]), 0.0);
            assert_eq!(g.voxel([ijk[0], ijk[1] + 8, ijk[2]]), 0.0);
        }
        // Across the face between the stored and the dropped leaf: the lerp towards 0.
        let v = g.sample_trilinear([7.5, 3.0, 3.0]);
        assert_eq!(v, 0.5 * g.voxel([7, 3, 3]));
    }

    /// The per-leaf mask shortcut of `active_index_bounds` agrees with a voxel-by-voxel
    /// scan.
    #[test]
    fn active_bounds_from_masks() {
        let mut state = 0x1234_5678_9ABC_DEF0u64;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state
        };
        for _ in 0..200 {
            let mut leaves = Vec::new();
            for n in 0..3 {
                let mut active = [0u64; 8];
                // Sparse masks: a few random bits per word in some words.
                for w in active.iter_mut() {
                    if next() % 3 == 0 {
                        *w = next() & next() & next() & next();
                    }
                }
                let o = [(next() % 5) as i32 * 8 - 16, n * 8, (next() % 3) as i32 * 8];
                leaves.push(RawLeaf {
                    active,
                    ..leaf(o, |_| 1.0)
                });
            }
            let raw = RawGrid {
                name: "d".into(),
                class: String::new(),
                background: 0.0,
                leaves,
                tiles: vec![],
                index_to_world: DMat4::IDENTITY,
            };
            let mut lo = [i32::MAX; 3];
            let mut hi = [i32::MIN; 3];
            let mut any = false;
            for l in &raw.leaves {
                for off in 0..BRICK_VOXELS {
                    if l.active[off / 64] >> (off % 64) & 1 == 1 {
                        let d = [(off >> 6) as i32, ((off >> 3) & 7) as i32, (off & 7) as i32];
                        for a in 0..3 {
                            lo[a] = lo[a].min(l.origin[a] + d[a]);
                            hi[a] = hi[a].max(l.origin[a] + d[a]);
                        }
                        any = true;
                    }
                }
            }
            assert_eq!(raw.active_index_bounds(), any.then_some((lo, hi)));
        }
    }

    /// The parallel build makes exactly the grid the serial one does: the same index,
    /// the same bricks in the same order, the same counts.
    #[test]
    fn parallel_build_equals_serial() {
        let mut leaves = Vec::new();
        for n in 0..300i32 {
            let origin = [(n % 7) * 8, ((n / 7) % 6) * 8, (n / 42) * 8 - 16];
            leaves.push(match n % 5 {
                // Background-only leaves, dropped.
                0 => leaf(origin, |_| 0.0),
                // NaN and negative values, sanitised.
                1 => leaf(origin, |i| if i % 3 == 0 { f32::NAN } else { -(i as f32) }),
                // Short value lists (a reader bug) read as background.
                2 => RawLeaf {
                    values: vec![1.5; 100],
                    ..leaf(origin, |_| 0.0)
                },
                _ => leaf(origin, |i| ((i * 31 + n as usize) % 17) as f32 * 0.1),
            });
        }
        // A duplicate origin: the later leaf wins in both builds.
        leaves.push(leaf([0, 0, -16], |i| i as f32));
        let raw = RawGrid {
            name: "density".into(),
            class: "fog volume".into(),
            background: 0.0,
            leaves,
            tiles: vec![RawTile {
                origin: [64, 0, 0],
                dim: 16,
                value: 0.5,
                active: true,
            }],
            index_to_world: DMat4::IDENTITY,
        };
        let a = Grid::from_raw(&raw).unwrap();
        let b = Grid::from_raw_serial(&raw).unwrap();
        assert_eq!(a.index, b.index);
        assert_eq!(a.bricks.len(), b.bricks.len());
        for (x, y) in a.bricks.iter().zip(&b.bricks) {
            assert_eq!(x.map(f32::to_bits), y.map(f32::to_bits));
        }
        assert_eq!(
            (
                a.sanitized_voxels,
                a.active_voxels,
                a.brick_min,
                a.brick_dims
            ),
            (
                b.sanitized_voxels,
                b.active_voxels,
                b.brick_min,
                b.brick_dims
            )
        );
        assert!(a.sanitized_voxels > 0);
        assert_eq!(a.voxel([3, 0, -16]), ((3 << 6) as f32));
    }
}

/// The eight corners of the box `lo`..`hi` (x varies fastest).
pub fn box_corners(lo: DVec3, hi: DVec3) -> [DVec3; 8] {
    std::array::from_fn(|i| {
        DVec3::new(
            if i & 1 == 0 { lo.x } else { hi.x },
            if i & 2 == 0 { lo.y } else { hi.y },
            if i & 4 == 0 { lo.z } else { hi.z },
        )
    })
}
