//! Fog: homogeneous media bounded by a closed gprim (fog boxes) and world fog, read
//! from USD (`NimbusVolumeAPI` on a gprim, a bound volume material, `nimbus:fill =
//! "world"`) and tracked like any other medium, their walks clipped to the inside of
//! the surface (src/volume/boundary.rs).

mod common;

use common::cli::{assert_clean_error, nimbus};
use glam::DVec3;
use nimbus::scene::{load_stage, LoadOptions, Scene, VolumeShape};
use nimbus::track::delta::Delta;
use nimbus::track::free_path::{Query, TransmittanceEstimator};
use nimbus::track::ratio::Ratio;
use nimbus::track::track_length::Tracking;
use nimbus::volume::counters::Counters;
use nimbus::volume::majorant::MajorantSpec;
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg32;
use std::path::Path;

const HEADER: &str = "#usda 1.0\n(\n    upAxis = \"Z\"\n    metersPerUnit = 1\n)\n";

/// A pure absorber (σa = 0.7 per unit) so transmittance is exp(−0.7·chord).
const SIGMA: f64 = 0.7;

fn write(dir: &Path, name: &str, body: &str) -> std::path::PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, format!("{HEADER}{body}")).unwrap();
    path
}

fn load(path: &Path) -> Scene {
    load_stage(path, &LoadOptions::default()).unwrap_or_else(|e| panic!("{e}"))
}

/// A rotated, non-uniformly scaled cube and a sphere (two fog boxes, apart).
fn shapes_stage(dir: &Path) -> std::path::PathBuf {
    let absorber = format!(
        "    float nimbus:densityScale = 1\n    color3f nimbus:absorption = ({SIGMA}, {SIGMA}, {SIGMA})\n    color3f nimbus:scattering = (0, 0, 0)\n"
    );
    write(
        dir,
        "shapes.usda",
        &format!(
            r#"def Cube "box" (
    prepend apiSchemas = ["NimbusVolumeAPI"]
)
{{
    double size = 2
{absorber}    double3 xformOp:translate = (-3, 0, 0)
    float3 xformOp:rotateXYZ = (20, 35, 50)
    float3 xformOp:scale = (1.5, 0.8, 1.1)
    uniform token[] xformOpOrder = ["xformOp:translate", "xformOp:rotateXYZ", "xformOp:scale"]
}}
def Sphere "ball" (
    prepend apiSchemas = ["NimbusVolumeAPI"]
)
{{
    double radius = 1.3
{absorber}    double3 xformOp:translate = (3, 0.5, -0.25)
    uniform token[] xformOpOrder = ["xformOp:translate"]
}}
"#
        ),
    )
}

/// The distance the ray `o + t·d`, t ≥ 0, runs inside the convex surface given by its
/// triangles, from an exact f64 ray–triangle test written here (independent of the
/// renderer's BVH): between the nearest and farthest hits, from 0 when `o` is inside.
fn convex_chord(points: &[[f64; 3]], triangles: &[[u32; 3]], o: DVec3, d: DVec3) -> f64 {
    let mut hits: Vec<f64> = Vec::new();
    for t in triangles {
        let [a, b, c] = t.map(|i| DVec3::from_array(points[i as usize]));
        let (e1, e2) = (b - a, c - a);
        let p = d.cross(e2);
        let det = e1.dot(p);
        if det.abs() < 1e-300 {
            continue;
        }
        let s = o - a;
        let u = s.dot(p) / det;
        let q = s.cross(e1);
        let v = d.dot(q) / det;
        if u < 0.0 || v < 0.0 || u + v > 1.0 {
            continue;
        }
        hits.push(e2.dot(q) / det);
    }
    let near = hits.iter().copied().fold(f64::INFINITY, f64::min);
    let far = hits.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    if hits.is_empty() || far <= 0.0 {
        return 0.0;
    }
    far - near.max(0.0)
}

