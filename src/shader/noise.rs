//! Blender's Noise Texture, evaluated as Cycles 5.0 evaluates it.
//!
//! A scene made in Blender that drives a volume's density with a Noise Texture renders the
//! same in Nimbus only if Nimbus computes the same function: the same lattice hash, the
//! same gradients, the same remapping constants and the same handling of large
//! coordinates. This module implements that algorithm from its published description
//! (Perlin's "Improving Noise", 2002, with the integer hash of Bob Jenkins' lookup3 and the
//! range constants of Open Shading Language, as Cycles' SVM uses them), written for Nimbus.
//!
//! Pieces, bottom up:
//! - [`hash_uint3`], [`hash_uint4`]: lookup3's final mix over 3 or 4 words (4 words need
//!   one full mix first), hashing the integer lattice corners.
//! - [`perlin_signed_3d`], [`perlin_signed_4d`]: gradient noise scaled to about [-1, 1],
//!   after folding coordinates into one period of 100000 (Cycles' guard against float
//!   precision loss far from the origin).
//! - fractal sums over octaves ([`NoiseType`]): fBM, multifractal, heterogeneous terrain,
//!   hybrid multifractal and ridged multifractal, with Blender's fractional Detail.
//! - [`NoiseTexture`]: the node itself, Scale, Distortion (the position displaced by
//!   three or four more noises at fixed random offsets) and the Color output (two more
//!   evaluations at other fixed offsets).
//!
//! **Floating-point order.** Blender has two implementations of this one algorithm,
//! Cycles' SVM (`intern/cycles/kernel/svm/noise.h`, `fractal_noise.h`, `noisetex.h`) and
//! blenlib's (`BLI_noise`, which Geometry Nodes uses), and Cycles
//! itself compiles its kernel twice on x86-64: for SSE4.2 and, picked at run time on any
//! CPU that has it, for AVX2 with `-mfma -ffp-contract=fast -freciprocal-math`, where the
//! compiler fuses multiplies into adds. They agree to about 1e-7 but not to the bit. The
//! differences are confined to a few operations, which [`Arithmetic`] names: the fade
//! polynomial, linear interpolation, the trilinear and quadrilinear orders, the period
//! fold and the fractals' multiply-adds. [`CyclesAvx2`] reproduces Cycles' AVX2 kernel
//! and [`Blenlib`] Geometry Nodes, each bit for bit (`tests/blender_noise.rs` checks both
//! against bpy 5.0.1 at 190,000 points: every Fac and Color value equal);
//! [`CyclesSse`] is the SSE4.2 kernel as read from the source, not checked against a
//! render. [`NoiseTexture::eval`] uses [`CyclesAvx2`]: what Cycles renders on any x86-64
//! CPU since 2013, and within float rounding of the others (docs/shaders.md has the
//! measured differences).

use std::ops::{Add, Mul};

// ---------------------------------------------------------------------------------------
// Hashing: Bob Jenkins' lookup3 (burtleburtle.net/bob/c/lookup3.c), as its `final` and
// `mix` steps are used on 1 to 4 words with the initial value 0xdeadbeef + 4n + 13.
// ---------------------------------------------------------------------------------------

/// lookup3's `final`: the last avalanche of the three state words; the hash is `c`.
#[inline(always)]
const fn lookup3_final(mut a: u32, mut b: u32, mut c: u32) -> u32 {
    c ^= b;
    c = c.wrapping_sub(b.rotate_left(14));
    a ^= c;
    a = a.wrapping_sub(c.rotate_left(11));
    b ^= a;
    b = b.wrapping_sub(a.rotate_left(25));
    c ^= b;
    c = c.wrapping_sub(b.rotate_left(16));
    a ^= c;
    a = a.wrapping_sub(c.rotate_left(4));
    b ^= a;
    b = b.wrapping_sub(a.rotate_left(14));
    c ^= b;
    c.wrapping_sub(b.rotate_left(24))
}

/// lookup3's `mix`: needed once when more than three words are hashed.
#[inline(always)]
const fn lookup3_mix(mut a: u32, mut b: u32, mut c: u32) -> (u32, u32, u32) {
    a = a.wrapping_sub(c);
    a ^= c.rotate_left(4);
    c = c.wrapping_add(b);
    b = b.wrapping_sub(a);
    b ^= a.rotate_left(6);
    a = a.wrapping_add(c);
    c = c.wrapping_sub(b);
    c ^= b.rotate_left(8);
    b = b.wrapping_add(a);
    a = a.wrapping_sub(c);
    a ^= c.rotate_left(16);
    c = c.wrapping_add(b);
    b = b.wrapping_sub(a);
    b ^= a.rotate_left(19);
    a = a.wrapping_add(c);
    c = c.wrapping_sub(b);
    c ^= b.rotate_left(4);
    b = b.wrapping_add(a);
    (a, b, c)
}

/// lookup3's initial state for `n` 32-bit words.
#[inline(always)]
const fn lookup3_init(n: u32) -> u32 {
    0xdeadbeef_u32.wrapping_add(n << 2).wrapping_add(13)
}

/// Hash of one word (Blender's White Noise in 1D).
#[inline(always)]
pub const fn hash_uint(kx: u32) -> u32 {
    let init = lookup3_init(1);
    lookup3_final(init.wrapping_add(kx), init, init)
}

/// Hash of two words (the seeds of the random offsets are hashed as two floats' bits).
#[inline(always)]
pub const fn hash_uint2(kx: u32, ky: u32) -> u32 {
    let init = lookup3_init(2);
    lookup3_final(init.wrapping_add(kx), init.wrapping_add(ky), init)
}

/// Hash of three words: one 3D lattice corner.
#[inline(always)]
pub const fn hash_uint3(kx: u32, ky: u32, kz: u32) -> u32 {
    let init = lookup3_init(3);
    lookup3_final(
        init.wrapping_add(kx),
        init.wrapping_add(ky),
        init.wrapping_add(kz),
    )
}

/// Hash of four words: one 4D lattice corner. lookup3 takes words three at a time, so
/// the first three are mixed before the fourth joins.
#[inline(always)]
pub const fn hash_uint4(kx: u32, ky: u32, kz: u32, kw: u32) -> u32 {
    let init = lookup3_init(4);
    let (a, b, c) = lookup3_mix(
        init.wrapping_add(kx),
        init.wrapping_add(ky),
        init.wrapping_add(kz),
    );
    lookup3_final(a.wrapping_add(kw), b, c)
}

/// A hash mapped to [0, 1], both ends included: the integer as a float times 2^-32
/// (`u32::MAX` rounds to 2^32 in float, so the factor is exact).
const fn uint_to_unit_float(n: u32) -> f32 {
    n as f32 * (1.0 / u32::MAX as f32)
}

/// Two floats hashed by their bit patterns to [0, 1].
pub const fn hash_float2_to_float(x: f32, y: f32) -> f32 {
    uint_to_unit_float(hash_uint2(x.to_bits(), y.to_bits()))
}

/// Up to four floats hashed by their bit patterns to [0, 1] (Cycles'
/// `hash_float*_to_float`).
#[inline(always)]
fn hash_floats_to_float(words: &[f32]) -> f32 {
    uint_to_unit_float(match *words {
        [a] => hash_uint(a.to_bits()),
        [a, b] => hash_uint2(a.to_bits(), b.to_bits()),
        [a, b, c] => hash_uint3(a.to_bits(), b.to_bits(), c.to_bits()),
        [a, b, c, d] => hash_uint4(a.to_bits(), b.to_bits(), c.to_bits(), d.to_bits()),
        _ => 0,
    })
}

/// Blender's White Noise Texture's Value (Cycles' `svm_node_tex_white_noise`): the bit
/// patterns of the first `dims` coordinates hashed to [0, 1] — 1D `w`; 2D `x y`; 3D
/// `x y z`; 4D `x y z w` of `k = [x, y, z, w]`.
#[inline]
pub fn white_noise_value(k: [f32; 4], dims: u8) -> f32 {
    let [x, y, z, w] = k;
    match dims {
        1 => hash_floats_to_float(&[w]),
        2 => hash_floats_to_float(&[x, y]),
        3 => hash_floats_to_float(&[x, y, z]),
        _ => hash_floats_to_float(&[x, y, z, w]),
    }
}

/// The White Noise Texture's Color: the Value, then the same words with 1 and with 2
/// appended (1D to 3D), or permuted (4D: z x w y, then w z y x).
#[inline]
pub fn white_noise_color(k: [f32; 4], dims: u8) -> [f32; 3] {
    let h = hash_floats_to_float;
    let [x, y, z, w] = k;
    match dims {
        1 => [h(&[w]), h(&[w, 1.0]), h(&[w, 2.0])],
        2 => [h(&[x, y]), h(&[x, y, 1.0]), h(&[x, y, 2.0])],
        3 => [h(&[x, y, z]), h(&[x, y, z, 1.0]), h(&[x, y, z, 2.0])],
        _ => [h(&[x, y, z, w]), h(&[z, x, w, y]), h(&[w, z, y, x])],
    }
}

// ---------------------------------------------------------------------------------------
// The fixed offsets that stand in for seeds.
// ---------------------------------------------------------------------------------------

