//! `nimbus.render` and `RenderResult`: a render through the library's session
//! (`nimbus::render::session`), on a worker thread with the GIL released; the calling
//! thread waits, polls for signals (Ctrl-C sets the session's stop flag and raises
//! `KeyboardInterrupt` at once) and for `cancel()`, and calls the progress callbacks:
//! `progress` as rows finish, `on_pass` with the image after each pass of the
//! library's progressive render (`nimbus::render::progressive`).

use crate::errors::{guarded, Cancelled, Error, SettingsError};
use crate::{json_to_py, stage_file};
use nimbus::output::products::{requested_aovs, requested_outputs, OutputRequest, Outputs};
use nimbus::output::stats::{RenderStats, RunFacts};
use nimbus::render::film::{Aov, Film, Region};
use nimbus::render::progressive::{Clock, Progress};
use nimbus::render::sampler::SamplerKind;
use nimbus::render::session::{Overrides, Session, DEFAULT_OCTREE_PRUNE};
use nimbus::render::splits::SplitLayer;
use nimbus::track::select::{Choice, SchemeKind, TrackerKind, TransmittanceKind};
use numpy::{PyArray1, PyArrayMethods};
use pyo3::exceptions::PyKeyboardInterrupt;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc::{channel, Receiver, RecvTimeoutError};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// How often the waiting thread polls for signals and reports progress.
const POLL: Duration = Duration::from_millis(20);

