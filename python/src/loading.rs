//! Reading the stage into a session: on a worker thread, so a large stage or VDB can be
//! interrupted, and the session's warnings handed to Python's `warnings`.

use crate::errors::{guarded, Error};
use crate::wait::{check_stop, recv};
use nimbus::render::session::{Overrides, Session};
use pyo3::prelude::*;
use std::path::Path;
use std::sync::atomic::AtomicBool;
use std::sync::mpsc::{channel, RecvTimeoutError};
use std::sync::Mutex;

/// Opens a session on a worker thread with the GIL released, polling for signals and
/// `cancel()` meanwhile: a stop returns at once (the worker's session is dropped when
/// it has loaded).
pub fn open_session(
    py: Python<'_>,
    path: &Path,
    o: &Overrides,
    cancel: Option<&Py<PyAny>>,
) -> PyResult<Session> {
    let (tx, rx) = channel::<PyResult<Session>>();
    let (path, o) = (path.to_path_buf(), o.clone());
    std::thread::Builder::new()
        .name("nimbus-load".into())
        .spawn(move || {
            let _ = tx.send(guarded(|| Session::open(&path, &o)));
        })
        .map_err(|e| Error::new_err(format!("cannot start the loading thread: {e}")))?;
    let rx = Mutex::new(rx);
    // No worker shares it: a stop here only returns early.
    let stop = AtomicBool::new(false);
    loop {
        match recv(py, &rx) {
            Ok(r) => return r,
            Err(RecvTimeoutError::Timeout) => check_stop(py, &stop, cancel)?,
            Err(RecvTimeoutError::Disconnected) => {
                return Err(Error::new_err("the loading thread ended without a result"))
            }
        }
    }
}

/// The session's warnings (what the CLI prints to stderr) as `UserWarning`s, attributed
/// to the caller of `render` (stacklevel 2).
pub fn warn_all(py: Python<'_>, warnings: &[String]) -> PyResult<()> {
    if warnings.is_empty() {
        return Ok(());
    }
    let w = py.import("warnings")?;
    for msg in warnings {
        w.call_method1(
            "warn",
            (
                format!("nimbus: {msg}"),
                py.get_type::<pyo3::exceptions::PyUserWarning>(),
                2,
            ),
        )?;
    }
    Ok(())
}
