//! Transform motion blur (issue 45): each camera sample draws a time over the camera's
//! shutter, and moving volumes and a moving camera are where they are at that time
//! ([`nimbus::motion`], `Medium::set_motion`, `CameraRays::ray_at`).
//!
//! - Reference by time-averaging: a volume that moves (a time-sampled translate and
//!   rotation) over the shutter, and separately a camera that moves, render equal
//!   within noise to the mean of K = 16 static renders at the shutter's K midpoint
//!   times (each with the shutter closed, at `--frame` 1 + τ_k, its own seed).
//!   Estimator: the luminance of each pixel's mean, with variance v/n (the pixel's
//!   sample variance over its n independent samples; a static mean's variance is
//!   Σ_k v_k/n_k / K²). For the image and each 8×8 block, z = Σ(L_blur − L_ref) /
//!   √Σ(var_blur + var_ref), |z| < 4. Samples: 512 per pixel blurred, 16 × 32
//!   static, seeds fixed. Discretisation: the volume moves 0.4 units (about 4 pixels)
//!   and turns 20° over the shutter, so neighbouring times of the reference are a
//!   quarter-pixel apart: the midpoint rule's error (O(1/K²) of the motion's
//!   curvature, 0 for the translate) is far below the noise.
//! - The blur is there: against the frame's static render, the z of some image column
//!   (Σ over its pixels, same estimator) exceeds 8 (measured values printed).
//! - Nothing moving, or the shutter closed: bit for bit the render without motion (no
//!   time is drawn). A blurred render is the same whatever the thread count.

mod common;

use common::repo as root;
use nimbus::render::analysis::CodePaths;
use nimbus::render::film::{luminance, Film};
use nimbus::render::sampler::SamplerKind;
use nimbus::render::session::{Overrides, Session};
use std::path::{Path, PathBuf};

const W: u32 = 32;
const H: u32 = 24;

/// The cloud example's volume and camera, with `volume_ops` and `camera_ops` as their
/// transforms and the camera's shutter `(open, close)`, lit by its sun and sky.
fn stage(
    dir: &Path,
    name: &str,
    volume_ops: &str,
    camera_ops: &str,
    shutter: (f64, f64),
) -> PathBuf {
    lit_stage(dir, name, volume_ops, camera_ops, SUN_AND_SKY, shutter)
}

/// The cloud example's sun and sky.
const SUN_AND_SKY: &str = r#"    def DistantLight "Sun"
    {
        float inputs:intensity = 6
        bool inputs:normalize = 1
        float3 xformOp:rotateXYZ = (-30, 80, 0)
        uniform token[] xformOpOrder = ["xformOp:rotateXYZ"]
    }
    def DomeLight "Sky"
    {
        float inputs:intensity = 0.35
        color3f inputs:color = (0.35, 0.55, 1)
    }"#;

/// [`stage`] with `lights` for its lights.
fn lit_stage(
    dir: &Path,
    name: &str,
    volume_ops: &str,
    camera_ops: &str,
    lights: &str,
    shutter: (f64, f64),
) -> PathBuf {
    let vdb = root().join("scenes/cloud/cloud.vdb");
    let text = format!(
        r#"#usda 1.0
(
    defaultPrim = "World"
    upAxis = "Y"
)
def Xform "World"
{{
    def Volume "Cloud" (
        prepend apiSchemas = ["NimbusVolumeAPI"]
    )
    {{
        rel field:density = </World/Cloud/density>
        float nimbus:densityScale = 24
        color3f nimbus:absorption = (0.02, 0.02, 0.02)
        color3f nimbus:scattering = (0.98, 0.98, 0.98)
        float nimbus:anisotropy = 0.5
{volume_ops}
        def OpenVDBAsset "density"
        {{
            asset filePath = @{vdb}@
            token fieldName = "density"
        }}
    }}
    def Camera "Camera"
    {{
        float focalLength = 50
        float horizontalAperture = 36
        float verticalAperture = 27
        float2 clippingRange = (0.1, 1000)
        double shutter:open = {open}
        double shutter:close = {close}
{camera_ops}
    }}
{lights}
}}
"#,
        vdb = vdb.display(),
        open = shutter.0,
        close = shutter.1,
    );
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path
}