fn parse_choice<K: Choice>(what: &str, v: Option<String>) -> PyResult<Option<K>> {
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

/// What the calling thread checks while it waits: a signal (Ctrl-C raises
/// `KeyboardInterrupt`) and the caller's `cancel()` (True raises `Cancelled`). Either
/// sets `stop`, so the worker ends after the pass it is in.
fn check_stop(py: Python<'_>, stop: &AtomicBool, cancel: Option<&Py<PyAny>>) -> PyResult<()> {
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
fn recv<T: Send>(py: Python<'_>, rx: &Mutex<Receiver<T>>) -> Result<T, RecvTimeoutError> {
    py.allow_threads(|| {
        rx.lock().map_or(Err(RecvTimeoutError::Disconnected), |r| {
            r.recv_timeout(POLL)
        })
    })
}

/// Opens a session on a worker thread with the GIL released, polling for signals and
/// `cancel()` meanwhile: a stop returns at once (the worker's session is dropped when
/// it has loaded).
fn open_session(
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
    // Behind a mutex only so the closure handed to allow_threads is Sync.
    let rx = Mutex::new(rx);
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

/// A film's R, G, B, A means interleaved, row 0 at the top: the buffer of an
/// (H, W, 4) array.
fn interleaved_rgba(film: &Film) -> Vec<f32> {
    let chans = [Aov::R, Aov::G, Aov::B, Aov::A].map(|a| film.channel(a));
    let n = film.width as usize * film.height as usize;
    let mut v = Vec::with_capacity(n * 4);
    for i in 0..n {
        v.extend(chans.iter().map(|c| c[i]));
    }
    v
}

/// A split layer's R, G, B means interleaved: the buffer of an (H, W, 3) array.
fn interleaved_layer(film: &Film, i: usize) -> Vec<f32> {
    let chans = film.layer(i);
    let n = film.width as usize * film.height as usize;
    let mut v = Vec::with_capacity(n * 3);
    for p in 0..n {
        v.extend(chans.iter().map(|c| c[p]));
    }
    v
}

/// What the render thread sends the calling thread.
enum Msg {
    /// A pass finished: samples per pixel so far, passes so far, the image so far
    /// (only when `on_pass` wants it).
    Pass(u32, u32, Option<Vec<f32>>),
    Done(PyResult<Rendered>),
}

fn warn_all(py: Python<'_>, warnings: &[String]) -> PyResult<()> {
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

/// The finished render: owns the session and the film so `write` can write exactly
/// what `nimbus render` writes.
#[pyclass(module = "nimbus._nimbus", name = "RenderResult", frozen)]
pub struct RenderResult {
    #[pyo3(get)]
    rgba: Py<PyAny>,
    #[pyo3(get)]
    aovs: Py<PyDict>,
    #[pyo3(get)]
    stats: Py<PyAny>,
    #[pyo3(get)]
    warnings: Py<PyList>,
    #[pyo3(get)]
    auto_summary: Option<String>,
    session: Arc<Session>,
    film: Film,
    progress: Progress,
    facts: RunFacts,
    aov_list: Vec<Aov>,
    /// The split layers the film holds, in its order (`write` writes them).
    layers: Vec<SplitLayer>,
    region: Option<Region>,
}

#[pymethods]
impl RenderResult {
    /// Writes the EXR(s) (and optionally the stats JSON and a preview PNG) as
    /// `nimbus render -o PATH` would: the render's AOVs unless `aovs` names others.
    #[pyo3(signature = (path, *, aovs=None, stats=None, preview=None))]
    fn write(
        &self,
        py: Python<'_>,
        path: PathBuf,
        aovs: Option<Vec<String>>,
        stats: Option<PathBuf>,
        preview: Option<PathBuf>,
    ) -> PyResult<()> {
        let aov_list = match aovs {
            Some(names) => guarded(|| requested_aovs(&names))?,
            None => self.aov_list.clone(),
        };
        let request = OutputRequest {
            output: Some(path),
            aovs: aov_list,
            layers: self.layers.clone(),
            stats,
            preview,
            region: self.region.is_some(),
            ..OutputRequest::default()
        };
        py.allow_threads(|| {
            guarded(|| {
                let s = &self.session;
                let outputs =
                    Outputs::resolve(&s.stage_path, &s.scene.settings, &request, s.frame, false)?;
                outputs.write(s, &self.film, &self.facts, &self.progress)
            })
        })
    }

    #[getter]
    fn width(&self) -> u32 {
        self.session.width
    }
    #[getter]
    fn height(&self) -> u32 {
        self.session.height
    }
    /// Samples per pixel actually taken.
    #[getter]
    fn spp(&self) -> u32 {
        self.progress.spp
    }
    #[getter]
    fn seed(&self) -> u64 {
        self.session.seed
    }
    #[getter]
    fn tracker(&self) -> &'static str {
        self.session.tracking.tracker.name()
    }

    fn __repr__(&self) -> String {
        format!(
            "<nimbus.RenderResult {}x{} {} spp tracker {}>",
            self.session.width,
            self.session.height,
            self.progress.spp,
            self.session.tracking.tracker.name()
        )
    }
}

type Rendered = (Film, Progress, usize, bool);

/// Renders a stage and returns a RenderResult (rgba, aovs, stats, write()).
///
/// `stage` is a .usda/.usdc/.usdz path or a .vdb file; or give the usda text as
/// `stage_text`, whose relative asset paths resolve against `base_dir` (default: the
/// working directory; the text is written to a hidden temporary .usda there while the
/// stage loads).
///
/// The other keyword arguments are `nimbus render`'s flags (`--max-depth` is
/// `max_depth`, `--res 320x240` is `res=(320, 240)`, `--region X0,Y0,X1,Y1` is
/// `region=(x0, y0, x1, y1)`) with the same meaning and defaults; None leaves the
/// choice to the stage, and the stage's silence to the schema fallbacks. `tracker` is
/// "auto" or one of tracker_names(). `aovs` takes aov_names() and the splits
/// (`direct`, `indirect`, `emission`, `lightgroup:GROUP`), which come back in
/// `RenderResult.aovs` as (H, W, 3) arrays under their layer names
/// (`lightgroup_GROUP`); `"NAME=EXPR"` names a layer of a light path expression
/// (a RenderVar's `lpe` sourceName, docs/aovs.md), returned as NAME. `output`,
/// `stats` and `preview` write files as `-o`, `--stats` and `--preview` do; without
/// them nothing is written (use RenderResult.write).
///
/// The GIL is released while the stage loads and renders. On the calling thread:
/// `progress(done, total)` as rows finish (total = spp * height; None with a time
/// limit alone); `on_pass(spp, total_spp, rgba)` after each pass of the progressive
/// render (the CLI's passes: 1 sample, then doubling, each at most about 2 s;
/// `spp` samples per pixel so far, `total_spp` the cap or None, `rgba` a float32
/// (H, W, 4) copy of the image so far); `cancel()` every 20 ms while the stage loads
/// and renders. A callback that raises stops the render and its exception
/// propagates; `on_pass` returning False or `cancel()` returning True stops it and
/// raises Cancelled at once, as Ctrl-C raises KeyboardInterrupt.
///
/// Raises StageError, VdbError, SettingsError or OutputError (all nimbus.Error),
/// with the messages of the CLI.
#[pyfunction]
#[pyo3(signature = (
    stage=None, *, stage_text=None, base_dir=None,
    spp=None, res=None, region=None, seed=None, sampler=None, threads=None, max_depth=None,
    majorant_cell=None, octree_depth=None, octree_prune=DEFAULT_OCTREE_PRUNE,
    tracker=None, scheme=None, transmittance=None, control=None,
    reduced_termination=false, no_absorption_events=false, majorant_scale=1.0,
    profile=false, no_specialise=false, aovs=None, time_limit=None,
    strict=false, no_default_lights=false, grid=None, camera=None, frame=None, output=None, stats=None, preview=None,
    progress=None, on_pass=None, cancel=None
))]
#[allow(clippy::too_many_arguments)]
pub fn render(
    py: Python<'_>,
    stage: Option<PathBuf>,
    stage_text: Option<String>,
    base_dir: Option<PathBuf>,
    spp: Option<u32>,
    res: Option<(u32, u32)>,
    region: Option<(u32, u32, u32, u32)>,
    seed: Option<u64>,
    sampler: Option<String>,
    threads: Option<usize>,
    max_depth: Option<u32>,
    majorant_cell: Option<u32>,
    octree_depth: Option<u32>,
    octree_prune: f32,
    tracker: Option<String>,
    scheme: Option<String>,
    transmittance: Option<String>,
    control: Option<f32>,
    reduced_termination: bool,
    no_absorption_events: bool,
    majorant_scale: f32,
    profile: bool,
    no_specialise: bool,
    aovs: Option<Vec<String>>,
    time_limit: Option<f64>,
    strict: bool,
    no_default_lights: bool,
    grid: Option<String>,
    camera: Option<String>,
    frame: Option<f64>,
    output: Option<PathBuf>,
    stats: Option<PathBuf>,
    preview: Option<PathBuf>,
    progress: Option<Py<PyAny>>,
    on_pass: Option<Py<PyAny>>,
    cancel: Option<Py<PyAny>>,
) -> PyResult<RenderResult> {
    let wall = Instant::now();
    if let Some(t) = &tracker {
        if t != "auto" && TrackerKind::from_name(t).is_none() {
            return Err(SettingsError::new_err(format!(
                "invalid value '{t}' for tracker; known: auto, {}",
                TrackerKind::names()
            )));
        }
    }
    let region = match region {
        Some((x0, y0, x1, y1)) if x0 < x1 && y0 < y1 => Some(Region { x0, y0, x1, y1 }),
        Some((x0, y0, x1, y1)) => {
            return Err(SettingsError::new_err(format!(
                "region ({x0}, {y0}, {x1}, {y1}) is not (x0, y0, x1, y1) with x0 < x1, y0 < y1"
            )))
        }
        None => None,
    };
    let overrides = Overrides {
        frame,
        camera,
        spp,
        res,
        seed,
        sampler: parse_choice::<SamplerKind>("sampler", sampler)?,
        threads,
        max_depth,
        majorant_cell,
        octree_depth,
        octree_prune: Some(octree_prune),
        tracker,
        scheme: parse_choice::<SchemeKind>("scheme", scheme)?,
        transmittance: parse_choice::<TransmittanceKind>("transmittance", transmittance)?,
        control,
        reduced_termination,
        no_absorption_events,
        majorant_scale: Some(majorant_scale),
        profile,
        no_specialise,
        time_limit,
        grid,
        strict,
        no_default_lights,
    };
    // `NAME=EXPR` is a layer of a light path expression (a RenderVar's `lpe`
    // sourceName); the rest are `--aovs` names.
    let (lpe_names, aov_names): (Vec<String>, Vec<String>) = aovs
        .unwrap_or_default()
        .into_iter()
        .partition(|n| n.contains('='));
    let (aov_list, mut requested_layers) = guarded(|| requested_outputs(&aov_names))?;
    for n in &lpe_names {
        let (name, expr) = n.split_once('=').unwrap_or_default();
        let layer = SplitLayer::parse(name.trim(), expr, "lpe")
            .map_err(|e| SettingsError::new_err(format!("aovs entry '{n}': {e}")))?;
        if name.trim().is_empty() {
            return Err(SettingsError::new_err(format!(
                "aovs entry '{n}': no layer name before '='"
            )));
        }
        if !requested_layers.contains(&layer) {
            requested_layers.push(layer);
        }
    }
    let (path, tmp) = stage_file(stage, stage_text, base_dir)?;
    let session = Arc::new(open_session(py, &path, &overrides, cancel.as_ref())?);
    drop(tmp);
    if let Some(r) = region {
        if !r.fits(session.width, session.height) {
            return Err(SettingsError::new_err(format!(
                "region ({}, {}, {}, {}) does not lie inside the {}x{} frame",
                r.x0, r.y0, r.x1, r.y1, session.width, session.height
            )));
        }
    }
    let request = OutputRequest {
        output,
        aovs: aov_list.clone(),
        layers: requested_layers.clone(),
        stats,
        preview,
        region: region.is_some(),
        ..OutputRequest::default()
    };
    // Files are written only when asked for (unlike the CLI, which always writes the
    // stage's products): resolve them before rendering so a bad path fails at once.
    let outputs =
        if request.output.is_some() || request.stats.is_some() || request.preview.is_some() {
            Some(guarded(|| {
                Outputs::resolve(&path, &session.scene.settings, &request, frame, false)
            })?)
        } else {
            None
        };
    warn_all(py, &session.warnings)?;

    // The film's split layers: every layer a product written asks for (the requested
    // ones among them, as the CLI's), else the requested ones.
    let layers = match &outputs {
        Some(o) => o.split_layers(),
        None => requested_layers.clone(),
    };
    let deep = outputs.as_ref().is_some_and(|o| o.deep());
    let extra = guarded(|| session.extra_outputs(layers.clone(), deep))?;

    // r.stats is always filled, so the counters always run (as `--stats` makes them).
    let count = true;
    let stop = Arc::new(AtomicBool::new(false));
    let done = Arc::new(AtomicU64::new(0));
    let rows = region.map_or(session.height, |r| r.height());
    let total = (session.spp != u32::MAX).then(|| session.spp as u64 * rows as u64);
    let total_spp = (session.spp != u32::MAX).then_some(session.spp);
    let want_image = on_pass.is_some();
    let (tx, rx) = channel::<Msg>();
    {
        let (session, stop, done) = (session.clone(), stop.clone(), done.clone());
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
                        &stop,
                        &|n| {
                            done.fetch_add(n as u64, Ordering::Relaxed);
                        },
                        |film, p| {
                            let image = want_image.then(|| interleaved_rgba(film));
                            // The caller may have returned already (a stop): no one
                            // listens then, which is fine.
                            let _ = pass_tx.send(Msg::Pass(p.spp, p.passes, image));
                            Ok::<(), anyhow::Error>(())
                        },
                    )?;
                    Ok((film, p, threads, job.paths.count))
                });
                let _ = tx.send(Msg::Done(r));
            })
            .map_err(|e| Error::new_err(format!("cannot start the render thread: {e}")))?;
    }
    // Behind a mutex only so the closure handed to allow_threads is Sync.
    let rx = Mutex::new(rx);
    let mut reported = u64::MAX;
    let mut report = |py: Python<'_>, d: u64| -> PyResult<()> {
        if let Some(cb) = &progress {
            if d != reported {
                reported = d;
                cb.call1(py, (d, total))?;
            }
        }
        Ok(())
    };
    let (h, w) = match region {
        Some(r) => (r.height() as usize, r.width() as usize),
        None => (session.height as usize, session.width as usize),
    };
    let rendered = loop {
        let r = match recv(py, &rx) {
            Ok(Msg::Done(r)) => break r?,
            Ok(Msg::Pass(spp_done, _passes, image)) => {
                // The rows of this pass are done: report them before the image.
                report(py, done.load(Ordering::Relaxed)).and_then(|_| {
                    match (&on_pass, image) {
                        (Some(cb), Some(v)) => {
                            let rgba = PyArray1::from_vec(py, v).reshape([h, w, 4])?;
                            let go = cb.call1(py, (spp_done, total_spp, rgba))?;
                            // Only an explicit False stops (None, the usual return
                            // of a function without one, does not).
                            if go.bind(py).is(&pyo3::types::PyBool::new(py, false)) {
                                return Err(Cancelled::new_err(
                                    "render cancelled by on_pass (it returned False)",
                                ));
                            }
                            Ok(())
                        }
                        _ => Ok(()),
                    }
                })
            }
            Err(RecvTimeoutError::Timeout) => {
                // Ctrl-C (or any signal handler raising), or cancel(): stop the render
                // and return at once; the worker finishes its current pass and drops
                // its result.
                check_stop(py, &stop, cancel.as_ref())
                    .and_then(|_| report(py, done.load(Ordering::Relaxed)))
            }
            Err(RecvTimeoutError::Disconnected) => {
                return Err(Error::new_err("the render thread ended without a result"))
            }
        };
        if let Err(e) = r {
            stop.store(true, Ordering::SeqCst);
            return Err(e);
        }
    };
    let (film, p, threads, counting) = rendered;
    report(py, done.load(Ordering::Relaxed))?;
    if p.interrupted {
        return Err(PyKeyboardInterrupt::new_err("render stopped"));
    }
    let facts = RunFacts {
        wall_seconds: wall.elapsed().as_secs_f64(),
        threads,
        counting,
        tile: None,
    };
    if let Some(outputs) = &outputs {
        py.allow_threads(|| guarded(|| outputs.write(&session, &film, &facts, &p)))?;
    }
    // One copy: the film's channels interleaved into the buffer numpy then owns.
    let rgba = PyArray1::from_vec(py, interleaved_rgba(&film)).reshape([h, w, 4])?;
    let aov_dict = PyDict::new(py);
    for a in &aov_list {
        let arr = PyArray1::from_vec(py, film.channel(*a)).reshape([h, w])?;
        aov_dict.set_item(a.channel_name(), arr)?;
    }
    for (i, l) in layers.iter().enumerate() {
        if requested_layers.contains(l) {
            let arr = PyArray1::from_vec(py, interleaved_layer(&film, i)).reshape([h, w, 3])?;
            aov_dict.set_item(&l.name, arr)?;
        }
    }
    let stats_value = guarded(|| Ok(RenderStats::new(&session, &film, &p, &facts)))?;
    let stats_py = json_to_py(py, &stats_value)?;
    let warnings = PyList::new(py, &session.warnings)?;
    let auto_summary = session.auto_summary();
    Ok(RenderResult {
        rgba: rgba.into_any().unbind(),
        aovs: aov_dict.unbind(),
        stats: stats_py.unbind(),
        warnings: warnings.unbind(),
        auto_summary,
        session,
        film,
        progress: p,
        facts,
        aov_list,
        layers,
        region,
    })
}
