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

use crate::track::free_path::{
    majorant, prefetch_next, walk_collisions, with_walk, OpticalDepth, Query,
    TransmittanceEstimator,
};

use crate::color::Spectrum;
use crate::volume::counters::Tally;
use rand::Rng;
use std::ops::ControlFlow;

pub const RR_THRESHOLD: f32 = 0.1;
pub const RR_SURVIVAL: f32 = 0.5;

/// Ratio tracking's majorant multiplier on shadow rays towards local lights
/// ([`TransmittanceEstimator::LOCAL_LIGHT_MAJORANT_SCALE`]).
pub const LOOSE_MAJORANT: f32 = 2.0;

#[derive(Clone, Copy, Debug, Default)]
pub struct Ratio;

#[derive(Clone, Copy, Debug, Default)]
pub struct ResidualRatio;

/// A transmittance estimate: one value per channel, or one scalar for a grey medium,
/// where the three channels would hold the same product (the single-channel
/// estimators of [`grey`](super::grey)). Both run the same estimator code.
pub trait Estimate: Copy {
    const ONE: Self;
    const ZERO: Self;
    /// Multiplies each channel λ by `f(σt(λ))` (a grey estimate: `f(σt)` once).
    fn attenuate(&mut self, sigma_t: &Spectrum, f: impl Fn(f32) -> f32);
    /// The largest channel magnitude.
    fn magnitude(&self) -> f32;
    fn divide(&mut self, s: f32);
    fn spectrum(self) -> Spectrum;
    /// `self + (fine − (even + odd)/2)·inv_p`: a telescoping estimate's base term plus
    /// its correction ([`telescoping`](super::telescoping)).
    fn telescope(self, fine: Self, even: Self, odd: Self, inv_p: f32) -> Self;
}

impl Estimate for Spectrum {
    const ONE: Self = [1.0; 3];
    const ZERO: Self = [0.0; 3];
    #[inline(always)]
    fn attenuate(&mut self, sigma_t: &Spectrum, f: impl Fn(f32) -> f32) {
        for ch in 0..3 {
            self[ch] *= f(sigma_t[ch]);
        }
    }
    #[inline(always)]
    fn magnitude(&self) -> f32 {
        self[0].abs().max(self[1].abs()).max(self[2].abs())
    }
    #[inline(always)]
    fn divide(&mut self, s: f32) {
        for v in self.iter_mut() {
            *v /= s;
        }
    }
    #[inline(always)]
    fn spectrum(self) -> Spectrum {
        self
    }
    #[inline(always)]
    fn telescope(self, fine: Self, even: Self, odd: Self, inv_p: f32) -> Self {
        std::array::from_fn(|ch| self[ch] + (fine[ch] - 0.5 * (even[ch] + odd[ch])) * inv_p)
    }
}

impl Estimate for f32 {
    const ONE: Self = 1.0;
    const ZERO: Self = 0.0;
    #[inline(always)]
    fn attenuate(&mut self, sigma_t: &Spectrum, f: impl Fn(f32) -> f32) {
        *self *= f(sigma_t[0]);
    }
    #[inline(always)]
    fn magnitude(&self) -> f32 {
        self.abs()
    }
    #[inline(always)]
    fn divide(&mut self, s: f32) {
        *self /= s;
    }
    #[inline(always)]
    fn spectrum(self) -> Spectrum {
        [self; 3]
    }
    #[inline(always)]
    fn telescope(self, fine: Self, even: Self, odd: Self, inv_p: f32) -> Self {
        self + (fine - 0.5 * (even + odd)) * inv_p
    }
}

/// Applies Russian roulette to `tr`; returns false when the estimate was killed.
#[inline(always)]
fn roulette<T: Estimate, R: Rng>(tr: &mut T, rng: &mut R) -> bool {
    let m = tr.magnitude();
    if m == 0.0 {
        return false; // nothing left to estimate (e.g. the control's exp underflowed)
    }
    if m < RR_THRESHOLD {
        if rng.gen::<f32>() >= RR_SURVIVAL {
            *tr = T::ZERO;
            return false;
        }
        tr.divide(RR_SURVIVAL);
    }
    true
}

