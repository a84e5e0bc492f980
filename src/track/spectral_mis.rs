//! Spectral MIS tracking: hero-channel null-scattering free paths combined over the RGB
//! channels with the one-sample balance heuristic (Miller et al. 2019, as pbrt-v4's
//! `VolPathIntegrator` and Cycles' `volume_sample_channel` do), within the
//! one-query-one-free-path interface of [`FreePathSampler`].
//!
//! # The estimator
//!
//! A query starts with throughput T and picks a hero channel h with probability
//! q_h = w_h / Σ_c w_c, w_c = |T_c|·max(α_c, [`ALBEDO_FLOOR`]), α_c = σs_c/σt_c (1 where
//! σt_c = 0); uniform if every w_c is 0. It then walks the tentative collisions of the
//! shared achromatic majorant μ̄ (the medium's majorant walk, as spectral tracking does)
//! and decides each one with channel h's event probabilities
//!
//!   P_k(★) = |μ★_k| / (|μa_k| + |μs_k| + |μn_k|),  ★ ∈ {a, s, n},  μn_k = μ̄ − μt_k,
//!
//! which are μ★_k/μ̄ whenever the majorant bounds channel k (μn_k ≥ 0). With
//! `no_absorption_events` μa is left out of P (non-emissive media only, as for the
//! other trackers). For a free path x with tentative collisions 1..m (null, …, null,
//! then a real event or none for an escape), the density of the tentative distances
//! is the same for every channel (it depends on μ̄ only), so the path's pdf when
//! channel k is the hero is D(x)·p_k(x), p_k = Π_i P_k(★_i), and its contribution in
//! channel λ is D(x)·f_λ(x), f_λ = Π_i μ★_λ,i/μ̄ (the collision estimator's
//! numerator: the μ̄·e^{−∫μ̄} of the distance density cancels). The one-sample MIS
//! estimator with the balance heuristic over the channels is then
//!
//!   T'_λ = T_λ · f_λ(x) / Σ_k q_k·p_k(x),
//!
//! and E[T'_λ] = Σ_h q_h ∫ D p_h · T_λ f_λ / Σ_k q_k p_k = T_λ ∫ D f_λ: unbiased for
//! every channel wherever Σ_k q_k p_k > 0 where f_λ ≠ 0. That holds: f_λ ≠ 0 needs
//! μ★_λ,i ≠ 0 at every collision, so P_λ(★_i) > 0 and p_λ > 0, and q_λ > 0 whenever
//! T_λ ≠ 0 (the albedo floor keeps purely absorbing channels in the mixture, which
//! their transmittance and emission need). Signed null coefficients (non-bounding
//! majorants) only change signs of f, as in `weighted-delta`: still unbiased.
//!
//! The products are kept relative to the hero, r_k = p_k/p_h and g_λ = f_λ/p_h, in
//! f64 (long runs of null collisions would underflow f32 products); then
//! T'_λ = T_λ·g_λ·W / Σ_k w_k·r_k with W = Σ_k w_k. The hero's own ratio is exactly 1
//! at every collision, so the denominator is at least w_h > 0. Absorption events carry
//! the same weight, which is the μa(λ)/(μ̄·Pa)-style weight the integrator multiplies
//! emission by ([`FreePath::Absorb`]).
//!
//! # Grey media and several media
//!
//! In a grey medium every channel has the same probabilities, so p_k = f_λ for all k
//! and every weight is exactly 1 under a bounding majorant: the estimator is delta
//! tracking. Queries on grey cross-sections with `majorant_scale ≥ 1` are therefore run
//! by [`Delta`] itself (bit-identical decisions, weights and random numbers); with a
//! scaled-down majorant they take the MIS path (signed weights, unbiased). In the race over several media ([`race_collisions`])
//! the tentative distances are still shared by all channels (the superposed processes
//! do not depend on the channel) and each collision is decided with the producing
//! medium's coefficients and majorant, so the same products apply unchanged; the hero
//! is chosen with the albedo proxy of the summed cross-sections.

