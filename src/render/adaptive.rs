//! Adaptive sampling (issue 48): each pixel stops taking samples once its estimated
//! noise is below a threshold.
//!
//! **The error estimate** is Cycles' (so the add-on can hand Cycles' Noise Threshold
//! over unchanged): the pixel keeps, beside the sum of its samples, the sum of its
//! even-numbered samples (0, 2, 4, …). With I the mean of all n samples and A twice
//! the even samples' sum over n (the mean of the even half), the error is
//!
//!   e = (|I_r − A_r| + |I_g − A_g| + |I_b − A_b|) / (10⁻⁴ + √(I_r + I_g + I_b)):
//!
//! half the difference between the two halves' means, which shrinks as σ/√n, in
//! units between absolute and relative (the square root keeps dark pixels from
//! taking every sample).
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

/// Samples between two checks of one pixel (even, so that both halves have equal
/// counts at every check).
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
    let mut diff = 0.0;
    let mut intensity = 0.0;
    for c in 0..3 {
        let i = px.rgb[c] / n;
        let a = 2.0 * px.half[c] / n;
        diff += (i - a).abs();
        intensity += i;
    }
    diff / (1e-4 + intensity.max(0.0).sqrt())
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

    /// The error of equal halves is 0; of halves differing by 2d in one channel, d over
    /// the root of the intensity; checks only at min_spp + k·STEP.
    #[test]
    fn error_and_check_points() {
        let mut px = Pixel::default();
        for i in 0..16 {
            px.add_sample([if i % 2 == 0 { 1.0 } else { 3.0 }, 0.0, 0.0], 1.0);
        }
        // I = 2, A = 1 (even samples are 1): |I − A| = 1, √I = √2.
        assert!((error(&px) - 1.0 / (1e-4 + 2f64.sqrt())).abs() < 1e-12);
        let a = Adaptive::new(0.8, 16, 1024);
        assert!(a.converged(&px));
        let strict = Adaptive::new(0.5, 16, 1024);
        assert!(!strict.converged(&px));
        px.add_sample([2.0, 0.0, 0.0], 1.0);
        assert!(!a.converged(&px), "17 samples is not a check point");
        assert_eq!(Adaptive::new(0.1, 0, 1024).min_spp, 32);
        assert_eq!(Adaptive::new(0.1, 0, 64).min_spp, 16);
        assert_eq!(Adaptive::new(0.1, 5, 64).min_spp, 6);
    }
}
