//! Scattered directions guided towards local lights (issue 44).
//!
//! Where a local light sits inside or beside a dense medium, most of a pixel's light
//! arrives along the rare walks that wander close to it: next-event estimation from a
//! vertex next to the light is orders of magnitude larger than from one a few mean
//! free paths away, and the phase function, which alone chooses where a walk goes,
//! knows nothing of the light. A point light inside the smoke is then dominated by
//! those rare walks (relMSE that barely falls with samples; docs/trackers.md).
//!
//! Here the direction a path continues in after a scattering vertex `p` is drawn from
//! the one-sample mixture
//!
//! ```text
//! q(ω) = (1 − α) · phase(ω) + α · Σ_ℓ P_ℓ(p) · vMF(ω; ω_ℓ, κ)
//! ```
//!
//! with ω_ℓ the direction from `p` to light ℓ's centre, P_ℓ(p) ∝ Φ_ℓ / max(d_ℓ², r_ℓ²)
//! (its power over its squared distance, `d_ℓ` no nearer than its radius) and vMF the
//! von Mises–Fisher lobe of concentration κ. The path's throughput is multiplied by
//! phase(ω) / q(ω) ≤ 1 / (1 − α): unbiased for every α < 1 (q > 0 wherever the
//! phase function is), bounded, and equal to the phase sampling it replaces when α = 0.
//! α and κ are measured choices, not derived optima (docs/trackers.md, "Scattered
//! directions guided towards local lights").

use crate::render::equiangular::LocalLight;
use crate::render::phase::{azimuth, hg, orthonormal_basis, sample_hg};
use glam::DVec3;
use std::f64::consts::PI;

/// α: the share of continuations drawn from the lights' lobes.
pub const LOBE_SHARE: f64 = 0.5;
/// κ: the lobes' concentration (a lobe holds half its mass within about 21° of the
/// light's direction).
pub const KAPPA: f64 = 10.0;

/// One light's lobe: where it points from a vertex and how much it is chosen.
#[derive(Clone, Copy, Debug)]
struct Lobe {
    center: DVec3,
    power: f64,
    /// The squared distance the choice never counts nearer than (the light's radius).
    min_distance2: f64,
}

/// Past this many lobes a continuation is guided towards one light only: the one the
/// vertex's next event chose ([`crate::render::light_choice`]), so a vertex costs no
/// pass over every lobe (docs/trackers.md, "Many local lights": at 1,000 lights the
/// mixture was most of the render).
pub const ONE_LOBE_LIGHTS: usize = 32;

/// The local lights continuations are guided towards (every light of
/// [`crate::render::lights::Lights::locals`] with power), built once per render.
#[derive(Clone, Debug)]
pub struct LightLobes {
    lobes: Vec<Lobe>,
    /// Past [`ONE_LOBE_LIGHTS`]: each local light's lobe centre by its index in
    /// `locals` (`None` for one without power), for [`Self::sample_towards`].
    one_lobe: Option<Vec<Option<DVec3>>>,
}

impl LightLobes {
    /// `None` when no light has power (nothing to guide towards: the phase function
    /// alone, as without guiding). `locals` is a prefix of
    /// [`crate::render::lights::Lights::locals`].
    pub fn new(locals: &[LocalLight]) -> Option<LightLobes> {
        let lit = |l: &&LocalLight| l.power > 0.0 && l.power.is_finite();
        let lobes: Vec<Lobe> = locals
            .iter()
            .filter(lit)
            .map(|l| Lobe {
                center: l.center,
                power: l.power,
                min_distance2: l.radius * l.radius,
            })
            .collect();
        let one_lobe = (lobes.len() > ONE_LOBE_LIGHTS)
            .then(|| locals.iter().map(|l| lit(&l).then_some(l.center)).collect());
        (!lobes.is_empty()).then_some(LightLobes { lobes, one_lobe })
    }

    /// Whether continuations are guided towards the next event's chosen light alone.
    #[inline]
    pub fn one_lobe(&self) -> bool {
        self.one_lobe.is_some()
    }

