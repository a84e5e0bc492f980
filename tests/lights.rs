//! UsdLux lights: what Nimbus loads against what Pixar's USD computes
//! (`tests/fixtures/make_light_stages.py`), bad textures, and renders against
//! closed-form (or quadrature) answers.

mod common;

use std::f64::consts::PI;
use std::path::Path;

use glam::{DMat4, DVec3};
use nimbus::render::camera::CameraRays;
use nimbus::render::guiding::LightLobes;
use nimbus::render::integrator::{Integrator, SelectSegments};
use nimbus::render::light_choice::LightChoice;
use nimbus::render::lights::{EnvMap, Lights, RectEmitter, SphereEmitter, Sun};
use nimbus::render::phase::hg;
use nimbus::render::sampler::pixel_sampler;
use nimbus::scene::{load_stage, Camera, LoadOptions};
use nimbus::track::delta::Delta;
use nimbus::track::ratio::Ratio;
use nimbus::volume::counters::Counters;
use nimbus::volume::medium::Medium;
use rand::{Rng, SeedableRng};
use serde_json::Value;

// ----- loading, against pxr ------------------------------------------------------------

/// Runs the fixture generator into a fresh temp dir; `None` (with a message) when
/// Pixar's USD or OpenEXR's Python bindings are not installed.
fn generate_fixtures() -> Option<(tempfile::TempDir, Value)> {
    common::pxr_fixtures(
        "make_light_stages.py",
        &["pxr", "OpenEXR", "numpy"],
        common::data::SETUP_PYTHON,
        false,
    )
}

/// Values authored as float are widened exactly by both sides; derived quantities
/// (powers of two, areas, normalizations) are computed in double by both.
const TOL: f64 = 1e-9;

fn num(v: &Value) -> f64 {
    v.as_f64()
        .unwrap_or_else(|| panic!("expected a number, got {v}"))
}

fn close(a: f64, b: f64) -> bool {
    (a - b).abs() <= TOL * a.abs().max(b.abs()).max(1.0)
}

fn assert_num(what: &str, actual: f64, expected: &Value) {
    let e = num(expected);
    assert!(close(actual, e), "{what}: got {actual}, pxr says {e}");
}

fn assert_vec(what: &str, actual: &[f64], expected: &Value) {
    assert_vec_tol(what, actual, expected, TOL);
}

/// pxr evaluates the colour temperature in float: emission that includes it is
/// compared to float precision.
const FLOAT_TOL: f64 = 1e-6;

fn assert_vec_tol(what: &str, actual: &[f64], expected: &Value, tol: f64) {
    let e: Vec<f64> = expected
        .as_array()
        .expect("array")
        .iter()
        .map(num)
        .collect();
    assert_eq!(actual.len(), e.len(), "{what}: length");
    for (a, b) in actual.iter().zip(&e) {
        assert!(
            (a - b).abs() <= tol * a.abs().max(b.abs()).max(1.0),
            "{what}: got {actual:?}, pxr says {e:?}"
        );
    }
}

/// pxr's row-major, row-vector matrix against our column-vector one.
fn assert_matrix(what: &str, m: &DMat4, expected: &Value) {
    for (r, row) in expected.as_array().unwrap().iter().enumerate() {
        for (c, e) in row.as_array().unwrap().iter().enumerate() {
            assert!(
                close(m.col(r)[c], num(e)),
                "{what}[{r}][{c}]: got {m:?}, pxr {expected}"
            );
        }
    }
}

