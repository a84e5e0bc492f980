//! Library values as Python objects. They go through the JSON text the CLI's `--json`
//! prints rather than a conversion of their own, so a dict from Python and the CLI's
//! output are the same data by construction.

use crate::errors::Error;
use pyo3::prelude::*;

/// A serialisable library value as Python objects (dicts, lists, floats, …) through
/// its JSON text: exactly what the CLI's `--json` prints (non-finite floats are
/// `None` in both).
pub fn json_to_py<'py>(py: Python<'py>, v: &impl serde::Serialize) -> PyResult<Bound<'py, PyAny>> {
    let text = serde_json::to_string(v).map_err(|e| Error::new_err(e.to_string()))?;
    py.import("json")?.call_method1("loads", (text,))
}
