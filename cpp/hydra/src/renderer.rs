//! The Rust half of the render pass: a [`Session`] of the scene Hydra describes, its
//! film, and the pass schedule `nimbus render` uses. Each `render_pass` adds one pass of
//! samples; since each pixel's random stream lives in the film, the image after the
//! last pass is the one `nimbus render` gives for the same scene, settings and seed.
//!
//! Nothing here may unwind into C++: every entry point runs under `catch_unwind` and
//! turns a panic into an error (cxx makes errors C++ exceptions, which the C++ half
//! catches and reports).

use crate::ffi::bridge::{PassInfo, SceneDesc, SettingDescriptor};
use crate::scene::{scene_of, STAGE_NAME};
use anyhow::{anyhow, Result};
use nimbus::render::film::{Aov, Film};
use nimbus::render::progressive::Clock;
use nimbus::render::progressive::{PassSchedule, Stopwatch};
use nimbus::render::session::{Overrides, Session};
use nimbus::scene::RenderSettings;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::Path;

/// A render in progress.
struct Running {
    session: Session,
    film: Film,
    schedule: PassSchedule,
    pool: rayon::ThreadPool,
    spp: u32,
    passes: u32,
    seconds: f64,
}

pub struct Renderer {
    running: Option<Running>,
    /// The film size when there is nothing to render (no volume, or an error).
    size: (u32, u32),
    /// Threads the host synced prims on.
    sync_threads: u32,
}

pub fn new_renderer() -> Box<Renderer> {
    Box::new(Renderer {
        running: None,
        size: (0, 0),
        sync_threads: 0,
    })
}

/// Runs `f`, turning a panic into an error.
fn guarded<T>(what: &str, f: impl FnOnce() -> Result<T>) -> Result<T> {
    match catch_unwind(AssertUnwindSafe(f)) {
        Ok(r) => r,
        Err(payload) => {
            let msg = payload
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| payload.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "unknown panic".to_string());
            Err(anyhow!("{STAGE_NAME}: internal error in {what}: {msg}"))
        }
    }
}

impl Renderer {
    pub fn reset(&mut self, desc: &SceneDesc) -> Result<Vec<String>> {
        self.running = None;
        self.size = (desc.width, desc.height);
        self.sync_threads = desc.sync_threads;
        guarded("reset", || {
            let (scene, mut warnings) = scene_of(desc)?;
            if scene.volumes.is_empty() {
                warnings.push(format!(
                    "{STAGE_NAME}: the scene has no volume; the image is empty"
                ));
                return Ok(warnings);
            }
            let session = Session::from_scene(Path::new(STAGE_NAME), scene, &Overrides::default())
                .map_err(|e| anyhow!("{e:#}"))?;
            warnings.extend(session.scene.warnings.lines());
            warnings.extend(session.warnings.iter().cloned());
            if let Some(line) = session.auto_summary() {
                warnings.push(line);
            }
            let film = session.job(true).new_film(None);
            let pool = session.pool(0)?;
            let schedule = PassSchedule::new(session.spp, None, None);
            self.running = Some(Running {
                session,
                film,
                schedule,
                pool,
                spp: 0,
                passes: 0,
                seconds: 0.0,
            });
            Ok(warnings)
        })
    }

    pub fn render_pass(&mut self) -> Result<PassInfo> {
        let result = guarded("render_pass", || {
            let Some(r) = self.running.as_mut() else {
                return Ok(PassInfo {
                    converged: true,
                    ..PassInfo::default()
                });
            };
            if let Some(n) = r.schedule.next(r.seconds, 0.0) {
                let clock = Stopwatch::start(Clock::Wall);
                let job = r.session.job(true);
                let film = &mut r.film;
                r.pool.install(|| job.render_pass(film, n, &|| {}));
                let dt = clock.elapsed();
                r.schedule.finished(n, dt);
                r.spp += n;
                r.passes += 1;
                r.seconds += dt;
            }
            Ok(info(r))
        });
        if result.is_err() {
            self.running = None;
        }
        result
    }

