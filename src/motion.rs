//! Transform motion over the camera's shutter: a prim's local → world transform as
//! keyframes at frame-relative times, linearly interpolated between them.
//!
//! The USD reader puts a key at each end of the shutter and at every authored time
//! sample between, then bisects each interval until the interpolation stays within
//! [`KEY_TOLERANCE`] of the transform USD itself computes at the midpoint (a linear
//! translate needs no extra key; a rotation does). Renderers interpolate the same
//! matrices everywhere (rays, bounds), so what is drawn is one consistent motion.

use glam::{DMat3, DMat4, DVec3};

/// Where the interpolation between two keys may stray from USD's own transform at
/// their midpoint: a point of the prim's local unit cube may land this far off (in
/// local units) before the interval is split.
pub const KEY_TOLERANCE: f64 = 1e-4;

/// How far LᵀL of a rigid motion's linear part L may stray from the identity: a
/// rotation evaluated in double precision is orthonormal to ~1e-15; a scale animated
/// by even 0.1 % is 2e-3 off.
pub const RIGID_TOLERANCE: f64 = 1e-6;

/// A box holding nothing: the start of a union.
const EMPTY_BOX: (DVec3, DVec3) = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));

/// Bisections per authored interval at most (2⁸ keys).
pub const MAX_SPLITS: u32 = 8;

/// A transform at frame-relative times (time codes from the frame: the shutter's
/// `open` … `close`), increasing, at least two.
#[derive(Clone, Debug, PartialEq)]
pub struct TransformMotion {
    keys: Vec<(f64, DMat4)>,
}

impl TransformMotion {
    /// The motion through `keys` (time, transform); `None` with fewer than two keys,
    /// times not strictly increasing, or all transforms equal (nothing moves).
    pub fn new(keys: Vec<(f64, DMat4)>) -> Option<TransformMotion> {
        let increasing = keys.windows(2).all(|w| w[0].0 < w[1].0);
        let moves = keys.iter().any(|k| k.1 != keys[0].1);
        (keys.len() >= 2 && increasing && moves).then_some(TransformMotion { keys })
    }

    /// Keys for `transform_at` over `[open, close]`: the two ends, every time of
    /// `authored` inside, and bisections where the interpolation strays from it.
    pub fn sample(
        open: f64,
        close: f64,
        authored: &[f64],
        mut transform_at: impl FnMut(f64) -> Result<DMat4, String>,
    ) -> Result<Option<TransformMotion>, String> {
        let mut times: Vec<f64> = [open]
            .into_iter()
            .chain(authored.iter().copied().filter(|&t| t > open && t < close))
            .chain([close])
            .collect();
        times.dedup();
        let mut keys = Vec::new();
        let first = transform_at(times[0])?;
        keys.push((times[0], first));
        for w in times.windows(2) {
            let (a, b) = (keys.last().unwrap().1, transform_at(w[1])?);
            refine(
                &mut keys,
                (w[0], a),
                (w[1], b),
                MAX_SPLITS,
                &mut transform_at,
            )?;
        }
        Ok(TransformMotion::new(keys))
    }

    /// The same motion followed by the static transform `by` (an instance's
    /// placement): every key left-multiplied, which interpolation commutes with.
    pub fn placed(&self, by: DMat4) -> TransformMotion {
        TransformMotion {
            keys: self.keys.iter().map(|&(t, m)| (t, by * m)).collect(),
        }
    }

    /// The motion seen from the prim's place at the frame, `frame`: keys
    /// M(t)·frame⁻¹, each mapping where the prim is at the frame to where it is at t
    /// (interpolation commutes with the constant right factor).
    pub fn relative_to(&self, frame: &DMat4) -> TransformMotion {
        let inverse = frame.inverse();
        TransformMotion {
            keys: self.keys.iter().map(|&(t, m)| (t, m * inverse)).collect(),
        }
    }

    /// Whether the prim only turns and slides away from its place at the frame
    /// (`frame`): every key's [`Self::relative_to`] map is a rotation and a
    /// translation, within [`RIGID_TOLERANCE`] (no change of scale or shear, which a
    /// constant scale above or below the moving op never makes).
    pub fn is_rigid_from(&self, frame: &DMat4) -> bool {
        self.relative_to(frame).keys.iter().all(|(_, m)| {
            let l = DMat3::from_mat4(*m);
            let gram = l.transpose() * l - DMat3::IDENTITY;
            gram.to_cols_array()
                .iter()
                .all(|e| e.abs() <= RIGID_TOLERANCE)
        })
    }

    /// The keys (time, transform).
    pub fn keys(&self) -> &[(f64, DMat4)] {
        &self.keys
    }

    /// The transform at frame-relative `time` (clamped to the keys' span).
    #[inline]
    pub fn at(&self, time: f64) -> DMat4 {
        let k = &self.keys;
        let i = k.partition_point(|key| key.0 <= time);
        if i == 0 {
            return k[0].1;
        }
        if i == k.len() {
            return k[i - 1].1;
        }
        let ((t0, m0), (t1, m1)) = (k[i - 1], k[i]);
        lerp(m0, m1, (time - t0) / (t1 - t0))
    }

