//! Blender's Voronoi Texture node, 3D, one octave, every feature and metric, as Cycles 5.0
//! evaluates it (`kernel/svm/voronoi.h`: `voronoi_f1`, `voronoi_f2`,
//! `voronoi_smooth_f1`, `voronoi_distance_to_edge`, `voronoi_n_sphere_radius` for a
//! float3 and the node's `fractal_voronoi_x_fx` with Detail 0; `util/hash.h`:
//! `hash_pcg3d_i`, `hash_int3_to_float3`), written for Nimbus from that description:
//!
//! - the Vector times Scale; its cell `floor(c)` and the position in the cell `c − floor(c)`;
//! - each cell at an offset −1..1 (−2..2 for Smooth F1; z outermost, x innermost) holds
//!   one point, `offset + h · randomness` for the cell's hash h ∈ [0, 1]³ (PCG 3D of the
//!   integer cell, each 31-bit word as a float times 2⁻³¹);
//! - F1 takes the nearest point by squared distance (the first kept on ties), F2 the
//!   second nearest; Distance is its Euclidean distance, Color the hash of its cell,
//!   Position the point (cell + offset + h · randomness) divided by Scale (0 where Scale
//!   is 0);
//! - Smooth F1 blends distance, colour and position over the 125 points by a smooth
//!   minimum (Smoothness halved, in [0, 0.5]; 0 is F1);
//! - Distance to Edge is the distance to the nearest bisector between the nearest point
//!   and another; N-Sphere Radius half the distance from the nearest point to its own
//!   nearest neighbour.
//!
//! Normalize divides Distance by the feature's largest value: the metric's distance of
//! (0.5 + 0.5 randomness) on every axis for F1 and Smooth F1, twice that for F2, 0.5 +
//! 0.5 randomness for Distance to Edge.
//! Distances are the node's metric (Euclidean, Manhattan, Chebychev, Minkowski), but
//! Distance to Edge's and N-Sphere Radius', which are Euclidean (as in Cycles). Detail
//! 0 (or Roughness 0) is one octave: only that is read; other dimensions are refused by
//! the readers. `tests/blender_voronoi.rs` checks every
//! feature against Blender 5.0.1.

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

/// The node's outputs at one point (those its feature does not have are 0, as in
/// Cycles).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct VoronoiValues {
    pub distance: f32,
    pub color: [f32; 3],
    pub position: [f32; 3],
    pub radius: f32,
}

/// Bounds of the node's outputs over a box.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VoronoiBounds {
    pub distance: Interval,
    pub color: [Interval; 3],
    pub position: [Interval; 3],
    pub radius: Interval,
}

/// Which output an instruction reads.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum VoronoiOutput {
    Distance,
    Color,
    Position,
    Radius,
}

/// The node's feature (its `feature` property).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum VoronoiFeature {
    F1,
    F2,
    SmoothF1,
    DistanceToEdge,
    NSphereRadius,
}

/// The node's distance metric (its `distance` property; Minkowski with the Exponent
/// socket). Distance to Edge and N-Sphere Radius are Euclidean whatever it is (Cycles).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum VoronoiMetric {
    Euclidean,
    Manhattan,
    Chebychev,
    Minkowski(f32),
}

impl VoronoiMetric {
    /// Cycles' `voronoi_distance` of the offset `d`.
    #[inline(always)]
    pub fn distance(self, d: [f32; 3]) -> f32 {
        match self {
            VoronoiMetric::Euclidean => dot(d, d).sqrt(),
            VoronoiMetric::Manhattan => d[0].abs() + d[1].abs() + d[2].abs(),
            VoronoiMetric::Chebychev => d[0].abs().max(d[1].abs()).max(d[2].abs()),
            VoronoiMetric::Minkowski(e) => {
                (d[0].abs().powf(e) + d[1].abs().powf(e) + d[2].abs().powf(e)).powf(1.0 / e)
            }
        }
    }

    /// What the search for the nearest points compares: the squared length for
    /// Euclidean (the same order, one square root less), else the distance.
    #[inline(always)]
    fn key(self, d: [f32; 3]) -> f32 {
        match self {
            VoronoiMetric::Euclidean => dot(d, d),
            m => m.distance(d),
        }
    }

    /// The distance of a key.
    #[inline(always)]
    fn of_key(self, key: f32) -> f32 {
        match self {
            VoronoiMetric::Euclidean => key.sqrt(),
            _ => key,
        }
    }
}

/// The node's settings read (3D, Detail 0).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VoronoiTexture {
    pub scale: f32,
    /// Clamped to [0, 1] as Cycles does.
    pub randomness: f32,
    pub normalize: bool,
    pub feature: VoronoiFeature,
    /// Smooth F1's Smoothness socket (Cycles halves it and clamps it to [0, 0.5]).
    pub smoothness: f32,
    pub metric: VoronoiMetric,
    /// Octaves beyond the first (Cycles clamps it to [0, 15]; a fraction blends in a
    /// last partial octave). 0, or a Roughness of 0, is one octave.
    pub detail: f32,
    /// Each octave's weight relative to the previous one ([0, 1]).
    pub roughness: f32,
    /// Each octave's scale relative to the previous one.
    pub lacunarity: f32,
}

impl Default for VoronoiTexture {
    /// The node's defaults.
    fn default() -> Self {
        VoronoiTexture {
            scale: 5.0,
            randomness: 1.0,
            normalize: false,
            feature: VoronoiFeature::F1,
            smoothness: 1.0,
            metric: VoronoiMetric::Euclidean,
            detail: 0.0,
            roughness: 0.5,
            lacunarity: 2.0,
        }
    }
}

#[inline(always)]
fn dot(a: [f32; 3], b: [f32; 3]) -> f32 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

#[inline(always)]
fn sub(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    std::array::from_fn(|k| a[k] - b[k])
}