/// Every light's prim path, world transform, inputs and resolved texture path, and the
/// emission Nimbus derives from them (UsdLux units, normalize, world sizes), against
/// pxr. Dome orientation: the radiance Nimbus returns in six world directions equals the
/// texel pxr's transform and OpenEXR's lat-long convention put there.
#[test]
fn loaded_lights_match_pxr() {
    let Some((dir, expected)) = generate_fixtures() else {
        return;
    };
    let scene = load_stage(&dir.path().join("lights.usda"), &LoadOptions::default())
        .expect("fixture stage loads");
    let lights = Lights::from_scene(&scene).expect("lights build (texture readable)");

    let distant = expected["distant"].as_array().unwrap();
    assert_eq!(scene.distant_lights.len(), distant.len(), "distant lights");
    assert_eq!(lights.suns.len(), distant.len(), "suns");
    for ((l, sun), e) in scene.distant_lights.iter().zip(&lights.suns).zip(distant) {
        assert_eq!(l.prim_path, e["prim_path"].as_str().unwrap());
        assert_vec("direction", &l.direction, &e["direction"]);
        assert_num("intensity", l.intensity, &e["intensity"]);
        assert_num("exposure", l.exposure, &e["exposure"]);
        assert_vec("color", &l.color, &e["color"]);
        assert_eq!(l.normalize, e["normalize"].as_bool().unwrap(), "normalize");
        assert_num("angle", l.angle_degrees, &e["angle_degrees"]);
        assert_vec("sun ∫L dω", &sun.irradiance, &e["derived"]["irradiance"]);
        assert_num(
            "sun cos θmax",
            sun.cos_half_angle,
            &e["derived"]["cos_half_angle"],
        );
        assert_vec("sun direction", &sun.direction.to_array(), &e["direction"]);
    }

    let spheres = expected["sphere"].as_array().unwrap();
    assert_eq!(
        scene.sphere_lights.len(),
        spheres.len(),
        "sphere lights (the invisible one dropped)"
    );
    for ((l, em), e) in scene.sphere_lights.iter().zip(&lights.spheres).zip(spheres) {
        assert_eq!(l.prim_path, e["prim_path"].as_str().unwrap());
        assert_matrix(&l.prim_path, &l.light_to_world, &e["matrix"]);
        assert_num("intensity", l.intensity, &e["intensity"]);
        assert_num("exposure", l.exposure, &e["exposure"]);
        assert_vec("color", &l.color, &e["color"]);
        assert_num("radius", l.radius, &e["radius"]);
        assert_eq!(l.treat_as_point, e["treat_as_point"].as_bool().unwrap());
        assert_eq!(l.normalize, e["normalize"].as_bool().unwrap());
        let d = &e["derived"];
        assert_vec("sphere centre", &em.center.to_array(), &d["center"]);
        assert_num("sphere world radius", em.radius, &d["radius"]);
        assert_vec_tol("sphere radiance", &em.radiance, &d["radiance"], FLOAT_TOL);
    }

    let rects = expected["rect"].as_array().unwrap();
    assert_eq!(scene.rect_lights.len(), rects.len(), "rect lights");
    for ((l, em), e) in scene.rect_lights.iter().zip(&lights.rects).zip(rects) {
        assert_eq!(l.prim_path, e["prim_path"].as_str().unwrap());
        assert_matrix(&l.prim_path, &l.light_to_world, &e["matrix"]);
        assert_num("width", l.width, &e["width"]);
        assert_num("height", l.height, &e["height"]);
        assert_num("intensity", l.intensity, &e["intensity"]);
        assert_eq!(l.normalize, e["normalize"].as_bool().unwrap());
        let d = &e["derived"];
        assert_vec("rect centre", &em.center.to_array(), &d["center"]);
        assert_vec("rect edge u", &em.edge_u.to_array(), &d["edge_u"]);
        assert_vec("rect edge v", &em.edge_v.to_array(), &d["edge_v"]);
        assert_vec(
            "rect normal (local −Z)",
            &em.normal.to_array(),
            &d["normal"],
        );
        assert_num("rect area", em.area, &d["area"]);
        assert_vec("rect radiance", &em.radiance, &d["radiance"]);
    }

    let domes = expected["dome"].as_array().unwrap();
    assert_eq!(scene.dome_lights.len(), domes.len(), "dome lights");
    let mut constant = [0.0; 3];
    for (l, e) in scene.dome_lights.iter().zip(domes) {
        assert_eq!(l.prim_path, e["prim_path"].as_str().unwrap());
        assert_matrix(&l.prim_path, &l.light_to_world, &e["matrix"]);
        assert_num("dome intensity", l.intensity, &e["intensity"]);
        assert_num("dome exposure", l.exposure, &e["exposure"]);
        assert_eq!(l.texture_format, e["texture_format"].as_str().unwrap());
        match (&l.texture_file, e["texture_file"].as_str()) {
            (Some(ours), Some(theirs)) => {
                let canon = |p: &str| std::fs::canonicalize(p).expect("texture exists");
                assert_eq!(canon(ours), canon(theirs), "resolved texture path");
            }
            (None, None) => {
                let s = e["derived"]["scale"].as_array().unwrap();
                for c in 0..3 {
                    constant[c] += num(&s[c]);
                }
            }
            other => panic!("{}: texture {other:?}", l.prim_path),
        }
    }
    assert_eq!(lights.env_maps.len(), 1, "one textured dome");
    let map = &lights.env_maps[0];
    assert_eq!((map.width, map.height), (16, 8), "texture size");
    for c in 0..3 {
        assert!(close(lights.environment[c], constant[c]), "constant dome");
    }
    let sky = domes
        .iter()
        .find(|d| d["texture_file"].is_string())
        .unwrap();
    for probe in sky["derived"]["probes"].as_array().unwrap() {
        let dirn: Vec<f64> = probe["direction"]
            .as_array()
            .unwrap()
            .iter()
            .map(num)
            .collect();
        let w = DVec3::new(dirn[0], dirn[1], dirn[2]);
        let got = map.radiance(w);
        // Texels are f32 in the file; both sides multiply the same f32 by the scale.
        assert_vec(
            &format!("dome radiance towards {w}"),
            &got,
            &probe["radiance"],
        );
    }
}

/// UsdLux's colour temperature: Nimbus' spline through pxr's blackbody table against
/// `UsdLux.BlackbodyTemperatureAsRgb` from 500 K to 12,500 K (pxr evaluates in float:
/// relative tolerance 1e-5, absolute 1e-6 near 0).
#[test]
fn color_temperature_matches_pxr() {
    use nimbus::color::usd_blackbody_rgb;
    let Some((_dir, expected)) = generate_fixtures() else {
        return;
    };
    for pair in expected["blackbody"].as_array().unwrap() {
        let t = num(&pair[0]);
        let e: Vec<f64> = pair[1].as_array().unwrap().iter().map(num).collect();
        let got = usd_blackbody_rgb(t);
        for c in 0..3 {
            assert!(
                (got[c] - e[c]).abs() <= 1e-5 * e[c].abs() + 1e-6,
                "{t} K: got {got:?}, pxr says {e:?}"
            );
        }
    }
}

// ----- bad dome textures -------------------------------------------------------------------

const CAMERA: &str = "def Camera \"Cam\" { double3 xformOp:translate = (0, 0, 5)\n uniform token[] xformOpOrder = [\"xformOp:translate\"] }\n";

