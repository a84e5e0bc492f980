//! The denoised frame mixed back towards the noisy one where the denoiser's own error
//! is the larger (issue 48).
//!
//! A denoiser trades noise for bias: at few samples it removes far more error than it
//! adds, but as the samples grow its bias (detail smoothed away) stays while the
//! noise it removes shrinks, and past some count the denoised frame is further from
//! the converged image than the noisy one (OIDN on the cloud: 1.2e-4 against 1.23e-4
//! at 2,048 spp, on the smoke 1.9e-4 against 1.5e-4 at 1,024; docs/sampling.md,
//! "Keeping the noisy value where it is closer"). The film knows each pixel's noise, so
//! each pixel and channel takes the mix d + w (x − d) of the denoised value d and the
//! noisy x whose expected squared error (1 − w)² b² + w² v is least: w = b² / (b² + v),
//! with v the variance of x (`beauty_variance`) and b² the denoiser's squared error,
//! estimated as E[(x − d)²] − v (x's noise is in the difference too). Both are means
//! over a 5 × 5 window (one pixel's difference is one noisy draw), and v's window mean
//! is counted against b² with a margin of four of its own standard errors
//! (√(2/m) relative for m degrees of freedom, the window's samples less one per pixel),
//! because a sample variance of few samples is most often too small: without the
//! margin the mix made 4-spp frames 8 % worse than OIDN's; with it they stay within
//! 1 %, and at 1,024-2,048 spp it is 0.72-0.83 of OIDN's error.
//!
//! The same w of each channel mixes every split layer with its own denoised and noisy
//! values, so the layers still sum to the beauty as closely as the denoised ones did:
//! Σ(dᵢ + w (xᵢ − dᵢ)) − (d + w (x − d)) = (1 − w)(Σdᵢ − d) + w (Σxᵢ − x).

/// Half the window's edge: 5 × 5 pixels.
const RADIUS: usize = 2;
/// How many standard errors of the window's variance estimate the difference must
/// exceed it by before any of it counts as the denoiser's error.
const MARGIN: f64 = 4.0;

/// The weights w of the noisy values, one per pixel, of one channel: `noisy` and
/// `denoised` its values, `variance` the variance of each noisy value (the largest
/// float where it is unknown), `samples` each pixel's sample count.
pub fn noisy_weights(
    width: usize,
    height: usize,
    noisy: &[f32],
    denoised: &[f32],
    variance: &[f32],
    samples: &[f32],
) -> Vec<f32> {
    let n = width * height;
    let mut difference = vec![0.0f64; n];
    let mut var = vec![0.0f64; n];
    let mut dof = vec![0.0f64; n];
    for i in 0..n {
        difference[i] = (noisy[i] as f64 - denoised[i] as f64).powi(2);
        // An unknown variance (fewer than two samples) keeps the window denoised.
        var[i] = if variance[i] >= f32::MAX {
            f64::INFINITY
        } else {
            variance[i].max(0.0) as f64
        };
        dof[i] = (samples[i] as f64 - 1.0).max(0.0);
    }
    let difference = window_means(width, height, &difference);
    let var = window_means(width, height, &var);
    let dof = window_sums(width, height, &dof);
    (0..n)
        .map(|i| {
            let (e, v, m) = (difference[i], var[i], dof[i]);
            if !v.is_finite() || m <= 0.0 {
                return 0.0;
            }
            let bias2 = (e - v * (1.0 + MARGIN * (2.0 / m).sqrt())).max(0.0);
            if bias2 == 0.0 {
                0.0
            } else {
                (bias2 / (bias2 + v)) as f32
            }
        })
        .collect()
}

/// `denoised` moved towards `noisy` by `weights`, in place: d + w (x − d).
pub fn mix(denoised: &mut [f32], noisy: &[f32], weights: &[f32]) {
    for ((d, &x), &w) in denoised.iter_mut().zip(noisy).zip(weights) {
        if w > 0.0 {
            *d += w * (x - *d);
        }
    }
}

/// Each pixel's mean over the window around it that lies inside the image.
fn window_means(width: usize, height: usize, values: &[f64]) -> Vec<f64> {
    let sums = window_sums(width, height, values);
    let ones = window_sums(width, height, &vec![1.0; values.len()]);
    sums.iter().zip(&ones).map(|(s, c)| s / c).collect()
}