/// The volume turning and sliding along x over frames 0 → 2 (at frame 1: the cloud
/// example's placement).
const MOVING_VOLUME: &str = r#"        double3 xformOp:translate.timeSamples = { 0: (-0.4, 0, 0), 2: (0.4, 0, 0) }
        float3 xformOp:rotateXYZ.timeSamples = { 0: (0, 0, 0), 2: (0, 40, 0) }
        uniform token[] xformOpOrder = ["xformOp:translate", "xformOp:rotateXYZ"]"#;
const STILL_VOLUME: &str = r#"        double3 xformOp:translate = (0, 0, 0)
        float3 xformOp:rotateXYZ = (0, 20, 0)
        uniform token[] xformOpOrder = ["xformOp:translate", "xformOp:rotateXYZ"]"#;
const STILL_CAMERA: &str = r#"        double3 xformOp:translate = (0, -0.5, 4.2)
        float3 xformOp:rotateXYZ = (5, 0, 0)
        uniform token[] xformOpOrder = ["xformOp:translate", "xformOp:rotateXYZ"]"#;
/// The camera sliding up and sideways over frames 0 → 2.
const MOVING_CAMERA: &str = r#"        double3 xformOp:translate.timeSamples = { 0: (-0.3, -0.7, 4.2), 2: (0.3, -0.3, 4.2) }
        float3 xformOp:rotateXYZ = (5, 0, 0)
        uniform token[] xformOpOrder = ["xformOp:translate", "xformOp:rotateXYZ"]"#;

const SHUTTER: (f64, f64) = (-0.5, 0.5);
const CLOSED: (f64, f64) = (0.0, 0.0);

fn open(stage: &Path, frame: f64, spp: u32, seed: u64, threads: usize) -> Session {
    let o = Overrides {
        frame: Some(frame),
        spp: Some(spp),
        res: Some((W, H)),
        seed: Some(seed),
        sampler: Some(SamplerKind::Independent),
        max_depth: Some(8),
        threads: Some(threads),
        ..Overrides::default()
    };
    Session::open(stage, &o).unwrap()
}

fn render(s: &Session) -> Film {
    let job = s.job_with(CodePaths {
        count: false,
        specialise: true,
    });
    common::render_job(s, &job, None)
}

/// Per pixel: (mean luminance, variance of that mean).
fn pixels(f: &Film) -> Vec<(f64, f64)> {
    f.pixels
        .iter()
        .map(|p| {
            let n = (p.samples - p.nonfinite) as f64;
            (luminance(p.rgb.map(|v| v / n)), p.luminance_variance() / n)
        })
        .collect()
}

/// The mean of K static renders at the shutter's midpoint times (frame 1 + τ_k), each
/// with its own seed.
fn time_average(still: &Path, k: usize, spp: u32) -> Vec<(f64, f64)> {
    let mut acc = vec![(0.0, 0.0); (W * H) as usize];
    for i in 0..k {
        let tau = SHUTTER.0 + (SHUTTER.1 - SHUTTER.0) * (i as f64 + 0.5) / k as f64;
        let s = open(still, 1.0 + tau, spp, 100 + i as u64, 2);
        for (a, p) in acc.iter_mut().zip(pixels(&render(&s))) {
            a.0 += p.0 / k as f64;
            a.1 += p.1 / (k * k) as f64;
        }
    }
    acc
}

/// z of the pixels `idx`: Σ(a − b) / √Σ(var_a + var_b) (0 where nothing varies).
fn z(a: &[(f64, f64)], b: &[(f64, f64)], idx: impl Iterator<Item = usize>) -> f64 {
    let (mut d, mut v) = (0.0, 0.0);
    for i in idx {
        d += a[i].0 - b[i].0;
        v += a[i].1 + b[i].1;
    }
    if v == 0.0 {
        0.0
    } else {
        d / v.sqrt()
    }
}