/// Cycles' `smoothstep(0, 1, x)`: 0 below 0, 1 above 1, x²(3 − 2x) between.
#[inline(always)]
fn smoothstep01(x: f32) -> f32 {
    if x < 0.0 {
        0.0
    } else if x >= 1.0 {
        1.0
    } else {
        x * x * (3.0 - 2.0 * x)
    }
}

/// Cycles' `mix(a, b, t)`: a + t (b − a).
#[inline(always)]
fn mix(a: f32, b: f32, t: f32) -> f32 {
    a + t * (b - a)
}

/// The cell `floor(c)` of the scaled Vector `c` (as integers and floats) and the
/// position in it.
struct Cell {
    at: [i32; 3],
    at_f: [f32; 3],
    local: [f32; 3],
}

impl VoronoiTexture {
    fn randomness(&self) -> f32 {
        self.randomness.clamp(0.0, 1.0)
    }

    /// Smooth F1's smoothness as Cycles uses it: half the socket, in [0, 0.5].
    fn smoothing(&self) -> f32 {
        (self.smoothness / 2.0).clamp(0.0, 0.5)
    }

    /// The feature evaluated: Smooth F1 with no smoothness is F1 (as Cycles).
    fn evaluated(&self) -> VoronoiFeature {
        match self.feature {
            VoronoiFeature::SmoothF1 if self.smoothing() == 0.0 => VoronoiFeature::F1,
            f => f,
        }
    }

    /// The largest F1 distance: the metric's distance of (0.5 + 0.5 randomness) on
    /// every axis (√3 times that for Euclidean), computed as Cycles does.
    pub fn max_distance(&self) -> f32 {
        let m = 0.5 + 0.5 * self.randomness();
        self.metric.distance([m; 3])
    }

    /// The metric F1, F2 and Smooth F1 use.
    fn metric_of(&self, feature: VoronoiFeature) -> VoronoiMetric {
        match feature {
            VoronoiFeature::DistanceToEdge | VoronoiFeature::NSphereRadius => {
                VoronoiMetric::Euclidean
            }
            _ => self.metric,
        }
    }

    /// What Normalize divides Distance by: F1's [`max_distance`] (twice it for F2), and
    /// 0.5 + 0.5 randomness for Distance to Edge; 1 when Normalize is off.
    ///
    /// [`max_distance`]: VoronoiTexture::max_distance
    fn normalizer(&self) -> f32 {
        if !self.normalize {
            return 1.0;
        }
        self.max_distance_param()
    }

    /// Cycles' `params.max_distance`: what Normalize divides by (after the octaves'
    /// total amplitude, with Detail).
    fn max_distance_param(&self) -> f32 {
        match self.evaluated() {
            VoronoiFeature::F2 => self.max_distance() * 2.0,
            VoronoiFeature::DistanceToEdge => 0.5 + 0.5 * self.randomness(),
            VoronoiFeature::NSphereRadius => 1.0,
            _ => self.max_distance(),
        }
    }

    /// More than one octave (Cycles' fractal Voronoi): Detail and Roughness both above
    /// 0. N-Sphere Radius has no octaves.
    pub fn is_fractal(&self) -> bool {
        self.detail != 0.0
            && self.roughness != 0.0
            && self.evaluated() != VoronoiFeature::NSphereRadius
    }

    /// The node with one octave at `scale` times this one's (no normalization): what
    /// the octaves' bounds are taken from.
    fn octave_node(&self, scale: f32) -> VoronoiTexture {
        VoronoiTexture {
            scale: self.scale * scale,
            normalize: false,
            detail: 0.0,
            ..*self
        }
    }

    fn cell(&self, p: [f32; 3]) -> Cell {
        Self::cell_of(p.map(|c| c * self.scale))
    }

    /// The cell of the scaled Vector `coord`.
    fn cell_of(coord: [f32; 3]) -> Cell {
        let at_f = coord.map(f32::floor);
        Cell {
            at: at_f.map(|c| c as i32),
            at_f,
            local: std::array::from_fn(|a| coord[a] - at_f[a]),
        }
    }

    /// The point of the cell at `off` from `cell`, in `cell`'s coordinates, and that
    /// cell's hash.
    #[inline(always)]
    fn point(&self, cell: [i32; 3], off: [i32; 3]) -> ([f32; 3], [f32; 3]) {
        let h = hash_int3_to_float3(std::array::from_fn(|a| cell[a].wrapping_add(off[a])));
        let r = self.randomness();
        (std::array::from_fn(|a| off[a] as f32 + h[a] * r), h)
    }

    /// A point in the cell `c`'s coordinates in the scaled Vector's (an octave's
    /// Position before the scales are divided out).
    fn position(c: &Cell, q: [f32; 3]) -> [f32; 3] {
        std::array::from_fn(|a| q[a] + c.at_f[a])
    }

    /// Position's output: a position in the scaled Vector's coordinates back in the
    /// Vector's (0 where Scale is 0).
    fn unscaled(&self, v: [f32; 3]) -> [f32; 3] {
        v.map(|x| {
            if self.scale != 0.0 {
                x / self.scale
            } else {
                0.0
            }
        })
    }

    /// The outputs at the Vector `p`.
    #[inline]
    pub fn eval(&self, p: [f32; 3]) -> VoronoiValues {
        if self.is_fractal() {
            return match self.evaluated() {
                VoronoiFeature::DistanceToEdge => VoronoiValues {
                    distance: self.fractal_distance_to_edge(p),
                    ..Default::default()
                },
                _ => self.fractal(p),
            };
        }
        let c = self.cell(p);
        let mut v = match self.evaluated() {
            VoronoiFeature::NSphereRadius => VoronoiValues {
                radius: self.n_sphere_radius(c.at, self.nearest(&c, VoronoiMetric::Euclidean).0),
                ..Default::default()
            },
            _ => self.octave(&c),
        };
        if self.normalize {
            v.distance /= self.normalizer();
        }
        v.position = self.unscaled(v.position);
        v
    }

