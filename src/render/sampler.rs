//! Per-pixel random number streams. Each pixel's generator is seeded from the render
//! seed and the pixel index alone, so an image is identical at any thread count.
//!
//! Two kinds of stream, one type ([`Sampler`]):
//!
//! - **independent**: a PCG32 stream per pixel, every number independent of the others;
//! - **sobol** (randomised quasi-Monte Carlo): within each sample of a pixel the first
//!   [`Sampler::start_sample`]`(dims)` numbers are dimensions of a scrambled Sobol'
//!   point set, the rest come from the PCG stream. Dimensions are taken in pairs, each
//!   pair the first two Sobol' dimensions (a (0,2)-sequence: every prefix of 2^m
//!   samples puts one point in each of the 2^m elementary rectangles of any shape),
//!   with the sample index shuffled and the point Owen-scrambled by hashes of the
//!   pixel, the seed and the pair (Burley 2020, "Practical Hash-based Owen
//!   Scrambling"). Owen scrambling makes every point uniform on the unit square and
//!   independent pairs independent of each other, so any estimator stays unbiased
//!   however many numbers a path draws; stratification lowers the variance of the
//!   low dimensions (pixel position, first free path, first light and phase samples).
//!
//! The sample index lives in the stream, so progressive passes continue it: N samples
//! in any number of passes draw the same numbers.

use crate::track::select::Choice;
use rand::RngCore;
use rand_pcg::Pcg32;

/// Where a render's random numbers come from (`--sampler`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum SamplerKind {
    /// The first [`SOBOL_DIMS`] numbers of each sample from scrambled Sobol' points.
    #[default]
    Sobol,
    /// Every number from the pixel's PCG32 stream.
    Independent,
}

/// Dimensions of each sample the `sobol` sampler stratifies: the pixel position, then
/// the first numbers the camera ray's free path and its first vertex draw. Measured
/// in docs/performance.md: more dimensions cost time and bought nothing.
pub const SOBOL_DIMS: u32 = 8;

impl Choice for SamplerKind {
    const ALL: &'static [Self] = &[SamplerKind::Sobol, SamplerKind::Independent];

    fn name(self) -> &'static str {
        match self {
            SamplerKind::Sobol => "sobol",
            SamplerKind::Independent => "independent",
        }
    }

    fn help(self) -> &'static str {
        match self {
            SamplerKind::Sobol => {
                "scrambled Sobol' points for the first dimensions of each sample (the default)"
            }
            SamplerKind::Independent => "independent PCG32 numbers",
        }
    }
}

impl SamplerKind {
    /// The dimensions per sample drawn from Sobol' points.
    pub fn qmc_dims(self) -> u32 {
        match self {
            SamplerKind::Sobol => SOBOL_DIMS,
            SamplerKind::Independent => 0,
        }
    }
}

/// A pixel's random stream; see the module documentation.
#[derive(Clone, Debug)]
pub struct Sampler {
    pcg: Pcg32,
    /// Hash of the render seed and the pixel: the root of every scramble.
    key: u32,
    /// Samples started so far: the current sample's index is one less.
    started: u32,
    /// The next dimension of the current sample.
    dim: u32,
    /// Dimensions drawn from the Sobol' points in the current sample (0: independent).
    qmc_dims: u32,
    /// The second value of the current pair, drawn with the first.
    pending: u32,
}

/// The generator for pixel `pixel` of a render with seed `seed`.
pub fn pixel_sampler(seed: u64, pixel: u64) -> Sampler {
    // Distinct streams per pixel (PCG's increment), state mixed from both inputs.
    let state = splitmix(seed ^ splitmix(pixel));
    Sampler {
        pcg: Pcg32::new(state, (pixel << 1) | 1),
        key: (splitmix(state ^ 0x5AB0_15EE_D00D_F00D) >> 32) as u32,
        started: 0,
        dim: 0,
        qmc_dims: 0,
        pending: 0,
    }
}

impl Sampler {
    /// Begins the pixel's next sample: its first `qmc_dims` numbers come from the
    /// Sobol' points of this sample index, the rest from the independent stream.
    /// `qmc_dims` 0 leaves the stream independent.
    #[inline]
    pub fn start_sample(&mut self, qmc_dims: u32) {
        self.started = self.started.wrapping_add(1);
        self.dim = 0;
        self.qmc_dims = qmc_dims;
    }

