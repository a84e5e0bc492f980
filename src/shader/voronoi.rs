//! Blender's Voronoi Texture node, 3D, feature F1, Euclidean distance, as Cycles 5.0
//! evaluates it (`kernel/svm/voronoi.h`: `voronoi_f1` for a float3 and the node's
//! `fractal_voronoi_x_fx` with Detail 0; `util/hash.h`: `hash_pcg3d_i`,
//! `hash_int3_to_float3`), written for Nimbus from that description:
//!
//! - the Vector times Scale; its cell `floor(c)` and the position in the cell `c − floor(c)`;
//! - each of the 27 cells at offsets −1..1 (z outermost, x innermost) holds one point,
//!   `offset + h · randomness` for the cell's hash h ∈ [0, 1]³ (PCG 3D of the integer
//!   cell, each 31-bit word as a float times 2⁻³¹);
//! - the nearest point by squared distance, the first kept on ties; Distance is its
//!   Euclidean distance, Color the hash of its cell, Position the point (cell + offset +
//!   h · randomness) divided by Scale (0 where Scale is 0).
//!
//! Normalize divides Distance by √3 (0.5 + 0.5 randomness), the node's largest F1
//! distance. Detail 0 (or Roughness 0) is one octave: only that is read; the other
//! features, metrics and dimensions are refused by the readers.
//! `tests/blender_voronoi.rs` checks it against Blender 5.0.1.

use super::interval::Interval;

/// Blender's PCG 3D integer hash (`hash_pcg3d_i`): signed 32-bit words with wrapping
/// arithmetic and an arithmetic shift, the result masked to 31 bits.
#[inline(always)]
pub fn hash_pcg3d_i(k: [i32; 3]) -> [i32; 3] {
    let [mut x, mut y, mut z] = k.map(|c| c.wrapping_mul(1_664_525).wrapping_add(1_013_904_223));
    x = x.wrapping_add(y.wrapping_mul(z));
    y = y.wrapping_add(z.wrapping_mul(x));
    z = z.wrapping_add(x.wrapping_mul(y));
    x ^= x >> 16;
    y ^= y >> 16;
    z ^= z >> 16;
    x = x.wrapping_add(y.wrapping_mul(z));
    y = y.wrapping_add(z.wrapping_mul(x));
    z = z.wrapping_add(x.wrapping_mul(y));
    [x, y, z].map(|c| c & 0x7FFF_FFFF)
}

/// `hash_int3_to_float3`: each 31-bit word as a float times 1 / float(0x7FFFFFFF)
/// (= 2⁻³¹: 0x7FFFFFFF rounds to 2³¹), so in [0, 1] with both ends reachable.
#[inline(always)]
pub fn hash_int3_to_float3(k: [i32; 3]) -> [f32; 3] {
    hash_pcg3d_i(k).map(|h| h as f32 * (1.0 / 0x7FFF_FFFF as f32))
}

/// The node's outputs at one point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VoronoiF1 {
    pub distance: f32,
    pub color: [f32; 3],
    pub position: [f32; 3],
}

/// Which output an instruction reads.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum VoronoiOutput {
    Distance,
    Color,
    Position,
}

/// The node's settings read (3D, F1, Euclidean, Detail 0).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VoronoiTexture {
    pub scale: f32,
    /// Clamped to [0, 1] as Cycles does.
    pub randomness: f32,
    pub normalize: bool,
}

impl Default for VoronoiTexture {
    /// The node's defaults.
    fn default() -> Self {
        VoronoiTexture {
            scale: 5.0,
            randomness: 1.0,
            normalize: false,
        }
    }
}

#[inline(always)]
fn dot(a: [f32; 3], b: [f32; 3]) -> f32 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

impl VoronoiTexture {
    fn randomness(&self) -> f32 {
        self.randomness.clamp(0.0, 1.0)
    }

    /// The largest F1 distance (what Normalize divides by): √3 (0.5 + 0.5 randomness),
    /// computed as Cycles does (the length of that vector).
    pub fn max_distance(&self) -> f32 {
        let m = 0.5 + 0.5 * self.randomness();
        dot([m; 3], [m; 3]).sqrt()
    }