fn dome_stage(dir: &Path, dome_body: &str) -> String {
    let path = dir.join("dome.usda");
    std::fs::write(
        &path,
        format!("#usda 1.0\n{CAMERA}def DomeLight \"Sky\" {{\n{dome_body}\n}}\n"),
    )
    .unwrap();
    let scene = load_stage(&path, &LoadOptions::default()).expect("stage loads");
    match Lights::from_scene(&scene) {
        Ok(_) => panic!("a bad dome texture was accepted: {dome_body}"),
        Err(e) => e.to_string(),
    }
}

/// A missing file, a file that is not an EXR, and an image too small for its layout
/// are errors naming the light prim and the file (`tests/domes.rs` has the rest).
#[test]
fn bad_dome_textures_are_clear_errors() {
    let dir = tempfile::tempdir().unwrap();
    let e = dome_stage(dir.path(), "asset inputs:texture:file = @./nowhere.exr@");
    assert!(
        e.contains("/Sky") && e.contains("nowhere.exr") && e.contains("not found"),
        "{e}"
    );

    std::fs::write(dir.path().join("fake.exr"), b"not an exr").unwrap();
    let e = dome_stage(dir.path(), "asset inputs:texture:file = @./fake.exr@");
    assert!(
        e.contains("/Sky") && e.contains("fake.exr") && e.contains("OpenEXR"),
        "{e}"
    );

    write_exr(&dir.path().join("square.exr"), 4, 4, |_, _| [1.0; 3]);
    let e = dome_stage(
        dir.path(),
        "asset inputs:texture:file = @./square.exr@\n token inputs:texture:format = \"cubeMapVerticalCross\"",
    );
    assert!(
        e.contains("/Sky") && e.contains("4×4") && e.contains("square.exr"),
        "{e}"
    );
}

fn write_exr(path: &Path, w: usize, h: usize, f: impl Fn(usize, usize) -> [f32; 3] + Sync) {
    use exr::prelude::*;
    write_rgb_file(path, w, h, |x, y| {
        let c = f(x, y);
        (c[0], c[1], c[2])
    })
    .expect("write test exr");
}

/// An explicit `latlong` texture of any size is read, values and all.
#[test]
fn latlong_texture_is_read_through_the_stage() {
    let dir = tempfile::tempdir().unwrap();
    write_exr(&dir.path().join("sky.exr"), 6, 5, |x, y| {
        [x as f32, y as f32, 0.5]
    });
    let path = dir.path().join("dome.usda");
    std::fs::write(
        &path,
        format!("#usda 1.0\n{CAMERA}def DomeLight \"Sky\" {{\n asset inputs:texture:file = @./sky.exr@\n token inputs:texture:format = \"latlong\"\n float inputs:intensity = 2\n}}\n"),
    )
    .unwrap();
    let scene = load_stage(&path, &LoadOptions::default()).unwrap();
    let lights = Lights::from_scene(&scene).unwrap();
    let m = &lights.env_maps[0];
    assert_eq!((m.width, m.height), (6, 5));
    // Texel (x=4, y=1): row 1 from the top, column 4.
    assert_eq!(m.texels[6 + 4], [8.0, 2.0, 1.0]);
    assert_eq!(
        lights.environment, [0.0; 3],
        "the textured dome is not a constant"
    );
}

// ----- rendering ---------------------------------------------------------------------

/// A 9×9 camera at `position` looking down −Z; its central pixel's ray is exactly −Z,
/// over [near, far] (depths along −Z).
fn camera(position: DVec3, near: f64, far: f64) -> CameraRays {
    let cam = Camera {
        prim_path: "/Camera".into(),
        camera_to_world: DMat4::from_translation(position),
        focal_length: 1000.0,
        horizontal_aperture: 10.0,
        vertical_aperture: 10.0,
        horizontal_aperture_offset: 0.0,
        vertical_aperture_offset: 0.0,
        clipping_range: (near, far),
        projection: Default::default(),
        f_stop: 0.0,
        focus_distance: 0.0,
        shutter: None,
        motion: None,
    };
    CameraRays::new(&cam, 9, 9)
}

/// `n` samples of the central pixel's radiance: delta tracking, ratio-tracked shadow
/// rays, seed `seed`.
fn samples(
    medium: &Medium,
    lights: &Lights,
    cam: &CameraRays,
    max_depth: u32,
    n: usize,
    seed: u64,
) -> Vec<[f64; 3]> {
    samples_select(medium, lights, cam, max_depth, n, seed, SelectSegments::Off)
}

/// [`samples`] by each way of sampling scattering points near local lights: the
/// trackers' collisions alone, then with equiangular samples by MIS.
fn samples_each(
    medium: &Medium,
    lights: &Lights,
    cam: &CameraRays,
    n: usize,
    seed: u64,
) -> [Vec<[f64; 3]>; 2] {
    let select = SelectSegments::Off;
    [Vec::new(), lights.locals()].map(|locals| {
        samples_with_locals(medium, lights, cam, 1, n, seed, select, locals, None, None)
    })
}

/// [`samples`], with `ratio-select`'s walks for every segment when `select` says so.
fn samples_select(
    medium: &Medium,
    lights: &Lights,
    cam: &CameraRays,
    max_depth: u32,
    n: usize,
    seed: u64,
    select: SelectSegments,
) -> Vec<[f64; 3]> {
    samples_with_locals(
        medium,
        lights,
        cam,
        max_depth,
        n,
        seed,
        select,
        Vec::new(),
        None,
        None,
    )
}

