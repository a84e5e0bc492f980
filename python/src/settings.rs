//! `render`'s keyword arguments as the library's settings: choice names, the region,
//! and the AOVs and split layers asked for. Each check raises `SettingsError` with the
//! message the CLI gives for the same flag, before any stage is read.

use crate::errors::{guarded, SettingsError};
use nimbus::output::products::requested_outputs;
use nimbus::render::film::{Aov, Region};
use nimbus::render::session::Session;
use nimbus::render::splits::SplitLayer;
use nimbus::track::select::{Choice, TrackerKind};
use pyo3::prelude::*;

/// A choice given by name (`sampler`, `scheme`, `transmittance`); None leaves it to
/// the stage.
pub fn parse_choice<K: Choice>(what: &str, v: Option<String>) -> PyResult<Option<K>> {
    match v {
        None => Ok(None),
        Some(name) => K::from_name(&name).map(Some).ok_or_else(|| {
            SettingsError::new_err(format!(
                "invalid value '{name}' for {what}; known: {}",
                K::names()
            ))
        }),
    }
}

/// The tracker stays a name in `Overrides` (the session resolves "auto" once it knows
/// the scene), so only its spelling is checked here.
pub fn check_tracker(tracker: Option<&String>) -> PyResult<()> {
    if let Some(t) = tracker {
        if t != "auto" && TrackerKind::from_name(t).is_none() {
            return Err(SettingsError::new_err(format!(
                "invalid value '{t}' for tracker; known: auto, {}",
                TrackerKind::names()
            )));
        }
    }
    Ok(())
}

/// `region=(x0, y0, x1, y1)` as the film's region; whether it fits the frame is known
/// only once the stage is read ([`check_region_fits`]).
pub fn parse_region(region: Option<(u32, u32, u32, u32)>) -> PyResult<Option<Region>> {
    match region {
        Some((x0, y0, x1, y1)) if x0 < x1 && y0 < y1 => Ok(Some(Region { x0, y0, x1, y1 })),
        Some((x0, y0, x1, y1)) => Err(SettingsError::new_err(format!(
            "region ({x0}, {y0}, {x1}, {y1}) is not (x0, y0, x1, y1) with x0 < x1, y0 < y1"
        ))),
        None => Ok(None),
    }
}

/// The region must lie inside the frame the session resolved (stage or `res`).
pub fn check_region_fits(region: Option<Region>, session: &Session) -> PyResult<()> {
    if let Some(r) = region {
        if !r.fits(session.width, session.height) {
            return Err(SettingsError::new_err(format!(
                "region ({}, {}, {}, {}) does not lie inside the {}x{} frame",
                r.x0, r.y0, r.x1, r.y1, session.width, session.height
            )));
        }
    }
    Ok(())
}

/// The `aovs` argument as the film channels and the split layers asked for. `NAME=EXPR`
/// is a layer of a light path expression (a RenderVar's `lpe` sourceName); the rest
/// are `--aovs` names, which the library parses as the CLI's.
pub fn requested_aovs_and_layers(
    aovs: Option<Vec<String>>,
) -> PyResult<(Vec<Aov>, Vec<SplitLayer>)> {
    let (lpe_names, aov_names): (Vec<String>, Vec<String>) = aovs
        .unwrap_or_default()
        .into_iter()
        .partition(|n| n.contains('='));
    let (aov_list, mut requested_layers) = guarded(|| requested_outputs(&aov_names))?;
    for n in &lpe_names {
        let layer = lpe_layer(n)?;
        if !requested_layers.contains(&layer) {
            requested_layers.push(layer);
        }
    }
    Ok((aov_list, requested_layers))
}

/// One `NAME=EXPR` entry as a split layer named NAME.
fn lpe_layer(entry: &str) -> PyResult<SplitLayer> {
    let (name, expr) = entry.split_once('=').unwrap_or_default();
    let layer = SplitLayer::parse(name.trim(), expr, "lpe")
        .map_err(|e| SettingsError::new_err(format!("aovs entry '{entry}': {e}")))?;
    if name.trim().is_empty() {
        return Err(SettingsError::new_err(format!(
            "aovs entry '{entry}': no layer name before '='"
        )));
    }
    Ok(layer)
}
