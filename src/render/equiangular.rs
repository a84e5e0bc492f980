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
//! p̃_d(s) = σt(x(s)) exp(−τ̃(a, s)), τ̃ the optical depth from a to s taken at the
//! midpoint of each majorant segment's density bounds. It is the exact density of
//! delta tracking in constant media (fog boxes, world fog, whose bounds are equal)
//! and close to it where the majorants are tight (docs/trackers.md, "Equiangular
//! sampling and MIS").
//!
//! With several local lights one is chosen per segment with probability
//! Q_ℓ ∝ Φ_ℓ ∫ ds / r_ℓ(s)² (its power times the segment's equiangular mass: its
//! share of unshadowed single scattering). Then Q_ℓ p_e,ℓ(s) = Φ_ℓ / (M r_ℓ(s)²),
//! M = Σ_k Φ_k ∫ 1/r_k², which the tracker's side evaluates without trigonometry.
//!
//! A spot light's integral runs only over the stretch of [a, b] inside its cone
//! ([`Cone`]): equiangular points are drawn there, and outside it the collisions keep
//! their whole weight, so the partition of unity holds at every s. A sphere light
//! can likewise be sampled on the chord through a ball around it alone
//! ([`LocalLight::chord`]): near the light, where a collision's next-event estimate
//! grows as 1/r² and the rare collisions there are a render's fireflies, equiangular
//! points take most of the weight; farther out the collisions keep it all, and no
//! transmittance is estimated for points the light barely reaches.

use glam::DVec3;

/// A local light as the equiangular sampler sees it: where it is, how much it sends
/// (a proxy: the choice among lights only needs proportions) and, for a spot, the
/// cone outside which it lights nothing.
#[derive(Clone, Copy, Debug)]
pub struct LocalLight {
    pub center: DVec3,
    /// Emitted power (W, mean over channels; for a spot, the share its cone's solid
    /// angle passes).
    pub power: f64,
    /// How far its emitting surface reaches from the centre (a sphere's radius, half
    /// a rect's diagonal): scattered directions guided towards it never weigh it as
    /// nearer ([`crate::render::guiding`]).
    pub radius: f64,
    pub cone: Option<Cone>,
    /// Equiangular points only on the chord of a segment through the ball of this
    /// radius around `center` (in a grid, where the collisions keep the rest of the
    /// segment: [`crate::render::job`]); `None`: on the whole stretch.
    pub chord: Option<f64>,
}

impl LocalLight {
    /// The stretch of `[a, b]` on the unit-speed line `o + s·ω` this light's
    /// equiangular points are drawn on (all of it, the part inside its cone, and with a
    /// [`Self::chord`] the part inside that ball).
    #[inline]
    pub fn stretch(&self, o: DVec3, omega: DVec3, a: f64, b: f64) -> Option<(f64, f64)> {
        let (a, b) = match &self.cone {
            None => (a < b).then_some((a, b)),
            Some(cone) => cone.clip(o, omega, a, b),
        }?;
        let Some(radius) = self.chord else {
            return Some((a, b));
        };
        // |o + sω − c|² = r²: s = f ± √(r² − h²), f the foot of the perpendicular.
        let f = (self.center - o).dot(omega);
        let h2 = (o + omega * f - self.center).length_squared();
        let half = (radius * radius - h2).max(0.0).sqrt();
        let (lo, hi) = (a.max(f - half), b.min(f + half));
        (half > 0.0 && lo < hi).then_some((lo, hi))
    }

    /// The equiangular density towards this light over its [`Self::stretch`].
    #[inline]
    pub fn equiangular(&self, o: DVec3, omega: DVec3, a: f64, b: f64) -> Option<Equiangular> {
        if self.power <= 0.0 {
            return None;
        }
        let (a, b) = self.stretch(o, omega, a, b)?;
        Equiangular::new(o, omega, self.center, a, b)
    }

    /// Q_ℓ p_ℓ(s) = Φ / (M r²) at point `x` = x(`s`) of the line, 0 where this light's
    /// equiangular samples never land (outside its stretch, or no power).
    #[inline]
    pub fn density_at(&self, seg: (DVec3, DVec3, f64, f64), s: f64, x: DVec3, total: f64) -> f64 {
        let (o, omega, a, b) = seg;
        if self.power <= 0.0 {
            return 0.0;
        }
        match self.stretch(o, omega, a, b) {
            Some((a, b)) if s >= a && s <= b => {
                self.power / (total * (x - self.center).length_squared())
            }
            _ => 0.0,
        }
    }
}

