//! The progressive render (`nimbus::render::progressive`) on a worker thread, and the
//! calling thread's side of it: while it waits (`crate::wait`) it calls `progress` as
//! rows finish and `on_pass` after each pass, and stops the worker when a callback
//! raises, `on_pass` returns False, `cancel()` returns True or a signal arrives.
//!
//! Python is called only on the calling thread (it holds the GIL); the worker only
//! counts rows in an atomic and sends a message per pass.

use crate::arrays::{interleaved_rgba, rgba_array};
use crate::errors::{guarded, Cancelled, Error};
use crate::wait::{check_stop, recv};
use nimbus::render::adaptive::Convergence;
use nimbus::render::film::{Film, Region};
use nimbus::render::progressive::{Clock, Progress};
use nimbus::render::session::{ExtraOutputs, Session};
use pyo3::exceptions::PyKeyboardInterrupt;
use pyo3::prelude::*;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc::{channel, RecvTimeoutError, Sender};
use std::sync::{Arc, Mutex};

/// The worker's result: the film, the progress (samples, passes, interrupted), the
/// pool's thread count and whether the path counters ran.
pub type Rendered = (Film, Progress, usize, bool);

/// The Python callables of a render, all optional.
pub struct Callbacks {
    /// `progress(done, total)` as rows finish.
    pub progress: Option<Py<PyAny>>,
    /// `on_pass(spp, total_spp, rgba)` after each pass.
    pub on_pass: Option<Py<PyAny>>,
    /// `on_noise(spp, noise, converged)` after each pass, before `on_pass`.
    pub on_noise: Option<Py<PyAny>>,
    /// `cancel()` every [`crate::wait::POLL`].
    pub cancel: Option<Py<PyAny>>,
}

/// What the render thread sends the calling thread.
enum Msg {
    /// A pass finished: samples per pixel so far, passes so far, the image so far
    /// (only when `on_pass` wants it), the pixels' convergence.
    Pass(u32, u32, Option<Vec<f32>>, Convergence),
    Done(PyResult<Rendered>),
}

/// What the worker shares with the calling thread: the stop flag both set, and the
/// rows (times samples) done, which the worker counts and `progress` reports.
#[derive(Clone, Default)]
struct Shared {
    stop: Arc<AtomicBool>,
    done: Arc<AtomicU64>,
}

/// Renders the session's passes on a worker thread and waits for them, calling
/// `callbacks` on this thread. `shape` is the image's (height, width).
pub fn render_passes(
    py: Python<'_>,
    session: &Arc<Session>,
    extra: ExtraOutputs,
    region: Option<Region>,
    shape: (usize, usize),
    callbacks: &Callbacks,
) -> PyResult<Rendered> {
    let shared = Shared::default();
    let (tx, rx) = channel::<Msg>();
    spawn_worker(
        session.clone(),
        extra,
        region,
        shared.clone(),
        callbacks.on_pass.is_some(),
        tx,
    )?;
    let rows = region.map_or(session.height, |r| r.height());
    let total = (session.spp != u32::MAX).then(|| session.spp as u64 * rows as u64);
    let total_spp = (session.spp != u32::MAX).then_some(session.spp);
    let mut rows_report = RowReport::new(callbacks.progress.as_ref(), total);
    let rx = Mutex::new(rx);
    let rendered = loop {
        let r = match recv(py, &rx) {
            Ok(Msg::Done(r)) => break r?,
            Ok(Msg::Pass(spp_done, _passes, image, convergence)) => {
                // The rows of this pass are done: report them, then the noise, before
                // the image.
                rows_report
                    .report(py, shared.done.load(Ordering::Relaxed))
                    .and_then(|_| {
                        show_noise(py, callbacks.on_noise.as_ref(), spp_done, convergence)
                    })
                    .and_then(|_| {
                        show_pass(
                            py,
                            callbacks.on_pass.as_ref(),
                            spp_done,
                            total_spp,
                            image,
                            shape,
                        )
                    })
            }
            Err(RecvTimeoutError::Timeout) => {
                // Ctrl-C (or any signal handler raising), or cancel(): stop the render
                // and return at once; the worker finishes its current pass and drops
                // its result.
                check_stop(py, &shared.stop, callbacks.cancel.as_ref())
                    .and_then(|_| rows_report.report(py, shared.done.load(Ordering::Relaxed)))
            }
            Err(RecvTimeoutError::Disconnected) => {
                return Err(Error::new_err("the render thread ended without a result"))
            }
        };
        if let Err(e) = r {
            shared.stop.store(true, Ordering::SeqCst);
            return Err(e);
        }
    };
    rows_report.report(py, shared.done.load(Ordering::Relaxed))?;
    if rendered.1.interrupted {
        return Err(PyKeyboardInterrupt::new_err("render stopped"));
    }
    Ok(rendered)
}

