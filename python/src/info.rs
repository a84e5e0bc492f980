//! `nimbus.info`: the library's description of a stage, VDB file or deep EXR
//! (`nimbus::output::describe`), converted to Python objects through the JSON
//! `nimbus info --json` prints — the same data by construction.

use crate::errors::guarded;
use crate::json::json_to_py;
use crate::stage_input::stage_file;
use nimbus::output::describe::{describe, DescribeOptions};
use pyo3::prelude::*;
use std::path::PathBuf;

/// What `nimbus info --json` prints: for a stage, its volumes with their fields and
/// grids, lights, camera, render settings, holdouts, the scene analysis and what `auto`
/// picks; for a .vdb file its grids; for a deep EXR its sample counts.
#[pyfunction]
#[pyo3(signature = (stage=None, *, stage_text=None, base_dir=None, frame=None, octree_depth=8))]
pub fn info<'py>(
    py: Python<'py>,
    stage: Option<PathBuf>,
    stage_text: Option<String>,
    base_dir: Option<PathBuf>,
    frame: Option<f64>,
    octree_depth: u32,
) -> PyResult<Bound<'py, PyAny>> {
    let (path, tmp) = stage_file(stage, stage_text, base_dir)?;
    let o = DescribeOptions {
        frame,
        octree_depth,
    };
    let d = py.allow_threads(|| guarded(|| describe(&path, &o)));
    // The temporary stage (stage_text) is read until here.
    drop(tmp);
    json_to_py(py, &d?)
}
