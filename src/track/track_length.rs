//! The track-length estimator of transmittance: a shadow ray runs the render's own
//! free-path sampler and keeps its throughput if it escapes, 0 at the first real
//! collision. E[throughput·1{escape}] = T(λ), so it is unbiased wherever the free-path
//! sampler is; the estimate is binary for grey media (a visibility test), noisier than
//! ratio tracking's product, but it stops at the first real collision.
//!
//! Its point is the comparison of trackers: with every shadow ray tracked by the
//! tracker that samples the free paths, two trackers render the same estimator in
//! distribution (for grey media, both shadow rays are Bernoulli(T)) and differ only in
//! what they cost, which is what the supplement's Tables 1 and 2 compare. Decomposition
//! tracking's shadow rays then end at the first control collision, which needs no
//! lookup.

use crate::color::Spectrum;
use crate::track::free_path::{FreePath, FreePathSampler, Query, TransmittanceEstimator};
use crate::volume::counters::Tally;
use rand::Rng;

/// Shadow rays tracked by the free-path sampler `F`.
#[derive(Clone, Copy, Debug)]
pub struct Tracking<F: FreePathSampler>(pub F);

impl<F: FreePathSampler> TransmittanceEstimator for Tracking<F> {
    #[inline]
    fn transmittance<R: Rng, C: Tally>(&self, q: &Query, rng: &mut R, c: &mut C) -> Spectrum {
        let mut throughput = [1.0; 3];
        match self.0.sample(q, &mut throughput, rng, c) {
            FreePath::Escape => throughput,
            FreePath::Scatter { .. } | FreePath::Absorb { .. } => [0.0; 3],
        }
    }
}
