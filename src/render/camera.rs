//! Primary rays from a UsdGeomCamera (pinhole; the aperture is conformed to the image
//! aspect with USD's default "expandAperture" policy).

use crate::scene::Camera;
use glam::{DMat4, DVec3};

pub struct CameraRays {
    camera_to_world: DMat4,
    focal: f64,
    aperture: (f64, f64),
    offset: (f64, f64),
    near: f64,
    far: f64,
    width: u32,
    height: u32,
}

/// A primary ray: unit world direction, and the distance range inside the clipping planes.
pub struct PrimaryRay {
    pub origin: DVec3,
    pub dir: DVec3,
    pub tmin: f64,
    pub tmax: f64,
    /// Camera depth per unit distance along the ray: the cosine between `dir` and the
    /// camera's view axis (world −Z of the camera), so depth = t · `depth_per_t`.
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
        CameraRays {
            camera_to_world: cam.camera_to_world,
            focal: cam.focal_length,
            aperture: (h, v),
            offset: (cam.horizontal_aperture_offset, cam.vertical_aperture_offset),
            near: cam.clipping_range.0,
            far: cam.clipping_range.1,
            width,
            height,
        }
    }

    /// The ray through image position (`px + jx`, `py + jy`), y down.
    pub fn ray(&self, px: f64, py: f64) -> PrimaryRay {
        let sx = px / self.width as f64 - 0.5;
        let sy = 0.5 - py / self.height as f64;
        let d_cam = DVec3::new(
            sx * self.aperture.0 + self.offset.0,
            sy * self.aperture.1 + self.offset.1,
            -self.focal,
        );
        let origin = self.camera_to_world.transform_point3(DVec3::ZERO);
        let d_world = self.camera_to_world.transform_vector3(d_cam);
        let len = d_world.length();
        // Clipping planes are depths along the camera's −Z: the point at depth z lies at
        // parameter z/focal along d_cam, i.e. world distance (z/focal)·|d_world|.
        let dir = d_world / len;
        PrimaryRay {
            origin,
            dir,
            tmin: self.near / self.focal * len,
            tmax: self.far / self.focal * len,
            depth_per_t: dir.dot(self.view_axis()),
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
