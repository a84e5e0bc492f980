//! Decomposition tracking (paper §4) and its spectral form (§5.2).
//!
//! In each majorant cell the density is split into a constant control d_c and a
//! residual d(x) − d_c. Two independent collision processes run side by side: the
//! control with rate μ̄c = d_c·max σt (its coefficients are known, so its collisions
//! need no density lookup) and the residual with rate μ̄r = r·max σt, where r bounds
//! |d − d_c| in the cell. Their union is a null-collision process with majorant
//! μ̄c + μ̄r (the supplement's §1.1), so the estimator is unbiased for any control.
//!
//! - control = cell minimum (`control` = 0): analog decomposition tracking; for grey
//!   media every control collision is real and residual collisions are accepted with
//!   probability (d − d_min)/(d_max − d_min).
//! - control above the minimum: the residual goes negative in places and is tracked
//!   with signed weights (weighted decomposition).
//! - with a spectral scheme, both processes choose events by it, with the same albedo
//!   in both (density-driven media): spectral decomposition.

use super::race::race;
use super::scheme::{collide, Coefficients, Scheme, SchemeOptions};
use crate::color::Spectrum;
use crate::track::free_path::{with_walk, FreePath, FreePathSampler, OpticalDepth, Query};
use crate::volume::counters::Tally;
use crate::volume::majorant::Segment;
use rand::Rng;
use std::marker::PhantomData;
use std::ops::ControlFlow;

#[derive(Clone, Copy, Debug)]
pub struct Decomposition<S: Scheme> {
    /// Control position in the cell: d_c = d_min + control·(d_max − d_min).
    pub control: f32,
    pub options: SchemeOptions,
    _scheme: PhantomData<S>,
}

impl<S: Scheme> Decomposition<S> {
    pub fn new(control: f32, options: SchemeOptions) -> Self {
        Decomposition {
            control: control.clamp(0.0, 1.0),
            options,
            _scheme: PhantomData,
        }
    }
}

/// A majorant segment split into a constant control d_c and a residual bound
/// r ≥ |d − d_c|, with the rates of their collision processes μ̄c = d_c·max σt and
/// μ̄r = r·max σt. Shared with the single-channel
/// [`GreyDecomposition`](super::grey::GreyDecomposition).
#[derive(Clone, Copy)]
pub(super) struct Split {
    pub dc: f32,
    pub r: f32,
    pub mu_c: f32,
    pub mu_r: f32,
}

impl Split {
    /// The split at d_c = d_min + control·(d_max − d_min).
    #[inline(always)]
    pub(super) fn of(q: &Query, seg: &Segment, control: f32) -> Split {
        let t_max = q.sigma.t_max;
        let dc = seg.dmin + control * (seg.dmax - seg.dmin);
        let r = (seg.dmax - dc).max(dc - seg.dmin) * q.majorant_scale;
        Split {
            dc,
            r,
            mu_c: dc * t_max,
            mu_r: r * t_max,
        }
    }

    /// The residual d(x) − d_c at `t`, looked up and counted. A residual beyond its
    /// bound, or below 0 when the control is the minimum (`at_minimum`), is counted as
    /// a majorant violation.
    #[inline(always)]
    pub(super) fn residual<C: Tally>(&self, q: &Query, t: f32, at_minimum: bool, c: &mut C) -> f32 {
        let d = q.medium.density_on(q.ray, t, c);
        c.residual_lookup();
        let dr = d - self.dc;
        if dr > self.r || (at_minimum && dr < 0.0) {
            c.majorant_violation();
        }
        dr
    }
}

/// A split majorant cell and what its control's collisions need, which is constant
/// over the cell (coefficients, or a grey medium's event probabilities).
#[derive(Clone, Copy)]
pub(super) struct Cell<K> {
    pub split: Split,
    pub control: K,
}

impl<S: Scheme> Decomposition<S> {
    #[inline(always)]
    fn cell(&self, q: &Query, seg: &Segment) -> Cell<Coefficients> {
        let split = Split::of(q, seg, self.control);
        Cell {
            split,
            control: Coefficients::of(q.sigma, split.dc, split.mu_c),
        }
    }

    /// One tentative collision at `t` of the control (`control_first`) or the
    /// residual process of `cell`.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn decide<R: Rng, C: Tally>(
        &self,
        q: &Query,
        cell: &Cell<Coefficients>,
        control_first: bool,
        t: f32,
        throughput: &mut Spectrum,
        rng: &mut R,
        c: &mut C,
    ) -> Option<FreePath> {
        let (k, mu_bar) = if control_first {
            c.control_collision();
            (cell.control, cell.split.mu_c)
        } else {
            let dr = cell.split.residual(q, t, self.control == 0.0, c);
            (
                Coefficients::of(q.sigma, dr, cell.split.mu_r),
                cell.split.mu_r,
            )
        };
        collide::<S, C>(&k, mu_bar, t, self.options, rng.gen(), throughput, c)
    }
}

