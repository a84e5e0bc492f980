//! Holdout geometry: reading UsdGeom gprims (`scene::geometry`, against stages authored
//! by Pixar's USD in `tests/fixtures/make_holdout_stages.py`) and the ray queries of
//! `render::holdouts` (against brute force over every triangle, and analytic shapes).

mod common;

use std::path::Path;

use glam::{DMat4, DVec3};
use nimbus::render::holdouts::Holdouts;
use nimbus::scene::geometry::{MAX_CHORD_ERROR, RINGS, SEGMENTS};
use nimbus::scene::{load_stage, HoldoutMesh, LoadOptions, Scene, SceneError};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;
use serde_json::Value;

fn generate_fixtures() -> Option<(tempfile::TempDir, Value)> {
    common::pxr_fixtures(
        "make_holdout_stages.py",
        &["pxr"],
        common::data::SETUP_PYTHON,
        true,
    )
}

fn load(path: &Path, frame: Option<f64>) -> Result<Scene, SceneError> {
    load_stage(
        path,
        &LoadOptions {
            frame,
            camera: None,
        },
    )
}

fn num(v: &Value) -> f64 {
    v.as_f64()
        .unwrap_or_else(|| panic!("expected a number, got {v}"))
}

fn vec3(v: &Value) -> DVec3 {
    let a = v.as_array().expect("3-vector");
    DVec3::new(num(&a[0]), num(&a[1]), num(&a[2]))
}

/// pxr's row-major, row-vector matrix as a glam column-vector matrix (its transpose).
fn pxr_matrix(v: &Value) -> DMat4 {
    let rows: Vec<f64> = v
        .as_array()
        .unwrap()
        .iter()
        .flat_map(|r| r.as_array().unwrap().iter().map(num).collect::<Vec<_>>())
        .collect();
    DMat4::from_cols_slice(&rows)
}

fn close(a: f64, b: f64, tol: f64) -> bool {
    (a - b).abs() <= tol * a.abs().max(b.abs()).max(1.0)
}

/// Triangles a tessellated implicit gprim has (see `scene::geometry`).
fn expected_triangles(prim_type: &str) -> usize {
    let (s, r) = (SEGMENTS, RINGS);
    match prim_type {
        // Two pole fans and RINGS − 2 bands of quads.
        "Sphere" => 2 * s + 2 * s * (r - 2),
        // Two hemispheres (RINGS/2 − 1 bands each), the cylinder band, two pole fans.
        "Capsule" => 2 * s * (r - 1) + 2 * s,
        "Cube" => 12,
        "Cylinder" => 4 * s,
        "Cone" => 2 * s,
        "Plane" => 2,
        other => panic!("no tessellation for {other}"),
    }
}

fn axis_index(axis: Option<&str>) -> usize {
    match axis.unwrap_or("Z") {
        "X" => 0,
        "Y" => 1,
        _ => 2,
    }
}

#[test]
fn holdout_prims_are_read_with_world_transforms() {
    let Some((_dir, expected)) = generate_fixtures() else {
        return;
    };
    let read = [
        "/World/QuadTri",
        "/World/Degenerate",
        "/Shapes/Sphere",
        "/Shapes/DefaultSphere",
        "/Shapes/Cube",
        "/Shapes/Cylinder",
        "/Shapes/Cone",
        "/Shapes/Capsule",
        "/Shapes/Plane",
        "/Shapes/RenderPurpose",
        "/Shapes/Applied",
        "/Rocks/Rock0/Rock",
        "/Rocks/Rock1/Rock",
    ];
    for case in expected["holdouts"].as_array().unwrap() {
        let frame = case["frame"].as_f64();
        let stage = Path::new(case["stage"].as_str().unwrap());
        let scene = load(stage, frame).unwrap_or_else(|e| panic!("load at {frame:?}: {e}"));
        let prims = case["prims"].as_array().unwrap();
        let paths: Vec<&str> = scene
            .holdouts
            .iter()
            .map(|h| h.prim_path.as_str())
            .collect();
        let pxr_paths: Vec<&str> = prims.iter().map(|p| p["path"].as_str().unwrap()).collect();
        assert_eq!(paths, pxr_paths, "prims read at {frame:?} (pxr's rules)");
        assert_eq!(paths, read, "prims read at {frame:?}");
        for (h, e) in scene.holdouts.iter().zip(prims) {
            let what = format!("{} at {frame:?}", h.prim_path);
            assert_eq!(h.prim_type, e["type"].as_str().unwrap(), "{what}");
            assert_eq!(
                h.double_sided,
                e["double_sided"].as_bool().unwrap(),
                "{what}"
            );
            if h.prim_type == "Mesh" {
                check_mesh(&what, h, e);
            } else {
                check_implicit(&what, h, e);
            }
        }
    }
}

