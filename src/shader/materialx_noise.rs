//! MaterialX's `noise3d` and `fractal3d` (float outputs), as the MaterialX standard
//! library defines them (`libraries/stdlib/genglsl/lib/mx_noise.glsl`: Perlin noise with
//! lookup3's 3-word hash, Perlin's 12 edge gradients, the quintic fade, trilinear
//! interpolation in the nested `(1 - s) a + s b` form and the range constant 0.9820).
//!
//! It is the same lattice noise as Blender's ([`super::noise`]), written for Nimbus:
//! the hash, gradients and range constant agree, so only [`MaterialX`]'s two groupings
//! (the fade polynomial in float, the nested interpolation) and what MaterialX leaves out
//! differ. MaterialX folds no coordinates into a period, adds no distortion, and its
//! fractal is a plain sum of `octaves` whole octaves, without normalisation. Checked
//! bit for bit against a numpy transcription of the published GLSL
//! (`tests/fixtures/materialx_noise_values.py`, `tests/materialx_noise.rs`).

use super::noise::{hash_uint3, perlin_3d, Arithmetic, Blenlib, Wide};

/// The float grouping of MaterialX's GLSL: `t t t (t (6t - 15) + 10)` in single
/// precision, and the trilinear interpolation `mx_trilerp`, which is written as
/// blenlib's is.
#[derive(Clone, Copy, Debug)]
pub struct MaterialX;

impl Arithmetic for MaterialX {
    #[inline(always)]
    fn fade(t: f32) -> f32 {
        t * t * t * (t * (t * 6.0 - 15.0) + 10.0)
    }

    #[inline(always)]
    fn lerp(a: f32, b: f32, t: f32) -> f32 {
        (1.0 - t) * a + t * b
    }

    #[inline(always)]
    fn trilerp(lo: [f32; 4], hi: [f32; 4], u: f32, v: f32, w: f32) -> f32 {
        Blenlib::trilerp(lo, hi, u, v, w)
    }

    /// MaterialX folds nothing (unused here).
    #[inline(always)]
    fn remainder(a: f32) -> f32 {
        a
    }
}

/// MaterialX's signed 3D Perlin noise, about [-1, 1] (`mx_perlin_noise_float`).
/// Positions must stay below 2^31 in magnitude (MaterialX converts the floor to an
/// `int`).
#[inline]
pub fn perlin_noise_3d(p: [f32; 3]) -> f32 {
    0.9820 * perlin_3d::<MaterialX>(p[0], p[1], p[2])
}

/// `mx_fractal3d_noise_float`: `octaves` octaves of [`perlin_noise_3d`], each at
/// `lacunarity` times the frequency and `diminish` times the amplitude of the last.
/// Compiled a second time with AVX2, where the corners' hashes are 8 lanes wide, and
/// picked at run time: the same operations, so the same values (Rust fuses no
/// multiply-add it is not asked to).
#[inline]
pub fn fractal_noise_3d(p: [f32; 3], octaves: i32, lacunarity: f32, diminish: f32) -> f32 {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: the CPU has the instructions `fractal_avx2` is compiled for.
        return unsafe { fractal_avx2(p, octaves, lacunarity, diminish) };
    }
    fractal::<MaterialX>(p, octaves, lacunarity, diminish)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn fractal_avx2(p: [f32; 3], octaves: i32, lacunarity: f32, diminish: f32) -> f32 {
    fractal::<Wide<MaterialX>>(p, octaves, lacunarity, diminish)
}

#[inline(always)]
fn fractal<A: Arithmetic>(mut p: [f32; 3], octaves: i32, lacunarity: f32, diminish: f32) -> f32 {
    let mut result = 0.0f32;
    let mut amplitude = 1.0f32;
    for _ in 0..octaves {
        result += amplitude * (0.9820 * perlin_3d::<A>(p[0], p[1], p[2]));
        amplitude *= diminish;
        p = [p[0] * lacunarity, p[1] * lacunarity, p[2] * lacunarity];
    }
    result
}

