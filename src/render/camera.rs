//! Primary rays from a UsdGeomCamera: a perspective pinhole, an orthographic view, and
//! either through a thin lens for depth of field. The aperture is conformed to the image
//! aspect with USD's default "expandAperture" policy.
//!
//! Units follow UsdGeomCamera and GfCamera: apertures, their offsets and the focal length
//! are in tenths of a scene unit (GfCamera's `APERTURE_UNIT` and `FOCAL_LENGTH_UNIT`,
//! 0.1); the clipping range and `focusDistance` in scene units, all in the camera's
//! local space (a scaled camera transform scales them with it).
//!
//! - **Perspective**: the image plane spans the apertures at the focal length; only
//!   their ratios matter to a pinhole.
//! - **Orthographic**: the view is the apertures × 0.1 units wide (GfCamera's frustum
//!   window), shifted by the offsets × 0.1; rays are parallel to the view axis, leaving
//!   the camera's z = 0 plane and clipped to [near, far] along it.
//! - **Thin lens** (`fStop` > 0 and `focusDistance` > 0): a lens disk of radius
//!   `focalLength · 0.1 / (2 · fStop)` scene units in the camera's z = 0 plane; each ray
//!   leaves a point of the disk towards the point its pinhole ray (perspective) or its
//!   parallel ray (orthographic) meets at depth `focusDistance`, so that plane is sharp
//!   and a point at depth z is blurred into a disk of diameter
//!   `2 r · |z − focusDistance| / z` on the focus plane's scale (pbrt-v4's
//!   `ProjectiveCamera`; the diameter is the f-number's definition, focal length over
//!   fStop).
//!
//! Clipping planes are depths along the view axis, whatever the ray: a ray whose camera-
//! space direction falls `D` units in depth per unit parameter reaches depth z at
//! parameter z / D.

use crate::motion::TransformMotion;
use crate::scene::{Camera, Projection};
use glam::{DMat4, DVec2, DVec3};
use std::f64::consts::FRAC_PI_4;

/// GfCamera's `APERTURE_UNIT` (= `FOCAL_LENGTH_UNIT`): apertures, their offsets and the
/// focal length are in tenths of a scene unit.
pub const LENS_UNIT: f64 = 0.1;

pub struct CameraRays {
    camera_to_world: DMat4,
    projection: Projection,
    focal: f64,
    aperture: (f64, f64),
    offset: (f64, f64),
    near: f64,
    far: f64,
    width: u32,
    height: u32,
    /// The thin lens, when the camera has depth of field.
    lens: Option<ThinLens>,
    /// `camera_to_world` over the shutter, when the camera moves while it is open.
    motion: Option<TransformMotion>,
    /// `shutter:open`, `shutter:close`, when open.
    shutter: Option<(f64, f64)>,
}

/// A thin lens: its radius and the depth of the plane in focus, in camera-space units.
#[derive(Clone, Copy, Debug)]
struct ThinLens {
    radius: f64,
    focus: f64,
}

/// A primary ray: unit world direction, and the distance range inside the clipping planes.
pub struct PrimaryRay {
    pub origin: DVec3,
    pub dir: DVec3,
    pub tmin: f64,
    pub tmax: f64,
    /// Camera depth per unit distance along the ray: the cosine between `dir` and the
    /// camera's view axis (world −Z of the camera), so depth = t · `depth_per_t` (every
    /// ray leaves the camera's z = 0 plane).
    pub depth_per_t: f64,
}

impl CameraRays {
    pub fn new(cam: &Camera, width: u32, height: u32) -> CameraRays {
        let image_aspect = width as f64 / height as f64;
        let (mut h, mut v) = (cam.horizontal_aperture, cam.vertical_aperture);
        if h / v < image_aspect {
            h = v * image_aspect;
        } else {
            v = h / image_aspect;
        }
        let lens = (cam.f_stop > 0.0 && cam.focus_distance > 0.0).then(|| ThinLens {
            radius: cam.focal_length * LENS_UNIT / (2.0 * cam.f_stop),
            focus: cam.focus_distance,
        });
        CameraRays {
            camera_to_world: cam.camera_to_world,
            projection: cam.projection,
            focal: cam.focal_length,
            aperture: (h, v),
            offset: (cam.horizontal_aperture_offset, cam.vertical_aperture_offset),
            near: cam.clipping_range.0,
            far: cam.clipping_range.1,
            width,
            height,
            lens,
            motion: cam.motion.clone(),
            shutter: cam.shutter,
        }
    }

    /// Random numbers a primary ray draws after the pixel position: two for a point on
    /// the lens when the camera has depth of field, else none (so a render without
    /// depth of field draws exactly the numbers it always drew).
    pub fn lens_dims(&self) -> u32 {
        if self.lens.is_some() {
            2
        } else {
            0
        }
    }

    /// The ray through image position (`px + jx`, `py + jy`), y down, from the centre of
    /// the lens (the pinhole ray; the only ray without depth of field), at the frame.
    pub fn ray(&self, px: f64, py: f64) -> PrimaryRay {
        self.ray_at(px, py, 0.0)
    }