/// Ratio tracking along `q`'s ray; with `STOCHASTIC`, each collision reads one voxel
/// of the trilinear stencil ([`Medium::density_estimate`]), which keeps the estimate
/// unbiased because every factor is linear in the density.
///
/// A segment whose density is constant (its bounds equal: inside a fog box, world
/// fog, a uniform cell of a grid) attenuates in closed form, exp(−d·σt·Δt), with no
/// lookup: there every tentative collision under the tight majorant would be real and
/// the estimate 0 or 1 (the track-length estimator's variance), where the exact factor
/// has none. The walk goes on with a fresh optical depth, which the memoryless
/// exponential allows.
///
/// [`Medium::density_estimate`]: crate::volume::medium::Medium::density_estimate
#[inline(always)]
pub(super) fn ratio<T: Estimate, R: Rng, C: Tally, const STOCHASTIC: bool>(
    q: &Query,
    rng: &mut R,
    c: &mut C,
) -> T {
    let sg = q.sigma;
    let mut tr = T::ONE;
    with_walk!(q, |walk| {
        let mut tau = OpticalDepth::sample(rng);
        while let Some(seg) = c.next_segment(&mut walk) {
            if seg.dmin == seg.dmax {
                if seg.dmax > 0.0 {
                    let len = seg.t1 - seg.t0;
                    tr.attenuate(&sg.t, |st| (-seg.dmax * st * len).exp());
                    if !roulette(&mut tr, rng) {
                        return tr;
                    }
                }
                continue;
            }
            let mu_bar = majorant(q, &seg);
            if !(mu_bar > 0.0) {
                continue;
            }
            let mut t = seg.t0;
            while let Some(tc) = tau.collide(t, seg.t1, mu_bar) {
                t = tc;
                tau = OpticalDepth::sample(rng);
                prefetch_next(q, tau, t, seg.t1, mu_bar);
                let d = if STOCHASTIC {
                    q.medium.density_estimate_on(q.ray, t, rng.gen::<u64>(), c)
                } else {
                    q.medium.density_on(q.ray, t, c)
                };
                c.null_collision();
                tr.attenuate(&sg.t, |st| 1.0 - d * st / mu_bar);
                if !roulette(&mut tr, rng) {
                    return tr;
                }
            }
        }
        tr
    })
}

/// [`ratio`], calling `at(t, d, μ̄, T̂, rng, counters)` at each tentative collision with
/// its density and the product T̂ of the collisions before it (what `ratio-select`
/// weighs the collision by).
#[inline(always)]
pub(super) fn ratio_walk<T: Estimate, R: Rng, C: Tally, const STOCHASTIC: bool>(
    q: &Query,
    rng: &mut R,
    c: &mut C,
    mut at: impl FnMut(f32, f32, f32, &T, &mut R, &mut C),
) -> T {
    let sg = q.sigma;
    let mut tr = T::ONE;
    walk_collisions(q, rng, c, |t, mu_bar, rng, c| {
        let d = if STOCHASTIC {
            q.medium.density_estimate_on(q.ray, t, rng.gen::<u64>(), c)
        } else {
            q.medium.density_on(q.ray, t, c)
        };
        c.null_collision();
        at(t, d, mu_bar, &tr, rng, c);
        tr.attenuate(&sg.t, |st| 1.0 - d * st / mu_bar);
        if roulette(&mut tr, rng) {
            ControlFlow::Continue(())
        } else {
            ControlFlow::Break(())
        }
    });
    tr
}

/// Residual ratio tracking along `q`'s ray, with each cell's minimum as control.
#[inline(always)]
pub(super) fn residual_ratio<T: Estimate, R: Rng, C: Tally>(
    q: &Query,
    rng: &mut R,
    c: &mut C,
) -> T {
    let sg = q.sigma;
    let mut tr = T::ONE;
    with_walk!(q, |walk| {
        let mut tau = OpticalDepth::sample(rng);
        while let Some(seg) = c.next_segment(&mut walk) {
            if seg.dmin > 0.0 {
                let len = seg.t1 - seg.t0;
                tr.attenuate(&sg.t, |st| (-seg.dmin * st * len).exp());
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
            while let Some(tc) = tau.collide(t, seg.t1, mu_r) {
                t = tc;
                tau = OpticalDepth::sample(rng);
                prefetch_next(q, tau, t, seg.t1, mu_r);
                let d = q.medium.density_on(q.ray, t, c);
                c.residual_lookup();
                c.null_collision();
                tr.attenuate(&sg.t, |st| 1.0 - (d - seg.dmin) * st / mu_r);
                if !roulette(&mut tr, rng) {
                    return tr;
                }
            }
        }
        tr
    })
}

impl TransmittanceEstimator for Ratio {
    const LOCAL_LIGHT_MAJORANT_SCALE: f32 = LOOSE_MAJORANT;

    fn transmittance<R: Rng, C: Tally>(&self, q: &Query, rng: &mut R, c: &mut C) -> Spectrum {
        ratio::<Spectrum, R, C, false>(q, rng, c)
    }
}

/// Ratio tracking with one-voxel stochastic lookups (`ratio-select`'s shadow rays).
#[derive(Clone, Copy, Debug, Default)]
pub struct StochasticRatio;

impl TransmittanceEstimator for StochasticRatio {
    const LOCAL_LIGHT_MAJORANT_SCALE: f32 = LOOSE_MAJORANT;

    fn transmittance<R: Rng, C: Tally>(&self, q: &Query, rng: &mut R, c: &mut C) -> Spectrum {
        ratio::<Spectrum, R, C, true>(q, rng, c)
    }
}

impl TransmittanceEstimator for ResidualRatio {
    fn transmittance<R: Rng, C: Tally>(&self, q: &Query, rng: &mut R, c: &mut C) -> Spectrum {
        residual_ratio::<Spectrum, R, C>(q, rng, c)
    }
}