/// z of the image and of each 8×8 block.
fn block_z(a: &[(f64, f64)], b: &[(f64, f64)]) -> Vec<f64> {
    let mut out = vec![z(a, b, 0..(W * H) as usize)];
    for by in 0..H / 8 {
        for bx in 0..W / 8 {
            let idx = (0..64).map(|j| ((by * 8 + j / 8) * W + bx * 8 + j % 8) as usize);
            out.push(z(a, b, idx));
        }
    }
    out
}

/// z of each image column (the blur's signature: light moved across columns).
fn column_z(a: &[(f64, f64)], b: &[(f64, f64)]) -> Vec<f64> {
    (0..W)
        .map(|x| z(a, b, (0..H).map(|y| (y * W + x) as usize)))
        .collect()
}

/// z of each image row.
fn row_z(a: &[(f64, f64)], b: &[(f64, f64)]) -> Vec<f64> {
    (0..H)
        .map(|y| z(a, b, (0..W).map(|x| (y * W + x) as usize)))
        .collect()
}

fn worst(z: &[f64]) -> f64 {
    z.iter().fold(0f64, |m, v| m.max(v.abs()))
}

/// The stage's `motion blur` warnings, each as "prim attribute message".
fn blur_warnings(s: &Session) -> Vec<String> {
    s.scene
        .warnings
        .iter()
        .filter(|w| w.kind == "motion blur")
        .map(|w| format!("{} {:?} {}", w.prim, w.attribute, w.message))
        .collect()
}

/// A blurred render against its time average, and against the static frame.
fn check_against_time_average(blurred: &Path, still: &Path, what: &str) {
    let s = open(blurred, 1.0, 512, 7, 2);
    let motion = s.scene.camera.motion.is_some()
        || s.scene.volumes[0].motion.is_some()
        || s.scene.sphere_lights.iter().any(|l| l.motion.is_some());
    assert!(motion, "{what}: the stage's motion was not read");
    let warnings = blur_warnings(&s);
    assert!(warnings.is_empty(), "{what}: {warnings:?}");
    let blur = pixels(&render(&s));
    let reference = time_average(still, 16, 32);
    let z = block_z(&blur, &reference);
    println!("{what}: blurred vs time average, z image and blocks: {z:.2?}");
    assert!(worst(&z) < 4.0, "{what}: blurred vs time average: {z:.2?}");
    let frame = pixels(&render(&open(still, 1.0, 512, 11, 2)));
    let z_frame = column_z(&blur, &frame);
    println!("{what}: blurred vs the static frame: {z_frame:.2?}");
    assert!(
        worst(&z_frame) > 8.0,
        "{what}: the blur does not show against the static frame: {z_frame:.2?}"
    );
}

#[test]
fn a_moving_volume_renders_as_the_mean_of_its_instants() {
    let dir = tempfile::tempdir().unwrap();
    let blurred = stage(
        dir.path(),
        "blur.usda",
        MOVING_VOLUME,
        STILL_CAMERA,
        SHUTTER,
    );
    let still = stage(
        dir.path(),
        "still.usda",
        MOVING_VOLUME,
        STILL_CAMERA,
        CLOSED,
    );
    check_against_time_average(&blurred, &still, "moving volume");
}

#[test]
fn a_moving_camera_renders_as_the_mean_of_its_instants() {
    let dir = tempfile::tempdir().unwrap();
    let blurred = stage(
        dir.path(),
        "blur.usda",
        STILL_VOLUME,
        MOVING_CAMERA,
        SHUTTER,
    );
    let still = stage(
        dir.path(),
        "still.usda",
        STILL_VOLUME,
        MOVING_CAMERA,
        CLOSED,
    );
    check_against_time_average(&blurred, &still, "moving camera");
}

