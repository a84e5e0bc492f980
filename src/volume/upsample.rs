//! Production-size benchmark grids (issue 17 part 3): a real grid upsampled by an
//! integer factor per axis with trilinear interpolation, plus procedural detail and a
//! noise-edged halo that grows the active region.
//!
//! Fine voxel `p` sits at the coarse index-space point `p / factor`, so every coarse
//! voxel centre is a fine voxel centre and, without detail, the fine grid is the coarse
//! grid's trilinear field sampled `factor`³ times more densely (exactly the values of
//! [`Grid::sample_trilinear`]). A fine voxel is active when the coarse voxel nearest to
//! it is active, or when it lies in the halo: within `halo` coarse voxels (dilation
//! steps alternating 6 and 26 neighbours, trilinearly interpolated and perturbed by noise) of the active region.
//! Everything is deterministic for a given seed; leaves are generated in parallel.

use crate::volume::grid::{floor_i32, Grid, GridError, RawGrid, RawLeaf, BRICK, BRICK_VOXELS};
use glam::DMat4;
use rayon::prelude::*;

/// Parameters of [`upsample`].
#[derive(Clone, Debug, PartialEq)]
pub struct UpsampleParams {
    /// Fine voxels per coarse voxel along each axis (1..=16).
    pub factor: i32,
    /// Width of the grown region around the active voxels, in coarse voxels (0..=64).
    pub halo: i32,
    /// Noise amplitude on the halo's edge, in coarse voxels (≥ 0).
    pub edge_noise: f32,
    /// Relative amplitude of the multiplicative detail on the upsampled density (0..=1).
    pub detail: f32,
    /// Density added inside the active region and fading out across the halo (≥ 0).
    pub halo_density: f32,
    pub seed: u64,
}

impl Default for UpsampleParams {
    fn default() -> Self {
        UpsampleParams {
            factor: 4,
            halo: 20,
            edge_noise: 1.5,
            detail: 0.5,
            halo_density: 0.05,
            seed: 17,
        }
    }
}

/// Largest coarse distance array (cells) [`upsample`] allocates.
const MAX_COARSE_CELLS: u64 = 1 << 30;

/// Most fine leaves the generator considers (each up to 2 KiB of values: 8.6 GB at the
/// limit). smoke.vdb at the defaults has about 0.8 M.
const MAX_CANDIDATE_LEAVES: u64 = 1 << 22;

fn unsupported(raw: &RawGrid, message: String) -> GridError {
    GridError::Unsupported {
        grid: raw.name.clone(),
        message,
    }
}

/// The upsampled grid; see the module documentation. Errors name the grid.
pub fn upsample(raw: &RawGrid, params: &UpsampleParams) -> Result<RawGrid, GridError> {
    let p = params;
    if !(1..=16).contains(&p.factor) {
        return Err(unsupported(
            raw,
            format!("upsampling factor {} outside 1..=16", p.factor),
        ));
    }
    if !(0..=64).contains(&p.halo) {
        return Err(unsupported(raw, format!("halo {} outside 0..=64", p.halo)));
    }
    let finite_nonneg = |v: f32| v.is_finite() && v >= 0.0;
    if !finite_nonneg(p.edge_noise)
        || !finite_nonneg(p.halo_density)
        || !(finite_nonneg(p.detail) && p.detail <= 1.0)
    {
        return Err(unsupported(
            raw,
            "edge noise and halo density must be finite and ≥ 0, detail in [0, 1]".into(),
        ));
    }
    let coarse = Grid::from_raw(raw)?;
    let mut out = RawGrid {
        name: raw.name.clone(),
        class: raw.class.clone(),
        background: raw.background,
        leaves: Vec::new(),
        tiles: Vec::new(),
        index_to_world: raw.index_to_world
            * DMat4::from_scale(glam::DVec3::splat(1.0 / p.factor as f64)),
    };
    let Some((lo, hi)) = raw.active_index_bounds() else {
        return Ok(out);
    };
    let dist = Distance::new(raw, lo, hi, p.halo)?;
    let f = p.factor;
    // Fine voxels that can be active: nearest coarse voxel within the dilated box.
    let flo = [0, 1, 2].map(|a| (dist.lo[a]) * f - f / 2);
    let fhi = [0, 1, 2].map(|a| (dist.lo[a] + dist.dims[a] - 1) * f + (f - 1) / 2 + f);
    let llo = flo.map(|c| c.div_euclid(BRICK));
    let lhi = fhi.map(|c| c.div_euclid(BRICK));
    let ldims = [0, 1, 2].map(|a| (lhi[a] - llo[a] + 1) as usize);
    let leaf_count = ldims[0] * ldims[1] * ldims[2];
    // Every candidate may become a 2 KiB leaf: refuse before allocating what the machine
    // may not have, rather than being killed for it.
    if leaf_count as u64 > MAX_CANDIDATE_LEAVES {
        return Err(unsupported(
            raw,
            format!(
                "factor {f} and halo {} make {}x{}x{} candidate leaves of 8³ voxels (up to {:.1} GB); more than the generator's limit of {MAX_CANDIDATE_LEAVES}",
                p.halo,
                ldims[0],
                ldims[1],
                ldims[2],
                leaf_count as f64 * (BRICK_VOXELS * 4) as f64 / 1e9
            ),
        ));
    }
    let leaves: Vec<RawLeaf> = (0..leaf_count)
        .into_par_iter()
        .filter_map(|n| {
            let l = [
                n % ldims[0],
                (n / ldims[0]) % ldims[1],
                n / (ldims[0] * ldims[1]),
            ];
            let origin = [0, 1, 2].map(|a| (llo[a] + l[a] as i32) * BRICK);
            make_leaf(&coarse, &dist, p, origin)
        })
        .collect();
    out.leaves = leaves;
    Ok(out)
}