impl<S: Scheme> FreePathSampler for Decomposition<S> {
    #[inline]
    fn sample<R: Rng, C: Tally>(
        &self,
        q: &Query,
        throughput: &mut Spectrum,
        rng: &mut R,
        c: &mut C,
    ) -> FreePath {
        walk_processes(
            q,
            rng,
            c,
            |seg| self.cell(q, seg),
            |cell, control_first, t, rng, c| {
                self.decide(q, cell, control_first, t, throughput, rng, c)
            },
        )
    }

    /// Every medium runs its control and residual processes; the race merges the 2k
    /// processes in `t` order.
    fn sample_race<R: Rng, C: Tally>(
        &self,
        qs: &[Query],
        throughput: &mut Spectrum,
        rng: &mut R,
        c: &mut C,
    ) -> (FreePath, usize) {
        race_processes(
            qs,
            rng,
            c,
            |q, seg| self.cell(q, seg),
            |q, cell, control_first, t, rng, c| {
                self.decide(q, cell, control_first, t, throughput, rng, c)
            },
        )
    }
}

/// The two collision processes of decomposition tracking along `q`'s ray: `cell` splits
/// each majorant segment into its control and residual, and `decide` turns a tentative collision of the control (`true`) or the residual
/// into an event, `None` for a null collision. Shared by [`Decomposition`] and the
/// single-channel [`GreyDecomposition`](super::grey::GreyDecomposition), which must
/// make the same draws in the same order.
#[inline(always)]
pub(super) fn walk_processes<R: Rng, C: Tally, K>(
    q: &Query,
    rng: &mut R,
    c: &mut C,
    cell: impl Fn(&Segment) -> Cell<K>,
    mut decide: impl FnMut(&Cell<K>, bool, f32, &mut R, &mut C) -> Option<FreePath>,
) -> FreePath {
    with_walk!(q, |walk| {
        let (mut tau_c, mut tau_r) = (OpticalDepth::sample(rng), OpticalDepth::sample(rng));
        while let Some(seg) = c.next_segment(&mut walk) {
            let k = cell(&seg);
            let (mu_c, mu_r) = (k.split.mu_c, k.split.mu_r);
            if !(mu_c > 0.0) && !(mu_r > 0.0) {
                continue;
            }
            // Each process spends its own optical depth across cells.
            let mut tc = tau_c.time(seg.t0, mu_c);
            let mut tr = tau_r.time(seg.t0, mu_r);
            loop {
                let control_first = tc <= tr;
                let t = if control_first { tc } else { tr };
                if t >= seg.t1 {
                    tau_c = tau_c.left(tc, seg.t1, mu_c);
                    tau_r = tau_r.left(tr, seg.t1, mu_r);
                    break;
                }
                if let Some(event) = decide(&k, control_first, t, rng, c) {
                    return event;
                }
                // Memoryless: only the process that fired draws its next time.
                if control_first {
                    tc = OpticalDepth::sample(rng).time(t, mu_c);
                } else {
                    tr = OpticalDepth::sample(rng).time(t, mu_r);
                }
            }
        }
        FreePath::Escape
    })
}

/// [`walk_processes`] for several media: every medium runs its control and residual
/// processes, and the race ([`race`]) merges the 2k processes in `t` order. The cell is
/// split again at each tentative collision (the race hands out segments, not cells).
#[inline(always)]
pub(super) fn race_processes<R: Rng, C: Tally, K>(
    qs: &[Query],
    rng: &mut R,
    c: &mut C,
    cell: impl Fn(&Query, &Segment) -> Cell<K>,
    mut decide: impl FnMut(&Query, &Cell<K>, bool, f32, &mut R, &mut C) -> Option<FreePath>,
) -> (FreePath, usize) {
    race(
        qs,
        rng,
        c,
        |i, seg| {
            let s = cell(&qs[i], seg).split;
            [s.mu_c, s.mu_r]
        },
        |e, rng, c| {
            let q = &qs[e.lane];
            match decide(q, &cell(q, e.seg), e.process == 0, e.t, rng, c) {
                Some(event) => ControlFlow::Break(event),
                None => ControlFlow::Continue(()),
            }
        },
    )
    .unwrap_or((FreePath::Escape, 0))
}
