//! Scattering points sampled towards local lights (equiangular sampling, Kulla and
//! Fajardo 2012), combined with the trackers' free-path sampling by multiple
//! importance sampling.
//!
//! Along a path segment `x(s) = o + s·ω` (s in world units) the single-scattering
//! light of a local light ℓ is the integral ∫ T(0, s) σs(s) E_ℓ(x(s)) ds, with E_ℓ the
//! next-event estimate at x(s) (phase function × radiance × shadow transmittance /
//! light-sample density). The trackers sample s with the density of the first real
//! collision, p_d(s) = σt(s) T(0, s); where ℓ is near the segment, E_ℓ ∝ 1/r² peaks
//! and few collisions land there. Equiangular sampling draws s with density
//! ∝ 1/|x(s) − c_ℓ|² over the segment's stretch [a, b] inside media, so the peak is
//! sampled where it is.
//!
//! The two strategies are combined with weights w_d(s) + w_e(s) = 1 at every s
//! (multi-sample MIS, Veach 1997): the tracker's collision estimate of light ℓ is
//! multiplied by w_d, and one equiangular sample per segment adds
//! w_e · T̂(0, s) σs(s) E_ℓ / p_e(s), T̂ a ratio-tracking estimate. Each strategy then
//! estimates ∫ w·(…) exactly (the collision estimator is unbiased for any integrand
//! of the collision point, here w_d·E_ℓ), so the sum is unbiased for *any* such
//! partition of unity. The weights need the densities only to be good, not to be
//! right: the balance heuristic with p_d replaced by a deterministic stand-in,
//! p̃_d(s) = σt(x(s)) exp(−σt(x(s)) (s − a)), which is the exact density of delta
//! tracking in a homogeneous medium (fog boxes, world fog) and a guess elsewhere
//! (docs/trackers.md, "Equiangular sampling and MIS").
//!
//! With several local lights one is chosen per segment with probability
//! Q_ℓ ∝ Φ_ℓ ∫_a^b ds / r_ℓ(s)² (its power times the segment's equiangular mass: its
//! share of unshadowed single scattering). Then Q_ℓ p_e,ℓ(s) = Φ_ℓ / (M r_ℓ(s)²),
//! M = Σ_k Φ_k ∫ 1/r_k², which the tracker's side evaluates without trigonometry.

use glam::DVec3;

/// A local light as the equiangular sampler sees it: where it is and how much it
/// sends (a proxy: the choice among lights only needs proportions).
#[derive(Clone, Copy, Debug)]
pub struct LocalLight {
    pub center: DVec3,
    /// Emitted power (W, mean over channels; shaping left out).
    pub power: f64,
}

/// The equiangular density towards one point over `[a, b]` of a unit-speed line.
#[derive(Clone, Copy, Debug)]
pub struct Equiangular {
    /// Where the line passes closest to the point (s of the foot of the perpendicular).
    foot: f64,
    /// The distance of the point from the line (clamped away from 0).
    d: f64,
    theta_a: f64,
    /// θ_b − θ_a: the angle the segment subtends from the point.
    span: f64,
}

impl Equiangular {
    /// Towards `center` from the unit-speed line `o + s·ω`, s in [`a`, `b`] (`b` may
    /// be infinite); `None` for an empty segment.
    pub fn new(o: DVec3, omega: DVec3, center: DVec3, a: f64, b: f64) -> Option<Equiangular> {
        if !(a < b) {
            return None;
        }
        let to_c = center - o;
        let foot = to_c.dot(omega);
        // A light on the line itself would make the density a spike; a distance far
        // below any scene scale keeps it finite (and the estimate unbiased).
        let scale = to_c.length().max(1.0);
        let d = (to_c - omega * foot).length().max(1e-9 * scale);
        let theta_a = ((a - foot) / d).atan();
        let theta_b = if b.is_finite() {
            ((b - foot) / d).atan()
        } else {
            std::f64::consts::FRAC_PI_2
        };
        let span = theta_b - theta_a;
        (span > 0.0).then_some(Equiangular {
            foot,
            d,
            theta_a,
            span,
        })
    }