use super::delta::Delta;
use super::race::race_collisions;
use super::scheme::{pick, Coefficients, SchemeOptions};
use crate::color::Spectrum;
use crate::track::free_path::{walk_collisions, FreePath, FreePathSampler, Query};
use crate::volume::counters::Tally;
use rand::Rng;
use std::ops::ControlFlow;

/// The smallest albedo the hero-channel choice uses: a purely absorbing channel with
/// non-zero throughput keeps a share of the hero choices (its transmittance and
/// emission need paths sampled with it, see the module docs).
pub const ALBEDO_FLOOR: f32 = 0.125;

/// Which denominator the estimator divides by. Only [`Denominator::Balance`] is the
/// tracker; the others are deliberately wrong and exist so the tests can show that
/// they detect a broken MIS weight.
#[doc(hidden)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Denominator {
    /// Σ_k q_k·p_k: the balance heuristic (unbiased).
    Balance,
    /// q_h·p_h only (biased: drops the other channels' terms).
    HeroOnly,
    /// Σ_k p_k / 3, the uniform channel choice's pdf though h was chosen by q (biased).
    Uniform,
}

#[derive(Clone, Copy, Debug)]
pub struct SpectralMis {
    /// `no_absorption_events` is honoured; `reduced_termination` does not apply.
    pub options: SchemeOptions,
    #[doc(hidden)]
    pub denominator: Denominator,
}

impl SpectralMis {
    pub fn new(options: SchemeOptions) -> Self {
        SpectralMis {
            options,
            denominator: Denominator::Balance,
        }
    }
}

/// Whether delta tracking runs the query: grey cross-sections ([`crate::volume::medium::Sigma::is_grey`]) under
/// a bounding majorant. Under a scaled-down, non-bounding majorant delta tracking is
/// biased, so grey queries take the MIS path, whose signed weights stay unbiased there
/// as `weighted-delta`'s do.
#[inline(always)]
fn delta_suffices(q: &Query) -> bool {
    q.sigma.is_grey() && q.majorant_scale >= 1.0
}

/// The per-query MIS state.
struct Mis {
    hero: usize,
    /// Unnormalised hero-choice weights: q_k = w_k / Σ w.
    w: [f32; 3],
    /// p_k / p_h.
    r: [f64; 3],
    /// f_λ / p_h.
    g: [f64; 3],
}

impl Mis {
    /// Picks the hero channel for throughput `thr` and scattering/extinction `s`, `t`.
    #[inline(always)]
    fn start<R: Rng>(thr: &Spectrum, s: Spectrum, t: Spectrum, rng: &mut R) -> Mis {
        let mut w = [0f32; 3];
        for ch in 0..3 {
            let albedo = if t[ch] > 0.0 { s[ch] / t[ch] } else { 1.0 };
            w[ch] = thr[ch].abs() * albedo.max(ALBEDO_FLOOR);
        }
        let sum = w[0] + w[1] + w[2];
        if !(sum > 0.0) || !sum.is_finite() {
            w = [1.0; 3];
        }
        let sum = w[0] + w[1] + w[2];
        let u: f32 = rng.gen::<f32>() * sum;
        let hero = if u < w[0] {
            0
        } else if u < w[0] + w[1] {
            1
        } else {
            2
        };
        // Rounding can leave u past the last non-zero weight: never a zero-weight hero.
        let hero = if w[hero] > 0.0 {
            hero
        } else if w[2] > 0.0 {
            2
        } else if w[1] > 0.0 {
            1
        } else {
            0
        };
        Mis {
            hero,
            w,
            r: [1.0; 3],
            g: [1.0; 3],
        }
    }

