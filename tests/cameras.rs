//! UsdGeomCamera as stages author it: orthographic views, a thin lens for depth of field,
//! clipping planes, and a warning (an error under `--strict`) for what a camera asks for
//! and Nimbus does not render. Cameras are read from generated stages; the volumes are
//! procedural cubes rendered by the integrator, their alpha the silhouette.

mod common;

use common::cli::{nimbus, root, stderr};
use common::{render, Setup};
use glam::{DMat4, DVec3};
use nimbus::render::camera::CameraRays;
use nimbus::render::film::Aov;
use nimbus::render::lights::Lights;
use nimbus::scene::{load_stage, Camera, LoadOptions};
use nimbus::track::select::TrackerSettings;
use nimbus::volume::grid::Grid;
use nimbus::volume::medium::Medium;
use nimbus::volume::procedural::grid_from_fn;
use std::path::{Path, PathBuf};

/// The camera `/Cam` of a stage holding only a camera with `body` (USD text).
fn stage_camera(dir: &Path, body: &str) -> Camera {
    let path = dir.join("camera.usda");
    std::fs::write(
        &path,
        format!("#usda 1.0\ndef Camera \"Cam\" {{\n{body}\n}}\n"),
    )
    .unwrap();
    load_stage(&path, &LoadOptions::default())
        .expect("camera stage loads")
        .camera
}

/// An absorbing cube of side `side` centred at `center`: optical depth 400 across,
/// so it is opaque and its alpha image is its silhouette (edges blurred by a voxel's
/// trilinear ramp).
fn cube(center: DVec3, side: f64) -> Medium {
    let n = 16;
    let vs = 1.0 / n as f64;
    let raw = grid_from_fn(
        "density",
        [n, n, n],
        DVec3::splat(-0.5 + 0.5 * vs),
        vs,
        |_| 1.0,
    );
    let sigma = 400.0 / side;
    Medium::new(
        "/Cube",
        Grid::from_raw(&raw).unwrap(),
        DMat4::from_translation(center) * DMat4::from_scale(DVec3::splat(side)),
        1.0,
        [sigma; 3],
        [0.0; 3],
        0.0,
        8,
    )
    .unwrap()
}

/// The alpha image of `medium` through `camera` (`w` × `h`, `spp` samples, no lights).
fn alpha(medium: &Medium, camera: &CameraRays, w: u32, h: u32, spp: u32, seed: u64) -> Vec<f64> {
    let lights = Lights::default();
    let film = render(
        &Setup {
            medium,
            lights: &lights,
            camera,
            width: w,
            height: h,
            spp,
            max_depth: 1,
            seed,
        },
        &TrackerSettings::default(),
    );
    film.channel(Aov::A).into_iter().map(f64::from).collect()
}

/// A camera on +Z at `z` looking down −Z (the stage's xformOp text).
fn at_z(z: f64) -> String {
    format!("double3 xformOp:translate = (0, 0, {z})\nuniform token[] xformOpOrder = [\"xformOp:translate\"]")
}

