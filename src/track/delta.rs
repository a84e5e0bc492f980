//! Delta tracking with an achromatic majorant μ̄ = d_max·max_λ σt(λ).
//!
//! For grey media this is analog delta tracking: every collision weight is 1. For
//! chromatic media the events are chosen by the per-channel average of each coefficient
//! (the paper's "avg" probabilities) and the throughput takes the collision weights
//! w★(λ) = μ★(λ)/(μ̄·P★), so the estimate stays unbiased.
//!
//! Delta tracking needs μ̄ ≥ μt. A collision where any channel's extinction exceeds
//! the majorant is counted in `majorant_violations`. While the channel average stays
//! below μ̄ the signed null weights keep the estimate unbiased; where the null
//! probability itself would be negative the collision is treated as a null collision
//! with unit weight (biased, and reported, never silent). `weighted-delta` is the
//! estimator that stays unbiased there.

use super::race::race_collisions;
use crate::color::Spectrum;
use crate::track::free_path::{walk_collisions, FreePath, FreePathSampler, Query};
use crate::volume::counters::Tally;
use rand::Rng;
use std::ops::ControlFlow;

#[derive(Clone, Copy, Debug, Default)]
pub struct Delta;

impl FreePathSampler for Delta {
    #[inline]
    fn sample<R: Rng, C: Tally>(
        &self,
        q: &Query,
        throughput: &mut Spectrum,
        rng: &mut R,
        c: &mut C,
    ) -> FreePath {
        let avg_a = crate::track::free_path::avg(q.sigma.a);
        let avg_s = crate::track::free_path::avg(q.sigma.s);
        walk_collisions(q, rng, c, |t, mu_bar, rng, c| {
            decide(q, t, mu_bar, avg_a, avg_s, throughput, rng, c)
        })
        .unwrap_or(FreePath::Escape)
    }

    fn sample_race<R: Rng, C: Tally>(
        &self,
        qs: &[Query],
        throughput: &mut Spectrum,
        rng: &mut R,
        c: &mut C,
    ) -> (FreePath, usize) {
        race_collisions(qs, rng, c, |q, t, mu_bar, rng, c| {
            let (avg_a, avg_s) = (
                crate::track::free_path::avg(q.sigma.a),
                crate::track::free_path::avg(q.sigma.s),
            );
            decide(q, t, mu_bar, avg_a, avg_s, throughput, rng, c)
        })
        .unwrap_or((FreePath::Escape, 0))
    }
}

/// One tentative collision of delta tracking at `t` under majorant `mu_bar`.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn decide<R: Rng, C: Tally>(
    q: &Query,
    t: f32,
    mu_bar: f32,
    avg_a: f32,
    avg_s: f32,
    throughput: &mut Spectrum,
    rng: &mut R,
    c: &mut C,
) -> ControlFlow<FreePath> {
    let sg = q.sigma;
    let Collision { d, pa, ps, u } = collide(q, t, mu_bar, avg_a, avg_s, rng, c);
    let pn = 1.0 - pa - ps;
    if u < pa {
        c.real_collision();
        // Absorption weight w_a(λ) = μa(λ)/(μ̄·Pa) = σa(λ)/avg σa (1 for grey
        // media), for the emission collected at absorption events.
        for ch in 0..3 {
            throughput[ch] *= sg.a[ch] / avg_a;
        }
        c.observe_throughput(*throughput);
        return ControlFlow::Break(FreePath::Absorb { t });
    }
    if u < pa + ps {
        c.real_collision();
        for ch in 0..3 {
            throughput[ch] *= d * sg.s[ch] / (mu_bar * ps);
        }
        c.observe_throughput(*throughput);
        return ControlFlow::Break(FreePath::Scatter { t });
    }
    c.null_collision();
    if pn > 0.0 {
        for ch in 0..3 {
            throughput[ch] *= (mu_bar - d * sg.t[ch]) / (mu_bar * pn);
        }
        c.observe_throughput(*throughput);
    }
    ControlFlow::Continue(())
}

/// A tentative collision of delta tracking: the density there, the event
/// probabilities P★ = avg_λ μ★(λ)/μ̄ and the uniform that decides between them.
pub(super) struct Collision {
    pub d: f32,
    pub pa: f32,
    pub ps: f32,
    pub u: f32,
}

/// Looks up the density at `t`, computes the probabilities and draws the uniform;
/// counts a violation where any channel's extinction exceeds the majorant (its null
/// weight turns negative), not only the average's, with a tolerance for rounding
/// where the density equals the majorant. Shared with the single-channel tracker,
/// which must make the same decisions from the same numbers.
#[inline(always)]
pub(super) fn collide<R: Rng, C: Tally>(
    q: &Query,
    t: f32,
    mu_bar: f32,
    avg_a: f32,
    avg_s: f32,
    rng: &mut R,
    c: &mut C,
) -> Collision {
    let d = q.medium.density_on(q.ray, t, c);
    if d * q.sigma.t_max > mu_bar * (1.0 + 1e-5) {
        c.majorant_violation();
    }
    Collision {
        d,
        pa: d * avg_a / mu_bar,
        ps: d * avg_s / mu_bar,
        u: rng.gen(),
    }
}
