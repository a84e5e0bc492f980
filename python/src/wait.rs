//! How the calling thread waits for a worker (the stage's load, the render): with the
//! GIL released, in slices of [`POLL`], so between slices it can run Python's signal
//! handlers (Ctrl-C) and the caller's `cancel()`. Either one sets the worker's stop
//! flag and returns at once; the worker notices after the pass it is in.

use crate::errors::Cancelled;
use pyo3::prelude::*;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{Receiver, RecvTimeoutError};
use std::sync::Mutex;
use std::time::Duration;

/// How often the waiting thread polls for signals and reports progress.
pub const POLL: Duration = Duration::from_millis(20);

/// What the calling thread checks while it waits: a signal (Ctrl-C raises
/// `KeyboardInterrupt`) and the caller's `cancel()` (True raises `Cancelled`). Either
/// sets `stop`, so the worker ends after the pass it is in.
pub fn check_stop(py: Python<'_>, stop: &AtomicBool, cancel: Option<&Py<PyAny>>) -> PyResult<()> {
    let r = py.check_signals().and_then(|_| match cancel {
        Some(c) if c.call0(py)?.is_truthy(py)? => {
            Err(Cancelled::new_err("render cancelled by cancel()"))
        }
        _ => Ok(()),
    });
    if r.is_err() {
        stop.store(true, Ordering::SeqCst);
    }
    r
}

/// Waits for one message from a worker with the GIL released, for at most [`POLL`].
/// The receiver is behind a mutex only so the closure handed to `allow_threads` is
/// Sync.
pub fn recv<T: Send>(py: Python<'_>, rx: &Mutex<Receiver<T>>) -> Result<T, RecvTimeoutError> {
    py.allow_threads(|| {
        rx.lock().map_or(Err(RecvTimeoutError::Disconnected), |r| {
            r.recv_timeout(POLL)
        })
    })
}
