//! The reference image of `nimbus bench error`: loaded from an EXR, or rendered with many
//! samples by delta tracking and cached under a key that changes whenever anything that
//! could change the image does.

use crate::output::compare::Image;
use crate::output::exr::{write_exr, ExrMetadata};
use crate::render::analysis::CodePaths;
use crate::render::film::{Aov, Film};
use crate::render::job::RenderJob;
use crate::render::progressive::{render_progressive, Budget, Clock};
use crate::scene::Scene;
use crate::track::select::TrackerSettings;
use crate::volume::asset::AssetLocation;
use anyhow::{bail, Context, Result};
use std::hash::Hasher;
use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;

/// R, G, B of an image, row-major.
pub struct Rgb {
    pub width: usize,
    pub height: usize,
    pub channels: [Vec<f32>; 3],
}

impl Rgb {
    pub fn from_film(film: &Film) -> Rgb {
        Rgb {
            width: film.width as usize,
            height: film.height as usize,
            channels: [Aov::R, Aov::G, Aov::B].map(|a| film.channel(a)),
        }
    }

    /// R, G, B of an EXR, found by name like `nimbus compare` finds them.
    pub fn read(path: &Path) -> Result<Rgb> {
        let image = Image::read(path)?;
        let mut channels: [Vec<f32>; 3] = Default::default();
        for (c, name) in channels.iter_mut().zip(["R", "G", "B"]) {
            *c = image.channel(name)?.to_vec();
        }
        Ok(Rgb {
            width: image.width,
            height: image.height,
            channels,
        })
    }
}

/// How the reference is rendered (everything else comes from the stage).
#[derive(Clone, Copy, Debug)]
pub struct ReferenceSettings {
    pub spp: u32,
    pub seed: u64,
}

/// The default cache folder: `$XDG_CACHE_HOME/nimbus`, else `$HOME/.cache/nimbus`.
pub fn default_cache_dir() -> Option<PathBuf> {
    let nonempty = |k: &str| std::env::var_os(k).filter(|v| !v.is_empty());
    nonempty("XDG_CACHE_HOME")
        .map(PathBuf::from)
        .or_else(|| nonempty("HOME").map(|h| PathBuf::from(h).join(".cache")))
        .map(|d| d.join("nimbus"))
}

/// The cache key: FNV-1a 64 (stable across runs and builds) over the stage file's bytes,
/// the evaluated scene (camera, lights, volumes with their resolved field paths and
/// coefficients, render settings: this covers sublayers and references), each field
/// file's path, size and modification time, the job (resolution, depth, majorant
/// structure), the reference settings and the Nimbus version.
pub fn cache_key(scene: &Scene, job: &RenderJob, r: &ReferenceSettings) -> Result<u64> {
    let mut h = fnv::FnvHasher::default();
    let mut put = |s: &str| {
        h.write(s.as_bytes());
        h.write(&[0xff]);
    };
    let stage = std::fs::read(&scene.stage_path)
        .with_context(|| format!("{}: cannot read the stage", scene.stage_path.display()))?;
    put(&format!("stage bytes {}", stage.len()));
    put(&String::from_utf8_lossy(&stage));
    put(&format!("{scene:?}"));
    for v in &scene.volumes {
        if let Some(AssetLocation::File(p)) = v.shape.field().map(|f| &f.file) {
            // A missing file fails later, when the medium is loaded.
            let meta = std::fs::metadata(p).ok();
            let mtime = meta
                .as_ref()
                .and_then(|m| m.modified().ok())
                .and_then(|t| t.duration_since(std::time::UNIX_EPOCH).ok());
            put(&format!(
                "field {} {:?} {:?}",
                p.display(),
                meta.map(|m| m.len()),
                mtime
            ));
        }
    }
    put(&format!(
        "job {}x{} depth {} majorants {}",
        job.width,
        job.height,
        job.max_depth,
        // One medium keeps the key of references cached before several volumes.
        match job.media {
            [m] => format!("{:?}", m.majorants.spec()),
            media => format!(
                "{:?}",
                media.iter().map(|m| m.majorants.spec()).collect::<Vec<_>>()
            ),
        }
    ));
    put(&format!(
        "reference {:?} {:?} nimbus {}",
        r,
        TrackerSettings::default(),
        env!("CARGO_PKG_VERSION")
    ));
    Ok(h.finish())
}

/// The cached reference for `job` (its tracking and seed are replaced by the reference
/// settings), rendered and written to `cache_dir` first if it is not there.
pub fn cached_or_render(
    scene: &Scene,
    job: &RenderJob,
    r: &ReferenceSettings,
    cache_dir: &Path,
    pool: &rayon::ThreadPool,
) -> Result<(Rgb, PathBuf)> {
    let key = cache_key(scene, job, r)?;
    let path = cache_dir.join(format!("reference-{key:016x}.exr"));
    if path.is_file() {
        match Rgb::read(&path) {
            Ok(rgb) if (rgb.width, rgb.height) == (job.width as usize, job.height as usize) => {
                eprintln!(
                    "nimbus: reusing the cached reference {} ({} spp, seed {})",
                    path.display(),
                    r.spp,
                    r.seed
                );
                return Ok((rgb, path));
            }
            // A damaged or foreign file under our name: render it again.
            _ => eprintln!(
                "nimbus: warning: the cached reference {} is unreadable or has the wrong size; rendering it again",
                path.display()
            ),
        }
    }
    std::fs::create_dir_all(cache_dir)
        .with_context(|| format!("cannot create the cache folder {}", cache_dir.display()))?;
    eprintln!(
        "nimbus: rendering the reference: delta tracking, {} spp, seed {}, {}x{} (cached as {})",
        r.spp,
        r.seed,
        job.width,
        job.height,
        path.display()
    );
    let reference_job = RenderJob {
        paths: CodePaths::default(),
        spp: r.spp,
        seed: r.seed,
        tracking: TrackerSettings::default(),
        ..*job
    };
    let budget = Budget {
        clock: Clock::Wall,
        spp_cap: r.spp,
        time_limit: None,
        checkpoint: None,
    };
    let never = AtomicBool::new(false);
    let (film, p) = render_progressive(
        &reference_job,
        None,
        pool,
        &budget,
        &never,
        &|_| {},
        |_, p| {
            eprintln!(
                "nimbus: reference: {}/{} spp, {:.1} s",
                p.spp, r.spp, p.seconds
            );
            Ok::<(), anyhow::Error>(())
        },
    )?;
    let (_, _, nonfinite) = film.totals();
    if nonfinite > 0 {
        bail!("the reference has {nonfinite} NaN or infinite samples; it was not cached");
    }
    write_exr(
        &path,
        &film,
        &[Aov::R, Aov::G, Aov::B, Aov::A],
        &ExrMetadata {
            stage: scene.stage_path.display().to_string(),
            tracker: reference_job.tracking.tracker.name().into(),
            scheme: reference_job.tracking.scheme.name().into(),
            transmittance: reference_job.tracking.transmittance.name().into(),
            spp: p.spp,
            render_seconds: p.seconds,
            time: scene.time,
            product: None,
            denoise: Default::default(),
            farm: None,
        },
    )?;
    Ok((Rgb::from_film(&film), path))
}
