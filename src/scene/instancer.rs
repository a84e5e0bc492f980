//! UsdGeomPointInstancer: where each instance of each prototype goes.
//!
//! Instance i places prototype `protoIndices[i]` by scale, then orientation, then
//! translation (`scales`, `orientations`, `positions`), under the instancer's own
//! transform, with the prototype root's transform included (UsdGeomPointInstancer's
//! `IncludeProtoXform`, its default). Instances whose id (`ids`, else the index) is in
//! `invisibleIds` are left out. Velocities (motion blur) are not read.

use super::attrs::*;
use glam::{DMat4, DQuat, DVec3};
use openusd::sdf::{self, Value};
use openusd::usd::{Prim, TimeCode};

/// The instances of a PointInstancer: for each, its prototype (an index into
/// `prototypes`) and its transform in the instancer's space.
pub(super) struct Instances {
    pub prototypes: Vec<sdf::Path>,
    pub placed: Vec<(usize, DMat4)>,
}

/// Reads `prim`'s prototypes and instances at `time`. Bad input (arrays of other
/// lengths than `protoIndices`, an index past the prototypes, a non-finite value) is an
/// error naming the prim and attribute.
pub(super) fn instances(prim: &Prim, time: Option<TimeCode>) -> Result<Instances, SceneError> {
    let prototypes = targets(prim, "prototypes")?;
    let indices = read_int_array(prim, "protoIndices", time)?.unwrap_or_default();
    let n = indices.len();
    let positions = read_vec3_array(prim, "positions", time)?.unwrap_or_default();
    let scales = read_vec3_array(prim, "scales", time)?;
    let orientations = read_quat_array(prim, "orientations", time)?;
    let ids = read_int_array(prim, "ids", time)?;
    let invisible = read_int_array(prim, "invisibleIds", time)?.unwrap_or_default();
    let length = |name: &str, len: Option<usize>| match len {
        Some(len) if len != n => Err(prim_error(
            prim.path(),
            format!("`{name}` has {len} entries, `protoIndices` {n}: one per instance"),
        )),
        _ => Ok(()),
    };
    length("positions", Some(positions.len()))?;
    length("scales", scales.as_ref().map(Vec::len))?;
    length("orientations", orientations.as_ref().map(Vec::len))?;
    length("ids", ids.as_ref().map(Vec::len))?;
    let mut placed = Vec::with_capacity(n);
    for (i, &proto) in indices.iter().enumerate() {
        let id = ids.as_ref().map_or(i as i64, |ids| ids[i]);
        if invisible.contains(&id) {
            continue;
        }
        let proto = usize::try_from(proto)
            .ok()
            .filter(|&p| p < prototypes.len());
        let Some(proto) = proto else {
            return Err(prim_error(
                prim.path(),
                format!(
                    "protoIndices[{i}] = {} is not one of its {} prototypes",
                    indices[i],
                    prototypes.len()
                ),
            ));
        };
        let scale = scales
            .as_ref()
            .map_or(DVec3::ONE, |s| DVec3::from_array(s[i]));
        let rotation = orientations.as_ref().map_or(DQuat::IDENTITY, |q| q[i]);
        let m = DMat4::from_scale_rotation_translation(
            scale,
            rotation,
            DVec3::from_array(positions[i]),
        );
        if !m.is_finite() {
            return Err(prim_error(
                prim.path(),
                format!(
                    "instance {i}'s transform is not finite (positions, scales or orientations)"
                ),
            ));
        }
        placed.push((proto, m));
    }
    Ok(Instances { prototypes, placed })
}

/// A quaternion array (`quath[]`, `quatf[]`, `quatd[]`), normalised (a zero one is the
/// identity, as UsdGeomPointInstancer reads it).
fn read_quat_array(
    prim: &Prim,
    name: &str,
    time: Option<TimeCode>,
) -> Result<Option<Vec<DQuat>>, SceneError> {
    let Some(value) = read_value(prim, name, time)? else {
        return Ok(None);
    };
    let q = |w: f64, x: f64, y: f64, z: f64| {
        let q = DQuat::from_xyzw(x, y, z, w);
        if q.length_squared() > 0.0 {
            q.normalize()
        } else {
            DQuat::IDENTITY
        }
    };
    let f = |h: half::f16| f64::from(h.to_f32());
    Ok(Some(match value {
        Value::QuathVec(v) => v
            .into_iter()
            .map(|p| q(f(p.w), f(p.x), f(p.y), f(p.z)))
            .collect(),
        Value::QuatfVec(v) => v
            .into_iter()
            .map(|p| q(p.w.into(), p.x.into(), p.y.into(), p.z.into()))
            .collect(),
        Value::QuatdVec(v) => v.into_iter().map(|p| q(p.w, p.x, p.y, p.z)).collect(),
        other => return Err(wrong_type(prim, name, "a quaternion array", &other)),
    }))
}
