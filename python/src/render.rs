//! `nimbus.render` and `RenderResult`: a render through the library's session
//! (`nimbus::render::session`), on a worker thread with the GIL released; the calling
//! thread waits, polls for signals (Ctrl-C sets the session's stop flag and raises
//! `KeyboardInterrupt` at once) and calls the progress callback.

use crate::errors::{guarded, Error, SettingsError};
use crate::{json_to_py, stage_file};
use nimbus::output::products::{requested_aovs, OutputRequest, Outputs};
use nimbus::output::stats::{RenderStats, RunFacts};
use nimbus::render::film::{Aov, Film};
use nimbus::render::progressive::{Clock, Progress};
use nimbus::render::sampler::SamplerKind;
use nimbus::render::session::{ExtraOutputs, Overrides, Session, DEFAULT_OCTREE_PRUNE};
use nimbus::track::select::{Choice, SchemeKind, TrackerKind, TransmittanceKind};
use numpy::{PyArray1, PyArrayMethods};
use pyo3::exceptions::PyKeyboardInterrupt;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc::{channel, RecvTimeoutError};
use std::sync::Arc;
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

/// Opens a session with the GIL released.
fn open_session(py: Python<'_>, path: &Path, o: &Overrides) -> PyResult<Session> {
    py.allow_threads(|| guarded(|| Session::open(path, o)))
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
            stats,
            preview,
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
/// `max_depth`, `--res 320x240` is `res=(320, 240)`) with the same meaning and
/// defaults; None leaves the choice to the stage, and the stage's silence to the
/// schema fallbacks. `tracker` is "auto" or one of tracker_names(). `output`, `stats`
/// and `preview` write files as `-o`, `--stats` and `--preview` do; without them
/// nothing is written (use RenderResult.write).
///
/// The GIL is released while the stage loads and renders. `progress(done, total)` is
/// called on the calling thread as rows finish (total = spp * height; None with a
/// time limit alone); an exception it raises stops the render and propagates. Ctrl-C
/// stops the render and raises KeyboardInterrupt at once.
///
/// Raises StageError, VdbError, SettingsError or OutputError (all nimbus.Error),
/// with the messages of the CLI.
#[pyfunction]
#[pyo3(signature = (
    stage=None, *, stage_text=None, base_dir=None,
    spp=None, res=None, seed=None, sampler=None, threads=None, max_depth=None,
    majorant_cell=None, octree_depth=None, octree_prune=DEFAULT_OCTREE_PRUNE,
    tracker=None, scheme=None, transmittance=None, control=None,
    reduced_termination=false, no_absorption_events=false, majorant_scale=1.0,
    profile=false, no_specialise=false, aovs=None, time_limit=None,
    strict=false, no_default_lights=false, grid=None, camera=None, frame=None, output=None, stats=None, preview=None,
    progress=None
))]
#[allow(clippy::too_many_arguments)]
pub fn render(
    py: Python<'_>,
    stage: Option<PathBuf>,
    stage_text: Option<String>,
    base_dir: Option<PathBuf>,
    spp: Option<u32>,
    res: Option<(u32, u32)>,
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
    let aov_names = aovs.unwrap_or_default();
    let aov_list = guarded(|| requested_aovs(&aov_names))?;
    let (path, tmp) = stage_file(stage, stage_text, base_dir)?;
    let session = Arc::new(open_session(py, &path, &overrides)?);
    drop(tmp);
    let request = OutputRequest {
        output,
        aovs: aov_list.clone(),
        stats,
        preview,
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

    // r.stats is always filled, so the counters always run (as `--stats` makes them).
    let count = true;
    let stop = Arc::new(AtomicBool::new(false));
    let done = Arc::new(AtomicU64::new(0));
    let total = (session.spp != u32::MAX).then(|| session.spp as u64 * session.height as u64);
    let (tx, rx) = channel::<PyResult<Rendered>>();
    // Split AOVs and deep images the files written ask for are filled by this render.
    let extra = match &outputs {
        Some(o) => guarded(|| session.extra_outputs(o.split_layers(), o.deep()))?,
        None => ExtraOutputs::default(),
    };
    {
        let (session, stop, done) = (session.clone(), stop.clone(), done.clone());
        std::thread::Builder::new()
            .name("nimbus-render".into())
            .spawn(move || {
                let r = guarded(|| {
                    let mut job = session.job(count);
                    extra.apply(&mut job);
                    let pool = session.pool(0)?;
                    let threads = pool.current_num_threads();
                    let (film, p) = session.render(
                        &job,
                        None,
                        &pool,
                        Clock::Wall,
                        None,
                        &stop,
                        &|n| {
                            done.fetch_add(n as u64, Ordering::Relaxed);
                        },
                        |_, _| Ok::<(), anyhow::Error>(()),
                    )?;
                    Ok((film, p, threads, job.paths.count))
                });
                let _ = tx.send(r);
            })
            .map_err(|e| Error::new_err(format!("cannot start the render thread: {e}")))?;
    }
    // Behind a mutex only so the closure handed to allow_threads is Sync.
    let rx = std::sync::Mutex::new(rx);
    let mut reported = u64::MAX;
    let rendered = loop {
        match py.allow_threads(|| {
            rx.lock().map_or(Err(RecvTimeoutError::Disconnected), |r| {
                r.recv_timeout(POLL)
            })
        }) {
            Ok(r) => break r?,
            Err(RecvTimeoutError::Timeout) => {
                // Ctrl-C (or any signal handler raising): stop the render and return at
                // once; the worker finishes its current pass and drops its result.
                if let Err(e) = py.check_signals() {
                    stop.store(true, Ordering::SeqCst);
                    return Err(e);
                }
                let d = done.load(Ordering::Relaxed);
                if let Some(cb) = &progress {
                    if d != reported {
                        reported = d;
                        if let Err(e) = cb.call1(py, (d, total)) {
                            stop.store(true, Ordering::SeqCst);
                            return Err(e);
                        }
                    }
                }
            }
            Err(RecvTimeoutError::Disconnected) => {
                return Err(Error::new_err("the render thread ended without a result"))
            }
        }
    };
    let (film, p, threads, counting) = rendered;
    if let Some(cb) = &progress {
        let d = done.load(Ordering::Relaxed);
        if d != reported {
            cb.call1(py, (d, total))?;
        }
    }
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
    let (w, h) = (session.width as usize, session.height as usize);
    // One copy: the film's channels interleaved into the buffer numpy then owns.
    let rgba = {
        let chans = [Aov::R, Aov::G, Aov::B, Aov::A].map(|a| film.channel(a));
        let mut v = Vec::with_capacity(w * h * 4);
        for i in 0..w * h {
            v.extend(chans.iter().map(|c| c[i]));
        }
        PyArray1::from_vec(py, v).reshape([h, w, 4])?
    };
    let aov_dict = PyDict::new(py);
    for a in &aov_list {
        let arr = PyArray1::from_vec(py, film.channel(*a)).reshape([h, w])?;
        aov_dict.set_item(a.channel_name(), arr)?;
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
    })
}