    pub fn read_aov(&self, name: &str, components: usize, out: &mut [f32]) -> bool {
        guarded("read_aov", || Ok(self.copy_aov(name, components, out))).unwrap_or(false)
    }

    fn copy_aov(&self, name: &str, components: usize, out: &mut [f32]) -> bool {
        let channels: Vec<Aov> = match name {
            "color" => vec![Aov::R, Aov::G, Aov::B, Aov::A],
            "depth" => Vec::new(),
            other => match Aov::from_name(other) {
                Some(a) => vec![a],
                None => return false,
            },
        };
        let clear = if name == "depth" { 1.0 } else { 0.0 };
        out.fill(clear);
        let Some(r) = &self.running else {
            return true;
        };
        if components == 0 || channels.is_empty() {
            return true;
        }
        let (w, h) = (r.film.width as usize, r.film.height as usize);
        if out.len() < w * h * components {
            return false;
        }
        for (c, aov) in channels.iter().enumerate().take(components) {
            let values = r.film.channel(*aov);
            // The film's row 0 is the top; Hydra's buffers start at the bottom row.
            for y in 0..h {
                let dst = (h - 1 - y) * w;
                for x in 0..w {
                    out[(dst + x) * components + c] = values[y * w + x];
                }
            }
        }
        true
    }

    pub fn stats_line(&self) -> String {
        match &self.running {
            None => format!(
                "{STAGE_NAME}: {}x{}: nothing to render, prims synced on {} threads",
                self.size.0, self.size.1, self.sync_threads
            ),
            Some(r) => {
                let i = info(r);
                let s = &r.session;
                format!(
                    "{STAGE_NAME}: {}x{}, {} of {} spp in {} passes, tracker {}, {:.2} lookups/sample, {:.3} s loading, {:.3} s rendering, prims synced on {} threads",
                    s.width,
                    s.height,
                    i.spp,
                    i.target_spp,
                    r.passes,
                    s.tracking.tracker.name(),
                    i.lookups_per_sample,
                    s.load_seconds,
                    i.seconds,
                    self.sync_threads
                )
            }
        }
    }
}

fn info(r: &Running) -> PassInfo {
    let (totals, samples, _) = r.film.totals();
    PassInfo {
        spp: r.spp,
        target_spp: r.session.spp,
        converged: r.spp >= r.session.spp,
        lookups_per_sample: match samples {
            0 => 0.0,
            n => totals.density_lookups as f64 / n as f64,
        },
        seconds: r.seconds,
    }
}

/// The settings hdNimbus reads (the render-settings schema's names), with the defaults
/// a stage without them gets.
pub fn setting_descriptors() -> Vec<SettingDescriptor> {
    let d = RenderSettings::default();
    let number = |key: &str, name: &str, v: f64, is_int: bool| SettingDescriptor {
        key: key.to_string(),
        name: name.to_string(),
        is_text: false,
        is_int,
        number: v,
        text: String::new(),
    };
    let token = |key: &str, name: &str, v: &str| SettingDescriptor {
        key: key.to_string(),
        name: name.to_string(),
        is_text: true,
        is_int: false,
        number: 0.0,
        text: v.to_string(),
    };
    vec![
        number(
            "nimbus:samples",
            "Samples per pixel",
            d.samples as f64,
            true,
        ),
        number("nimbus:seed", "Seed", d.seed as f64, true),
        number(
            "nimbus:maxDepth",
            "Maximum scattering depth",
            d.max_depth as f64,
            true,
        ),
        token("nimbus:tracker", "Tracker", "auto"),
        token("nimbus:scheme", "Scheme", ""),
        token("nimbus:transmittance", "Transmittance estimator", ""),
        number(
            "nimbus:control",
            "Decomposition control",
            nimbus::track::select::TrackerSettings::default().control as f64,
            false,
        ),
        number(
            "nimbus:octreeDepth",
            "Majorant octree depth (0: flat grid)",
            0.0,
            true,
        ),
    ]
}

/// Whether hdNimbus writes an AOV of this name.
pub fn is_aov(name: &str) -> bool {
    name == "color"
        || name == "depth"
        || Aov::from_name(name).is_some_and(|a| a.uses_counters() || a == Aov::Variance)
}