/// Coarse distance (in dilation steps, alternating 6 and 26 neighbours) to the active voxels, over the
/// active bounds grown by `halo + 1`; `halo + 1` means "beyond the halo".
struct Distance {
    lo: [i32; 3],
    dims: [i32; 3],
    d: Vec<u8>,
    far: u8,
}

impl Distance {
    fn new(raw: &RawGrid, lo: [i32; 3], hi: [i32; 3], halo: i32) -> Result<Distance, GridError> {
        let pad = halo + 1;
        let dlo = lo.map(|c| c - pad);
        let dims = [0, 1, 2].map(|a| hi[a] - lo[a] + 1 + 2 * pad);
        let cells = dims.iter().map(|&d| d as u64).product::<u64>();
        if cells > MAX_COARSE_CELLS {
            return Err(unsupported(
                raw,
                format!(
                    "active bounds plus halo span {}x{}x{} voxels; more than the generator's limit of {} voxels",
                    dims[0], dims[1], dims[2], MAX_COARSE_CELLS
                ),
            ));
        }
        let far = (halo + 1) as u8;
        let mut dist = Distance {
            lo: dlo,
            dims,
            d: vec![far; cells as usize],
            far,
        };
        let mut set = |q: [i32; 3]| {
            if let Some(i) = dist.at(q) {
                dist.d[i] = 0;
            }
        };
        for leaf in &raw.leaves {
            for off in 0..BRICK_VOXELS {
                if leaf.active[off / 64] >> (off % 64) & 1 == 1 {
                    let d = [(off >> 6) as i32, ((off >> 3) & 7) as i32, (off & 7) as i32];
                    set([0, 1, 2].map(|a| leaf.origin[a] + d[a]));
                }
            }
        }
        for t in raw.tiles.iter().filter(|t| t.active) {
            for z in t.origin[2]..t.origin[2] + t.dim {
                for y in t.origin[1]..t.origin[1] + t.dim {
                    for x in t.origin[0]..t.origin[0] + t.dim {
                        set([x, y, z]);
                    }
                }
            }
        }
        for step in 1..=halo as u8 {
            let prev = dist.d.clone();
            let (nx, ny) = (dims[0] as usize, dims[1] as usize);
            let strides = [1usize, nx, nx * ny];
            dist.d
                .par_chunks_mut(nx * ny)
                .enumerate()
                .for_each(|(z, slab)| {
                    for y in 0..ny {
                        for x in 0..nx {
                            let i = (z * ny + y) * nx + x;
                            if prev[i] != far {
                                continue;
                            }
                            let c = [x, y, z];
                            // Odd steps grow along the 6 face neighbours, even steps
                            // along all 26: an octagonal, roughly round dilation.
                            let near = if step % 2 == 1 {
                                (0..3).any(|a| {
                                    (c[a] > 0 && prev[i - strides[a]] < step)
                                        || (c[a] + 1 < dims[a] as usize
                                            && prev[i + strides[a]] < step)
                                })
                            } else {
                                let r = |a: usize| {
                                    c[a].saturating_sub(1)..=(c[a] + 1).min(dims[a] as usize - 1)
                                };
                                r(2).any(|zz| {
                                    r(1).any(|yy| {
                                        r(0).any(|xx| prev[(zz * ny + yy) * nx + xx] < step)
                                    })
                                })
                            };
                            if near {
                                slab[y * nx + x] = step;
                            }
                        }
                    }
                });
        }
        Ok(dist)
    }