/// The convex cone a spot light lights: every ray that leaves a ball of radius R
/// around the light's centre within the cutoff angle θ of its axis stays inside the
/// cone of half-angle θ whose apex lies R / sin θ behind the centre (the cone
/// tangent to the ball; disks and rects lie in the ball of their half-diagonal).
#[derive(Clone, Copy, Debug)]
pub struct Cone {
    apex: DVec3,
    /// Unit.
    axis: DVec3,
    cos: f64,
}

impl Cone {
    /// The cone of a light of `radius` at `center` shaped to `cutoff` radians around
    /// unit `axis`; `None` for a cutoff of 90° or more (then the lit region is not a
    /// convex cone and no stretch is cut off) or one too narrow to hold the ball.
    pub fn new(center: DVec3, axis: DVec3, cutoff: f64, radius: f64) -> Option<Cone> {
        if !(cutoff < std::f64::consts::FRAC_PI_2) {
            return None;
        }
        let sin = cutoff.sin();
        if radius > 0.0 && !(sin > 1e-6) {
            return None;
        }
        let back = if radius > 0.0 { radius / sin } else { 0.0 };
        Some(Cone {
            apex: center - axis * back,
            axis,
            cos: cutoff.cos(),
        })
    }

    /// Whether `x` lies inside the cone.
    #[inline]
    pub fn holds(&self, x: DVec3) -> bool {
        let v = x - self.apex;
        let h = v.dot(self.axis);
        h >= 0.0 && h * h >= self.cos * self.cos * v.length_squared()
    }

