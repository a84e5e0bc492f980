//! Adaptive sampling (issue 48): each pixel stops taking samples once its estimated
//! noise is below a threshold.
//!
//! **The error estimate** means what Cycles' does (so the add-on can hand Cycles'
//! Noise Threshold over unchanged), estimated with less noise. Cycles keeps, beside
//! the sum of a pixel's samples, the sum of its even-numbered samples, and takes
//!
//!   e = (|I_r − A_r| + |I_g − A_g| + |I_b − A_b|) / (10⁻⁴ + √(I_r + I_g + I_b)),
//!
//! I the mean of all n samples and A the mean of the even half. I − A is half the
//! difference of the two halves' means, a normal variable of standard deviation σ/√n
//! (σ the channel's per-sample standard deviation), whose expected magnitude is
//! √(2/π) σ/√n. Nimbus uses that expectation, with each channel's sample variance for
//! σ² (the pixel keeps Σx and Σx² per channel):
//!
//!   e = √(2/π) (σ_r + σ_g + σ_b)/√n / (10⁻⁴ + √(I_r + I_g + I_b)).
//!
//! One difference is a single draw: its magnitude is below a third of its expectation
//! one time in four, so a pixel whose noise is three times the threshold stops at its
//! next check one time in four. In a volume, whose samples are heavy-tailed, that
//! stopped the wrong pixels: on the time-to-target cloud the halves' estimate took
//! 1.7× the samples fixed spp needs for the same relMSE; the sample variance (n ≥
//! `min_spp` samples) takes 0.7× (benches/time_to_target/README.md). The units stay
//! between absolute and relative (the square root keeps dark pixels from taking every
//! sample).
//!
//! **When it is checked.** Only at sample counts n = `min_spp` + k·[`STEP`] (k ≥ 0),
//! and from the pixel's own sums alone, never a neighbour's: whether a pixel stops
//! after n samples is a function of its first n samples. Its sample stream is its own
//! (seeded by the pixel's index), so the frame is the same whatever the threads, the
//! split into progressive passes or into farm tiles (each tile's pixels stop exactly
//! where the whole frame's do). Cycles also keeps a converged pixel's neighbours
//! sampling; Nimbus does not, so that tiles need no overlap.
//!
//! **Bias.** The decision reads the samples that are then averaged, so the estimate of
//! a stopped pixel is not exactly unbiased: a pixel whose rare bright samples have not
//! shown yet looks converged sooner. Every pixel takes `min_spp` samples first, which
//! bounds how early that can happen; docs/sampling.md states the bias measured
//! against fixed-spp renders at equal total samples.

use crate::render::film::Pixel;

/// Samples between two checks of one pixel.
pub const STEP: u32 = 4;

/// A render's adaptive sampling: stop a pixel once its error is below `threshold`,
/// never before `min_spp` samples (and never past the render's spp).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Adaptive {
    pub threshold: f64,
    pub min_spp: u32,
}

impl Adaptive {
    /// `threshold` (> 0) with `min_spp` samples at least; `min_spp` 0 picks
    /// [`Adaptive::default_min_spp`] of `spp`. The minimum is rounded up to an even
    /// count.
    pub fn new(threshold: f64, min_spp: u32, spp: u32) -> Adaptive {
        let min = match min_spp {
            0 => Adaptive::default_min_spp(spp),
            n => n,
        };
        Adaptive {
            threshold,
            min_spp: min.next_multiple_of(2).max(2),
        }
    }

    /// The minimum when none is given: √spp, at least 16 (Cycles' rule for its
    /// automatic Min Samples is of the same form; below 16 samples the two halves'
    /// difference is too rough an estimate to stop on).
    pub fn default_min_spp(spp: u32) -> u32 {
        ((spp as f64).sqrt().ceil() as u32).max(16)
    }

    /// Whether `px` (with `n` samples) stops here: a check point, and its error below
    /// the threshold.
    #[inline]
    pub fn converged(&self, px: &Pixel) -> bool {
        let n = px.samples;
        n >= self.min_spp && (n - self.min_spp) % STEP == 0 && error(px) < self.threshold
    }
}