/// Component `axis` of the pseudo-random offset number `seed`, in [100, 200]: Perlin
/// noise has no seed, so Distortion and the Color output evaluate it at positions moved
/// by these offsets, far enough to be uncorrelated and near enough to keep precision.
const fn random_offset(seed: f32, axis: f32) -> f32 {
    100.0 + hash_float2_to_float(seed, axis) * 100.0
}

/// The offset number `seed` in 2 to 4 dimensions: component `axis` hashes (seed, axis).
const fn offset<const N: usize>(seed: f32) -> [f32; N] {
    let mut o = [0.0f32; N];
    let mut axis = 0;
    while axis < N {
        o[axis] = random_offset(seed, axis as f32);
        axis += 1;
    }
    o
}

/// The 1D offset of `seed`: one word hashed (Cycles' `random_float_offset`), not the
/// pair (seed, axis) of the other dimensions.
const fn offset1(seed: f32) -> [f32; 1] {
    [100.0 + uint_to_unit_float(hash_uint(seed.to_bits())) * 100.0]
}

/// 1D offsets: seed 0 distorts W; seeds 1 and 2 give Color's green and blue.
const OFFSETS_1D: [[f32; 1]; 3] = [offset1(0.0), offset1(1.0), offset1(2.0)];

/// 2D offsets: seeds 0 and 1 distort x and y; seeds 2 and 3 give Color's green and blue.
const OFFSETS_2D: [[f32; 2]; 4] = [
    offset::<2>(0.0),
    offset::<2>(1.0),
    offset::<2>(2.0),
    offset::<2>(3.0),
];

/// 3D offsets: seeds 0, 1, 2 distort x, y, z; seeds 3 and 4 give Color's green and blue.
const OFFSETS_3D: [[f32; 3]; 5] = [
    offset::<3>(0.0),
    offset::<3>(1.0),
    offset::<3>(2.0),
    offset::<3>(3.0),
    offset::<3>(4.0),
];

/// 4D offsets: seeds 0 to 3 distort x, y, z, w; seeds 4 and 5 give Color's green and blue.
const OFFSETS_4D: [[f32; 4]; 6] = [
    offset::<4>(0.0),
    offset::<4>(1.0),
    offset::<4>(2.0),
    offset::<4>(3.0),
    offset::<4>(4.0),
    offset::<4>(5.0),
];

// ---------------------------------------------------------------------------------------
// Perlin noise.
// ---------------------------------------------------------------------------------------

/// The floating-point grouping of the few operations where Cycles' kernels and Blender's
/// Geometry Nodes (blenlib) differ: same algorithm, different last bits. [`CyclesAvx2`]
/// is what Nimbus renders with; [`Blenlib`] lets the test against Geometry Nodes check the
/// algorithm to the bit.
pub trait Arithmetic: Copy {
    /// Perlin's quintic fade 6t^5 - 15t^4 + 10t^3.
    fn fade(t: f32) -> f32;
    /// The fade of 1D noise, which Cycles computes in scalar code as
    /// `t t t (t (6t - 15) + 10)`: the same polynomial grouped as blenlib groups it.
    #[inline(always)]
    fn fade1(t: f32) -> f32 {
        Self::fade(t)
    }
    /// Linear interpolation from `a` (t = 0) to `b` (t = 1).
    fn lerp(a: f32, b: f32, t: f32) -> f32;
    /// 1D noise's interpolation of the two corners' terms `s0·f` and `s1·f1` (slopes
    /// `s0`, `s1`; `f1 = f − 1`) at `u`: by default the products, then [`lerp`](Self::lerp).
    #[inline(always)]
    fn lerp1(s0: f32, s1: f32, f: f32, f1: f32, u: f32) -> f32 {
        Self::lerp(s0 * f, s1 * f1, u)
    }
    /// The first coordinate `p` of a 1D or 2D position moved by Distortion: `p + s·d`
    /// for the noise `s` and the strength `d` (Cycles computes these in scalar code; its
    /// AVX2 build fuses this one, and in 2D not the second: found against its renders).
    #[inline(always)]
    fn distort(p: f32, s: f32, d: f32) -> f32 {
        p + s * d
    }
    /// Interpolation of a 2D cell's corner values, ordered (x, y) = (0,0), (0,1), (1,0),
    /// (1,1): along x, then y (Cycles' SSE `bi_mix`).
    #[inline(always)]
    fn bilerp(c: [f32; 4], u: f32, v: f32) -> f32 {
        Self::lerp(Self::lerp(c[0], c[2], u), Self::lerp(c[1], c[3], u), v)
    }
    /// Interpolation of a cell's corner values, `lo` on its x = 0 face and `hi` on its
    /// x = 1 face, each ordered (y, z) = (0,0), (0,1), (1,0), (1,1).
    fn trilerp(lo: [f32; 4], hi: [f32; 4], u: f32, v: f32, w: f32) -> f32;
    /// The remainder of `a / PERIOD`, with `a`'s sign.
    fn remainder(a: f32) -> f32;
    /// `a b + c` where the fractals accumulate: one rounding where the reference fuses
    /// the multiply and the add, two where it does not.
    #[inline(always)]
    fn madd(a: f32, b: f32, c: f32) -> f32 {
        a * b + c
    }
    /// The gradients of a 3D cell's 8 corners dotted with the offsets from them
    /// ([`gradients3_scalar`]); [`Wide`] computes them in vector lanes.
    #[inline(always)]
    fn gradients3(lattice: [i32; 3], f: [f32; 3]) -> [f32; 8] {
        gradients3_scalar(lattice, f)
    }
    /// The 4D analogue of [`gradients3`](Self::gradients3).
    #[inline(always)]
    fn gradients4(lattice: [i32; 4], f: [f32; 4]) -> [f32; 16] {
        gradients4_scalar(lattice, f)
    }
    /// 4D: the corners of the w = 0 cell face (`near`, as [`trilerp`](Self::trilerp)
    /// takes them) and of the w = 1 face (`far`), interpolated at (u, v, t, s). By
    /// default trilinearly on each face, then along w.
    #[inline(always)]
    fn quadlerp(
        near: ([f32; 4], [f32; 4]),
        far: ([f32; 4], [f32; 4]),
        uvt: [f32; 3],
        s: f32,
    ) -> f32 {
        let [u, v, t] = uvt;
        let a = Self::trilerp(near.0, near.1, u, v, t);
        let b = Self::trilerp(far.0, far.1, u, v, t);
        Self::lerp(a, b, s)
    }
}

/// Four interpolations at once (one SIMD `mix` in Cycles). Written out rather than with
/// `array::from_fn`, whose closure may stay a call outside [`NoiseTexture`]'s FMA build.
#[inline(always)]
fn lerp4<A: Arithmetic>(a: [f32; 4], b: [f32; 4], t: f32) -> [f32; 4] {
    [
        A::lerp(a[0], b[0], t),
        A::lerp(a[1], b[1], t),
        A::lerp(a[2], b[2], t),
        A::lerp(a[3], b[3], t),
    ]
}

/// Cycles 5.0's x86 CPU kernel for CPUs without AVX2 (`kernel/svm/noise.h` under
/// `__KERNEL_SSE__`, SSE4.2, no fused multiply-add): the fade as
/// `(t t)(t (t (6t - 15) + 10))`, interpolation as `a + t (b - a)` along x for all four
/// (y, z) pairs at once, then y, then z (then w), and the remainder as
/// `a - trunc(a / b) b` in float (SSE4.2's `fmod` of a vector). Unlike [`CyclesAvx2`] it
/// was read from the source, not checked against a render (the machine this was written
/// on has AVX2, so Cycles there runs the other kernel).
#[derive(Clone, Copy, Debug)]
pub struct CyclesSse;

impl Arithmetic for CyclesSse {
    #[inline(always)]
    fn fade(t: f32) -> f32 {
        let a = t * 6.0 + -15.0;
        let b = t * a + 10.0;
        (t * t) * (t * b)
    }

    #[inline(always)]
    fn fade1(t: f32) -> f32 {
        let a = t * 6.0 + -15.0;
        let b = t * a + 10.0;
        ((t * t) * t) * b
    }

    #[inline(always)]
    fn lerp(a: f32, b: f32, t: f32) -> f32 {
        a + t * (b - a)
    }

    #[inline(always)]
    fn trilerp(lo: [f32; 4], hi: [f32; 4], u: f32, v: f32, w: f32) -> f32 {
        let s = lerp4::<Self>(lo, hi, u);
        Self::lerp(Self::lerp(s[0], s[2], v), Self::lerp(s[1], s[3], v), w)
    }

    /// Equals C's `fmodf` except within a few ulps below a multiple of `PERIOD`, where the
    /// rounded quotient already reaches the next integer. The quotient is a product with
    /// the reciprocal: Cycles is built with `-freciprocal-math`, which folds a division
    /// by a constant into one.
    #[inline(always)]
    fn remainder(a: f32) -> f32 {
        a - trunc(a * (1.0 / PERIOD)) * PERIOD
    }
}

