//! `nimbus._nimbus`: the Python module of Nimbus (PyO3). It calls the library's render
//! session (`nimbus::render::session`), never the CLI; `python/nimbus/__init__.py`
//! re-exports it.
//!
//! Errors are `nimbus.Error` subclasses carrying the CLI's message (`{e:#}` of the
//! anyhow error); a panic becomes `nimbus.Error` too. Renders run on a worker thread
//! with the GIL released; the calling thread waits, polls for signals (Ctrl-C sets the
//! session's stop flag and raises `KeyboardInterrupt` at once) and calls the progress
//! callback.

use nimbus::output::exr::read_all_channels;
use nimbus::output::products::{requested_aovs, OutputRequest, Outputs};
use nimbus::output::stats::{RenderStats, RunFacts};
use nimbus::output::OutputError as LibOutputError;
use nimbus::render::analysis::Given;
use nimbus::render::film::{Aov, Film};
use nimbus::render::progressive::{Clock, Progress};
use nimbus::render::sampler::SamplerKind;
use nimbus::render::session::{ExtraOutputs, Overrides, Session, DEFAULT_OCTREE_PRUNE};
use nimbus::scene::schema::tokens;
use nimbus::scene::SceneError;
use nimbus::track::select::{Choice, SchemeKind, TrackerKind, TrackerSettings, TransmittanceKind};
use nimbus::volume::vdb::{self, VdbError as LibVdbError};
use numpy::{PyArray1, PyArrayDyn, PyArrayMethods, PyReadonlyArrayDyn, PyUntypedArrayMethods};
use pyo3::create_exception;
use pyo3::exceptions::{PyException, PyKeyboardInterrupt};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};
use serde_json::{json, Value};
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc::{channel, RecvTimeoutError};
use std::sync::Arc;
use std::time::{Duration, Instant};

create_exception!(
    _nimbus,
    Error,
    PyException,
    "Base class of every error Nimbus raises."
);
create_exception!(
    _nimbus,
    StageError,
    Error,
    "The stage could not be opened, composed or read (nimbus::scene::SceneError)."
);
create_exception!(
    _nimbus,
    VdbError,
    Error,
    "A VDB file could not be read (nimbus::volume::vdb::VdbError)."
);
create_exception!(
    _nimbus,
    SettingsError,
    Error,
    "A setting or keyword argument is invalid, or the scene cannot be rendered as asked."
);
create_exception!(
    _nimbus,
    OutputError,
    Error,
    "An output file could not be written."
);

/// How often the waiting thread polls for signals and reports progress.
const POLL: Duration = Duration::from_millis(20);

/// The Python exception for a library error: the type by the first match in the
/// error's chain (VDB, then stage, then output), else `SettingsError`; the message is
/// the CLI's.
fn to_py(e: anyhow::Error) -> PyErr {
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
fn guarded<T>(f: impl FnOnce() -> anyhow::Result<T>) -> PyResult<T> {
    match catch_unwind(AssertUnwindSafe(f)) {
        Ok(Ok(v)) => Ok(v),
        Ok(Err(e)) => Err(to_py(e)),
        Err(p) => Err(panic_to_py(p)),
    }
}

fn json_to_py<'py>(py: Python<'py>, v: &impl serde::Serialize) -> PyResult<Bound<'py, PyAny>> {
    let text = serde_json::to_string(v).map_err(|e| Error::new_err(e.to_string()))?;
    py.import("json")?.call_method1("loads", (text,))
}

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

/// A stage given as usda text: written to a hidden temporary `.usda` in `base_dir`
/// (default: the working directory) so relative asset paths resolve against it; the
/// file is removed when this is dropped (right after the stage is loaded).
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

fn field_json(f: &nimbus::scene::Field) -> Value {
    json!({
        "prim_path": f.prim_path,
        "file": f.file.to_string(),
        "field_name": f.field_name,
        "field_index": f.field_index,
    })
}

