//! `nimbus._nimbus`: the Python module of Nimbus (PyO3). It calls the library — the
//! render session (`nimbus::render::session`), the stage description and the image
//! comparison `nimbus info` and `nimbus compare` print — never the CLI;
//! `python/nimbus/__init__.py` re-exports it.
//!
//! The modules, each using only those below it (this file registers what the top ones
//! define):
//! - `info`: `info`, the description `nimbus info --json` prints
//! - `compare`: `compare`, the comparison `nimbus compare --json` prints; `read_exr`
//! - `render`: `render`, the entry that runs the steps below in order
//!   - `settings`: the keyword arguments as the library's settings (`Overrides`, the
//!     region, the AOVs and split layers asked for)
//!   - `loading`: the stage read into a session on a worker thread; its warnings
//!   - `passes`: the progressive render on a worker thread; `progress`, `on_pass`
//!   - `wait`: waiting for a worker with the GIL released; Ctrl-C and `cancel()`
//!   - `result`: `RenderResult` (`write` writes what `nimbus render` writes)
//!   - `arrays`: the film's channels and split layers as numpy arrays
//! - `stage_input`: the stage argument, a path or usda text (`render`, `info`)
//! - `json`: library results as Python objects through the JSON the CLI prints
//!   (`json_to_py`), so a dict from Python and the CLI's `--json` are the same data
//! - `errors`: the exceptions (`nimbus.Error` and its subclasses carry the CLI's
//!   message, `{e:#}` of the anyhow error; a panic becomes `nimbus.Error` too)

mod arrays;
mod compare;
mod errors;
mod info;
mod json;
mod loading;
mod passes;
mod render;
mod result;
mod settings;
mod stage_input;
mod wait;

use nimbus::render::film::Aov;
use nimbus::scene::schema::tokens;
use nimbus::track::select::{Choice, SchemeKind, TrackerKind, TransmittanceKind};
use nimbus::volume::vdb;
use pyo3::prelude::*;
use pyo3::types::PyDict;

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
    m.add_class::<result::RenderResult>()?;
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