/// Cycles 5.0's x86 CPU kernel with AVX2 (`kernel_avx2.cpp`, built with `-mfma
/// -ffp-contract=fast -freciprocal-math`), which Cycles runs on any CPU with AVX2: the
/// SSE grouping with the fade's two multiply-adds and every interpolation
/// `a + t (b - a)` fused into one rounding, 4D interpolated along w first (its 8-wide
/// gradients), the remainder's quotient taken with the reciprocal of the period, and the
/// fractals' accumulations fused. The values it gives were checked against renders of
/// that kernel (`tests/blender_noise.rs`). Without the `fma` target feature, Rust's
/// `mul_add` is a call to the C library's `fmaf`: correct, slower.
#[derive(Clone, Copy, Debug)]
pub struct CyclesAvx2;

impl Arithmetic for CyclesAvx2 {
    #[inline(always)]
    fn fade(t: f32) -> f32 {
        let a = t.mul_add(6.0, -15.0);
        let b = t.mul_add(a, 10.0);
        (t * t) * (t * b)
    }

    #[inline(always)]
    fn fade1(t: f32) -> f32 {
        let a = t.mul_add(6.0, -15.0);
        let b = t.mul_add(a, 10.0);
        ((t * t) * t) * b
    }

    #[inline(always)]
    fn lerp(a: f32, b: f32, t: f32) -> f32 {
        t.mul_add(b - a, a)
    }

    #[inline(always)]
    fn trilerp(lo: [f32; 4], hi: [f32; 4], u: f32, v: f32, w: f32) -> f32 {
        let s = lerp4::<Self>(lo, hi, u);
        Self::lerp(Self::lerp(s[0], s[2], v), Self::lerp(s[1], s[3], v), w)
    }

    /// The scalar 1D code as the AVX2 build contracts it (checked against Cycles' renders,
    /// `tests/blender_noise.rs`): `a + u (b − a)` with `a = s0 f` becomes
    /// `fma(s0, f, u · fma(−s0, f, s1 f1))`.
    #[inline(always)]
    fn lerp1(s0: f32, s1: f32, f: f32, f1: f32, u: f32) -> f32 {
        let d = (-s0).mul_add(f, s1 * f1);
        s0.mul_add(f, u * d)
    }

    #[inline(always)]
    fn distort(p: f32, s: f32, d: f32) -> f32 {
        s.mul_add(d, p)
    }

    #[inline(always)]
    fn remainder(a: f32) -> f32 {
        let quotient = trunc(a * (1.0 / PERIOD));
        (-quotient).mul_add(PERIOD, a)
    }

    #[inline(always)]
    fn madd(a: f32, b: f32, c: f32) -> f32 {
        a.mul_add(b, c)
    }

    #[inline(always)]
    fn quadlerp(
        near: ([f32; 4], [f32; 4]),
        far: ([f32; 4], [f32; 4]),
        uvt: [f32; 3],
        s: f32,
    ) -> f32 {
        let lo = lerp4::<Self>(near.0, far.0, s);
        let hi = lerp4::<Self>(near.1, far.1, s);
        Self::trilerp(lo, hi, uvt[0], uvt[1], uvt[2])
    }
}

/// Blender's Geometry Nodes (blenlib's `BLI_noise`, compiled without fused multiply-add):
/// the fade's polynomial in double precision, interpolation as `(1 - t) a + t b` nested
/// over x, y, z, and an exact `fmod`.
#[derive(Clone, Copy, Debug)]
pub struct Blenlib;

impl Arithmetic for Blenlib {
    #[inline(always)]
    fn fade(t: f32) -> f32 {
        // t^3 in float, the rest in double (blenlib's literals are doubles), rounded once
        // to double by the product and again to float on return.
        let t3 = t * t * t;
        let td = t as f64;
        (t3 as f64 * (td * (td * 6.0 - 15.0) + 10.0)) as f32
    }

    #[inline(always)]
    fn lerp(a: f32, b: f32, t: f32) -> f32 {
        (1.0 - t) * a + t * b
    }

    /// blenlib's bilinear `mix`: `(1.0 - y)` is a double, so the y = 0 row's product
    /// and the sum are taken in double and rounded to float once, on return.
    #[inline(always)]
    fn bilerp(c: [f32; 4], u: f32, v: f32) -> f32 {
        let u1 = 1.0 - u;
        let row0 = c[0] * u1 + c[2] * u;
        let row1 = c[1] * u1 + c[3] * u;
        ((1.0 - v as f64) * row0 as f64 + (v * row1) as f64) as f32
    }

    #[inline(always)]
    fn trilerp(lo: [f32; 4], hi: [f32; 4], u: f32, v: f32, w: f32) -> f32 {
        let (u1, v1, w1) = (1.0 - u, 1.0 - v, 1.0 - w);
        let face =
            |y0: usize, y1: usize| v1 * (lo[y0] * u1 + hi[y0] * u) + v * (lo[y1] * u1 + hi[y1] * u);
        w1 * face(0, 2) + w * face(1, 3)
    }

    #[inline(always)]
    fn remainder(a: f32) -> f32 {
        a % PERIOD
    }
}

/// `x` split into its floor (as an integer lattice coordinate) and the fraction above it.
/// Coordinates reach here folded below 100001 in magnitude, so the integer conversion is
/// exact and gives the floor without a call to the C library's `floorf` (which is what
/// `f32::floor` becomes on x86-64 without SSE4.1).
#[inline(always)]
fn floor_frac(x: f32) -> (i32, f32) {
    debug_assert!(x.is_nan() || x.abs() < 2e9, "{x} is not folded");
    let t = x as i32;
    // Truncation rounds negative non-integers up: one less then (branch-free).
    let i = t - ((t as f32) > x) as i32;
    (i, x - i as f32)
}

/// `q` rounded toward zero, as `f32::trunc` but inline: from 2^23 on every float is an
/// integer already.
#[inline(always)]
fn trunc(q: f32) -> f32 {
    if q.abs() < 8388608.0 {
        (q as i32) as f32
    } else {
        q
    }
}

/// `v` negated when `bit` (0 or 1) is 1, by flipping the sign bit, as Cycles' SIMD code
/// does: the signs come from random hash bits, where a branch would mispredict.
#[inline(always)]
fn negate_if(v: f32, bit: u32) -> f32 {
    f32::from_bits(v.to_bits() ^ (bit << 31))
}

/// `a` if `c`, else `b`, by bit masks: the compiler turns a plain `if` on hash bits into a
/// branch, mispredicted as often as the hash is random.
#[inline(always)]
fn select(c: bool, a: f32, b: f32) -> f32 {
    let m = 0u32.wrapping_sub(c as u32);
    f32::from_bits((a.to_bits() & m) | (b.to_bits() & !m))
}

/// The 1D gradient: a slope of ±1 to ±8 picked by 4 hash bits (the noise is the slope
/// times the offset from the corner).
#[inline(always)]
fn slope1(hash: u32) -> f32 {
    let h = hash & 15;
    negate_if((1 + (h & 7)) as f32, (h >> 3) & 1)
}

/// The 2D gradient dotted with the offset (x, y): (±1, ±2) or (±2, ±1), by 3 hash bits.
#[inline(always)]
fn grad2(hash: u32, x: f32, y: f32) -> f32 {
    let h = hash & 7;
    let u = select(h < 4, x, y);
    let v = 2.0 * select(h < 4, y, x);
    negate_if(u, h & 1) + negate_if(v, (h >> 1) & 1)
}

/// Dot product of the offset (x, y, z) from a corner with the corner's gradient: one of
/// Perlin's 12 cube-edge directions (with 4 repeated to make 16), picked by 4 hash bits.
#[inline(always)]
fn grad3(hash: u32, x: f32, y: f32, z: f32) -> f32 {
    let h = hash & 15;
    let u = select(h < 8, x, y);
    let vt = select(h == 12 || h == 14, x, z);
    let v = select(h < 4, y, vt);
    negate_if(u, h & 1) + negate_if(v, (h >> 1) & 1)
}

/// The 4D analogue: 32 gradients with three non-zero ±1 components, picked by 5 bits.
#[inline(always)]
fn grad4(hash: u32, x: f32, y: f32, z: f32, w: f32) -> f32 {
    let h = hash & 31;
    let u = select(h < 24, x, y);
    let v = select(h < 16, y, z);
    let s = select(h < 8, z, w);
    negate_if(u, h & 1) + negate_if(v, (h >> 1) & 1) + negate_if(s, (h >> 2) & 1)
}

/// Corner `i` of a cell (0..8 for 3D, 0..16 for 4D) as its offsets along (x, y, z, w):
/// bit 2 is x, bit 1 y, bit 0 z and bit 3 w, so corners 0-3 are the x = 0 face's (y, z)
/// = (0,0), (0,1), (1,0), (1,1) in Cycles' SSE lane order and 4-7 the x = 1 face's.
const fn corner_offset(i: usize) -> [u32; 4] {
    [
        (i >> 2) as u32 & 1,
        (i >> 1) as u32 & 1,
        i as u32 & 1,
        (i >> 3) as u32 & 1,
    ]
}

/// The corners' offsets per axis, as lanes: `CORNERS[axis][i]`.
const CORNERS: [[u32; 16]; 4] = {
    let mut c = [[0u32; 16]; 4];
    let mut i = 0;
    while i < 16 {
        let o = corner_offset(i);
        let mut axis = 0;
        while axis < 4 {
            c[axis][i] = o[axis];
            axis += 1;
        }
        i += 1;
    }
    c
};