/// What `nimbus info` reports, as data: the stage's volumes with their fields and
/// grids, lights, camera, render settings, the scene analysis and what `auto` picks.
#[pyfunction]
#[pyo3(signature = (stage=None, *, stage_text=None, base_dir=None, frame=None, octree_depth=8))]
fn info<'py>(
    py: Python<'py>,
    stage: Option<PathBuf>,
    stage_text: Option<String>,
    base_dir: Option<PathBuf>,
    frame: Option<f64>,
    octree_depth: u32,
) -> PyResult<Bound<'py, PyAny>> {
    let (path, tmp) = stage_file(stage, stage_text, base_dir)?;
    let o = Overrides {
        frame,
        octree_depth: Some(octree_depth.clamp(1, nimbus::volume::majorant::MAX_DEPTH)),
        ..Overrides::default()
    };
    let session = open_session(py, &path, &o)?;
    drop(tmp);
    let value = guarded(|| Ok(info_json(&session)))?;
    json_to_py(py, &value)
}

fn info_json(s: &Session) -> Value {
    let scene = &s.scene;
    let volumes: Vec<Value> = scene
        .volumes
        .iter()
        .map(|v| {
            let grids = |f: &nimbus::scene::Field| match vdb::list_grids(&f.file) {
                Ok(gs) => Value::Array(
                    gs.iter()
                        .map(|g| {
                            json!({"name": g.name, "type": g.value_type, "active_voxels": g.active_voxels})
                        })
                        .collect(),
                ),
                Err(_) => Value::Null,
            };
            let fields: serde_json::Map<String, Value> = v
                .fields
                .iter()
                .map(|(name, f)| {
                    let mut j = field_json(f);
                    j["grids"] = grids(f);
                    (name.clone(), j)
                })
                .collect();
            let e = &v.emission;
            json!({
                "prim_path": v.prim_path,
                "density_field": v.density.prim_path,
                "density_scale": v.density_scale,
                "absorption": v.absorption,
                "scattering": v.scattering,
                "anisotropy": v.anisotropy,
                "temperature_field": e.temperature.as_ref().map(|(n, _)| n),
                "temperature_scale": e.temperature_scale,
                "blackbody_intensity": e.blackbody_intensity,
                "emission_field": e.emission.as_ref().map(|(n, _)| n),
                "emission_color": e.emission_color,
                "emission_scale": e.emission_scale,
                "albedo_field": v.albedo.as_ref().map(|(n, _)| n),
                "material_shader": v.material_shader,
                "fields": fields,
            })
        })
        .collect();
    let mut lights = Vec::new();
    for l in &scene.distant_lights {
        lights.push(
            json!({"type": "distant", "prim_path": l.prim_path, "direction": l.direction,
            "intensity": l.intensity, "exposure": l.exposure, "color": l.color,
            "normalize": l.normalize, "angle": l.angle_degrees}),
        );
    }
    for l in &scene.dome_lights {
        lights.push(
            json!({"type": "dome", "prim_path": l.prim_path, "intensity": l.intensity,
            "exposure": l.exposure, "color": l.color, "texture_file": l.texture_file,
            "texture_format": l.texture_format}),
        );
    }
    for l in &scene.sphere_lights {
        lights.push(json!({"type": "sphere", "prim_path": l.prim_path,
            "position": l.light_to_world.w_axis.truncate().to_array(), "radius": l.radius,
            "intensity": l.intensity, "exposure": l.exposure, "color": l.color,
            "normalize": l.normalize, "treat_as_point": l.treat_as_point}));
    }
    for l in &scene.rect_lights {
        lights.push(json!({"type": "rect", "prim_path": l.prim_path,
            "position": l.light_to_world.w_axis.truncate().to_array(), "width": l.width,
            "height": l.height, "intensity": l.intensity, "exposure": l.exposure,
            "color": l.color, "normalize": l.normalize}));
    }
    let c = &scene.camera;
    let st = &scene.settings;
    // What `render` would do without flags (as `nimbus info` says): the stage may name
    // the majorant structure.
    let given = Given {
        majorants: st.octree_depth.is_some(),
        ..Given::default()
    };
    let (t, reason) = s.analysis.choose(TrackerSettings::default(), given);
    json!({
        "stage": s.stage_path.display().to_string(),
        "time": if scene.time.is_nan() { Value::Null } else { json!(scene.time) },
        "vdb_reader": vdb::active_reader().name(),
        "camera": {
            "prim_path": c.prim_path,
            "focal_length": c.focal_length,
            "horizontal_aperture": c.horizontal_aperture,
            "vertical_aperture": c.vertical_aperture,
            "clipping_range": c.clipping_range,
        },
        "lights": lights,
        "render_settings": {
            "prim_path": st.prim_path,
            "resolution": [st.resolution.0, st.resolution.1],
            "samples": st.samples,
            "max_depth": st.max_depth,
            "seed": st.seed,
            "tracker": st.tracker,
            "products": st.products.iter().map(|p| json!({
                "prim_path": p.prim_path,
                "product_name": p.product_name,
                "preview_name": p.preview_name,
                "vars": p.vars.iter().map(|v| v.source_name.clone()).collect::<Vec<_>>(),
            })).collect::<Vec<_>>(),
        },
        "volumes": volumes,
        "analysis": s.analysis,
        "auto": {
            "tracker": t.tracker.name(),
            "scheme": t.scheme.name(),
            "transmittance": t.transmittance.name(),
            "no_absorption_events": t.options.no_absorption_events,
            "reason": reason,
        },
        "warnings": s.warnings,
    })
}