    /// The next Sobol' dimension of the current sample, as 32 bits of fixed point.
    /// Out of line: drawn for the first few numbers of a sample only, and inlined it
    /// would keep every `gen()` (most of them plain PCG steps) from being inlined.
    #[inline(never)]
    fn next_qmc(&mut self) -> u32 {
        let d = self.dim;
        self.dim += 1;
        if d & 1 == 1 {
            return self.pending;
        }
        let pair = d >> 1;
        let h = mix32(self.key ^ mix32(pair.wrapping_mul(0x9E37_79B9).wrapping_add(1)));
        let j = owen_scramble(self.started.wrapping_sub(1), h);
        let x = owen_scramble(sobol0(j), mix32(h ^ 0x68E3_1DA4));
        self.pending = owen_scramble(sobol1(j), mix32(h ^ 0xB529_7A4D));
        x
    }
}

impl RngCore for Sampler {
    #[inline]
    fn next_u32(&mut self) -> u32 {
        if self.dim < self.qmc_dims {
            self.next_qmc()
        } else {
            self.pcg.next_u32()
        }
    }

    /// A Sobol' dimension fills the high 32 bits (what a float is made from); the low
    /// bits come from the independent stream, jittering within the finest stratum.
    #[inline]
    fn next_u64(&mut self) -> u64 {
        if self.dim < self.qmc_dims {
            let hi = self.next_qmc() as u64;
            (hi << 32) | self.pcg.next_u32() as u64
        } else {
            self.pcg.next_u64()
        }
    }

    fn fill_bytes(&mut self, dest: &mut [u8]) {
        self.pcg.fill_bytes(dest)
    }

    fn try_fill_bytes(&mut self, dest: &mut [u8]) -> Result<(), rand::Error> {
        self.pcg.try_fill_bytes(dest)
    }
}

/// The first Sobol' dimension (van der Corput in base 2) of index `i`.
#[inline]
fn sobol0(i: u32) -> u32 {
    i.reverse_bits()
}

/// The second Sobol' dimension of index `i`: its generator matrix is Pascal's
/// triangle mod 2 (column k is column k−1 xor itself shifted down by one), applied a
/// byte of the index at a time from [`SOBOL1_BYTES`].
#[inline]
fn sobol1(i: u32) -> u32 {
    let t = &SOBOL1_BYTES;
    t[0][(i & 0xFF) as usize]
        ^ t[1][((i >> 8) & 0xFF) as usize]
        ^ t[2][((i >> 16) & 0xFF) as usize]
        ^ t[3][(i >> 24) as usize]
}

/// `SOBOL1_BYTES[k][b]`: the xor of the generator columns 8k … 8k+7 selected by the
/// bits of `b`.
static SOBOL1_BYTES: [[u32; 256]; 4] = sobol1_tables();

const fn sobol1_tables() -> [[u32; 256]; 4] {
    let mut columns = [0u32; 32];
    let mut v = 1u32 << 31;
    let mut k = 0;
    while k < 32 {
        columns[k] = v;
        v ^= v >> 1;
        k += 1;
    }
    let mut t = [[0u32; 256]; 4];
    let mut byte = 0;
    while byte < 4 {
        let mut b = 0;
        while b < 256 {
            let mut x = 0u32;
            let mut bit = 0;
            while bit < 8 {
                if (b >> bit) & 1 == 1 {
                    x ^= columns[byte * 8 + bit];
                }
                bit += 1;
            }
            t[byte][b] = x;
            b += 1;
        }
        byte += 1;
    }
    t
}

/// Nested uniform (Owen) scrambling of a base-2 fixed-point value, by a hash in
/// which each bit of the bit-reversed value is flipped by a function of the bits below
/// it only (so each digit is permuted depending on the digits before it).
#[inline]
fn owen_scramble(v: u32, seed: u32) -> u32 {
    let mut x = v.reverse_bits();
    x ^= x.wrapping_mul(0x3D20_ADEA);
    x = x.wrapping_add(seed);
    x = x.wrapping_mul((seed >> 16) | 1);
    x ^= x.wrapping_mul(0x0552_6C56);
    x ^= x.wrapping_mul(0x53A2_2864);
    x.reverse_bits()
}

/// A 32-bit integer hash (good avalanche; for seeds, not for sampling).
#[inline]
fn mix32(mut x: u32) -> u32 {
    x ^= x >> 16;
    x = x.wrapping_mul(0x7FEB_352D);
    x ^= x >> 15;
    x = x.wrapping_mul(0x846C_A68B);
    x ^ (x >> 16)
}

