//! What a stage that does not say gets, following `usdrecord`'s convention: with no
//! camera, a default camera framing the volumes; with no light, a default sun and sky.
//! Each is announced by a warning (the caller prints it), so nothing is silently made up.

use super::description::{Camera, DistantLight, DomeLight, Scene};
use glam::{DMat4, DVec3};

/// The prim path the default camera reports (no prim has it: it is not on the stage).
pub const DEFAULT_CAMERA: &str = "(default camera)";

/// USD's default camera lens: 50 mm on a 20.955 × 15.2908 mm aperture (UsdGeomCamera's
/// schema fallbacks).
const FOCAL_LENGTH: f64 = 50.0;
const HORIZONTAL_APERTURE: f64 = 20.955;

/// A camera to be placed by [`frame_box`] once the volumes' bounds are known.
pub fn placeholder_camera() -> Camera {
    Camera {
        prim_path: DEFAULT_CAMERA.into(),
        camera_to_world: DMat4::IDENTITY,
        focal_length: FOCAL_LENGTH,
        horizontal_aperture: HORIZONTAL_APERTURE,
        vertical_aperture: HORIZONTAL_APERTURE * 0.75,
        horizontal_aperture_offset: 0.0,
        vertical_aperture_offset: 0.0,
        clipping_range: (0.1, 1e6),
        projection: Default::default(),
        f_stop: 0.0,
        focus_distance: 0.0,
        shutter: None,
        motion: None,
    }
}

/// The default camera for an image of `aspect` = width / height: looking down −Z (+Y
/// up) at the centre of the world box `lo..hi`, far enough back that the box's bounding
/// sphere fits the narrower field of view with a 10 % margin, the clipping range
/// bracketing the sphere.
pub fn frame_box(lo: DVec3, hi: DVec3, aspect: f64) -> Camera {
    let mut c = placeholder_camera();
    c.vertical_aperture = c.horizontal_aperture / aspect.max(1e-6);
    let centre = 0.5 * (lo + hi);
    let radius = (0.5 * (hi - lo).length()).max(1e-6);
    let narrow = c.horizontal_aperture.min(c.vertical_aperture);
    let half_fov = (0.5 * narrow / c.focal_length).atan();
    let distance = 1.1 * radius / half_fov.sin();
    c.camera_to_world = DMat4::from_translation(centre + DVec3::new(0.0, 0.0, distance));
    c.clipping_range = (
        (distance - radius).max(distance * 1e-3) * 0.5,
        (distance + radius) * 2.0,
    );
    c
}

/// Whether the stage has no light prim at all (read by Nimbus or not) and no emissive
/// volume: only such a stage gets the default lights. A fire lit by itself stays lit by
/// itself, and a stage whose only light Nimbus cannot render is not lit by others.
pub fn wants_default_lights(scene: &Scene) -> bool {
    scene.light_prims == 0
        && scene.distant_lights.is_empty()
        && scene.dome_lights.is_empty()
        && scene.sphere_lights.is_empty()
        && scene.rect_lights.is_empty()
        && scene.disk_lights.is_empty()
        && scene.cylinder_lights.is_empty()
        && !scene.volumes.iter().any(|v| v.emission.is_emissive())
}

/// Adds the default lights: a sun of illuminance 3 from above, in front and to the
/// left of a −Z camera (warm white, UsdLux's 0.53° angle, normalized), and a blue-grey
/// sky dome of intensity 0.5.
pub fn add_default_lights(scene: &mut Scene) {
    let towards = DVec3::new(-0.5, 0.8, 0.6).normalize();
    scene.distant_lights.push(DistantLight {
        light_group: None,
        prim_path: "(default sun)".into(),
        controls: Default::default(),
        direction: towards.to_array(),
        intensity: 3.0,
        exposure: 0.0,
        color: [1.0, 0.96, 0.9],
        normalize: true,
        color_temperature: None,
        angle_degrees: 0.53,
    });
    scene.dome_lights.push(DomeLight {
        light_group: None,
        prim_path: "(default sky)".into(),
        controls: Default::default(),
        light_to_world: DMat4::IDENTITY,
        intensity: 0.5,
        exposure: 0.0,
        color: [0.55, 0.65, 0.85],
        color_temperature: None,
        texture_file: None,
        texture_format: "automatic".into(),
    });
}