/// [`samples_select`], also sampling scattering points towards `locals`, guiding
/// scattered directions towards `guide`'s lobes and choosing one light per vertex by
/// `light_choice`.
#[allow(clippy::too_many_arguments)]
fn samples_with_locals(
    medium: &Medium,
    lights: &Lights,
    cam: &CameraRays,
    max_depth: u32,
    n: usize,
    seed: u64,
    select: SelectSegments,
    locals: Vec<nimbus::render::equiangular::LocalLight>,
    guide: Option<LightLobes>,
    light_choice: Option<LightChoice>,
) -> Vec<[f64; 3]> {
    let it = Integrator {
        free_path: Delta,
        transmittance: Ratio,
        channel_per_path: false,
        majorant_scale: 1.0,
        count: true,
        profile: false,
        media: std::slice::from_ref(medium),
        lights,
        camera: cam,
        width: 9,
        height: 9,
        spp: 1,
        max_depth,
        seed,
        qmc_dims: 0,
        extras: Default::default(),
        select_segments: select,
        locals,
        shutter: None,
        guide,
        light_choice,
    };
    let mut rng = pixel_sampler(seed, 40);
    let mut c = Counters::default();
    (0..n)
        .map(|_| it.sample(4.5, 4.5, &mut rng, &mut c).rgb)
        .collect()
}

fn mean_se(s: &[[f64; 3]]) -> ([f64; 3], [f64; 3]) {
    let n = s.len() as f64;
    let m = [0, 1, 2].map(|c| s.iter().map(|v| v[c]).sum::<f64>() / n);
    let se = [0, 1, 2].map(|c| {
        let var = s.iter().map(|v| (v[c] - m[c]).powi(2)).sum::<f64>() / (n - 1.0);
        (var / n).sqrt()
    });
    (m, se)
}

fn z_scores(s: &[[f64; 3]], expected: [f64; 3]) -> [f64; 3] {
    let (m, se) = mean_se(s);
    eprintln!("mean {m:?} ± {se:?}, expected {expected:?}");
    [0, 1, 2].map(|c| (m[c] - expected[c]) / se[c].max(1e-300))
}

/// Composite Simpson over [a, b] with `n` (even) intervals.
fn simpson(a: f64, b: f64, n: usize, f: impl Fn(f64) -> f64) -> f64 {
    let h = (b - a) / n as f64;
    let mut s = f(a) + f(b);
    for i in 1..n {
        s += f(a + i as f64 * h) * if i % 2 == 1 { 4.0 } else { 2.0 };
    }
    s * h / 3.0
}

/// Single scattering seen by a camera inside a homogeneous medium (the cube of side 20,
/// σs = 0.1, σa = 0.05, so every path stays where the density is exactly 1): along the
/// central ray x(t) = −t·Z, t ∈ [t0, t1] (the clipping range),
/// L = ∫ σs e^{−σt (t − t0)} S(x(t)) dt with S the light's in-scattered radiance
/// (phase × emission × transmittance to the light), both integrals by quadrature.
struct SlabSetup {
    medium: Medium,
    cam: CameraRays,
    t0: f64,
    t1: f64,
}

const SIGMA_S: f64 = 0.1;
const SIGMA_T: f64 = 0.15;

fn slab(g: f64) -> SlabSetup {
    let cam = camera(DVec3::ZERO, 0.1, 7.0);
    let ray = cam.ray(4.5, 4.5);
    assert!((ray.dir - DVec3::NEG_Z).length() < 1e-12);
    SlabSetup {
        medium: common::unit_cube(20.0, [SIGMA_T - SIGMA_S; 3], [SIGMA_S; 3], g),
        t0: ray.tmin,
        t1: ray.tmax,
        cam,
    }
}

impl SlabSetup {
    fn expected(&self, s: impl Fn(DVec3) -> [f64; 3]) -> [f64; 3] {
        [0, 1, 2].map(|c| {
            simpson(self.t0, self.t1, 400, |t| {
                SIGMA_S * (-SIGMA_T * (t - self.t0)).exp() * s(DVec3::new(0.0, 0.0, -t))[c]
            })
        })
    }
}

/// A point light (a sphere light with treatAsPoint): S = f(cos) · I · e^{−σt d}/d².
/// HG g = 0.4 checks the phase argument's orientation. N = 4,000,000, seed 11; |z| < 4.
#[test]
fn point_light_single_scattering_matches_quadrature() {
    let setup = slab(0.4);
    let c = DVec3::new(1.0, 0.5, -3.0);
    let intensity = [2.0, 1.0, 0.5];
    let lights = Lights {
        spheres: vec![SphereEmitter {
            center: c,
            radius: 0.0,
            radiance: intensity,
            ..Default::default()
        }],
        ..Default::default()
    };
    let expected = setup.expected(|x| {
        let v = c - x;
        let d = v.length();
        let f = hg(0.4, DVec3::NEG_Z.dot(v / d));
        intensity.map(|i| f * i * (-SIGMA_T * d).exp() / (d * d))
    });
    for s in samples_each(&setup.medium, &lights, &setup.cam, 4_000_000, 11) {
        let z = z_scores(&s, expected);
        assert!(
            z.iter().all(|z| z.abs() < 4.0),
            "z = {z:?}, expected {expected:?}"
        );
    }
}

