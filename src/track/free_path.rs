//! The free-path sampling interface every tracker implements: a [`Query`] in, a
//! [`FreePath`] out ([`FreePathSampler`]), shadow-ray [`TransmittanceEstimator`]s, and
//! the pieces the collision loops share (the walk over majorant segments, the optical
//! depth to the next tentative collision, small spectrum helpers).

use crate::color::Spectrum;
use crate::volume::counters::Tally;
use crate::volume::majorant::Segment;
use crate::volume::medium::{IndexRay, Medium, Sigma};
use rand::Rng;
use std::ops::ControlFlow;

/// The outcome of sampling a free path along a ray.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum FreePath {
    /// A real scattering collision at distance `t`.
    Scatter { t: f32 },
    /// A real absorption collision: the path ends. The throughput carries the
    /// absorption weight μa(λ)/(μ̄·Pa), so the integrator adds throughput × Le here.
    Absorb { t: f32 },
    /// The ray left the medium (or reached `tmax`) without a real collision.
    Escape,
}

/// What a tracker is handed for one free-path query.
pub struct Query<'a> {
    pub medium: &'a Medium,
    /// The cross-sections to track (the medium's, or one channel's for naive delta).
    pub sigma: &'a Sigma,
    pub ray: &'a IndexRay,
    pub tmin: f32,
    pub tmax: f32,
    /// Multiplies every majorant: 1 for the medium's bounds; below 1 to test trackers
    /// with non-bounding majorants.
    pub majorant_scale: f32,
}

/// Samples the first real collision, multiplying `throughput` by collision weights.
/// Samplers are small copyable parameter sets (the track-length estimator of
/// [`track_length`](super::track_length) holds one).
pub trait FreePathSampler: Sync + Copy {
    fn sample<R: Rng, C: Tally>(
        &self,
        q: &Query,
        throughput: &mut Spectrum,
        rng: &mut R,
        c: &mut C,
    ) -> FreePath;

    /// Samples the first real collision in the sum of several media overlapping along
    /// the ray (one query per medium, same ray and range; [`race`]), and returns the
    /// medium whose collision it was (0 on escape).
    fn sample_race<R: Rng, C: Tally>(
        &self,
        qs: &[Query],
        throughput: &mut Spectrum,
        rng: &mut R,
        c: &mut C,
    ) -> (FreePath, usize);
}

/// Estimates transmittance along a shadow ray.
pub trait TransmittanceEstimator: Sync {
    /// The majorant multiplier of shadow rays towards local lights (and of the
    /// equiangular points' transmittance). Ratio tracking under the octree's tight
    /// majorants degenerates towards the 0/1 estimate (relative second moment
    /// exp(∫ μ²/μ̄), 1/T when μ̄ = μ); twice the majorant halves that exponent for at
    /// most twice the shadow lookups. Measured to pay towards local lights and not
    /// towards the sun (docs/trackers.md), where it stays 1, so sun- and dome-lit
    /// renders are unchanged.
    const LOCAL_LIGHT_MAJORANT_SCALE: f32 = 1.0;

    fn transmittance<R: Rng, C: Tally>(&self, q: &Query, rng: &mut R, c: &mut C) -> Spectrum;

    /// The transmittance of several media along one ray: the product of independent
    /// estimates of each medium's transmittance, which is unbiased for the product
    /// (the sum medium's transmittance). Stops once the product is 0.
    fn transmittance_race<R: Rng, C: Tally>(
        &self,
        qs: &[Query],
        rng: &mut R,
        c: &mut C,
    ) -> Spectrum {
        let mut tr = [1f32; 3];
        for q in qs {
            mul(&mut tr, self.transmittance(q, rng, c));
            if tr == [0.0; 3] {
                break;
            }
        }
        tr
    }
}

/// Binds `$walk` to the medium's walk along `$q`'s ray and runs `$body` with it: for
/// a grid medium the bare majorant walk (built in place, no clipping state), for fog
/// the walk clipped to its region ([`Medium::walk`]). The body is compiled once per
/// walk type, so the grid path pays nothing for fog.
macro_rules! with_walk {
    ($q:expr, |$walk:ident| $body:expr) => {
        match &$q.medium.region {
            $crate::volume::boundary::MediumRegion::Grid => {
                let mut $walk = $q
                    .medium
                    .majorants
                    .walk($q.ray.o, $q.ray.d, $q.tmin, $q.tmax);
                $body
            }
            _ => {
                let mut $walk = $q.medium.walk($q.ray, $q.tmin, $q.tmax);
                $body
            }
        }
    };
}
pub(crate) use with_walk;

