//! Spectral tracking (paper §5): one achromatic majorant and one free path for all
//! channels, events chosen by a probability [`Scheme`], per-channel collision weights.
//!
//! Because every scheme's preference uses absolute values, this tracker also handles
//! non-bounding majorants (negative null coefficients) with signed weights: with the avg
//! scheme it is `weighted-delta`.

use super::scheme::{choose, probabilities, Coefficients, Event, Scheme, SchemeOptions};
use super::{exp_step, mul, FreePath, FreePathSampler, Query, Spectrum};
use crate::volume::medium::Counters;
use rand::Rng;
use std::marker::PhantomData;

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
    fn sample<R: Rng>(
        &self,
        q: &Query,
        throughput: &mut Spectrum,
        rng: &mut R,
        c: &mut Counters,
    ) -> FreePath {
        let sg = q.sigma;
        for seg in q.medium.majorants.walk(q.ray.o, q.ray.d, q.tmin, q.tmax) {
            c.cells_visited += 1;
            let mu_bar = seg.dmax * sg.t_max * q.majorant_scale;
            if !(mu_bar > 0.0) {
                continue;
            }
            let mut t = seg.t0;
            loop {
                t += exp_step(rng, mu_bar);
                if t >= seg.t1 {
                    break;
                }
                let d = q.medium.density(q.ray.at(t), c);
                let k = Coefficients {
                    mu_a: sg.a.map(|s| d * s),
                    mu_s: sg.s.map(|s| d * s),
                    mu_n: sg.t.map(|s| mu_bar - d * s),
                };
                if k.mu_n.iter().any(|&m| m < 0.0) {
                    c.majorant_violations += 1;
                }
                let p = probabilities::<S>(&k, mu_bar, *throughput, self.options);
                let (event, w) = choose(&k, mu_bar, p, rng.gen());
                mul(throughput, w);
                c.observe_throughput(*throughput);
                match event {
                    Event::Absorb => {
                        c.real_collisions += 1;
                        return FreePath::Absorb { t };
                    }
                    Event::Scatter => {
                        c.real_collisions += 1;
                        return FreePath::Scatter { t };
                    }
                    Event::Null => c.null_collisions += 1,
                }
            }
        }
        FreePath::Escape
    }
}