/// Two equal cubes 6 units apart in depth cover the same area of an orthographic view
/// (64 × 64 over the 2 × 2 units that apertures of 20 make): the summed alpha of each
/// (16 spp, seed 1) agrees within 5 standard errors of the difference, each pixel's
/// alpha being a mean of 16 values in [0, 1] (variance ≤ 1/4 each, only at the
/// silhouette's edge pixels: at most 300 of them). The same cubes under a perspective
/// camera at that distance differ by their depth ratio squared, (16/10)² = 2.56.
#[test]
fn orthographic_footprints_do_not_depend_on_depth() {
    let dir = tempfile::tempdir().unwrap();
    let ortho = stage_camera(
        dir.path(),
        &format!(
            "token projection = \"orthographic\"\nfloat horizontalAperture = 20\nfloat verticalAperture = 20\nfloat2 clippingRange = (0.1, 100)\n{}",
            at_z(10.0)
        ),
    );
    let rays = CameraRays::new(&ortho, 64, 64);
    let (w, h, spp) = (64, 64, 16);
    let near = alpha(&cube(DVec3::new(0.3, -0.2, 0.0), 0.5), &rays, w, h, spp, 1);
    let far = alpha(&cube(DVec3::new(0.3, -0.2, -6.0), 0.5), &rays, w, h, spp, 1);
    let (a_near, a_far) = (near.iter().sum::<f64>(), far.iter().sum::<f64>());
    // The silhouette's area in pixels: 0.5² units at 32 px per unit, plus the ramp.
    assert!(
        (250.0..330.0).contains(&a_near),
        "near cube covers {a_near} px"
    );
    eprintln!("orthographic footprints {a_near:.2} vs {a_far:.2} px");
    let edge_pixels = 300.0;
    let se = (2.0 * edge_pixels * 0.25 / spp as f64).sqrt();
    assert!(
        (a_near - a_far).abs() < 5.0 * se,
        "orthographic footprints {a_near} vs {a_far} px (5 se = {})",
        5.0 * se
    );

    let persp = stage_camera(
        dir.path(),
        &format!(
            "float focalLength = 50\nfloat horizontalAperture = 20\nfloat verticalAperture = 20\nfloat2 clippingRange = (0.1, 100)\n{}",
            at_z(10.0)
        ),
    );
    let rays = CameraRays::new(&persp, 64, 64);
    let near = alpha(&cube(DVec3::new(0.3, -0.2, 0.0), 0.5), &rays, w, h, spp, 1);
    let far = alpha(&cube(DVec3::new(0.3, -0.2, -6.0), 0.5), &rays, w, h, spp, 1);
    let ratio = near.iter().sum::<f64>() / far.iter().sum::<f64>();
    eprintln!("perspective footprint ratio {ratio:.3} (depth ratio² 2.56)");
    assert!(
        (2.2..2.9).contains(&ratio),
        "perspective footprint ratio {ratio}"
    );
}

/// Weighted centroid and second moment (x² + y² about the centroid) of an image.
fn moments(img: &[f64], w: usize) -> (f64, f64, f64, f64) {
    let s: f64 = img.iter().sum();
    let (mut mx, mut my) = (0.0, 0.0);
    for (i, a) in img.iter().enumerate() {
        mx += a * (i % w) as f64;
        my += a * (i / w) as f64;
    }
    let (mx, my) = (mx / s, my / s);
    let mut m2 = 0.0;
    for (i, a) in img.iter().enumerate() {
        let (dx, dy) = ((i % w) as f64 - mx, (i / w) as f64 - my);
        m2 += a * (dx * dx + dy * dy);
    }
    (s, mx, my, m2 / s)
}

