//! What moves while the camera's shutter is open. The camera's and the volumes'
//! transforms are sampled over the shutter ([`transform_motion`]) and blurred; any
//! other prim is rendered at the scene's one time code, so a transform of it that
//! changes within the shutter is rendered sharp where the stage asks for a blur: a
//! warning names the prim and the xformOp that moves it.

use super::attrs::{prim_error, read_value, to_dmat4, SceneError};
use crate::motion::TransformMotion;
use openusd::usd::{Prim, TimeCode};
use openusd_schemas::geom::{self, Xformable, XformableExt};

/// Every xformOp `prim`'s world transform depends on: each prim from `prim` up its
/// ancestors (as far as its transform inherits: a `!resetXformStack!` stops it), with
/// the names of its ops.
fn inherited_ops(prim: &Prim) -> Result<Vec<(Prim, Vec<String>)>, SceneError> {
    let mut out = Vec::new();
    let mut current = Some(prim.clone());
    while let Some(p) = current.filter(|p| !p.path().is_abs_root()) {
        let err = |e: openusd::Error| prim_error(p.path(), e);
        if let Some(xformable) = Xformable::from_prim(p.clone()).map_err(err)? {
            let (ops, resets) = xformable.ordered_xform_ops().map_err(err)?;
            let names = ops.iter().map(|op| op.attribute().name().to_string());
            out.push((p.clone(), names.collect()));
            if resets {
                break;
            }
        }
        current = p.parent();
    }
    Ok(out)
}

/// The first prim, from `prim` up its ancestors (as far as its transform inherits),
/// with an xformOp whose value changes within `shutter` (frame-relative) around `time`,
/// and the name of that op. At the default time (no frame), any op with more than one
/// time sample counts: there is no frame to open the shutter around.
pub(super) fn moving_op(
    prim: &Prim,
    time: Option<TimeCode>,
    shutter: (f64, f64),
) -> Result<Option<(Prim, String)>, SceneError> {
    for (p, ops) in inherited_ops(prim)? {
        for name in ops {
            let varying = p
                .attribute(&name)
                .value_might_be_time_varying()
                .map_err(|e| prim_error(p.path(), e))?;
            if varying && changes_within(&p, &name, time, shutter)? {
                return Ok(Some((p, name)));
            }
        }
    }
    Ok(None)
}

/// The local → world transform of `prim` over the shutter around the frame `time`
/// (frame-relative keys), as UsdGeomXformable interpolates its ops' time samples:
/// `None` when nothing above it moves within the shutter.
pub(super) fn transform_motion(
    prim: &Prim,
    time: TimeCode,
    (open, close): (f64, f64),
) -> Result<Option<TransformMotion>, SceneError> {
    let frame = time.value();
    let mut authored = Vec::new();
    for (p, ops) in inherited_ops(prim)? {
        for name in ops {
            let times = p
                .attribute(&name)
                .time_sample_times()
                .map_err(|e| prim_error(p.path(), e))?;
            authored.extend(times.into_iter().map(|t| t - frame));
        }
    }
    authored.sort_by(f64::total_cmp);
    let at = |t: f64| -> Result<glam::DMat4, String> {
        let mut cache = geom::XformCache::new(Some(TimeCode::new(frame + t)));
        let m = cache
            .local_to_world_transform(prim)
            .map_err(|e| format!("cannot compute its transform at time {}: {e}", frame + t))?;
        let m = to_dmat4(&m);
        match m.is_finite() {
            true => Ok(m),
            false => Err(format!(
                "its world transform at time {} is not finite (a NaN or infinite value in its xformOps or an ancestor's)",
                frame + t
            )),
        }
    };
    TransformMotion::sample(open, close, &authored, at).map_err(|e| prim_error(prim.path(), e))
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