    /// The outputs at the Vector `p`.
    #[inline]
    pub fn eval(&self, p: [f32; 3]) -> VoronoiF1 {
        let r = self.randomness();
        let coord = p.map(|c| c * self.scale);
        let cell_f = coord.map(f32::floor);
        let local: [f32; 3] = std::array::from_fn(|a| coord[a] - cell_f[a]);
        let cell = cell_f.map(|c| c as i32);
        let mut best = f32::MAX;
        let mut target_offset = [0i32; 3];
        let mut target = [0.0f32; 3];
        for k in -1..=1 {
            for j in -1..=1 {
                for i in -1..=1 {
                    let off = [i, j, k];
                    let h =
                        hash_int3_to_float3(std::array::from_fn(|a| cell[a].wrapping_add(off[a])));
                    let point: [f32; 3] = std::array::from_fn(|a| off[a] as f32 + h[a] * r);
                    let d: [f32; 3] = std::array::from_fn(|a| point[a] - local[a]);
                    let d2 = dot(d, d);
                    if d2 < best {
                        best = d2;
                        target_offset = off;
                        target = point;
                    }
                }
            }
        }
        let d: [f32; 3] = std::array::from_fn(|a| target[a] - local[a]);
        let mut distance = dot(d, d).sqrt();
        if self.normalize {
            distance /= self.max_distance();
        }
        let color = hash_int3_to_float3(std::array::from_fn(|a| {
            cell[a].wrapping_add(target_offset[a])
        }));
        let position = std::array::from_fn(|a| {
            let q = target[a] + cell_f[a];
            if self.scale != 0.0 {
                q / self.scale
            } else {
                0.0
            }
        });
        VoronoiF1 {
            distance,
            color,
            position,
        }
    }