/// `mx_cell_noise_float(vec3)`, the `ND_cellnoise3d_float` node: the lookup3 hash of the
/// integer cell `floor(p)` (`mx_hash_int(x, y, z)`, the hash of [`perlin_noise_3d`]'s
/// corners) mapped to [0, 1] as `mx_bits_to_01` does: `float(bits) / float(0xffffffff)`,
/// the hash rounded to a float and divided by 2^32 (0xffffffff rounds to 2^32), so both
/// ends are reached: 0 for the hash 0, 1 for hashes from 0xffffff80 on. Constant in each
/// unit cell. Coordinates beyond ±2^31 saturate (GLSL's `int()` of them is undefined).
#[inline]
pub fn cell_noise_3d(p: [f32; 3]) -> f32 {
    let [x, y, z] = p.map(|c| c.floor() as i32 as u32);
    hash_uint3(x, y, z) as f32 / u32::MAX as f32
}

/// The `ND_noise3d_float` node: `noise * amplitude + pivot`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Noise3d {
    pub amplitude: f32,
    pub pivot: f32,
}

impl Default for Noise3d {
    /// The node definition's defaults.
    fn default() -> Self {
        Noise3d {
            amplitude: 1.0,
            pivot: 0.0,
        }
    }
}

impl Noise3d {
    pub fn eval(&self, position: [f32; 3]) -> f32 {
        perlin_noise_3d(position) * self.amplitude + self.pivot
    }
}

/// The `ND_fractal3d_float` node: `fractal * amplitude`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Fractal3d {
    pub amplitude: f32,
    pub octaves: i32,
    pub lacunarity: f32,
    pub diminish: f32,
}

impl Default for Fractal3d {
    /// The node definition's defaults.
    fn default() -> Self {
        Fractal3d {
            amplitude: 1.0,
            octaves: 3,
            lacunarity: 2.0,
            diminish: 0.5,
        }
    }
}

impl Fractal3d {
    pub fn eval(&self, position: [f32; 3]) -> f32 {
        fractal_noise_3d(position, self.octaves, self.lacunarity, self.diminish) * self.amplitude
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn zero_at_lattice_points_and_one_octave_is_noise() {
        assert_eq!(perlin_noise_3d([1.0, -2.0, 7.0]), 0.0);
        let p = [0.3, -1.7, 2.2];
        assert_eq!(fractal_noise_3d(p, 1, 2.0, 0.5), perlin_noise_3d(p));
        assert_eq!(fractal_noise_3d(p, 0, 2.0, 0.5), 0.0);
    }

    #[test]
    fn cell_noise_is_constant_per_cell_and_in_0_1() {
        assert_eq!(
            cell_noise_3d([0.1, 0.2, 0.3]),
            cell_noise_3d([0.9, 0.99, 0.0])
        );
        assert_ne!(
            cell_noise_3d([0.1, 0.2, 0.3]),
            cell_noise_3d([-0.1, 0.2, 0.3])
        );
        // The bits-to-float map reaches both ends.
        assert_eq!(0u32 as f32 / u32::MAX as f32, 0.0);
        assert_eq!(u32::MAX as f32 / u32::MAX as f32, 1.0);
        for i in 0..1000 {
            let v = cell_noise_3d([i as f32 * 0.37 - 100.0, i as f32 * -0.11, 3.0]);
            assert!((0.0..=1.0).contains(&v));
        }
    }

    #[test]
    fn close_to_blenders_unfolded_noise() {
        // Same lattice, gradients and constant: equal up to the groupings' rounding.
        for i in 0..1000 {
            let p = [
                i as f32 * 0.0137 - 5.0,
                i as f32 * 0.0071 + 0.3,
                2.0 - i as f32 * 0.003,
            ];
            let b = super::super::noise::perlin_signed_3d::<Blenlib>(p);
            assert!((perlin_noise_3d(p) - b).abs() < 1e-6, "{p:?}");
        }
    }
}
