//! The renderer behind the render pass: a [`Session`] of the scene Hydra describes
//! (already converted by [`crate::scene`]), its film, and the pass schedule `nimbus
//! render` uses. Each `render_pass` adds one pass of samples; since each pixel's random
//! stream lives in the film, the image after the last pass is the one `nimbus render`
//! gives for the same scene, settings and seed.
//!
//! It knows nothing of the bridge: `crate::ffi` turns the bridge's structs into a
//! [`Scene`] and this module's results back into structs, and guards every call
//! against panics.

use crate::scene::STAGE_NAME;
use anyhow::{anyhow, Result};
use nimbus::render::film::{Aov, Film};
use nimbus::render::progressive::Clock;
use nimbus::render::progressive::{PassSchedule, Stopwatch};
use nimbus::render::session::{ExtraOutputs, Overrides, Session};
use nimbus::render::splits::SplitLayer;
use nimbus::scene::Scene;
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
    /// The finished film denoised (`nimbus:denoise`): its channels by name, read
    /// instead of the film's; or why denoising failed (shown in the stats line).
    denoised: Option<Result<Vec<(String, Vec<f32>)>, String>>,
}

/// What the render pass renders: nothing (after `clear`, or when the scene had no
/// volume or failed), or a render in progress.
#[derive(Default)]
pub struct Renderer {
    running: Option<Running>,
    /// The film size when there is nothing to render (no volume, or an error).
    size: (u32, u32),
    /// Threads the host synced prims on.
    sync_threads: u32,
}

/// Where a render stands after a pass.
#[derive(Clone, Debug, Default)]
pub struct PassState {
    pub spp: u32,
    pub target_spp: u32,
    pub converged: bool,
    /// Mean density lookups per sample so far.
    pub lookups_per_sample: f64,
    pub seconds: f64,
}

impl Renderer {
    /// Forgets the render in progress: until [`Renderer::start`] succeeds there is
    /// nothing to render, and the buffers are black at `size`.
    pub fn clear(&mut self, size: (u32, u32), sync_threads: u32) {
        self.running = None;
        self.size = size;
        self.sync_threads = sync_threads;
    }

    /// Starts rendering `scene` (whose conversion warned `warnings`) with the split
    /// layers the bound AOVs `aovs` ask for; returns the warnings to show.
    pub fn start(
        &mut self,
        scene: Scene,
        aovs: &[String],
        mut warnings: Vec<String>,
    ) -> Result<Vec<String>> {
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
        let (extras, layers) = split_layers(&session, aovs, &mut warnings)?;
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
            denoised: None,
        });
        Ok(warnings)
    }

    /// Drops the render in progress after an error, keeping the size.
    pub fn stop(&mut self) {
        self.running = None;
    }

    /// Renders one more pass (nothing once converged, or with nothing to render).
    pub fn render_pass(&mut self) -> PassState {
        let Some(r) = self.running.as_mut() else {
            return PassState {
                converged: true,
                ..PassState::default()
            };
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
        let state = info(r);
        // Denoised once, when the last pass is done (as `nimbus render` denoises the
        // finished frame); the passes before show the noisy image.
        if state.converged && r.session.denoise && r.denoised.is_none() {
            let d = nimbus::output::denoise::denoise_film(&r.film, &r.layers);
            r.denoised = Some(d.map(|(channels, _)| channels));
        }
        state
    }

    /// Copies AOV `name` into `out` (`components` floats per pixel, row 0 at the
    /// bottom as Hydra's buffers hold it); false when `name` is no AOV Nimbus has.
    pub fn read_aov(&self, name: &str, components: usize, out: &mut [f32]) -> bool {
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
            let values = match denoised(r, aov.channel_name()) {
                Some(v) => v.to_vec(),
                None => r.film.channel(*aov),
            };
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
        let layer = match ["R", "G", "B"].map(|c| denoised(r, &format!("{name}.{c}"))) {
            [Some(a), Some(b), Some(c)] => [a.to_vec(), b.to_vec(), c.to_vec()],
            _ => r.film.layer(i),
        };
        for (c, values) in layer.iter().enumerate().take(components) {
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
                let denoise = match &r.denoised {
                    None => String::new(),
                    Some(Ok(_)) => ", denoised".to_string(),
                    Some(Err(e)) => format!(", not denoised: {e}"),
                };
                format!(
                    "{STAGE_NAME}: {}x{}, {} of {} spp in {} passes, tracker {}, {:.2} lookups/sample, {:.3} s loading, {:.3} s rendering, prims synced on {} threads{denoise}",
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

/// The denoised channel `name`, once the render is finished and denoised.
fn denoised<'a>(r: &'a Running, name: &str) -> Option<&'a [f32]> {
    let Some(Ok(channels)) = &r.denoised else {
        return None;
    };
    channels
        .iter()
        .find(|c| c.0 == name)
        .map(|c| c.1.as_slice())
}

fn info(r: &Running) -> PassState {
    let (totals, samples, _) = r.film.totals();
    PassState {
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
}
