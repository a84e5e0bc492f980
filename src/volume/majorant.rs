//! The majorant structure: a uniform grid of cells over the density grid, each with the
//! minimum and maximum of the *reconstructed* density inside it, and a DDA that walks a
//! ray through the cells as segments of constant bounds.
//!
//! Trackers never see the cells, only [`Segment`]s, so the structure is a parameter of
//! the tracking code rather than baked into it (an octree can hand out the same
//! segments). A cell size of 0 gives one cell for the whole volume: a global majorant.

use crate::volume::grid::Grid;
use glam::Vec3;

/// A stretch `[t0, t1)` of a ray over which the density lies in `[dmin, dmax]`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Segment {
    pub t0: f32,
    pub t1: f32,
    pub dmin: f32,
    pub dmax: f32,
}

pub struct MajorantGrid {
    /// Continuous index-space corner of cell (0,0,0).
    origin: Vec3,
    /// Cell edge in index units (voxels).
    cell: Vec3,
    dims: [i32; 3],
    /// (min, max) density per cell, x fastest.
    bounds: Vec<(f32, f32)>,
}

impl MajorantGrid {
    /// Builds per-cell bounds. Each cell's voxel range is dilated by one voxel on each
    /// side: trilinear reconstruction at a point reads the 2×2×2 voxels around it, which
    /// reach one voxel past the cell, and the extra voxel on the low side absorbs
    /// rounding of positions computed right at a cell face.
    pub fn build(grid: &Grid, cell_voxels: u32) -> MajorantGrid {
        let Some((lo, hi)) = grid.index_bounds else {
            return MajorantGrid {
                origin: Vec3::ZERO,
                cell: Vec3::ONE,
                dims: [0; 3],
                bounds: Vec::new(),
            };
        };
        // The region where the field can differ from the background: the active voxel
        // centres, widened by one voxel (where interpolation falls off to background).
        let rlo = [0, 1, 2].map(|a| lo[a] - 1);
        let rhi = [0, 1, 2].map(|a| hi[a] + 1);
        let extent = [0, 1, 2].map(|a| rhi[a] - rlo[a]);
        let cell = if cell_voxels == 0 {
            extent.map(|e| e.max(1))
        } else {
            [cell_voxels as i32; 3]
        };
        let dims = [0, 1, 2].map(|a| ((extent[a] + cell[a] - 1) / cell[a]).max(1));
        let n = (dims[0] * dims[1] * dims[2]) as usize;
        let bounds: Vec<(f32, f32)> = {
            use rayon::prelude::*;
            (0..n)
                .into_par_iter()
                .map(|i| {
                    let i = i as i32;
                    let c = [
                        i % dims[0],
                        (i / dims[0]) % dims[1],
                        i / (dims[0] * dims[1]),
                    ];
                    let vlo = [0, 1, 2].map(|a| rlo[a] + c[a] * cell[a] - 1);
                    let vhi = [0, 1, 2].map(|a| rlo[a] + (c[a] + 1) * cell[a] + 1);
                    grid.value_range(vlo, vhi)
                })
                .collect()
        };
        MajorantGrid {
            origin: Vec3::new(rlo[0] as f32, rlo[1] as f32, rlo[2] as f32),
            cell: Vec3::new(cell[0] as f32, cell[1] as f32, cell[2] as f32),
            dims,
            bounds,
        }
    }

    pub fn cell_count(&self) -> usize {
        self.bounds.len()
    }

    pub fn dims(&self) -> [i32; 3] {
        self.dims
    }

    /// Largest density anywhere (the global majorant).
    pub fn max_density(&self) -> f32 {
        self.bounds.iter().fold(0f32, |m, b| m.max(b.1))
    }

    /// Continuous index-space box covered by the cells.
    pub fn index_region(&self) -> Option<(Vec3, Vec3)> {
        if self.bounds.is_empty() {
            return None;
        }
        let d = Vec3::new(
            self.dims[0] as f32,
            self.dims[1] as f32,
            self.dims[2] as f32,
        );
        Some((self.origin, self.origin + d * self.cell))
    }

