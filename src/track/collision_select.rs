//! One ratio-tracking walk along a ray that estimates both terms of the radiance
//! arriving along it: the transmittance to its end (what the background contributes)
//! and the in-scattering, by choosing one of the walk's tentative collisions to scatter
//! at.
//!
//! Along a ray the radiance is L = ∫ T(t)·μs(t)·Ls(t) dt + T(tmax)·Lb. Free-path
//! sampling estimates it by one Bernoulli trial per ray (escape with the background, or
//! scatter), and in a pixel that is half cloud and half sky that coin flip is most of
//! the pixel's variance. Ratio tracking instead walks the tentative collisions t_i of
//! the majorant process (rate μ̄) to the end of the ray and keeps the product
//! T̂_i = Π_{j<i} (1 − μt(t_j)/μ̄): T̂ at the end estimates T(tmax), and
//!
//!   Σ_i a_i·Ls(t_i),   a_i(λ) = T̂_i(λ)·μs(t_i, λ)/μ̄,
//!
//! is an unbiased estimate of the in-scattering integral (the expectation of a sum over
//! a Poisson process of rate μ̄ is ∫ μ̄·E[…] dt, and E[T̂(t)] = T(t)). Evaluating Ls at
//! every t_i would cost a path per collision, so one collision I is chosen with
//! probability p_I = ā_I / Σ ā_i (ā the channel average of |a|, by weighted reservoir
//! sampling as the walk goes: no storage) and continues the path with throughput
//! a_I(λ)/p_I. Both terms are unbiased and each is always estimated: no coin flip
//! between them.
//!
//! The density lookups are ratio tracking's own (the walk's), with its Russian roulette
//! on small products (which keeps the sum unbiased: the later a_i carry the roulette's
//! division). Each reads one voxel of the trilinear stencil, chosen with the trilinear
//! weights ([`Medium::density_estimate`]): the factors and the a_i are linear in the
//! density, so an unbiased estimate of it keeps them unbiased. The walk goes on past
//! the collision free-path sampling would have stopped at, so it looks up more often
//! than a free path does; what it buys is measured in docs/performance.md ("One walk for
//! both terms").
//!
//! [`Medium::density_estimate`]: crate::volume::medium::Medium::density_estimate

use super::ratio::{ratio_walk, Estimate};
use crate::color::Spectrum;
use crate::track::free_path::Query;
use crate::volume::counters::Tally;
use rand::Rng;

/// The estimates of one walk.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SegmentEstimate {
    /// Transmittance to the end of the ray, per channel (without the path's
    /// throughput).
    pub transmittance: Spectrum,
    /// The collision chosen to scatter at: its distance and the throughput a path
    /// scattering there carries (the path's throughput times a_I / p_I); `None` when
    /// no collision could scatter.
    pub scatter: Option<(f32, Spectrum)>,
    /// With emission asked for, the collision chosen (independently, by
    /// T̂_i·μa(t_i)/μ̄) to evaluate the source term ∫ T·μa·Le at, and the weight of
    /// its Le; `None` otherwise.
    pub emit: Option<(f32, Spectrum)>,
}

/// One collision kept out of a stream of them, each with probability proportional to
/// its weight's channel average (weighted reservoir sampling of size 1).
#[derive(Clone, Copy)]
struct Reservoir {
    /// Σ ā_i so far.
    sum: f32,
    t: f32,
    a: Spectrum,
    a_avg: f32,
}

impl Reservoir {
    const EMPTY: Reservoir = Reservoir {
        sum: 0.0,
        t: 0.0,
        a: [0.0; 3],
        a_avg: 0.0,
    };

    /// Offers the collision at `t` with weight `a`.
    #[inline(always)]
    fn offer<R: Rng>(&mut self, t: f32, a: Spectrum, rng: &mut R) {
        let a_avg = (a[0].abs() + a[1].abs() + a[2].abs()) * (1.0 / 3.0);
        if a_avg > 0.0 {
            self.sum += a_avg;
            // Keep it with probability ā_i / Σ ā: the last one kept was then chosen
            // with probability ā_I / Σ ā over the whole stream.
            if rng.gen::<f32>() * self.sum < a_avg {
                *self = Reservoir {
                    t,
                    a,
                    a_avg,
                    ..*self
                };
            }
        }
    }

    /// The kept collision and its weight a_I / p_I = a_I · Σ ā / ā_I.
    #[inline(always)]
    fn chosen(self) -> Option<(f32, Spectrum)> {
        (self.sum > 0.0).then(|| (self.t, self.a.map(|x| x * (self.sum / self.a_avg))))
    }
}

/// Ratio tracking along `q`'s ray, choosing one collision for in-scattering (and one
/// for emission when `emission`), for a path of `throughput`: the choice is in
/// proportion to the path's contribution, throughput × T̂ × μ/μ̄, averaged over the
/// channels (the history-aware choice of spectral tracking's hist-avg).
///
/// `T` is the walk's estimate T̂: one value per channel, or one scalar for a grey
/// medium (`f32`), whose three channels would hold the same product. The weights are
/// formed per channel from it either way, so on a grey medium both make the same
/// choices from the same random numbers.
#[inline(always)]
pub fn ratio_select<T: Estimate, R: Rng, C: Tally>(
    q: &Query,
    throughput: Spectrum,
    emission: bool,
    rng: &mut R,
    c: &mut C,
) -> SegmentEstimate {
    let sg = q.sigma;
    let mut scatter = Reservoir::EMPTY;
    let mut emit = Reservoir::EMPTY;
    // One voxel of the trilinear stencil per collision, chosen by its weight: every use
    // of d is linear, so the estimates stay unbiased at an eighth of the reads.
    let tr = ratio_walk::<T, R, C, true>(q, rng, c, |t, d, mu_bar, tr, rng, c| {
        if d * sg.t_max > mu_bar {
            c.majorant_violation();
        }
        let scale = d / mu_bar;
        let tr = tr.spectrum();
        // The path's weight of this collision before its own attenuation: T̂_i.
        let w: Spectrum = std::array::from_fn(|k| throughput[k] * tr[k] * scale);
        scatter.offer(t, std::array::from_fn(|k| w[k] * sg.s[k]), rng);
        if emission {
            emit.offer(t, std::array::from_fn(|k| w[k] * sg.a[k]), rng);
        }
    });
    let scatter = scatter.chosen();
    if let Some((_, w)) = scatter {
        c.real_collision();
        c.observe_throughput(w);
    }
    SegmentEstimate {
        transmittance: tr.spectrum(),
        scatter,
        emit: emit.chosen(),
    }
}