    /// One octave of F1, F2, Smooth F1 or Distance to Edge in the cell `c`, its
    /// Position in the scaled Vector's coordinates.
    #[inline(always)]
    fn octave(&self, c: &Cell) -> VoronoiValues {
        match self.evaluated() {
            VoronoiFeature::F2 => self.f2(c),
            VoronoiFeature::SmoothF1 => self.smooth_f1(c),
            VoronoiFeature::DistanceToEdge => VoronoiValues {
                distance: self.distance_to_edge(c),
                ..Default::default()
            },
            _ => self.f1(c),
        }
    }

    /// Cycles' `fractal_voronoi_x_fx` (F1, F2, Smooth F1 with Detail): octaves at
    /// scales 1, lacunarity, lacunarity²…, their Distance and Color summed with
    /// amplitudes 1, roughness, roughness²…, their Position blended towards each
    /// octave's by its amplitude (`mix`, a + t(b − a)); a fractional Detail blends in
    /// a last octave by its fraction; Normalize divides the Distance by the total
    /// amplitude times the one-octave divisor and the Color by the total amplitude.
    fn fractal(&self, p: [f32; 3]) -> VoronoiValues {
        let coord = p.map(|c| c * self.scale);
        let (mut amplitude, mut max_amplitude, mut scale) = (1.0f32, 0.0f32, 1.0f32);
        let mut out = VoronoiValues::default();
        let octaves = self.detail.ceil() as i32;
        for i in 0..=octaves {
            let o = self.octave(&Self::cell_of(coord.map(|c| c * scale)));
            if i as f32 <= self.detail {
                max_amplitude += amplitude;
                out.distance += o.distance * amplitude;
                for a in 0..3 {
                    out.color[a] += o.color[a] * amplitude;
                    out.position[a] = mix(out.position[a], o.position[a] / scale, amplitude);
                }
                scale *= self.lacunarity;
                amplitude *= self.roughness;
            } else {
                let remainder = self.detail - self.detail.floor();
                if remainder != 0.0 {
                    max_amplitude = mix(max_amplitude, max_amplitude + amplitude, remainder);
                    out.distance = mix(
                        out.distance,
                        out.distance + o.distance * amplitude,
                        remainder,
                    );
                    for a in 0..3 {
                        out.color[a] = mix(
                            out.color[a],
                            out.color[a] + o.color[a] * amplitude,
                            remainder,
                        );
                        let towards = mix(out.position[a], o.position[a] / scale, amplitude);
                        out.position[a] = mix(out.position[a], towards, remainder);
                    }
                }
            }
        }
        if self.normalize {
            out.distance /= max_amplitude * self.max_distance_param();
            out.color = out.color.map(|c| c / max_amplitude);
        }
        out.position = self.unscaled(out.position);
        out
    }

    /// Cycles' `fractal_voronoi_distance_to_edge`: each octave's distance to an edge
    /// (in the first octave's units: divided by its scale) taken where it is nearer,
    /// blended in by the octave's amplitude; Normalize divides by the blend of the
    /// octaves' divisors.
    fn fractal_distance_to_edge(&self, p: [f32; 3]) -> f32 {
        let coord = p.map(|c| c * self.scale);
        let max_distance = self.max_distance_param();
        let (mut amplitude, mut max_amplitude, mut scale) = (1.0f32, max_distance, 1.0f32);
        let mut distance = 8.0f32;
        let octaves = self.detail.ceil() as i32;
        for i in 0..=octaves {
            let d = self.distance_to_edge(&Self::cell_of(coord.map(|c| c * scale)));
            if i as f32 <= self.detail {
                max_amplitude = mix(max_amplitude, max_distance / scale, amplitude);
                distance = mix(distance, distance.min(d / scale), amplitude);
                scale *= self.lacunarity;
                amplitude *= self.roughness;
            } else {
                let remainder = self.detail - self.detail.floor();
                if remainder != 0.0 {
                    let towards = mix(max_amplitude, max_distance / scale, amplitude);
                    max_amplitude = mix(max_amplitude, towards, remainder);
                    let towards = mix(distance, distance.min(d / scale), amplitude);
                    distance = mix(distance, distance.min(towards), remainder);
                }
            }
        }
        if self.normalize {
            distance /= max_amplitude;
        }
        distance
    }

    /// The nearest of the 27 points by `metric` (the first on ties): its offset, its
    /// position and its key ([`VoronoiMetric::key`]).
    fn nearest(&self, c: &Cell, metric: VoronoiMetric) -> ([i32; 3], [f32; 3], f32) {
        let mut best = f32::MAX;
        let mut target = ([0i32; 3], [0.0f32; 3]);
        for k in -1..=1 {
            for j in -1..=1 {
                for i in -1..=1 {
                    let off = [i, j, k];
                    let (q, _) = self.point(c.at, off);
                    let d2 = metric.key(sub(q, c.local));
                    if d2 < best {
                        best = d2;
                        target = (off, q);
                    }
                }
            }
        }
        (target.0, target.1, best)
    }

    fn f1(&self, c: &Cell) -> VoronoiValues {
        let (off, q, key) = self.nearest(c, self.metric);
        VoronoiValues {
            distance: self.metric.of_key(key),
            color: hash_int3_to_float3(std::array::from_fn(|a| c.at[a].wrapping_add(off[a]))),
            position: Self::position(c, q),
            radius: 0.0,
        }
    }

    /// The second nearest of the 27 points (Cycles' `voronoi_f2`).
    fn f2(&self, c: &Cell) -> VoronoiValues {
        let (mut d1, mut d2) = (f32::MAX, f32::MAX);
        let (mut first, mut second) = (([0i32; 3], [0.0f32; 3]), ([0i32; 3], [0.0f32; 3]));
        for k in -1..=1 {
            for j in -1..=1 {
                for i in -1..=1 {
                    let off = [i, j, k];
                    let (q, _) = self.point(c.at, off);
                    let dd = self.metric.key(sub(q, c.local));
                    if dd < d1 {
                        (d2, second) = (d1, first);
                        (d1, first) = (dd, (off, q));
                    } else if dd < d2 {
                        (d2, second) = (dd, (off, q));
                    }
                }
            }
        }
        let (off, q) = second;
        VoronoiValues {
            distance: self.metric.of_key(d2),
            color: hash_int3_to_float3(std::array::from_fn(|a| c.at[a].wrapping_add(off[a]))),
            position: Self::position(c, q),
            radius: 0.0,
        }
    }

