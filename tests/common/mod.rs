//! Shared pieces of the integration tests: statistics helpers, a 1-D analytic medium and
//! a renderer over every tracker setting (the stress tests), and in submodules the
//! inputs from outside the repository (`data`: the shared data and Python's `pxr`, with
//! the `NIMBUS_REQUIRE_DATA` switch).
#![allow(dead_code)]

pub mod cli;
pub mod data;

#[allow(unused_imports)] // not every test binary uses each
pub use data::{missing, pxr_fixtures, pxr_python, python_imports, repo, shared_data, shared_file};

use glam::{DMat4, DVec3};
use nimbus::render::analysis::CodePaths;
use nimbus::render::camera::CameraRays;
use nimbus::render::film::{Aov, Film};
use nimbus::render::job::RenderJob;
use nimbus::render::lights::Lights;
use nimbus::render::sampler::SamplerKind;
use nimbus::scene::Camera;
use nimbus::track::select::{
    LightSampling, SchemeKind, TrackerKind, TrackerSettings, TransmittanceKind,
};
use nimbus::volume::counters::Counters;
use nimbus::volume::grid::Grid;
use nimbus::volume::medium::Medium;
use nimbus::volume::procedural::grid_from_fn;

/// Mean and standard error of samples.
pub fn mean_se(v: &[f64]) -> (f64, f64) {
    let n = v.len() as f64;
    let m = v.iter().sum::<f64>() / n;
    let var = v.iter().map(|x| (x - m) * (x - m)).sum::<f64>() / (n - 1.0);
    (m, (var / n).sqrt())
}

/// Optical depth of the piecewise-linear interpolant of `f` sampled at integer x, from
/// x = a to x = b (exact trapezoid integration per voxel interval, clipped): what
/// trilinear reconstruction gives along a ray through voxel centres.
pub fn optical_depth(f: &dyn Fn(f64) -> f64, a: f64, b: f64) -> f64 {
    let mut tau = 0.0;
    let mut x0 = a;
    while x0 < b {
        let i = x0.floor();
        let x1 = (i + 1.0).min(b);
        let lerp = |x: f64| f(i) + (f(i + 1.0) - f(i)) * (x - i);
        tau += 0.5 * (lerp(x0) + lerp(x1)) * (x1 - x0);
        x0 = x1;
    }
    tau
}

/// Every tracker setting a render can select: each tracker, with each scheme where the
/// scheme matters, with both shadow-ray estimators.
pub fn all_settings(majorant_scale: f32) -> Vec<TrackerSettings> {
    use nimbus::track::select::Choice;
    let mut out = Vec::new();
    for &tracker in TrackerKind::ALL {
        let schemes: &[SchemeKind] = if tracker.uses_scheme() {
            SchemeKind::ALL
        } else {
            &[SchemeKind::HistAvg]
        };
        for &scheme in schemes {
            for &transmittance in TransmittanceKind::ALL {
                out.push(TrackerSettings {
                    tracker,
                    scheme,
                    transmittance,
                    majorant_scale,
                    ..TrackerSettings::default()
                });
            }
        }
    }
    out
}

pub fn label(s: &TrackerSettings) -> String {
    let scheme = if s.tracker.uses_scheme() {
        format!("/{}", s.scheme.name())
    } else {
        String::new()
    };
    format!(
        "{}{}+{} (majorant ×{})",
        s.tracker.name(),
        scheme,
        s.transmittance.name(),
        s.majorant_scale
    )
}

/// No sun; a constant environment of radiance `env`.
pub fn sky(env: [f64; 3]) -> Lights {
    Lights {
        suns: vec![],
        environment: env,
        ..Lights::default()
    }
}