fn check_mesh(what: &str, h: &HoldoutMesh, e: &Value) {
    let pxr_points = e["world_points"].as_array().unwrap();
    assert_eq!(h.points.len(), pxr_points.len(), "{what}: points");
    for (p, q) in h.points.iter().zip(pxr_points) {
        let q = vec3(q);
        for a in 0..3 {
            assert!(close(p[a], q[a], 1e-12), "{what}: point {p:?}, pxr {q}");
        }
    }
    match h.prim_path.as_str() {
        "/World/QuadTri" => {
            assert_eq!(h.triangles, vec![[0, 1, 2], [0, 2, 3], [1, 4, 2]], "{what}");
            assert_eq!((h.faces, h.degenerate_triangles), (2, 0), "{what}");
        }
        "/World/Degenerate" => {
            // [0,1,1] repeats an index, [0,1,2] is collinear; the pentagon is three
            // triangles; face 4 is a hole.
            assert_eq!(
                h.triangles,
                vec![[0, 1, 3], [0, 1, 4], [0, 4, 3], [0, 3, 2]],
                "{what}"
            );
            assert_eq!((h.faces, h.degenerate_triangles), (4, 2), "{what}");
        }
        other => panic!("unexpected mesh {other}"),
    }
}

fn check_implicit(what: &str, h: &HoldoutMesh, e: &Value) {
    assert_eq!(
        h.triangles.len(),
        expected_triangles(&h.prim_type),
        "{what}"
    );
    assert_eq!(h.degenerate_triangles, 0, "{what}");
    // Back to the prim's local space: the tessellation's bounds are pxr's extent (the
    // extreme points are vertices), so size, radius, height and axis are all read right.
    let world = pxr_matrix(&e["world"]);
    let to_local = world.inverse();
    let local: Vec<DVec3> = h
        .points
        .iter()
        .map(|p| to_local.transform_point3(DVec3::from_array(*p)))
        .collect();
    let lo = local.iter().fold(DVec3::INFINITY, |m, p| m.min(*p));
    let hi = local.iter().fold(DVec3::NEG_INFINITY, |m, p| m.max(*p));
    let extent = e["local_extent"].as_array().unwrap();
    let (elo, ehi) = (vec3(&extent[0]), vec3(&extent[1]));
    for a in 0..3 {
        assert!(
            close(lo[a], elo[a], 1e-9) && close(hi[a], ehi[a], 1e-9),
            "{what}: bounds {lo}..{hi}, pxr extent {elo}..{ehi}"
        );
    }
    let axis = axis_index(e["axis"].as_str());
    match h.prim_type.as_str() {
        "Sphere" => {
            let r = num(&e["radius"]);
            for p in &local {
                assert!(close(p.length(), r, 1e-9), "{what}: {p} not on the sphere");
            }
        }
        "Cone" => {
            // The apex points up the axis (+height/2): the only point up there.
            let h2 = num(&e["height"]) / 2.0;
            let top: Vec<&DVec3> = local.iter().filter(|p| p[axis] > h2 * 0.5).collect();
            assert_eq!(top.len(), 1, "{what}: apex");
            assert!(close(top[0][axis], h2, 1e-9), "{what}: apex {}", top[0]);
        }
        "Plane" => {
            // Flat across its axis; X: width along z, length along y.
            assert!(local.iter().all(|p| p[axis].abs() < 1e-9), "{what}");
            assert_eq!(axis, 0, "{what}");
            assert!(close(hi.z - lo.z, num(&e["width"]), 1e-9), "{what}: width");
            assert!(
                close(hi.y - lo.y, num(&e["length"]), 1e-9),
                "{what}: length"
            );
        }
        _ => {}
    }
}

#[test]
fn bad_holdout_prims_are_errors_naming_the_prim() {
    let Some((_dir, expected)) = generate_fixtures() else {
        return;
    };
    for case in expected["bad"].as_array().unwrap() {
        let stage = case["stage"].as_str().unwrap();
        match load(Path::new(stage), None) {
            Err(SceneError::Prim { prim, message }) => {
                assert_eq!(prim, case["prim"].as_str().unwrap(), "{stage}: {message}");
                let want = case["message"].as_str().unwrap();
                assert!(
                    message.contains(want),
                    "{stage}: `{message}` should say `{want}`"
                );
            }
            Err(other) => panic!("{stage}: expected a prim error, got {other}"),
            Ok(scene) => panic!("{stage}: loaded {} holdouts", scene.holdouts.len()),
        }
    }
}