/// A sphere light of radius 0.6: S = (1/4π) · 2π L ∫₀^θmax e^{−σt s(θ)} sin θ dθ with
/// s(θ) the distance to the sphere's near surface. N = 4,000,000, seed 12; |z| < 4.
#[test]
fn sphere_light_single_scattering_matches_quadrature() {
    let setup = slab(0.0);
    let c = DVec3::new(0.8, -0.6, -4.0);
    let r = 0.6;
    let radiance = [1.5, 1.0, 3.0];
    let lights = Lights {
        spheres: vec![SphereEmitter {
            center: c,
            radius: r,
            radiance,
            ..Default::default()
        }],
        ..Default::default()
    };
    let expected = setup.expected(|x| {
        let d = (c - x).length();
        let theta_max = (r / d).asin();
        let integral = simpson(0.0, theta_max, 200, |t| {
            let s = d * t.cos() - (r * r - d * d * t.sin().powi(2)).max(0.0).sqrt();
            (-SIGMA_T * s).exp() * t.sin()
        });
        radiance.map(|l| l * 2.0 * PI * integral / (4.0 * PI))
    });
    for s in samples_each(&setup.medium, &lights, &setup.cam, 4_000_000, 12) {
        let z = z_scores(&s, expected);
        assert!(
            z.iter().all(|z| z.abs() < 4.0),
            "z = {z:?}, expected {expected:?}"
        );
    }
}

fn rect_facing(normal: DVec3) -> RectEmitter {
    // A 1.2 × 0.8 rectangle at (0, 1.5, −4) in the XZ plane.
    let edge_u = DVec3::new(1.2, 0.0, 0.0);
    let edge_v = DVec3::new(0.0, 0.0, 0.8);
    RectEmitter {
        center: DVec3::new(0.0, 1.5, -4.0),
        edge_u,
        edge_v,
        normal,
        area: 1.2 * 0.8,
        radiance: [2.0, 4.0, 1.0],
        ..Default::default()
    }
}

/// A rect light facing the ray (emitting along −Y): S = (1/4π) ∫_A L cos θ_l e^{−σt d}/d²
/// dA (Simpson 2D over the rectangle). N = 4,000,000, seed 13; |z| < 4. Turned away
/// (emitting along +Y) it contributes exactly nothing: one-sided.
#[test]
fn rect_light_single_scattering_matches_quadrature_and_is_one_sided() {
    let setup = slab(0.0);
    let rect = rect_facing(DVec3::NEG_Y);
    let expected = setup.expected(|x| {
        let e = simpson(-0.5, 0.5, 40, |a| {
            simpson(-0.5, 0.5, 40, |b| {
                let q = rect.center + rect.edge_u * a + rect.edge_v * b;
                let v = q - x;
                let d2 = v.length_squared();
                let cos_l = (-(v / d2.sqrt())).dot(rect.normal).max(0.0);
                cos_l * (-SIGMA_T * d2.sqrt()).exp() / d2
            })
        }) * rect.area;
        rect.radiance.map(|l| l * e / (4.0 * PI))
    });
    let lights = Lights {
        rects: vec![rect],
        ..Default::default()
    };
    for s in samples_each(&setup.medium, &lights, &setup.cam, 4_000_000, 13) {
        let z = z_scores(&s, expected);
        assert!(
            z.iter().all(|z| z.abs() < 4.0),
            "z = {z:?}, expected {expected:?}"
        );
    }

    let away = Lights {
        rects: vec![rect_facing(DVec3::Y)],
        ..Default::default()
    };
    let s = samples(&setup.medium, &away, &setup.cam, 1, 20_000, 14);
    assert!(
        s.iter().all(|v| *v == [0.0; 3]),
        "the back of a rect light emitted"
    );
}

/// A normalized DistantLight of angle 20° straight up (+Y): radiance
/// s / (π sin²θmax) over the disk, and S = (1/4π) · 2π L ∫₀^θmax e^{−σt·10/cos θ} sin θ dθ
/// (every shadow ray leaves through the y = 10 face, whose density ramp is symmetric
/// about the face, so the optical depth is σt × the distance to the plane).
/// N = 4,000,000, seed 15; |z| < 4.
#[test]
fn sun_disk_single_scattering_matches_quadrature() {
    use nimbus::render::lights::distant_size_factor;
    let setup = slab(0.0);
    let theta_max = 10f64.to_radians();
    let s = [3.0, 2.0, 1.0];
    let radiance = s.map(|v| v / distant_size_factor(theta_max));
    let solid_angle = 2.0 * PI * (1.0 - theta_max.cos());
    let lights = Lights {
        suns: vec![Sun {
            direction: DVec3::Y,
            irradiance: radiance.map(|l| l * solid_angle),
            cos_half_angle: theta_max.cos(),
            ..Default::default()
        }],
        ..Default::default()
    };
    let integral = simpson(0.0, theta_max, 400, |t| {
        (-SIGMA_T * 10.0 / t.cos()).exp() * t.sin()
    });
    let expected = setup.expected(|_| radiance.map(|l| l * 2.0 * PI * integral / (4.0 * PI)));
    let samples = samples(&setup.medium, &lights, &setup.cam, 1, 4_000_000, 15);
    let z = z_scores(&samples, expected);
    assert!(
        z.iter().all(|z| z.abs() < 4.0),
        "z = {z:?}, expected {expected:?}"
    );
}

/// A cube (side 1, σa = 0.5, σs = (2, 1, 0.5), g = 0.5, multiple scattering) in front of
/// a camera on +Z, lit by `lights`.
fn lit_cube(lights: &Lights, n: usize, seed: u64) -> Vec<[f64; 3]> {
    lit_cube_to_depth(lights, 64, n, seed)
}

