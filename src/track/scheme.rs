//! Event probabilities of the general collision estimator (tracking.md §2, §4).
//!
//! At a tentative collision with coefficients μa(λ), μs(λ), μn(λ) = μ̄ − μt(λ), a scheme
//! picks P★ for ★ ∈ {a, s, n}; the throughput is multiplied by w★(λ) = μ★(λ)/(μ̄·P★).
//! Schemes are zero-sized types so each tracker is monomorphised per scheme: no dynamic
//! dispatch per collision.

use crate::track::free_path::{mul, FreePath};

use crate::color::Spectrum;
use crate::volume::counters::Tally;
use crate::volume::medium::Sigma;

/// Which event a collision turned into.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Event {
    Absorb,
    Scatter,
    Null,
}

/// The coefficients at one tentative collision, per channel.
#[derive(Clone, Copy, Debug)]
pub struct Coefficients {
    pub mu_a: Spectrum,
    pub mu_s: Spectrum,
    pub mu_n: Spectrum,
}

impl Coefficients {
    /// The coefficients of density `d` with cross-sections `sigma` under majorant
    /// `mu_bar`: μ★ = d·σ★, μn = μ̄ − d·σt.
    #[inline(always)]
    pub fn of(sigma: &Sigma, d: f32, mu_bar: f32) -> Coefficients {
        Coefficients {
            mu_a: sigma.a.map(|s| d * s),
            mu_s: sigma.s.map(|s| d * s),
            mu_n: sigma.t.map(|s| mu_bar - d * s),
        }
    }
}

/// Options that change how probabilities are assigned, independent of the scheme.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SchemeOptions {
    /// Never choose absorption (non-emissive media): Pa = 0, Ps and Pn renormalised.
    pub no_absorption_events: bool,
    /// "Reduced termination rates" (max scheme): Ps = max μs/μ̄, Pn = max μn/μ̄,
    /// Pa = 1 − Ps − Pn.
    pub reduced_termination: bool,
}

/// A probability scheme: the unnormalised preference of one event given its channel
/// coefficients and the current path throughput.
pub trait Scheme: Copy + Send + Sync + 'static {
    const NAME: &'static str;
    /// Preference for an event with coefficients `mu` (may be negative: null
    /// coefficients under a non-bounding majorant, residuals under a high control).
    fn preference(mu: Spectrum, throughput: Spectrum) -> f32;
}

#[derive(Clone, Copy, Debug)]
pub struct Max;
#[derive(Clone, Copy, Debug)]
pub struct Avg;
#[derive(Clone, Copy, Debug)]
pub struct HistMax;
#[derive(Clone, Copy, Debug)]
pub struct HistAvg;

impl Scheme for Max {
    const NAME: &'static str = "max";
    #[inline(always)]
    fn preference(mu: Spectrum, _w: Spectrum) -> f32 {
        mu[0].abs().max(mu[1].abs()).max(mu[2].abs())
    }
}

impl Scheme for Avg {
    const NAME: &'static str = "avg";
    #[inline(always)]
    fn preference(mu: Spectrum, _w: Spectrum) -> f32 {
        (mu[0].abs() + mu[1].abs() + mu[2].abs()) * (1.0 / 3.0)
    }
}

impl Scheme for HistMax {
    const NAME: &'static str = "hist-max";
    #[inline(always)]
    fn preference(mu: Spectrum, w: Spectrum) -> f32 {
        (mu[0] * w[0])
            .abs()
            .max((mu[1] * w[1]).abs())
            .max((mu[2] * w[2]).abs())
    }
}

impl Scheme for HistAvg {
    const NAME: &'static str = "hist-avg";
    #[inline(always)]
    fn preference(mu: Spectrum, w: Spectrum) -> f32 {
        ((mu[0] * w[0]).abs() + (mu[1] * w[1]).abs() + (mu[2] * w[2]).abs()) * (1.0 / 3.0)
    }
}

