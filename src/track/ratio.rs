//! Transmittance estimators for shadow rays.
//!
//! - Ratio tracking (Novák et al. 2014): T̂(λ) = Π (1 − μt(x_i,λ)/μ̄) over tentative
//!   collisions drawn at rate μ̄.
//! - Residual ratio tracking: the cell's minimum density is a control whose
//!   transmittance exp(−d_min·σt·Δt) is known in closed form; only the residual
//!   (d − d_min)·σt is ratio-tracked, under μ̄r = (d_max − d_min)·max σt, so lookups
//!   happen at rate μ̄r instead of μ̄.
//!
//! Russian roulette on small estimates keeps long shadow rays cheap: once the largest
//! channel magnitude drops below [`RR_THRESHOLD`], the estimate survives with
//! probability [`RR_SURVIVAL`] and is divided by it, which keeps it unbiased.

use super::{walk_collisions, OpticalDepth, Query, Spectrum, TransmittanceEstimator};
use crate::volume::medium::Tally;
use rand::Rng;
use std::ops::ControlFlow;

pub const RR_THRESHOLD: f32 = 0.1;
pub const RR_SURVIVAL: f32 = 0.5;

#[derive(Clone, Copy, Debug, Default)]
pub struct Ratio;

#[derive(Clone, Copy, Debug, Default)]
pub struct ResidualRatio;

/// Applies Russian roulette to `tr`; returns false when the estimate was killed.
#[inline(always)]
fn roulette<R: Rng>(tr: &mut Spectrum, rng: &mut R) -> bool {
    let m = tr[0].abs().max(tr[1].abs()).max(tr[2].abs());
    if m == 0.0 {
        return false; // nothing left to estimate (e.g. the control's exp underflowed)
    }
    if m < RR_THRESHOLD {
        if rng.gen::<f32>() >= RR_SURVIVAL {
            *tr = [0.0; 3];
            return false;
        }
        for v in tr.iter_mut() {
            *v /= RR_SURVIVAL;
        }
    }
    true
}

impl TransmittanceEstimator for Ratio {
    fn transmittance<R: Rng, C: Tally>(&self, q: &Query, rng: &mut R, c: &mut C) -> Spectrum {
        let sg = q.sigma;
        let mut tr = [1f32; 3];
        walk_collisions(q, rng, c, |t, mu_bar, rng, c| {
            let d = q.medium.density(q.ray.at(t), c);
            c.null_collision();
            for ch in 0..3 {
                tr[ch] *= 1.0 - d * sg.t[ch] / mu_bar;
            }
            if roulette(&mut tr, rng) {
                ControlFlow::Continue(())
            } else {
                ControlFlow::Break(())
            }
        });
        tr
    }
}

impl TransmittanceEstimator for ResidualRatio {
    fn transmittance<R: Rng, C: Tally>(&self, q: &Query, rng: &mut R, c: &mut C) -> Spectrum {
        let sg = q.sigma;
        let mut tr = [1f32; 3];
        let mut walk = q.medium.majorants.walk(q.ray.o, q.ray.d, q.tmin, q.tmax);
        let mut tau = OpticalDepth::sample(rng);
        while let Some(seg) = c.next_segment(&mut walk) {
            if seg.dmin > 0.0 {
                let len = seg.t1 - seg.t0;
                for ch in 0..3 {
                    tr[ch] *= (-seg.dmin * sg.t[ch] * len).exp();
                }
                // The control attenuates without collisions, so roulette here too:
                // otherwise a shadow ray whose estimate the control has driven to ~0
                // keeps walking (and looking up the residual) to the far side.
                if !roulette(&mut tr, rng) {
                    return tr;
                }
            }
            let mu_r = (seg.dmax - seg.dmin) * sg.t_max * q.majorant_scale;
            if !(mu_r > 0.0) {
                continue;
            }
            let mut t = seg.t0;
            loop {
                let Some(tc) = tau.collide(t, seg.t1, mu_r) else {
                    break;
                };
                t = tc;
                tau = OpticalDepth::sample(rng);
                let d = q.medium.density(q.ray.at(t), c);
                c.residual_lookup();
                c.null_collision();
                for ch in 0..3 {
                    tr[ch] *= 1.0 - (d - seg.dmin) * sg.t[ch] / mu_r;
                }
                if !roulette(&mut tr, rng) {
                    return tr;
                }
            }
        }
        tr
    }
}
