//! Procedural density grids: the example scenes' clouds and the analytic media of the
//! tests are generated here, as [`RawGrid`]s like the ones readers produce.

use crate::volume::grid::{RawGrid, RawLeaf, BRICK, BRICK_VOXELS};
use glam::{DMat4, DVec3};

/// Samples `density(world position)` at the voxel centres of an index box
/// `[0, dims)` whose voxel `(i,j,k)` sits at `origin + voxel_size·(i,j,k)`. Bricks where
/// every value is 0 are left out (sparse), voxels with a value > 0 are active.
pub fn grid_from_fn(
    name: &str,
    dims: [i32; 3],
    origin: DVec3,
    voxel_size: f64,
    density: impl Fn(DVec3) -> f64 + Sync,
) -> RawGrid {
    use rayon::prelude::*;
    let bd = dims.map(|d| (d + BRICK - 1) / BRICK);
    let n = (bd[0] * bd[1] * bd[2]) as usize;
    let leaves: Vec<RawLeaf> = (0..n)
        .into_par_iter()
        .filter_map(|b| {
            let b = b as i32;
            let bo = [b % bd[0], (b / bd[0]) % bd[1], b / (bd[0] * bd[1])].map(|c| c * BRICK);
            let mut values = vec![0f32; BRICK_VOXELS];
            let mut active = [0u64; 8];
            let mut any = false;
            for off in 0..BRICK_VOXELS {
                let (x, y, z) = ((off >> 6) as i32, ((off >> 3) & 7) as i32, (off & 7) as i32);
                let ijk = [bo[0] + x, bo[1] + y, bo[2] + z];
                if ijk[0] >= dims[0] || ijk[1] >= dims[1] || ijk[2] >= dims[2] {
                    continue;
                }
                let p =
                    origin + DVec3::new(ijk[0] as f64, ijk[1] as f64, ijk[2] as f64) * voxel_size;
                let v = density(p) as f32;
                if v != 0.0 {
                    values[off] = v;
                    active[off / 64] |= 1 << (off % 64);
                    any = true;
                }
            }
            any.then_some(RawLeaf {
                origin: bo,
                values,
                active,
            })
        })
        .collect();
    RawGrid {
        name: name.to_string(),
        class: "fog volume".into(),
        background: 0.0,
        leaves,
        tiles: Vec::new(),
        index_to_world: DMat4::from_translation(origin)
            * DMat4::from_scale(DVec3::splat(voxel_size)),
    }
}

/// A deterministic value-noise fBm in [0, 1), for cloud shapes.
pub fn fbm(p: DVec3, octaves: u32) -> f64 {
    let mut sum = 0.0;
    let mut amp = 0.5;
    let mut q = p;
    for _ in 0..octaves {
        sum += amp * value_noise(q);
        q *= 2.03;
        amp *= 0.5;
    }
    sum
}

fn hash3(i: i64, j: i64, k: i64) -> f64 {
    let mut h = (i as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15)
        ^ (j as u64).wrapping_mul(0xC2B2_AE3D_27D4_EB4F)
        ^ (k as u64).wrapping_mul(0x1656_67B1_9E37_79F9);
    h ^= h >> 33;
    h = h.wrapping_mul(0xFF51_AFD7_ED55_8CCD);
    h ^= h >> 33;
    (h >> 11) as f64 / (1u64 << 53) as f64
}

fn value_noise(p: DVec3) -> f64 {
    let f = p.floor();
    let t = p - f;
    let s = t * t * (DVec3::splat(3.0) - 2.0 * t); // smoothstep
    let (i, j, k) = (f.x as i64, f.y as i64, f.z as i64);
    let mut r = 0.0;
    for c in 0..8 {
        let (dx, dy, dz) = ((c & 1) as i64, ((c >> 1) & 1) as i64, ((c >> 2) & 1) as i64);
        let w = (if dx == 1 { s.x } else { 1.0 - s.x })
            * (if dy == 1 { s.y } else { 1.0 - s.y })
            * (if dz == 1 { s.z } else { 1.0 - s.z });
        r += w * hash3(i + dx, j + dy, k + dz);
    }
    r
}

/// The example cloud: a cluster of soft spheres eroded by fBm, inside the unit-ish box
/// [-1, 1]³ (density ~1 in the core).
pub fn cloud_density(p: DVec3) -> f64 {
    let blobs = [
        (DVec3::new(0.0, -0.1, 0.0), 0.62),
        (DVec3::new(0.45, 0.05, 0.1), 0.42),
        (DVec3::new(-0.45, 0.0, -0.05), 0.45),
        (DVec3::new(0.1, 0.35, -0.1), 0.4),
    ];
    let mut shape: f64 = 0.0;
    for (c, r) in blobs {
        let d = (p - c).length() / r;
        shape = shape.max(1.0 - d);
    }
    let n = fbm(p * 3.0 + DVec3::new(11.3, 4.7, 2.1), 5);
    let v = (shape * 3.0 + (n - 0.5) * 1.6).clamp(0.0, 1.0);
    // Smooth edge ramp.
    v * v * (3.0 - 2.0 * v)
}
