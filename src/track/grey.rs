//! Single-channel trackers for grey media (σa, σs the same in every channel).
//!
//! In a grey medium delta tracking is analog — every collision weight μ★/(μ̄·P★) is 1 —
//! and ratio tracking's three channels hold the same product. These trackers skip the
//! per-channel weights and keep one scalar, while making the same decisions from the
//! same random numbers as [`Delta`](super::delta::Delta) and [`Ratio`](super::ratio::Ratio):
//! on a grey medium the image differs from the general path's only by the rounding
//! of weights that are 1 there. [`dispatch_specialised`](super::dispatch_specialised)
//! picks them only for grey media.

use super::delta::{collide, Collision};
use super::race::race_collisions;
use super::ratio::{RR_SURVIVAL, RR_THRESHOLD};
use super::{
    avg, walk_collisions, FreePath, FreePathSampler, Query, Spectrum, TransmittanceEstimator,
};
use crate::volume::medium::Tally;
use rand::Rng;
use std::ops::ControlFlow;

/// Analog delta tracking of a grey medium: the throughput is never touched.
#[derive(Clone, Copy, Debug, Default)]
pub struct GreyDelta;

/// Ratio tracking of a grey medium with one scalar estimate.
#[derive(Clone, Copy, Debug, Default)]
pub struct GreyRatio;

impl FreePathSampler for GreyDelta {
    #[inline]
    fn sample<R: Rng, C: Tally>(
        &self,
        q: &Query,
        _throughput: &mut Spectrum,
        rng: &mut R,
        c: &mut C,
    ) -> FreePath {
        // The same expressions as `Delta`, so the same events from the same numbers.
        let avg_a = avg(q.sigma.a);
        let avg_s = avg(q.sigma.s);
        walk_collisions(q, rng, c, |t, mu_bar, rng, c| {
            decide(q, t, mu_bar, avg_a, avg_s, rng, c)
        })
        .unwrap_or(FreePath::Escape)
    }

    fn sample_race<R: Rng, C: Tally>(
        &self,
        qs: &[Query],
        _throughput: &mut Spectrum,
        rng: &mut R,
        c: &mut C,
    ) -> (FreePath, usize) {
        race_collisions(qs, rng, c, |q, t, mu_bar, rng, c| {
            decide(q, t, mu_bar, avg(q.sigma.a), avg(q.sigma.s), rng, c)
        })
        .unwrap_or((FreePath::Escape, 0))
    }
}

/// One tentative collision of analog delta tracking in a grey medium.
#[inline(always)]
fn decide<R: Rng, C: Tally>(
    q: &Query,
    t: f32,
    mu_bar: f32,
    avg_a: f32,
    avg_s: f32,
    rng: &mut R,
    c: &mut C,
) -> ControlFlow<FreePath> {
    let Collision { pa, ps, u, .. } = collide(q, t, mu_bar, avg_a, avg_s, rng, c);
    if u < pa {
        c.real_collision();
        return ControlFlow::Break(FreePath::Absorb { t });
    }
    if u < pa + ps {
        c.real_collision();
        return ControlFlow::Break(FreePath::Scatter { t });
    }
    c.null_collision();
    ControlFlow::Continue(())
}

impl TransmittanceEstimator for GreyRatio {
    #[inline]
    fn transmittance<R: Rng, C: Tally>(&self, q: &Query, rng: &mut R, c: &mut C) -> Spectrum {
        let st = q.sigma.t[0];
        let mut tr = 1f32;
        walk_collisions(q, rng, c, |t, mu_bar, rng, c| {
            let d = q.medium.density(q.ray.at(t), c);
            c.null_collision();
            tr *= 1.0 - d * st / mu_bar;
            // Russian roulette as in `Ratio` (same threshold, same draws).
            let m = tr.abs();
            if m == 0.0 {
                return ControlFlow::Break(());
            }
            if m < RR_THRESHOLD {
                if rng.gen::<f32>() >= RR_SURVIVAL {
                    tr = 0.0;
                    return ControlFlow::Break(());
                }
                tr /= RR_SURVIVAL;
            }
            ControlFlow::Continue(())
        });
        [tr; 3]
    }
}
