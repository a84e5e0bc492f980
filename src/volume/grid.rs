//! Sparse voxel grids owned by Rust.
//!
//! Readers (the OpenVDB bridge, vdb-rs) hand over a [`RawGrid`]: OpenVDB's leaf nodes
//! (8³ bricks) and active tiles as plain data. [`Grid`] turns that into the layout the
//! hot loop wants: a dense top-level index over brick coordinates pointing into a
//! contiguous brick pool, so a lookup is index → brick → 8 loads → lerp.

use glam::{DMat4, DVec3};

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
            sum = sum.wrapping_add(mix(
                key(t.origin) ^ mix(((t.dim as u64) << 32) | t.value.to_bits() as u64) ^ 0xA5A5,
            ));
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
            for off in 0..BRICK_VOXELS {
                if leaf.active[off / 64] >> (off % 64) & 1 == 1 {
                    let d = [(off >> 6) as i32, ((off >> 3) & 7) as i32, (off & 7) as i32];
                    for a in 0..3 {
                        lo[a] = lo[a].min(leaf.origin[a] + d[a]);
                        hi[a] = hi[a].max(leaf.origin[a] + d[a]);
                    }
                    any = true;
                }
            }
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

    /// World-space axis-aligned bounds of the active region (voxel centres), or `None`.
    pub fn world_bounds(&self) -> Option<(DVec3, DVec3)> {
        let (lo, hi) = self.active_index_bounds()?;
        let mut wlo = DVec3::splat(f64::INFINITY);
        let mut whi = DVec3::splat(f64::NEG_INFINITY);
        for c in 0..8 {
            let p = DVec3::new(
                if c & 1 == 0 { lo[0] } else { hi[0] } as f64,
                if c & 2 == 0 { lo[1] } else { hi[1] } as f64,
                if c & 4 == 0 { lo[2] } else { hi[2] } as f64,
            );
            let w = self.index_to_world.transform_point3(p);
            wlo = wlo.min(w);
            whi = whi.max(w);
        }
        Some((wlo, whi))
    }
}