    #[inline]
    fn at(&self, q: [i32; 3]) -> Option<usize> {
        let r = [0, 1, 2].map(|a| q[a] - self.lo[a]);
        if (0..3).all(|a| (r[a] as u32) < self.dims[a] as u32) {
            Some(((r[2] * self.dims[1] + r[1]) * self.dims[0] + r[0]) as usize)
        } else {
            None
        }
    }

    #[inline]
    fn get(&self, q: [i32; 3]) -> f32 {
        self.at(q).map_or(self.far, |i| self.d[i]) as f32
    }

    /// Trilinear interpolation at the continuous coarse point `c`.
    #[inline]
    fn trilinear(&self, c: [f32; 3]) -> f32 {
        let i = c.map(floor_i32);
        let t = [0, 1, 2].map(|a| c[a] - i[a] as f32);
        let mut v = 0.0;
        for n in 0..8 {
            let d = [(n >> 2) & 1, (n >> 1) & 1, n & 1];
            let w = (0..3)
                .map(|a| if d[a] == 1 { t[a] } else { 1.0 - t[a] })
                .product::<f32>();
            if w > 0.0 {
                v += w * self.get([i[0] + d[0], i[1] + d[1], i[2] + d[2]]);
            }
        }
        v
    }

    /// Minimum over the coarse box `[lo, hi]` (inclusive).
    fn min_over(&self, lo: [i32; 3], hi: [i32; 3]) -> u8 {
        let mut m = self.far;
        for z in lo[2]..=hi[2] {
            for y in lo[1]..=hi[1] {
                for x in lo[0]..=hi[0] {
                    if let Some(i) = self.at([x, y, z]) {
                        m = m.min(self.d[i]);
                    }
                }
            }
        }
        m
    }
}

/// One fine leaf at `origin`, or `None` when none of its voxels is active.
fn make_leaf(
    coarse: &Grid,
    dist: &Distance,
    p: &UpsampleParams,
    origin: [i32; 3],
) -> Option<RawLeaf> {
    let f = p.factor;
    let halo = p.halo as f32;
    // Coarse voxels whose distance the leaf's voxels can read (nearest and trilinear).
    let clo = origin.map(|c| (c - f).div_euclid(f));
    let chi = origin.map(|c| (c + BRICK + f).div_euclid(f));
    let dmin = dist.min_over(clo, chi) as f32;
    if dmin > 0.0 && dmin > halo + p.edge_noise {
        return None;
    }
    let inv = 1.0 / f as f32;
    let mut values = vec![0f32; BRICK_VOXELS];
    let mut active = [0u64; 8];
    let mut any = false;
    let edge_noise = LeafNoise::new(origin, p.seed);
    let detail_noise = LeafNoise::new(origin, p.seed ^ 0x5EED_0001);
    let halo_noise = LeafNoise::new(origin, p.seed ^ 0x5EED_0002);
    for off in 0..BRICK_VOXELS {
        let q = [
            origin[0] + (off >> 6) as i32,
            origin[1] + ((off >> 3) & 7) as i32,
            origin[2] + (off & 7) as i32,
        ];
        let nearest = q.map(|c| (c + f / 2).div_euclid(f));
        let c = q.map(|v| v as f32 * inv);
        let inside = dist.get(nearest) == 0.0;
        if !inside && p.halo == 0 {
            continue;
        }
        let d = if inside && p.halo_density == 0.0 {
            0.0
        } else {
            dist.trilinear(c)
        };
        if !inside && d + p.edge_noise * edge_noise.at(q) > halo {
            continue;
        }
        any = true;
        active[off / 64] |= 1 << (off % 64);
        let base = coarse.sample_trilinear(c);
        let mut v = if p.detail > 0.0 {
            base * (1.0 + p.detail * detail_noise.at(q))
        } else {
            base
        };
        if p.halo_density > 0.0 {
            let fade = (1.0 - d / (halo + 1.0)).clamp(0.0, 1.0);
            v += p.halo_density * fade * fade * (0.5 + 0.5 * halo_noise.at(q));
        }
        values[off] = v.max(0.0);
    }
    any.then_some(RawLeaf {
        origin,
        values,
        active,
    })
}

