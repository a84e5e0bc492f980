//! UsdGeomCamera → [`Camera`], and a warning for each authored camera attribute that
//! changes the image and that Nimbus does not render (its exposure, stereo, extra
//! clipping planes, a projection it does not know, an fStop without a focus distance).

use super::attrs::{
    authored, missing, prim_error, read_f64, read_string, read_value, read_vec2, require_f64,
    SceneError,
};
use super::description::{Camera, Projection};
use super::diagnostics::Diagnostics;
use glam::DMat4;
use openusd::sdf::Value;
use openusd::usd::{Prim, TimeCode};

/// Reads the camera `prim` (`camera_to_world` already evaluated) at `t`, adding a
/// warning for what it asks for and the render will not show.
pub(super) fn read_camera(
    prim: &Prim,
    t: Option<TimeCode>,
    camera_to_world: DMat4,
    warnings: &mut Diagnostics,
) -> Result<Camera, SceneError> {
    let path = prim.path().to_string();
    let clip =
        read_vec2(prim, "clippingRange", t)?.ok_or_else(|| missing(prim, "clippingRange"))?;
    let projection = match read_string(prim, "projection", t)?.as_deref() {
        None | Some("perspective") => Projection::Perspective,
        Some("orthographic") => Projection::Orthographic,
        Some(other) => {
            warnings.warn(
                "camera projection",
                &path,
                Some("projection"),
                format!("projection `{other}` is not a UsdGeomCamera projection Nimbus renders (perspective, orthographic): rendered as perspective"),
            );
            Projection::Perspective
        }
    };
    let f_stop = read_f64(prim, "fStop", t)?.unwrap_or(0.0);
    let focus_distance = read_f64(prim, "focusDistance", t)?.unwrap_or(0.0);
    for (name, v) in [("fStop", f_stop), ("focusDistance", focus_distance)] {
        if !(v.is_finite() && v >= 0.0) {
            return Err(prim_error(
                prim.path(),
                format!("{name} = {v} must be finite and ≥ 0"),
            ));
        }
    }
    if f_stop > 0.0 && focus_distance == 0.0 {
        warnings.warn(
            "camera focus",
            &path,
            Some("focusDistance"),
            format!(
                "fStop = {f_stop} without a focusDistance: no depth of field (everything in focus)"
            ),
        );
    }
    unrendered_attributes(prim, t, &path, warnings)?;
    Ok(Camera {
        prim_path: path,
        camera_to_world,
        projection,
        focal_length: require_f64(prim, "focalLength", t)?,
        horizontal_aperture: require_f64(prim, "horizontalAperture", t)?,
        vertical_aperture: require_f64(prim, "verticalAperture", t)?,
        horizontal_aperture_offset: read_f64(prim, "horizontalApertureOffset", t)?.unwrap_or(0.0),
        vertical_aperture_offset: read_f64(prim, "verticalApertureOffset", t)?.unwrap_or(0.0),
        clipping_range: (clip[0], clip[1]),
        f_stop,
        focus_distance,
        shutter: None,
        motion: None,
    })
}

/// Camera attributes that change a render and that Nimbus leaves out, with the value
/// that changes nothing (UsdGeomCamera's fallback): each authored otherwise warns.
const EXPOSURE_ATTRIBUTES: [(&str, f64); 5] = [
    ("exposure", 0.0),
    ("exposure:iso", 100.0),
    ("exposure:time", 1.0),
    ("exposure:fStop", 1.0),
    ("exposure:responsivity", 1.0),
];

fn unrendered_attributes(
    prim: &Prim,
    t: Option<TimeCode>,
    path: &str,
    warnings: &mut Diagnostics,
) -> Result<(), SceneError> {
    for (name, neutral) in EXPOSURE_ATTRIBUTES {
        if !authored(&prim.attribute(name), prim)? {
            continue;
        }
        if let Some(v) = read_f64(prim, name, t)? {
            if v != neutral {
                warnings.warn(
                    "camera exposure",
                    path,
                    Some(name),
                    format!("{name} = {v} is not applied: the image is rendered at the exposure of {name} = {neutral}"),
                );
            }
        }
    }
    if let Some(role) = read_string(prim, "stereoRole", t)? {
        if role != "mono" {
            warnings.warn(
                "camera stereo",
                path,
                Some("stereoRole"),
                format!("stereoRole `{role}`: Nimbus renders this camera as a mono camera (no eye offset)"),
            );
        }
    }
    if let Some(planes) = read_value(prim, "clippingPlanes", t)? {
        let count = match &planes {
            Value::Vec4fVec(v) => v.len(),
            Value::Vec4dVec(v) => v.len(),
            _ => 0,
        };
        if count > 0 {
            warnings.warn(
                "camera clipping planes",
                path,
                Some("clippingPlanes"),
                format!("{count} clipping plane(s) are not applied: only clippingRange clips camera rays"),
            );
        }
    }
    Ok(())
}

/// The camera's shutter interval (`shutter:open`, `shutter:close`, frame-relative),
/// when it is open for a while (open < close): a render through it would show motion.
pub(super) fn shutter(prim: &Prim, t: Option<TimeCode>) -> Result<Option<(f64, f64)>, SceneError> {
    let open = read_f64(prim, "shutter:open", t)?.unwrap_or(0.0);
    let close = read_f64(prim, "shutter:close", t)?.unwrap_or(0.0);
    Ok((open < close).then_some((open, close)))
}