    /// Starts a walk along `o + t·d` for `t` in `[tmin, tmax)`.
    pub fn walk(&self, o: Vec3, d: Vec3, tmin: f32, tmax: f32) -> CellWalk<'_> {
        CellWalk::new(self, o, d, tmin, tmax)
    }
}

/// Amanatides–Woo traversal of the majorant cells along a ray, yielding one segment per
/// cell in order along the ray. Restartable by construction: callers keep their own `t`
/// and simply move on to the next segment.
pub struct CellWalk<'a> {
    grid: &'a MajorantGrid,
    cell: [i32; 3],
    step: [i32; 3],
    t_next: [f32; 3],
    t_delta: [f32; 3],
    t: f32,
    t_end: f32,
}

impl<'a> CellWalk<'a> {
    fn new(grid: &'a MajorantGrid, o: Vec3, d: Vec3, tmin: f32, tmax: f32) -> CellWalk<'a> {
        let mut walk = CellWalk {
            grid,
            cell: [0; 3],
            step: [0; 3],
            t_next: [f32::INFINITY; 3],
            t_delta: [f32::INFINITY; 3],
            t: 0.0,
            t_end: -1.0,
        };
        let Some((lo, hi)) = grid.index_region() else {
            return walk;
        };
        // Slab test against the cell region.
        let (mut t0, mut t1) = (tmin, tmax);
        for a in 0..3 {
            if d[a] == 0.0 {
                if o[a] < lo[a] || o[a] >= hi[a] {
                    return walk;
                }
                continue;
            }
            let inv = 1.0 / d[a];
            let (mut ta, mut tb) = ((lo[a] - o[a]) * inv, (hi[a] - o[a]) * inv);
            if ta > tb {
                std::mem::swap(&mut ta, &mut tb);
            }
            t0 = t0.max(ta);
            t1 = t1.min(tb);
        }
        if !(t0 < t1) {
            return walk;
        }
        let p = o + d * t0;
        for a in 0..3 {
            let rel = (p[a] - grid.origin[a]) / grid.cell[a];
            let c = (rel.floor() as i32).clamp(0, grid.dims[a] - 1);
            walk.cell[a] = c;
            if d[a] > 0.0 {
                walk.step[a] = 1;
                let face = grid.origin[a] + (c + 1) as f32 * grid.cell[a];
                walk.t_next[a] = t0 + (face - p[a]) / d[a];
                walk.t_delta[a] = grid.cell[a] / d[a];
            } else if d[a] < 0.0 {
                walk.step[a] = -1;
                let face = grid.origin[a] + c as f32 * grid.cell[a];
                walk.t_next[a] = t0 + (face - p[a]) / d[a];
                walk.t_delta[a] = -grid.cell[a] / d[a];
            }
        }
        walk.t = t0;
        walk.t_end = t1;
        walk
    }
}

impl Iterator for CellWalk<'_> {
    type Item = Segment;

    #[inline]
    fn next(&mut self) -> Option<Segment> {
        if !(self.t < self.t_end) {
            return None;
        }
        let a = if self.t_next[0] < self.t_next[1] {
            if self.t_next[0] < self.t_next[2] {
                0
            } else {
                2
            }
        } else if self.t_next[1] < self.t_next[2] {
            1
        } else {
            2
        };
        let t1 = self.t_next[a].min(self.t_end).max(self.t);
        let dims = self.grid.dims;
        let idx = ((self.cell[2] * dims[1] + self.cell[1]) * dims[0] + self.cell[0]) as usize;
        let (dmin, dmax) = self.grid.bounds[idx];
        let seg = Segment {
            t0: self.t,
            t1,
            dmin,
            dmax,
        };
        self.t = t1;
        self.cell[a] += self.step[a];
        self.t_next[a] += self.t_delta[a];
        if self.cell[a] < 0 || self.cell[a] >= dims[a] {
            self.t_end = self.t; // left the grid
        }
        Some(seg)
    }
}