/// A spot (a small sphere light with a 35° cone) above the cloud, sliding along x and
/// tilting its cone 30° about z over frames 0 → 2 (over the shutter: 1.2 units and
/// 15°), beside a faint sky; `auto` samples a spot's segments equiangularly in a
/// heterogeneous medium too, so both light-sampling paths see the moving light.
const MOVING_SPOT: &str = r#"    def SphereLight "Spot" (
        prepend apiSchemas = ["ShapingAPI"]
    )
    {
        float inputs:intensity = 60
        float inputs:radius = 0.1
        float inputs:shaping:cone:angle = 35
        float inputs:shaping:cone:softness = 0.2
        double3 xformOp:translate.timeSamples = { 0: (-1.2, 1.3, 0.2), 2: (1.2, 1.3, 0.2) }
        float3 xformOp:rotateXYZ.timeSamples = { 0: (-90, 0, -15), 2: (-90, 0, 15) }
        uniform token[] xformOpOrder = ["xformOp:translate", "xformOp:rotateXYZ"]
    }
    def DomeLight "Sky"
    {
        float inputs:intensity = 0.1
    }"#;

#[test]
fn a_moving_light_renders_as_the_mean_of_its_instants() {
    let dir = tempfile::tempdir().unwrap();
    let lit = |name: &str, shutter| {
        lit_stage(
            dir.path(),
            name,
            STILL_VOLUME,
            STILL_CAMERA,
            MOVING_SPOT,
            shutter,
        )
    };
    let (blurred, still) = (lit("blur.usda", SHUTTER), lit("still.usda", CLOSED));
    check_against_time_average(&blurred, &still, "moving spot");
}

/// A light whose size changes over the shutter is not blurred (its samples could not be
/// carried along rigidly): a warning names it and the op, and it renders at the frame.
#[test]
fn a_light_that_scales_warns_and_renders_at_the_frame() {
    let dir = tempfile::tempdir().unwrap();
    let scaling = MOVING_SPOT.replace(
        r#"uniform token[] xformOpOrder = ["xformOp:translate", "xformOp:rotateXYZ"]"#,
        r#"float3 xformOp:scale.timeSamples = { 0: (1, 1, 1), 2: (2, 2, 2) }
        uniform token[] xformOpOrder = ["xformOp:translate", "xformOp:rotateXYZ", "xformOp:scale"]"#,
    );
    let path = lit_stage(
        dir.path(),
        "scaling.usda",
        STILL_VOLUME,
        STILL_CAMERA,
        &scaling,
        SHUTTER,
    );
    let s = open(&path, 1.0, 1, 1, 1);
    assert!(s.scene.sphere_lights[0].motion.is_none());
    let w = blur_warnings(&s);
    assert_eq!(w.len(), 1, "{w:?}");
    assert!(
        w[0].contains("/World/Spot") && w[0].contains("scales"),
        "{w:?}"
    );
}

fn bits(f: &Film) -> Vec<u64> {
    f.pixels
        .iter()
        .flat_map(|p| p.rgb.map(f64::to_bits).into_iter().chain([p.lum.to_bits()]))
        .collect()
}

#[test]
fn without_motion_nothing_changes_and_blur_is_deterministic() {
    let dir = tempfile::tempdir().unwrap();
    let plain = stage(dir.path(), "plain.usda", STILL_VOLUME, STILL_CAMERA, CLOSED);
    let reference = bits(&render(&open(&plain, 1.0, 8, 3, 2)));
    // The shutter open with nothing moving, and the moving volume with the shutter
    // closed (at frame 1 it is where the still one is): no time drawn, the same bits.
    let open_still = stage(dir.path(), "open.usda", STILL_VOLUME, STILL_CAMERA, SHUTTER);
    let s = open(&open_still, 1.0, 8, 3, 2);
    assert!(s.scene.volumes[0].motion.is_none() && s.scene.camera.motion.is_none());
    assert!(
        bits(&render(&s)) == reference,
        "shutter open, nothing moving"
    );
    let closed = stage(
        dir.path(),
        "closed.usda",
        MOVING_VOLUME,
        STILL_CAMERA,
        CLOSED,
    );
    assert!(
        bits(&render(&open(&closed, 1.0, 8, 3, 2))) == reference,
        "moving volume, shutter closed"
    );
    // Blurred: the same frame on 1 and 2 threads.
    let blurred = stage(
        dir.path(),
        "blur.usda",
        MOVING_VOLUME,
        MOVING_CAMERA,
        SHUTTER,
    );
    // (The session's thread count overrides the pool's default.)
    let f1 = render(&open(&blurred, 1.0, 8, 3, 1));
    let f2 = render(&open(&blurred, 1.0, 8, 3, 2));
    assert!(bits(&f1) == bits(&f2), "blurred: 1 thread against 2");
    assert!(
        bits(&f2) != reference,
        "blurred: the same as the still frame"
    );
}

