//! Attribute, relationship and asset reads on prims, and the errors the stage loader
//! reports: the helpers `stage` (the loader), `lights` and `shading` share. Reads go
//! through `sdf::Value` and accept every numeric precision an author might have used.

use crate::volume::asset::AssetLocation;
use glam::DMat4;
use openusd::gf;
use openusd::sdf::{self, Value};
use openusd::usd::{self, Prim, TimeCode};
use std::fmt::Display;
use std::io::Read;
use std::path::{Path, PathBuf};
use std::sync::Arc;

#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    /// The stage as a whole could not be opened or composed.
    #[error("{path}: {message}")]
    Stage { path: String, message: String },
    /// One prim is malformed or refers to something that does not exist.
    #[error("{prim}: {message}")]
    Prim { prim: String, message: String },
}

/// `error` and every `source()` under it, so the detail (a parse position, the
/// file that failed) is not lost behind a generic top-level message.
pub(super) fn error_chain(error: &dyn std::error::Error) -> String {
    let mut text = error.to_string();
    let mut source = error.source();
    while let Some(cause) = source {
        let cause_text = cause.to_string();
        if !text.contains(&cause_text) {
            text.push_str(": ");
            text.push_str(&cause_text);
        }
        source = cause.source();
    }
    text
}

pub(super) fn stage_error(path: &Path, message: impl Display) -> SceneError {
    SceneError::Stage {
        path: path.display().to_string(),
        message: message.to_string(),
    }
}

pub(super) fn prim_error(prim: &sdf::Path, message: impl Display) -> SceneError {
    SceneError::Prim {
        prim: prim.to_string(),
        message: message.to_string(),
    }
}

pub(super) fn prim_error_str(prim: &str, message: impl Display) -> SceneError {
    SceneError::Prim {
        prim: prim.to_string(),
        message: message.to_string(),
    }
}

/// A field without a file at `time`. A frame sequence is authored as time samples
/// only (as Houdini and EmberGen exports do), which USD does not consult at the default
/// time: say so, since "not authored" would be misleading.
pub(super) fn unauthored_file_path(prim: &Prim, time: Option<TimeCode>) -> SceneError {
    let times = prim
        .attribute("filePath")
        .time_sample_times()
        .unwrap_or_default();
    match (time, times.first(), times.last()) {
        (None, Some(first), Some(last)) => prim_error(
            prim.path(),
            format!(
                "filePath has only time samples ({} of them, frames {first} to {last}) and no \
                 default value; render with --frame or --frames",
                times.len()
            ),
        ),
        _ => prim_error(prim.path(), "filePath is not authored"),
    }
}

pub(super) fn is_valid(prim: &Prim) -> Result<bool, SceneError> {
    prim.is_valid().map_err(|e| prim_error(prim.path(), e))
}

pub(super) fn missing(prim: &Prim, attr: &str) -> SceneError {
    prim_error(
        prim.path(),
        format!("`{attr}` has no value (and no schema fallback)"),
    )
}

pub(super) fn to_u32(prim: &Prim, attr: &str, v: i64) -> Result<u32, SceneError> {
    u32::try_from(v).map_err(|_| prim_error(prim.path(), format!("`{attr}` = {v} is out of range")))
}

/// Converts openusd's row-major, row-vector matrix (p' = p·M) into a glam
/// column-vector matrix (p' = M·p), which is its transpose. Reading the
/// row-major array as column-major *is* that transpose.
pub(crate) fn to_dmat4(m: &gf::Matrix4d) -> DMat4 {
    DMat4::from_cols_array(&m.0)
}

// ----- relationships -------------------------------------------------------------

pub(super) fn targets(prim: &Prim, rel: &str) -> Result<Vec<sdf::Path>, SceneError> {
    let rel = prim.relationship(rel);
    rel.targets().map_err(|e| prim_error(rel.path(), e))
}

pub(super) fn first_target(prim: &Prim, rel: &str) -> Result<Option<sdf::Path>, SceneError> {
    Ok(targets(prim, rel)?.into_iter().next())
}