    /// A continuation from `p` when [`Self::one_lobe`]: drawn from
    /// (1 − α) phase + α vMF towards local light `chosen` (the next event's choice,
    /// `None` or a light without a lobe: the phase function alone), with the weight
    /// phase / that density. Unbiased whatever light was chosen (each such density
    /// is positive wherever the phase function is), so the choice may come from any
    /// distribution. The density returned for MIS against environment light is the
    /// phase function's, which [`Self::pdf`] returns too in this mode: the weights
    /// of both sides must be the same function of the direction, and the mixture
    /// actually drawn from depends on the choice.
    pub fn sample_towards(
        &self,
        p: DVec3,
        dir: DVec3,
        g: f64,
        chosen: Option<usize>,
        u: [f64; 3],
    ) -> (DVec3, f64, f64) {
        let center = chosen
            .and_then(|k| self.one_lobe.as_ref()?.get(k).copied().flatten())
            .filter(|&c| c != p);
        let Some(center) = center else {
            let omega = sample_hg(g, dir, u[1], u[2]);
            return (omega, 1.0, hg(g, dir.dot(omega)));
        };
        let axis = (center - p).normalize();
        let omega = match u[0] < LOBE_SHARE {
            true => sample_vmf(axis, KAPPA, u[1], u[2]),
            false => sample_hg(g, dir, u[1], u[2]),
        };
        let phase = hg(g, dir.dot(omega));
        let q = mix(phase, vmf_pdf(omega.dot(axis), KAPPA));
        (omega, phase / q, phase)
    }

    /// Light ℓ's unnormalised choice weight at `p`, and its direction from `p`
    /// (`None` at its centre, where no direction points to it).
    #[inline]
    fn lobe_at(l: &Lobe, p: DVec3) -> Option<(f64, DVec3)> {
        let to = l.center - p;
        let d2 = to.length_squared();
        (d2 > 0.0).then(|| (importance(l.power, d2, l.min_distance2), to / d2.sqrt()))
    }

    /// Σ_ℓ P_ℓ(p) vMF(ω; ω_ℓ, κ): the lobes' part of the mixture at `omega`.
    fn lobes_pdf(&self, p: DVec3, omega: DVec3) -> f64 {
        let (mut sum, mut total) = (0.0, 0.0);
        for l in &self.lobes {
            if let Some((w, to)) = Self::lobe_at(l, p) {
                total += w;
                sum += w * vmf_pdf(omega.dot(to), KAPPA);
            }
        }
        if total > 0.0 {
            sum / total
        } else {
            0.0
        }
    }

    /// The mixture's density q(`omega`) at vertex `p` for a path that arrived along
    /// `dir` through a medium of anisotropy `g` (in [`Self::one_lobe`] mode the phase
    /// function's, the MIS stand-in of [`Self::sample_towards`]).
    pub fn pdf(&self, p: DVec3, dir: DVec3, g: f64, omega: DVec3) -> f64 {
        let phase = hg(g, dir.dot(omega));
        match self.one_lobe() {
            true => phase,
            false => self.mixture(p, phase, omega),
        }
    }

    /// q(`omega`) at `p` given the phase function's density there.
    fn mixture(&self, p: DVec3, phase: f64, omega: DVec3) -> f64 {
        match self.lobes_pdf(p, omega) {
            0.0 => phase,
            lobes => mix(phase, lobes),
        }
    }

    /// A continuation from vertex `p` (arrived along `dir`, anisotropy `g`) drawn from
    /// the mixture with the three uniform numbers `u`: the direction, its weight
    /// phase / q and its density q.
    pub fn sample(&self, p: DVec3, dir: DVec3, g: f64, u: [f64; 3]) -> (DVec3, f64, f64) {
        let total: f64 = self
            .lobes
            .iter()
            .filter_map(|l| Self::lobe_at(l, p))
            .map(|(w, _)| w)
            .sum();
        if !(total > 0.0) {
            // At a light's centre with no other light: the phase function alone.
            let omega = sample_hg(g, dir, u[1], u[2]);
            return (omega, 1.0, hg(g, dir.dot(omega)));
        }
        let omega = if u[0] < LOBE_SHARE {
            // The light whose cumulative share passes u0/α of the total.
            let target = u[0] / LOBE_SHARE * total;
            let mut acc = 0.0;
            let mut axis = DVec3::Z;
            for (w, to) in self.lobes.iter().filter_map(|l| Self::lobe_at(l, p)) {
                acc += w;
                axis = to;
                if acc > target {
                    break;
                }
            }
            sample_vmf(axis, KAPPA, u[1], u[2])
        } else {
            sample_hg(g, dir, u[1], u[2])
        };
        let phase = hg(g, dir.dot(omega));
        let q = self.mixture(p, phase, omega);
        (omega, phase / q, q)
    }
}

/// The mixture (1 − α) · phase + α · lobes of the phase function's density and the
/// lobes' at one direction.
#[inline]
fn mix(phase: f64, lobes: f64) -> f64 {
    (1.0 - LOBE_SHARE) * phase + LOBE_SHARE * lobes
}