/// A moving light still renders at the frame's time, with a warning naming it.
#[test]
fn what_is_not_blurred_warns() {
    let dir = tempfile::tempdir().unwrap();
    let path = stage(
        dir.path(),
        "light.usda",
        STILL_VOLUME,
        STILL_CAMERA,
        SHUTTER,
    );
    let text = std::fs::read_to_string(&path).unwrap().replace(
        r#"float3 xformOp:rotateXYZ = (-30, 80, 0)"#,
        r#"float3 xformOp:rotateXYZ.timeSamples = { 0: (-30, 70, 0), 2: (-30, 90, 0) }"#,
    );
    std::fs::write(&path, text).unwrap();
    let s = open(&path, 1.0, 1, 1, 1);
    let w = blur_warnings(&s);
    assert_eq!(w.len(), 1, "{w:?}");
    assert!(
        w[0].contains("/World/Sun") && w[0].contains("xformOp:rotateXYZ"),
        "{w:?}"
    );
}

// ----- velocity ------------------------------------------------------------------

/// Units per second the test's velocity grid flows at along +x: at 24 time codes per
/// second, the shutter's ±0.5 time codes move the cube ±0.2 units.
const SPEED: f64 = 9.6;

/// A unit cube of density 1 (voxel 0.05, over [-1.6, 1.55]³) and, in the same file, a
/// velocity grid (SPEED, 0, 0) over the whole region.
fn cube_vdb(dir: &Path) -> PathBuf {
    use nimbus::volume::procedural::{grid_from_fn, vec3_grid_from_fn};
    use nimbus::volume::vdb::{write_grids, WriteGrid};
    let origin = glam::DVec3::splat(-1.6);
    let inside = |p: glam::DVec3| p.abs().max_element() < 0.5;
    let density = grid_from_fn("density", [64; 3], origin, 0.05, |p| inside(p) as u8 as f64);
    let vel = vec3_grid_from_fn("vel", [64; 3], origin, 0.05, |_| [SPEED, 0.0, 0.0]);
    let path = dir.join("cube.vdb");
    write_grids(&path, &[WriteGrid::Float(&density), WriteGrid::Vec3s(&vel)]).unwrap();
    path
}

/// The cube seen from +z, lit from the side; `fields` its field relationships and
/// assets, `ops` its transform.
fn cube_stage(
    dir: &Path,
    name: &str,
    vdb: &Path,
    with_vel: bool,
    ops: &str,
    shutter: (f64, f64),
) -> PathBuf {
    let vel = match with_vel {
        true => format!(
            r#"        rel field:vel = </World/Cube/vel>
        def OpenVDBAsset "vel"
        {{
            asset filePath = @{}@
            token fieldName = "vel"
        }}"#,
            vdb.display()
        ),
        false => String::new(),
    };
    let text = format!(
        r#"#usda 1.0
(
    defaultPrim = "World"
    timeCodesPerSecond = 24
)
def Xform "World"
{{
    def Volume "Cube" (
        prepend apiSchemas = ["NimbusVolumeAPI"]
    )
    {{
        rel field:density = </World/Cube/density>
        float nimbus:densityScale = 2
        color3f nimbus:absorption = (0.2, 0.2, 0.2)
        color3f nimbus:scattering = (0.8, 0.8, 0.8)
{ops}
        def OpenVDBAsset "density"
        {{
            asset filePath = @{vdb}@
            token fieldName = "density"
        }}
{vel}
    }}
    def Camera "Camera"
    {{
        float focalLength = 50
        float horizontalAperture = 36
        float verticalAperture = 27
        double shutter:open = {open}
        double shutter:close = {close}
        double3 xformOp:translate = (0, 0, 4)
        uniform token[] xformOpOrder = ["xformOp:translate"]
    }}
    def DistantLight "Sun"
    {{
        float inputs:intensity = 3
        bool inputs:normalize = 1
        float3 xformOp:rotateXYZ = (-20, 60, 0)
        uniform token[] xformOpOrder = ["xformOp:rotateXYZ"]
    }}
    def DomeLight "Sky"
    {{
        float inputs:intensity = 0.05
    }}
}}
"#,
        vdb = vdb.display(),
        open = shutter.0,
        close = shutter.1,
    );
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path
}