    /// ∫_a^b ds / r(s)², r the distance to the point: θ span / d.
    #[inline]
    pub fn mass(&self) -> f64 {
        self.span / self.d
    }

    /// The s of uniform number `u`: equal angle steps seen from the point.
    #[inline]
    pub fn sample(&self, u: f64) -> f64 {
        self.foot + self.d * (self.theta_a + u * self.span).tan()
    }

    /// The density of [`Self::sample`] at `s` (in [a, b]): 1 / (mass · r²).
    #[inline]
    pub fn pdf(&self, s: f64) -> f64 {
        let h = s - self.foot;
        self.d / (self.span * (self.d * self.d + h * h))
    }
}

/// The deterministic stand-in for the trackers' collision density at distance `s − a`
/// into the media where the extinction is `sigma_t` (see the module documentation).
#[inline]
pub fn tracker_density(sigma_t: f64, s_minus_a: f64) -> f64 {
    if sigma_t <= 0.0 {
        return 0.0;
    }
    sigma_t * (-sigma_t * s_minus_a.max(0.0)).exp()
}

/// The balance-heuristic weight of a strategy of density `p` against `q`.
#[inline]
pub fn balance(p: f64, q: f64) -> f64 {
    if p + q > 0.0 {
        p / (p + q)
    } else {
        0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The density integrates to 1 over the segment and `sample` is its inverse CDF:
    /// the fraction of 10⁵ stratified samples below the midpoint equals the
    /// midpoint's CDF (computed by the trapezoid rule on the density) to 1e-4.
    #[test]
    fn density_is_normalised_and_sampled() {
        let o = DVec3::new(0.0, 0.0, 0.0);
        let w = DVec3::new(1.0, 0.0, 0.0);
        let c = DVec3::new(2.0, 0.5, 0.0);
        let e = Equiangular::new(o, w, c, 0.5, 6.0).unwrap();
        let n = 200_000;
        let h = 5.5 / n as f64;
        let integral: f64 = (0..=n)
            .map(|i| {
                let s = 0.5 + i as f64 * h;
                let wt = if i == 0 || i == n { 0.5 } else { 1.0 };
                wt * e.pdf(s) * h
            })
            .sum();
        assert!((integral - 1.0).abs() < 1e-6, "{integral}");
        let mid = 3.0;
        let cdf: f64 = (0..=n)
            .map(|i| {
                let s = 0.5 + i as f64 * (mid - 0.5) / n as f64;
                let wt = if i == 0 || i == n { 0.5 } else { 1.0 };
                wt * e.pdf(s) * (mid - 0.5) / n as f64
            })
            .sum();
        let m = 100_000;
        let below = (0..m)
            .filter(|&i| e.sample((i as f64 + 0.5) / m as f64) < mid)
            .count();
        assert!((below as f64 / m as f64 - cdf).abs() < 1e-4);
        // The mass is ∫ 1/r².
        let mass: f64 = (0..=n)
            .map(|i| {
                let s = 0.5 + i as f64 * h;
                let wt = if i == 0 || i == n { 0.5 } else { 1.0 };
                let r2 = (o + w * s - c).length_squared();
                wt * h / r2
            })
            .sum();
        assert!((mass - e.mass()).abs() < 1e-6 * mass);
    }

    /// An infinite segment (world fog without a holdout) has a finite mass and its
    /// samples stay finite.
    #[test]
    fn an_unbounded_segment_is_sampled() {
        let e = Equiangular::new(
            DVec3::ZERO,
            DVec3::Z,
            DVec3::new(1.0, 0.0, 3.0),
            0.0,
            f64::INFINITY,
        )
        .unwrap();
        assert!((e.mass() - (std::f64::consts::FRAC_PI_2 + 3f64.atan())).abs() < 1e-12);
        let s = e.sample(0.999_999);
        assert!(s.is_finite() && s > 3.0);
        assert!(Equiangular::new(DVec3::ZERO, DVec3::Z, DVec3::X, 2.0, 2.0).is_none());
    }
}
