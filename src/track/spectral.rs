//! Spectral tracking (paper §5): one achromatic majorant and one free path for all
//! channels, events chosen by a probability [`Scheme`], per-channel collision weights.
//!
//! Because every scheme's preference uses absolute values, this tracker also handles
//! non-bounding majorants (negative null coefficients) with signed weights: with the avg
//! scheme it is `weighted-delta`.

use super::race::race_collisions;
use super::scheme::{collide, Coefficients, Scheme, SchemeOptions};
use crate::color::Spectrum;
use crate::track::free_path::{walk_collisions, FreePath, FreePathSampler, Query};
use crate::volume::counters::Tally;
use rand::Rng;
use std::marker::PhantomData;
use std::ops::ControlFlow;

#[derive(Clone, Copy, Debug)]
pub struct Spectral<S: Scheme> {
    pub options: SchemeOptions,
    _scheme: PhantomData<S>,
}

impl<S: Scheme> Spectral<S> {
    pub fn new(options: SchemeOptions) -> Self {
        Spectral {
            options,
            _scheme: PhantomData,
        }
    }
}

impl<S: Scheme> FreePathSampler for Spectral<S> {
    #[inline]
    fn sample<R: Rng, C: Tally>(
        &self,
        q: &Query,
        throughput: &mut Spectrum,
        rng: &mut R,
        c: &mut C,
    ) -> FreePath {
        walk_collisions(q, rng, c, |t, mu_bar, rng, c| {
            self.decide(q, t, mu_bar, throughput, rng, c)
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
            self.decide(q, t, mu_bar, throughput, rng, c)
        })
        .unwrap_or((FreePath::Escape, 0))
    }
}

impl<S: Scheme> Spectral<S> {
    /// One tentative collision at `t` under majorant `mu_bar`.
    #[inline(always)]
    fn decide<R: Rng, C: Tally>(
        &self,
        q: &Query,
        t: f32,
        mu_bar: f32,
        throughput: &mut Spectrum,
        rng: &mut R,
        c: &mut C,
    ) -> ControlFlow<FreePath> {
        let d = q.medium.density_on(q.ray, t, c);
        let k = Coefficients::of(q.sigma, d, mu_bar);
        if k.mu_n.iter().any(|&m| m < 0.0) {
            c.majorant_violation();
        }
        match collide::<S, C>(&k, mu_bar, t, self.options, rng.gen(), throughput, c) {
            Some(end) => ControlFlow::Break(end),
            None => ControlFlow::Continue(()),
        }
    }
}