/// The gradients of a 3D cell's 8 corners dotted with the offsets from them, in corner
/// order ([`corner_offset`]), one corner at a time.
#[inline(always)]
fn gradients3_scalar(lattice: [i32; 3], f: [f32; 3]) -> [f32; 8] {
    let mut g = [0.0f32; 8];
    for (i, g) in g.iter_mut().enumerate() {
        let (dx, dy, dz) = (CORNERS[0][i], CORNERS[1][i], CORNERS[2][i]);
        let h = hash_uint3(
            (lattice[0] as u32).wrapping_add(dx),
            (lattice[1] as u32).wrapping_add(dy),
            (lattice[2] as u32).wrapping_add(dz),
        );
        *g = grad3(h, f[0] - dx as f32, f[1] - dy as f32, f[2] - dz as f32);
    }
    g
}

/// The corner hashes and gradients in AVX2's 8 lanes.
#[cfg(target_arch = "x86_64")]
mod wide {
    use super::{lookup3_init, CORNERS};
    use std::arch::x86_64::*;

    /// `x` rotated left by `K` bits in every lane (`R` = 32 − `K`; AVX2 has no rotate).
    #[inline(always)]
    unsafe fn rotl<const K: i32, const R: i32>(x: __m256i) -> __m256i {
        _mm256_or_si256(_mm256_slli_epi32::<K>(x), _mm256_srli_epi32::<R>(x))
    }

    /// lookup3's `final` ([`super::lookup3_final`]) in every lane.
    #[inline(always)]
    unsafe fn lookup3_final(mut a: __m256i, mut b: __m256i, mut c: __m256i) -> __m256i {
        c = _mm256_xor_si256(c, b);
        c = _mm256_sub_epi32(c, rotl::<14, 18>(b));
        a = _mm256_xor_si256(a, c);
        a = _mm256_sub_epi32(a, rotl::<11, 21>(c));
        b = _mm256_xor_si256(b, a);
        b = _mm256_sub_epi32(b, rotl::<25, 7>(a));
        c = _mm256_xor_si256(c, b);
        c = _mm256_sub_epi32(c, rotl::<16, 16>(b));
        a = _mm256_xor_si256(a, c);
        a = _mm256_sub_epi32(a, rotl::<4, 28>(c));
        b = _mm256_xor_si256(b, a);
        b = _mm256_sub_epi32(b, rotl::<14, 18>(a));
        c = _mm256_xor_si256(c, b);
        _mm256_sub_epi32(c, rotl::<24, 8>(b))
    }

    /// `v` with its sign flipped where `bit` (0 or 1 per lane) is 1.
    #[inline(always)]
    unsafe fn negate_if(v: __m256, bit: __m256i) -> __m256 {
        _mm256_xor_ps(v, _mm256_castsi256_ps(_mm256_slli_epi32::<31>(bit)))
    }

    /// [`super::grad3`] in every lane: the same selections, by blends.
    #[inline(always)]
    unsafe fn grad3(hash: __m256i, x: __m256, y: __m256, z: __m256) -> __m256 {
        let h = _mm256_and_si256(hash, _mm256_set1_epi32(15));
        let mask = |m: __m256i| _mm256_castsi256_ps(m);
        let below8 = mask(_mm256_cmpgt_epi32(_mm256_set1_epi32(8), h));
        let below4 = mask(_mm256_cmpgt_epi32(_mm256_set1_epi32(4), h));
        let twelve_or_fourteen = mask(_mm256_or_si256(
            _mm256_cmpeq_epi32(h, _mm256_set1_epi32(12)),
            _mm256_cmpeq_epi32(h, _mm256_set1_epi32(14)),
        ));
        // blendv(a, b, m): b where m is set.
        let u = _mm256_blendv_ps(y, x, below8);
        let vt = _mm256_blendv_ps(z, x, twelve_or_fourteen);
        let v = _mm256_blendv_ps(vt, y, below4);
        let one = _mm256_set1_epi32(1);
        _mm256_add_ps(
            negate_if(u, _mm256_and_si256(h, one)),
            negate_if(v, _mm256_and_si256(_mm256_srli_epi32::<1>(h), one)),
        )
    }

    /// lookup3's `mix` ([`super::lookup3_mix`]) in every lane.
    #[inline(always)]
    unsafe fn lookup3_mix(
        mut a: __m256i,
        mut b: __m256i,
        mut c: __m256i,
    ) -> (__m256i, __m256i, __m256i) {
        let (add, sub, xor) = (_mm256_add_epi32, _mm256_sub_epi32, _mm256_xor_si256);
        a = sub(a, c);
        a = xor(a, rotl::<4, 28>(c));
        c = add(c, b);
        b = sub(b, a);
        b = xor(b, rotl::<6, 26>(a));
        a = add(a, c);
        c = sub(c, b);
        c = xor(c, rotl::<8, 24>(b));
        b = add(b, a);
        a = sub(a, c);
        a = xor(a, rotl::<16, 16>(c));
        c = add(c, b);
        b = sub(b, a);
        b = xor(b, rotl::<19, 13>(a));
        a = add(a, c);
        c = sub(c, b);
        c = xor(c, rotl::<4, 28>(b));
        b = add(b, a);
        (a, b, c)
    }

    /// [`super::grad4`] in every lane.
    #[inline(always)]
    unsafe fn grad4(hash: __m256i, x: __m256, y: __m256, z: __m256, w: __m256) -> __m256 {
        let h = _mm256_and_si256(hash, _mm256_set1_epi32(31));
        let below = |n: i32| _mm256_castsi256_ps(_mm256_cmpgt_epi32(_mm256_set1_epi32(n), h));
        let u = _mm256_blendv_ps(y, x, below(24));
        let v = _mm256_blendv_ps(z, y, below(16));
        let s = _mm256_blendv_ps(w, z, below(8));
        let one = _mm256_set1_epi32(1);
        let bit = |k: __m256i| _mm256_and_si256(k, one);
        _mm256_add_ps(
            _mm256_add_ps(
                negate_if(u, bit(h)),
                negate_if(v, bit(_mm256_srli_epi32::<1>(h))),
            ),
            negate_if(s, bit(_mm256_srli_epi32::<2>(h))),
        )
    }

    /// The offsets along axis `k` of the 8 corners from corner `first` on, as integer
    /// and float lanes.
    #[inline(always)]
    unsafe fn axis(k: usize, first: usize) -> (__m256i, __m256) {
        let d = _mm256_loadu_si256(CORNERS[k][first..first + 8].as_ptr() as *const __m256i);
        (d, _mm256_cvtepi32_ps(d))
    }

    /// [`super::gradients4_scalar`]: corners 0-7 (w = 0) in one vector, 8-15 (w = 1) in the next.
    ///
    /// # Safety
    /// The CPU must have AVX2.
    #[target_feature(enable = "avx2")]
    #[inline]
    pub(super) unsafe fn gradients4(lattice: [i32; 4], f: [f32; 4]) -> [f32; 16] {
        let init = _mm256_set1_epi32(lookup3_init(4) as i32);
        let mut out = [0.0f32; 16];
        for half in 0..2 {
            let mut word = [init; 4];
            let mut offset = [_mm256_setzero_ps(); 4];
            for k in 0..4 {
                let (d, df) = axis(k, 8 * half);
                word[k] = _mm256_add_epi32(_mm256_set1_epi32(lattice[k]), d);
                offset[k] = _mm256_sub_ps(_mm256_set1_ps(f[k]), df);
            }
            let (a, b, c) = lookup3_mix(
                _mm256_add_epi32(init, word[0]),
                _mm256_add_epi32(init, word[1]),
                _mm256_add_epi32(init, word[2]),
            );
            let h = lookup3_final(_mm256_add_epi32(a, word[3]), b, c);
            let g = grad4(h, offset[0], offset[1], offset[2], offset[3]);
            _mm256_storeu_ps(out[8 * half..].as_mut_ptr(), g);
        }
        out
    }

    /// [`super::gradients3_scalar`] with the 8 corners in the 8 lanes.
    ///
    /// # Safety
    /// The CPU must have AVX2.
    #[target_feature(enable = "avx2")]
    #[inline]
    pub(super) unsafe fn gradients3(lattice: [i32; 3], f: [f32; 3]) -> [f32; 8] {
        let init = _mm256_set1_epi32(lookup3_init(3) as i32);
        let mut word = [init; 3];
        let mut offset = [_mm256_setzero_ps(); 3];
        for k in 0..3 {
            let (d, df) = axis(k, 0);
            let corner = _mm256_add_epi32(_mm256_set1_epi32(lattice[k]), d);
            word[k] = _mm256_add_epi32(init, corner);
            offset[k] = _mm256_sub_ps(_mm256_set1_ps(f[k]), df);
        }
        let h = lookup3_final(word[0], word[1], word[2]);
        let g = grad3(h, offset[0], offset[1], offset[2]);
        let mut out = [0.0f32; 8];
        _mm256_storeu_ps(out.as_mut_ptr(), g);
        out
    }
}