// ----- typed attribute reads ---------------------------------------------------------
//
// Reads go through `sdf::Value` and accept every numeric precision an author
// might have used (float, double, half), since stages in the wild are not
// consistent about it. `None` means neither an opinion nor a schema fallback.

pub(super) fn authored(attr: &usd::Attribute, prim: &Prim) -> Result<bool, SceneError> {
    attr.has_authored_value()
        .map_err(|e| prim_error(prim.path(), format!("{}: {e}", attr.name())))
}

/// `read()` when `name` has an authored opinion on `prim`, else `None` (also for a
/// property with a schema fallback).
pub(super) fn if_authored<T>(
    prim: &Prim,
    name: &str,
    read: impl FnOnce() -> Result<Option<T>, SceneError>,
) -> Result<Option<T>, SceneError> {
    if authored(&prim.attribute(name), prim)? {
        read()
    } else {
        Ok(None)
    }
}

pub(super) fn read_value(
    prim: &Prim,
    name: &str,
    time: Option<TimeCode>,
) -> Result<Option<Value>, SceneError> {
    prim.attribute(name)
        .get_at::<Value>(time)
        .map_err(|e| prim_error(prim.path(), format!("cannot read `{name}`: {e}")))
}

pub(super) fn wrong_type(prim: &Prim, name: &str, expected: &str, value: &Value) -> SceneError {
    prim_error(
        prim.path(),
        format!("`{name}` should be {expected}, found {value:?}"),
    )
}

pub(super) fn read_f64(
    prim: &Prim,
    name: &str,
    time: Option<TimeCode>,
) -> Result<Option<f64>, SceneError> {
    let Some(value) = read_value(prim, name, time)? else {
        return Ok(None);
    };
    match value {
        Value::Float(v) => Ok(Some(f64::from(v))),
        Value::Double(v) => Ok(Some(v)),
        Value::Half(v) => Ok(Some(f64::from(v))),
        Value::Int(v) => Ok(Some(f64::from(v))),
        other => Err(wrong_type(prim, name, "a number", &other)),
    }
}

pub(super) fn require_f64(
    prim: &Prim,
    name: &str,
    time: Option<TimeCode>,
) -> Result<f64, SceneError> {
    read_f64(prim, name, time)?.ok_or_else(|| missing(prim, name))
}

pub(super) fn read_i64(
    prim: &Prim,
    name: &str,
    time: Option<TimeCode>,
) -> Result<Option<i64>, SceneError> {
    let Some(value) = read_value(prim, name, time)? else {
        return Ok(None);
    };
    match value {
        Value::Int(v) => Ok(Some(i64::from(v))),
        Value::Int64(v) => Ok(Some(v)),
        Value::Uint(v) => Ok(Some(i64::from(v))),
        Value::Uint64(v) => i64::try_from(v)
            .map(Some)
            .map_err(|_| wrong_type(prim, name, "an int", &value)),
        Value::Uchar(v) => Ok(Some(i64::from(v))),
        other => Err(wrong_type(prim, name, "an int", &other)),
    }
}

pub(super) fn read_vec3(
    prim: &Prim,
    name: &str,
    time: Option<TimeCode>,
) -> Result<Option<[f64; 3]>, SceneError> {
    let Some(value) = read_value(prim, name, time)? else {
        return Ok(None);
    };
    match value {
        Value::Vec3f(v) => Ok(Some([v.x, v.y, v.z].map(f64::from))),
        Value::Vec3d(v) => Ok(Some([v.x, v.y, v.z])),
        Value::Vec3h(v) => Ok(Some([v.x, v.y, v.z].map(f64::from))),
        other => Err(wrong_type(prim, name, "a 3-vector/colour", &other)),
    }
}

pub(super) fn read_vec2(
    prim: &Prim,
    name: &str,
    time: Option<TimeCode>,
) -> Result<Option<[f64; 2]>, SceneError> {
    let Some(value) = read_value(prim, name, time)? else {
        return Ok(None);
    };
    match value {
        Value::Vec2f(v) => Ok(Some([v.x, v.y].map(f64::from))),
        Value::Vec2d(v) => Ok(Some([v.x, v.y])),
        Value::Vec2h(v) => Ok(Some([v.x, v.y].map(f64::from))),
        other => Err(wrong_type(prim, name, "a 2-vector", &other)),
    }
}