#[test]
fn stage_without_geometry_has_no_holdouts() {
    let Some((_dir, expected)) = generate_fixtures() else {
        return;
    };
    let scene = load(Path::new(expected["empty"].as_str().unwrap()), None).unwrap();
    assert!(scene.holdouts.is_empty());
    assert!(Holdouts::build(&scene.holdouts).is_empty());
}

// ----- ray queries ------------------------------------------------------------------------

/// A stage written as text (no pxr needed), loaded.
fn load_text(text: &str) -> Scene {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("stage.usda");
    std::fs::write(&path, text).unwrap();
    load(&path, None).unwrap()
}

fn unit(rng: &mut Pcg64) -> DVec3 {
    loop {
        let v = DVec3::new(
            rng.gen_range(-1.0..1.0),
            rng.gen_range(-1.0..1.0),
            rng.gen_range(-1.0..1.0),
        );
        let l = v.length();
        if l > 0.1 && l <= 1.0 {
            return v / l;
        }
    }
}

fn mesh(path: &str, points: Vec<[f64; 3]>, triangles: Vec<[u32; 3]>) -> HoldoutMesh {
    HoldoutMesh {
        prim_path: path.to_string(),
        prim_type: "Mesh".to_string(),
        faces: triangles.len(),
        points,
        triangles,
        degenerate_triangles: 0,
        double_sided: false,
    }
}

/// Random triangles of many sizes, a grid of quads sharing edges and vertices, and a
/// few large triangles, all shifted by `offset` (precision away from the origin).
fn random_scene(rng: &mut Pcg64, offset: DVec3) -> Vec<HoldoutMesh> {
    let mut points = Vec::new();
    let mut tris = Vec::new();
    for _ in 0..3000 {
        let c = DVec3::new(
            rng.gen_range(-5.0..5.0),
            rng.gen_range(-5.0..5.0),
            rng.gen_range(-5.0..5.0),
        );
        let size = rng.gen_range(0.02..1.5);
        let first = points.len() as u32;
        for _ in 0..3 {
            points.push((offset + c + unit(rng) * size).to_array());
        }
        tris.push([first, first + 1, first + 2]);
    }
    let soup = mesh("/Soup", points, tris);
    let n = 20;
    let mut points = Vec::new();
    let mut tris = Vec::new();
    for j in 0..=n {
        for i in 0..=n {
            let (x, y) = (i as f64 * 0.4 - 4.0, j as f64 * 0.4 - 4.0);
            points.push((offset + DVec3::new(x, y, 0.3 * (x * 0.7).sin() * y.cos())).to_array());
        }
    }
    for j in 0..n as u32 {
        for i in 0..n as u32 {
            let v = j * (n as u32 + 1) + i;
            tris.push([v, v + 1, v + n as u32 + 2]);
            tris.push([v, v + n as u32 + 2, v + n as u32 + 1]);
        }
    }
    let grid = mesh("/Grid", points, tris);
    let big = mesh(
        "/Big",
        vec![
            (offset + DVec3::new(-20.0, -20.0, 4.5)).to_array(),
            (offset + DVec3::new(20.0, -20.0, 4.6)).to_array(),
            (offset + DVec3::new(0.0, 25.0, 4.4)).to_array(),
        ],
        vec![[0, 1, 2]],
    );
    vec![soup, grid, big]
}

/// Brute force over every triangle, written independently of the BVH's test (plane
/// hit, then barycentric coordinates from areas). Returns the nearest hit that is not
/// within `GRAZE` of an edge or of the interval's ends, and the distances of the hits
/// that are (either answer is right for those).
const GRAZE: f64 = 1e-9;