/// Starts the render thread: it renders every pass, sends a [`Msg::Pass`] after each
/// (with the image when `want_image`) and [`Msg::Done`] at the end.
fn spawn_worker(
    session: Arc<Session>,
    extra: ExtraOutputs,
    region: Option<Region>,
    shared: Shared,
    want_image: bool,
    tx: Sender<Msg>,
) -> PyResult<()> {
    // RenderResult.stats is always filled, so the counters always run (as `--stats`
    // makes them).
    let count = true;
    std::thread::Builder::new()
        .name("nimbus-render".into())
        .spawn(move || {
            let pass_tx = tx.clone();
            let r = guarded(|| {
                let mut job = session.job(count);
                extra.apply(&mut job);
                let pool = session.pool(0)?;
                let threads = pool.current_num_threads();
                let (film, p) = session.render(
                    &job,
                    region,
                    &pool,
                    Clock::Wall,
                    None,
                    &shared.stop,
                    &|n| {
                        shared.done.fetch_add(n as u64, Ordering::Relaxed);
                    },
                    |film, p| {
                        let image = want_image.then(|| interleaved_rgba(film));
                        // The caller may have returned already (a stop): no one
                        // listens then, which is fine.
                        let _ = pass_tx.send(Msg::Pass(p.spp, p.passes, image, p.convergence));
                        Ok::<(), anyhow::Error>(())
                    },
                )?;
                Ok((film, p, threads, job.paths.count))
            });
            let _ = tx.send(Msg::Done(r));
        })
        .map(|_| ())
        .map_err(|e| Error::new_err(format!("cannot start the render thread: {e}")))
}

/// `progress(done, total)`, called only when `done` changed since the last call
/// (`total` is None with a time limit alone).
struct RowReport<'a> {
    callback: Option<&'a Py<PyAny>>,
    total: Option<u64>,
    reported: u64,
}

impl<'a> RowReport<'a> {
    fn new(callback: Option<&'a Py<PyAny>>, total: Option<u64>) -> Self {
        RowReport {
            callback,
            total,
            reported: u64::MAX,
        }
    }

    fn report(&mut self, py: Python<'_>, done: u64) -> PyResult<()> {
        if let Some(cb) = self.callback {
            if done != self.reported {
                self.reported = done;
                cb.call1(py, (done, self.total))?;
            }
        }
        Ok(())
    }
}

/// Hands a finished pass's noise estimate to `on_noise`: the mean over the pixels of
/// the estimate adaptive sampling stops on (the stats' `estimated_noise`, the CLI
/// progress line's "noise"), and the share of pixels stopped (None without adaptive
/// sampling).
fn show_noise(
    py: Python<'_>,
    on_noise: Option<&Py<PyAny>>,
    spp_done: u32,
    c: Convergence,
) -> PyResult<()> {
    if let Some(cb) = on_noise {
        cb.call1(py, (spp_done, c.mean_error, c.stopped))?;
    }
    Ok(())
}

/// Hands a finished pass's image to `on_pass`. Only an explicit False stops the render
/// (None, the usual return of a function without one, does not).
fn show_pass(
    py: Python<'_>,
    on_pass: Option<&Py<PyAny>>,
    spp_done: u32,
    total_spp: Option<u32>,
    image: Option<Vec<f32>>,
    shape: (usize, usize),
) -> PyResult<()> {
    let (Some(cb), Some(v)) = (on_pass, image) else {
        return Ok(());
    };
    let rgba = rgba_array(py, v, shape)?;
    let go = cb.call1(py, (spp_done, total_spp, rgba))?;
    if go.bind(py).is(&pyo3::types::PyBool::new(py, false)) {
        return Err(Cancelled::new_err(
            "render cancelled by on_pass (it returned False)",
        ));
    }
    Ok(())
}