    /// The transform at the frame's own time (0), where the render's other lookups
    /// (emission, albedo, shader graphs) are placed.
    pub fn at_frame(&self) -> DMat4 {
        self.at(0.0)
    }

    /// The world box that holds `corners` (local points) at every time: between two
    /// keys each point moves on a straight line, so the keys' boxes hold it.
    pub fn swept_box(&self, corners: &[DVec3]) -> (DVec3, DVec3) {
        self.keys
            .iter()
            .map(|(_, m)| Self::box_of(m, corners))
            .fold(EMPTY_BOX, |a, b| (a.0.min(b.0), a.1.max(b.1)))
    }

    /// The box around `points` placed by `m`.
    pub fn box_of(m: &DMat4, points: &[DVec3]) -> (DVec3, DVec3) {
        points.iter().fold(EMPTY_BOX, |b, &p| {
            let w = m.transform_point3(p);
            (b.0.min(w), b.1.max(w))
        })
    }
}

/// Component-wise interpolation, as USD interpolates a matrix-valued attribute.
#[inline]
fn lerp(a: DMat4, b: DMat4, s: f64) -> DMat4 {
    a + (b - a) * s
}

/// Pushes the keys after `(ta, a)` up to and including `(tb, b)`, bisecting while the
/// midpoint's interpolation strays from `transform_at` there.
fn refine(
    keys: &mut Vec<(f64, DMat4)>,
    (ta, a): (f64, DMat4),
    (tb, b): (f64, DMat4),
    depth: u32,
    transform_at: &mut impl FnMut(f64) -> Result<DMat4, String>,
) -> Result<(), String> {
    let tm = 0.5 * (ta + tb);
    let m = transform_at(tm)?;
    if depth == 0 || stray(m, lerp(a, b, 0.5)) <= KEY_TOLERANCE {
        keys.push((tb, b));
        return Ok(());
    }
    refine(keys, (ta, a), (tm, m), depth - 1, transform_at)?;
    refine(keys, (tm, m), (tb, b), depth - 1, transform_at)
}

/// How far the interpolated transform `approx` takes a corner of the local unit cube
/// from where `exact` takes it, measured back in `exact`'s local units.
fn stray(exact: DMat4, approx: DMat4) -> f64 {
    let back = exact.inverse() * approx;
    let mut worst: f64 = 0.0;
    for i in 0..8 {
        let c = DVec3::new(
            if i & 1 == 0 { -1.0 } else { 1.0 },
            if i & 2 == 0 { -1.0 } else { 1.0 },
            if i & 4 == 0 { -1.0 } else { 1.0 },
        );
        worst = worst.max((back.transform_point3(c) - c).length());
    }
    // A singular exact transform (a zero scale): compare in world units instead.
    if !worst.is_finite() {
        return (exact - approx)
            .to_cols_array()
            .iter()
            .map(|v| v.abs())
            .fold(0.0, f64::max);
    }
    worst
}

#[cfg(test)]
mod tests {
    use super::*;

    fn translate(t: f64) -> DMat4 {
        DMat4::from_translation(DVec3::new(2.0 * t, 0.0, 0.0))
    }

    #[test]
    fn a_linear_translate_needs_only_its_ends() {
        let m = TransformMotion::sample(-0.25, 0.25, &[], |t| Ok(translate(t)))
            .unwrap()
            .unwrap();
        assert_eq!(m.keys().len(), 2);
        assert_eq!(m.at(0.0), translate(0.0));
        assert!((m.at(0.1).w_axis.x - 0.2).abs() < 1e-12);
        // Clamped outside the keys.
        assert_eq!(m.at(1.0), translate(0.25));
    }

    #[test]
    fn a_rotation_is_bisected_until_within_tolerance() {
        let rot = |t: f64| Ok(DMat4::from_rotation_z(t * std::f64::consts::FRAC_PI_2));
        let m = TransformMotion::sample(0.0, 1.0, &[], rot)
            .unwrap()
            .unwrap();
        assert!(m.keys().len() > 2);
        for i in 0..=100 {
            let t = i as f64 / 100.0;
            // A uniform rotation strays most at an interval's midpoint, which was checked.
            assert!(
                stray(rot(t).unwrap(), m.at(t)) <= KEY_TOLERANCE * 1.001,
                "t = {t}"
            );
        }
    }

    #[test]
    fn nothing_moving_is_no_motion() {
        assert!(
            TransformMotion::sample(0.0, 1.0, &[0.5], |_| Ok(DMat4::IDENTITY))
                .unwrap()
                .is_none()
        );
    }

    #[test]
    fn the_swept_box_holds_both_ends() {
        let m = TransformMotion::sample(0.0, 1.0, &[], |t| Ok(translate(t)))
            .unwrap()
            .unwrap();
        let (lo, hi) = m.swept_box(&[DVec3::splat(-1.0), DVec3::splat(1.0)]);
        assert_eq!((lo.x, hi.x), (-1.0, 3.0));
    }
}