fn brute_force(
    meshes: &[HoldoutMesh],
    o: DVec3,
    d: DVec3,
    tmin: f64,
    tmax: f64,
) -> (Option<f64>, Vec<f64>) {
    let mut sure: Option<f64> = None;
    let mut grazing = Vec::new();
    for m in meshes {
        for t in &m.triangles {
            let [a, b, c] = t.map(|i| DVec3::from_array(m.points[i as usize]));
            let n = (b - a).cross(c - a);
            let nn = n.length_squared();
            let denom = n.dot(d);
            let dist = n.dot(a - o);
            if denom.abs() <= GRAZE * nn.sqrt() {
                // (Nearly) parallel: ambiguous only when the ray (nearly) lies in the plane.
                if dist.abs() <= 1e-6 * nn.sqrt() {
                    grazing.push(f64::NAN);
                }
                continue;
            }
            let t = dist / denom;
            let p = o + d * t;
            let la = n.dot((c - b).cross(p - b)) / nn;
            let lb = n.dot((a - c).cross(p - c)) / nn;
            let lc = n.dot((b - a).cross(p - a)) / nn;
            let margin = la.min(lb).min(lc);
            let eps = GRAZE * t.abs().max(1.0);
            if margin > GRAZE && t > tmin + eps && t < tmax - eps {
                sure = Some(sure.map_or(t, |s: f64| s.min(t)));
            } else if margin >= -GRAZE && t > tmin - eps && t < tmax + eps {
                grazing.push(t);
            }
        }
    }
    (sure, grazing)
}

fn check_against_brute_force(
    meshes: &[HoldoutMesh],
    rng: &mut Pcg64,
    rays: usize,
    centre: DVec3,
) -> (usize, usize) {
    let holdouts = Holdouts::build(meshes);
    let stats = holdouts.stats();
    let total: usize = meshes.iter().map(|m| m.triangles.len()).sum();
    assert_eq!(stats.triangles, total);
    assert_eq!(stats.meshes, meshes.len());
    assert!(stats.bytes > 0 && stats.build_seconds >= 0.0);
    let (mut hits, mut ambiguous) = (0, 0);
    for k in 0..rays {
        let o = centre
            + DVec3::new(
                rng.gen_range(-6.0..6.0),
                rng.gen_range(-6.0..6.0),
                rng.gen_range(-6.0..6.0),
            );
        let d = unit(rng);
        let tmin = if k % 4 == 0 {
            rng.gen_range(0.0..3.0)
        } else {
            0.0
        };
        let tmax = if k % 3 == 0 {
            rng.gen_range(tmin..tmin + 8.0)
        } else {
            f64::INFINITY
        };
        let (sure, grazing) = brute_force(meshes, o, d, tmin, tmax);
        let got = holdouts.hit(o, d, tmin, tmax);
        let blocked = holdouts.occluded(o, d, tmin, tmax);
        let what = format!("ray {k}: o {o} d {d} ({tmin}, {tmax}): bvh {got:?}, brute {sure:?}, grazing {grazing:?}");
        assert_eq!(
            blocked,
            got.is_some(),
            "{what}: occluded disagrees with hit"
        );
        if grazing.is_empty() {
            match (got, sure) {
                (None, None) => {}
                (Some(t), Some(s)) => assert!(close(t, s, 1e-9), "{what}"),
                _ => panic!("{what}"),
            }
            hits += usize::from(sure.is_some());
            continue;
        }
        // A grazing candidate is hit or missed within rounding: the answer must be the
        // sure nearest hit or one of them, nearer than it.
        ambiguous += 1;
        match got {
            None => assert!(sure.is_none(), "{what}"),
            Some(t) => {
                let is_sure = sure.is_some_and(|s| close(t, s, 1e-9));
                let is_grazing = grazing.iter().any(|&g| g.is_nan() || close(t, g, 1e-9))
                    && sure.is_none_or(|s| t <= s * (1.0 + 1e-9));
                assert!(is_sure || is_grazing, "{what}");
            }
        }
    }
    (hits, ambiguous)
}