/// The grouping `A` with the corners' hashes and gradients computed in AVX2's 8 lanes
/// ([`wide`]): lane for lane the same integer and float operations as one corner at a
/// time, so the same values (`wide_gradients_equal_one_corner_at_a_time`). The hashes
/// are most of a noise evaluation's work.
///
/// It is chosen once, where the CPU has been checked: only functions compiled with
/// `#[target_feature(enable = "avx2")]` and called after `is_x86_feature_detected!`
/// name it ([`NoiseTexture::eval`]'s AVX2 build, MaterialX's fractal). Naming it
/// elsewhere would run AVX2 instructions on a CPU that may lack them, hence private to
/// the shader module.
#[derive(Clone, Copy, Debug)]
pub(in crate::shader) struct Wide<A>(std::marker::PhantomData<A>);

impl<A: Arithmetic> Arithmetic for Wide<A> {
    #[inline(always)]
    fn fade(t: f32) -> f32 {
        A::fade(t)
    }
    #[inline(always)]
    fn fade1(t: f32) -> f32 {
        A::fade1(t)
    }
    #[inline(always)]
    fn lerp(a: f32, b: f32, t: f32) -> f32 {
        A::lerp(a, b, t)
    }
    #[inline(always)]
    fn bilerp(c: [f32; 4], u: f32, v: f32) -> f32 {
        A::bilerp(c, u, v)
    }
    #[inline(always)]
    fn lerp1(s0: f32, s1: f32, f: f32, f1: f32, u: f32) -> f32 {
        A::lerp1(s0, s1, f, f1, u)
    }
    #[inline(always)]
    fn distort(p: f32, s: f32, d: f32) -> f32 {
        A::distort(p, s, d)
    }
    #[inline(always)]
    fn trilerp(lo: [f32; 4], hi: [f32; 4], u: f32, v: f32, w: f32) -> f32 {
        A::trilerp(lo, hi, u, v, w)
    }
    #[inline(always)]
    fn remainder(a: f32) -> f32 {
        A::remainder(a)
    }
    #[inline(always)]
    fn madd(a: f32, b: f32, c: f32) -> f32 {
        A::madd(a, b, c)
    }
    #[inline(always)]
    fn quadlerp(
        near: ([f32; 4], [f32; 4]),
        far: ([f32; 4], [f32; 4]),
        uvt: [f32; 3],
        s: f32,
    ) -> f32 {
        A::quadlerp(near, far, uvt, s)
    }
    #[inline(always)]
    fn gradients3(lattice: [i32; 3], f: [f32; 3]) -> [f32; 8] {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: `Wide` is only named where the CPU has AVX2 (see the type).
        return unsafe { wide::gradients3(lattice, f) };
        #[cfg(not(target_arch = "x86_64"))]
        gradients3_scalar(lattice, f)
    }
    #[inline(always)]
    fn gradients4(lattice: [i32; 4], f: [f32; 4]) -> [f32; 16] {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: as for `gradients3`.
        return unsafe { wide::gradients4(lattice, f) };
        #[cfg(not(target_arch = "x86_64"))]
        gradients4_scalar(lattice, f)
    }
}

/// Unscaled 1D Perlin noise (0 at every integer).
#[inline(always)]
pub fn perlin_1d<A: Arithmetic>(x: f32) -> f32 {
    let (xi, fx) = floor_frac(x);
    let s0 = slope1(hash_uint(xi as u32));
    let s1 = slope1(hash_uint((xi as u32).wrapping_add(1)));
    A::lerp1(s0, s1, fx, fx - 1.0, A::fade1(fx))
}

/// Unscaled 2D Perlin noise (0 at every lattice point).
#[inline(always)]
pub fn perlin_2d<A: Arithmetic>(x: f32, y: f32) -> f32 {
    let (xi, fx) = floor_frac(x);
    let (yi, fy) = floor_frac(y);
    let (x0, y0) = (xi as u32, yi as u32);
    let (x1, y1) = (x0.wrapping_add(1), y0.wrapping_add(1));
    let c = [
        grad2(hash_uint2(x0, y0), fx, fy),
        grad2(hash_uint2(x0, y1), fx, fy - 1.0),
        grad2(hash_uint2(x1, y0), fx - 1.0, fy),
        grad2(hash_uint2(x1, y1), fx - 1.0, fy - 1.0),
    ];
    A::bilerp(c, A::fade(fx), A::fade(fy))
}

/// Unscaled 3D Perlin noise (0 at every lattice point).
#[inline(always)]
pub fn perlin_3d<A: Arithmetic>(x: f32, y: f32, z: f32) -> f32 {
    let (xi, fx) = floor_frac(x);
    let (yi, fy) = floor_frac(y);
    let (zi, fz) = floor_frac(z);
    let g = A::gradients3([xi, yi, zi], [fx, fy, fz]);
    let lo = [g[0], g[1], g[2], g[3]];
    let hi = [g[4], g[5], g[6], g[7]];
    A::trilerp(lo, hi, A::fade(fx), A::fade(fy), A::fade(fz))
}

/// The 4D analogue of [`gradients3_scalar`]: 16 corners, bit 3 of the index the w
/// offset.
#[inline(always)]
fn gradients4_scalar(lattice: [i32; 4], f: [f32; 4]) -> [f32; 16] {
    let mut g = [0.0f32; 16];
    for (i, g) in g.iter_mut().enumerate() {
        let d = [CORNERS[0][i], CORNERS[1][i], CORNERS[2][i], CORNERS[3][i]];
        let h = hash_uint4(
            (lattice[0] as u32).wrapping_add(d[0]),
            (lattice[1] as u32).wrapping_add(d[1]),
            (lattice[2] as u32).wrapping_add(d[2]),
            (lattice[3] as u32).wrapping_add(d[3]),
        );
        *g = grad4(
            h,
            f[0] - d[0] as f32,
            f[1] - d[1] as f32,
            f[2] - d[2] as f32,
            f[3] - d[3] as f32,
        );
    }
    g
}

/// Unscaled 4D Perlin noise: the 16 corner gradients interpolated by
/// [`Arithmetic::quadlerp`].
#[inline(always)]
pub fn perlin_4d<A: Arithmetic>(x: f32, y: f32, z: f32, w: f32) -> f32 {
    let (xi, fx) = floor_frac(x);
    let (yi, fy) = floor_frac(y);
    let (zi, fz) = floor_frac(z);
    let (wi, fw) = floor_frac(w);
    let (u, v, t, s) = (A::fade(fx), A::fade(fy), A::fade(fz), A::fade(fw));
    let g = A::gradients4([xi, yi, zi, wi], [fx, fy, fz, fw]);
    let face = |k: usize| [g[k], g[k + 1], g[k + 2], g[k + 3]];
    // Faces: (x, w) = (0, 0), (1, 0), (0, 1), (1, 1) start at corners 0, 4, 8, 12.
    let near = (face(0), face(4));
    let far = (face(8), face(12));
    A::quadlerp(near, far, [u, v, t], s)
}

/// Perlin noise repeats every `PERIOD` on each axis: floats far from the origin have too
/// few fraction bits for a smooth lattice, so Cycles folds coordinates into one period.
const PERIOD: f32 = 100000.0;
/// From here on a float has at most 3 fraction bits (0.125 steps at 1e6) and the folded
/// coordinate would sit on lattice points or halfway, where Perlin noise is 0 or
/// degenerate; Cycles then moves it by half a cell.
const CORRECTION_FROM: f32 = 1000000.0;

/// `a` folded into (-PERIOD, PERIOD), moved by half a cell from 1e6 on.
#[inline(always)]
fn fold<A: Arithmetic>(a: f32) -> f32 {
    let correction = if a.abs() >= CORRECTION_FROM { 0.5 } else { 0.0 };
    A::remainder(a) + correction
}

/// [`fold`] with C's exact `fmodf`: Cycles folds 1D and 2D coordinates one float at a
/// time (its `float2` has no vector `fmod`), so every kernel takes the exact remainder.
#[inline(always)]
fn fold_exact(a: f32) -> f32 {
    let correction = if a.abs() >= CORRECTION_FROM { 0.5 } else { 0.0 };
    a % PERIOD + correction
}

/// Range constants that map Perlin noise to about [-1, 1], measured by Open Shading
/// Language's authors for these gradient sets (Cycles' `noise_scale1` to
/// `noise_scale4`).
pub const SCALE_1D: f32 = 0.2500;
pub const SCALE_2D: f32 = 0.6616;
const SCALE_3D: f32 = 0.9820;
const SCALE_4D: f32 = 0.8344;

#[inline(always)]
fn fold4<A: Arithmetic>(p: [f32; 4]) -> [f32; 4] {
    [
        fold::<A>(p[0]),
        fold::<A>(p[1]),
        fold::<A>(p[2]),
        fold::<A>(p[3]),
    ]
}

/// Signed 3D Perlin noise, about [-1, 1].
#[inline(always)]
pub fn perlin_signed_3d<A: Arithmetic>(p: [f32; 3]) -> f32 {
    SCALE_3D * perlin_3d::<A>(fold::<A>(p[0]), fold::<A>(p[1]), fold::<A>(p[2]))
}

/// Signed 4D Perlin noise, about [-1, 1] (range constant 0.8344).
#[inline(always)]
pub fn perlin_signed_4d<A: Arithmetic>(p: [f32; 4]) -> f32 {
    let f = fold4::<A>(p);
    SCALE_4D * perlin_4d::<A>(f[0], f[1], f[2], f[3])
}

