//! Per-pixel random number streams. Each pixel's generator is seeded from the render
//! seed and the pixel index alone, so an image is identical at any thread count.

use rand_pcg::Pcg32;

pub type Sampler = Pcg32;

/// The generator for pixel `pixel` of a render with seed `seed`.
pub fn pixel_sampler(seed: u64, pixel: u64) -> Sampler {
    // Distinct streams per pixel (PCG's increment), state mixed from both inputs.
    let state = splitmix(seed ^ splitmix(pixel));
    Pcg32::new(state, (pixel << 1) | 1)
}

fn splitmix(mut x: u64) -> u64 {
    x = x.wrapping_add(0x9E37_79B9_7F4A_7C15);
    x = (x ^ (x >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    x = (x ^ (x >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    x ^ (x >> 31)
}