    /// Smooth F1 (Cycles' `voronoi_smooth_f1`): a smooth minimum over the 125 points
    /// of the cells at offsets −2..2, each step blending the running distance, colour
    /// and position towards the point's by h = smoothstep(½ + ½ (s − d)/k) and taking
    /// off k h (1 − h) (divided by 1 + 3k for the colour and position).
    fn smooth_f1(&self, c: &Cell) -> VoronoiValues {
        let k_s = self.smoothing();
        let mut s = 8.0f32;
        let mut color = [0.0f32; 3];
        let mut pos = [0.0f32; 3];
        for k in -2..=2 {
            for j in -2..=2 {
                for i in -2..=2 {
                    let (q, hash) = self.point(c.at, [i, j, k]);
                    let dist = self.metric.distance(sub(q, c.local));
                    let h = smoothstep01(0.5 + 0.5 * (s - dist) / k_s);
                    let mut correction = k_s * h * (1.0 - h);
                    s = mix(s, dist, h) - correction;
                    correction /= 1.0 + 3.0 * k_s;
                    for a in 0..3 {
                        color[a] = mix(color[a], hash[a], h) - correction;
                        pos[a] = mix(pos[a], q[a], h) - correction;
                    }
                }
            }
        }
        VoronoiValues {
            distance: s,
            color,
            position: Self::position(c, pos),
            radius: 0.0,
        }
    }

    /// Distance to Edge (Cycles' `voronoi_distance_to_edge`): the distance to the
    /// nearest bisector plane between the nearest point and another (points within
    /// 0.01 of the nearest are skipped).
    fn distance_to_edge(&self, c: &Cell) -> f32 {
        // Cycles' two passes visit the same 27 points: their offsets from the Vector
        // are computed (and hashed) once.
        let mut to_points = [[0.0f32; 3]; 27];
        let (mut least, mut closest) = (f32::MAX, 0);
        let mut n = 0;
        for k in -1..=1 {
            for j in -1..=1 {
                for i in -1..=1 {
                    let to_point = sub(self.point(c.at, [i, j, k]).0, c.local);
                    let d2 = dot(to_point, to_point);
                    if d2 < least {
                        (least, closest) = (d2, n);
                    }
                    to_points[n] = to_point;
                    n += 1;
                }
            }
        }
        let to_closest = to_points[closest];
        let mut best = 8.0f32;
        for to_point in to_points {
            let perpendicular = sub(to_point, to_closest);
            let l2 = dot(perpendicular, perpendicular);
            if l2 > 0.0001 {
                let length = l2.sqrt();
                let n = perpendicular.map(|x| x / length);
                let mid: [f32; 3] = std::array::from_fn(|a| (to_closest[a] + to_point[a]) / 2.0);
                best = best.min(dot(mid, n));
            }
        }
        best
    }

    /// N-Sphere Radius (Cycles' `voronoi_n_sphere_radius`) of the point at offset `off`
    /// from `cell`: half its distance to the nearest of the 26 points around it. It does
    /// not depend on where in the cell the Vector is.
    fn n_sphere_radius(&self, cell: [i32; 3], off: [i32; 3]) -> f32 {
        let (closest, _) = self.point(cell, off);
        let mut best = f32::MAX;
        let mut other = [0.0f32; 3];
        for k in -1..=1 {
            for j in -1..=1 {
                for i in -1..=1 {
                    if (i, j, k) == (0, 0, 0) {
                        continue;
                    }
                    let (q, _) = self.point(cell, [i + off[0], j + off[1], k + off[2]]);
                    let d = sub(closest, q);
                    let dist = dot(d, d).sqrt();
                    if dist < best {
                        best = dist;
                        other = q;
                    }
                }
            }
        }
        let d = sub(other, closest);
        dot(d, d).sqrt() / 2.0
    }