/// A constant velocity grid moves the field as a translate of the same speed does:
/// the velocity-blurred cube against the transform-blurred one, |z| < 4 (image and 8×8
/// blocks, 512 spp each, the estimator above); and the blur shows against the still
/// frame (a column's |z| > 8).
#[test]
fn a_constant_velocity_grid_blurs_as_the_same_translate() {
    let dir = tempfile::tempdir().unwrap();
    let vdb = cube_vdb(dir.path());
    let still_ops = "        double3 xformOp:translate = (0, 0, 0)\n        uniform token[] xformOpOrder = [\"xformOp:translate\"]";
    let moving_ops = "        double3 xformOp:translate.timeSamples = { 0: (-0.4, 0, 0), 2: (0.4, 0, 0) }\n        uniform token[] xformOpOrder = [\"xformOp:translate\"]";
    let flowing = cube_stage(dir.path(), "vel.usda", &vdb, true, still_ops, SHUTTER);
    let moved = cube_stage(dir.path(), "moved.usda", &vdb, false, moving_ops, SHUTTER);
    let still = cube_stage(dir.path(), "still.usda", &vdb, true, still_ops, CLOSED);
    let s = open(&flowing, 1.0, 512, 21, 2);
    let v = s.scene.volumes[0]
        .velocity
        .as_ref()
        .expect("the vel field is read");
    assert_eq!(v.field.0, "vel");
    assert!((v.seconds_per_time_code - 1.0 / 24.0).abs() < 1e-15);
    assert!(s.scene.volumes[0].motion.is_none());
    let film = render_counted(&s);
    let (counters, _, nonfinite) = film.totals();
    assert_eq!(nonfinite, 0);
    // The widened majorants bound the advected density at every tentative collision.
    assert_eq!(counters.majorant_violations, 0);
    let by_velocity = pixels(&film);
    let by_transform = pixels(&render(&open(&moved, 1.0, 512, 22, 2)));
    let z = block_z(&by_velocity, &by_transform);
    println!("velocity vs translate: {z:.2?}");
    assert!(worst(&z) < 4.0, "velocity vs translate: {z:.2?}");
    let frame = pixels(&render(&open(&still, 1.0, 512, 23, 2)));
    let z_frame = column_z(&by_velocity, &frame);
    println!("velocity vs the still frame: {z_frame:.2?}");
    assert!(worst(&z_frame) > 8.0, "no blur: {z_frame:.2?}");
}

/// A render with counting on: the film (its counters hold lookups and majorant
/// violations).
fn render_counted(s: &Session) -> Film {
    let job = s.job_with(CodePaths {
        count: true,
        specialise: true,
    });
    common::render_job(s, &job, None)
}

