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

/// A Vec3s grid (its x, y, z components, as the readers and the VDB writer take one)
/// sampling `value(world position)` at every voxel of the box `[0, dims)` placed as in
/// [`grid_from_fn`]; every voxel is active, so the components share one topology
/// (a velocity field for the motion-blur tests and benches).
pub fn vec3_grid_from_fn(
    name: &str,
    dims: [i32; 3],
    origin: DVec3,
    voxel_size: f64,
    value: impl Fn(DVec3) -> [f64; 3] + Sync,
) -> [RawGrid; 3] {
    let mut x = grid_from_fn(name, dims, origin, voxel_size, |_| 1.0);
    let [mut y, mut z] = [x.clone(), x.clone()];
    for (lx, (ly, lz)) in x
        .leaves
        .iter_mut()
        .zip(y.leaves.iter_mut().zip(&mut z.leaves))
    {
        for off in 0..BRICK_VOXELS {
            let ijk = [(off >> 6) as i32, ((off >> 3) & 7) as i32, (off & 7) as i32];
            let p = origin
                + DVec3::new(
                    (lx.origin[0] + ijk[0]) as f64,
                    (lx.origin[1] + ijk[1]) as f64,
                    (lx.origin[2] + ijk[2]) as f64,
                ) * voxel_size;
            let v = value(p);
            (lx.values[off], ly.values[off], lz.values[off]) =
                (v[0] as f32, v[1] as f32, v[2] as f32);
        }
    }
    [x, y, z]
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
    let f = DVec3::new(floor(p.x), floor(p.y), floor(p.z));
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

/// `x.floor()` for |x| < 2⁵³ without the libm call (not inlined on baseline x86-64):
/// the same value (a signed zero aside, which `value_noise` cannot tell apart).
#[inline(always)]
fn floor(x: f64) -> f64 {
    let i = x as i64 as f64;
    if i > x {
        i - 1.0
    } else {
        i
    }
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

/// The billows of the cumulus: (centre, radius) in the grid's [-1, 1]³, x the long
/// axis. A broad, low base row, a taller central tower and smaller cauliflower heads
/// on top.
const BILLOWS: [([f64; 3], f64); 16] = [
    // Base row, sitting on the flat bottom.
    ([-0.55, -0.22, 0.05], 0.30),
    ([-0.25, -0.18, -0.12], 0.36),
    ([0.10, -0.20, 0.10], 0.38),
    ([0.45, -0.22, -0.05], 0.32),
    ([0.00, -0.22, -0.30], 0.30),
    ([-0.10, -0.24, 0.32], 0.28),
    // Middle.
    ([-0.30, 0.08, 0.02], 0.33),
    ([0.05, 0.12, -0.05], 0.40),
    ([0.38, 0.05, 0.08], 0.30),
    ([0.10, 0.10, 0.28], 0.26),
    // Tower and heads.
    ([-0.08, 0.42, 0.00], 0.30),
    ([0.22, 0.38, -0.10], 0.25),
    ([-0.32, 0.32, -0.08], 0.22),
    ([0.05, 0.62, 0.05], 0.22),
    ([0.28, 0.55, 0.10], 0.16),
    ([-0.18, 0.60, -0.12], 0.16),
];

/// The cloud base (world y of the flat bottom).
const BASE: f64 = -0.48;

/// Polynomial smooth minimum (blend width `k`).
fn smin(a: f64, b: f64, k: f64) -> f64 {
    // Far apart, the blend weight clamps to 0 or 1 whatever the division would round
    // to: skip it (the latency of the billows' chain of blends), same value.
    let q = b - a;
    let h = if q >= k * 1.000001 {
        1.0
    } else if q <= -k * 1.000001 {
        0.0
    } else {
        (0.5 + 0.5 * q / k).clamp(0.0, 1.0)
    };
    b + (a - b) * h - k * h * (1.0 - h)
}

/// The example cumulus (`scenes/cloud`, and `nimbus bench cumulus` at production
/// size): a smooth union of spherical billows cut flat at the base, its surface
/// displaced by fBm (rounded cauliflower lumps at two scales), a soft edge a few voxels
/// wide, and a denser core. Density in [0, 1], exactly 0 outside. Resolution-free: a
/// finer grid samples the same smooth field, so its interior stays smooth at voxel scale.
pub fn cumulus(p: DVec3) -> f64 {
    let mut d = cumulus_shape(p);
    // Outside the lumps' reach the density is 0: skips the fBm for most of the box
    // (the same values, since the lumps could not bring `d` below 0).
    if d >= CUMULUS_LUMP_REACH {
        return 0.0;
    }
    // Lumps: large ones mostly on top, small ones everywhere; the base stays flatter.
    let up = ((p.y - BASE) / 0.4).clamp(0.0, 1.0);
    let big = fbm(p * 3.2 + DVec3::new(5.2, 1.3, 7.9), 3) - 0.5;
    let small = fbm(p * 9.0 + DVec3::new(-3.7, 2.9, 0.4), 3) - 0.5;
    d += (0.04 + 0.2 * up) * big + (0.03 + 0.06 * up) * small;
    if d >= 0.0 {
        return 0.0;
    }
    // Soft edge over ~0.05, then denser inwards.
    let edge = (-d / 0.05).min(1.0);
    let edge = edge * edge * (3.0 - 2.0 * edge);
    let core = 0.55 + 0.45 * (-d / 0.3).min(1.0);
    let wisp = 0.8 + 0.4 * fbm(p * 14.0 + DVec3::new(1.1, 8.3, -2.2), 2);
    let v = (edge * core * wisp).clamp(0.0, 1.0);
    if v < 1e-3 {
        0.0
    } else {
        v
    }
}

/// How far the lumps can move the cumulus' surface outwards: fBm of 3 octaves lies in
/// [0, 0.875), so each lump term is at least −0.5 times its largest amplitude
/// (0.24 and 0.09), −0.165 in all; 0.17 leaves room for rounding.
const CUMULUS_LUMP_REACH: f64 = 0.17;

/// The cumulus' billows as a signed distance (negative inside), before the lumps.
/// 1-Lipschitz: a sphere's distance is, and the polynomial smooth minimum's gradient
/// is a convex combination of its arguments' (h∇a + (1 − h)∇b).
fn cumulus_shape(p: DVec3) -> f64 {
    let dist = |(c, r): ([f64; 3], f64)| (p - DVec3::from(c)).length() - r;
    let mut d = dist(BILLOWS[0]);
    for b in &BILLOWS[1..] {
        d = smin(d, dist(*b), 0.08);
    }
    // Flat bottom, slightly rounded where it meets the sides.
    -smin(-d, p.y - BASE, 0.06)
}

/// A world-space box (within [-1, 1]³) outside which [`cumulus`] is 0: the cells of a
/// lattice of spacing 1/64 whose centre lies within the lumps' reach plus the cell's
/// half-diagonal (exact by the shape's Lipschitz bound).
pub fn cumulus_bounds() -> (DVec3, DVec3) {
    const CELLS: i32 = 128;
    let s = 2.0 / CELLS as f64;
    let reach = CUMULUS_LUMP_REACH + 0.5 * s * 3f64.sqrt();
    let (mut lo, mut hi) = (DVec3::splat(1.0), DVec3::splat(-1.0));
    for k in 0..CELLS {
        for j in 0..CELLS {
            for i in 0..CELLS {
                let c = DVec3::new(i as f64, j as f64, k as f64) * s - DVec3::splat(1.0);
                if cumulus_shape(c + DVec3::splat(0.5 * s)) < reach {
                    lo = lo.min(c);
                    hi = hi.max(c + DVec3::splat(s));
                }
            }
        }
    }
    (lo, hi)
}
