//! `nimbus._nimbus`: the Python module of Nimbus (PyO3). It calls the library — the
//! render session (`nimbus::render::session`), the stage description and the image
//! comparison `nimbus info` and `nimbus compare` print — never the CLI;
//! `python/nimbus/__init__.py` re-exports it.
//!
//! - `errors`: the exceptions (`nimbus.Error` and its subclasses carry the CLI's
//!   message, `{e:#}` of the anyhow error; a panic becomes `nimbus.Error` too)
//! - `render`: `render` and `RenderResult`
//! - `info`: `info`, the description `nimbus info --json` prints
//! - `compare`: `compare`, the comparison `nimbus compare --json` prints; `read_exr`
//!
//! Library results reach Python as the JSON the CLI prints (`json_to_py`), so a
//! dict from Python and the CLI's `--json` are the same data.

mod compare;
mod errors;
mod info;
mod render;

use errors::{OutputError, SettingsError};
use nimbus::render::film::Aov;
use nimbus::scene::schema::tokens;
use nimbus::track::select::{Choice, SchemeKind, TrackerKind, TransmittanceKind};
use nimbus::volume::vdb;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::path::PathBuf;

/// A serialisable library value as Python objects (dicts, lists, floats, …) through
/// its JSON text: exactly what the CLI's `--json` prints (non-finite floats are
/// `None` in both).
fn json_to_py<'py>(py: Python<'py>, v: &impl serde::Serialize) -> PyResult<Bound<'py, PyAny>> {
    let text = serde_json::to_string(v).map_err(|e| errors::Error::new_err(e.to_string()))?;
    py.import("json")?.call_method1("loads", (text,))
}

/// A stage given as usda text: written to a hidden temporary `.usda` in `base_dir`
/// (default: the working directory) so relative asset paths resolve against it; the
/// file is removed when this is dropped (right after the stage is read).
fn stage_file(
    stage: Option<PathBuf>,
    stage_text: Option<String>,
    base_dir: Option<PathBuf>,
) -> PyResult<(PathBuf, Option<tempfile::NamedTempFile>)> {
    match (stage, stage_text) {
        (Some(p), None) => Ok((p, None)),
        (None, Some(text)) => {
            let dir = base_dir.unwrap_or_else(|| PathBuf::from("."));
            let mut f = tempfile::Builder::new()
                .prefix(".nimbus-stage-")
                .suffix(".usda")
                .tempfile_in(&dir)
                .map_err(|e| {
                    OutputError::new_err(format!(
                        "cannot write the stage text to a temporary file in {}: {e}",
                        dir.display()
                    ))
                })?;
            use std::io::Write;
            f.write_all(text.as_bytes())
                .and_then(|_| f.flush())
                .map_err(|e| OutputError::new_err(format!("{}: {e}", f.path().display())))?;
            Ok((f.path().to_path_buf(), Some(f)))
        }
        (Some(_), Some(_)) => Err(SettingsError::new_err(
            "give either a stage path or stage_text, not both",
        )),
        (None, None) => Err(SettingsError::new_err(
            "no stage: give a path or stage_text",
        )),
    }
}

/// The tracker names `render(tracker=...)` accepts besides "auto".
#[pyfunction]
fn tracker_names() -> Vec<&'static str> {
    TrackerKind::ALL.iter().map(|t| t.name()).collect()
}

#[pyfunction]
fn scheme_names() -> Vec<&'static str> {
    SchemeKind::ALL.iter().map(|t| t.name()).collect()
}

#[pyfunction]
fn transmittance_names() -> Vec<&'static str> {
    TransmittanceKind::ALL.iter().map(|t| t.name()).collect()
}

#[pyfunction]
fn aov_names() -> Vec<&'static str> {
    Aov::ALL.iter().map(|a| a.channel_name()).collect()
}

/// The VDB reader in use: "openvdb" (the C++ bridge) or "rust" (Nimbus' own reader;
/// `NIMBUS_VDB_READER` picks one).
#[pyfunction]
fn vdb_reader() -> &'static str {
    vdb::active_reader().name()
}

#[pymodule]
fn _nimbus(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    errors::register(m)?;
    m.add_class::<render::RenderResult>()?;
    m.add_function(wrap_pyfunction!(info::info, m)?)?;
    m.add_function(wrap_pyfunction!(render::render, m)?)?;
    m.add_function(wrap_pyfunction!(compare::compare, m)?)?;
    m.add_function(wrap_pyfunction!(compare::read_exr, m)?)?;
    m.add_function(wrap_pyfunction!(tracker_names, m)?)?;
    m.add_function(wrap_pyfunction!(scheme_names, m)?)?;
    m.add_function(wrap_pyfunction!(transmittance_names, m)?)?;
    m.add_function(wrap_pyfunction!(aov_names, m)?)?;
    m.add_function(wrap_pyfunction!(vdb_reader, m)?)?;
    let schema = PyDict::new(py);
    for (k, v) in [
        ("DENSITY_FIELD", tokens::DENSITY_FIELD),
        ("DENSITY_SCALE", tokens::DENSITY_SCALE),
        ("ABSORPTION", tokens::ABSORPTION),
        ("SCATTERING", tokens::SCATTERING),
        ("ANISOTROPY", tokens::ANISOTROPY),
        ("TEMPERATURE_FIELD", tokens::TEMPERATURE_FIELD),
        ("TEMPERATURE_SCALE", tokens::TEMPERATURE_SCALE),
        ("BLACKBODY_INTENSITY", tokens::BLACKBODY_INTENSITY),
        ("EMISSION_FIELD", tokens::EMISSION_FIELD),
        ("EMISSION_COLOR", tokens::EMISSION_COLOR),
        ("EMISSION_SCALE", tokens::EMISSION_SCALE),
        ("ALBEDO_FIELD", tokens::ALBEDO_FIELD),
        ("SAMPLES", tokens::SAMPLES),
        ("MAX_DEPTH", tokens::MAX_DEPTH),
        ("SEED", tokens::SEED),
        ("TRACKER", tokens::TRACKER),
        ("SCHEME", tokens::SCHEME),
        ("TRANSMITTANCE", tokens::TRANSMITTANCE),
        ("CONTROL", tokens::CONTROL),
        ("OCTREE_DEPTH", tokens::OCTREE_DEPTH),
        ("PREVIEW_NAME", tokens::PREVIEW_NAME),
        ("VOLUME_API", nimbus::scene::schema::VOLUME_API),
        (
            "RENDER_SETTINGS_API",
            nimbus::scene::schema::RENDER_SETTINGS_API,
        ),
    ] {
        schema.set_item(k, v)?;
    }
    m.add("_schema_tokens", schema)?;
    Ok(())
}