/// Transmittance through a fog cube and a fog sphere equals exp(−σt·chord), the chord
/// computed exactly against the same triangles. Estimators: delta tracking's escape
/// (the track-length estimator) with the medium's own majorant, which for a
/// homogeneous medium is the density, so each estimate is 1{no collision before
/// leaving} (Bernoulli, mean T, variance T(1−T)); and ratio tracking, which on the
/// fog's clipped segments (density bounds equal) attenuates in closed form: exact to
/// f32 (relative 2e-5 allowed for the f32 interval ends) with no lookup.
/// Per shape 48 rays: 32 from a sphere of radius 5 around the shape towards random
/// points of its box (some miss: T = 1 exactly), 16 starting inside it; N = 4,000
/// estimates per ray, seeds 7 (rays) and 8 (estimates); |z| < 4 per ray with σ = sqrt(T(1−T)/N) from the exact
/// T (a miss must give exactly 1). Also checks the mean of the 96 z-scores: |z̄| < 4/√96.
#[test]
fn chord_transmittance_through_a_cube_and_a_sphere_is_exact() {
    let dir = tempfile::tempdir().unwrap();
    let scene = load(&shapes_stage(dir.path()));
    assert!(scene.holdouts.is_empty(), "fog gprims are not holdouts");
    assert!(scene.warnings.is_empty(), "{:?}", scene.warnings.lines());
    let media =
        nimbus::render::job::media_for_scene_with(&scene, MajorantSpec::Uniform { cell_voxels: 0 })
            .unwrap();
    assert_eq!(media.len(), 2);
    // Ray geometry from one stream, estimates from another: which rays are drawn does
    // not depend on how many numbers an estimator takes.
    let mut rng = Pcg32::seed_from_u64(7);
    let mut est = Pcg32::seed_from_u64(8);
    let n = 4_000;
    let mut zs = Vec::new();
    for (volume, medium) in scene.volumes.iter().zip(&media) {
        let VolumeShape::Mesh(fog) = &volume.shape else {
            panic!("{} is not a fog box", volume.prim_path)
        };
        assert!(fog.closed, "{}", volume.prim_path);
        let (pts, tris) = (&fog.mesh.points, &fog.mesh.triangles);
        let (lo, hi) = pts.iter().fold(
            (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
            |(lo, hi), p| (lo.min(DVec3::from_array(*p)), hi.max(DVec3::from_array(*p))),
        );
        let centre = (lo + hi) / 2.0;
        let (mut hit, mut inside) = (0, 0);
        for k in 0..48 {
            let target = lo + (hi - lo) * DVec3::new(rng.gen(), rng.gen(), rng.gen());
            let o = if k < 32 {
                let u = DVec3::new(rng.gen(), rng.gen(), rng.gen()) * 2.0 - 1.0;
                centre + u.normalize() * 5.0
            } else {
                centre + (DVec3::new(rng.gen(), rng.gen(), rng.gen()) - 0.5) * 0.4
            };
            let d = (target - o).normalize();
            let chord = convex_chord(pts, tris, o, d);
            let expected = (-SIGMA * chord).exp();
            let ray = medium.index_ray(o, d);
            let q = Query {
                medium,
                sigma: &medium.sigma,
                ray: &ray,
                tmin: 0.0,
                tmax: f32::INFINITY,
                majorant_scale: 1.0,
            };
            let mut c = Counters::default();
            let exact = Ratio.transmittance(&q, &mut est, &mut c)[0] as f64;
            assert!(
                (exact - expected).abs() <= 2e-5 * expected.max(1e-3),
                "{} ray {k}: ratio tracking {exact} against exp(−σ·chord) {expected}",
                volume.prim_path
            );
            assert_eq!(c.density_lookups, 0, "ratio tracking looked the fog up");
            let sum: f64 = (0..n)
                .map(|_| Tracking(Delta).transmittance(&q, &mut est, &mut c)[0] as f64)
                .sum();
            let mean = sum / n as f64;
            if chord == 0.0 {
                assert_eq!(mean, 1.0, "{} ray {k}: a miss", volume.prim_path);
                assert_eq!(
                    c.density_lookups, 0,
                    "{} ray {k}: a miss looks nothing up",
                    volume.prim_path
                );
                continue;
            }
            hit += 1;
            inside += (k >= 32) as usize;
            let se = (expected * (1.0 - expected) / n as f64).sqrt();
            let z = (mean - expected) / se;
            assert!(
                z.abs() < 4.0,
                "{} ray {k}: chord {chord:.5}, T̂ {mean:.5} against exp(−σ·chord) {expected:.5}, z {z:.2}",
                volume.prim_path
            );
            zs.push(z);
        }
        // A guard that the rays exercise the shape (they aim at random points of its
        // bounding box, which a rotated, squashed cube fills a fraction of): at least
        // 12 of the 32 from outside meet it, and all 16 from inside.
        assert!(
            hit >= 12 + 16 && inside == 16,
            "{}: {hit} rays met it, {inside} from inside",
            volume.prim_path
        );
    }
    let zbar = zs.iter().sum::<f64>() / zs.len() as f64;
    assert!(zbar.abs() < 4.0 / (zs.len() as f64).sqrt(), "mean z {zbar}");
}

/// A gprim bound to a material whose volume output Nimbus reads is a fog box; world fog
/// is a Volume with `nimbus:fill = "world"` and no fields, and has no end; `nimbus
/// info` says which.
#[test]
fn material_fog_boxes_and_world_fog_are_read() {
    let dir = tempfile::tempdir().unwrap();
    let path = write(
        dir.path(),
        "material.usda",
        r#"def Material "haze"
{
    token outputs:mtlx:volume.connect = </haze/vdf.outputs:out>
    def Shader "vdf"
    {
        uniform token info:id = "ND_anisotropic_vdf"
        color3f inputs:absorption = (0.1, 0.2, 0.3)
        color3f inputs:scattering = (0.4, 0.5, 0.6)
        float inputs:anisotropy = 0.3
        token outputs:out
    }
}
def Sphere "ball" (
    prepend apiSchemas = ["MaterialBindingAPI"]
)
{
    rel material:binding = </haze>
}
def Cube "wall"
{
}
def Volume "world" (
    prepend apiSchemas = ["NimbusVolumeAPI"]
)
{
    uniform token nimbus:fill = "world"
    float nimbus:densityScale = 0.02
}
"#,
    );
    let scene = load(&path);
    assert_eq!(scene.holdouts.len(), 1, "the unbound cube stays a holdout");
    assert_eq!(scene.holdouts[0].prim_path, "/wall");
    let ball = scene
        .volumes
        .iter()
        .find(|v| v.prim_path == "/ball")
        .unwrap();
    assert!(matches!(&ball.shape, VolumeShape::Mesh(m) if m.closed));
    let f32s = |v: [f64; 3]| v.map(|x| x as f32);
    assert_eq!(
        (
            f32s(ball.absorption),
            f32s(ball.scattering),
            ball.anisotropy as f32
        ),
        ([0.1, 0.2, 0.3], [0.4, 0.5, 0.6], 0.3)
    );
    assert_eq!(
        ball.material_shader.as_deref(),
        Some("/haze/vdf (ND_anisotropic_vdf)")
    );
    let world = scene
        .volumes
        .iter()
        .find(|v| v.prim_path == "/world")
        .unwrap();
    assert_eq!(world.shape, VolumeShape::World);
    assert_eq!(world.density_scale as f32, 0.02);
    let media =
        nimbus::render::job::media_for_scene_with(&scene, MajorantSpec::Uniform { cell_voxels: 0 })
            .unwrap();
    assert_eq!(media.len(), 2);
    // World fog has no end (as Cycles' world volume): a finite stretch of length L
    // transmits exp(−σt·L) (σt = 0.02 · (0.1 + 0.9); ratio tracking, Bernoulli, N =
    // 20,000, seed 3, |z| < 4), and a ray to infinity nothing at all.
    let world = &media[scene
        .volumes
        .iter()
        .position(|v| v.prim_path == "/world")
        .unwrap()];
    let mut rng = Pcg32::seed_from_u64(3);
    let o = DVec3::new(1e3, -2e3, 5.0);
    let ray = world.index_ray(o, DVec3::new(0.6, 0.8, 0.0));
    for (tmax, expected) in [(30f32, (-0.02f64 * 30.0).exp()), (f32::INFINITY, 0.0)] {
        let q = Query {
            medium: world,
            sigma: &world.sigma,
            ray: &ray,
            tmin: 0.0,
            tmax,
            majorant_scale: 1.0,
        };
        let mut c = Counters::default();
        let n = 20_000;
        let mean = (0..n)
            .map(|_| Ratio.transmittance(&q, &mut rng, &mut c)[0] as f64)
            .sum::<f64>()
            / n as f64;
        if expected == 0.0 {
            assert_eq!(mean, 0.0, "a ray to infinity in world fog");
        } else {
            let z = (mean - expected) / (expected * (1.0 - expected) / n as f64).sqrt();
            assert!(
                z.abs() < 4.0,
                "world fog over {tmax}: {mean} against {expected}, z {z:.2}"
            );
        }
    }
    let info = nimbus(&["info", path.to_str().unwrap()]);
    let out = String::from_utf8_lossy(&info.stdout);
    assert!(info.status.success(), "{}", common::cli::stderr(&info));
    assert!(
        out.contains("volume: /ball densityField fog box (") && out.contains("closed)"),
        "{out}"
    );
    assert!(
        out.contains("volume: /world densityField world fog"),
        "{out}"
    );
}

/// Surfaces that do not bound a region cleanly are read (never a NaN or a hang) with a
/// stage warning naming the prim: an open mesh (a cube missing a face) is inside by
/// parity; a mesh whose faces point inwards is read outwards; one face wound against
/// its neighbours is turned. Each renders a finite image.
#[test]
fn open_inverted_and_misoriented_surfaces_warn_and_render() {
    let dir = tempfile::tempdir().unwrap();
    // A unit cube's 6 quads, outward (counter-clockwise seen from outside).
    let quads = [
        [0, 3, 2, 1], // z = 0, facing −z
        [4, 5, 6, 7], // z = 1
        [0, 1, 5, 4], // y = 0
        [2, 3, 7, 6], // y = 1
        [1, 2, 6, 5], // x = 1
        [0, 4, 7, 3], // x = 0
    ];
    let points = "[(0,0,0),(1,0,0),(1,1,0),(0,1,0),(0,0,1),(1,0,1),(1,1,1),(0,1,1)]";
    let mesh = |name: &str, faces: &[[i32; 4]]| {
        let idx: Vec<String> = faces.iter().flatten().map(|i| i.to_string()).collect();
        format!(
            "def Mesh \"{name}\" (\n    prepend apiSchemas = [\"NimbusVolumeAPI\"]\n)\n{{\n    point3f[] points = {points}\n    int[] faceVertexCounts = [{}]\n    int[] faceVertexIndices = [{}]\n}}\n",
            vec!["4"; faces.len()].join(","),
            idx.join(",")
        )
    };
    let reversed: Vec<[i32; 4]> = quads.iter().map(|q| [q[3], q[2], q[1], q[0]]).collect();
    let mut one_flipped = quads.to_vec();
    one_flipped[2] = reversed[2];
    let cases = [
        (
            "open",
            mesh("open", &quads[..5]),
            "not a closed, orientable surface",
        ),
        (
            "inverted",
            mesh("inverted", &reversed),
            "faces point inwards",
        ),
        (
            "flipped",
            mesh("flipped", &one_flipped),
            "2 of its 12 faces point the other way",
        ),
    ];
    let camera = r#"def Camera "cam"
{
    double3 xformOp:translate = (0.5, -4, 0.5)
    float xformOp:rotateX = 90
    uniform token[] xformOpOrder = ["xformOp:translate", "xformOp:rotateX"]
}
def DistantLight "sun"
{
}
def RenderSettings "settings"
{
    int2 resolution = (16, 16)
    rel camera = </cam>
    int nimbus:samples = 4
}
"#;
    for (name, body, warning) in cases {
        let path = write(
            dir.path(),
            &format!("{name}.usda"),
            &format!("{body}{camera}"),
        );
        let scene = load(&path);
        let lines = scene.warnings.lines().join("\n");
        assert!(
            lines.contains(&format!("/{name}")) && lines.contains(warning),
            "{name}: {lines}"
        );
        let VolumeShape::Mesh(fog) = &scene.volumes[0].shape else {
            panic!("{name}: not a fog box")
        };
        assert_eq!(fog.closed, name != "open", "{name}");
        let exr = dir.path().join(format!("{name}.exr"));
        let out = nimbus(&[
            "render",
            path.to_str().unwrap(),
            "-o",
            exr.to_str().unwrap(),
        ]);
        assert!(
            out.status.success(),
            "{name}: {}",
            common::cli::stderr(&out)
        );
    }
}

/// Fog has no grids: a field named on a fog box is an error naming the prim and the
/// attribute; an unknown `nimbus:fill` token too.
#[test]
fn fields_on_fog_and_unknown_fill_tokens_are_errors() {
    let dir = tempfile::tempdir().unwrap();
    let fog_field = write(
        dir.path(),
        "field.usda",
        "def Cube \"fog\" (\n    prepend apiSchemas = [\"NimbusVolumeAPI\"]\n)\n{\n    token nimbus:temperatureField = \"temperature\"\n}\n",
    );
    assert_clean_error(
        &nimbus(&[
            "render",
            fog_field.to_str().unwrap(),
            "-o",
            dir.path().join("a.exr").to_str().unwrap(),
        ]),
        "/fog: nimbus:temperatureField = \"temperature\": fog",
    );
    let fill = write(
        dir.path(),
        "fill.usda",
        "def Volume \"fog\" (\n    prepend apiSchemas = [\"NimbusVolumeAPI\"]\n)\n{\n    uniform token nimbus:fill = \"sky\"\n}\n",
    );
    assert_clean_error(
        &nimbus(&[
            "render",
            fill.to_str().unwrap(),
            "-o",
            dir.path().join("b.exr").to_str().unwrap(),
        ]),
        "nimbus:fill = \"sky\" is not one of",
    );
}

/// A ray through more volumes than one tracker call races (64) is tracked span by
/// span: 80 unit fog cubes in a row along x (pure absorbers, σa = 0.01) seen end-on by
/// an orthographic camera whose rays all pass through every cube, lit by a constant
/// white dome: each pixel's value estimates T = exp(−0.01·80) = 0.4493. Estimator: the
/// camera ray's escape weight (delta tracking through homogeneous media: 0 or 1,
/// variance T(1−T)); 16×16 pixels × 64 spp = 16,384 samples, seed 1 (the stage's
/// default); |z| < 4 on the image mean with σ = sqrt(T(1−T)/16,384). Dropping the 16
/// cubes past the 64th would give T = 0.527 (z ≈ 20).
#[test]
fn a_ray_through_eighty_volumes_sees_all_of_them() {
    let dir = tempfile::tempdir().unwrap();
    let mut body = String::new();
    for k in 0..80 {
        body += &format!(
            "def Cube \"c{k}\" (\n    prepend apiSchemas = [\"NimbusVolumeAPI\"]\n)\n{{\n    double size = 1\n    color3f nimbus:absorption = (0.01, 0.01, 0.01)\n    color3f nimbus:scattering = (0, 0, 0)\n    double3 xformOp:translate = ({}, 0, 0)\n    uniform token[] xformOpOrder = [\"xformOp:translate\"]\n}}\n",
            1.5 * k as f64
        );
    }
    body += r#"def Camera "cam"
{
    token projection = "orthographic"
    float horizontalAperture = 5
    float verticalAperture = 5
    float2 clippingRange = (0.1, 1000)
    double3 xformOp:translate = (-5, 0, 0)
    float3 xformOp:rotateXYZ = (90, 0, -90)
    uniform token[] xformOpOrder = ["xformOp:translate", "xformOp:rotateXYZ"]
}
def DomeLight "sky"
{
}
def RenderSettings "settings"
{
    int2 resolution = (16, 16)
    rel camera = </cam>
    int nimbus:samples = 64
}
"#;
    let stage = write(dir.path(), "row.usda", &body);
    let exr = dir.path().join("row.exr");
    let out = nimbus(&[
        "render",
        stage.to_str().unwrap(),
        "-o",
        exr.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", common::cli::stderr(&out));
    assert!(
        !common::cli::stderr(&out).contains("more than 64"),
        "{}",
        common::cli::stderr(&out)
    );
    let c = common::cli::channels(&exr);
    let r = common::cli::channel(&c, "R");
    let mean = r.iter().map(|&v| v as f64).sum::<f64>() / r.len() as f64;
    let t = (-0.01f64 * 80.0).exp();
    let se = (t * (1.0 - t) / (r.len() as f64 * 64.0)).sqrt();
    let z = (mean - t) / se;
    assert!(z.abs() < 4.0, "mean {mean:.5} against {t:.5}: z {z:.2}");
}

/// The "camera sees no volume" warning probes with each medium's own walk: a camera
/// inside world fog sees it however short its clipping range (the fog's constant brick
/// covers only a box around the scene, here 40 units away), while the same camera
/// with a fog box there instead is warned.
#[test]
fn a_camera_inside_world_fog_is_not_warned_that_it_sees_no_volume() {
    let dir = tempfile::tempdir().unwrap();
    let scene = |fog: &str| {
        format!(
            r#"def Camera "cam"
{{
    float2 clippingRange = (0.1, 0.5)
    double3 xformOp:translate = (0, 0, 40)
    uniform token[] xformOpOrder = ["xformOp:translate"]
}}
def SphereLight "bulb"
{{
    float inputs:intensity = 10
    double3 xformOp:translate = (0, 0, 39)
    uniform token[] xformOpOrder = ["xformOp:translate"]
}}
def Cube "box" (
    prepend apiSchemas = ["NimbusVolumeAPI"]
)
{{
    float nimbus:densityScale = 0.1
}}
{fog}"#
        )
    };
    let world = "def Volume \"world\" (\n    prepend apiSchemas = [\"NimbusVolumeAPI\"]\n)\n{\n    uniform token nimbus:fill = \"world\"\n    float nimbus:densityScale = 0.02\n}\n";
    for (name, fog, warned) in [("world.usda", world, false), ("box.usda", "", true)] {
        let path = write(dir.path(), name, &scene(fog));
        let out = dir.path().join(format!("{name}.exr"));
        let r = common::cli::nimbus(&[
            "render",
            path.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
            "--res",
            "8x8",
            "--spp",
            "1",
            "--camera",
            "/cam",
        ]);
        let err = common::cli::stderr(&r);
        assert!(r.status.success(), "{err}");
        assert_eq!(err.contains("probe grid reaches"), warned, "{name}: {err}");
    }
}
