//! The exceptions of `nimbus` and how library errors and panics become them.
//!
//! Their module is `nimbus` (where `python/nimbus/__init__.py` re-exports them), not
//! the extension module `nimbus._nimbus`: pickle finds a class by `__module__` and
//! name, so `pickle.loads(pickle.dumps(e))` gives the same type and message, and an
//! error raised in a `multiprocessing` or `ProcessPoolExecutor` worker reaches the
//! parent as itself (BaseException's own `__reduce__` carries the message in `args`).

use nimbus::output::OutputError as LibOutputError;
use nimbus::scene::SceneError;
use nimbus::volume::vdb::VdbError as LibVdbError;
use pyo3::create_exception;
use pyo3::exceptions::PyException;
use pyo3::prelude::*;
use std::panic::{catch_unwind, AssertUnwindSafe};

create_exception!(
    nimbus,
    Error,
    PyException,
    "Base class of every error Nimbus raises."
);
create_exception!(
    nimbus,
    StageError,
    Error,
    "The stage could not be opened, composed or read (nimbus::scene::SceneError)."
);
create_exception!(
    nimbus,
    VdbError,
    Error,
    "A VDB file could not be read (nimbus::volume::vdb::VdbError)."
);
create_exception!(
    nimbus,
    SettingsError,
    Error,
    "A setting or keyword argument is invalid, or the scene cannot be rendered as asked."
);
create_exception!(
    nimbus,
    OutputError,
    Error,
    "An output file could not be written."
);

create_exception!(
    nimbus,
    Cancelled,
    PyException,
    "The render was stopped by its caller: a `cancel()` that returned True, or an\n\
     `on_pass` callback that returned False. Not a `nimbus.Error`: nothing went wrong."
);

/// Adds the exception types to the module.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add("Error", py.get_type::<Error>())?;
    m.add("StageError", py.get_type::<StageError>())?;
    m.add("VdbError", py.get_type::<VdbError>())?;
    m.add("SettingsError", py.get_type::<SettingsError>())?;
    m.add("OutputError", py.get_type::<OutputError>())?;
    m.add("Cancelled", py.get_type::<Cancelled>())?;
    Ok(())
}

/// The Python exception for a library error: the type by the first match in the
/// error's chain (VDB, then stage, then output), else `SettingsError`; the message is
/// the CLI's.
pub fn to_py(e: anyhow::Error) -> PyErr {
    let msg = format!("{e:#}");
    if e.chain().any(|c| c.downcast_ref::<LibVdbError>().is_some()) {
        return VdbError::new_err(msg);
    }
    if e.chain().any(|c| c.downcast_ref::<SceneError>().is_some()) {
        return StageError::new_err(msg);
    }
    if e.chain()
        .any(|c| c.downcast_ref::<LibOutputError>().is_some())
    {
        return OutputError::new_err(msg);
    }
    SettingsError::new_err(msg)
}

/// A panic's message as `nimbus.Error` (no panic crosses into Python).
fn panic_to_py(p: Box<dyn std::any::Any + Send>) -> PyErr {
    let what = p
        .downcast_ref::<String>()
        .cloned()
        .or_else(|| p.downcast_ref::<&str>().map(|s| s.to_string()))
        .unwrap_or_else(|| "unknown panic".into());
    Error::new_err(format!("internal error (a Nimbus panic): {what}"))
}

/// Runs `f`, turning a library error or a panic into a Python exception.
pub fn guarded<T>(f: impl FnOnce() -> anyhow::Result<T>) -> PyResult<T> {
    match catch_unwind(AssertUnwindSafe(f)) {
        Ok(Ok(v)) => Ok(v),
        Ok(Err(e)) => Err(to_py(e)),
        Err(p) => Err(panic_to_py(p)),
    }
}
