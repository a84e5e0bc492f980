//! `RenderResult`: what `render` returns. It keeps the session and the film, not just
//! the arrays, so `write` can write later exactly what `nimbus render` writes.

use crate::errors::guarded;
use nimbus::output::products::{requested_aovs, OutputRequest, Outputs};
use nimbus::output::stats::RunFacts;
use nimbus::render::film::{Aov, Film, Region};
use nimbus::render::progressive::Progress;
use nimbus::render::session::Session;
use nimbus::render::splits::SplitLayer;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};
use std::path::PathBuf;
use std::sync::Arc;

/// The finished render: owns the session and the film so `write` can write exactly
/// what `nimbus render` writes.
#[pyclass(module = "nimbus._nimbus", name = "RenderResult", frozen)]
pub struct RenderResult {
    #[pyo3(get)]
    pub rgba: Py<PyAny>,
    #[pyo3(get)]
    pub aovs: Py<PyDict>,
    #[pyo3(get)]
    pub stats: Py<PyAny>,
    #[pyo3(get)]
    pub warnings: Py<PyList>,
    #[pyo3(get)]
    pub auto_summary: Option<String>,
    pub session: Arc<Session>,
    pub film: Film,
    pub progress: Progress,
    pub facts: RunFacts,
    pub aov_list: Vec<Aov>,
    /// The split layers the film holds, in its order (`write` writes them).
    pub layers: Vec<SplitLayer>,
    pub region: Option<Region>,
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
                let mut outputs =
                    Outputs::resolve(&s.stage_path, &s.scene.settings, &request, s.frame, false)?;
                outputs.set_denoise(s.denoise)?;
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
