//! What moves while the camera's shutter is open. Nimbus renders every prim at the
//! scene's one time code (no motion blur), so a transform that changes within the
//! shutter interval is rendered sharp where the stage asks for a blur: a warning names
//! the prim and the xformOp that moves it.

use super::attrs::{prim_error, read_value, SceneError};
use openusd::usd::{Prim, TimeCode};
use openusd_schemas::geom::{Xformable, XformableExt};

/// The first prim, from `prim` up its ancestors (as far as its transform inherits),
/// with an xformOp whose value changes within `shutter` (frame-relative) around `time`,
/// and the name of that op. At the default time (no frame), any op with more than one
/// time sample counts: there is no frame to open the shutter around.
pub(super) fn moving_op(
    prim: &Prim,
    time: Option<TimeCode>,
    shutter: (f64, f64),
) -> Result<Option<(Prim, String)>, SceneError> {
    let mut current = Some(prim.clone());
    while let Some(p) = current.filter(|p| !p.path().is_abs_root()) {
        let err = |e: openusd::Error| prim_error(p.path(), e);
        let Some(xformable) = Xformable::from_prim(p.clone()).map_err(err)? else {
            current = p.parent();
            continue;
        };
        let (ops, resets) = xformable.ordered_xform_ops().map_err(err)?;
        for op in &ops {
            let attr = op.attribute();
            let varying = attr
                .value_might_be_time_varying()
                .map_err(|e| prim_error(p.path(), e))?;
            if varying && changes_within(&p, attr.name(), time, shutter)? {
                return Ok(Some((p.clone(), attr.name().to_string())));
            }
        }
        if resets {
            break;
        }
        current = p.parent();
    }
    Ok(None)
}

/// Whether the time-sampled attribute `name` of `prim` takes more than one value over
/// the shutter interval around `time`: at its two ends and at every sample between.
fn changes_within(
    prim: &Prim,
    name: &str,
    time: Option<TimeCode>,
    (open, close): (f64, f64),
) -> Result<bool, SceneError> {
    let Some(t) = time.map(|t| t.value()) else {
        return Ok(true);
    };
    let (t0, t1) = (t + open, t + close);
    let times = prim
        .attribute(name)
        .time_sample_times()
        .map_err(|e| prim_error(prim.path(), e))?;
    let first = read_value(prim, name, Some(TimeCode::new(t0)))?;
    for s in times.into_iter().filter(|&s| s > t0 && s < t1).chain([t1]) {
        if read_value(prim, name, Some(TimeCode::new(s)))? != first {
            return Ok(true);
        }
    }
    Ok(false)
}

/// The first of the camera's lens attributes `names` on `camera` that changes within the
/// shutter (a zoom or a focus pull during the exposure), if any.
pub(super) fn moving_attribute<'n>(
    camera: &Prim,
    names: &[&'n str],
    time: Option<TimeCode>,
    shutter: (f64, f64),
) -> Result<Option<&'n str>, SceneError> {
    for &name in names {
        let varying = camera
            .attribute(name)
            .value_might_be_time_varying()
            .map_err(|e| prim_error(camera.path(), e))?;
        if varying && changes_within(camera, name, time, shutter)? {
            return Ok(Some(name));
        }
    }
    Ok(None)
}