    /// The stretch of `[a, b]` on the unit-speed line `o + s·ω` inside the cone (a
    /// convex set, so one interval). The line crosses the double cone's surface at
    /// the roots of a quadratic and the apex's plane at one more point; these cut
    /// [a, b] into pieces each wholly inside or outside, told by their midpoints.
    pub fn clip(&self, o: DVec3, omega: DVec3, a: f64, b: f64) -> Option<(f64, f64)> {
        if !(a < b) {
            return None;
        }
        let d = o - self.apex;
        let (dn, wn) = (d.dot(self.axis), omega.dot(self.axis));
        let c2 = self.cos * self.cos;
        // (h(s))² − cos² |v(s)|² = α s² + β s + γ, h(s) = dn + s wn.
        let alpha = wn * wn - c2;
        let beta = 2.0 * (dn * wn - c2 * d.dot(omega));
        let gamma = dn * dn - c2 * d.length_squared();
        let mut cuts = [f64::NAN; 5];
        cuts[0] = a;
        cuts[1] = b;
        if wn != 0.0 {
            cuts[2] = -dn / wn;
        }
        if alpha.abs() > 1e-12 {
            let disc = beta * beta - 4.0 * alpha * gamma;
            if disc >= 0.0 {
                // The numerically stable pair of roots.
                let q = -0.5 * (beta + beta.signum() * disc.sqrt());
                cuts[3] = q / alpha;
                if q != 0.0 {
                    cuts[4] = gamma / q;
                }
            }
        } else if beta != 0.0 {
            cuts[3] = -gamma / beta;
        }
        let mut n = 0;
        let mut pts = [0f64; 5];
        for c in cuts {
            if c >= a && c <= b {
                pts[n] = c;
                n += 1;
            }
        }
        let pts = &mut pts[..n];
        pts.sort_by(f64::total_cmp);
        let mut inside: Option<(f64, f64)> = None;
        for w in pts.windows(2) {
            let (lo, hi) = (w[0], w[1]);
            if !(lo < hi) {
                continue;
            }
            let mid = if hi.is_finite() {
                0.5 * (lo + hi)
            } else {
                lo + lo.abs().max(1.0)
            };
            if self.holds(o + omega * mid) {
                inside = Some(inside.map_or((lo, hi), |(l, _)| (l, hi)));
            }
        }
        inside
    }
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

/// The deterministic stand-in for the trackers' collision density at a point where
/// the extinction is `sigma_t`, the optical depth from the segment's start being
/// about `tau` (see the module documentation).
#[inline]
pub fn tracker_density(sigma_t: f64, tau: f64) -> f64 {
    if sigma_t <= 0.0 {
        return 0.0;
    }
    sigma_t * (-tau.max(0.0)).exp()
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
    /// A chord light's stretch is the segment's part inside its ball: the line
    /// y = 0.6 through a ball of radius 1 at the origin crosses it on x ∈ [−0.8, 0.8];
    /// a segment from −0.5 keeps [−0.5, 0.8]; one that misses the ball, or a line
    /// farther than the radius, has none.
    #[test]
    fn a_chord_stretch_is_the_segment_inside_the_ball() {
        let light = LocalLight {
            center: DVec3::ZERO,
            power: 1.0,
            radius: 0.1,
            cone: None,
            chord: Some(1.0),
        };
        let o = DVec3::new(-3.0, 0.6, 0.0);
        let (a, b) = light.stretch(o, DVec3::X, 0.0, 10.0).unwrap();
        assert!(
            (a - 2.2).abs() < 1e-12 && (b - 3.8).abs() < 1e-12,
            "{a} {b}"
        );
        let (a, b) = light.stretch(o, DVec3::X, 2.5, 10.0).unwrap();
        assert!(
            (a - 2.5).abs() < 1e-12 && (b - 3.8).abs() < 1e-12,
            "{a} {b}"
        );
        assert!(light.stretch(o, DVec3::X, 4.0, 10.0).is_none());
        assert!(light
            .stretch(DVec3::new(-3.0, 1.2, 0.0), DVec3::X, 0.0, 10.0)
            .is_none());
        let whole = LocalLight {
            chord: None,
            ..light
        };
        assert_eq!(whole.stretch(o, DVec3::X, 0.0, 10.0), Some((0.0, 10.0)));
    }

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
    /// `Cone::clip` against the point test on a fine grid of s: for 2,000 random
    /// lines (fixed seed) through cones of 5°–85°, every s of 4,001 steps over [a, b]
    /// lies inside the clipped stretch exactly when the cone holds x(s), except
    /// within 1e-6 of the stretch's ends (the roots' rounding).
    #[test]
    fn a_cone_clips_the_stretch_it_holds() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_pcg::Pcg64::seed_from_u64(44);
        let unit = |rng: &mut rand_pcg::Pcg64| loop {
            let v = DVec3::new(
                rng.gen_range(-1.0..1.0),
                rng.gen_range(-1.0..1.0),
                rng.gen_range(-1.0..1.0),
            );
            if v.length_squared() > 0.01 && v.length_squared() <= 1.0 {
                break v.normalize();
            }
        };
        let (mut nonempty, mut unbounded) = (0, 0);
        for i in 0..2000 {
            let axis = unit(&mut rng);
            let cutoff = rng.gen_range(5f64..85.0).to_radians();
            let radius = if i % 2 == 0 {
                0.0
            } else {
                rng.gen_range(0.0..0.5)
            };
            let center = DVec3::new(rng.gen_range(-1.0..1.0), 0.0, rng.gen_range(-1.0..1.0));
            let cone = Cone::new(center, axis, cutoff, radius).unwrap();
            // The ball around the centre is inside the cone.
            assert!(cone.holds(center + unit(&mut rng) * radius * 0.999));
            let o = DVec3::new(
                rng.gen_range(-3.0..3.0),
                rng.gen_range(-3.0..3.0),
                rng.gen_range(-3.0..3.0),
            );
            let omega = unit(&mut rng);
            let (a, b) = (rng.gen_range(0.0..1.0), rng.gen_range(1.0..8.0));
            let b = if i % 7 == 0 { f64::INFINITY } else { b };
            let clip = cone.clip(o, omega, a, b);
            let bend = if b.is_finite() { b } else { a + 100.0 };
            for j in 0..=4000 {
                let s = a + (bend - a) * j as f64 / 4000.0;
                let held = cone.holds(o + omega * s);
                let inside = clip.is_some_and(|(lo, hi)| s >= lo && s <= hi);
                let near =
                    clip.is_some_and(|(lo, hi)| (s - lo).abs() < 1e-6 || (s - hi).abs() < 1e-6);
                assert!(
                    held == inside || near,
                    "line {i}: s {s} held {held} clip {clip:?}"
                );
            }
            if let Some((lo, hi)) = clip {
                assert!(a <= lo && lo < hi && hi <= b);
                nonempty += 1;
                unbounded += hi.is_infinite() as u32;
            }
        }
        // The draw exercises both kinds of stretch (counts fixed by the seed).
        assert!(nonempty > 200 && unbounded > 5, "{nonempty} {unbounded}");
        assert!(Cone::new(DVec3::ZERO, DVec3::Z, 1.6, 0.0).is_none());
    }
}