/// The EmberGen fire (frame 50 of ../shared/data: `temperature` as density, `flames` as
/// emission; it has no velocity grid) with a velocity grid this test writes: a swirl
/// about the fire's vertical axis plus an updraft, up to 600 units/s, over the fire's
/// box. Blurred over ±0.5 frames at 24 fps it renders finite, different from the
/// still frame (some row's or column's |z| > 8), with no tentative collision above its widened majorants; the lookups per
/// sample (the `lookups` AOV's mean, a velocity read counted as one lookup) are printed
/// beside the still frame's.
#[test]
fn the_embergen_fire_blurs_by_a_velocity_grid() {
    use nimbus::volume::procedural::vec3_grid_from_fn;
    use nimbus::volume::vdb::{read_float_grid, write_grids, WriteGrid};
    let Some(fire) = common::shared_file("embergen_fire_a/embergen_fire_a_50.vdb") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let loc = nimbus::volume::asset::AssetLocation::File(fire.clone());
    let t = read_float_grid(&loc, "temperature", None).unwrap();
    let (lo, hi) = t.world_bounds(glam::DMat4::IDENTITY).unwrap();
    let centre = 0.5 * (lo + hi);
    let voxel = (hi - lo).max_element() / 48.0;
    let dims = ((hi - lo) / voxel).ceil().as_ivec3() + 3;
    let origin = lo - voxel;
    let radius = 0.5 * (hi - lo).x.max((hi - lo).z);
    // ω × (p − c) about +y, 600 units/s at the box's side, and 400 units/s upwards:
    // over ±1/48 s up to 12.5 and 8.3 units, 4.6 and 3.1 pixels of the 32-pixel image.
    let omega = 600.0 / radius;
    let vel = vec3_grid_from_fn("vel", dims.to_array(), origin, voxel, |p| {
        let r = p - centre;
        [-omega * r.z, 400.0, omega * r.x]
    });
    let vel_vdb = dir.path().join("vel.vdb");
    write_grids(&vel_vdb, &[WriteGrid::Vec3s(&vel)]).unwrap();
    let stage = |name: &str, shutter: (f64, f64)| {
        let text = format!(
            r#"#usda 1.0
(
    timeCodesPerSecond = 24
)
def Camera "Cam" {{
    double3 xformOp:translate = (0, -25, 120)
    uniform token[] xformOpOrder = ["xformOp:translate"]
    float focalLength = 50
    float horizontalAperture = 36
    float verticalAperture = 36
    double shutter:open = {open}
    double shutter:close = {close}
}}
def Volume "Fire" (apiSchemas = ["NimbusVolumeAPI"]) {{
    token nimbus:densityField = "temperature"
    color3f nimbus:absorption = (0.5, 0.5, 0.5)
    color3f nimbus:scattering = (0.5, 0.5, 0.5)
    token nimbus:emissionField = "flames"
    color3f nimbus:emissionColor = (1, 0.5, 0.2)
    float nimbus:emissionScale = 40
    rel field:temperature = </Fire/temperature>
    rel field:flames = </Fire/flames>
    rel field:vel = </Fire/vel>
    def OpenVDBAsset "temperature" {{ asset filePath = @{fire}@
        token fieldName = "temperature" }}
    def OpenVDBAsset "flames" {{ asset filePath = @{fire}@
        token fieldName = "flames" }}
    def OpenVDBAsset "vel" {{ asset filePath = @{vel}@
        token fieldName = "vel" }}
}}
"#,
            fire = fire.display(),
            vel = vel_vdb.display(),
            open = shutter.0,
            close = shutter.1,
        );
        let path = dir.path().join(name);
        std::fs::write(&path, text).unwrap();
        path
    };
    let mut lookups = Vec::new();
    let mut images = Vec::new();
    for (name, shutter) in [("blur.usda", SHUTTER), ("still.usda", CLOSED)] {
        let s = open(&stage(name, shutter), 1.0, 256, 5, 2);
        assert_eq!(s.scene.volumes[0].velocity.is_some(), shutter == SHUTTER);
        let film = render_counted(&s);
        common::assert_film_finite(name, &film);
        let (c, samples, nonfinite) = film.totals();
        assert_eq!(nonfinite, 0, "{name}");
        assert_eq!(
            c.majorant_violations, 0,
            "{name}: a density above its majorant"
        );
        lookups.push(c.density_lookups as f64 / samples as f64);
        images.push(pixels(&film));
    }
    // The updraft moves light across rows, the swirl across columns.
    let (zc, zr) = (
        column_z(&images[0], &images[1]),
        row_z(&images[0], &images[1]),
    );
    println!(
        "EmberGen frame 50: lookups per sample blurred {:.1}, still {:.1}; blurred vs still, columns' z {zc:.1?}, rows' z {zr:.1?}",
        lookups[0], lookups[1]
    );
    assert!(
        worst(&zc).max(worst(&zr)) > 8.0,
        "no blur: {zc:.1?} {zr:.1?}"
    );
}