/// Unsigned 3D Perlin noise, about [0, 1].
pub fn perlin_unsigned_3d<A: Arithmetic>(p: [f32; 3]) -> f32 {
    0.5 * perlin_signed_3d::<A>(p) + 0.5
}

/// Unsigned 4D Perlin noise, about [0, 1].
pub fn perlin_unsigned_4d<A: Arithmetic>(p: [f32; 4]) -> f32 {
    0.5 * perlin_signed_4d::<A>(p) + 0.5
}

// ---------------------------------------------------------------------------------------
// Fractals over octaves.
// ---------------------------------------------------------------------------------------

/// A 3- or 4-component position (`[f32; 3]` and `[f32; 4]` cannot take operator impls here).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pt<const N: usize>(pub [f32; N]);

impl<const N: usize> Add for Pt<N> {
    type Output = Self;
    #[inline(always)]
    fn add(self, o: Self) -> Self {
        let mut r = self.0;
        for (r, o) in r.iter_mut().zip(o.0) {
            *r += o;
        }
        Pt(r)
    }
}

impl<const N: usize> Mul<f32> for Pt<N> {
    type Output = Self;
    #[inline(always)]
    fn mul(self, s: f32) -> Self {
        let mut r = self.0;
        for r in &mut r {
            *r *= s;
        }
        Pt(r)
    }
}

/// A position in 3 or 4 dimensions with signed Perlin noise at it: what the fractals need,
/// dispatched statically.
pub trait SignedNoise: Copy + Add<Output = Self> + Mul<f32, Output = Self> {
    fn snoise<A: Arithmetic>(self) -> f32;
    /// `snoise + offset`, the range constant's product fused into the sum where the
    /// reference fuses it (Cycles' AVX2 kernel inlines the scaling into the sum).
    fn snoise_plus<A: Arithmetic>(self, offset: f32) -> f32;
}

impl SignedNoise for Pt<1> {
    #[inline(always)]
    fn snoise<A: Arithmetic>(self) -> f32 {
        SCALE_1D * perlin_1d::<A>(fold_exact(self.0[0]))
    }
    #[inline(always)]
    fn snoise_plus<A: Arithmetic>(self, offset: f32) -> f32 {
        A::madd(SCALE_1D, perlin_1d::<A>(fold_exact(self.0[0])), offset)
    }
}

impl SignedNoise for Pt<2> {
    #[inline(always)]
    fn snoise<A: Arithmetic>(self) -> f32 {
        let [x, y] = self.0;
        SCALE_2D * perlin_2d::<A>(fold_exact(x), fold_exact(y))
    }
    #[inline(always)]
    fn snoise_plus<A: Arithmetic>(self, offset: f32) -> f32 {
        let [x, y] = self.0;
        A::madd(
            SCALE_2D,
            perlin_2d::<A>(fold_exact(x), fold_exact(y)),
            offset,
        )
    }
}

impl SignedNoise for Pt<3> {
    #[inline(always)]
    fn snoise<A: Arithmetic>(self) -> f32 {
        perlin_signed_3d::<A>(self.0)
    }
    #[inline(always)]
    fn snoise_plus<A: Arithmetic>(self, offset: f32) -> f32 {
        let [x, y, z] = self.0;
        let (x, y, z) = (fold::<A>(x), fold::<A>(y), fold::<A>(z));
        A::madd(SCALE_3D, perlin_3d::<A>(x, y, z), offset)
    }
}

impl SignedNoise for Pt<4> {
    #[inline(always)]
    fn snoise<A: Arithmetic>(self) -> f32 {
        perlin_signed_4d::<A>(self.0)
    }
    #[inline(always)]
    fn snoise_plus<A: Arithmetic>(self, offset: f32) -> f32 {
        let [x, y, z, w] = fold4::<A>(self.0);
        A::madd(SCALE_4D, perlin_4d::<A>(x, y, z, w), offset)
    }
}

/// The number of whole octaves after the first, as C's float-to-int truncation gives it.
#[inline(always)]
fn whole_octaves(detail: f32) -> i32 {
    detail as i32
}

/// The fraction of the last octave: Detail 2.7 adds 70 % of a fourth octave.
#[inline(always)]
fn fractional_octave(detail: f32) -> f32 {
    detail - detail.floor()
}

/// Fractal Brownian motion: octaves of doubling (`lacunarity`) frequency and
/// `roughness`-scaled amplitude summed. Normalized, the sum is divided by the total
/// amplitude and mapped to about [0, 1]; a fractional Detail blends the sums without and
/// with the partial octave (each normalized by its own amplitude).
#[inline(always)]
pub fn fbm<A: Arithmetic, P: SignedNoise>(
    p: P,
    detail: f32,
    roughness: f32,
    lacunarity: f32,
    normalize: bool,
) -> f32 {
    let mut fscale = 1.0f32;
    let mut amp = 1.0f32;
    let mut maxamp = 0.0f32;
    let mut sum = 0.0f32;
    // Two octaves per step: their noises do not depend on each other, and written
    // side by side the CPU overlaps one's hash chain with the other's (a lookup in a
    // tracking walk waits for its result, so latency is what counts). The sums are
    // taken in the same order as one octave at a time: the same values.
    let octaves = whole_octaves(detail) + 1;
    for _ in 0..octaves / 2 {
        let next = fscale * lacunarity;
        let (t0, t1) = ((p * fscale).snoise::<A>(), (p * next).snoise::<A>());
        sum = A::madd(t0, amp, sum);
        maxamp += amp;
        amp *= roughness;
        sum = A::madd(t1, amp, sum);
        maxamp += amp;
        amp *= roughness;
        fscale = next * lacunarity;
    }
    if octaves % 2 == 1 {
        let t = (p * fscale).snoise::<A>();
        sum = A::madd(t, amp, sum);
        maxamp += amp;
        amp *= roughness;
        fscale *= lacunarity;
    }
    let rmd = fractional_octave(detail);
    if rmd != 0.0 {
        let t = (p * fscale).snoise::<A>();
        let sum2 = A::madd(t, amp, sum);
        if normalize {
            // (0.5 sum) / maxamp, left to right, as Cycles groups it.
            A::lerp(
                0.5 * sum / maxamp + 0.5,
                0.5 * sum2 / (maxamp + amp) + 0.5,
                rmd,
            )
        } else {
            A::lerp(sum, sum2, rmd)
        }
    } else if normalize {
        0.5 * sum / maxamp + 0.5
    } else {
        sum
    }
}

/// Multifractal: a product of (1 + amplitude * noise) over octaves, so rough areas get
/// rougher (Musgrave's multiplicative cascade).
#[inline(always)]
pub fn multifractal<A: Arithmetic, P: SignedNoise>(
    mut p: P,
    detail: f32,
    roughness: f32,
    lacunarity: f32,
) -> f32 {
    let mut value = 1.0f32;
    let mut pwr = 1.0f32;
    for _ in 0..=whole_octaves(detail) {
        value *= A::madd(pwr, p.snoise::<A>(), 1.0);
        pwr *= roughness;
        p = p * lacunarity;
    }
    let rmd = fractional_octave(detail);
    if rmd != 0.0 {
        value *= A::madd(rmd * pwr, p.snoise::<A>(), 1.0);
    }
    value
}

/// Heterogeneous terrain: each octave's increment is scaled by the value so far, so
/// low areas stay smooth and high areas get detail.
#[inline(always)]
pub fn hetero_terrain<A: Arithmetic, P: SignedNoise>(
    mut p: P,
    detail: f32,
    roughness: f32,
    lacunarity: f32,
    offset: f32,
) -> f32 {
    let mut pwr = roughness;
    // The first octave unscaled.
    let mut value = p.snoise_plus::<A>(offset);
    p = p * lacunarity;
    for _ in 1..=whole_octaves(detail) {
        // value + increment, with the increment's last product fused into the sum.
        value = A::madd(p.snoise_plus::<A>(offset) * pwr, value, value);
        pwr *= roughness;
        p = p * lacunarity;
    }
    let rmd = fractional_octave(detail);
    if rmd != 0.0 {
        let increment = p.snoise_plus::<A>(offset) * pwr * value;
        value = A::madd(rmd, increment, value);
    }
    value
}

/// Hybrid multifractal: additive octaves weighted by the previous octaves' signal
/// (times `gain`, at most 1); stops once the weight falls to 0.001.
#[inline(always)]
pub fn hybrid_multifractal<A: Arithmetic, P: SignedNoise>(
    mut p: P,
    detail: f32,
    roughness: f32,
    lacunarity: f32,
    offset: f32,
    gain: f32,
) -> f32 {
    let mut pwr = 1.0f32;
    let mut value = 0.0f32;
    let mut weight = 1.0f32;
    let mut i = 0;
    while weight > 0.001 && i <= whole_octaves(detail) {
        weight = weight.min(1.0);
        let signal = p.snoise_plus::<A>(offset) * pwr;
        pwr *= roughness;
        value = A::madd(weight, signal, value);
        weight *= gain * signal;
        p = p * lacunarity;
        i += 1;
    }
    let rmd = fractional_octave(detail);
    if rmd != 0.0 && weight > 0.001 {
        weight = weight.min(1.0);
        let signal = p.snoise_plus::<A>(offset) * pwr;
        value = A::madd(rmd * weight, signal, value);
    }
    value
}

