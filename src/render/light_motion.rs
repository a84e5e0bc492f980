//! Local lights that move over the shutter.
//!
//! A light that only turns and slides (the USD reader keeps no other motion, see
//! `TransformMotion::is_rigid_from`) looks the same from every point that moves with
//! it. So a point p at time t sees what the light *as placed at the frame* shows the
//! point Rel(t)⁻¹ p, where Rel(t) = M(t)·M(frame)⁻¹ carries the light from its place at
//! the frame to its place at t: the light's emitter, built once at the frame, samples
//! from there, and the sample's direction and distance are carried back by Rel(t).
//! A rigid map keeps solid angles and distances, so the sample's weight (radiance over
//! its density) is unchanged and the estimate stays exact. Between two keys the
//! interpolated map is rigid only to within the keys' tolerance
//! ([`crate::motion::KEY_TOLERANCE`]): the direction is renormalised and the distance
//! rescaled so the shadow ray still ends on the light.

use crate::motion::TransformMotion;
use glam::{DMat3, DVec3};

/// A light's motion relative to its place at the frame.
#[derive(Clone, Debug)]
pub struct LightMotion {
    relative: TransformMotion,
}

impl LightMotion {
    /// The motion of a light whose local → world transform is `frame` at the frame and
    /// `motion` over the shutter.
    pub fn new(motion: &TransformMotion, frame: &glam::DMat4) -> LightMotion {
        LightMotion {
            relative: motion.relative_to(frame),
        }
    }

    /// Where `p` is, seen from the light as placed at the frame, at `time`; and the
    /// linear map that carries a direction from there back to the world at `time`.
    #[inline]
    pub fn seen_from_frame(&self, p: DVec3, time: f64) -> (DVec3, DMat3) {
        let rel = self.relative.at(time);
        let linear = DMat3::from_mat4(rel);
        // Rel⁻¹ p for a (near-)rigid map: Lᵀ (p − t), as exact as the map is rigid.
        let q = linear.transpose() * (p - rel.w_axis.truncate());
        (q, linear)
    }

    /// A direction `wi` and distance found from [`Self::seen_from_frame`]'s point, in
    /// the world at the time it was taken (`linear` is what it returned).
    #[inline]
    pub fn back_to_world(linear: &DMat3, wi: DVec3, distance: f64) -> (DVec3, f64) {
        let w = *linear * wi;
        let length = w.length();
        (w / length, distance * length)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DMat4;

    /// A light turned 90° about Y and slid 2 along X over the shutter: a point that
    /// moves with it sees what the light at the frame shows its starting place.
    #[test]
    fn a_point_moving_with_the_light_sees_the_light_at_the_frame() {
        let frame = DMat4::from_translation(DVec3::new(0.0, 1.0, 0.0));
        let turn = |t: f64| {
            DMat4::from_translation(DVec3::new(2.0 * t, 0.0, 0.0))
                * DMat4::from_rotation_y(t * std::f64::consts::FRAC_PI_2)
                * frame
        };
        let keys = (0..=64)
            .map(|i| (i as f64 / 64.0, turn(i as f64 / 64.0)))
            .collect();
        let motion = TransformMotion::new(keys).unwrap();
        assert!(motion.is_rigid_from(&frame));
        let m = LightMotion::new(&motion, &frame);
        let p0 = DVec3::new(0.3, -0.5, 0.7);
        for t in [0.0, 0.25, 0.6, 1.0] {
            // p0 carried along with the light to time t.
            let rel = turn(t) * frame.inverse();
            let p = rel.transform_point3(p0);
            let (q, linear) = m.seen_from_frame(p, t);
            assert!((q - p0).length() < 1e-3, "t {t}: {q} vs {p0}");
            // A direction towards the light's origin maps to the world's.
            let to_light = (frame.transform_point3(DVec3::ZERO) - q).normalize();
            let (w, d) = LightMotion::back_to_world(&linear, to_light, 1.0);
            let world = (rel.transform_point3(DVec3::new(0.0, 1.0, 0.0)) - p).normalize();
            assert!((w - world).length() < 2e-3, "t {t}: {w} vs {world}");
            assert!((d - 1.0).abs() < 2e-3);
        }
    }

    #[test]
    fn a_scaling_light_is_not_rigid() {
        let frame = DMat4::IDENTITY;
        let keys = vec![(0.0, frame), (1.0, DMat4::from_scale(DVec3::splat(1.01)))];
        let motion = TransformMotion::new(keys).unwrap();
        assert!(!motion.is_rigid_from(&frame));
    }
}