pub(super) fn read_int2(
    prim: &Prim,
    name: &str,
    time: Option<TimeCode>,
) -> Result<Option<[i64; 2]>, SceneError> {
    let Some(value) = read_value(prim, name, time)? else {
        return Ok(None);
    };
    match value {
        Value::Vec2i(v) => Ok(Some([i64::from(v.x), i64::from(v.y)])),
        other => Err(wrong_type(prim, name, "an int2", &other)),
    }
}

pub(super) fn read_string(
    prim: &Prim,
    name: &str,
    time: Option<TimeCode>,
) -> Result<Option<String>, SceneError> {
    let Some(value) = read_value(prim, name, time)? else {
        return Ok(None);
    };
    match value {
        Value::Token(t) => Ok(Some(t.to_string())),
        Value::String(s) => Ok(Some(s)),
        other => Err(wrong_type(prim, name, "a token or string", &other)),
    }
}

pub(super) fn read_asset(
    prim: &Prim,
    name: &str,
    time: Option<TimeCode>,
) -> Result<Option<sdf::AssetPath>, SceneError> {
    let Some(value) = read_value(prim, name, time)? else {
        return Ok(None);
    };
    match value {
        Value::AssetPath(a) => Ok(Some(a)),
        other => Err(wrong_type(prim, name, "an asset path", &other)),
    }
}

pub(super) fn read_bool(
    prim: &Prim,
    name: &str,
    time: Option<TimeCode>,
) -> Result<Option<bool>, SceneError> {
    let Some(value) = read_value(prim, name, time)? else {
        return Ok(None);
    };
    match value {
        Value::Bool(b) => Ok(Some(b)),
        other => Err(wrong_type(prim, name, "a bool", &other)),
    }
}

/// An int array (`int[]`, or any integer width an author used); `None` when unauthored
/// with no fallback.
pub(super) fn read_int_array(
    prim: &Prim,
    name: &str,
    time: Option<TimeCode>,
) -> Result<Option<Vec<i64>>, SceneError> {
    let Some(value) = read_value(prim, name, time)? else {
        return Ok(None);
    };
    let widen = |v: Vec<i64>| Ok(Some(v));
    match value {
        Value::IntVec(v) => widen(v.into_iter().map(i64::from).collect()),
        Value::Int64Vec(v) => widen(v),
        Value::UintVec(v) => widen(v.into_iter().map(i64::from).collect()),
        Value::UcharVec(v) => widen(v.into_iter().map(i64::from).collect()),
        // Values past i64::MAX are out of range for any index; saturate so the
        // range check reports them.
        Value::Uint64Vec(v) => widen(
            v.into_iter()
                .map(|x| i64::try_from(x).unwrap_or(i64::MAX))
                .collect(),
        ),
        other => Err(wrong_type(prim, name, "an int array", &other)),
    }
}

/// A 3-vector array (`point3f[]`, `double3[]`, `half3[]`, …), widened to f64.
pub(super) fn read_vec3_array(
    prim: &Prim,
    name: &str,
    time: Option<TimeCode>,
) -> Result<Option<Vec<[f64; 3]>>, SceneError> {
    let Some(value) = read_value(prim, name, time)? else {
        return Ok(None);
    };
    match value {
        Value::Vec3fVec(v) => Ok(Some(
            v.into_iter()
                .map(|p| [p.x, p.y, p.z].map(f64::from))
                .collect(),
        )),
        Value::Vec3dVec(v) => Ok(Some(v.into_iter().map(|p| [p.x, p.y, p.z]).collect())),
        Value::Vec3hVec(v) => Ok(Some(
            v.into_iter()
                .map(|p| [p.x, p.y, p.z].map(f64::from))
                .collect(),
        )),
        other => Err(wrong_type(prim, name, "a 3-vector array", &other)),
    }
}

// ----- assets ----------------------------------------------------------------------------

