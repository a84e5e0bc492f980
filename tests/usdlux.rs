//! UsdLux, complete for volumes: disk and cylinder lights (and lines), zero-size and
//! `treatAsPoint` spheres, ShapingAPI's cone, softness and focus, light and shadow
//! linking (`collection:lightLink`, `collection:shadowLink`) per volume and per
//! holdout, the light-value checks, and the warnings for what is not rendered.
//!
//! Stages are generated here (the example cloud with its lights replaced); renders
//! against closed forms or quadrature use the library's integrator on a homogeneous
//! slab, as tests/lights.rs does.

mod common;

use std::f64::consts::PI;
use std::path::{Path, PathBuf};

use common::cli::{assert_clean_error, nimbus, root, stats_json, stderr};
use glam::{DMat4, DVec3};
use nimbus::render::camera::CameraRays;
use nimbus::render::holdouts::Holdouts;
use nimbus::render::integrator::{Extras, Integrator, SelectSegments};
use nimbus::render::lights::{HoldoutSet, Lights, Link, Shaping, SphereEmitter, Sun};
use nimbus::render::sampler::pixel_sampler;
use nimbus::scene::{load_stage, Camera, Collection, LoadOptions, Scene};
use nimbus::track::delta::Delta;
use nimbus::track::ratio::Ratio;
use nimbus::volume::counters::Counters;
use nimbus::volume::medium::Medium;

// ----- stages ----------------------------------------------------------------------

/// The example cloud (`/World/Cloud`) with its sun and sky replaced by `prims` (USD
/// text inside /World).
fn cloud_with(dir: &Path, prims: &str) -> PathBuf {
    let text = std::fs::read_to_string(root().join("scenes/cloud/cloud.usda")).unwrap();
    let start = text.find("    def DistantLight \"Sun\"").unwrap();
    let end = text.find("def Scope \"Render\"").unwrap();
    let text = format!("{}{prims}\n}}\n\n{}", &text[..start], &text[end..]).replace(
        "@./cloud.vdb@",
        &format!("@{}@", root().join("scenes/cloud/cloud.vdb").display()),
    );
    let path = dir.join("stage.usda");
    std::fs::write(&path, text).unwrap();
    path
}

fn load(prims: &str) -> (tempfile::TempDir, Scene) {
    let dir = tempfile::tempdir().unwrap();
    let stage = cloud_with(dir.path(), prims);
    let scene = load_stage(&stage, &LoadOptions::default()).expect("stage loads");
    (dir, scene)
}

fn load_error(prims: &str) -> String {
    let dir = tempfile::tempdir().unwrap();
    let stage = cloud_with(dir.path(), prims);
    match load_stage(&stage, &LoadOptions::default()) {
        Ok(_) => panic!("{prims} loaded"),
        Err(e) => format!("{e:#}"),
    }
}

/// Values authored as float (sizes, scales, angles) carry float rounding into what is
/// derived from them.
fn close(a: f64, b: f64) -> bool {
    (a - b).abs() <= 1e-6 * a.abs().max(b.abs()).max(1.0)
}

fn assert_rgb(what: &str, a: [f64; 3], b: [f64; 3]) {
    assert!(
        (0..3).all(|c| close(a[c], b[c])),
        "{what}: got {a:?}, expected {b:?}"
    );
}

// ----- the slab ----------------------------------------------------------------------