/// Walks the tentative collisions of the null-collision process whose majorant is
/// μ̄ = d_max·max σt (times `q.majorant_scale`) in each cell along the query's ray,
/// restarting the exponential at every cell boundary and skipping empty cells without
/// a lookup. `at(t, μ̄, rng, counters)` decides each collision; breaking returns its
/// value, running off the end returns `None`. (pbrt-v4's `SampleT_maj`, monomorphised.)
#[inline(always)]
pub fn walk_collisions<R: Rng, C: Tally, T>(
    q: &Query,
    rng: &mut R,
    c: &mut C,
    mut at: impl FnMut(f32, f32, &mut R, &mut C) -> ControlFlow<T>,
) -> Option<T> {
    with_walk!(q, |walk| {
        let mut tau = OpticalDepth::sample(rng);
        while let Some(seg) = c.next_segment(&mut walk) {
            let mu_bar = majorant(q, &seg);
            if !(mu_bar > 0.0) {
                continue; // empty cell: skipped without a lookup
            }
            let mut t = seg.t0;
            loop {
                let Some(tc) = tau.collide(t, seg.t1, mu_bar) else {
                    break;
                };
                t = tc;
                tau = OpticalDepth::sample(rng);
                prefetch_next(q, tau, t, seg.t1, mu_bar);
                if let ControlFlow::Break(v) = at(t, mu_bar, rng, c) {
                    return Some(v);
                }
            }
        }
        None
    })
}

/// Where the medium asks for it ([`Medium::prefetch`]), starts the lookup of the
/// tentative collision that follows one at `t` should that one be null: `tau`, drawn
/// before the current lookup, already fixes it (at rate `mu` up to the cell exit `t1`;
/// past the exit the next cell's rate decides, and nothing is prefetched). The current
/// lookup's miss and the next one's then overlap instead of queueing.
#[inline(always)]
pub fn prefetch_next(q: &Query, tau: OpticalDepth, t: f32, t1: f32, mu: f32) {
    if q.medium.prefetch {
        let next = tau.time(t, mu);
        if next < t1 {
            q.medium.density.prefetch(q.ray.at(next).to_array());
        }
    }
}

/// The achromatic majorant μ̄ = d_max·max σt (times the query's majorant scale) of a
/// majorant segment.
#[inline(always)]
pub fn majorant(q: &Query, seg: &Segment) -> f32 {
    seg.dmax * q.sigma.t_max * q.majorant_scale
}

/// The optical depth left to the next tentative collision of a null-collision process
/// with a piecewise-constant majorant. Sampled once per collision (Exp(1)) and spent
/// across cell boundaries, which is the same process as restarting the exponential at
/// every boundary (memorylessness) but costs no random number and no logarithm per
/// cell crossed — at deep octree levels most cells are crossed without a collision.
#[derive(Clone, Copy, Debug)]
pub struct OpticalDepth(f32);

impl OpticalDepth {
    #[inline(always)]
    pub fn sample<R: Rng>(rng: &mut R) -> OpticalDepth {
        OpticalDepth(exp_step(rng, 1.0))
    }

    /// The collision distance from `t` at rate `mu` (infinite when `mu` is 0).
    #[inline(always)]
    pub fn time(self, t: f32, mu: f32) -> f32 {
        if mu > 0.0 {
            t + self.0 / mu
        } else {
            f32::INFINITY
        }
    }

    /// The optical depth left at `t1` of a collision pending at `tc ≥ t1` at rate `mu`
    /// (unchanged when `mu` is 0: nothing was spent).
    #[inline(always)]
    pub fn left(self, tc: f32, t1: f32, mu: f32) -> OpticalDepth {
        if mu > 0.0 {
            OpticalDepth(((tc - t1) * mu).max(0.0))
        } else {
            self
        }
    }

    /// With rate `mu > 0` from `t` to `t1`: the collision distance if it falls before
    /// `t1`, else `None` after spending the stretch's optical depth.
    #[inline(always)]
    pub fn collide(&mut self, t: f32, t1: f32, mu: f32) -> Option<f32> {
        let tc = t + self.0 / mu;
        if tc < t1 {
            Some(tc)
        } else {
            self.0 = (self.0 - (t1 - t) * mu).max(0.0);
            None
        }
    }
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

#[inline(always)]
pub fn mul(a: &mut Spectrum, w: Spectrum) {
    a[0] *= w[0];
    a[1] *= w[1];
    a[2] *= w[2];
}