/// A light's unnormalised importance at a point `d2` (squared distance) from its
/// centre: its power over the squared distance, never nearer than its radius
/// (`radius2`, squared) nor than 10⁻⁶ (a point light's centre). Lobes and the choice
/// among many lights ([`crate::render::light_choice`]) both weigh lights by it.
#[inline]
pub fn importance(power: f64, d2: f64, radius2: f64) -> f64 {
    power / d2.max(radius2).max(1e-12)
}

/// The von Mises–Fisher density on the sphere at cosine `cos` from its axis,
/// κ / (2π (1 − e^(−2κ))) · e^(κ (cos − 1)).
#[inline]
pub fn vmf_pdf(cos: f64, kappa: f64) -> f64 {
    kappa / (2.0 * PI * (1.0 - (-2.0 * kappa).exp())) * (kappa * (cos - 1.0)).exp()
}

/// A direction from the von Mises–Fisher lobe around `axis` (unit): the cosine by
/// inverting its CDF, 1 + ln(u + (1 − u) e^(−2κ)) / κ, the azimuth uniform.
pub fn sample_vmf(axis: DVec3, kappa: f64, u1: f64, u2: f64) -> DVec3 {
    let cos = (1.0 + (u1 + (1.0 - u1) * (-2.0 * kappa).exp()).ln() / kappa).clamp(-1.0, 1.0);
    let sin = (1.0 - cos * cos).max(0.0).sqrt();
    let (cos_phi, sin_phi) = azimuth(u2);
    let (t, b) = orthonormal_basis(axis);
    (t * (sin * cos_phi) + b * (sin * sin_phi) + axis * cos).normalize()
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_pcg::Pcg64;

    fn light(center: DVec3, power: f64, radius: f64) -> LocalLight {
        LocalLight {
            center,
            power,
            radius,
            cone: None,
            chord: None,
        }
    }

    /// ∫ f over the sphere by a midpoint rule in (cos θ, φ) around `axis`.
    fn sphere_integral(axis: DVec3, n: usize, f: impl Fn(DVec3) -> f64) -> f64 {
        let (t, b) = orthonormal_basis(axis);
        let mut sum = 0.0;
        for i in 0..n {
            let c = -1.0 + (i as f64 + 0.5) * 2.0 / n as f64;
            let s = (1.0 - c * c).sqrt();
            for j in 0..n {
                let phi = (j as f64 + 0.5) * 2.0 * PI / n as f64;
                sum += f(t * (s * phi.cos()) + b * (s * phi.sin()) + axis * c);
            }
        }
        sum * (2.0 / n as f64) * (2.0 * PI / n as f64)
    }

    #[test]
    fn the_mixture_is_a_density() {
        // Two lights, one of them close; the quadrature is centred on the close one,
        // whose lobe is the sharpest feature (κ = 10: its width is resolved by the
        // 2000 cos θ steps of the rule).
        let lobes = LightLobes::new(&[
            light(DVec3::new(0.3, 0.0, 0.1), 5.0, 0.05),
            light(DVec3::new(-4.0, 2.0, 1.0), 200.0, 0.5),
        ])
        .unwrap();
        let (p, dir) = (DVec3::ZERO, DVec3::new(0.0, 0.6, 0.8));
        for g in [0.0, 0.3, -0.5] {
            let axis = DVec3::new(0.3, 0.0, 0.1).normalize();
            let integral = sphere_integral(axis, 2000, |w| lobes.pdf(p, dir, g, w));
            assert!((integral - 1.0).abs() < 2e-3, "g {g}: ∫q = {integral}");
        }
    }

    /// The guided continuation's estimate of ∫ phase(ω) h(ω) dω, h a test function
    /// peaked towards the light, against quadrature: the mean of weight × h over
    /// N = 400,000 draws (seed 44) within 4 standard errors (the draws' own sample
    /// standard deviation / √N). A weight phase / q from the wrong density (e.g. the
    /// lobe alone) fails it.
    #[test]
    fn guided_continuations_are_unbiased() {
        let c = DVec3::new(1.0, 0.5, -0.2);
        let lobes = LightLobes::new(&[light(c, 10.0, 0.1), light(-c, 3.0, 0.1)]).unwrap();
        let (p, dir, g) = (DVec3::ZERO, DVec3::new(0.0, 0.0, 1.0), 0.3);
        let axis = c.normalize();
        let h = |w: DVec3| (4.0 * (w.dot(axis) - 1.0)).exp() + 0.1;
        let exact = sphere_integral(axis, 2000, |w| hg(g, dir.dot(w)) * h(w));
        let mut rng = Pcg64::seed_from_u64(44);
        assert_mean_within_4_se(400_000, exact, |_| {
            let (w, weight, q) = lobes.sample(p, dir, g, [rng.gen(), rng.gen(), rng.gen()]);
            assert!(weight <= 1.0 / (1.0 - LOBE_SHARE) + 1e-9 && q > 0.0);
            assert!((weight - hg(g, dir.dot(w)) / lobes.pdf(p, dir, g, w)).abs() < 1e-12);
            weight * h(w)
        });
    }

    /// The mean of `draw(i)` over i < `n` lies within 4 of its standard errors (the
    /// draws' own sample deviation / √n) of `exact`.
    fn assert_mean_within_4_se(n: usize, exact: f64, mut draw: impl FnMut(usize) -> f64) {
        let (mut s, mut s2) = (0.0, 0.0);
        for i in 0..n {
            let v = draw(i);
            s += v;
            s2 += v * v;
        }
        let mean = s / n as f64;
        let se = ((s2 / n as f64 - mean * mean) / n as f64).sqrt();
        let z = (mean - exact) / se;
        assert!(z.abs() < 4.0, "mean {mean}, exact {exact}, z {z}");
    }

    /// Past [`ONE_LOBE_LIGHTS`] a continuation is guided towards the one light chosen
    /// for it, from whatever distribution: here light 3, light 20, a light without
    /// power (39) or none, in turn. The mean of weight × h over N = 400,000 draws
    /// (seed 45) is ∫ phase · h by quadrature within 4 standard errors, the density
    /// returned for MIS (and `pdf`) is the phase function's, and the weight is
    /// phase / ((1 − α) phase + α vMF) of the chosen lobe (≤ 1 / (1 − α)). Dividing by
    /// the mixture over every lobe instead fails it.
    #[test]
    fn continuations_towards_the_chosen_light_are_unbiased() {
        let mut lights: Vec<LocalLight> = (0..40)
            .map(|i| {
                let a = i as f64 * 0.7;
                light(
                    DVec3::new(3.0 * a.cos(), 3.0 * a.sin(), 0.2 * i as f64 - 4.0),
                    1.0 + i as f64,
                    0.1,
                )
            })
            .collect();
        lights[3].center = DVec3::new(1.0, 0.5, -0.2);
        lights[39].power = 0.0;
        let lobes = LightLobes::new(&lights).unwrap();
        assert!(lobes.one_lobe());
        let (p, dir, g) = (DVec3::ZERO, DVec3::new(0.0, 0.0, 1.0), 0.3);
        let axis = lights[3].center.normalize();
        let h = |w: DVec3| (4.0 * (w.dot(axis) - 1.0)).exp() + 0.1;
        let exact = sphere_integral(axis, 2000, |w| hg(g, dir.dot(w)) * h(w));
        let mut rng = Pcg64::seed_from_u64(45);
        assert_mean_within_4_se(400_000, exact, |i| {
            let chosen = [Some(3), Some(20), Some(39), None][i % 4];
            let u = [rng.gen(), rng.gen(), rng.gen()];
            let (w, weight, pdf) = lobes.sample_towards(p, dir, g, chosen, u);
            let phase = hg(g, dir.dot(w));
            assert!((pdf - phase).abs() < 1e-12 && (lobes.pdf(p, dir, g, w) - phase).abs() < 1e-12);
            assert!(weight > 0.0 && weight <= 1.0 / (1.0 - LOBE_SHARE) + 1e-9);
            weight * h(w)
        });
    }

    #[test]
    fn no_light_with_power_guides_nothing() {
        assert!(LightLobes::new(&[]).is_none());
        assert!(LightLobes::new(&[light(DVec3::X, 0.0, 0.0)]).is_none());
    }

    #[test]
    fn vmf_samples_follow_its_density() {
        // The mean cosine of the lobe, E[cos] = coth κ − 1/κ, over 200,000 draws
        // (seed 7) within 4 standard errors.
        let mut rng = Pcg64::seed_from_u64(7);
        let axis = DVec3::new(0.2, -0.3, 0.9).normalize();
        let n = 200_000;
        let (mut s, mut s2) = (0.0, 0.0);
        for _ in 0..n {
            let c = sample_vmf(axis, KAPPA, rng.gen(), rng.gen()).dot(axis);
            s += c;
            s2 += c * c;
        }
        let mean = s / n as f64;
        let se = ((s2 / n as f64 - mean * mean) / n as f64).sqrt();
        let exact = 1.0 / KAPPA.tanh() - 1.0 / KAPPA;
        assert!(((mean - exact) / se).abs() < 4.0, "{mean} vs {exact}");
    }
}