#[test]
fn ray_queries_agree_with_brute_force() {
    let mut rng = Pcg64::seed_from_u64(18);
    for offset in [DVec3::ZERO, DVec3::new(1000.0, -2000.0, 500.0)] {
        let meshes = random_scene(&mut rng, offset);
        let rays = 20_000;
        let (hits, ambiguous) = check_against_brute_force(&meshes, &mut rng, rays, offset);
        eprintln!("offset {offset}: {hits} hits of {rays} rays, {ambiguous} grazing");
        // Throughput, for the record (not asserted: the machine is shared).
        let holdouts = Holdouts::build(&meshes);
        let queries: Vec<(DVec3, DVec3)> = (0..200_000)
            .map(|_| {
                (
                    offset + unit(&mut rng) * rng.gen_range(0.0..6.0),
                    unit(&mut rng),
                )
            })
            .collect();
        let start = std::time::Instant::now();
        let nearest = queries
            .iter()
            .filter(|(o, d)| holdouts.hit(*o, *d, 0.0, f64::INFINITY).is_some())
            .count();
        let hit_time = start.elapsed().as_secs_f64();
        let start = std::time::Instant::now();
        let blocked = queries
            .iter()
            .filter(|(o, d)| holdouts.occluded(*o, *d, 0.0, f64::INFINITY))
            .count();
        let any_time = start.elapsed().as_secs_f64();
        assert_eq!(nearest, blocked);
        eprintln!(
            "  {} triangles: hit {:.0} ns/ray, occluded {:.0} ns/ray (one thread)",
            holdouts.stats().triangles,
            hit_time * 1e9 / queries.len() as f64,
            any_time * 1e9 / queries.len() as f64
        );
        assert!(hits > rays / 4, "too few hits ({hits}) to test anything");
        assert!(ambiguous < rays / 1000, "{ambiguous} grazing rays");
    }
}

#[test]
fn sphere_tessellation_is_within_its_chord_error() {
    let scene = load_text(
        "#usda 1.0\n\
         def Sphere \"Ball\" {\n\
             double radius = 2\n\
             double3 xformOp:translate = (1, 2, 3)\n\
             uniform token[] xformOpOrder = [\"xformOp:translate\"]\n\
         }\n",
    );
    let holdouts = Holdouts::build(&scene.holdouts);
    let (c, r) = (DVec3::new(1.0, 2.0, 3.0), 2.0);
    let inner = r * (1.0 - MAX_CHORD_ERROR);
    let mut rng = Pcg64::seed_from_u64(7);
    let mut worst: f64 = 0.0;
    for _ in 0..5000 {
        // From the centre: the hit is between the inscribed ball and the sphere.
        let d = unit(&mut rng);
        let t = holdouts
            .hit(c, d, 0.0, f64::INFINITY)
            .expect("a ray from inside hits");
        assert!(
            t <= r * (1.0 + 1e-12) && t >= inner,
            "t {t} outside [{inner}, {r}]"
        );
        worst = worst.max((r - t) / r);
        // From outside: the tessellation contains the ball of radius r(1 − error) and
        // lies inside the sphere, so its entry is between theirs.
        let o = c + unit(&mut rng) * 10.0;
        let aim = c + unit(&mut rng) * rng.gen_range(0.0..1.5);
        let d = (aim - o).normalize();
        let entry = |radius: f64| {
            let oc = o - c;
            let b = oc.dot(d);
            let disc = b * b - (oc.length_squared() - radius * radius);
            -b - disc.sqrt()
        };
        let t = holdouts
            .hit(o, d, 0.0, f64::INFINITY)
            .expect("aimed inside the inner ball");
        assert!(
            t >= entry(r) * (1.0 - 1e-12) && t <= entry(inner) * (1.0 + 1e-12),
            "{t}"
        );
    }
    eprintln!(
        "sphere: largest chord error seen {worst:.2e} of the radius (bound {MAX_CHORD_ERROR:e})"
    );
}

#[test]
fn cube_seen_from_inside_is_hit() {
    let scene = load_text("#usda 1.0\ndef Cube \"Box\" {\n    double size = 2\n}\n");
    let holdouts = Holdouts::build(&scene.holdouts);
    assert_eq!(holdouts.stats().triangles, 12);
    let o = DVec3::ZERO;
    // Face centres, a shared face diagonal, an edge and a corner: no cracks anywhere.
    for (d, t) in [
        (DVec3::X, 1.0),
        (DVec3::NEG_Z, 1.0),
        (
            DVec3::new(-1.0, 0.3, 0.3),
            DVec3::new(-1.0, 0.3, 0.3).length(),
        ),
        (DVec3::new(1.0, 1.0, 0.0), 2f64.sqrt()),
        (DVec3::new(1.0, 1.0, 1.0), 3f64.sqrt()),
        (DVec3::new(-1.0, 1.0, -1.0), 3f64.sqrt()),
    ] {
        let d = d.normalize();
        let got = holdouts.hit(o, d, 0.0, f64::INFINITY);
        assert!(
            got.is_some_and(|g| close(g, t, 1e-12)),
            "{d}: {got:?}, want {t}"
        );
        assert!(holdouts.occluded(o, d, 0.0, 10.0), "{d}");
        assert!(
            !holdouts.occluded(o, d, 0.0, 0.99),
            "{d}: nothing before the wall"
        );
        assert!(
            holdouts.hit(o, d, t * 1.001, 100.0).is_none(),
            "{d}: nothing past the wall"
        );
    }
    let mut rng = Pcg64::seed_from_u64(3);
    for _ in 0..10_000 {
        let o = DVec3::new(
            rng.gen_range(-0.9..0.9),
            rng.gen_range(-0.9..0.9),
            rng.gen_range(-0.9..0.9),
        );
        let d = unit(&mut rng);
        // Distance to the wall along d: the nearest slab exit.
        let exit = (0..3)
            .map(|a| ((d[a].signum() - o[a]) / d[a]).abs())
            .fold(f64::INFINITY, f64::min);
        let t = holdouts
            .hit(o, d, 0.0, f64::INFINITY)
            .expect("every ray from inside hits");
        assert!(close(t, exit, 1e-9), "{o} {d}: {t} vs {exit}");
    }
}