    /// Bounds of the outputs over the Vector box `[lo, hi]`.
    ///
    /// In each unit cell c of the scaled box the node takes its points from the cells
    /// around c (their hashes computed here as in [`eval`]). Over the box's part B of the
    /// cell each point q's distance lies between dist(q, B) (near) and the largest
    /// distance from q to B (far). So:
    ///
    /// - F1 lies between the least near and the least far; F2 between the second
    ///   least of each (the k-th smallest of values each within its interval lies
    ///   between the k-th smallest ends). Only points with near at most that upper end
    ///   can be the one taken, so Color and Position lie in the hull of their hashes and
    ///   positions.
    /// - Smooth F1 runs its recurrence over the 125 points in [`eval`]'s order on
    ///   intervals: the distance by its monotonicity (`cover_smooth`), the colour and
    ///   position in interval arithmetic; a point whose h is 0 over the whole box leaves
    ///   the running values as they are, exactly as in [`eval`].
    /// - Distance to Edge: for each point p that can be nearest, the least over the
    ///   other points q of the distance to their bisector, bounded through near and far
    ///   (`cover_cell`); never below 0 but by rounding (the Vector is on the nearest
    ///   point's side of every bisector).
    /// - N-Sphere Radius depends only on the nearest point: the hull of the radii of the
    ///   points that can be nearest.
    ///
    /// Boxes over 512 cells, or reaching ±10⁹, get global ranges: F1 in [0, √3 (0.5 +
    /// 0.5 r)] (per axis the own cell's point or the next one is within (1 + r)/2
    /// whatever the hashes), F2 and Distance to Edge in [0, 2√3] (every point is within
    /// 2 of the cell per axis), Smooth F1 in [F1's range − 125 k/4], Color in [0, 1]³
    /// (Smooth F1's less its corrections), Position within a cell and a randomness of
    /// the box, the radius in [0, 1.23] (half the distance to the next cell's point).
    ///
    /// [`eval`]: VoronoiTexture::eval
    pub fn bounds(&self, lo: [f32; 3], hi: [f32; 3]) -> VoronoiBounds {
        if self.is_fractal() {
            return self.fractal_bounds(lo, hi);
        }
        let feature = self.evaluated();
        let r = self.randomness();
        let s = self.scale;
        let l: [f32; 3] = std::array::from_fn(|a| (lo[a] * s).min(hi[a] * s));
        let h: [f32; 3] = std::array::from_fn(|a| (lo[a] * s).max(hi[a] * s));
        let norm = Interval::point(self.normalizer());
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
        let mut out = Cover::default();
        if !finite || count > 512.0 {
            let metric = self.metric_of(feature);
            let far = metric.distance([0.5 + 0.5 * r; 3]);
            let far2 = metric.distance([2.0; 3]);
            let k_s = self.smoothing();
            let (distance, colour) = match feature {
                VoronoiFeature::F1 => (Interval::new(0.0, far), Interval::new(0.0, 1.0)),
                VoronoiFeature::SmoothF1 => {
                    let c = 125.0 * k_s / 4.0;
                    (Interval::new(-c, far), Interval::new(-c, 1.0))
                }
                VoronoiFeature::F2 | VoronoiFeature::DistanceToEdge => {
                    (Interval::new(0.0, far2), Interval::new(0.0, 1.0))
                }
                VoronoiFeature::NSphereRadius => (Interval::point(0.0), Interval::point(0.0)),
            };
            let below = match feature {
                VoronoiFeature::SmoothF1 => 125.0 * k_s / 4.0,
                _ => 0.0,
            };
            out.distance = Some(distance.widened(1e-5, 1e-5));
            out.color = [Some(colour.widened(1e-5, 1e-5)); 3];
            out.position = std::array::from_fn(|a| {
                Some(Interval::new(first[a] - 2.0 - below, last[a] + 2.0 + r).widened(1e-5, 1e-5))
            });
            out.radius = Some(Interval::new(0.0, 1.23));
        } else {
            let first = first.map(|c| c as i32);
            let last = last.map(|c| c as i32);
            for cz in first[2]..=last[2] {
                for cy in first[1]..=last[1] {
                    for cx in first[0]..=last[0] {
                        let cell = [cx, cy, cz];
                        // The box's part of this cell, in cell-local coordinates.
                        let blo: [f32; 3] =
                            std::array::from_fn(|a| (l[a] - cell[a] as f32).clamp(0.0, 1.0));
                        let bhi: [f32; 3] =
                            std::array::from_fn(|a| (h[a] - cell[a] as f32).clamp(0.0, 1.0));
                        match feature {
                            VoronoiFeature::SmoothF1 => self.cover_smooth(&mut out, cell, blo, bhi),
                            _ => self.cover_cell(&mut out, feature, cell, blo, bhi),
                        }
                    }
                }
            }
        }
        let zero = Interval::point(0.0);
        let (distance, color, position, radius) = match feature {
            VoronoiFeature::DistanceToEdge => (out.distance, None, None, None),
            VoronoiFeature::NSphereRadius => (None, None, None, out.radius),
            _ => (
                out.distance,
                Cover::three(out.color),
                Cover::three(out.position),
                None,
            ),
        };
        VoronoiBounds {
            distance: distance.unwrap_or(zero).div(norm),
            color: color.unwrap_or([zero; 3]),
            position: position.map_or([zero; 3], |p| p.map(to_position)),
            radius: radius.unwrap_or(zero),
        }
    }

    /// Bounds of the fractal outputs ([`fractal`], [`fractal_distance_to_edge`]) over the
    /// Vector box `[lo, hi]`, from each octave's bounds ([`bounds`] of the node at the
    /// octave's scale) combined as the octaves are: Distance and Color summed with the
    /// amplitudes (a partial octave's times its fraction), Position in the hull of the
    /// octaves' (each step moves it towards the octave's by a weight in [0, 1]), and
    /// Distance to Edge in the hull of the running distance and the octave's where the
    /// amplitude is below 1 (the first octave's exactly). The evaluation scales the
    /// Vector by Scale and then by the octave's scale, the bounds by their product: the
    /// box is widened by 1e-6 of its magnitude, which covers the difference in
    /// rounding; the results by 1e-5 relative and 1e-6 absolute for the sums'.
    ///
    /// [`fractal`]: VoronoiTexture::fractal
    /// [`fractal_distance_to_edge`]: VoronoiTexture::fractal_distance_to_edge
    /// [`bounds`]: VoronoiTexture::bounds
    fn fractal_bounds(&self, lo: [f32; 3], hi: [f32; 3]) -> VoronoiBounds {
        let margin = |a: usize| lo[a].abs().max(hi[a].abs()) * 1e-6 + 1e-30;
        let wlo: [f32; 3] = std::array::from_fn(|a| lo[a].min(hi[a]) - margin(a));
        let whi: [f32; 3] = std::array::from_fn(|a| lo[a].max(hi[a]) + margin(a));
        let edge = self.evaluated() == VoronoiFeature::DistanceToEdge;
        let max_distance = self.max_distance_param();
        let (mut amplitude, mut scale) = (1.0f32, 1.0f32);
        let mut max_amplitude = if edge { max_distance } else { 0.0 };
        let zero = Interval::point(0.0);
        let mut distance = if edge { Interval::point(8.0) } else { zero };
        let mut color = [zero; 3];
        let mut position: Option<[Interval; 3]> = None;
        let octaves = self.detail.ceil() as i32;
        for i in 0..=octaves {
            let full = i as f32 <= self.detail;
            let remainder = self.detail - self.detail.floor();
            if !full && remainder == 0.0 {
                break;
            }
            let b = self.octave_node(scale).bounds(wlo, whi);
            let weight = if full {
                amplitude
            } else {
                amplitude * remainder
            };
            if edge {
                let nearer = distance.min(b.distance.div(Interval::point(scale)));
                distance = if full && amplitude == 1.0 {
                    nearer
                } else {
                    distance.hull(nearer)
                };
            } else {
                distance = distance.add(b.distance.mul(Interval::point(weight)));
                for (c, bc) in color.iter_mut().zip(b.color) {
                    *c = c.add(bc.mul(Interval::point(weight)));
                }
                position = Some(match position {
                    None => b.position,
                    Some(p) => std::array::from_fn(|a| p[a].hull(b.position[a])),
                });
            }
            if full {
                max_amplitude = match edge {
                    true => mix(max_amplitude, max_distance / scale, amplitude),
                    false => max_amplitude + amplitude,
                };
                scale *= self.lacunarity;
                amplitude *= self.roughness;
            } else {
                max_amplitude = match edge {
                    true => mix(
                        max_amplitude,
                        mix(max_amplitude, max_distance / scale, amplitude),
                        remainder,
                    ),
                    false => mix(max_amplitude, max_amplitude + amplitude, remainder),
                };
            }
        }
        if self.normalize {
            let divisor = if edge {
                max_amplitude
            } else {
                max_amplitude * max_distance
            };
            distance = distance.div(Interval::point(divisor));
            color = color.map(|c| c.div(Interval::point(max_amplitude)));
        }
        let widen = |v: Interval| v.widened(1e-5, 1e-6);
        VoronoiBounds {
            distance: widen(distance),
            color: color.map(widen),
            position: position.map_or([zero; 3], |p| p.map(widen)),
            radius: zero,
        }
    }

