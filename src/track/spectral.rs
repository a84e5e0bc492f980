//! Spectral tracking (paper §5): one achromatic majorant and one free path for all
//! channels, events chosen by a probability [`Scheme`], per-channel collision weights.
//!
//! Because every scheme's preference uses absolute values, this tracker also handles
//! non-bounding majorants (negative null coefficients) with signed weights: with the avg
//! scheme it is `weighted-delta`.

use super::race::race_collisions;
use super::scheme::{choose, probabilities, Coefficients, Event, Scheme, SchemeOptions};
use super::{mul, walk_collisions, FreePath, FreePathSampler, Query, Spectrum};
use crate::volume::medium::Tally;
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
        let sg = q.sigma;
        let d = q.medium.density(q.ray.at(t), c);
        let k = Coefficients {
            mu_a: sg.a.map(|s| d * s),
            mu_s: sg.s.map(|s| d * s),
            mu_n: sg.t.map(|s| mu_bar - d * s),
        };
        if k.mu_n.iter().any(|&m| m < 0.0) {
            c.majorant_violation();
        }
        let p = probabilities::<S>(&k, mu_bar, *throughput, self.options);
        let (event, w) = choose(&k, mu_bar, p, rng.gen());
        mul(throughput, w);
        c.observe_throughput(*throughput);
        match event {
            Event::Absorb => {
                c.real_collision();
                ControlFlow::Break(FreePath::Absorb { t })
            }
            Event::Scatter => {
                c.real_collision();
                ControlFlow::Break(FreePath::Scatter { t })
            }
            Event::Null => {
                c.null_collision();
                ControlFlow::Continue(())
            }
        }
    }
}