/// The finished render: owns the session and the film so `write` can write exactly
/// what `nimbus render` writes.
#[pyclass(module = "nimbus._nimbus", name = "RenderResult", frozen)]
struct RenderResult {
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
    grid=None, camera=None, frame=None, output=None, stats=None, preview=None,
    progress=None
))]
#[allow(clippy::too_many_arguments)]
fn render(
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

/// An image argument of `compare`: an EXR path, or an array (H, W, C) / (H, W).
fn image_channels(
    obj: &Bound<'_, PyAny>,
) -> PyResult<(String, usize, usize, Vec<(String, Vec<f32>)>)> {
    if let Ok(path) = obj.extract::<PathBuf>() {
        let (w, h, chans) = read_all_channels(&path)
            .map_err(|e| Error::new_err(format!("{}: {e}", path.display())))?;
        return Ok((path.display().to_string(), w, h, chans));
    }
    let np = obj.py().import("numpy")?;
    let arr = np.call_method1("asarray", (obj, "float32"))?;
    let arr: PyReadonlyArrayDyn<'_, f32> = arr.extract()?;
    let shape = arr.shape().to_vec();
    let (h, w, c) = match shape.as_slice() {
        [h, w] => (*h, *w, 1),
        [h, w, c] if (1..=4).contains(c) => (*h, *w, *c),
        _ => {
            return Err(SettingsError::new_err(format!(
                "an image array has shape (H, W) or (H, W, C) with C in 1..4, got {shape:?}"
            )))
        }
    };
    let data: Vec<f32> = arr.as_array().iter().copied().collect();
    let names: &[&str] = match c {
        1 => &["R"],
        2 => &["R", "G"],
        3 => &["R", "G", "B"],
        _ => &["R", "G", "B", "A"],
    };
    let chans = names
        .iter()
        .enumerate()
        .map(|(k, n)| {
            (
                n.to_string(),
                data.iter().skip(k).step_by(c).copied().collect(),
            )
        })
        .collect();
    Ok(("<array>".into(), w, h, chans))
}

/// A channel by exact name, else a unique `layer.name` (as `nimbus compare` finds it).
fn find_channel<'a>(chans: &'a [(String, Vec<f32>)], name: &str) -> Option<&'a [f32]> {
    if let Some(c) = chans.iter().find(|c| c.0 == name) {
        return Some(&c.1);
    }
    let suffix = format!(".{name}");
    let hits: Vec<_> = chans.iter().filter(|c| c.0.ends_with(&suffix)).collect();
    match hits.as_slice() {
        [one] => Some(&one.1),
        _ => None,
    }
}

/// Values are clamped to ±this (the largest half float) before comparing, as
/// `nimbus compare` does (its module is private to the CLI, so the metric is restated
/// here; `tests/test_compare.py` checks both agree).
const CLAMP: f32 = 65504.0;
/// Added to b² in the relative MSE denominator (`nimbus compare`'s).
const REL_EPSILON: f64 = 0.01;

