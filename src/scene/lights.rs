//! UsdLux lights → plain [`Scene`](super::Scene) light types.
//!
//! Kept apart from `stage.rs` (which finds the prims and evaluates their world
//! transforms) so light reading is one concept in one place. Every property reads
//! its UsdLux schema fallback when unauthored (the registry knows UsdLux), so the
//! `unwrap_or` values below only matter for stages the registry cannot type.

use super::attrs::{
    authored, prim_error, read_asset, read_f64, read_string, read_value, read_vec3, wrong_type,
    SceneError,
};
use super::description::{DistantLight, DomeLight, RectLight, SphereLight};
use super::schema::tokens;
use glam::{DMat4, DVec3};
use openusd::sdf::Value;
use openusd::usd::{Prim, TimeCode};

/// Schema type names of the lights Nimbus reads.
const DISTANT_LIGHT: &str = "DistantLight";
const DOME_LIGHT: &str = "DomeLight";
const SPHERE_LIGHT: &str = "SphereLight";
const RECT_LIGHT: &str = "RectLight";

/// The lights of a stage, by type.
#[derive(Default)]
pub(super) struct StageLights {
    pub distant: Vec<DistantLight>,
    pub dome: Vec<DomeLight>,
    pub sphere: Vec<SphereLight>,
    pub rect: Vec<RectLight>,
}

/// Whether `prim` is a light type Nimbus reads.
pub(super) fn is_light(prim: &Prim) -> Result<bool, openusd::Error> {
    for ty in [DISTANT_LIGHT, DOME_LIGHT, SPHERE_LIGHT, RECT_LIGHT] {
        if prim.is_a(ty)? {
            return Ok(true);
        }
    }
    Ok(false)
}

/// UsdLux's light base classes and the API schemas that make any prim a light: a prim
/// matching one is a light to its author, whether or not Nimbus renders it.
const LIGHT_BASES: [&str; 3] = ["BoundableLightBase", "NonboundableLightBase", "PluginLight"];
// The specific APIs first: each includes LightAPI.
const LIGHT_APIS: [&str; 3] = ["MeshLightAPI", "VolumeLightAPI", "LightAPI"];

/// Whether `prim` is a light of any kind (read by Nimbus or not): a stage with one gets
/// no default lights.
pub(super) fn is_any_light(prim: &Prim) -> Result<bool, openusd::Error> {
    Ok(is_light_type(prim)? || light_api(prim)?.is_some())
}

/// Whether `prim`'s type is a UsdLux light (of any kind, read or not).
pub(super) fn is_light_type(prim: &Prim) -> Result<bool, openusd::Error> {
    for ty in LIGHT_BASES {
        if prim.is_a(ty)? {
            return Ok(true);
        }
    }
    Ok(false)
}

/// The light API schema applied to `prim`, if any.
pub(super) fn light_api(prim: &Prim) -> Result<Option<&'static str>, openusd::Error> {
    for api in LIGHT_APIS {
        if prim.has_api_schema(api)? {
            return Ok(Some(api));
        }
    }
    Ok(None)
}

/// Reads every (visible) light prim, given with its local → world transform.
pub(super) fn read_lights(
    prims: &[(Prim, DMat4)],
    time: Option<TimeCode>,
) -> Result<StageLights, SceneError> {
    let mut lights = StageLights::default();
    for (prim, to_world) in prims {
        let is = |ty: &str| prim.is_a(ty).map_err(|e| prim_error(prim.path(), e));
        if is(DISTANT_LIGHT)? {
            lights.distant.push(distant_light(prim, time, to_world)?);
        } else if is(DOME_LIGHT)? {
            lights.dome.push(dome_light(prim, time, to_world)?);
        } else if is(SPHERE_LIGHT)? {
            lights.sphere.push(sphere_light(prim, time, to_world)?);
        } else if is(RECT_LIGHT)? {
            lights.rect.push(rect_light(prim, time, to_world)?);
        }
    }
    Ok(lights)
}

/// The LightAPI inputs every light has.
struct Common {
    intensity: f64,
    exposure: f64,
    color: [f64; 3],
    normalize: bool,
    color_temperature: Option<f64>,
    light_group: Option<String>,
}

fn common(prim: &Prim, t: Option<TimeCode>, intensity_fallback: f64) -> Result<Common, SceneError> {
    let enable_temperature = read_bool(prim, "inputs:enableColorTemperature", t)?.unwrap_or(false);
    let color_temperature = match enable_temperature {
        true => Some(read_f64(prim, "inputs:colorTemperature", t)?.unwrap_or(6500.0)),
        false => None,
    };
    Ok(Common {
        intensity: read_f64(prim, "inputs:intensity", t)?.unwrap_or(intensity_fallback),
        exposure: read_f64(prim, "inputs:exposure", t)?.unwrap_or(0.0),
        color: read_vec3(prim, "inputs:color", t)?.unwrap_or([1.0; 3]),
        normalize: read_bool(prim, "inputs:normalize", t)?.unwrap_or(false),
        color_temperature,
        light_group: read_string(prim, tokens::LIGHT_GROUP, t)?.filter(|g| !g.is_empty()),
    })
}