/// Where a field's file is. openusd resolves the asset path against the layer
/// that authored it during value resolution; a path inside a .usdz resolves to
/// the package-relative form `pkg.usdz[member]`, whose bytes are read here
/// through the resolver (the renderer cannot open them as a file).
pub(super) fn asset_location(
    prim: &Prim,
    asset: &sdf::AssetPath,
) -> Result<AssetLocation, SceneError> {
    let authored = &asset.authored_path;
    let resolved = match asset.resolved_path().filter(|r| !r.is_empty()) {
        Some(resolved) => resolved.to_string(),
        None => {
            resolve_from_package_root(&prim.attribute("filePath"), authored).ok_or_else(|| {
                prim_error(
                    prim.path(),
                    format!("filePath @{authored}@ does not resolve to an existing file"),
                )
            })?
        }
    };
    let resolved = resolved.as_str();
    if !openusd::ar::is_package_relative_path(resolved) {
        return Ok(AssetLocation::File(PathBuf::from(resolved)));
    }
    let (package, member) = openusd::ar::split_package_relative_path_outer(resolved)
        .ok_or_else(|| prim_error(prim.path(), format!("malformed package path {resolved}")))?;
    let bytes = read_packaged(resolved).map_err(|e| {
        prim_error(
            prim.path(),
            format!("cannot read @{authored}@ from {resolved}: {e}"),
        )
    })?;
    Ok(AssetLocation::Packaged {
        package: PathBuf::from(package),
        member,
        bytes: Arc::new(bytes),
    })
}

/// pxr's Ar treats a relative path without a leading `./` or `../` as a search
/// path: when it does not resolve next to the authoring layer and that layer is
/// inside a package, it is looked up from the package root. UsdUtils'
/// usdz packager relies on this (it rewrites some dependencies to `0/file.vdb`
/// inside a layer in a subdirectory); openusd 0.8 only anchors to the layer, so
/// the lookup is retried here for the package of each layer with an opinion.
pub(super) fn resolve_from_package_root(attr: &usd::Attribute, authored: &str) -> Option<String> {
    use openusd::ar::Resolver;
    let search_path_style = !authored.is_empty()
        && !authored.starts_with("./")
        && !authored.starts_with("../")
        && !Path::new(authored).is_absolute()
        && !openusd::ar::is_package_relative_path(authored);
    if !search_path_style {
        return None;
    }
    let resolver = openusd::ar::DefaultResolver::new();
    let sites = attr.property_stack().ok()?;
    sites.iter().find_map(|site| {
        let package = package_of_layer(&site.layer)?;
        let candidate = openusd::ar::join_package_relative_path(&package, authored);
        resolver
            .resolve(&candidate)
            .map(|r| r.to_string_lossy().into_owned())
    })
}

/// The outermost package a layer identifier lives in (or is), if any.
pub(super) fn package_of_layer(layer: &str) -> Option<String> {
    if openusd::ar::is_package_relative_path(layer) {
        return openusd::ar::split_package_relative_path_outer(layer).map(|(package, _)| package);
    }
    layer
        .to_ascii_lowercase()
        .ends_with(".usdz")
        .then(|| layer.to_string())
}

pub(super) fn read_packaged(resolved: &str) -> std::io::Result<Vec<u8>> {
    use openusd::ar::Resolver;
    let resolver = openusd::ar::DefaultResolver::new();
    let mut asset = resolver.open_asset(&openusd::ar::ResolvedPath::new(resolved))?;
    let mut bytes = Vec::new();
    asset.read_to_end(&mut bytes)?;
    Ok(bytes)
}

/// The shader prim and property a connection source path names.
pub(super) fn split_property(path: &sdf::Path) -> (sdf::Path, String) {
    let prim = path.prim_path();
    let full = path.as_str();
    let property = full
        .strip_prefix(prim.as_str())
        .and_then(|rest| rest.strip_prefix('.'))
        .unwrap_or_default()
        .to_string();
    (prim, property)
}

pub(super) fn shader_id(shader: &Prim) -> Result<String, SceneError> {
    Ok(read_string(shader, "info:id", None)?.unwrap_or_default())
}
