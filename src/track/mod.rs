//! Free-path sampling and transmittance estimation: the null-collision family of
//! Kutz et al. 2017 (see `../shared/docs/tracking.md`).
//!
//! Every tracker walks the [`Segment`](crate::volume::majorant::Segment)s the majorant
//! structure hands out (the exponential is memoryless, so sampling restarts at every
//! cell boundary) and decides at each tentative collision between absorption,
//! scattering and a null collision. Trackers are plain functions over concrete types:
//! no dynamic dispatch per collision.

pub mod delta;
pub mod ratio;

use rand::Rng;

pub use crate::volume::medium::Spectrum;

/// The outcome of sampling a free path along a ray.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum FreePath {
    /// A real scattering collision at distance `t`.
    Scatter { t: f32 },
    /// A real absorption collision: the path ends (no emission yet).
    Absorb { t: f32 },
    /// The ray left the medium (or reached `tmax`) without a real collision.
    Escape,
}

/// An exponential step with rate `mu` (`mu > 0`): −ln(1 − u)/μ. `1 − u` lies in (0, 1],
/// so the logarithm is finite.
#[inline(always)]
pub fn exp_step<R: Rng>(rng: &mut R, mu: f32) -> f32 {
    let u: f32 = rng.gen();
    -(1.0 - u).ln() / mu
}

#[inline(always)]
pub fn avg(s: Spectrum) -> f32 {
    (s[0] + s[1] + s[2]) * (1.0 / 3.0)
}

#[inline(always)]
pub fn max3(s: Spectrum) -> f32 {
    s[0].max(s[1]).max(s[2])
}