    /// F1, F2, Distance to Edge and N-Sphere Radius over the part [blo, bhi] of `cell`
    /// ([`bounds`](VoronoiTexture::bounds)).
    fn cover_cell(
        &self,
        out: &mut Cover,
        feature: VoronoiFeature,
        cell: [i32; 3],
        blo: [f32; 3],
        bhi: [f32; 3],
    ) {
        let metric = self.metric_of(feature);
        // (near, far, hash, point, offset) of each of the 27 points.
        let mut points = [(0.0f32, 0.0f32, [0.0f32; 3], [0.0f32; 3], [0i32; 3]); 27];
        let mut n = 0;
        for k in -1..=1 {
            for j in -1..=1 {
                for i in -1..=1 {
                    let off = [i, j, k];
                    let (q, hash) = self.point(cell, off);
                    let (near, far) = near_far(q, blo, bhi, metric);
                    points[n] = (near, far, hash, q, off);
                    n += 1;
                }
            }
        }
        let nears = two_smallest(points.map(|p| p.0));
        let fars = two_smallest(points.map(|p| p.1));
        let rank = match feature {
            VoronoiFeature::F2 => 1,
            _ => 0,
        };
        let upper = fars[rank];
        // (With room for the rounding of eval's own distances.)
        let taken = |p: &(f32, f32, [f32; 3], [f32; 3], [i32; 3])| p.0 <= upper + 1e-5;
        match feature {
            VoronoiFeature::F1 | VoronoiFeature::F2 => {
                out.distance(Interval::new(nears[rank], upper));
                for p in points.iter().filter(|p| taken(p)) {
                    out.colour(p.2);
                    out.point(std::array::from_fn(|a| p.3[a] + cell[a] as f32));
                }
            }
            VoronoiFeature::DistanceToEdge => {
                // At x, with p the nearest point, the distance to the bisector of p and
                // q is (|x − q|² − |x − p|²) / (2 |q − p|): between (near_q² − far_p²)
                // and (far_q² − near_p²) over 2 |q − p|. The node takes the least over
                // q (skipping q within 0.01 of p: here, for the lower end, only those
                // surely skipped; for the upper, only those surely not). p is one of
                // the points that can be nearest.
                let (mut lower, mut upper) = (f32::INFINITY, f32::NEG_INFINITY);
                for p in points.iter().filter(|p| taken(p)) {
                    let (mut least_lo, mut least_hi) = (8.0f32, 8.0f32);
                    for q in &points {
                        let d = sub(q.3, p.3);
                        let l2 = dot(d, d);
                        let length = l2.sqrt();
                        if l2 > 0.99e-4 {
                            least_lo = least_lo.min((q.0 * q.0 - p.1 * p.1) / (2.0 * length));
                        }
                        if l2 > 1.01e-4 {
                            least_hi = least_hi.min((q.1 * q.1 - p.0 * p.0) / (2.0 * length));
                        }
                    }
                    lower = lower.min(least_lo);
                    upper = upper.max(least_hi);
                }
                // It is never below 0 but by rounding: x is on p's side of every
                // bisector.
                let lower = lower.max(-1e-5);
                out.distance(Interval::new(lower, upper).widened(1e-5, 1e-5));
            }
            VoronoiFeature::NSphereRadius => {
                for p in points.iter().filter(|p| taken(p)) {
                    out.radius(Interval::point(self.n_sphere_radius(cell, p.4)));
                }
            }
            VoronoiFeature::SmoothF1 => unreachable!("cover_smooth"),
        }
    }