/// Depth of field: a small opaque cube (side 0.1) at depth 5 under a lens focused at
/// 10 is blurred into the thin lens's circle of confusion. A lens of radius
/// r = focalLength / 10 / (2 fStop) = 50 / 10 / 4 = 1.25 units focused at z_f images
/// a point at depth z as a disk of radius f · r · |1/z_f − 1/z| on the film (f = 50
/// tenths): 50 · 1.25 · 0.1 = 6.25 tenths = 25 px (96 px over 24 tenths).
///
/// The alpha image is that disk convolved with the cube's own image (about a square of
/// a = f · 0.1 / 5 = 1 tenth = 4 px; a² measured as the image's summed alpha) and the
/// pixel's box, so its second moment about the centroid is M = R²/2 + a²/6 + 1/6 (a
/// uniform disk of radius R has E[x² + y²] = R²/2, a square of side a has a²/6, the box
/// 1/6): the measured radius is R = √(2 (M − a²/6 − 1/6)). Its standard error comes from the delta method over
/// the pixels, each pixel's alpha a mean of 256 values in [0, 1] (variance ≤ α(1 − α)
/// per value); the test allows 5 of them plus 2 % for the cube's depth (its faces at
/// 5 ± 0.05 blur by 25 ± 0.5 px, and the near face bounds the silhouette) and the pixel
/// grid. In focus, the same cube stays within its own 2 px.
#[test]
fn depth_of_field_blurs_into_the_thin_lens_circle_of_confusion() {
    let dir = tempfile::tempdir().unwrap();
    let lens = |f_stop: f64| {
        stage_camera(
            dir.path(),
            &format!(
                "float focalLength = 50\nfloat horizontalAperture = 24\nfloat verticalAperture = 24\nfloat fStop = {f_stop}\nfloat focusDistance = 10\nfloat2 clippingRange = (0.1, 100)\n{}",
                at_z(0.0)
            ),
        )
    };
    let (w, h, spp) = (96usize, 96usize, 256u32);
    let cam = lens(2.0);
    assert_eq!((cam.f_stop, cam.focus_distance), (2.0, 10.0));
    let rays = CameraRays::new(&cam, w as u32, h as u32);
    assert_eq!(rays.lens_dims(), 2);
    let img = alpha(
        &cube(DVec3::new(0.0, 0.0, -5.0), 0.1),
        &rays,
        w as u32,
        h as u32,
        spp,
        3,
    );
    let (s, mx, my, m2) = moments(&img, w);
    // Delta method: ∂M/∂α_i = ((r_i² − M) ) / S.
    let mut var = 0.0;
    for (i, a) in img.iter().enumerate() {
        let (dx, dy) = ((i % w) as f64 - mx, (i / w) as f64 - my);
        let g = (dx * dx + dy * dy - m2) / s;
        var += g * g * a * (1.0 - a) / spp as f64;
    }
    let m_se = var.sqrt();
    // The cube's image: an opaque object's summed alpha is its image's area, blurred or
    // not (21.6 px² here: 4 px at depth 5, and its ramp and sides).
    let (a2, f, r_lens) = (s, 50.0, 50.0 * 0.1 / (2.0 * 2.0));
    let expected = f * r_lens * (1.0 / 10.0 - 1.0 / 5.0f64).abs() * w as f64 / 24.0;
    let measured = (2.0 * (m2 - a2 / 6.0 - 1.0 / 6.0)).sqrt();
    // dR/dM = 1/R.
    let tol = 5.0 * m_se / measured + 0.02 * expected;
    eprintln!("circle of confusion: measured {measured:.3} px, thin lens {expected:.3} px, ±{tol:.3}; M = {m2:.2} ± {m_se:.2} px², Σα = {s:.2}");
    assert!(
        (measured - expected).abs() < tol,
        "circle of confusion radius {measured:.3} px, thin lens {expected:.3} px (±{tol:.3}; M = {m2:.2} ± {m_se:.2})"
    );
    assert!(
        (mx - 47.5).abs() < 1.0 && (my - 47.5).abs() < 1.0,
        "centroid ({mx}, {my})"
    );

    // In focus: the cube at the focus depth stays the 2 px square of its pinhole image
    // (0.1 units at depth 10), whatever the lens.
    let sharp = alpha(
        &cube(DVec3::new(0.0, 0.0, -10.0), 0.1),
        &rays,
        w as u32,
        h as u32,
        64,
        3,
    );
    let (_, _, _, m_sharp) = moments(&sharp, w);
    eprintln!("in focus: second moment {m_sharp:.3} px²");
    assert!(m_sharp < 2.0, "in focus, second moment {m_sharp} px²");
}

/// `clippingRange` bounds camera rays: a cube at depth 10 vanishes behind a far plane
/// at 8 and in front of a near plane at 12, for a pinhole, a thin lens and an
/// orthographic camera alike, and shows inside (1, 20).
#[test]
fn clipping_range_excludes_what_lies_outside_it() {
    let dir = tempfile::tempdir().unwrap();
    let medium = cube(DVec3::new(0.0, 0.0, -10.0), 1.0);
    for kind in [
        "float focalLength = 50",
        "float focalLength = 50\nfloat fStop = 1\nfloat focusDistance = 4",
        "token projection = \"orthographic\"",
    ] {
        let covered = |range: &str| {
            let cam = stage_camera(
                dir.path(),
                &format!(
                    "{kind}\nfloat horizontalAperture = 20\nfloat verticalAperture = 20\nfloat2 clippingRange = {range}\n{}",
                    at_z(0.0)
                ),
            );
            alpha(&medium, &CameraRays::new(&cam, 16, 16), 16, 16, 4, 5)
                .iter()
                .sum::<f64>()
        };
        assert!(covered("(1, 20)") > 1.0, "{kind}: the cube shows");
        assert_eq!(covered("(1, 8)"), 0.0, "{kind}: behind the far plane");
        assert_eq!(covered("(12, 20)"), 0.0, "{kind}: before the near plane");
    }
}