    /// One tentative collision at `t` under majorant `mu_bar`, decided by the hero.
    #[inline(always)]
    fn decide<R: Rng, C: Tally>(
        &mut self,
        q: &Query,
        t: f32,
        mu_bar: f32,
        no_absorption: bool,
        rng: &mut R,
        c: &mut C,
    ) -> ControlFlow<FreePath> {
        let d = q.medium.density_on(q.ray, t, c);
        let k = Coefficients::of(q.sigma, d, mu_bar);
        if k.mu_n.iter().any(|&m| m < 0.0) {
            c.majorant_violation();
        }
        let p = [0, 1, 2].map(|ch| {
            let a = if no_absorption { 0.0 } else { k.mu_a[ch].abs() };
            let (s, n) = (k.mu_s[ch].abs(), k.mu_n[ch].abs());
            let sum = a + s + n;
            if sum > 0.0 {
                let inv = 1.0 / sum;
                [a * inv, s * inv, n * inv]
            } else {
                [0.0, 0.0, 1.0]
            }
        });
        let ph = p[self.hero];
        let e = pick(ph, rng.gen());
        let inv = 1.0 / ph[e] as f64;
        let mu = match e {
            0 => k.mu_a,
            1 => k.mu_s,
            _ => k.mu_n,
        };
        let inv_bar = 1.0 / mu_bar as f64;
        for ch in 0..3 {
            self.r[ch] *= p[ch][e] as f64 * inv;
            self.g[ch] *= mu[ch] as f64 * inv_bar * inv;
        }
        match e {
            0 => {
                c.real_collision();
                ControlFlow::Break(FreePath::Absorb { t })
            }
            1 => {
                c.real_collision();
                ControlFlow::Break(FreePath::Scatter { t })
            }
            _ => {
                c.null_collision();
                ControlFlow::Continue(())
            }
        }
    }

    /// Multiplies the throughput by the MIS weights f_λ / Σ_k q_k·p_k.
    #[inline(always)]
    fn finish<C: Tally>(&self, den: Denominator, throughput: &mut Spectrum, c: &mut C) {
        let w = self.w.map(|x| x as f64);
        let total = w[0] + w[1] + w[2];
        let scale = match den {
            Denominator::Balance => {
                total / (w[0] * self.r[0] + w[1] * self.r[1] + w[2] * self.r[2])
            }
            Denominator::HeroOnly => total / w[self.hero],
            Denominator::Uniform => 3.0 / (self.r[0] + self.r[1] + self.r[2]),
        };
        for ch in 0..3 {
            let v = throughput[ch] as f64 * self.g[ch] * scale;
            // Only a product overflowing f64 can get here non-finite; its true weight
            // is 0 (an infinite denominator) or unrepresentable.
            throughput[ch] = if v.is_finite() { v as f32 } else { 0.0 };
        }
        c.observe_throughput(*throughput);
    }
}

impl FreePathSampler for SpectralMis {
    #[inline]
    fn sample<R: Rng, C: Tally>(
        &self,
        q: &Query,
        throughput: &mut Spectrum,
        rng: &mut R,
        c: &mut C,
    ) -> FreePath {
        if delta_suffices(q) {
            return Delta.sample(q, throughput, rng, c);
        }
        let no_abs = self.options.no_absorption_events;
        let mut mis = Mis::start(throughput, q.sigma.s, q.sigma.t, rng);
        let end = walk_collisions(q, rng, c, |t, mu_bar, rng, c| {
            mis.decide(q, t, mu_bar, no_abs, rng, c)
        })
        .unwrap_or(FreePath::Escape);
        mis.finish(self.denominator, throughput, c);
        end
    }

    fn sample_race<R: Rng, C: Tally>(
        &self,
        qs: &[Query],
        throughput: &mut Spectrum,
        rng: &mut R,
        c: &mut C,
    ) -> (FreePath, usize) {
        if qs.iter().all(delta_suffices) {
            return Delta.sample_race(qs, throughput, rng, c);
        }
        let (mut s, mut t) = ([0f32; 3], [0f32; 3]);
        for q in qs {
            for ch in 0..3 {
                s[ch] += q.sigma.s[ch];
                t[ch] += q.sigma.t[ch];
            }
        }
        let no_abs = self.options.no_absorption_events;
        let mut mis = Mis::start(throughput, s, t, rng);
        let end = race_collisions(qs, rng, c, |q, t, mu_bar, rng, c| {
            mis.decide(q, t, mu_bar, no_abs, rng, c)
        })
        .unwrap_or((FreePath::Escape, 0));
        mis.finish(self.denominator, throughput, c);
        end
    }
}
