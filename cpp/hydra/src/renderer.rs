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
use nimbus::render::session::{ExtraOutputs, Overrides, Session};
use nimbus::render::splits::SplitLayer;
use nimbus::scene::RenderSettings;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::Path;

/// A render in progress.
struct Running {
    session: Session,
    /// The split layers the bound AOVs ask for, gathered while rendering.
    extras: ExtraOutputs,
    /// The AOV name of each of the film's split layers, in its order.
    layers: Vec<String>,
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
            let (extras, layers) = split_layers(&session, &desc.aovs, &mut warnings)?;
            let film = {
                let mut job = session.job(true);
                extras.apply(&mut job);
                job.new_film(None)
            };
            let pool = session.pool(0)?;
            let schedule = PassSchedule::new(session.spp, None, None);
            self.running = Some(Running {
                session,
                extras,
                layers,
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
                let mut job = r.session.job(true);
                r.extras.apply(&mut job);
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
        if is_split_aov(name) {
            return self.copy_layer(name, components, out);
        }
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

    /// A split AOV: its layer's R, G, B (the rest of `components` cleared). Black when
    /// the render has no such layer (its group matched nothing: a warning said so).
    fn copy_layer(&self, name: &str, components: usize, out: &mut [f32]) -> bool {
        out.fill(0.0);
        let Some(r) = &self.running else {
            return true;
        };
        let Some(i) = r.layers.iter().position(|l| l == name) else {
            return true;
        };
        let (w, h) = (r.film.width as usize, r.film.height as usize);
        if out.len() < w * h * components {
            return false;
        }
        for (c, values) in r.film.layer(i).iter().enumerate().take(components) {
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

/// The split layer AOV `name` asks for: `lpe:` and a light path expression, or a
/// shorthand (`lightgroup:GROUP`, `direct`, `indirect`, `emission`) as `nimbus render
/// --aovs` takes them (docs/aovs.md).
fn split_layer(name: &str) -> Option<Result<SplitLayer, String>> {
    if name.starts_with("lpe:") {
        Some(SplitLayer::parse(name, name, "lpe"))
    } else {
        SplitLayer::parse(name, name, "raw").ok().map(Ok)
    }
}

/// Whether `name` is a split AOV (an RGB image of part of the beauty).
pub fn is_split_aov(name: &str) -> bool {
    split_layer(name).is_some()
}

/// The split layers of the bound AOVs `aovs`, in the film's order, and their names.
/// A light path expression Nimbus cannot split, or a light group that matches no light
/// or volume, is a warning naming it (its buffer stays black): a host should not lose
/// the whole render for one AOV it offered.
fn split_layers(
    session: &Session,
    aovs: &[String],
    warnings: &mut Vec<String>,
) -> Result<(ExtraOutputs, Vec<String>)> {
    let mut layers = Vec::new();
    let mut names = Vec::new();
    for name in aovs {
        if names.contains(name) {
            continue;
        }
        let layer = match split_layer(name) {
            None => continue,
            Some(Err(e)) => {
                warnings.push(format!("{STAGE_NAME}: AOV {name}: {e}"));
                continue;
            }
            Some(Ok(l)) => l,
        };
        if let Err(e) = session.extra_outputs(vec![layer.clone()], false) {
            warnings.push(format!("{STAGE_NAME}: AOV {name}: {e:#}"));
            continue;
        }
        layers.push(layer);
        names.push(name.clone());
    }
    let extras = session
        .extra_outputs(layers, false)
        .map_err(|e| anyhow!("{e:#}"))?;
    Ok((extras, names))
}

/// Whether hdNimbus writes an AOV of this name.
pub fn is_aov(name: &str) -> bool {
    is_split_aov(name)
        || name == "color"
        || name == "depth"
        || Aov::from_name(name).is_some_and(|a| a.uses_counters() || a == Aov::Variance)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ffi::bridge::{CameraDesc, LightDesc};
    use crate::scene::tests::{identity, light, smoke_volume};
    use glam::DVec3;

    #[test]
    fn split_aov_names_are_the_shorthands_and_lpes() {
        for name in [
            "lightgroup:key",
            "lightgroup:/World/Sun",
            "direct",
            "indirect",
            "emission",
            "lpe:C.*<L.'key'>",
            "lpe:CX",
        ] {
            assert!(is_split_aov(name) && is_aov(name), "{name}");
        }
        for name in [
            "color",
            "depth",
            "lookups",
            "lightgroup:",
            "normal",
            "primId",
        ] {
            assert!(!is_split_aov(name), "{name}");
        }
    }

    /// A slab of density 1 over [-1, 1]³ lit by a sun of group `key` and a sphere
    /// light of none, seen from z = 5: the bound split AOVs are filled, the groups sum
    /// to the beauty within the f32 rounding of each mean, and an AOV whose group
    /// matches nothing (or an expression Nimbus cannot split) is a warning naming it and
    /// a black buffer, not a lost render.
    #[test]
    fn split_aovs_are_filled_and_a_bad_one_is_a_warning() {
        let dir = std::env::temp_dir().join(format!("hdnimbus-aovs-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let vdb = dir.join("slab.vdb");
        let vs = 2.0 / 16.0;
        let grid = nimbus::volume::procedural::grid_from_fn(
            "density",
            [16; 3],
            DVec3::splat(-1.0 + 0.5 * vs),
            vs,
            |_| 1.0,
        );
        nimbus::volume::vdb::write_float_grid(&vdb, &grid).unwrap();
        let mut volume = smoke_volume();
        volume.fields[0].file = vdb.to_str().unwrap().into();
        let sun = LightDesc {
            light_group: "key".into(),
            ..light("distantLight")
        };
        let mut bulb = light("sphereLight");
        bulb.xform[13] = 3.0;
        bulb.radius = 0.1;
        bulb.intensity = 50.0;
        let mut cam = identity();
        cam[14] = 5.0;
        let (w, h) = (8u32, 6u32);
        let desc = SceneDesc {
            camera: CameraDesc {
                path: "/cam".into(),
                xform: cam,
                focal_length: 5.0,
                horizontal_aperture: 3.6,
                vertical_aperture: 2.7,
                near: 0.1,
                far: 100.0,
                ..CameraDesc::default()
            },
            has_camera: true,
            lights: vec![sun, bulb],
            volumes: vec![volume],
            width: w,
            height: h,
            aovs: [
                "color",
                "lightgroup:key",
                "lightgroup:/sphereLight",
                "lightgroup:nothing",
                "lpe:CX",
                "lookups",
            ]
            .map(String::from)
            .to_vec(),
            ..SceneDesc::default()
        };
        let mut r = new_renderer();
        let warnings = r.reset(&desc).unwrap();
        std::fs::remove_dir_all(&dir).unwrap();
        for bad in ["AOV lightgroup:nothing", "AOV lpe:CX"] {
            assert!(
                warnings.iter().any(|w| w.contains(bad)),
                "no warning naming {bad}: {warnings:?}"
            );
        }
        while !r.render_pass().unwrap().converged {}
        let n = (w * h) as usize;
        let read = |name: &str, k: usize| {
            let mut v = vec![f32::NAN; n * k];
            assert!(r.read_aov(name, k, &mut v), "{name}");
            v
        };
        let color = read("color", 4);
        let key = read("lightgroup:key", 3);
        let bulb = read("lightgroup:/sphereLight", 3);
        assert!(read("lightgroup:nothing", 3).iter().all(|&v| v == 0.0));
        let total = |v: &[f32]| v.iter().map(|&x| x as f64).sum::<f64>();
        assert!(total(&key) > 0.0 && total(&bulb) > 0.0);
        for p in 0..n {
            for c in 0..3 {
                let (b, s) = (
                    color[p * 4 + c] as f64,
                    key[p * 3 + c] as f64 + bulb[p * 3 + c] as f64,
                );
                let bound = (b.abs() + s.abs()) * 2f64.powi(-24) + 1e-30;
                assert!(
                    (s - b).abs() <= bound,
                    "pixel {p} channel {c}: key + bulb {s}, beauty {b}"
                );
            }
        }
    }
}