/// The example cloud with `camera` (USD text) authored on its camera.
fn cloud_with_camera(dir: &Path, camera: &str) -> PathBuf {
    let text = std::fs::read_to_string(root().join("scenes/cloud/cloud.usda"))
        .unwrap()
        .replace(
            "float focalLength = 50",
            &format!("float focalLength = 50\n        {camera}"),
        )
        .replace(
            "@./cloud.vdb@",
            &format!("@{}@", root().join("scenes/cloud/cloud.vdb").display()),
        );
    let path = dir.join("stage.usda");
    std::fs::write(&path, text).unwrap();
    path
}

fn render_stage(stage: &Path, out: &Path, extra: &[&str]) -> std::process::Output {
    let mut args = vec![
        "render",
        stage.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--res",
        "16x12",
        "--spp",
        "1",
    ];
    args.extend_from_slice(extra);
    nimbus(&args)
}

fn warning_lines(o: &std::process::Output) -> Vec<String> {
    stderr(o)
        .lines()
        .filter(|l| l.starts_with("nimbus: warning:"))
        .map(str::to_string)
        .collect()
}

/// What a camera asks for and Nimbus does not render warns, naming the camera and the
/// attribute (an unknown projection, exposure, stereo, an fStop without a focus
/// distance, a lens attribute that changes while the shutter is open); `--strict` makes each
/// an error and writes no image; the same camera without them prints no warning.
#[test]
fn camera_warnings_name_the_attribute_and_fail_under_strict() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out.exr");
    let cases = [
        ("token projection = \"fisheye\"", "projection"),
        ("float exposure = 2", "exposure"),
        ("uniform token stereoRole = \"left\"", "stereoRole"),
        ("float fStop = 2.8", "focusDistance"),
        (
            // A moving camera is blurred (tests/motion_blur.rs); a focus pull is not.
            "double shutter:open = -0.25\n        double shutter:close = 0.25\n        float focusDistance.timeSamples = { 0: 5, 2: 6 }",
            "focusDistance",
        ),
    ];
    for (attrs, attribute) in cases {
        let stage = cloud_with_camera(dir.path(), attrs);
        let o = render_stage(&stage, &out, &["--frame", "1"]);
        assert!(o.status.success(), "{attrs}: {}", stderr(&o));
        let lines = warning_lines(&o);
        assert!(
            lines
                .iter()
                .any(|l| l.contains("/World/Camera") && l.contains(attribute)),
            "{attrs}: no warning naming /World/Camera and {attribute} in {lines:#?}"
        );
        let _ = std::fs::remove_file(&out);
        let o = render_stage(&stage, &out, &["--frame", "1", "--strict"]);
        assert!(!o.status.success(), "{attrs}: --strict rendered");
        assert!(stderr(&o).contains(attribute), "{attrs}: {}", stderr(&o));
        assert!(!out.exists(), "{attrs}: --strict wrote an image");
    }
    // A still camera with a shutter, an orthographic one and one with depth of field:
    // all rendered as authored, no warning.
    for attrs in [
        "double shutter:open = -0.25\n        double shutter:close = 0.25",
        "token projection = \"orthographic\"",
        "float fStop = 2.8\n        float focusDistance = 4",
    ] {
        let stage = cloud_with_camera(dir.path(), attrs);
        let o = render_stage(&stage, &out, &["--frame", "1", "--strict"]);
        assert!(o.status.success(), "{attrs}: {}", stderr(&o));
        assert!(
            warning_lines(&o).is_empty(),
            "{attrs}: {:#?}",
            warning_lines(&o)
        );
    }
}