/// `nimbus compare`'s per-channel metrics of `a` against reference `b`.
fn channel_error(name: &str, a: &[f32], b: &[f32]) -> Value {
    let clamp = |v: f32| v.min(CLAMP).max(-CLAMP) as f64;
    let (mut se, mut rel, mut sa, mut sb) = (0f64, 0f64, 0f64, 0f64);
    let (mut na, mut nb) = (0u64, 0u64);
    for (&x, &y) in a.iter().zip(b) {
        na += !x.is_finite() as u64;
        nb += !y.is_finite() as u64;
        let (x, y) = (clamp(x), clamp(y));
        let d2 = (x - y) * (x - y);
        se += d2;
        rel += d2 / (y * y + REL_EPSILON);
        sa += x;
        sb += y;
    }
    let n = a.len().max(1) as f64;
    json!({
        "channel": name, "mse": se / n, "relmse": rel / n, "rmse": (se / n).sqrt(),
        "mean_a": sa / n, "mean_b": sb / n, "nonfinite_a": na, "nonfinite_b": nb,
    })
}

/// Per-channel error of image `a` against reference `b` (`nimbus compare a b --json`):
/// each is an EXR path or an array (H, W, C) whose channels are R, G, B, A.
#[pyfunction]
fn compare<'py>(
    py: Python<'py>,
    a: Bound<'py, PyAny>,
    b: Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyAny>> {
    let (na, wa, ha, ca) = image_channels(&a)?;
    let (nb, wb, hb, cb) = image_channels(&b)?;
    if (wa, ha) != (wb, hb) {
        return Err(SettingsError::new_err(format!(
            "the images differ in size: {na} is {wa}x{ha}, {nb} is {wb}x{hb}"
        )));
    }
    let mut channels = Vec::new();
    for name in ["R", "G", "B", "A"] {
        match (find_channel(&ca, name), find_channel(&cb, name)) {
            (Some(x), Some(y)) => channels.push(channel_error(name, x, y)),
            _ if name == "A" => {}
            (x, _) => {
                let which = if x.is_none() { &na } else { &nb };
                return Err(SettingsError::new_err(format!(
                    "{which}: no channel {name}"
                )));
            }
        }
    }
    let rgb = &channels[..3];
    let avg = |k: &str| {
        rgb.iter()
            .map(|c| c[k].as_f64().unwrap_or(f64::NAN))
            .sum::<f64>()
            / 3.0
    };
    let sum = |k: &str| rgb.iter().map(|c| c[k].as_u64().unwrap_or(0)).sum::<u64>();
    let rgb = json!({
        "channel": "RGB", "mse": avg("mse"), "relmse": avg("relmse"), "rmse": avg("rmse"),
        "mean_a": avg("mean_a"), "mean_b": avg("mean_b"),
        "nonfinite_a": sum("nonfinite_a"), "nonfinite_b": sum("nonfinite_b"),
    });
    let v = json!({
        "a": na, "b": nb, "width": wa, "height": ha, "clamp": CLAMP,
        "relmse_epsilon": REL_EPSILON, "channels": channels, "rgb": rgb,
    });
    json_to_py(py, &v)
}

/// Every channel of an EXR as float32 arrays (H, W), by channel name.
#[pyfunction]
fn read_exr<'py>(py: Python<'py>, path: PathBuf) -> PyResult<Bound<'py, PyDict>> {
    let (w, h, chans) = py
        .allow_threads(|| read_all_channels(&path))
        .map_err(|e| Error::new_err(format!("{}: {e}", path.display())))?;
    let d = PyDict::new(py);
    for (name, data) in chans {
        let arr: Bound<'py, PyArrayDyn<f32>> = PyArray1::from_vec(py, data).reshape(vec![h, w])?;
        d.set_item(name, arr)?;
    }
    Ok(d)
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

/// The VDB reader compiled in: "openvdb" (the C++ bridge) or "vdb-rs".
#[pyfunction]
fn vdb_reader() -> &'static str {
    vdb::active_reader().name()
}

#[pymodule]
fn _nimbus(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add("Error", py.get_type::<Error>())?;
    m.add("StageError", py.get_type::<StageError>())?;
    m.add("VdbError", py.get_type::<VdbError>())?;
    m.add("SettingsError", py.get_type::<SettingsError>())?;
    m.add("OutputError", py.get_type::<OutputError>())?;
    m.add_class::<RenderResult>()?;
    m.add_function(wrap_pyfunction!(info, m)?)?;
    m.add_function(wrap_pyfunction!(render, m)?)?;
    m.add_function(wrap_pyfunction!(compare, m)?)?;
    m.add_function(wrap_pyfunction!(read_exr, m)?)?;
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