/// A pinhole camera placed by `camera_to_world` (looking down its −Z), with a square
/// aperture `aperture` over focal length `focal`.
pub fn camera(camera_to_world: DMat4, focal: f64, aperture: f64, w: u32, h: u32) -> CameraRays {
    let cam = Camera {
        prim_path: "/Camera".into(),
        camera_to_world,
        focal_length: focal,
        horizontal_aperture: aperture,
        vertical_aperture: aperture,
        horizontal_aperture_offset: 0.0,
        vertical_aperture_offset: 0.0,
        clipping_range: (1e-6, 1e12),
        projection: Default::default(),
        f_stop: 0.0,
        focus_distance: 0.0,
        shutter: None,
        motion: None,
    };
    CameraRays::new(&cam, w, h)
}

/// A camera on +Z at distance `dist` looking at the origin.
pub fn camera_on_z(dist: f64, focal: f64, aperture: f64, w: u32, h: u32) -> CameraRays {
    camera(
        DMat4::from_translation(DVec3::new(0.0, 0.0, dist)),
        focal,
        aperture,
        w,
        h,
    )
}

/// What one render of a test scene needs.
pub struct Setup<'a> {
    pub medium: &'a Medium,
    pub lights: &'a Lights,
    pub camera: &'a CameraRays,
    pub width: u32,
    pub height: u32,
    pub spp: u32,
    pub max_depth: u32,
    pub seed: u64,
}

/// The render job of `setup` with `settings`, as the tests have always run it: every
/// tracker as selected (no single-channel specialisation), counting on, independent
/// samples, and equiangular points only when `settings` asks for them by name. The
/// library instantiates the estimators (a test crate that did took minutes to build).
fn job<'a>(setup: &'a Setup<'a>, settings: &TrackerSettings) -> RenderJob<'a> {
    let light_sampling = match settings.light_sampling {
        LightSampling::Auto => LightSampling::Collisions,
        l => l,
    };
    RenderJob {
        media: std::slice::from_ref(setup.medium),
        lights: setup.lights,
        camera: setup.camera,
        width: setup.width,
        height: setup.height,
        spp: setup.spp,
        max_depth: setup.max_depth,
        seed: setup.seed,
        sampler: SamplerKind::Independent,
        tracking: TrackerSettings {
            light_sampling,
            ..*settings
        },
        paths: CodePaths {
            count: true,
            specialise: false,
        },
        extras: Default::default(),
    }
}

pub fn render(setup: &Setup, settings: &TrackerSettings) -> Film {
    job(setup, settings).render(&|| {})
}

/// `n` independent paths through image position (`fx`, `fy`), with per-path counters.
pub fn paths(
    setup: &Setup,
    settings: &TrackerSettings,
    fx: f64,
    fy: f64,
    n: usize,
) -> Vec<([f64; 3], Counters)> {
    job(setup, settings).paths(&[(fx, fy)], n)
}

/// Asserts that no pixel of any AOV is NaN or infinite and that no sample was dropped
/// as non-finite (the film drops such samples; here none may occur at all).
pub fn assert_film_finite(what: &str, film: &Film) {
    for aov in Aov::ALL {
        let ch = film.channel(aov);
        if let Some(i) = ch.iter().position(|v| !v.is_finite()) {
            panic!("{what}: AOV {} pixel {i} is {}", aov.channel_name(), ch[i]);
        }
    }
    let (_, samples, nonfinite) = film.totals();
    assert_eq!(
        nonfinite, 0,
        "{what}: {nonfinite} of {samples} samples were NaN or infinite"
    );
}

/// Multiplier of the stress suite's sample counts (`NIMBUS_STRESS=N`, default 1): the
/// heavy run is `NIMBUS_STRESS=20 cargo t --test stress`.
pub fn stress_factor() -> usize {
    std::env::var("NIMBUS_STRESS")
        .ok()
        .and_then(|v| v.parse().ok())
        .filter(|&n: &usize| n >= 1)
        .unwrap_or(1)
}

