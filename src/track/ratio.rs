//! Ratio tracking (Novák et al. 2014): an unbiased transmittance estimate
//! T̂(λ) = Π (1 − μt(x_i,λ)/μ̄) over tentative collisions, for shadow rays.
//!
//! Russian roulette on small estimates keeps long shadow rays cheap: once the largest
//! channel drops below [`RR_THRESHOLD`], the estimate survives with probability
//! `RR_SURVIVAL` and is divided by it, which keeps it unbiased.

use super::{exp_step, max3, Spectrum};
use crate::volume::medium::{Counters, IndexRay, Medium};
use rand::Rng;

pub const RR_THRESHOLD: f32 = 0.1;
pub const RR_SURVIVAL: f32 = 0.5;

pub fn transmittance<R: Rng>(
    medium: &Medium,
    ray: &IndexRay,
    tmin: f32,
    tmax: f32,
    rng: &mut R,
    counters: &mut Counters,
) -> Spectrum {
    let st = medium.sigma_t;
    let mut tr = [1f32; 3];
    for seg in medium.majorants.walk(ray.o, ray.d, tmin, tmax) {
        counters.cells_visited += 1;
        let mu_bar = seg.dmax * medium.sigma_t_max;
        if !(mu_bar > 0.0) {
            continue;
        }
        let mut t = seg.t0;
        loop {
            t += exp_step(rng, mu_bar);
            if t >= seg.t1 {
                break;
            }
            let d = medium.density(ray.at(t), counters);
            counters.null_collisions += 1;
            for c in 0..3 {
                tr[c] *= 1.0 - d * st[c] / mu_bar;
            }
            if max3(tr) < RR_THRESHOLD {
                if rng.gen::<f32>() >= RR_SURVIVAL {
                    return [0.0; 3];
                }
                for v in tr.iter_mut() {
                    *v /= RR_SURVIVAL;
                }
            }
        }
    }
    tr
}