fn splitmix(mut x: u64) -> u64 {
    x = x.wrapping_add(0x9E37_79B9_7F4A_7C15);
    x = (x ^ (x >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    x = (x ^ (x >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    x ^ (x >> 31)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::Rng;

    /// The pair `pair` (dimensions 2·pair, 2·pair + 1) of samples 0 … n−1 of `s`.
    fn points(s: &mut Sampler, pair: u32, n: u32) -> Vec<(u32, u32)> {
        (0..n)
            .map(|_| {
                s.start_sample(2 * pair + 2);
                for _ in 0..2 * pair {
                    s.next_u32();
                }
                (s.next_u32(), s.next_u32())
            })
            .collect()
    }

    /// Exact, not statistical: the first 2^m samples of a pair put one point in each
    /// of the 2^m elementary rectangles 2^−a × 2^−(m−a), for every shape a, m ≤ 10, in
    /// several pixels and pairs (the (0,2)-sequence property that the scrambles keep).
    #[test]
    fn every_power_of_two_prefix_is_a_0_m_2_net() {
        for pixel in [0u64, 7, 123_456] {
            for pair in [0u32, 1, 3] {
                let mut s = pixel_sampler(9, pixel);
                let pts = points(&mut s, pair, 1 << 10);
                for m in 0..=10u32 {
                    let prefix = &pts[..1 << m];
                    for a in 0..=m {
                        let mut seen = vec![false; 1 << m];
                        for &(x, y) in prefix {
                            // The top a bits of x and the top m − a bits of y.
                            let i = x.checked_shr(32 - a).unwrap_or(0);
                            let j = y.checked_shr(32 - (m - a)).unwrap_or(0);
                            let cell = ((i << (m - a)) | j) as usize;
                            assert!(
                                !seen[cell],
                                "pixel {pixel} pair {pair}: 2^{m} points, shape {a}: cell {cell} twice"
                            );
                            seen[cell] = true;
                        }
                    }
                }
            }
        }
    }

    /// Each number is uniform across pixels, and pairs are independent of each other:
    /// sample 5 of 65,536 pixels, dimension 0 in 64 bins and (dimension 0, dimension 2)
    /// in 8 × 8 bins, chi-square with 63 degrees of freedom < 103.4 (p = 0.001) each.
    /// Fails for a scramble that ignores the pixel (all values equal) or pairs that
    /// repeat one another (a diagonal 8 × 8 table).
    #[test]
    fn numbers_are_uniform_and_pairs_independent_across_pixels() {
        let n = 65_536u64;
        let (mut one, mut two) = ([0f64; 64], [0f64; 64]);
        for pixel in 0..n {
            let mut s = pixel_sampler(3, pixel);
            for _ in 0..6 {
                s.start_sample(SOBOL_DIMS);
            }
            let d0 = s.next_u32();
            s.next_u32();
            let d2 = s.next_u32();
            one[(d0 >> 26) as usize] += 1.0;
            two[((d0 >> 29) * 8 + (d2 >> 29)) as usize] += 1.0;
        }
        let expected = n as f64 / 64.0;
        let chi2 = |h: &[f64; 64]| {
            h.iter()
                .map(|o| (o - expected).powi(2) / expected)
                .sum::<f64>()
        };
        assert!(chi2(&one) < 103.4, "dimension 0: chi2 {}", chi2(&one));
        assert!(
            chi2(&two) < 103.4,
            "dimensions 0 and 2: chi2 {}",
            chi2(&two)
        );
    }

    /// `independent` (no Sobol' dimensions) is the PCG32 stream itself, bit for bit,
    /// and numbers past the Sobol' dimensions of a sample come from that stream too.
    #[test]
    fn independent_numbers_are_the_pcg_stream() {
        let (seed, pixel) = (11u64, 77u64);
        let state = splitmix(seed ^ splitmix(pixel));
        let mut pcg = Pcg32::new(state, (pixel << 1) | 1);
        let mut s = pixel_sampler(seed, pixel);
        for _ in 0..4 {
            s.start_sample(0);
            for _ in 0..10 {
                assert_eq!(s.gen::<f64>(), pcg.gen::<f64>());
                assert_eq!(s.gen::<f32>(), pcg.gen::<f32>());
            }
        }
        s.start_sample(2);
        s.gen::<f32>();
        s.gen::<f32>();
        assert_eq!(s.next_u32(), pcg.next_u32());
    }

    /// A sample's numbers depend on its index only: the 9th sample of a pixel draws
    /// the same numbers after 8 samples of any length.
    #[test]
    fn a_sample_does_not_depend_on_how_many_numbers_earlier_samples_drew() {
        let draw = |lengths: [usize; 8]| {
            let mut s = pixel_sampler(2, 5);
            for len in lengths {
                s.start_sample(SOBOL_DIMS);
                for _ in 0..len {
                    s.next_u32();
                }
            }
            s.start_sample(SOBOL_DIMS);
            (0..SOBOL_DIMS).map(|_| s.next_u32()).collect::<Vec<_>>()
        };
        assert_eq!(draw([0; 8]), draw([1, 5, 2, 40, 0, 3, 7, 100]));
    }
}