fn distant_light(
    prim: &Prim,
    t: Option<TimeCode>,
    to_world: &DMat4,
) -> Result<DistantLight, SceneError> {
    // The light emits along its local −Z, so the direction towards it is +Z.
    let z = to_world.transform_vector3(DVec3::Z);
    let direction = z
        .try_normalize()
        .ok_or_else(|| prim_error(prim.path(), "degenerate transform (zero Z axis)"))?;
    let c = common(prim, t, 50000.0)?;
    Ok(DistantLight {
        prim_path: prim.path().to_string(),
        light_group: c.light_group,
        direction: direction.to_array(),
        intensity: c.intensity,
        exposure: c.exposure,
        color: c.color,
        normalize: c.normalize,
        color_temperature: c.color_temperature,
        angle_degrees: read_f64(prim, "inputs:angle", t)?.unwrap_or(0.53),
    })
}

fn dome_light(prim: &Prim, t: Option<TimeCode>, to_world: &DMat4) -> Result<DomeLight, SceneError> {
    let texture = prim.attribute("inputs:texture:file");
    let texture_file = match authored(&texture, prim)? {
        true => read_asset(prim, "inputs:texture:file", t)?
            .filter(|a| !a.authored_path.is_empty())
            .map(|a| {
                a.resolved_path()
                    .filter(|r| !r.is_empty())
                    .unwrap_or(a.authored_path.as_str())
                    .to_string()
            }),
        false => None,
    };
    let c = common(prim, t, 1.0)?;
    Ok(DomeLight {
        prim_path: prim.path().to_string(),
        light_group: c.light_group,
        light_to_world: *to_world,
        intensity: c.intensity,
        exposure: c.exposure,
        color: c.color,
        color_temperature: c.color_temperature,
        texture_file,
        texture_format: read_string(prim, "inputs:texture:format", t)?
            .unwrap_or_else(|| "automatic".to_string()),
    })
}

fn sphere_light(
    prim: &Prim,
    t: Option<TimeCode>,
    to_world: &DMat4,
) -> Result<SphereLight, SceneError> {
    let c = common(prim, t, 1.0)?;
    let radius = read_f64(prim, "inputs:radius", t)?.unwrap_or(0.5);
    if !(radius >= 0.0 && radius.is_finite()) {
        return Err(prim_error(
            prim.path(),
            format!("inputs:radius = {radius} must be finite and ≥ 0"),
        ));
    }
    Ok(SphereLight {
        prim_path: prim.path().to_string(),
        light_group: c.light_group,
        light_to_world: *to_world,
        intensity: c.intensity,
        exposure: c.exposure,
        color: c.color,
        normalize: c.normalize,
        color_temperature: c.color_temperature,
        radius,
        treat_as_point: read_bool(prim, "treatAsPoint", t)?.unwrap_or(false),
    })
}

fn rect_light(prim: &Prim, t: Option<TimeCode>, to_world: &DMat4) -> Result<RectLight, SceneError> {
    let c = common(prim, t, 1.0)?;
    let width = read_f64(prim, "inputs:width", t)?.unwrap_or(1.0);
    let height = read_f64(prim, "inputs:height", t)?.unwrap_or(1.0);
    if !(width >= 0.0 && height >= 0.0 && width.is_finite() && height.is_finite()) {
        return Err(prim_error(
            prim.path(),
            format!("inputs:width = {width}, inputs:height = {height} must be finite and ≥ 0"),
        ));
    }
    let texture = prim.attribute("inputs:texture:file");
    if authored(&texture, prim)? {
        return Err(prim_error(
            prim.path(),
            "RectLight inputs:texture:file is not supported (only constant-colour rect lights)",
        ));
    }
    Ok(RectLight {
        prim_path: prim.path().to_string(),
        light_group: c.light_group,
        light_to_world: *to_world,
        intensity: c.intensity,
        exposure: c.exposure,
        color: c.color,
        normalize: c.normalize,
        color_temperature: c.color_temperature,
        width,
        height,
    })
}

fn read_bool(prim: &Prim, name: &str, time: Option<TimeCode>) -> Result<Option<bool>, SceneError> {
    let Some(value) = read_value(prim, name, time)? else {
        return Ok(None);
    };
    match value {
        Value::Bool(b) => Ok(Some(b)),
        Value::Int(v) => Ok(Some(v != 0)),
        other => Err(wrong_type(prim, name, "a bool", &other)),
    }
}
