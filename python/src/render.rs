//! `nimbus.render`: a render through the library's session (`nimbus::render::session`),
//! step by step as `nimbus render` does it: the keyword arguments checked
//! (`settings`), the stage read on a worker thread (`loading`), the files asked for
//! resolved, the passes rendered on a worker thread while this thread waits with the
//! GIL released and calls the callbacks (`passes`), and the film handed back as numpy
//! arrays (`arrays`) in a `RenderResult` (`result`).

use crate::arrays::{aov_dict, image_shape, interleaved_rgba, rgba_array};
use crate::errors::guarded;
use crate::json::json_to_py;
use crate::loading::{open_session, warn_all};
use crate::passes::{render_passes, Callbacks};
use crate::result::RenderResult;
use crate::settings::{
    check_region_fits, check_tracker, parse_choice, parse_region, requested_aovs_and_layers,
};
use crate::stage_input::stage_file;
use nimbus::output::denoise::{check_available, denoise_film, NOISY};
use nimbus::output::exr::Denoise;
use nimbus::output::products::{OutputRequest, Outputs};
use nimbus::output::stats::{RenderStats, RunFacts};
use nimbus::render::sampler::SamplerKind;
use nimbus::render::session::{Overrides, Session};
use nimbus::track::select::{SchemeKind, TransmittanceKind};
use numpy::PyArrayMethods;
use pyo3::prelude::*;
use pyo3::types::PyList;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

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
/// them nothing is written (use RenderResult.write). `denoise=True` (`--denoise`):
/// `rgba` and the split layers are denoised with Open Image Denoise, and `aovs` also
/// holds the noisy beauty ("noisy") and the albedo it was guided by ("albedo"), each
/// (H, W, 3); None leaves it to the stage's `nimbus:denoise`.
///
/// The GIL is released while the stage loads and renders. On the calling thread:
/// `progress(done, total)` as rows finish (total = spp * height; None with a time
/// limit alone); `on_pass(spp, total_spp, rgba)` after each pass of the progressive
/// render (the CLI's passes: 1 sample, then doubling, each at most about 2 s;
/// `spp` samples per pixel so far, `total_spp` the cap or None, `rgba` a float32
/// (H, W, 4) copy of the image so far); `on_noise(spp, noise, converged)` after each
/// pass, before `on_pass` (`noise` the mean over the pixels of adaptive sampling's
/// noise estimate, as the CLI's progress line and the stats' `estimated_noise`;
/// `converged` the share of pixels adaptive sampling stopped, None without it);
/// `cancel()` every 20 ms while the stage loads
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
    majorant_cell=None, octree_depth=None, octree_prune=None,
    tracker=None, scheme=None, transmittance=None, control=None,
    reduced_termination=false, no_absorption_events=false, majorant_scale=1.0,
    profile=false, no_specialise=false, aovs=None, time_limit=None,
    noise_threshold=None, min_spp=None, denoise=None, strict=false, no_default_lights=false, grid=None, camera=None, frame=None, output=None, stats=None, preview=None,
    progress=None, on_pass=None, on_noise=None, cancel=None
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
    octree_prune: Option<f32>,
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
    noise_threshold: Option<f64>,
    min_spp: Option<u32>,
    denoise: Option<bool>,
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
    on_noise: Option<Py<PyAny>>,
    cancel: Option<Py<PyAny>>,
) -> PyResult<RenderResult> {
    let wall = Instant::now();
    check_tracker(tracker.as_ref())?;
    let region = parse_region(region)?;
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
        octree_prune,
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
        noise_threshold,
        min_spp,
        denoise,
        grid,
        strict,
        no_default_lights,
        ..Overrides::default()
    };
    let (aov_list, requested_layers) = requested_aovs_and_layers(aovs)?;
    let (path, tmp) = stage_file(stage, stage_text, base_dir)?;
    let session = Arc::new(open_session(py, &path, &overrides, cancel.as_ref())?);
    drop(tmp);
    check_region_fits(region, &session)?;
    let request = OutputRequest {
        output,
        aovs: aov_list.clone(),
        layers: requested_layers.clone(),
        stats,
        preview,
        region: region.is_some(),
        ..OutputRequest::default()
    };
    let mut outputs = resolve_outputs(&path, &session, &request, frame)?;
    // As the CLI: a build without Open Image Denoise refuses before rendering.
    match &mut outputs {
        Some(o) => guarded(|| o.set_denoise(session.denoise))?,
        None if session.denoise => guarded(|| check_available().map_err(anyhow::Error::msg))?,
        None => {}
    }
    warn_all(py, &session.warnings)?;

    // The film's split layers: every layer a product written asks for (the requested
    // ones among them, as the CLI's), else the requested ones.
    let layers = match &outputs {
        Some(o) => o.split_layers(),
        None => requested_layers.clone(),
    };
    let deep = outputs.as_ref().is_some_and(|o| o.deep());
    let extra = guarded(|| session.extra_outputs(layers.clone(), deep))?;

    let shape = image_shape(session.width, session.height, region);
    let callbacks = Callbacks {
        progress,
        on_pass,
        on_noise,
        cancel,
    };
    let (film, p, threads, counting) =
        render_passes(py, &session, extra, region, shape, &callbacks)?;
    let facts = RunFacts {
        wall_seconds: wall.elapsed().as_secs_f64(),
        threads,
        counting,
        tile: None,
    };
    if let Some(outputs) = &outputs {
        py.allow_threads(|| guarded(|| outputs.write(&session, &film, &facts, &p)))?;
    }
    // Denoised: the beauty and the layers asked for are the denoised ones, the noisy
    // beauty and the albedo are in `aovs` ("noisy", "albedo"), as the EXR has them.
    let names: Vec<String> = layers.iter().map(|l| l.name.clone()).collect();
    let denoised = match session.denoise {
        true => Some(py.allow_threads(|| {
            guarded(|| denoise_film(&film, &names).map_err(anyhow::Error::msg))
        })?),
        false => None,
    };
    let rgba = match &denoised {
        Some((chans, _)) => interleave(chans, &["R", "G", "B", "A"]),
        None => interleaved_rgba(&film),
    };
    let rgba = rgba_array(py, rgba, shape)?;
    let aovs = aov_dict(py, &film, &aov_list, &layers, &requested_layers, shape)?;
    if let Some((chans, _)) = &denoised {
        let rgb = |l: &str| interleave(chans, &["R", "G", "B"].map(|c| format!("{l}.{c}")));
        for l in requested_layers.iter().map(|l| l.name.as_str()) {
            aovs.set_item(
                l,
                numpy::PyArray1::from_vec(py, rgb(l)).reshape([shape.0, shape.1, 3])?,
            )?;
        }
        for l in [NOISY, "albedo"] {
            aovs.set_item(
                l,
                numpy::PyArray1::from_vec(py, rgb(l)).reshape([shape.0, shape.1, 3])?,
            )?;
        }
    }
    let stats_value = guarded(|| {
        let mut stats = RenderStats::new(&session, &film, &p, &facts);
        if let Some((_, d)) = &denoised {
            stats.denoise = Denoise::Done.attribute();
            stats.denoise_seconds = d.seconds;
        }
        Ok(stats)
    })?;
    let stats_py = json_to_py(py, &stats_value)?;
    let warnings = PyList::new(py, &session.warnings)?;
    let auto_summary = session.auto_summary();
    Ok(RenderResult {
        rgba: rgba.unbind(),
        aovs: aovs.unbind(),
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

/// The files asked for (`output`, `stats`, `preview`). Unlike the CLI, which always
/// writes the stage's products, nothing is written unless asked; they are resolved
/// before rendering so a bad path fails at once.
fn resolve_outputs(
    path: &Path,
    session: &Session,
    request: &OutputRequest,
    frame: Option<f64>,
) -> PyResult<Option<Outputs>> {
    if request.output.is_none() && request.stats.is_none() && request.preview.is_none() {
        return Ok(None);
    }
    guarded(|| Outputs::resolve(path, &session.scene.settings, request, frame, false)).map(Some)
}

/// The named channels `names` of `chans` interleaved (pixels of `names.len()` values).
fn interleave<S: AsRef<str>>(chans: &[(String, Vec<f32>)], names: &[S]) -> Vec<f32> {
    let planes: Vec<&[f32]> = names
        .iter()
        .map(|n| {
            chans
                .iter()
                .find(|c| c.0 == n.as_ref())
                .map_or(&[][..], |c| c.1.as_slice())
        })
        .collect();
    let n = planes.iter().map(|p| p.len()).max().unwrap_or(0);
    let mut v = Vec::with_capacity(n * planes.len());
    for i in 0..n {
        v.extend(planes.iter().map(|p| p.get(i).copied().unwrap_or(0.0)));
    }
    v
}