/// Ridged multifractal: (offset - |noise|)^2 makes sharp ridges along noise's zero set;
/// each octave is weighted by the previous signal times `gain`, clamped to [0, 1]. Cycles
/// ignores a fractional Detail here (whole octaves only), and so does this.
#[inline(always)]
pub fn ridged_multifractal<A: Arithmetic, P: SignedNoise>(
    mut p: P,
    detail: f32,
    roughness: f32,
    lacunarity: f32,
    offset: f32,
    gain: f32,
) -> f32 {
    let mut pwr = roughness;
    let mut signal = offset - p.snoise::<A>().abs();
    signal *= signal;
    let mut value = signal;
    for _ in 1..=whole_octaves(detail) {
        p = p * lacunarity;
        let weight = (signal * gain).clamp(0.0, 1.0);
        signal = offset - p.snoise::<A>().abs();
        signal *= signal;
        signal *= weight;
        value = A::madd(signal, pwr, value);
        pwr *= roughness;
    }
    value
}

// ---------------------------------------------------------------------------------------
// The node.
// ---------------------------------------------------------------------------------------

/// The Noise Texture's Dimensions.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Dimensions {
    /// W alone (the Vector is ignored).
    D1,
    /// The Vector's x and y.
    D2,
    #[default]
    D3,
    /// 3D position plus W (e.g. animated over time).
    D4,
}

/// The Noise Texture's Type (Blender 4.1+).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum NoiseType {
    #[default]
    Fbm,
    Multifractal,
    HeteroTerrain,
    HybridMultifractal,
    RidgedMultifractal,
}

/// Blender's Noise Texture node: its properties and unconnected inputs, by their UI names.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NoiseTexture {
    pub dimensions: Dimensions,
    pub kind: NoiseType,
    /// Normalize (fBM only): map the sum to about [0, 1].
    pub normalize: bool,
    pub scale: f32,
    /// Octaves after the first; fractional values blend in a partial octave. Clamped to
    /// [0, 15] as the node clamps it.
    pub detail: f32,
    /// Amplitude ratio between octaves; negative values act as 0.
    pub roughness: f32,
    /// Frequency ratio between octaves.
    pub lacunarity: f32,
    /// Offset (hetero terrain, hybrid and ridged multifractal).
    pub offset: f32,
    /// Gain (hybrid and ridged multifractal).
    pub gain: f32,
    /// How far the position is displaced by noise before the fractal is evaluated.
    pub distortion: f32,
}

impl Default for NoiseTexture {
    /// A new node's values in Blender.
    fn default() -> Self {
        NoiseTexture {
            dimensions: Dimensions::D3,
            kind: NoiseType::Fbm,
            normalize: true,
            scale: 5.0,
            detail: 2.0,
            roughness: 0.5,
            lacunarity: 2.0,
            offset: 0.0,
            gain: 1.0,
            distortion: 0.0,
        }
    }
}

/// The inputs after the node's clamping, shared by every evaluation.
#[derive(Clone, Copy)]
struct Octaves {
    kind: NoiseType,
    normalize: bool,
    detail: f32,
    roughness: f32,
    lacunarity: f32,
    offset: f32,
    gain: f32,
}

impl Octaves {
    #[inline(always)]
    fn eval<A: Arithmetic, P: SignedNoise>(&self, p: P) -> f32 {
        let (d, r, l) = (self.detail, self.roughness, self.lacunarity);
        match self.kind {
            NoiseType::Fbm => fbm::<A, P>(p, d, r, l, self.normalize),
            NoiseType::Multifractal => multifractal::<A, P>(p, d, r, l),
            NoiseType::HeteroTerrain => hetero_terrain::<A, P>(p, d, r, l, self.offset),
            NoiseType::HybridMultifractal => {
                hybrid_multifractal::<A, P>(p, d, r, l, self.offset, self.gain)
            }
            NoiseType::RidgedMultifractal => {
                ridged_multifractal::<A, P>(p, d, r, l, self.offset, self.gain)
            }
        }
    }
}

impl NoiseTexture {
    fn octaves(&self) -> Octaves {
        Octaves {
            kind: self.kind,
            normalize: self.normalize,
            detail: self.detail.clamp(0.0, 15.0),
            roughness: self.roughness.max(0.0),
            lacunarity: self.lacunarity,
            offset: self.offset,
            gain: self.gain,
        }
    }

    /// Fac and Color at position `p` (the Vector input) and `w` (the W input, used in
    /// 4D only), as Cycles computes them on an x86-64 CPU with AVX2 ([`CyclesAvx2`]).
    pub fn eval(&self, p: [f32; 3], w: f32) -> (f32, [f32; 3]) {
        self.dispatch::<true>(p, w)
    }

    /// Where Color's green and blue fractals are evaluated: the position (scaled and
    /// distorted) plus these offsets (the fourth component is W's, used in 4D only).
    pub fn color_offsets(&self) -> [[f32; 4]; 2] {
        match self.dimensions {
            Dimensions::D1 => [OFFSETS_1D[1], OFFSETS_1D[2]].map(|o| [0.0, 0.0, 0.0, o[0]]),
            Dimensions::D2 => [OFFSETS_2D[2], OFFSETS_2D[3]].map(|o| [o[0], o[1], 0.0, 0.0]),
            Dimensions::D3 => [OFFSETS_3D[3], OFFSETS_3D[4]].map(|o| [o[0], o[1], o[2], 0.0]),
            Dimensions::D4 => [OFFSETS_4D[4], OFFSETS_4D[5]],
        }
    }

    /// Fac alone: Cycles skips Color's two extra fractals when Color is not connected.
    pub fn fac(&self, p: [f32; 3], w: f32) -> f32 {
        self.dispatch::<false>(p, w).0
    }

    /// [`CyclesAvx2`] fuses multiply-adds; with the CPU's FMA instructions that is one
    /// instruction, without them (Nimbus is built for baseline x86-64) a call to `fmaf`
    /// per operation. And with AVX2 the corners' hashes take one vector pass ([`Wide`]).
    /// So the whole evaluation is compiled again with AVX2 and FMA (and with FMA alone)
    /// and picked here, once per evaluation: the same values either way (the tests
    /// check), measured in docs/shaders.md.
    #[inline(always)]
    fn dispatch<const COLOR: bool>(&self, p: [f32; 3], w: f32) -> (f32, [f32; 3]) {
        #[cfg(target_arch = "x86_64")]
        {
            if std::arch::is_x86_feature_detected!("avx2")
                && std::arch::is_x86_feature_detected!("fma")
            {
                // SAFETY: the CPU has the instructions `eval_avx2` is compiled for.
                return unsafe { self.eval_avx2::<COLOR>(p, w) };
            }
            if std::arch::is_x86_feature_detected!("fma") {
                // SAFETY: the CPU has the instructions `eval_fma` is compiled for.
                return unsafe { self.eval_fma::<COLOR>(p, w) };
            }
        }
        self.eval_impl::<CyclesAvx2, COLOR>(p, w)
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    fn eval_avx2<const COLOR: bool>(&self, p: [f32; 3], w: f32) -> (f32, [f32; 3]) {
        self.eval_impl::<Wide<CyclesAvx2>, COLOR>(p, w)
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "fma")]
    fn eval_fma<const COLOR: bool>(&self, p: [f32; 3], w: f32) -> (f32, [f32; 3]) {
        self.eval_impl::<CyclesAvx2, COLOR>(p, w)
    }

    /// [`eval`](Self::eval) with another floating-point grouping: `Blenlib` gives
    /// Geometry Nodes' values.
    pub fn eval_with<A: Arithmetic>(&self, p: [f32; 3], w: f32) -> (f32, [f32; 3]) {
        self.eval_impl::<A, true>(p, w)
    }

    /// [`fac`](Self::fac) with another floating-point grouping.
    pub fn fac_with<A: Arithmetic>(&self, p: [f32; 3], w: f32) -> f32 {
        self.eval_impl::<A, false>(p, w).0
    }

    #[inline(always)]
    fn eval_impl<A: Arithmetic, const COLOR: bool>(&self, p: [f32; 3], w: f32) -> (f32, [f32; 3]) {
        let oct = self.octaves();
        match self.dimensions {
            Dimensions::D1 => {
                let p = Pt([w * self.scale]);
                texture::<A, 1, 3, COLOR>(p, self.distortion, &oct, &OFFSETS_1D)
            }
            Dimensions::D2 => {
                let s = self.scale;
                let p = Pt([p[0] * s, p[1] * s]);
                texture::<A, 2, 4, COLOR>(p, self.distortion, &oct, &OFFSETS_2D)
            }
            Dimensions::D3 => {
                let p = Pt(p) * self.scale;
                texture::<A, 3, 5, COLOR>(p, self.distortion, &oct, &OFFSETS_3D)
            }
            Dimensions::D4 => {
                let s = self.scale;
                let p = Pt([p[0] * s, p[1] * s, p[2] * s, w * s]);
                texture::<A, 4, 6, COLOR>(p, self.distortion, &oct, &OFFSETS_4D)
            }
        }
    }
}