    /// Smooth F1 over the part [blo, bhi] of `cell`: its recurrence in interval
    /// arithmetic, in [`eval`](VoronoiTexture::eval)'s order.
    fn cover_smooth(&self, out: &mut Cover, cell: [i32; 3], blo: [f32; 3], bhi: [f32; 3]) {
        let k_s = self.smoothing();
        let mut s = Interval::point(8.0);
        let mut colour = [Interval::point(0.0); 3];
        let mut pos = [Interval::point(0.0); 3];
        for k in -2..=2 {
            for j in -2..=2 {
                for i in -2..=2 {
                    let (q, hash) = self.point(cell, [i, j, k]);
                    let (near, far) = near_far(q, blo, bhi, self.metric);
                    let d = Interval::new(near, far).widened(1e-6, 1e-6);
                    // h rises with s and falls with d.
                    let t = |s: f32, d: f32| smoothstep01(0.5 + 0.5 * (s - d) / k_s);
                    let (h_lo, h_hi) = (t(s.lo, d.hi), t(s.hi, d.lo));
                    if h_hi == 0.0 {
                        // mix(x, y, 0) − 0 is x, exactly.
                        continue;
                    }
                    let g = |h: f32| h * (1.0 - h);
                    let g_hi = if h_lo <= 0.5 && 0.5 <= h_hi {
                        0.25
                    } else {
                        g(h_lo).max(g(h_hi))
                    };
                    let correction = Interval::new(k_s * g(h_lo).min(g(h_hi)), k_s * g_hi);
                    // One step of the smooth minimum rises with both the running
                    // distance and the point's (its partial derivatives are 1 − S(x) −
                    // S'(x)(x − S(x)) and S(x) + S'(x)(x − S(x)), both in [0, 1] for the
                    // smoothstep S), so its range is its value at the two corners; an
                    // interval evaluation would feed h's width back into s and grow
                    // without bound.
                    let step = |s: f32, d: f32| {
                        let h = t(s, d);
                        mix(s, d, h) - k_s * h * (1.0 - h)
                    };
                    s = Interval::new(step(s.lo, d.lo), step(s.hi, d.hi)).widened(1e-6, 1e-6);
                    let c = correction.div(Interval::point(1.0 + 3.0 * k_s));
                    for a in 0..3 {
                        colour[a] = blend(colour[a], Interval::point(hash[a]), h_lo, h_hi)
                            .sub(c)
                            .widened(1e-6, 1e-6);
                        pos[a] = blend(pos[a], Interval::point(q[a]), h_lo, h_hi)
                            .sub(c)
                            .widened(1e-6, 1e-6);
                    }
                }
            }
        }
        out.distance(s);
        for a in 0..3 {
            out.colour_interval(a, colour[a]);
            out.position_interval(
                a,
                pos[a]
                    .add(Interval::point(cell[a] as f32))
                    .widened(1e-6, 1e-6),
            );
        }
    }
}

/// The smallest and the second smallest of `v` in [`f32::total_cmp`]'s order: the
/// first two of `v` sorted. One pass instead of a sort of all 27 (which took a third of
/// the load of a stage of Voronoi graphs, `perf`).
fn two_smallest(v: [f32; 27]) -> [f32; 2] {
    use std::cmp::Ordering::Less;
    let (mut a, mut b) = match v[1].total_cmp(&v[0]) {
        Less => (v[1], v[0]),
        _ => (v[0], v[1]),
    };
    for &x in &v[2..] {
        if x.total_cmp(&a) == Less {
            (a, b) = (x, a);
        } else if x.total_cmp(&b) == Less {
            b = x;
        }
    }
    [a, b]
}

/// The least and largest `metric` distance from the point `q` to the box [blo, bhi]:
/// every metric rises with each axis' absolute offset, so these are its values at the
/// least and largest offsets per axis.
fn near_far(q: [f32; 3], blo: [f32; 3], bhi: [f32; 3], metric: VoronoiMetric) -> (f32, f32) {
    let below = std::array::from_fn(|a| (blo[a] - q[a]).max(q[a] - bhi[a]).max(0.0));
    let beyond = std::array::from_fn(|a| (q[a] - blo[a]).abs().max((q[a] - bhi[a]).abs()));
    (metric.distance(below), metric.distance(beyond))
}

/// mix(x, y, h) = (1 − h) x + h y over x, y and h ∈ [h_lo, h_hi] ⊂ [0, 1]: it rises
/// with x and y and is linear in h, so its ends are at the ends of h.
fn blend(x: Interval, y: Interval, h_lo: f32, h_hi: f32) -> Interval {
    let at = |h: f32, x: f32, y: f32| x + h * (y - x);
    Interval::new(
        at(h_lo, x.lo, y.lo).min(at(h_hi, x.lo, y.lo)),
        at(h_lo, x.hi, y.hi).max(at(h_hi, x.hi, y.hi)),
    )
}

/// The hulls [`VoronoiTexture::bounds`] gathers over the cells of a box.
#[derive(Default)]
struct Cover {
    distance: Option<Interval>,
    color: [Option<Interval>; 3],
    position: [Option<Interval>; 3],
    radius: Option<Interval>,
}

fn hull(acc: &mut Option<Interval>, v: Interval) {
    *acc = Some(acc.map_or(v, |a| a.hull(v)));
}

impl Cover {
    fn distance(&mut self, v: Interval) {
        hull(&mut self.distance, v);
    }

    fn radius(&mut self, v: Interval) {
        hull(&mut self.radius, v);
    }

    fn colour(&mut self, v: [f32; 3]) {
        for (a, x) in v.into_iter().enumerate() {
            self.colour_interval(a, Interval::point(x));
        }
    }

    fn point(&mut self, v: [f32; 3]) {
        for (a, x) in v.into_iter().enumerate() {
            self.position_interval(a, Interval::point(x));
        }
    }

    fn colour_interval(&mut self, a: usize, v: Interval) {
        hull(&mut self.color[a], v);
    }

    fn position_interval(&mut self, a: usize, v: Interval) {
        hull(&mut self.position[a], v);
    }