/// A 9×9 camera at the origin looking down −Z; its central pixel's ray is exactly −Z
/// over [near, far].
fn camera(near: f64, far: f64) -> CameraRays {
    let cam = Camera {
        prim_path: "/Camera".into(),
        camera_to_world: DMat4::IDENTITY,
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

/// Single scattering (maximum depth 1) seen along the central ray of [`camera`] inside
/// homogeneous cubes of side 20 centred at the origin (density exactly 1 where every
/// path and shadow ray below stays), σs = 0.1 and σa = 0.05 in total, split evenly
/// among `n_media` overlapping copies: L = ∫ σs e^{−σt (t − t0)} S(x(t)) dt, with S the
/// in-scattered radiance (isotropic phase).
struct Slab {
    media: Vec<Medium>,
    cam: CameraRays,
    t0: f64,
    t1: f64,
}

const SIGMA_S: f64 = 0.1;
const SIGMA_T: f64 = 0.15;

fn slab(n_media: usize) -> Slab {
    let cam = camera(0.1, 7.0);
    let ray = cam.ray(4.5, 4.5);
    assert!((ray.dir - DVec3::NEG_Z).length() < 1e-12);
    let k = n_media as f64;
    let sa = (SIGMA_T - SIGMA_S) / k;
    let ss = SIGMA_S / k;
    Slab {
        media: (0..n_media)
            .map(|_| common::unit_cube(20.0, [sa; 3], [ss; 3], 0.0))
            .collect(),
        t0: ray.tmin,
        t1: ray.tmax,
        cam,
    }
}

impl Slab {
    /// The single-scattering integral of `s(x)` (the radiance scattered per unit σs,
    /// before the phase function) along the central ray, with the scattering
    /// coefficient `sigma_s_lit` of the media lit.
    fn expected_lit(&self, sigma_s_lit: f64, s: impl Fn(DVec3) -> [f64; 3]) -> [f64; 3] {
        [0, 1, 2].map(|c| {
            simpson(self.t0, self.t1, 400, |t| {
                sigma_s_lit * (-SIGMA_T * (t - self.t0)).exp() * s(DVec3::new(0.0, 0.0, -t))[c]
                    / (4.0 * PI)
            })
        })
    }

    fn expected(&self, s: impl Fn(DVec3) -> [f64; 3]) -> [f64; 3] {
        self.expected_lit(SIGMA_S, s)
    }

    fn samples(&self, lights: &Lights, n: usize, seed: u64) -> Vec<[f64; 3]> {
        self.samples_with(lights, Extras::default(), n, seed)
    }

    /// [`Self::samples`] by each way of sampling scattering points near local lights:
    /// the trackers' collisions alone, then with equiangular samples by MIS.
    fn samples_each(&self, lights: &Lights, n: usize, seed: u64) -> [Vec<[f64; 3]>; 2] {
        [Vec::new(), lights.locals()]
            .map(|locals| self.samples_located(lights, Extras::default(), n, seed, locals))
    }

    /// `n` samples of the central pixel: delta tracking, ratio-tracked shadow rays.
    fn samples_with(&self, lights: &Lights, extras: Extras, n: usize, seed: u64) -> Vec<[f64; 3]> {
        self.samples_located(lights, extras, n, seed, Vec::new())
    }

    /// [`Self::samples_with`], also sampling scattering points towards `locals`.
    fn samples_located(
        &self,
        lights: &Lights,
        extras: Extras,
        n: usize,
        seed: u64,
        locals: Vec<nimbus::render::equiangular::LocalLight>,
    ) -> Vec<[f64; 3]> {
        let it = Integrator {
            free_path: Delta,
            transmittance: Ratio,
            channel_per_path: false,
            majorant_scale: 1.0,
            count: false,
            profile: false,
            media: &self.media,
            lights,
            camera: &self.cam,
            width: 9,
            height: 9,
            spp: 1,
            max_depth: 1,
            seed,
            qmc_dims: 0,
            extras,
            select_segments: SelectSegments::Off,
            locals,
            shutter: None,
            // Single scattering: no vertex continues, so no direction is guided.
            guide: None,
            light_choice: None,
        };
        let mut rng = pixel_sampler(seed, 40);
        let mut c = Counters::default();
        (0..n)
            .map(|_| it.sample(4.5, 4.5, &mut rng, &mut c).rgb)
            .collect()
    }
}

fn z_scores(s: &[[f64; 3]], expected: [f64; 3]) -> [f64; 3] {
    let n = s.len() as f64;
    let m = [0, 1, 2].map(|c| s.iter().map(|v| v[c]).sum::<f64>() / n);
    let se = [0, 1, 2].map(|c| {
        let var = s.iter().map(|v| (v[c] - m[c]).powi(2)).sum::<f64>() / (n - 1.0);
        (var / n).sqrt()
    });
    eprintln!("mean {m:?} ± {se:?}, expected {expected:?}");
    [0, 1, 2].map(|c| (m[c] - expected[c]) / se[c].max(1e-300))
}

fn assert_z(s: &[[f64; 3]], expected: [f64; 3]) {
    let z = z_scores(s, expected);
    assert!(
        z.iter().all(|z| z.abs() < 4.0),
        "z = {z:?}, expected {expected:?}"
    );
}

/// The radiance a sphere light (centre `c`, radius `r`, surface radiance `radiance`)
/// sends to `x` through a medium of extinction `sigma`, integrated over directions:
/// 2π L ∫ e^{−σ s(θ)} sin θ dθ over the cone it subtends (s the near root), or from
/// inside, with `interior`, over every direction (s the far root; 0 without it);
/// Simpson with `n` intervals.
fn sphere_fluence(
    c: DVec3,
    r: f64,
    radiance: [f64; 3],
    sigma: f64,
    interior: bool,
    x: DVec3,
    n: usize,
) -> [f64; 3] {
    let d = (c - x).length();
    let chord = |t: f64| (r * r - d * d * t.sin().powi(2)).max(0.0).sqrt();
    let integral = if d > r {
        simpson(0.0, (r / d).asin(), n, |t| {
            (-sigma * (d * t.cos() - chord(t))).exp() * t.sin()
        })
    } else if interior {
        simpson(0.0, PI, n, |t| {
            (-sigma * (d * t.cos() + chord(t))).exp() * t.sin()
        })
    } else {
        0.0
    };
    radiance.map(|l| l * 2.0 * PI * integral)
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

/// Radiance L from a surface point `q` with outward normal `n` reaching `x` through
/// the slab, per unit area: L cos θ_l e^{−σt d}/d² (0 from behind).
fn area_term(x: DVec3, q: DVec3, n: DVec3) -> f64 {
    let v = x - q;
    let d2 = v.length_squared();
    let d = d2.sqrt();
    let cos_l = (v / d).dot(n).max(0.0);
    cos_l * (-SIGMA_T * d).exp() / d2
}

// ----- disk and cylinder lights ----------------------------------------------------

/// A DiskLight of radius 0.5, scaled 1.6 along its X (an ellipse of semi-axes 0.8 and
/// 0.5) and turned to emit along −Y towards the ray, normalized: its radiance is
/// s/(π·0.8·0.5) (UsdLux: luminance / world-space area), and
/// S(x) = ∫_A L cos θ_l e^{−σt d}/d² dA by 2-D Simpson over the ellipse.
/// N = 2,000,000, seed 21; |z| < 4.
#[test]
fn disk_light_single_scattering_matches_quadrature() {
    let (_dir, scene) = load(
        r#"
    def DiskLight "Disk" {
        float inputs:intensity = 3
        color3f inputs:color = (1, 0.5, 2)
        bool inputs:normalize = 1
        float inputs:radius = 0.5
        double3 xformOp:translate = (0, 1.5, -4)
        float3 xformOp:rotateXYZ = (-90, 0, 0)
        float3 xformOp:scale = (1.6, 1, 1)
        uniform token[] xformOpOrder = ["xformOp:translate", "xformOp:rotateXYZ", "xformOp:scale"]
    }"#,
    );
    assert!(scene.warnings.is_empty(), "{:?}", scene.warnings);
    let lights = Lights::from_scene(&scene).unwrap();
    assert_eq!(lights.disks.len(), 1);
    let area = PI * 0.8 * 0.5;
    let radiance = [3.0, 1.5, 6.0].map(|s| s / area);
    assert_rgb("disk radiance", lights.disks[0].radiance, radiance);

    let setup = slab(1);
    let (c, a, b) = (
        DVec3::new(0.0, 1.5, -4.0),
        DVec3::new(0.8, 0.0, 0.0),
        DVec3::new(0.0, 0.0, -0.5),
    );
    let expected = setup.expected(|x| {
        let e = simpson(0.0, 1.0, 40, |r| {
            simpson(0.0, 2.0 * PI, 64, |phi| {
                let q = c + a * (r * phi.cos()) + b * (r * phi.sin());
                area_term(x, q, DVec3::NEG_Y) * r
            })
        }) * a.cross(b).length();
        radiance.map(|l| l * e)
    });
    for s in setup.samples_each(&lights, 2_000_000, 21) {
        assert_z(&s, expected);
    }
}

/// A CylinderLight (length 1.2 along X, radius 0.3) above the ray, unnormalized:
/// radiance s from its side, S(x) = ∫ L cos θ_l e^{−σt d}/d² dA over the side
/// (dA = r du dφ; the caps do not emit). N = 2,000,000, seed 22; |z| < 4.
#[test]
fn cylinder_light_single_scattering_matches_quadrature() {
    let (_dir, scene) = load(
        r#"
    def CylinderLight "Tube" {
        float inputs:intensity = 2
        color3f inputs:color = (1, 2, 0.5)
        float inputs:length = 1.2
        float inputs:radius = 0.3
        double3 xformOp:translate = (0, 1.5, -4)
        uniform token[] xformOpOrder = ["xformOp:translate"]
    }"#,
    );
    let lights = Lights::from_scene(&scene).unwrap();
    assert_eq!(lights.cylinders.len(), 1);
    let radiance = [2.0, 4.0, 1.0];
    let e = &lights.cylinders[0];
    assert!(!e.line);
    assert_rgb("cylinder radiance", e.radiance, radiance);
    assert!(close(e.area, 2.0 * PI * 0.3 * 1.2), "side area {}", e.area);

    let setup = slab(1);
    let c = DVec3::new(0.0, 1.5, -4.0);
    let expected = setup.expected(|x| {
        let e = simpson(-0.6, 0.6, 40, |u| {
            simpson(0.0, 2.0 * PI, 96, |phi| {
                let n = DVec3::new(0.0, phi.cos(), phi.sin());
                area_term(x, c + DVec3::X * u + n * 0.3, n) * 0.3
            })
        });
        radiance.map(|l| l * e)
    });
    for s in setup.samples_each(&lights, 2_000_000, 22) {
        assert_z(&s, expected);
    }
}

/// `treatAsLine` on a normalized cylinder: a line whose radiant intensity at angle θ
/// to its axis is s·sin θ/π (the normalized cylinder's far field, L·2rℓ sin θ with
/// L = s/(2πrℓ)), spread evenly along it: S(x) = ∫ (s sin θ/(πℓ)) e^{−σt d}/d² du.
/// N = 2,000,000, seed 23; |z| < 4.
#[test]
fn line_light_single_scattering_matches_quadrature() {
    let (_dir, scene) = load(
        r#"
    def CylinderLight "Line" {
        float inputs:intensity = 5
        bool inputs:normalize = 1
        bool treatAsLine = 1
        float inputs:length = 2
        float inputs:radius = 0.25
        double3 xformOp:translate = (0.5, 1.5, -3)
        float3 xformOp:rotateXYZ = (0, 30, 0)
        uniform token[] xformOpOrder = ["xformOp:translate", "xformOp:rotateXYZ"]
    }"#,
    );
    let lights = Lights::from_scene(&scene).unwrap();
    let e = &lights.cylinders[0];
    assert!(e.line);
    assert_rgb("line intensity", e.line_intensity, [5.0 / PI; 3]);

    let setup = slab(1);
    let c = DVec3::new(0.5, 1.5, -3.0);
    let axis = DMat4::from_rotation_y(30f64.to_radians()).transform_vector3(DVec3::X);
    let expected = setup.expected(|x| {
        let e = simpson(-1.0, 1.0, 200, |u| {
            let v = x - (c + axis * u);
            let d = v.length();
            let sin = (v / d).cross(axis).length();
            5.0 / PI * sin / 2.0 * (-SIGMA_T * d).exp() / (d * d)
        });
        [e; 3]
    });
    for s in setup.samples_each(&lights, 2_000_000, 23) {
        assert_z(&s, expected);
    }
}

/// A sphere of radius 0 emits, whatever `normalize` says: it has no size to
/// normalize by, so it is the point every normalized sphere is in the far field
/// (intensity s/4). `treatAsPoint` on a sized sphere keeps its far field: s·πr²
/// unnormalized, s/4 normalized. A zero-radius cylinder is a line of intensity s/π.
#[test]
fn zero_size_lights_emit_with_the_normalized_far_field() {
    let (_dir, scene) = load(
        r#"
    def SphereLight "Zero" {
        float inputs:intensity = 8
        float inputs:radius = 0
    }
    def SphereLight "ZeroPoint" {
        float inputs:intensity = 8
        float inputs:radius = 0
        bool treatAsPoint = 1
    }
    def SphereLight "Point" {
        float inputs:intensity = 8
        float inputs:radius = 0.5
        bool treatAsPoint = 1
    }
    def SphereLight "PointNormalized" {
        float inputs:intensity = 8
        float inputs:radius = 0.5
        bool treatAsPoint = 1
        bool inputs:normalize = 1
    }
    def CylinderLight "ZeroLine" {
        float inputs:intensity = 8
        float inputs:radius = 0
    }"#,
    );
    let lights = Lights::from_scene(&scene).unwrap();
    let intensities: Vec<f64> = lights.spheres.iter().map(|s| s.radiance[0]).collect();
    assert_eq!(
        lights.spheres.iter().map(|s| s.radius).collect::<Vec<_>>(),
        [0.0; 4]
    );
    for (got, want) in intensities.iter().zip([2.0, 2.0, 8.0 * PI * 0.25, 2.0]) {
        assert!(close(*got, want), "point intensities {intensities:?}");
    }
    let line = &lights.cylinders[0];
    assert!(line.line);
    assert_rgb("zero-radius cylinder", line.line_intensity, [8.0 / PI; 3]);
}

// ----- shaping -----------------------------------------------------------------------

fn shaping(angle: f64, softness: f64, focus: f64, tint: [f64; 3]) -> Shaping {
    let s = nimbus::scene::Shaping {
        cone_angle: angle,
        cone_softness: softness,
        focus,
        focus_tint: tint,
        ..Default::default()
    };
    // The light's −Z is world −Y.
    let to_world = DMat4::from_rotation_x(-PI / 2.0);
    Shaping::new(&s, &to_world).expect("shaping changes something")
}

/// The UsdLux falloff, written out from the docs: θsmoothStart = lerp(softness,
/// θcutoff, 0), factor = 1 − smoothstep(θ, θsmoothStart, θcutoff), times
/// lerp(|cos θ|^focus, focusTint, 1).
fn docs_factor(theta: f64, angle: f64, softness: f64, focus: f64, tint: f64) -> f64 {
    let cutoff = angle.to_radians();
    let start = cutoff + softness * (0.0 - cutoff);
    let cone = if theta > cutoff {
        0.0
    } else if theta <= start {
        1.0
    } else {
        let x = (theta - start) / (cutoff - start);
        1.0 - x * x * (3.0 - 2.0 * x)
    };
    let f = theta.cos().abs().powf(focus);
    cone * (tint + f * (1.0 - tint))
}

fn direction_at(theta: f64, phi: f64) -> DVec3 {
    // θ off the light's axis (world −Y).
    DVec3::new(
        theta.sin() * phi.cos(),
        -theta.cos(),
        theta.sin() * phi.sin(),
    )
}

/// Softness 0: exactly 1 inside the cone and exactly 0 outside it; softness 0.4 and a
/// focus of 3 with a tint: the docs' formula at 2,000 angles (to 1e-12).
#[test]
fn shaping_cone_softness_and_focus_follow_the_usdlux_formulas() {
    let hard = shaping(30.0, 0.0, 0.0, [0.0; 3]);
    for i in 0..=2000 {
        let theta = PI * i as f64 / 2000.0;
        let f = hard.factor(direction_at(theta, 0.7 * i as f64));
        let inside = theta < 30f64.to_radians() - 1e-9;
        let outside = theta > 30f64.to_radians() + 1e-9;
        if inside {
            assert_eq!(f, [1.0; 3], "θ = {theta}");
        }
        if outside {
            assert_eq!(f, [0.0; 3], "θ = {theta}");
        }
    }
    let tint = [0.2, 0.5, 1.0];
    let soft = shaping(50.0, 0.4, 3.0, tint);
    for i in 0..=2000 {
        let theta = PI * i as f64 / 2000.0;
        let f = soft.factor(direction_at(theta, 1.3 * i as f64));
        for c in 0..3 {
            let want = docs_factor(theta, 50.0, 0.4, 3.0, tint[c]);
            assert!(
                (f[c] - want).abs() < 1e-12,
                "θ = {theta}: {f:?}, docs {want}"
            );
        }
    }
}

/// A spot (a point light with a 25° cone, softness 0) above the slab aimed straight
/// up: every sample of the ray below is exactly 0. Aimed down, it equals the
/// point light's quadrature wherever the ray is inside its cone… and the whole ray
/// segment is (cone 80°): N = 1,000,000, seed 24; |z| < 4.
#[test]
fn spot_light_is_exactly_dark_outside_its_cone() {
    let setup = slab(1);
    let c = DVec3::new(0.0, 1.0, -3.0);
    let spot = |to_world: DMat4, angle: f64| {
        let s = nimbus::scene::Shaping {
            cone_angle: angle,
            ..Default::default()
        };
        Lights {
            spheres: vec![SphereEmitter {
                center: c,
                radius: 0.0,
                radiance: [2.0, 1.0, 0.5],
                shaping: Shaping::new(&s, &to_world),
                ..Default::default()
            }],
            ..Default::default()
        }
    };
    // Local −Z to world +Y: rotate by +90° about X.
    let up = spot(DMat4::from_rotation_x(PI / 2.0), 25.0);
    let s = setup.samples(&up, 20_000, 24);
    assert!(
        s.iter().all(|v| *v == [0.0; 3]),
        "a spot aimed away lit the ray"
    );

    let down = spot(DMat4::from_rotation_x(-PI / 2.0), 80.0);
    let x_in_cone = |x: DVec3| (x - c).normalize().dot(DVec3::NEG_Y) > 80f64.to_radians().cos();
    let expected = setup.expected(|x| {
        assert!(x_in_cone(x), "the test ray leaves the cone at {x}");
        let d = (c - x).length();
        [2.0, 1.0, 0.5].map(|i| i * (-SIGMA_T * d).exp() / (d * d))
    });
    for s in setup.samples_each(&down, 1_000_000, 25) {
        assert_z(&s, expected);
    }
}

/// A narrow spot (a point light, 25° cone, softness 0) 1 above the ray, aimed down,
/// lights only the stretch t ∈ [3 − tan 25°, 3 + tan 25°] of it (0.93 of the 6.9
/// the ray runs in the slab). Equiangular samples are drawn on that stretch alone
/// (the cone's clip, issue 44), collisions everywhere: both estimators equal the
/// point light's quadrature over the stretch, N = 1,000,000, seed 26, |z| < 4, and
/// the MIS estimator's standard error is the smaller (it puts every equiangular
/// sample where the light is).
#[test]
fn a_narrow_spot_is_sampled_on_its_cone_stretch() {
    let setup = slab(1);
    let c = DVec3::new(0.0, 1.0, -3.0);
    let shaping = nimbus::scene::Shaping {
        cone_angle: 25.0,
        ..Default::default()
    };
    let lights = Lights {
        spheres: vec![SphereEmitter {
            center: c,
            radius: 0.0,
            radiance: [2.0, 1.0, 0.5],
            // Local −Z to world −Y: rotate by −90° about X.
            shaping: Shaping::new(&shaping, &DMat4::from_rotation_x(-PI / 2.0)),
            ..Default::default()
        }],
        ..Default::default()
    };
    let half = 25f64.to_radians().tan();
    let expected = [2.0, 1.0, 0.5].map(|intensity| {
        simpson(3.0 - half, 3.0 + half, 400, |t| {
            let d = (c - DVec3::new(0.0, 0.0, -t)).length();
            SIGMA_S * (-SIGMA_T * (t - setup.t0)).exp() * intensity * (-SIGMA_T * d).exp()
                / (d * d)
                / (4.0 * PI)
        })
    });
    let [collisions, mis] = setup.samples_each(&lights, 1_000_000, 26);
    assert_z(&collisions, expected);
    assert_z(&mis, expected);
    let se = |s: &[[f64; 3]]| {
        let n = s.len() as f64;
        let m = s.iter().map(|v| v[0]).sum::<f64>() / n;
        (s.iter().map(|v| (v[0] - m).powi(2)).sum::<f64>() / (n - 1.0) / n).sqrt()
    };
    let (a, b) = (se(&collisions), se(&mis));
    eprintln!("standard error (R): collisions {a:.3e}, equiangular-mis {b:.3e}");
    assert!(b < a, "MIS did not lower the variance: {b} against {a}");
}

/// ShapingAPI on a distant light: its cone and softness apply to the directions of its
/// disk (here a 40° sun aimed down with a 10° cone, softness 0: only the directions
/// within 10° of its axis light the ray). S = (1/4π) ∫ L e^{−σt·10/cos θ} dω over
/// θ ≤ 10°. N = 1,000,000, seed 26; |z| < 4.
#[test]
fn shaped_sun_lights_only_within_its_cone() {
    let setup = slab(1);
    let theta_max = 20f64.to_radians();
    let radiance = 3.0;
    let solid_angle = 2.0 * PI * (1.0 - theta_max.cos());
    // Towards the light: +Y; the light's −Z is −Y.
    let s = nimbus::scene::Shaping {
        cone_angle: 10.0,
        ..Default::default()
    };
    let lights = Lights {
        suns: vec![Sun {
            direction: DVec3::Y,
            irradiance: [radiance * solid_angle; 3],
            cos_half_angle: theta_max.cos(),
            shaping: Shaping::new(&s, &DMat4::from_rotation_x(-PI / 2.0)),
            ..Default::default()
        }],
        ..Default::default()
    };
    let cone = 10f64.to_radians();
    let integral = simpson(0.0, cone, 400, |t| {
        (-SIGMA_T * 10.0 / t.cos()).exp() * t.sin()
    });
    let expected = setup.expected(|_| [radiance * 2.0 * PI * integral; 3]);
    for s in setup.samples_each(&lights, 1_000_000, 26) {
        assert_z(&s, expected);
    }
}

// ----- linking -----------------------------------------------------------------------

/// UsdCollectionAPI membership: includeRoot, includes and excludes of prims and their
/// descendants (the nearest target decides), and `explicitOnly`.
#[test]
fn collection_membership_follows_usd_collection_api() {
    let everything = Collection::default();
    assert!(everything.contains("/World/A") && everything.is_everything());
    let c = Collection {
        include_root: false,
        includes: vec!["/World/Group".into()],
        excludes: vec!["/World/Group/B".into()],
        explicit_only: false,
    };
    assert!(c.contains("/World/Group/A"));
    assert!(c.contains("/World/Group"));
    assert!(!c.contains("/World/Group/B"));
    assert!(!c.contains("/World/Group/B/Child"));
    assert!(!c.contains("/World/GroupX"));
    assert!(!c.contains("/World/Other"));
    let excluding = Collection {
        excludes: vec!["/World/B".into()],
        ..Collection::default()
    };
    assert!(excluding.contains("/World/A") && !excluding.contains("/World/B"));
    let explicit = Collection {
        include_root: false,
        includes: vec!["/World/Group".into()],
        explicit_only: true,
        ..Collection::default()
    };
    assert!(explicit.contains("/World/Group") && !explicit.contains("/World/Group/A"));
}

/// Two overlapping equal media (ids 0 and 1), the same sphere light: linked to medium
/// 0 only, the light lights only medium 0's scattering (half of σs), while both
/// attenuate; linked to none, every sample is exactly 0; with the light's shadow link
/// holding medium 0 only, its shadow rays see half the optical depth.
/// N = 2,000,000, seeds 31–33; |z| < 4.
#[test]
fn light_and_shadow_linking_exclude_exactly_the_named_volume() {
    let setup = slab(2);
    let c = DVec3::new(0.8, -0.6, -4.0);
    let r = 0.6;
    let radiance = [1.5, 1.0, 3.0];
    let lights_linked = |link: Link| Lights {
        spheres: vec![SphereEmitter {
            center: c,
            radius: r,
            radiance,
            link,
            ..Default::default()
        }],
        ..Default::default()
    };
    // In-scattered radiance from the sphere through optical depth σ per unit length
    // (the ray stays outside it).
    let sphere = |sigma: f64| move |x: DVec3| sphere_fluence(c, r, radiance, sigma, false, x, 200);

    let only_0 = Link {
        lit: 0b01,
        ..Link::ALL
    };
    let expected = setup.expected_lit(SIGMA_S / 2.0, sphere(SIGMA_T));
    for s in setup.samples_each(&lights_linked(only_0), 2_000_000, 31) {
        assert_z(&s, expected);
    }

    let none = Link {
        lit: 0,
        ..Link::ALL
    };
    for s in setup.samples_each(&lights_linked(none), 20_000, 32) {
        assert!(s.iter().all(|v| *v == [0.0; 3]), "an unlinked light lit");
    }

    let shadowed_by_0 = Link {
        shadowing: 0b01,
        ..Link::ALL
    };
    let expected = setup.expected(sphere(SIGMA_T / 2.0));
    for s in setup.samples_each(&lights_linked(shadowed_by_0), 2_000_000, 33) {
        assert_z(&s, expected);
    }
}

/// A sphere light (r 0.8) the ray passes through, 0.3 off its centre: with
/// `nimbus:lightsInterior` the points inside it see its radiance L from every
/// direction (2π L ∫₀^π e^{−σt s(θ)} sin θ dθ, s the far root), as Cycles' sphere
/// lights do; without it they see nothing and only the ray's stretches outside are
/// lit (the cone it subtends). Quadrature split at the sphere's crossings; both
/// estimators (collisions, equiangular MIS; and equiangular MIS on the chord through
/// a ball around it only, with the roulette on next events past it), N = 1,000,000,
/// seeds 45–47; |z| < 4.
/// The interior is 0.79 of the lit image here: the samples with it are checked to be
/// far (|z| > 20) from the quadrature without it.
#[test]
fn a_sphere_light_lights_its_interior_when_asked() {
    let setup = slab(1);
    let c = DVec3::new(0.3, 0.0, -4.0);
    let r: f64 = 0.8;
    let radiance = [1.5, 1.0, 3.0];
    let fluence =
        |interior: bool| move |x: DVec3| sphere_fluence(c, r, radiance, SIGMA_T, interior, x, 400);
    // The ray (0, 0, −t) is inside for |t − 4| < h.
    let h = (r * r - c.x * c.x).sqrt();
    let expected = |interior: bool| {
        let f = fluence(interior);
        [0, 1, 2].map(|ch| {
            let g = |t: f64| {
                SIGMA_S * (-SIGMA_T * (t - setup.t0)).exp() * f(DVec3::new(0.0, 0.0, -t))[ch]
                    / (4.0 * PI)
            };
            let (a, b) = (4.0 - h, 4.0 + h);
            simpson(setup.t0, a, 400, g) + simpson(a, b, 400, g) + simpson(b, setup.t1, 400, g)
        })
    };
    let lights = |interior: bool| Lights {
        spheres: vec![SphereEmitter {
            center: c,
            radius: r,
            radiance,
            interior,
            ..Default::default()
        }],
        ..Default::default()
    };
    let (with, without) = (expected(true), expected(false));
    eprintln!(
        "interior's share of the lit image: {:.3}",
        1.0 - without[0] / with[0]
    );
    for s in setup.samples_each(&lights(true), 1_000_000, 45) {
        assert_z(&s, with);
        let z = z_scores(&s, without);
        assert!(
            z.iter().all(|z| z.abs() > 20.0),
            "z against no interior: {z:?}"
        );
    }
    for s in setup.samples_each(&lights(false), 1_000_000, 46) {
        assert_z(&s, without);
    }
    // Equiangular points on the chord through a ball 1.5× the light's alone (what
    // `auto` does in a grid), the collisions keeping the rest of the ray, their next
    // events past the ball under the far roulette (survival (1.2 / d)²): the same
    // integral.
    let mut chord = lights(true).locals();
    chord[0].chord = Some(1.5 * r);
    let s = setup.samples_located(&lights(true), Extras::default(), 1_000_000, 47, chord);
    assert_z(&s, with);
}

/// Shadow linking over holdouts, from the stage: a light whose `collection:shadowLink`
/// excludes /World/OccA is shadowed by /World/OccB alone (a BVH of its own), every
/// other light by both; `inputs:shadow:enable = 0` by none. A light's
/// `collection:lightLink` with includeRoot off and the cloud included lights the cloud
/// and not /World/Cloud2.
#[test]
fn linking_collections_are_read_from_the_stage() {
    let (_dir, scene) = load(
        r#"
    def Volume "Cloud2" (
        prepend apiSchemas = ["NimbusVolumeAPI"]
    )
    {
        rel field:density = </World/Cloud/density>
        double3 xformOp:translate = (0, 0, -3)
        uniform token[] xformOpOrder = ["xformOp:translate"]
    }
    def Cube "OccA" {
        double size = 1
        double3 xformOp:translate = (0, 5, 0)
        uniform token[] xformOpOrder = ["xformOp:translate"]
    }
    def Cube "OccB" {
        double size = 1
        double3 xformOp:translate = (0, -5, 0)
        uniform token[] xformOpOrder = ["xformOp:translate"]
    }
    def SphereLight "Linked" (
        prepend apiSchemas = ["ShadowAPI"]
    ) {
        uniform bool collection:lightLink:includeRoot = 0
        rel collection:lightLink:includes = </World/Cloud>
        rel collection:shadowLink:excludes = </World/OccA>
    }
    def SphereLight "Plain" {}
    def SphereLight "Unshadowed" (
        prepend apiSchemas = ["ShadowAPI"]
    ) {
        bool inputs:shadow:enable = 0
    }"#,
    );
    assert!(scene.warnings.is_empty(), "{:?}", scene.warnings);
    let volumes: Vec<&str> = scene.volumes.iter().map(|v| v.prim_path.as_str()).collect();
    assert_eq!(volumes, ["/World/Cloud", "/World/Cloud2"]);
    let lights = Lights::from_scene(&scene).unwrap();
    let [linked, plain, unshadowed] = [0, 1, 2].map(|i| lights.spheres[i].link);
    assert_eq!(linked.lit, 0b01, "light link");
    assert_eq!(linked.shadowing, u64::MAX, "both volumes shadow");
    assert_eq!(linked.holdouts, HoldoutSet::Subset(0));
    assert_eq!(plain, Link::ALL);
    assert_eq!(unshadowed.shadowing, 0);
    assert_eq!(unshadowed.holdouts, HoldoutSet::None);
    assert!(lights.has_linking());

    let subset: &Holdouts = &lights.holdout_sets[0];
    assert_eq!(subset.stats().meshes, 1);
    let all = Holdouts::build(&scene.holdouts);
    let through = |y: f64| (DVec3::new(0.0, y, 3.0), DVec3::NEG_Z);
    for (y, blocked_by_subset) in [(5.0, false), (-5.0, true)] {
        let (o, d) = through(y);
        assert!(all.occluded(o, d, 0.0, 10.0), "y = {y}: every holdout");
        assert_eq!(
            subset.occluded(o, d, 0.0, 10.0),
            blocked_by_subset,
            "y = {y}"
        );
    }
}

/// The integrator honours a holdout shadow link: a sun straight up over the slab with
/// a holdout plane above the ray is blocked when the plane shadows it (every sample
/// exactly 0) and, with `HoldoutSet::None`, renders bit for bit as without the plane.
#[test]
fn holdout_shadow_linking_excludes_exactly_the_named_occluder() {
    let setup = slab(1);
    let plane = nimbus::scene::HoldoutMesh {
        prim_path: "/World/Roof".into(),
        prim_type: "Mesh".into(),
        points: vec![
            [-8.0, 4.0, 2.0],
            [8.0, 4.0, 2.0],
            [8.0, 4.0, -9.0],
            [-8.0, 4.0, -9.0],
        ],
        triangles: vec![[0, 1, 2], [0, 2, 3]],
        faces: 1,
        degenerate_triangles: 0,
        double_sided: true,
    };
    let holdouts = Holdouts::build(std::slice::from_ref(&plane));
    let sun = |link: Link| Lights {
        suns: vec![Sun {
            direction: DVec3::Y,
            irradiance: [1.0, 2.0, 3.0],
            cos_half_angle: 1.0,
            link,
            ..Default::default()
        }],
        ..Default::default()
    };
    let extras = Extras {
        holdouts: Some(&holdouts),
        ..Extras::default()
    };
    let blocked = setup.samples_with(&sun(Link::ALL), extras, 20_000, 41);
    assert!(
        blocked.iter().all(|v| *v == [0.0; 3]),
        "the roof let light through"
    );
    let unlinked = Link {
        holdouts: HoldoutSet::None,
        ..Link::ALL
    };
    let through = setup.samples_with(&sun(unlinked), extras, 20_000, 41);
    let open = setup.samples(&sun(Link::ALL), 20_000, 41);
    assert!(through.iter().any(|v| *v != [0.0; 3]));
    assert_eq!(
        through, open,
        "a roof outside the shadow link changed the render"
    );
}

/// A dome with linking leaves the environment scattered rays find and is reached by
/// next-event estimation alone: linked to every volume, a constant one renders bit for
/// bit as the same constant dome without linking (at maximum depth 1 both are sampled
/// uniformly at the vertex, with the same numbers, and camera rays see both).
#[test]
fn linked_dome_renders_as_the_unlinked_dome() {
    use nimbus::render::lights::LinkedDome;
    let setup = slab(1);
    let env = [0.3, 0.5, 0.8];
    let plain = Lights {
        environment: env,
        ..Default::default()
    };
    let linked = Lights {
        linked_domes: vec![LinkedDome {
            constant: env,
            map: None,
            link: Link {
                holdouts: HoldoutSet::None,
                ..Link::ALL
            },
        }],
        ..Default::default()
    };
    let a = setup.samples(&plain, 50_000, 51);
    let b = setup.samples(&linked, 50_000, 51);
    assert!(a.iter().any(|v| *v != [0.0; 3]));
    assert_eq!(a, b);
}

// ----- checks and warnings -----------------------------------------------------------

/// Non-finite intensity, exposure, colour or shaping values are errors naming the
/// prim and the attribute.
#[test]
fn non_finite_light_values_are_errors_naming_prim_and_attribute() {
    for (attr, text) in [
        ("inputs:intensity", "float inputs:intensity = nan"),
        ("inputs:intensity", "float inputs:intensity = inf"),
        ("inputs:exposure", "float inputs:exposure = -inf"),
        ("inputs:color", "color3f inputs:color = (1, nan, 1)"),
        (
            "inputs:shaping:cone:angle",
            "float inputs:shaping:cone:angle = nan",
        ),
        ("inputs:radius", "float inputs:radius = inf"),
    ] {
        for ty in ["SphereLight", "DiskLight", "CylinderLight"] {
            let e = load_error(&format!("    def {ty} \"Bad\" {{ {text} }}"));
            assert!(
                e.contains("/World/Bad") && e.contains(attr),
                "{ty} {text}: {e}"
            );
        }
    }
}

/// Every light-value warning and every light feature that is not rendered: one
/// warning naming the prim and attribute; `--strict` refuses the stage naming them.
#[test]
fn light_warnings_name_prim_and_attribute_and_fail_strict() {
    let dir = tempfile::tempdir().unwrap();
    let ies = dir.path().join("spot.ies");
    std::fs::write(&ies, "IESNA:LM-63-2002\n").unwrap();
    let stage = cloud_with(
        dir.path(),
        &format!(
            r#"
    def SphereLight "Negative" {{
        float inputs:intensity = -2
    }}
    def SphereLight "Bright" {{
        float inputs:exposure = 1000
    }}
    def SphereLight "Ies" (
        prepend apiSchemas = ["ShapingAPI"]
    ) {{
        asset inputs:shaping:ies:file = @{}@
    }}
    def DiskLight "Filtered" {{
        rel light:filters = </World/Filter>
    }}
    def LightFilter "Filter" {{}}
    def RectLight "Shadowy" (
        prepend apiSchemas = ["ShadowAPI"]
    ) {{
        color3f inputs:shadow:color = (0.2, 0, 0)
        float inputs:shadow:distance = 3
    }}
    def CylinderLight "Expression" {{
        pathExpression collection:lightLink:membershipExpression = "/World/Cloud"
    }}
    def RectLight "Textured" {{
        asset inputs:texture:file = @{}@
    }}
    def SphereLight "Tinted" {{
        color3f inputs:color = (1, -0.5, 1)
        float inputs:shaping:focus = -1
        float inputs:shaping:cone:softness = 2
    }}
    def DomeLight "Sky" (
        prepend apiSchemas = ["ShapingAPI"]
    ) {{
        float inputs:diffuse = 0.5
        float inputs:shaping:cone:angle = 30
    }}"#,
            ies.display(),
            ies.display()
        ),
    );
    let out = dir.path().join("out.exr");
    let stats = dir.path().join("stats.json");
    let o = nimbus(&[
        "render",
        stage.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--res",
        "16x12",
        "--spp",
        "1",
        "--stats",
        stats.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let s = stats_json(&stats);
    let w = s["stage_warnings"].as_array().expect("stage_warnings");
    let found: Vec<(String, String)> = w
        .iter()
        .map(|w| {
            (
                w["prim"].as_str().unwrap().to_string(),
                w["attribute"].as_str().unwrap_or("").to_string(),
            )
        })
        .collect();
    let expected = [
        ("/World/Negative", "inputs:intensity"),
        ("/World/Bright", "inputs:exposure"),
        ("/World/Ies", "inputs:shaping:ies:file"),
        ("/World/Filtered", "light:filters"),
        ("/World/Shadowy", "inputs:shadow:color"),
        ("/World/Shadowy", "inputs:shadow:distance"),
        (
            "/World/Expression",
            "collection:lightLink:membershipExpression",
        ),
        ("/World/Textured", "inputs:texture:file"),
        ("/World/Tinted", "inputs:color"),
        ("/World/Tinted", "inputs:shaping:focus"),
        ("/World/Tinted", "inputs:shaping:cone:softness"),
        ("/World/Sky", "inputs:diffuse"),
        ("/World/Sky", "inputs:shaping:cone:angle"),
    ];
    for (prim, attr) in expected {
        assert!(
            found.iter().any(|(p, a)| p == prim && a == attr),
            "no warning for {prim}.{attr} in {found:?}"
        );
    }
    let err = stderr(&o);
    assert!(
        err.contains("IES profile not supported: rendered without it"),
        "{err}"
    );
    // Disk and cylinder lights are read: no "not supported" light warning.
    assert!(!err.contains("DiskLight lights are not supported"), "{err}");
    assert!(
        !err.contains("CylinderLight lights are not supported"),
        "{err}"
    );

    let strict_out = dir.path().join("strict.exr");
    let o = nimbus(&[
        "render",
        stage.to_str().unwrap(),
        "-o",
        strict_out.to_str().unwrap(),
        "--res",
        "16x12",
        "--spp",
        "1",
        "--strict",
    ]);
    assert_clean_error(&o, "strict");
    for (prim, _) in expected {
        assert!(
            stderr(&o).contains(prim),
            "{prim} not named: {}",
            stderr(&o)
        );
    }
    assert!(!strict_out.exists(), "a refused render wrote its output");
}

/// A stage lit only by a disk and a cylinder light renders lit by them: no warning,
/// no default sun and sky, a finite non-black image.
#[test]
fn disk_and_cylinder_lights_light_a_stage_without_warnings() {
    let dir = tempfile::tempdir().unwrap();
    let stage = cloud_with(
        dir.path(),
        r#"
    def DiskLight "Disk" {
        float inputs:intensity = 40
        float inputs:radius = 1
        double3 xformOp:translate = (0, 0, 3)
        uniform token[] xformOpOrder = ["xformOp:translate"]
    }
    def CylinderLight "Tube" {
        float inputs:intensity = 20
        double3 xformOp:translate = (0, 2, 0)
        uniform token[] xformOpOrder = ["xformOp:translate"]
    }"#,
    );
    let out = dir.path().join("out.exr");
    let o = nimbus(&[
        "render",
        stage.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--res",
        "16x12",
        "--spp",
        "2",
        "--strict",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(!stderr(&o).contains("warning"), "{}", stderr(&o));
    let c = common::cli::channels(&out);
    let r = common::cli::channel(&c, "R");
    assert!(r.iter().all(|v| v.is_finite()));
    assert!(r.iter().any(|&v| v > 0.0), "the lights lit nothing");
}