/// [`lit_cube`] with at most `max_depth` scattering events.
fn lit_cube_to_depth(lights: &Lights, max_depth: u32, n: usize, seed: u64) -> Vec<[f64; 3]> {
    lit_cube_select(lights, max_depth, n, seed, SelectSegments::Off)
}

/// [`lit_cube_to_depth`], with `ratio-select`'s walks as `select` says.
fn lit_cube_select(
    lights: &Lights,
    max_depth: u32,
    n: usize,
    seed: u64,
    select: SelectSegments,
) -> Vec<[f64; 3]> {
    let medium = common::unit_cube(1.0, [0.5; 3], [2.0, 1.0, 0.5], 0.5);
    let cam = camera(DVec3::new(0.0, 0.0, 10.0), 0.1, 1e6);
    samples_select(&medium, lights, &cam, max_depth, n, seed, select)
}

fn two_sample_z(a: &[[f64; 3]], b: &[[f64; 3]]) -> [f64; 3] {
    let (ma, sa) = mean_se(a);
    let (mb, sb) = mean_se(b);
    eprintln!("a {ma:?} ± {sa:?}, b {mb:?} ± {sb:?}");
    [0, 1, 2].map(|c| (ma[c] - mb[c]) / (sa[c] * sa[c] + sb[c] * sb[c]).sqrt().max(1e-300))
}

/// A dome textured with a constant image renders like the constant dome: two
/// independent estimates (N = 50,000 each, seeds 21 and 22; 40,000 at the small
/// depths, seeds 31… and 41…) of the cube's central pixel, two-sample |z| < 4 per
/// channel. The textured dome is sampled at every scattering vertex (importance
/// sampling, a sin θ-weighted piecewise-constant density, combined with phase
/// sampling by MIS); the constant dome only through the phase-sampled continuation,
/// and by a shadow ray at a path's last vertex. At maximum depths 1 and 2 the last
/// vertex carries a large share of the light, so a wrong weight there would show.
#[test]
fn constant_texture_dome_matches_constant_dome() {
    let value = [0.7, 1.1, 0.4];
    let (w, h) = (32, 16);
    let map = EnvMap::new(w, h, vec![value; w * h], DMat4::from_rotation_x(0.3));
    let textured = Lights {
        env_maps: vec![map],
        ..Default::default()
    };
    let constant = Lights {
        environment: value,
        ..Default::default()
    };
    assert!(textured.environment_nee() && !constant.environment_nee());
    let a = lit_cube(&textured, 50_000, 21);
    let b = lit_cube(&constant, 50_000, 22);
    let z = two_sample_z(&a, &b);
    assert!(z.iter().all(|z| z.abs() < 4.0), "z = {z:?}");
    for depth in [1, 2] {
        let a = lit_cube_to_depth(&textured, depth, 40_000, 30 + depth as u64);
        let b = lit_cube_to_depth(&constant, depth, 40_000, 40 + depth as u64);
        let z = two_sample_z(&a, &b);
        assert!(
            z.iter().all(|z| z.abs() < 4.0),
            "max depth {depth}: z = {z:?}"
        );
    }
}

/// A non-constant dome (a bright patch in a dim sky, rotated) plus a constant dome:
/// importance sampling of the texture and uniform sampling agree. N = 100,000 each,
/// seeds 23 and 24; two-sample |z| < 4 per channel.
#[test]
fn importance_sampled_dome_agrees_with_uniform_sampling() {
    let a = lit_cube(&patch_sky_lights(true), 100_000, 23);
    let b = lit_cube(&patch_sky_lights(false), 100_000, 24);
    let z = two_sample_z(&a, &b);
    assert!(z.iter().all(|z| z.abs() < 4.0), "z = {z:?}");
}

/// ratio-select under an importance-sampled dome (NEE at every vertex, MIS with the
/// background its walks weight by T̂) agrees with delta tracking: the cube of
/// [`lit_cube`] under the bright-patch sky plus a constant dome, N = 100,000 each (seeds
/// 25 and 26), and at maximum depths 1 and 2, where the last vertex's shadow ray carries
/// the environment (N = 50,000, seeds 51… and 61…); two-sample |z| < 4 per channel.
#[test]
fn ratio_select_agrees_with_delta_under_a_textured_dome() {
    let lights = patch_sky_lights(true);
    for (depth, n, seed) in [(64, 100_000, 25), (1, 50_000, 51), (2, 50_000, 52)] {
        let a = lit_cube_select(&lights, depth, n, seed, SelectSegments::Off);
        let b = lit_cube_select(&lights, depth, n, seed + 10, SelectSegments::Rgb);
        let z = two_sample_z(&a, &b);
        assert!(
            z.iter().all(|z| z.abs() < 4.0),
            "max depth {depth}: z = {z:?}"
        );
    }
}