/// A cube of N³ = 16³ unit-density voxels, side `side`, centred at the origin. Its
/// trilinear density is exactly 1 inside [−side/2 + h/2, side/2 − h/2]³ (h the voxel
/// size) and ramps linearly to 0 across each face, symmetrically about the face plane,
/// so an axis-parallel ray through it sees optical depth σt·side exactly. Flat majorant
/// cells of 8 voxels.
pub fn unit_cube(side: f64, sigma_a: [f64; 3], sigma_s: [f64; 3], g: f64) -> Medium {
    let n = 16;
    let vs = 1.0 / n as f64;
    let raw = grid_from_fn(
        "density",
        [n, n, n],
        DVec3::splat(-0.5 + 0.5 * vs),
        vs,
        |_| 1.0,
    );
    Medium::new(
        "/Cube",
        Grid::from_raw(&raw).unwrap(),
        DMat4::from_scale(DVec3::splat(side)),
        1.0,
        sigma_a,
        sigma_s,
        g,
        8,
    )
    .unwrap()
}

/// A stage `NAME.usda` in `dir` with a camera and a volume `/V` (NimbusVolumeAPI) whose
/// fields `fields` are the same-named grids of one file `grids.vdb`; `attrs` go on the
/// volume.
pub fn grids_stage(
    dir: &std::path::Path,
    name: &str,
    fields: &[&str],
    attrs: &str,
) -> std::path::PathBuf {
    let mut text = String::from(
        r#"#usda 1.0
def Camera "Cam" {
    double3 xformOp:translate = (0, 0, 10)
    uniform token[] xformOpOrder = ["xformOp:translate"]
    float focalLength = 1000
    float horizontalAperture = 10
    float verticalAperture = 10
}
def Volume "V" (apiSchemas = ["NimbusVolumeAPI"]) {
"#,
    );
    text.push_str(attrs);
    text.push('\n');
    for f in fields {
        text.push_str(&format!("    rel field:{f} = </V/{f}>\n"));
    }
    for f in fields {
        text.push_str(&format!(
            "    def OpenVDBAsset \"{f}\" {{ asset filePath = @./grids.vdb@\n        token fieldName = \"{f}\" }}\n"
        ));
    }
    text.push_str("}\n");
    let path = dir.join(format!("{name}.usda"));
    std::fs::write(&path, text).unwrap();
    path
}

/// The error of loading `stage` and building its medium (which must fail), as printed.
pub fn load_message(stage: &std::path::Path) -> String {
    use nimbus::scene::{load_stage, LoadOptions};
    let msg = match load_stage(stage, &LoadOptions::default()) {
        Err(e) => e.to_string(),
        Ok(scene) => match medium_for_scene(&scene, 8) {
            Err(e) => format!("{e:#}"),
            Ok(_) => panic!("{} loaded", stage.display()),
        },
    };
    eprintln!("{msg}");
    msg
}

/// The medium of a scene's only volume, with a flat majorant grid of `cell_voxels`
/// cells (an error when the stage has several).
pub fn medium_for_scene(scene: &nimbus::scene::Scene, cell_voxels: u32) -> anyhow::Result<Medium> {
    let mut media = nimbus::render::job::media_for_scene_with(
        scene,
        nimbus::volume::majorant::MajorantSpec::Uniform { cell_voxels },
    )?;
    if media.len() > 1 {
        anyhow::bail!(
            "{}: the stage has {} volumes, expected one",
            scene.stage_path.display(),
            media.len()
        );
    }
    Ok(media.remove(0))
}

/// Renders `job` (a job of `session`, possibly with other tracking) to a film.
pub fn render_job(
    session: &nimbus::render::session::Session,
    job: &nimbus::render::job::RenderJob,
    region: Option<nimbus::render::film::Region>,
) -> Film {
    let pool = session.pool(2).unwrap();
    let never = std::sync::atomic::AtomicBool::new(false);
    let (film, _) = session
        .render(
            job,
            region,
            &pool,
            nimbus::render::progressive::Clock::Wall,
            None,
            &never,
            &|_| {},
            |_, _| Ok::<(), ()>(()),
        )
        .unwrap();
    film
}