    /// [`Self::ray`] with the camera where it is at frame-relative `time`.
    pub fn ray_at(&self, px: f64, py: f64, time: f64) -> PrimaryRay {
        let (o, v, depth) = self.pinhole(px, py);
        self.to_world(o, v, depth, time)
    }

    /// The shutter interval (frame-relative open, close), when it is open.
    pub fn shutter(&self) -> Option<(f64, f64)> {
        self.shutter
    }

    /// Whether the camera moves while the shutter is open.
    pub fn moves(&self) -> bool {
        self.motion.is_some()
    }

    /// The ray through image position (`px`, `py`) from the lens point that
    /// (`u1`, `u2`) ∈ [0,1)² picks (uniform over the lens disk); [`Self::ray`] for a
    /// camera without depth of field.
    pub fn ray_through_lens(&self, px: f64, py: f64, u1: f64, u2: f64) -> PrimaryRay {
        self.ray_through_lens_at(px, py, u1, u2, 0.0)
    }

    /// [`Self::ray_through_lens`] with the camera where it is at frame-relative `time`.
    pub fn ray_through_lens_at(&self, px: f64, py: f64, u1: f64, u2: f64, time: f64) -> PrimaryRay {
        let (o, v, depth) = self.pinhole(px, py);
        let Some(lens) = self.lens else {
            return self.to_world(o, v, depth, time);
        };
        // The point the lens-centre ray reaches at the focus depth stays sharp.
        let focus = o + v * (lens.focus / depth);
        let d = concentric_disk(u1, u2) * lens.radius;
        let from = o + DVec3::new(d.x, d.y, 0.0);
        self.to_world(from, focus - from, lens.focus, time)
    }

    /// Camera → world at frame-relative `time`.
    #[inline]
    fn camera_to_world_at(&self, time: f64) -> DMat4 {
        match &self.motion {
            None => self.camera_to_world,
            Some(m) => m.at(time),
        }
    }

    /// The lens-centre ray of image position (`px`, `py`) in camera space: its origin
    /// (on the z = 0 plane), direction, and the depth it falls per unit of that
    /// direction.
    #[inline]
    fn pinhole(&self, px: f64, py: f64) -> (DVec3, DVec3, f64) {
        let sx = px / self.width as f64 - 0.5;
        let sy = 0.5 - py / self.height as f64;
        let x = sx * self.aperture.0 + self.offset.0;
        let y = sy * self.aperture.1 + self.offset.1;
        match self.projection {
            Projection::Perspective => (DVec3::ZERO, DVec3::new(x, y, -self.focal), self.focal),
            Projection::Orthographic => (
                DVec3::new(x * LENS_UNIT, y * LENS_UNIT, 0.0),
                -DVec3::Z,
                1.0,
            ),
        }
    }

    /// The world ray from camera-space origin `o` along `v`, which falls `depth` in
    /// depth per unit: clipped to the clipping range's depths.
    #[inline]
    fn to_world(&self, o: DVec3, v: DVec3, depth: f64, time: f64) -> PrimaryRay {
        let to_world = self.camera_to_world_at(time);
        let origin = to_world.transform_point3(o);
        let d_world = to_world.transform_vector3(v);
        let len = d_world.length();
        // The point at depth z lies at parameter z/depth along v, i.e. world distance
        // (z/depth)·|d_world|.
        let dir = d_world / len;
        PrimaryRay {
            origin,
            dir,
            tmin: self.near / depth * len,
            tmax: self.far / depth * len,
            depth_per_t: dir.dot(
                to_world
                    .transform_vector3(-DVec3::Z)
                    .normalize_or(-DVec3::Z),
            ),
        }
    }

    /// The camera's position in the world.
    pub fn origin(&self) -> DVec3 {
        self.camera_to_world.transform_point3(DVec3::ZERO)
    }

    /// Unit world direction the camera looks along (its local −Z).
    pub fn view_axis(&self) -> DVec3 {
        self.camera_to_world
            .transform_vector3(-DVec3::Z)
            .normalize_or(-DVec3::Z)
    }
}

