//! Single-channel trackers for grey media (σa, σs the same in every channel).
//!
//! In a grey medium delta tracking and analog decomposition tracking are analog —
//! every collision weight μ★/(μ̄·P★) is 1 — and the three channels of ratio and
//! residual ratio tracking hold the same product. These trackers skip the per-channel
//! weights and keep one scalar, while making the same decisions from the same random
//! numbers as [`Delta`](super::delta::Delta), [`Decomposition`] with the cell minimum
//! as control and the avg scheme, [`Ratio`](super::ratio::Ratio),
//! [`StochasticRatio`](super::ratio::StochasticRatio) and
//! [`ResidualRatio`](super::ratio::ResidualRatio): on a grey medium the image differs
//! from the general path's only by the rounding of weights that are 1 there.
//! (`ratio-select`'s own walk runs single-channel by instantiating
//! [`ratio_select`](super::collision_select::ratio_select) with a scalar estimate.)
//! [`dispatch_specialised`](super::select::dispatch_specialised) picks them only for grey media.
//!
//! [`Decomposition`]: super::decomposition::Decomposition

use super::decomposition::{race_processes, walk_processes, Cell, Split};
use super::delta::{collide, Collision};
use super::race::race_collisions;
use super::ratio::{ratio, residual_ratio, Estimate};
use super::scheme::pick;
use crate::color::Spectrum;
use crate::track::free_path::{
    avg, walk_collisions, FreePath, FreePathSampler, Query, TransmittanceEstimator,
};
use crate::volume::counters::Tally;
use crate::volume::majorant::Segment;
use rand::Rng;
use std::ops::ControlFlow;

/// Analog delta tracking of a grey medium: the throughput is never touched.
#[derive(Clone, Copy, Debug, Default)]
pub struct GreyDelta;

/// Analog decomposition tracking of a grey medium (control = cell minimum): every
/// control collision is real, a residual collision is real with probability
/// (d − d_min)/(d_max − d_min), and the throughput is never touched.
#[derive(Clone, Copy, Debug, Default)]
pub struct GreyDecomposition;

/// Ratio tracking of a grey medium with one scalar estimate.
#[derive(Clone, Copy, Debug, Default)]
pub struct GreyRatio;

/// [`StochasticRatio`](super::ratio::StochasticRatio) (one voxel per collision,
/// `ratio-select`'s shadow rays) of a grey medium with one scalar estimate.
#[derive(Clone, Copy, Debug, Default)]
pub struct GreyStochasticRatio;

/// Residual ratio tracking (control = cell minimum) of a grey medium with one scalar
/// estimate.
#[derive(Clone, Copy, Debug, Default)]
pub struct GreyResidualRatio;

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

/// The avg scheme's preference for an event of coefficient `mu` in every channel:
/// the same operations as [`Avg`](super::scheme::Avg) on three equal channels, so the
/// same rounding.
#[inline(always)]
fn avg3(mu: f32) -> f32 {
    let m = mu.abs();
    (m + m + m) * (1.0 / 3.0)
}

/// The avg scheme's event probabilities (Pa, Ps, Pn) at density `d` under majorant
/// `mu_bar`, as [`probabilities`](super::scheme::probabilities) computes them for
/// three equal channels (no scheme options).
#[inline(always)]
fn probabilities(q: &Query, d: f32, mu_bar: f32) -> [f32; 3] {
    let sg = q.sigma;
    let p = [
        avg3(d * sg.a[0]),
        avg3(d * sg.s[0]),
        avg3(mu_bar - d * sg.t[0]),
    ];
    let sum = p[0] + p[1] + p[2];
    if !(sum > 0.0) {
        return [0.0, 0.0, 1.0];
    }
    let inv = 1.0 / sum;
    [p[0] * inv, p[1] * inv, p[2] * inv]
}

/// The event [`pick`] chooses from `u`, counted, as a free-path outcome.
#[inline(always)]
fn choose<C: Tally>(p: [f32; 3], u: f32, t: f32, c: &mut C) -> Option<FreePath> {
    match pick(p, u) {
        0 => {
            c.real_collision();
            Some(FreePath::Absorb { t })
        }
        1 => {
            c.real_collision();
            Some(FreePath::Scatter { t })
        }
        _ => {
            c.null_collision();
            None
        }
    }
}

impl GreyDecomposition {
    /// `Decomposition::cell` with control 0, and the control's event probabilities.
    #[inline(always)]
    fn cell(q: &Query, seg: &Segment) -> Cell<[f32; 3]> {
        let split = Split::of(q, seg, 0.0);
        Cell {
            split,
            control: probabilities(q, split.dc, split.mu_c),
        }
    }

    /// One tentative collision at `t` of the control (`control_first`) or the residual.
    #[inline(always)]
    fn decide<R: Rng, C: Tally>(
        q: &Query,
        cell: &Cell<[f32; 3]>,
        control_first: bool,
        t: f32,
        rng: &mut R,
        c: &mut C,
    ) -> Option<FreePath> {
        let p = if control_first {
            c.control_collision();
            cell.control
        } else {
            let dr = cell.split.residual(q, t, true, c);
            probabilities(q, dr, cell.split.mu_r)
        };
        choose(p, rng.gen(), t, c)
    }
}

impl FreePathSampler for GreyDecomposition {
    #[inline]
    fn sample<R: Rng, C: Tally>(
        &self,
        q: &Query,
        _throughput: &mut Spectrum,
        rng: &mut R,
        c: &mut C,
    ) -> FreePath {
        walk_processes(
            q,
            rng,
            c,
            |seg| Self::cell(q, seg),
            |cell, control_first, t, rng, c| Self::decide(q, cell, control_first, t, rng, c),
        )
    }

    fn sample_race<R: Rng, C: Tally>(
        &self,
        qs: &[Query],
        _throughput: &mut Spectrum,
        rng: &mut R,
        c: &mut C,
    ) -> (FreePath, usize) {
        race_processes(qs, rng, c, Self::cell, Self::decide)
    }
}

impl TransmittanceEstimator for GreyResidualRatio {
    #[inline]
    fn transmittance<R: Rng, C: Tally>(&self, q: &Query, rng: &mut R, c: &mut C) -> Spectrum {
        residual_ratio::<f32, R, C>(q, rng, c).spectrum()
    }
}

impl TransmittanceEstimator for GreyRatio {
    const LOCAL_LIGHT_MAJORANT_SCALE: f32 = super::ratio::LOOSE_MAJORANT;

    #[inline]
    fn transmittance<R: Rng, C: Tally>(&self, q: &Query, rng: &mut R, c: &mut C) -> Spectrum {
        ratio::<f32, R, C, false>(q, rng, c).spectrum()
    }
}

impl TransmittanceEstimator for GreyStochasticRatio {
    const LOCAL_LIGHT_MAJORANT_SCALE: f32 = super::ratio::LOOSE_MAJORANT;

    #[inline]
    fn transmittance<R: Rng, C: Tally>(&self, q: &Query, rng: &mut R, c: &mut C) -> Spectrum {
        ratio::<f32, R, C, true>(q, rng, c).spectrum()
    }
}