/// Distortion, then the fractal at the point (Fac) and, if asked, at the point moved by
/// the last two offsets (Color's green and blue; red is Fac). The first N offsets
/// displace the N coordinates.
#[inline(always)]
fn texture<A: Arithmetic, const N: usize, const M: usize, const COLOR: bool>(
    mut p: Pt<N>,
    distortion: f32,
    oct: &Octaves,
    offsets: &[[f32; N]; M],
) -> (f32, [f32; 3])
where
    Pt<N>: SignedNoise,
{
    if distortion != 0.0 {
        // A loop, not `array::from_fn`: its closure could escape the FMA build.
        let mut noise = [0.0f32; N];
        for (noise, offset) in noise.iter_mut().zip(offsets) {
            *noise = (p + Pt(*offset)).snoise::<A>();
        }
        for (axis, (p, noise)) in p.0.iter_mut().zip(noise).enumerate() {
            // Cycles computes 1D and 2D in scalar code, and its AVX2 build fuses the
            // first coordinate's product into the sum ([`Arithmetic::distort`]).
            *p = match N <= 2 && axis == 0 {
                true => A::distort(*p, noise, distortion),
                false => *p + noise * distortion,
            };
        }
    }
    let fac = oct.eval::<A, _>(p);
    if !COLOR {
        return (fac, [fac, 0.0, 0.0]);
    }
    let g = oct.eval::<A, _>(p + Pt(offsets[N]));
    let b = oct.eval::<A, _>(p + Pt(offsets[N + 1]));
    (fac, [fac, g, b])
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A small deterministic generator for test points (no dependency needed).
    fn points(n: usize, seed: u32, lo: f32, hi: f32) -> impl Iterator<Item = [f32; 4]> {
        let mut state = seed;
        let mut next = move || {
            state = hash_uint2(state, 0x9e3779b9);
            lo + (hi - lo) * (state as f32 / u32::MAX as f32)
        };
        (0..n).map(move |_| [next(), next(), next(), next()])
    }

    /// The AVX2 lanes give every corner's gradient equal to the bit to one corner at a
    /// time, over lattice cells on both sides of 0 and out to the folded range's ends
    /// (where the lattice coordinates' sums wrap the hash's words).
    #[test]
    #[cfg(target_arch = "x86_64")]
    fn wide_gradients_equal_one_corner_at_a_time() {
        if !std::arch::is_x86_feature_detected!("avx2") {
            eprintln!("SKIPPED: this CPU has no AVX2, the wide gradients are never used");
            return;
        }
        let mut cells = 0;
        for (lo, hi) in [(-3.0, 3.0), (-1e5, 1e5), (-1.9e9, 1.9e9)] {
            for q in points(20_000, 17, lo, hi) {
                let split = q.map(floor_frac);
                let lattice = split.map(|s| s.0);
                let frac = split.map(|s| s.1);
                let (l3, f3) = (
                    [lattice[0], lattice[1], lattice[2]],
                    [frac[0], frac[1], frac[2]],
                );
                // SAFETY: checked above that the CPU has AVX2.
                let (w3, w4) =
                    unsafe { (wide::gradients3(l3, f3), wide::gradients4(lattice, frac)) };
                assert_eq!(
                    w3.map(f32::to_bits),
                    gradients3_scalar(l3, f3).map(f32::to_bits),
                    "{q:?}"
                );
                assert_eq!(
                    w4.map(f32::to_bits),
                    gradients4_scalar(lattice, frac).map(f32::to_bits),
                    "{q:?}"
                );
                cells += 1;
            }
        }
        assert_eq!(cells, 60_000);
    }

    #[test]
    fn zero_at_lattice_points() {
        // Every gradient is dotted with a zero offset at a corner.
        for x in -3..3 {
            for y in -3..3 {
                for z in -3..3 {
                    let p = [x as f32, y as f32, z as f32];
                    assert_eq!(perlin_signed_3d::<CyclesAvx2>(p), 0.0, "{p:?}");
                    for w in [-2.0, 0.0, 5.0] {
                        assert_eq!(perlin_signed_4d::<CyclesAvx2>([p[0], p[1], p[2], w]), 0.0);
                    }
                }
            }
        }
    }

    #[test]
    fn continuous_across_cells() {
        // Points straddling lattice planes and random points: a step of 1e-3 moves the
        // noise by at most (max slope) * step; the slope of these noises is below 4.
        let eps = 1e-3f32;
        for q in points(20000, 7, -6.0, 6.0) {
            let p3 = [q[0], q[1], q[2]];
            let d3 = perlin_signed_3d::<CyclesAvx2>([p3[0] + eps, p3[1], p3[2]])
                - perlin_signed_3d::<CyclesAvx2>(p3);
            assert!(d3.abs() < 4.0 * eps, "{p3:?}: {d3}");
            let d4 = perlin_signed_4d::<CyclesAvx2>([q[0], q[1], q[2], q[3] + eps])
                - perlin_signed_4d::<CyclesAvx2>(q);
            assert!(d4.abs() < 4.0 * eps, "{q:?}: {d4}");
        }
        for k in -3..3 {
            let below = perlin_signed_3d::<CyclesAvx2>([k as f32 - 1e-6, 0.3, 0.6]);
            let above = perlin_signed_3d::<CyclesAvx2>([k as f32 + 1e-6, 0.3, 0.6]);
            assert!((below - above).abs() < 1e-5, "x = {k}: {below} {above}");
        }
    }

    #[test]
    fn within_range() {
        for q in points(20000, 3, -50.0, 50.0) {
            let n3 = perlin_signed_3d::<CyclesAvx2>([q[0], q[1], q[2]]);
            let n4 = perlin_signed_4d::<CyclesAvx2>(q);
            assert!(n3.abs() <= 1.05 && n4.abs() <= 1.05, "{q:?}: {n3} {n4}");
        }
    }

    #[test]
    fn detail_zero_is_one_octave() {
        let tex = NoiseTexture {
            detail: 0.0,
            ..NoiseTexture::default()
        };
        for q in points(1000, 11, -3.0, 3.0) {
            let p = [q[0], q[1], q[2]];
            let one = 0.5 * perlin_signed_3d::<CyclesAvx2>((Pt(p) * 5.0).0) + 0.5;
            assert_eq!(tex.fac(p, 0.0), one);
        }
    }

    #[test]
    fn fractional_detail_blends_neighbours() {
        let at = |detail| NoiseTexture {
            detail,
            ..NoiseTexture::default()
        };
        for q in points(1000, 5, -3.0, 3.0) {
            let p = [q[0], q[1], q[2]];
            let (a, b, m) = (
                at(2.0).fac(p, 0.0),
                at(3.0).fac(p, 0.0),
                at(2.25).fac(p, 0.0),
            );
            assert!((m - (0.75 * a + 0.25 * b)).abs() < 1e-6, "{p:?}");
        }
    }

    #[test]
    fn periodic_and_corrected_far_away() {
        // 0.25 + 100000 is exact in float: whole periods further from 0 (on the same
        // side: the fold keeps the sign), the same value.
        let p = [0.25f32, 1.5, -0.75];
        let far = [p[0] + 100000.0, p[1] + 200000.0, p[2] - 300000.0];
        assert_eq!(
            perlin_signed_3d::<CyclesAvx2>(p),
            perlin_signed_3d::<CyclesAvx2>(far)
        );
        // Past 1e6 the half-cell correction applies: 2e6 + 0.25 folds to 0.25 + 0.5.
        let moved = perlin_signed_3d::<CyclesAvx2>([0.75, p[1], p[2]]);
        assert_eq!(
            perlin_signed_3d::<CyclesAvx2>([2_000_000.0 + 0.25, p[1], p[2]]),
            moved
        );
        // Integer-valued large coordinates do not collapse to the lattice's zeros.
        assert_ne!(perlin_signed_3d::<CyclesAvx2>([3_000_000.0, 1e6, 5e6]), 0.0);
    }

    #[test]
    fn colour_red_is_fac_and_fac_skips_colour() {
        for kind in [NoiseType::Fbm, NoiseType::RidgedMultifractal] {
            for dimensions in [
                Dimensions::D1,
                Dimensions::D2,
                Dimensions::D3,
                Dimensions::D4,
            ] {
                let tex = NoiseTexture {
                    kind,
                    dimensions,
                    distortion: 0.5,
                    ..NoiseTexture::default()
                };
                let (fac, col) = tex.eval([0.1, 0.2, 0.3], 0.4);
                assert_eq!(col[0], fac);
                assert_eq!(tex.fac([0.1, 0.2, 0.3], 0.4), fac);
                assert_ne!(col[1], col[2]);
            }
        }
    }

    #[test]
    fn offsets_in_range() {
        for o in OFFSETS_3D
            .iter()
            .flatten()
            .chain(OFFSETS_4D.iter().flatten())
            .chain(OFFSETS_1D.iter().flatten())
            .chain(OFFSETS_2D.iter().flatten())
        {
            assert!((100.0..=200.0).contains(o), "{o}");
        }
        // The 3D and 4D offsets of a seed share their first three components.
        assert_eq!(OFFSETS_3D[3], OFFSETS_4D[3][..3]);
    }
}