/// Scattered directions guided towards local lights ([`LightLobes`]: half of them from
/// lobes towards the lights, weighted phase / mixture) render what the phase function
/// alone renders, with the environment's MIS taken against the mixture: the cube of
/// [`lit_cube`] under the bright-patch sky (NEE at every vertex) plus a sphere light
/// (r 0.1) inside it and one outside, delta and ratio-select, the whole path (max depth
/// 64) and two bounces; N = 100,000 each (seeds 71… guided, 81… not); two-sample
/// |z| < 4 per channel. Weighing the escaping ray's MIS by the phase function instead
/// of the mixture fails it (z 4.0 in G, 5.7 in B at max depth 64 with delta; checked
/// by hand).
#[test]
fn guided_continuations_agree_with_phase_sampling() {
    let mut lights = patch_sky_lights(true);
    for (center, radiance) in [
        (DVec3::new(0.2, -0.1, 0.1), 40.0),
        (DVec3::new(0.0, 1.6, 0.4), 15.0),
    ] {
        lights.spheres.push(SphereEmitter {
            center,
            radius: 0.1,
            radiance: [radiance, 0.8 * radiance, 0.5 * radiance],
            ..Default::default()
        });
    }
    let lobes = LightLobes::new(&lights.locals());
    assert!(lobes.is_some());
    let medium = common::unit_cube(1.0, [0.5; 3], [2.0, 1.0, 0.5], 0.5);
    let cam = camera(DVec3::new(0.0, 0.0, 10.0), 0.1, 1e6);
    let cases = [
        (64, SelectSegments::Off),
        (64, SelectSegments::Rgb),
        (2, SelectSegments::Off),
    ];
    for (i, (depth, select)) in cases.into_iter().enumerate() {
        let n = 100_000;
        let run = |guide: Option<LightLobes>, seed| {
            samples_with_locals(
                &medium,
                &lights,
                &cam,
                depth,
                n,
                seed,
                select,
                Vec::new(),
                guide,
                None,
            )
        };
        let a = run(lobes.clone(), 71 + i as u64);
        let b = run(None, 81 + i as u64);
        let z = two_sample_z(&a, &b);
        assert!(
            z.iter().all(|z| z.abs() < 4.0),
            "max depth {depth}, {select:?}: z = {z:?}"
        );
    }
}

/// Past `MANY_LIGHTS` local lights each vertex samples one, chosen by power over
/// squared distance and divided by its probability ([`LightChoice`]): the same image as
/// sampling every light. The cube of [`lit_cube`] (no dome) lit by six sphere lights
/// (inside and outside it, radiances 0.5–40; one a point, outside: inside the medium
/// a point light's next events have infinite variance) and a rect facing it (the choice
/// counts lights across kinds), delta at max depth 64 and at 2, ratio-select at 64, and
/// delta with equiangular points towards every light (whose MIS weights are per
/// light); N = 100,000 each (seeds 91… chosen, 101… every light); two-sample |z| < 4
/// per channel.
#[test]
fn one_light_chosen_among_many_agrees_with_every_light() {
    let mut lights = Lights {
        rects: vec![rect_facing(DVec3::new(0.0, -1.0, 0.0))],
        ..Default::default()
    };
    lights.rects[0].center = DVec3::new(0.0, 1.5, 0.0);
    let spheres = [
        (DVec3::new(0.2, -0.1, 0.1), 0.1, 40.0),
        (DVec3::new(-0.3, 0.3, -0.8), 0.0, 2.0),
        (DVec3::new(0.0, -1.6, 0.4), 0.2, 15.0),
        (DVec3::new(2.0, 0.5, 0.0), 0.3, 8.0),
        (DVec3::new(-0.4, -0.4, 0.4), 0.05, 0.5),
        (DVec3::new(0.0, 0.0, 3.0), 0.5, 25.0),
    ];
    for (center, radius, radiance) in spheres {
        lights.spheres.push(SphereEmitter {
            center,
            radius,
            radiance: [radiance, 0.7 * radiance, 0.4 * radiance],
            ..Default::default()
        });
    }
    let choice = LightChoice::new(&lights.locals());
    assert!(choice.is_some());
    let medium = common::unit_cube(1.0, [0.5; 3], [2.0, 1.0, 0.5], 0.5);
    let cam = camera(DVec3::new(0.0, 0.0, 10.0), 0.1, 1e6);
    let cases = [
        (64, SelectSegments::Off, false),
        (2, SelectSegments::Off, false),
        (64, SelectSegments::Rgb, false),
        (64, SelectSegments::Off, true),
    ];
    for (i, (depth, select, equiangular)) in cases.into_iter().enumerate() {
        let n = 100_000;
        let locals = if equiangular {
            lights.locals()
        } else {
            Vec::new()
        };
        let run = |choice: Option<LightChoice>, seed| {
            let locals = locals.clone();
            samples_with_locals(
                &medium, &lights, &cam, depth, n, seed, select, locals, None, choice,
            )
        };
        let a = run(choice.clone(), 91 + i as u64);
        let b = run(None, 101 + i as u64);
        let z = two_sample_z(&a, &b);
        assert!(
            z.iter().all(|z| z.abs() < 4.0),
            "max depth {depth}, {select:?}, equiangular {equiangular}: z = {z:?}"
        );
    }
}

/// Past `TREE_LIGHTS` local lights with power the light is chosen by descending a light
/// tree (src/render/light_choice.rs): the same image as sampling every light at every
/// vertex. A hundred sphere lights (radii 0.03–0.07, radiances 0–30, every tenth without
/// power) on a spiral through and around the cube of a medium with albedo 0.5; delta at
/// max depth 64, continuations from the phase function; N = 100,000 each (seeds 141,
/// 151); two-sample |z| < 4 per channel.
#[test]
fn lights_chosen_through_the_tree_agree_with_every_light() {
    let mut lights = Lights::default();
    for i in 0..100 {
        let a = i as f64 * 0.37;
        let r = [0.2, 0.6, 1.4][i % 3];
        let radiance = if i % 10 == 3 {
            0.0
        } else {
            (i * 13 % 30) as f64 + 0.5
        };
        lights.spheres.push(SphereEmitter {
            center: DVec3::new(r * a.cos(), r * a.sin(), -1.5 + 0.03 * i as f64),
            radius: 0.03 + 0.01 * (i % 5) as f64,
            radiance: [radiance, 0.7 * radiance, 0.4 * radiance],
            ..Default::default()
        });
    }
    let choice = LightChoice::new(&lights.locals());
    assert!(choice.as_ref().is_some_and(LightChoice::walks_a_tree));
    let medium = common::unit_cube(1.0, [0.5; 3], [2.0, 1.0, 0.5], 0.5);
    let cam = camera(DVec3::new(0.0, 0.0, 10.0), 0.1, 1e6);
    let n = 100_000;
    let off = SelectSegments::Off;
    let run = |choice, seed| {
        samples_with_locals(
            &medium,
            &lights,
            &cam,
            64,
            n,
            seed,
            off,
            Vec::new(),
            None,
            choice,
        )
    };
    let a = run(choice, 141);
    let b = run(None, 151);
    let z = two_sample_z(&a, &b);
    assert!(z.iter().all(|z| z.abs() < 4.0), "z = {z:?}");
}