    /// Bounds of the outputs over the Vector box `[lo, hi]`: Distance, then Color's and
    /// Position's components.
    ///
    /// In each unit cell c of the scaled box the node takes the nearest of 27 known
    /// points (the cells at offsets −1..1, their hashes computed here as in [`eval`]).
    /// Over the box's part B of the cell the distance to the nearest lies between
    /// min over points q of dist(q, B) and min over q of the largest distance from q to
    /// B (the nearest is no farther than any one point); only points q with dist(q, B)
    /// at most that upper end can be the nearest, so Color and Position lie in the hull
    /// of those points' hashes and positions. Boxes over more than 512 cells, or
    /// reaching ±2³⁰, get the global ranges: Distance in [0, √3 (0.5 + 0.5 r)] (per
    /// axis the own cell's point or the next one is within (1 + r)/2 whatever the
    /// hashes; the largest over the axis position is at (1 + r)/2), Color in [0, 1]³,
    /// Position within a cell and a randomness of the box.
    ///
    /// [`eval`]: VoronoiTexture::eval
    pub fn bounds(&self, lo: [f32; 3], hi: [f32; 3]) -> (Interval, [Interval; 3], [Interval; 3]) {
        let r = self.randomness();
        let s = self.scale;
        let l: [f32; 3] = std::array::from_fn(|a| (lo[a] * s).min(hi[a] * s));
        let h: [f32; 3] = std::array::from_fn(|a| (lo[a] * s).max(hi[a] * s));
        let norm = if self.normalize {
            self.max_distance()
        } else {
            1.0
        };
        let to_position = |iv: Interval| {
            if s != 0.0 {
                iv.div(Interval::point(s))
            } else {
                Interval::point(0.0)
            }
        };
        let first = l.map(|c| c.floor());
        let last = h.map(|c| c.floor());
        let finite = l.iter().chain(&h).all(|c| c.abs() < 1.0e9);
        let count: f64 = (0..3).map(|a| (last[a] - first[a] + 1.0) as f64).product();
        if !finite || count > 512.0 {
            let far = 3f32.sqrt() * (0.5 + 0.5 * r);
            let distance = Interval::new(0.0, far).div(Interval::point(norm));
            let position = std::array::from_fn(|a| {
                to_position(Interval::new(first[a] - 1.0, last[a] + 1.0 + r))
            });
            return (distance, [Interval::new(0.0, 1.0); 3], position);
        }
        let first = first.map(|c| c as i32);
        let last = last.map(|c| c as i32);
        let mut distance: Option<Interval> = None;
        let mut color: Option<[Interval; 3]> = None;
        let mut position: Option<[Interval; 3]> = None;
        let hull3 = |acc: &mut Option<[Interval; 3]>, v: [f32; 3]| {
            let v = v.map(Interval::point);
            *acc = Some(match acc {
                None => v,
                Some(a) => std::array::from_fn(|k| a[k].hull(v[k])),
            });
        };
        let mut candidates = Vec::with_capacity(27);
        for cz in first[2]..=last[2] {
            for cy in first[1]..=last[1] {
                for cx in first[0]..=last[0] {
                    let cell = [cx, cy, cz];
                    // The box's part of this cell, in cell-local coordinates.
                    let blo: [f32; 3] =
                        std::array::from_fn(|a| (l[a] - cell[a] as f32).clamp(0.0, 1.0));
                    let bhi: [f32; 3] =
                        std::array::from_fn(|a| (h[a] - cell[a] as f32).clamp(0.0, 1.0));
                    candidates.clear();
                    let mut upper = f32::INFINITY;
                    for k in -1..=1 {
                        for j in -1..=1 {
                            for i in -1..=1 {
                                let off = [i, j, k];
                                let key = std::array::from_fn(|a| cell[a].wrapping_add(off[a]));
                                let hash = hash_int3_to_float3(key);
                                let q: [f32; 3] =
                                    std::array::from_fn(|a| off[a] as f32 + hash[a] * r);
                                let (mut near, mut far) = (0.0f32, 0.0f32);
                                for a in 0..3 {
                                    let below = (blo[a] - q[a]).max(q[a] - bhi[a]).max(0.0);
                                    let beyond = (q[a] - blo[a]).abs().max((q[a] - bhi[a]).abs());
                                    near += below * below;
                                    far += beyond * beyond;
                                }
                                upper = upper.min(far.sqrt());
                                candidates.push((near.sqrt(), hash, q, cell));
                            }
                        }
                    }
                    let lower = candidates.iter().map(|c| c.0).fold(f32::INFINITY, f32::min);
                    let d = Interval::new(lower, upper);
                    distance = Some(distance.map_or(d, |o| o.hull(d)));
                    for &(near, hash, q, cell) in &candidates {
                        if near <= upper {
                            hull3(&mut color, hash);
                            hull3(
                                &mut position,
                                std::array::from_fn(|a| q[a] + cell[a] as f32),
                            );
                        }
                    }
                }
            }
        }
        let distance = distance
            .unwrap_or(Interval::point(0.0))
            .div(Interval::point(norm));
        let color = color.unwrap_or([Interval::new(0.0, 1.0); 3]);
        let position = position
            .unwrap_or([Interval::EVERYTHING; 3])
            .map(to_position);
        (distance, color, position)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::shader::noise::hash_uint2;

    fn next(s: &mut u32) -> f32 {
        *s = hash_uint2(*s, 0x9e37_79b9);
        *s as f32 / u32::MAX as f32
    }

    /// The bounds hold at random points of random boxes of every size class, for
    /// several scales and randomness, normalized or not.
    #[test]
    fn bounds_hold_in_random_boxes() {
        let mut s = 31u32;
        let nodes = [
            VoronoiTexture::default(),
            VoronoiTexture {
                scale: 2.5,
                randomness: 0.4,
                normalize: true,
            },
            VoronoiTexture {
                scale: -1.5,
                randomness: 0.0,
                normalize: false,
            },
        ];
        for node in nodes {
            for k in 0..1500 {
                let size = [0.01f32, 0.1, 0.6, 3.0, 200.0][k % 5];
                let lo: [f32; 3] = std::array::from_fn(|_| (next(&mut s) - 0.5) * 20.0);
                let hi: [f32; 3] = std::array::from_fn(|a| lo[a] + size * next(&mut s));
                let (d, c, p) = node.bounds(lo, hi);
                for _ in 0..40 {
                    let x: [f32; 3] =
                        std::array::from_fn(|a| lo[a] + (hi[a] - lo[a]) * next(&mut s));
                    let v = node.eval(x);
                    let ok = |iv: Interval, v: f32| v >= iv.lo - 1e-5 && v <= iv.hi + 1e-5;
                    assert!(ok(d, v.distance), "{node:?} distance {v:?} outside {d:?}");
                    for a in 0..3 {
                        assert!(ok(c[a], v.color[a]), "{node:?} colour {v:?} outside {c:?}");
                        assert!(
                            ok(p[a], v.position[a]),
                            "{node:?} position {v:?} outside {p:?}"
                        );
                    }
                }
            }
        }
    }

    /// F1 never exceeds the global bound √3 (0.5 + 0.5 r), and comes near it.
    #[test]
    fn distance_stays_under_the_global_bound() {
        let mut s = 5u32;
        for r in [0.0f32, 0.3, 1.0] {
            let node = VoronoiTexture {
                scale: 1.0,
                randomness: r,
                normalize: false,
            };
            let far = node.max_distance();
            let mut seen = 0f32;
            for _ in 0..200_000 {
                let p: [f32; 3] = std::array::from_fn(|_| (next(&mut s) - 0.5) * 100.0);
                seen = seen.max(node.eval(p).distance);
            }
            assert!(seen <= far * (1.0 + 1e-6), "r {r}: {seen} > {far}");
            eprintln!("randomness {r}: largest F1 seen {seen}, bound {far}");
        }
    }
}