/// Event probabilities (Pa, Ps, Pn) for `k` under scheme `S`.
#[inline(always)]
pub fn probabilities<S: Scheme>(
    k: &Coefficients,
    mu_bar: f32,
    w: Spectrum,
    opts: SchemeOptions,
) -> [f32; 3] {
    let mut p = [
        if opts.no_absorption_events {
            0.0
        } else {
            S::preference(k.mu_a, w)
        },
        S::preference(k.mu_s, w),
        S::preference(k.mu_n, w),
    ];
    if opts.reduced_termination && !opts.no_absorption_events {
        // Scattering and null take their maximum proportions, absorption the rest.
        let ps = Max::preference(k.mu_s, w) / mu_bar;
        let pn = Max::preference(k.mu_n, w) / mu_bar;
        if ps + pn <= 1.0 {
            return [1.0 - ps - pn, ps, pn];
        }
        // No absorption gap here: fall back to the max scheme's normalisation.
        p = [Max::preference(k.mu_a, w), ps * mu_bar, pn * mu_bar];
    }
    let sum = p[0] + p[1] + p[2];
    if !(sum > 0.0) {
        // Nothing happens here in any channel (zero coefficients everywhere): a null
        // collision with weight μn/μ̄ = 1.
        return [0.0, 0.0, 1.0];
    }
    let inv = 1.0 / sum;
    [p[0] * inv, p[1] * inv, p[2] * inv]
}

/// Chooses an event with probabilities `p` from a uniform `u`, and returns it with its
/// collision weights w★(λ) = μ★(λ)/(μ̄·P★).
#[inline(always)]
pub fn choose(k: &Coefficients, mu_bar: f32, p: [f32; 3], u: f32) -> (Event, Spectrum) {
    let e = pick(p, u);
    let (event, mu) = match e {
        0 => (Event::Absorb, k.mu_a),
        1 => (Event::Scatter, k.mu_s),
        _ => (Event::Null, k.mu_n),
    };
    let inv = 1.0 / (mu_bar * p[e]);
    (event, [mu[0] * inv, mu[1] * inv, mu[2] * inv])
}

/// The event (0 absorption, 1 scattering, 2 null) the uniform `u` picks with
/// probabilities `p`. Rounding can leave `u` past a sum slightly below 1: a
/// zero-probability event is never picked (its weight would divide by zero).
#[inline(always)]
pub fn pick(p: [f32; 3], u: f32) -> usize {
    let e = if u < p[0] {
        0
    } else if u < p[0] + p[1] {
        1
    } else {
        2
    };
    if p[e] > 0.0 {
        e
    } else if p[2] > 0.0 {
        2
    } else if p[1] > 0.0 {
        1
    } else {
        0
    }
}

/// One tentative collision with coefficients `k` under majorant `mu_bar`, decided by
/// scheme `S` from the uniform `u`: the throughput takes the event's weights and the
/// event is counted. Returns the free path's end at `t` for a real collision, `None`
/// for a null collision (shared by spectral and decomposition tracking).
#[allow(clippy::too_many_arguments)]
#[inline(always)]
pub fn collide<S: Scheme, C: Tally>(
    k: &Coefficients,
    mu_bar: f32,
    t: f32,
    options: SchemeOptions,
    u: f32,
    throughput: &mut Spectrum,
    c: &mut C,
) -> Option<FreePath> {
    let p = probabilities::<S>(k, mu_bar, *throughput, options);
    let (event, w) = choose(k, mu_bar, p, u);
    mul(throughput, w);
    c.observe_throughput(*throughput);
    match event {
        Event::Absorb => {
            c.real_collision();
            Some(FreePath::Absorb { t })
        }
        Event::Scatter => {
            c.real_collision();
            Some(FreePath::Scatter { t })
        }
        Event::Null => {
            c.null_collision();
            None
        }
    }
}