/// The pixel's error estimate (the module documentation); 0 with no samples.
pub fn error(px: &Pixel) -> f64 {
    let n = px.samples as f64;
    if n == 0.0 {
        return 0.0;
    }
    // The finite samples the sums hold.
    let m = (px.samples - px.nonfinite) as f64;
    let mut intensity = 0.0;
    for c in 0..3 {
        intensity += px.rgb[c] / n;
    }
    let difference = match m >= 2.0 {
        true => {
            let mut sigma = 0.0;
            for c in 0..3 {
                let variance = (px.rgb_sq[c] - px.rgb[c] * px.rgb[c] / m) / (m - 1.0);
                sigma += variance.max(0.0).sqrt();
            }
            (2.0 / std::f64::consts::PI).sqrt() * sigma / n.sqrt()
        }
        // One sample has no variance: the halves' difference is then the sample itself
        // (I − A = x − 2x), as large as the noise could be. (No pixel stops here:
        // the minimum is at least 2.)
        false => (0..3).map(|c| (px.rgb[c] / n).abs()).sum(),
    };
    difference / (1e-4 + intensity.max(0.0).sqrt())
}

/// How converged a film is: the mean of its pixels' errors, and with adaptive
/// sampling the fraction of pixels that have stopped.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Convergence {
    pub mean_error: f64,
    pub stopped: Option<f64>,
}

impl Convergence {
    /// Of `pixels` (one pass over them, after a pass).
    pub fn of(pixels: &[Pixel], adaptive: Option<Adaptive>) -> Convergence {
        if pixels.is_empty() {
            return Convergence::default();
        }
        let n = pixels.len() as f64;
        let mean_error = pixels.iter().map(error).sum::<f64>() / n;
        let stopped = adaptive.map(|a| pixels.iter().filter(|p| a.converged(p)).count() as f64 / n);
        Convergence {
            mean_error,
            stopped,
        }
    }

    /// Every pixel has stopped: more passes would take no sample.
    pub fn done(&self) -> bool {
        self.stopped == Some(1.0)
    }

    /// For a progress line: "noise 0.0123" and, with adaptive sampling, the share of
    /// pixels stopped.
    pub fn describe(&self) -> String {
        match self.stopped {
            Some(f) => format!(
                "noise {:.4}, {:.0}% of pixels converged",
                self.mean_error,
                100.0 * f
            ),
            None => format!("noise {:.4}", self.mean_error),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The error of equal samples is 0; of samples 1 and 3 alternating in one channel,
    /// √(2/π) σ/√n over the root of the intensity; checks only at min_spp + k·STEP.
    #[test]
    fn error_and_check_points() {
        let mut px = Pixel::default();
        for _ in 0..16 {
            px.add_sample([2.0, 1.0, 0.5], 1.0);
        }
        assert_eq!(error(&px), 0.0);
        let mut px = Pixel::default();
        for i in 0..16 {
            px.add_sample([if i % 2 == 0 { 1.0 } else { 3.0 }, 0.0, 0.0], 1.0);
        }
        // I = 2; σ² = Σ(x − 2)²/15 = 16/15; σ/√n = √(1/15); √I = √2.
        let expected = (2.0 / std::f64::consts::PI).sqrt() * (1.0f64 / 15.0).sqrt();
        assert!((error(&px) - expected / (1e-4 + 2f64.sqrt())).abs() < 1e-12);
        let a = Adaptive::new(0.2, 16, 1024);
        assert!(a.converged(&px));
        let strict = Adaptive::new(0.1, 16, 1024);
        assert!(!strict.converged(&px));
        px.add_sample([2.0, 0.0, 0.0], 1.0);
        assert!(!a.converged(&px), "17 samples is not a check point");
        assert_eq!(Adaptive::new(0.1, 0, 1024).min_spp, 32);
        assert_eq!(Adaptive::new(0.1, 0, 64).min_spp, 16);
        assert_eq!(Adaptive::new(0.1, 5, 64).min_spp, 6);
    }
}