/// Past `ONE_LOBE_LIGHTS` local lights a continuation is guided towards the one light
/// the vertex's next event chose (`LightLobes::sample_towards`), not the mixture of
/// every lobe: the same image as sampling every light at every vertex with directions
/// from the phase function. Forty sphere lights (radii 0.05–0.09, radiances 1–40) on
/// a spiral through and around the cube of [`lit_cube`]'s medium; delta at max depth
/// 64; N = 100,000 each (seeds 121, 131); two-sample |z| < 4 per channel.
#[test]
fn continuations_guided_towards_the_chosen_light_agree_with_the_phase_function() {
    let mut lights = Lights::default();
    for i in 0..40 {
        let a = i as f64 * 0.9;
        let r = if i % 2 == 0 { 0.3 } else { 1.2 };
        let radiance = 1.0 + (i * 7 % 40) as f64;
        lights.spheres.push(SphereEmitter {
            center: DVec3::new(r * a.cos(), r * a.sin(), -1.0 + 0.05 * i as f64),
            radius: 0.05 + 0.01 * (i % 5) as f64,
            radiance: [radiance, 0.7 * radiance, 0.4 * radiance],
            ..Default::default()
        });
    }
    let locals = lights.locals();
    let lobes = LightLobes::new(&locals).unwrap();
    assert!(lobes.one_lobe());
    let medium = common::unit_cube(1.0, [0.5; 3], [2.0, 1.0, 0.5], 0.5);
    let cam = camera(DVec3::new(0.0, 0.0, 10.0), 0.1, 1e6);
    let n = 100_000;
    let off = SelectSegments::Off;
    let choice = LightChoice::new(&locals);
    let a = samples_with_locals(
        &medium,
        &lights,
        &cam,
        64,
        n,
        121,
        off,
        Vec::new(),
        Some(lobes),
        choice,
    );
    let b = samples_with_locals(
        &medium,
        &lights,
        &cam,
        64,
        n,
        131,
        off,
        Vec::new(),
        None,
        None,
    );
    let z = two_sample_z(&a, &b);
    assert!(z.iter().all(|z| z.abs() < 4.0), "z = {z:?}");
}

/// The bright-patch sky (64×32, rotated) plus a dim constant dome; the texture
/// importance-sampled or sampled uniformly.
fn patch_sky_lights(importance: bool) -> Lights {
    let mut map = EnvMap::new(
        64,
        32,
        bright_patch_sky(64, 32),
        DMat4::from_rotation_y(1.0),
    );
    map.importance = importance;
    Lights {
        env_maps: vec![map],
        environment: [0.05, 0.05, 0.1],
        ..Default::default()
    }
}

fn bright_patch_sky(w: usize, h: usize) -> Vec<[f64; 3]> {
    (0..w * h)
        .map(|i| {
            let (x, y) = (i % w, i / w);
            if (20..26).contains(&x) && (6..10).contains(&y) {
                [60.0, 50.0, 30.0]
            } else {
                [0.2, 0.3, 0.5 + 0.01 * y as f64]
            }
        })
        .collect()
}

/// The sampler and its density agree: the mean of L(ω)/pdf(ω) over ω drawn by
/// `EnvMap::sample` is ∫ L dω = Σ texel · (2π/W)(cos θ₀ − cos θ₁), exactly. For
/// importance and uniform sampling; N = 200,000, seed 31; |z| < 4 per channel.
#[test]
fn envmap_sampling_estimates_the_integral() {
    let (w, h) = (64, 32);
    let texels = bright_patch_sky(w, h);
    let mut exact = [0.0; 3];
    for y in 0..h {
        let d_omega = 2.0 * PI / w as f64
            * ((PI * y as f64 / h as f64).cos() - (PI * (y + 1) as f64 / h as f64).cos());
        for x in 0..w {
            for c in 0..3 {
                exact[c] += texels[y * w + x][c] * d_omega;
            }
        }
    }
    for importance in [true, false] {
        let mut map = EnvMap::new(w, h, texels.clone(), DMat4::from_rotation_z(0.4));
        map.importance = importance;
        let mut rng = rand_pcg::Pcg32::seed_from_u64(31);
        let s: Vec<[f64; 3]> = (0..200_000)
            .map(|_| {
                let d = map.sample(rng.gen(), rng.gen());
                let p = map.pdf(d);
                map.radiance(d).map(|l| l / p)
            })
            .collect();
        let z = z_scores(&s, exact);
        assert!(
            z.iter().all(|z| z.abs() < 4.0),
            "importance {importance}: z = {z:?}"
        );
    }
}