#[test]
fn empty_holdouts_never_hit() {
    let only_degenerate = HoldoutMesh {
        degenerate_triangles: 4,
        ..mesh(
            "/Flat",
            vec![
                [0.0; 3],
                [1.0, 0.0, 0.0],
                [2.0, 0.0, 0.0],
                [f64::NAN, 0.0, 0.0],
            ],
            vec![[0, 1, 2], [0, 0, 1], [0, 1, 3], [0, 1, 9]],
        )
    };
    let built = [
        Holdouts::empty(),
        Holdouts::build(&[]),
        Holdouts::build(&[only_degenerate]),
    ];
    assert_eq!(built[2].stats().degenerate_triangles, 8);
    assert_eq!(built[2].stats().meshes, 1);
    let mut rng = Pcg64::seed_from_u64(1);
    for h in &built {
        assert!(h.is_empty());
        assert_eq!(h.stats().triangles, 0);
        for _ in 0..1000 {
            let o = DVec3::new(
                rng.gen_range(-3.0..3.0),
                rng.gen_range(-3.0..3.0),
                rng.gen_range(-3.0..3.0),
            );
            let d = unit(&mut rng);
            assert!(h.hit(o, d, 0.0, f64::INFINITY).is_none());
            assert!(!h.occluded(o, d, 0.0, f64::INFINITY));
        }
    }
}

#[test]
fn bad_triangles_given_to_build_are_skipped_and_counted() {
    // Built by hand (not by the loader): out-of-range indices and NaN points must not
    // panic; they are counted with the mesh's own degenerate triangles.
    let m = HoldoutMesh {
        degenerate_triangles: 2,
        ..mesh(
            "/Hand",
            vec![
                [0.0; 3],
                [1.0, 0.0, 0.0],
                [0.0, 1.0, 0.0],
                [f64::NAN, 0.0, 0.0],
            ],
            vec![[0, 1, 2], [0, 1, 3], [0, 1, 7], [1, 1, 2]],
        )
    };
    let h = Holdouts::build(&[m]);
    let s = h.stats();
    assert_eq!((s.triangles, s.degenerate_triangles), (1, 5));
    let down = DVec3::NEG_Z;
    assert_eq!(h.hit(DVec3::new(0.2, 0.2, 1.0), down, 0.0, 5.0), Some(1.0));
    // Both sides: from below too.
    assert_eq!(
        h.hit(DVec3::new(0.2, 0.2, -2.0), DVec3::Z, 0.0, 5.0),
        Some(2.0)
    );
    // NaN and empty intervals answer no.
    assert!(h
        .hit(DVec3::new(0.2, 0.2, 1.0), down, 0.0, f64::NAN)
        .is_none());
    assert!(!h.occluded(DVec3::new(0.2, 0.2, 1.0), down, 2.0, 1.0));
    assert!(!h.occluded(DVec3::new(f64::NAN, 0.2, 1.0), down, 0.0, 5.0));
}

#[test]
fn info_prints_the_holdouts() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("stage.usda");
    std::fs::write(
        &path,
        "#usda 1.0\ndef Cube \"Box\" {\n    double size = 2\n}\ndef Xform \"Empty\" {\n}\n",
    )
    .unwrap();
    let out = common::cli::nimbus(&["info", path.to_str().unwrap()]);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{}", common::cli::stderr(&out));
    assert!(
        text.contains("holdouts: 1 meshes, 12 triangles, 0 degenerate skipped, BVH built in"),
        "{text}"
    );
    assert!(text.contains("holdout /Box (Cube): 12 triangles"), "{text}");
}