/// Shirley and Chiu's concentric map of [0,1)² onto the unit disk: uniform (area
/// preserving), and it keeps the strata of a stratified pair compact.
fn concentric_disk(u1: f64, u2: f64) -> DVec2 {
    let a = 2.0 * u1 - 1.0;
    let b = 2.0 * u2 - 1.0;
    if a == 0.0 && b == 0.0 {
        return DVec2::ZERO;
    }
    let (r, phi) = if a.abs() > b.abs() {
        (a, FRAC_PI_4 * (b / a))
    } else {
        (b, 2.0 * FRAC_PI_4 - FRAC_PI_4 * (a / b))
    };
    DVec2::new(r * phi.cos(), r * phi.sin())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn camera(projection: Projection, f_stop: f64, focus: f64) -> Camera {
        Camera {
            prim_path: "/Cam".into(),
            camera_to_world: DMat4::from_rotation_y(0.3)
                * DMat4::from_translation(DVec3::new(1.0, 2.0, 3.0)),
            projection,
            focal_length: 35.0,
            horizontal_aperture: 20.0,
            vertical_aperture: 15.0,
            horizontal_aperture_offset: 1.5,
            vertical_aperture_offset: -0.5,
            clipping_range: (0.5, 40.0),
            f_stop,
            focus_distance: focus,
            shutter: None,
            motion: None,
        }
    }

    /// Camera-space position of world point `p`.
    fn local(cam: &Camera, p: DVec3) -> DVec3 {
        cam.camera_to_world.inverse().transform_point3(p)
    }

    /// Every ray through a pixel, from any lens point, meets the lens-centre ray at the
    /// focus depth, starts on the lens disk, and its clipping range ends at the
    /// clipping depths; for both projections.
    #[test]
    fn thin_lens_rays_converge_on_the_focus_plane() {
        for projection in [Projection::Perspective, Projection::Orthographic] {
            let cam = camera(projection, 2.8, 7.0);
            let rays = CameraRays::new(&cam, 64, 48);
            let radius = 35.0 * LENS_UNIT / (2.0 * 2.8);
            for (px, py) in [(3.5, 7.25), (40.0, 30.0), (63.9, 0.1)] {
                let centre = rays.ray(px, py);
                let t = 7.0 / centre.depth_per_t;
                let sharp = centre.origin + centre.dir * t;
                for (u1, u2) in [(0.1, 0.9), (0.5, 0.5), (0.99, 0.01), (0.3, 0.6)] {
                    let r = rays.ray_through_lens(px, py, u1, u2);
                    let o = local(&cam, r.origin);
                    let o0 = local(&cam, centre.origin);
                    assert!(o.z.abs() < 1e-12, "{projection:?}: the ray leaves z = 0");
                    assert!((o - o0).length() <= radius * (1.0 + 1e-12));
                    let hit = r.origin + r.dir * (7.0 / r.depth_per_t);
                    assert!(
                        (hit - sharp).length() < 1e-9,
                        "{projection:?}: {hit} vs {sharp}"
                    );
                    for (t, z) in [(r.tmin, 0.5), (r.tmax, 40.0)] {
                        let depth = -local(&cam, r.origin + r.dir * t).z;
                        assert!(
                            (depth - z).abs() < 1e-9 * z,
                            "{projection:?}: depth {depth}"
                        );
                    }
                }
            }
        }
    }

    /// Orthographic rays are parallel to the view axis and the view is the aperture ×
    /// 0.1 units (expanded to the image aspect), shifted by the offsets × 0.1.
    #[test]
    fn orthographic_window_is_a_tenth_of_the_aperture() {
        let cam = camera(Projection::Orthographic, 0.0, 0.0);
        let rays = CameraRays::new(&cam, 80, 60);
        assert_eq!(rays.lens_dims(), 0);
        let axis = rays.view_axis();
        let corner = |px, py| local(&cam, rays.ray(px, py).origin);
        let (a, b) = (corner(0.0, 0.0), corner(80.0, 60.0));
        assert!((b.x - a.x - 2.0).abs() < 1e-12 && (a.y - b.y - 1.5).abs() < 1e-12);
        let centre = corner(40.0, 30.0);
        assert!((centre - DVec3::new(0.15, -0.05, 0.0)).length() < 1e-12);
        for (px, py) in [(0.0, 0.0), (17.0, 33.0)] {
            let r = rays.ray(px, py);
            assert!((r.dir - axis).length() < 1e-12 && (r.depth_per_t - 1.0).abs() < 1e-12);
            assert!((r.tmin - 0.5).abs() < 1e-12 && (r.tmax - 40.0).abs() < 1e-12);
        }
    }

    /// Without depth of field the lens numbers are not drawn and change nothing; an
    /// fStop without a focus distance is a pinhole.
    #[test]
    fn no_lens_without_fstop_and_focus_distance() {
        for (f_stop, focus) in [(0.0, 5.0), (2.0, 0.0)] {
            let rays = CameraRays::new(&camera(Projection::Perspective, f_stop, focus), 8, 6);
            assert_eq!(rays.lens_dims(), 0);
            let (a, b) = (
                rays.ray(2.5, 3.5),
                rays.ray_through_lens(2.5, 3.5, 0.9, 0.1),
            );
            assert_eq!(
                (a.origin, a.dir, a.tmin, a.tmax),
                (b.origin, b.dir, b.tmin, b.tmax)
            );
        }
        assert_eq!(
            CameraRays::new(&camera(Projection::Perspective, 2.0, 5.0), 8, 6).lens_dims(),
            2
        );
    }

    #[test]
    fn concentric_disk_stays_in_the_disk_and_reaches_its_rim() {
        for i in 0..=20 {
            for j in 0..=20 {
                let p = concentric_disk(i as f64 / 20.0, j as f64 / 20.0);
                assert!(p.length() <= 1.0 + 1e-12);
            }
        }
        assert!((concentric_disk(1.0, 0.5).length() - 1.0).abs() < 1e-12);
    }
}