/// Each pixel's sum over the window around it that lies inside the image (rows, then
/// columns: the window is separable).
fn window_sums(width: usize, height: usize, values: &[f64]) -> Vec<f64> {
    let mut rows = vec![0.0; values.len()];
    for y in 0..height {
        for x in 0..width {
            let (x0, x1) = (x.saturating_sub(RADIUS), (x + RADIUS).min(width - 1));
            rows[y * width + x] = values[y * width + x0..=y * width + x1].iter().sum();
        }
    }
    let mut out = vec![0.0; values.len()];
    for y in 0..height {
        let (y0, y1) = (y.saturating_sub(RADIUS), (y + RADIUS).min(height - 1));
        for x in 0..width {
            out[y * width + x] = (y0..=y1).map(|yy| rows[yy * width + x]).sum();
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_pcg::Pcg64;

    /// Squared error against `truth`, summed.
    fn error(image: &[f32], truth: &[f64]) -> f64 {
        image
            .iter()
            .zip(truth)
            .map(|(a, t)| (*a as f64 - t).powi(2))
            .sum()
    }

    /// A 64×64 image whose left half the "denoiser" smooths wrongly (a constant
    /// offset: bias b = 0.2 where the noise's standard deviation is 0.05) and whose
    /// right half it gets right (d = the truth): the mix keeps the noisy values on
    /// the left and the denoised on the right, so its error is below both images'.
    /// Noise: Gaussian (Box–Muller), σ = 0.05 per pixel, variance reported exactly,
    /// 64 samples per pixel; Pcg64 seed 48. Expected squared error per pixel: noisy
    /// 0.0025 everywhere, denoised 0.04 left and 0 right; the mix is asserted below
    /// 0.6 × the noisy image's total (measured 0.49: the left half's 0.0025 and ~0
    /// on the right) and below 0.1 × the denoised one's.
    #[test]
    fn the_mix_keeps_the_noisy_values_where_the_denoiser_is_wrong() {
        let (w, h) = (64, 64);
        let mut rng = Pcg64::seed_from_u64(48);
        let sigma = 0.05f64;
        let truth: Vec<f64> = (0..w * h)
            .map(|i| 1.0 + 0.3 * ((i % w) as f64 / 9.0).sin())
            .collect();
        let noisy: Vec<f32> = truth
            .iter()
            .map(|t| {
                let (u1, u2): (f64, f64) = (rng.gen::<f64>().max(1e-300), rng.gen());
                let z = (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos();
                (t + sigma * z) as f32
            })
            .collect();
        let denoised: Vec<f32> = truth
            .iter()
            .enumerate()
            .map(|(i, t)| if i % w < w / 2 { t + 0.2 } else { *t } as f32)
            .collect();
        let variance = vec![(sigma * sigma) as f32; w * h];
        let samples = vec![64.0f32; w * h];
        let weights = noisy_weights(w, h, &noisy, &denoised, &variance, &samples);
        assert!(weights.iter().all(|w| (0.0..=1.0).contains(w)));
        let mut mixed = denoised.clone();
        mix(&mut mixed, &noisy, &weights);
        let (e_noisy, e_den, e_mix) = (
            error(&noisy, &truth),
            error(&denoised, &truth),
            error(&mixed, &truth),
        );
        eprintln!("squared error: noisy {e_noisy:.3}, denoised {e_den:.3}, mixed {e_mix:.3}");
        assert!(e_mix < 0.6 * e_noisy, "mixed {e_mix}, noisy {e_noisy}");
        assert!(e_mix < 0.1 * e_den, "mixed {e_mix}, denoised {e_den}");
    }

    /// Where the denoised value equals the noisy one, or the variance is unknown (one
    /// sample), the weight is 0: the denoised value stands.
    #[test]
    fn an_unknown_variance_or_no_difference_keeps_the_denoised_value() {
        let (w, h) = (8, 8);
        let x = vec![1.0f32; w * h];
        let d = vec![0.5f32; w * h];
        let unknown = noisy_weights(w, h, &x, &d, &vec![f32::MAX; w * h], &vec![1.0; w * h]);
        assert!(unknown.iter().all(|&v| v == 0.0));
        let same = noisy_weights(w, h, &x, &x, &vec![0.01; w * h], &vec![16.0; w * h]);
        assert!(same.iter().all(|&v| v == 0.0));
        // An exact noisy value (variance 0, e.g. the sky's) is kept whole.
        let exact = noisy_weights(w, h, &x, &d, &vec![0.0; w * h], &vec![16.0; w * h]);
        assert!(exact.iter().all(|&v| v == 1.0));
    }

    #[test]
    fn window_sums_count_only_the_pixels_inside_the_image() {
        let ones = vec![1.0; 6 * 5];
        let s = window_sums(6, 5, &ones);
        assert_eq!(s[0], 9.0); // a corner: 3 × 3
        assert_eq!(s[2 * 6 + 2], 25.0); // the middle: 5 × 5
        assert_eq!(s[2 * 6], 15.0); // left edge, middle row: 3 × 5
    }
}
