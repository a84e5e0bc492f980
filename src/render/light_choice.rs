//! One local light chosen per scattering vertex where a stage has many (issue 44).
//!
//! Next-event estimation samples every local light at every vertex: a shadow ray each,
//! the right trade for a few lights. With dozens (embers in smoke, a string of lamps in
//! fog) the shadow rays are most of a path's cost while most lights, far away or
//! behind thick smoke, add little. Past [`MANY_LIGHTS`] local lights, a vertex `p`
//! samples one light ℓ, chosen with probability
//!
//! ```text
//! P_ℓ(p) = w_ℓ(p) / Σ_k w_k(p),   w_ℓ(p) = Φ_ℓ / max(d_ℓ(p)², r_ℓ²)
//! ```
//!
//! (its power over its squared distance, never nearer than its radius: the weights of
//! [`crate::render::guiding`]'s lobes), and its estimate is divided by P_ℓ(p). Every
//! light with power has P_ℓ > 0 everywhere, so the sum over lights stays unbiased; the
//! equiangular MIS weights are per light and unchanged. A linear pass over the lights
//! per vertex: a light tree would make it logarithmic; at 100 lights the pass is cheap
//! beside the shadow rays, at 1,000 it is not, and a first tree lost more to its coarse
//! cluster weights than it saved (docs/trackers.md, "Many local lights").

use crate::render::equiangular::LocalLight;
use crate::render::guiding::importance;
use glam::DVec3;

/// Stages with more local lights than this choose one per vertex; up to it, every
/// light is sampled at every vertex (and such renders are unchanged).
pub const MANY_LIGHTS: usize = 4;

/// The local lights as the choice sees them, in [`crate::render::lights::Lights::locals`]'
/// order (the index next-event estimation counts lights by).
#[derive(Clone, Debug)]
pub struct LightChoice {
    lights: Vec<(DVec3, f64, f64)>,
}

impl LightChoice {
    /// `None` for [`MANY_LIGHTS`] local lights or fewer: every light is sampled.
    pub fn new(locals: &[LocalLight]) -> Option<LightChoice> {
        (locals.len() > MANY_LIGHTS).then(|| LightChoice {
            lights: locals
                .iter()
                .map(|l| (l.center, l.power.max(0.0), l.radius * l.radius))
                .collect(),
        })
    }

    /// The light vertex `p` samples, drawn with the uniform `u`, and its probability;
    /// `None` where no light has power.
    pub fn pick(&self, p: DVec3, u: f64) -> Option<(usize, f64)> {
        let weight =
            |&(c, power, r2): &(DVec3, f64, f64)| importance(power, (c - p).length_squared(), r2);
        let total: f64 = self.lights.iter().map(weight).sum();
        if !(total > 0.0 && total.is_finite()) {
            return None;
        }
        let target = u * total;
        let mut acc = 0.0;
        let mut last = None;
        for (k, l) in self.lights.iter().enumerate() {
            let w = weight(l);
            if w <= 0.0 {
                continue;
            }
            acc += w;
            last = Some((k, w / total));
            if acc > target {
                break;
            }
        }
        last
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn light(x: f64, power: f64) -> LocalLight {
        LocalLight {
            center: DVec3::new(x, 0.0, 0.0),
            power,
            radius: 0.1,
            cone: None,
            chord: None,
        }
    }

    #[test]
    fn few_lights_are_all_sampled() {
        let four: Vec<_> = (0..MANY_LIGHTS).map(|i| light(i as f64, 1.0)).collect();
        assert!(LightChoice::new(&four).is_none());
    }

    /// Every light is picked with the probability `pick` reports: the picks' counts
    /// over 200,000 draws (stratified u, so exact up to one draw per light) against
    /// P·N, and the probabilities sum to 1; a light without power is never picked.
    #[test]
    fn picks_follow_their_probabilities() {
        let lights = [
            light(0.0, 1.0),
            light(1.0, 0.0),
            light(2.0, 4.0),
            light(5.0, 20.0),
            light(0.05, 0.5),
            light(-3.0, 9.0),
        ];
        let choice = LightChoice::new(&lights).unwrap();
        let p = DVec3::new(0.5, 0.2, 0.0);
        let n = 200_000;
        let mut counts = [0usize; 6];
        let mut prob = [0.0; 6];
        for i in 0..n {
            let (k, pk) = choice.pick(p, (i as f64 + 0.5) / n as f64).unwrap();
            counts[k] += 1;
            prob[k] = pk;
        }
        assert_eq!(counts[1], 0);
        assert!((prob.iter().sum::<f64>() - 1.0).abs() < 1e-12, "{prob:?}");
        for k in 0..6 {
            let expected = prob[k] * n as f64;
            assert!(
                (counts[k] as f64 - expected).abs() <= 1.0,
                "{k}: {counts:?} {prob:?}"
            );
        }
    }
}