#[inline(always)]
fn hash(x: i32, y: i32, z: i32, seed: u64) -> f32 {
    let mut h = seed
        ^ (x as u32 as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15)
        ^ (y as u32 as u64).wrapping_mul(0xC2B2_AE3D_27D4_EB4F)
        ^ (z as u32 as u64).wrapping_mul(0x1656_67B1_9E37_79F9);
    h = (h ^ (h >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    h = (h ^ (h >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    h ^= h >> 31;
    // Top 24 bits → [-1, 1).
    (h >> 40) as f32 * (2.0 / (1u64 << 24) as f32) - 1.0
}

/// Three octaves of value noise (lattices of 32, 16 and 8 fine voxels, weights 4:2:1)
/// over one leaf, in [-1, 1]: a leaf (8-aligned) lies inside one lattice cell of each
/// octave, so the 3 × 8 lattice values are hashed once per leaf.
struct LeafNoise {
    origin: [i32; 3],
    corners: [[f32; 8]; 3],
}

const OCTAVES: [(u32, f32); 3] = [(5, 4.0 / 7.0), (4, 2.0 / 7.0), (3, 1.0 / 7.0)];

impl LeafNoise {
    fn new(origin: [i32; 3], seed: u64) -> LeafNoise {
        let corners = std::array::from_fn(|o| {
            let (shift, _) = OCTAVES[o];
            let cell = origin.map(|c| c >> shift);
            let s = seed.wrapping_add(o as u64);
            std::array::from_fn(|n| {
                let d = [(n >> 2) as i32 & 1, (n >> 1) as i32 & 1, n as i32 & 1];
                hash(cell[0] + d[0], cell[1] + d[1], cell[2] + d[2], s)
            })
        });
        LeafNoise { origin, corners }
    }

    /// The noise at fine voxel `q` of this leaf.
    #[inline]
    fn at(&self, q: [i32; 3]) -> f32 {
        let mut v = 0.0;
        for (o, &(shift, weight)) in OCTAVES.iter().enumerate() {
            let scale = 1.0 / (1u32 << shift) as f32;
            let t = [0, 1, 2].map(|a| {
                let u = (q[a] - ((self.origin[a] >> shift) << shift)) as f32 * scale;
                u * u * (3.0 - 2.0 * u)
            });
            let c = &self.corners[o];
            let lz = |a: f32, b: f32| a + (b - a) * t[2];
            let c00 = lz(c[0], c[1]);
            let c01 = lz(c[2], c[3]);
            let c10 = lz(c[4], c[5]);
            let c11 = lz(c[6], c[7]);
            let c0 = c00 + (c01 - c00) * t[1];
            let c1 = c10 + (c11 - c10) * t[1];
            v += weight * (c0 + (c1 - c0) * t[0]);
        }
        v
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::volume::grid::RawTile;

    fn coarse() -> RawGrid {
        // Two leaves, partly active, with a smooth-ish field and one active tile.
        let leaf = |origin: [i32; 3], salt: usize| RawLeaf {
            origin,
            values: (0..BRICK_VOXELS)
                .map(|i| ((i * 7 + salt * 13) % 23) as f32 * 0.125)
                .collect(),
            active: [
                0xF0F0_F0F0_FFFF_0000 ^ salt as u64,
                u64::MAX,
                0,
                0x1234,
                7,
                0,
                u64::MAX,
                1,
            ],
        };
        RawGrid {
            name: "density".into(),
            class: "fog volume".into(),
            background: 0.0,
            leaves: vec![leaf([0, 0, 0], 1), leaf([8, 0, 0], 2), leaf([0, 8, -8], 3)],
            tiles: vec![RawTile {
                origin: [16, 16, 16],
                dim: 8,
                value: 0.75,
                active: true,
            }],
            index_to_world: DMat4::from_scale(glam::DVec3::splat(0.5)),
        }
    }

    fn plain(factor: i32) -> UpsampleParams {
        UpsampleParams {
            factor,
            halo: 0,
            edge_noise: 0.0,
            detail: 0.0,
            halo_density: 0.0,
            seed: 1,
        }
    }

    /// Without detail the fine grid is the coarse trilinear field: coarse voxel centres
    /// exactly, in-between points as `sample_trilinear`; each active coarse voxel owns
    /// factor³ active fine voxels.
    #[test]
    fn plain_upsampling_is_the_trilinear_field() {
        let raw = coarse();
        let g = Grid::from_raw(&raw).unwrap();
        for factor in [1, 2, 4] {
            let up = upsample(&raw, &plain(factor)).unwrap();
            assert_eq!(
                up.active_voxel_count(),
                raw.active_voxel_count() * (factor as u64).pow(3),
                "factor {factor}"
            );
            let fine = Grid::from_raw(&up).unwrap();
            let (lo, hi) = raw.active_index_bounds().unwrap();
            for z in lo[2]..=hi[2] {
                for y in lo[1]..=hi[1] {
                    for x in lo[0]..=hi[0] {
                        let fq = [x * factor, y * factor, z * factor];
                        let fv = fine.voxel(fq);
                        // Inactive fine voxels hold 0; active ones the coarse value.
                        assert!(
                            fv.to_bits() == g.voxel([x, y, z]).to_bits() || fv == 0.0,
                            "({x},{y},{z}) x{factor}: {fv} vs {}",
                            g.voxel([x, y, z])
                        );
                        if factor == 2 && fv != 0.0 {
                            let mid = [fq[0] + 1, fq[1] + 1, fq[2] + 1];
                            let c = [x as f32 + 0.5, y as f32 + 0.5, z as f32 + 0.5];
                            let m = fine.voxel(mid);
                            assert!(m == 0.0 || m.to_bits() == g.sample_trilinear(c).to_bits());
                        }
                    }
                }
            }
            // The world position of coarse voxel k is that of fine voxel factor·k.
            let w = up
                .index_to_world
                .transform_point3(glam::DVec3::splat(4.0 * factor as f64));
            assert_eq!(
                w,
                raw.index_to_world.transform_point3(glam::DVec3::splat(4.0))
            );
        }
    }

    /// The halo grows the active region; the result is deterministic and depends on
    /// the seed.
    #[test]
    fn halo_grows_and_is_deterministic() {
        let raw = coarse();
        let params = UpsampleParams {
            halo: 3,
            ..UpsampleParams::default()
        };
        let a = upsample(&raw, &params).unwrap();
        let b = upsample(&raw, &params).unwrap();
        assert_eq!(a.checksum(), b.checksum());
        assert!(a.active_voxel_count() > raw.active_voxel_count() * 64);
        let c = upsample(
            &raw,
            &UpsampleParams {
                seed: 2,
                ..params.clone()
            },
        )
        .unwrap();
        assert_ne!(a.checksum(), c.checksum());
        assert!(a
            .leaves
            .iter()
            .all(|l| l.values.iter().all(|v| v.is_finite() && *v >= 0.0)));
    }

    #[test]
    fn bad_parameters_are_errors_naming_the_grid() {
        let raw = coarse();
        for params in [
            UpsampleParams {
                factor: 0,
                ..plain(1)
            },
            UpsampleParams {
                halo: 65,
                ..plain(1)
            },
            UpsampleParams {
                detail: 2.0,
                ..plain(1)
            },
            UpsampleParams {
                halo_density: f32::NAN,
                ..plain(1)
            },
        ] {
            let e = upsample(&raw, &params).unwrap_err().to_string();
            assert!(e.contains("density"), "{e}");
        }
        // Too large an output is refused before anything is allocated for it.
        let e = upsample(
            &raw,
            &UpsampleParams {
                halo: 64,
                ..plain(16)
            },
        )
        .unwrap_err()
        .to_string();
        assert!(
            e.contains("density") && e.contains("candidate leaves"),
            "{e}"
        );
    }
}
