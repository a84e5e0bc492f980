//! Delta tracking with an achromatic majorant.
//!
//! For grey media this is analog delta tracking (all collision weights are 1). For
//! chromatic media the events are chosen by the per-channel average of each
//! coefficient (the paper's "avg" probabilities), and the throughput is multiplied by
//! the local collision weights w★(λ) = μ★(λ)/(μ̄·P★) so the estimate stays unbiased.

use super::{avg, exp_step, FreePath, Spectrum};
use crate::volume::medium::{Counters, IndexRay, Medium};
use rand::Rng;

/// Samples the first real collision along `ray` in `[tmin, tmax)`, updating `throughput`
/// with the collision weights of the null collisions (and of the real one).
pub fn sample_free_path<R: Rng>(
    medium: &Medium,
    ray: &IndexRay,
    tmin: f32,
    tmax: f32,
    throughput: &mut Spectrum,
    rng: &mut R,
    counters: &mut Counters,
) -> FreePath {
    let sa = medium.sigma_a;
    let ss = medium.sigma_s;
    let st = medium.sigma_t;
    let (avg_sa, avg_ss) = (avg(sa), avg(ss));
    for seg in medium.majorants.walk(ray.o, ray.d, tmin, tmax) {
        counters.cells_visited += 1;
        let mu_bar = seg.dmax * medium.sigma_t_max;
        if !(mu_bar > 0.0) {
            continue; // empty cell: skipped without a lookup
        }
        let mut t = seg.t0;
        loop {
            t += exp_step(rng, mu_bar);
            if t >= seg.t1 {
                break;
            }
            let d = medium.density(ray.at(t), counters);
            // P★ = avg_λ μ★(λ) / μ̄.
            let pa = d * avg_sa / mu_bar;
            let ps = d * avg_ss / mu_bar;
            let pn = 1.0 - pa - ps;
            let u: f32 = rng.gen();
            if u < pa {
                counters.real_collisions += 1;
                return FreePath::Absorb { t };
            }
            if u < pa + ps {
                counters.real_collisions += 1;
                for c in 0..3 {
                    throughput[c] *= d * ss[c] / (mu_bar * ps);
                }
                return FreePath::Scatter { t };
            }
            counters.null_collisions += 1;
            if pn < 0.0 {
                // The majorant does not bound the extinction here: delta tracking is
                // biased. Counted, so it is never silent.
                counters.majorant_violations += 1;
                continue;
            }
            for c in 0..3 {
                throughput[c] *= (mu_bar - d * st[c]) / (mu_bar * pn);
            }
        }
    }
    FreePath::Escape
}