    /// All three components, when each has a value.
    fn three(v: [Option<Interval>; 3]) -> Option<[Interval; 3]> {
        match v {
            [Some(x), Some(y), Some(z)] => Some([x, y, z]),
            _ => None,
        }
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

    /// `two_smallest` is the first two of the sorted array, ties, signed zeros and
    /// infinities included (values drawn from a few levels so that ties are common).
    #[test]
    fn two_smallest_is_the_sorts_first_two() {
        let mut s = 7u32;
        let levels = [f32::INFINITY, -0.0, 0.0, 0.25, 0.5, 1.0, -1.0, 3.0];
        for n in 0..20_000 {
            let v: [f32; 27] = std::array::from_fn(|_| {
                let u = next(&mut s);
                match n % 2 {
                    0 => levels[(u * 7.999) as usize],
                    _ => u * 4.0 - 2.0,
                }
            });
            let mut sorted = v;
            sorted.sort_by(f32::total_cmp);
            let got = two_smallest(v);
            assert_eq!(
                got.map(f32::to_bits),
                [sorted[0], sorted[1]].map(f32::to_bits),
                "{v:?}"
            );
        }
    }

    /// The bounds hold at random points of random boxes of every size class, for
    /// several scales and randomness, normalized or not, with one octave and with
    /// several (a fractional Detail among them).
    #[test]
    fn bounds_hold_in_random_boxes() {
        let mut s = 31u32;
        let nodes = [
            VoronoiTexture::default(),
            VoronoiTexture {
                scale: 2.5,
                randomness: 0.4,
                normalize: true,
                ..Default::default()
            },
            VoronoiTexture {
                scale: -1.5,
                randomness: 0.0,
                normalize: false,
                ..Default::default()
            },
            // Fractal (stop 65): a fractional Detail with Normalize, and equal
            // amplitudes.
            VoronoiTexture {
                scale: 1.7,
                randomness: 0.9,
                normalize: true,
                detail: 2.5,
                roughness: 0.6,
                lacunarity: 2.2,
                ..Default::default()
            },
            VoronoiTexture {
                scale: 3.0,
                detail: 1.0,
                roughness: 1.0,
                lacunarity: 1.5,
                ..Default::default()
            },
        ];
        let features = [
            VoronoiFeature::F1,
            VoronoiFeature::F2,
            VoronoiFeature::SmoothF1,
            VoronoiFeature::DistanceToEdge,
            VoronoiFeature::NSphereRadius,
        ];
        let metrics = [
            VoronoiMetric::Euclidean,
            VoronoiMetric::Manhattan,
            VoronoiMetric::Chebychev,
            VoronoiMetric::Minkowski(0.5),
            VoronoiMetric::Minkowski(2.5),
        ];
        // Every feature with the node's defaults, and each again with another metric.
        let nodes = nodes.into_iter().enumerate().flat_map(|(k, n)| {
            features
                .into_iter()
                .enumerate()
                .flat_map(move |(i, feature)| {
                    [metrics[0], metrics[1 + (i + k) % 4]].map(|metric| VoronoiTexture {
                        feature,
                        // Smooth F1 at the socket's default and at its largest.
                        smoothness: [1.0, 1.0, 0.6, 1.0, 1.0][i]
                            * if n.normalize { 1.5 } else { 1.0 },
                        metric,
                        ..n
                    })
                })
        });
        for node in nodes {
            for k in 0..1500 {
                let size = [0.01f32, 0.1, 0.6, 3.0, 200.0][k % 5];
                let lo: [f32; 3] = std::array::from_fn(|_| (next(&mut s) - 0.5) * 20.0);
                let hi: [f32; 3] = std::array::from_fn(|a| lo[a] + size * next(&mut s));
                let b = node.bounds(lo, hi);
                let (d, c, p) = (b.distance, b.color, b.position);
                for _ in 0..40 {
                    let x: [f32; 3] =
                        std::array::from_fn(|a| lo[a] + (hi[a] - lo[a]) * next(&mut s));
                    let v = node.eval(x);
                    let ok = |iv: Interval, v: f32| v >= iv.lo - 1e-5 && v <= iv.hi + 1e-5;
                    assert!(ok(d, v.distance), "{node:?} distance {v:?} outside {d:?}");
                    assert!(
                        ok(b.radius, v.radius),
                        "{node:?} radius {v:?} outside {b:?}"
                    );
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

    /// The bounds are tight where the features are smooth: over boxes 0.01 wide (in
    /// the scaled units) the Distance bound of F1, F2, Smooth F1 and Distance to Edge
    /// is within 0.05 of the values seen at the box's points in at least 9 boxes of 10
    /// (a box across a cell face or an edge may be wider), and N-Sphere Radius's is a
    /// point in at least 9 of 10.
    #[test]
    fn small_boxes_get_tight_bounds() {
        let mut s = 77u32;
        for (feature, metric) in [
            (VoronoiFeature::F1, VoronoiMetric::Euclidean),
            (VoronoiFeature::F2, VoronoiMetric::Euclidean),
            (VoronoiFeature::SmoothF1, VoronoiMetric::Euclidean),
            (VoronoiFeature::DistanceToEdge, VoronoiMetric::Euclidean),
            (VoronoiFeature::NSphereRadius, VoronoiMetric::Euclidean),
            (VoronoiFeature::F1, VoronoiMetric::Manhattan),
            (VoronoiFeature::F2, VoronoiMetric::Chebychev),
            (VoronoiFeature::SmoothF1, VoronoiMetric::Minkowski(2.5)),
        ] {
            let node = VoronoiTexture {
                scale: 1.0,
                feature,
                metric,
                ..Default::default()
            };
            let mut tight = 0;
            for _ in 0..1000 {
                let lo: [f32; 3] = std::array::from_fn(|_| (next(&mut s) - 0.5) * 20.0);
                let hi = lo.map(|x| x + 0.01);
                let b = node.bounds(lo, hi);
                let iv = match feature {
                    VoronoiFeature::NSphereRadius => b.radius,
                    _ => b.distance,
                };
                let (mut seen_lo, mut seen_hi) = (f32::INFINITY, f32::NEG_INFINITY);
                for _ in 0..20 {
                    let x: [f32; 3] = std::array::from_fn(|a| lo[a] + 0.01 * next(&mut s));
                    let v = node.eval(x);
                    let v = match feature {
                        VoronoiFeature::NSphereRadius => v.radius,
                        _ => v.distance,
                    };
                    (seen_lo, seen_hi) = (seen_lo.min(v), seen_hi.max(v));
                }
                let slack = match feature {
                    VoronoiFeature::NSphereRadius => 1e-4,
                    _ => 0.05,
                };
                if seen_lo - iv.lo < slack && iv.hi - seen_hi < slack {
                    tight += 1;
                }
            }
            eprintln!("{feature:?} {metric:?}: {tight} of 1000 boxes tight");
            assert!(tight >= 900, "{feature:?} {metric:?}: {tight} of 1000");
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
                ..Default::default()
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
