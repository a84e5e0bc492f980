//! Albedo multiplier grids (issue 8: a colour `Cd` Vec3s grid, or a float grid as grey,
//! named by `nimbus:albedoField`): Vec3s reading and writing, the estimator against the
//! equivalent medium with constant coefficients, loading from stages and bad input.

mod common;

use common::medium_for_scene;
use common::{mean_se, paths, Setup};
use glam::{DMat4, DVec3};
use nimbus::render::lights::Lights;
use nimbus::scene::{load_stage, LoadOptions};
use nimbus::track::select::{SchemeKind, TrackerKind, TrackerSettings};
use nimbus::volume::albedo::Albedo;
use nimbus::volume::asset::AssetLocation;
use nimbus::volume::counters::Counters;
use nimbus::volume::grid::{RawGrid, RawTile};
use nimbus::volume::procedural::grid_from_fn;
use nimbus::volume::vdb::{
    list_grids, list_grids_with, read_color_grid, read_float_grid_with, read_vec3s_grid_with,
    write_grids, Reader, WriteGrid,
};
use std::path::{Path, PathBuf};

fn assert_mentions(msg: &str, needles: &[&str]) {
    for n in needles {
        assert!(msg.contains(n), "message lacks {n:?}: {msg}");
    }
}

// ----- Vec3s files -------------------------------------------------------------------------

/// Three components of one topology: 12³ voxels (two bricks per axis, partly filled) with
/// distinct, non-round values per component, one active and one inactive 8³ tile away
/// from the leaves, and distinct backgrounds.
fn vec3_components() -> [RawGrid; 3] {
    std::array::from_fn(|c| {
        let mut g = grid_from_fn("Cd", [12, 12, 12], DVec3::splat(-0.3), 0.05, |p| {
            0.013 + 0.1 * c as f64 + 0.37 * (p.x + 0.3) + 0.11 * (p.y + 0.3) * (p.z + 0.3)
        });
        g.background = [0.25, -0.5, 1e-3][c];
        g.tiles = vec![
            RawTile {
                origin: [64, 0, 8],
                dim: 8,
                value: [0.75, 0.125, 3.5][c],
                active: true,
            },
            RawTile {
                origin: [128, 128, 128],
                dim: 128,
                value: [-1.0, 2.0, 0.0625][c],
                active: false,
            },
        ];
        g
    })
}

fn assert_same_grid(what: &str, got: &RawGrid, want: &RawGrid) {
    assert_eq!(got.name, want.name, "{what}: name");
    assert_eq!(
        got.background.to_bits(),
        want.background.to_bits(),
        "{what}: background"
    );
    assert_eq!(got.index_to_world, want.index_to_world, "{what}: transform");
    let mut gl: Vec<_> = got.leaves.iter().collect();
    let mut wl: Vec<_> = want.leaves.iter().collect();
    gl.sort_by_key(|l| l.origin);
    wl.sort_by_key(|l| l.origin);
    assert_eq!(gl.len(), wl.len(), "{what}: leaf count");
    for (g, w) in gl.iter().zip(&wl) {
        assert_eq!(g.origin, w.origin, "{what}: leaf origin");
        assert_eq!(g.active, w.active, "{what}: leaf mask at {:?}", g.origin);
        let gb: Vec<u32> = g.values.iter().map(|v| v.to_bits()).collect();
        let wb: Vec<u32> = w.values.iter().map(|v| v.to_bits()).collect();
        assert_eq!(gb, wb, "{what}: leaf values at {:?}", g.origin);
    }
    let key = |t: &RawTile| (t.origin, t.dim);
    let mut gt = got.tiles.clone();
    let mut wt = want.tiles.clone();
    gt.sort_by_key(key);
    wt.sort_by_key(key);
    assert_eq!(gt, wt, "{what}: tiles");
}

/// Writes a Vec3s grid with Nimbus' writer (next to a float grid, in one file) and reads
/// it back through OpenVDB: every leaf value, mask, tile, background and the transform
/// come back bit for bit through both readers (OpenVDB reading the file also validates
/// the writer), and so does the float grid of the same file.
#[test]
fn vec3s_round_trip_both_readers() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("cd.vdb");
    let cd = vec3_components();
    let density = grid_from_fn("density", [8, 8, 8], DVec3::ZERO, 0.1, |p| 1.0 + p.x);
    write_grids(&path, &[WriteGrid::Float(&density), WriteGrid::Vec3s(&cd)]).unwrap();
    let loc = AssetLocation::File(path.clone());
    let types: Vec<String> = list_grids(&loc)
        .unwrap()
        .into_iter()
        .map(|g| g.value_type)
        .collect();
    assert_eq!(types, ["Tree_float_5_4_3", "Tree_vec3s_5_4_3"]);

    for reader in [Reader::OpenVdb, Reader::Rust] {
        if !reader.available() {
            common::data::openvdb_bridge("the OpenVDB round trip (the Rust reader's runs)");
            continue;
        }
        let who = reader.name();
        let d = read_float_grid_with(reader, &loc, "density", None).unwrap();
        assert_same_grid(&format!("density via {who}"), &d, &density);
        let got =
            read_vec3s_grid_with(reader, &loc, "Cd", None).unwrap_or_else(|e| panic!("{who}: {e}"));
        for c in 0..3 {
            assert_same_grid(&format!("Cd component {c} via {who}"), &got[c], &cd[c]);
        }
        // Reading a Vec3s grid as float, or a float grid as Vec3s, names both types.
        let e = read_float_grid_with(reader, &loc, "Cd", None)
            .unwrap_err()
            .to_string();
        assert_mentions(&e, &["cd.vdb", "\"Cd\" is Vec3s, expected float"]);
        let e = read_vec3s_grid_with(reader, &loc, "density", None)
            .unwrap_err()
            .to_string();
        assert_mentions(&e, &["\"density\" is float, expected Vec3s"]);
    }
    if Reader::OpenVdb.available() {
        let listed = list_grids_with(Reader::OpenVdb, &loc).unwrap();
        let cd_type = listed
            .iter()
            .find(|g| g.name == "Cd")
            .map(|g| &g.value_type);
        assert_eq!(cd_type.map(String::as_str), Some("Tree_vec3s_5_4_3"));
    }
    // A colour grid from a float grid is grey: the same grid three times.
    let grey = read_color_grid(&loc, "density", None).unwrap();
    for g in &grey {
        assert_same_grid("grey", g, &density);
    }
}

/// Vec3s grids as OpenVDB itself writes them (`tests/fixtures/vec3s_openvdb.vdb`, made by
/// `make_vec3s_vdb.cc`: blosc compression with active-value masks, one grid with full and
/// one with half floats): they pass Nimbus' header and tree validation and read back
/// through both readers with the generator's values (half floats to half precision),
/// identical bit for bit between the readers; so does the float grid of the same file.
#[test]
fn openvdb_written_vec3s_grids_read_back() {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/vec3s_openvdb.vdb");
    let loc = AssetLocation::File(path);
    for reader in [Reader::OpenVdb, Reader::Rust] {
        if reader.available() {
            let d = read_float_grid_with(reader, &loc, "density", None).unwrap();
            assert_eq!(d.active_voxel_count(), 216, "{}", reader.name());
        }
    }
    if Reader::OpenVdb.available() {
        for name in ["Cd", "Cd_half"] {
            let a = read_vec3s_grid_with(Reader::OpenVdb, &loc, name, None).unwrap();
            let b = read_vec3s_grid_with(Reader::Rust, &loc, name, None).unwrap();
            for c in 0..3 {
                assert_same_grid(&format!("{name}[{c}] rust vs openvdb"), &b[c], &a[c]);
            }
        }
    } else {
        common::data::openvdb_bridge("the comparison with OpenVDB (the Rust reader checked alone)");
    }
    // The generator's values (equal to OpenVDB's, checked above when it is built in).
    for (name, tol) in [("Cd", 0.0f32), ("Cd_half", 1e-3)] {
        let g = read_vec3s_grid_with(Reader::Rust, &loc, name, None).unwrap();
        let mut seen = 0;
        for c in 0..3 {
            assert_eq!(g[c].background, 0.0);
            assert_eq!(g[c].active_voxel_count(), 216 + 512, "{name}");
            let tile = g[c].tiles.iter().find(|t| t.active).expect("the tile");
            assert_eq!((tile.origin, tile.dim), ([64, 0, 0], 8));
            assert_eq!(tile.value, [0.125, 0.25, 0.375][c]);
            for leaf in &g[c].leaves {
                for off in 0..512 {
                    if leaf.active[off / 64] >> (off % 64) & 1 == 0 {
                        continue;
                    }
                    let ijk = [off >> 6, (off >> 3) & 7, off & 7].map(|v| v as i32);
                    let p = [0, 1, 2].map(|a| leaf.origin[a] + ijk[a]);
                    let want = [0.1f32, 0.2, 0.3][c] + 0.01 * p[c] as f32;
                    let got = leaf.values[off];
                    assert!(
                        (got - want).abs() <= tol,
                        "{name}[{c}] at {p:?}: {got} vs {want}"
                    );
                    seen += 1;
                }
            }
        }
        assert_eq!(seen, 3 * 216, "{name}");
    }
}

/// The writer refuses Vec3s components whose topologies differ.
#[test]
fn vec3s_components_must_share_topology() {
    let mut cd = vec3_components();
    cd[2].tiles.pop();
    let e = nimbus::volume::vdb::write_grids_bytes(&[WriteGrid::Vec3s(&cd)])
        .unwrap_err()
        .to_string();
    assert_mentions(&e, &["component 2", "topology"]);
}

// ----- the estimator -----------------------------------------------------------------------

const C: [f64; 3] = [0.3, 0.6, 0.9];

/// A constant albedo grid c over [−0.8125, 0.8125]³ (14³ voxels of 1/8, another transform
/// than the density's): its reconstruction is exactly c wherever the cube's density is
/// non-zero.
fn constant_albedo(c: [f64; 3]) -> Albedo {
    let raw = c.map(|v| grid_from_fn("Cd", [14, 14, 14], DVec3::splat(-0.8125), 0.125, |_| v));
    Albedo::new("/Cube", "test albedo", "Cd", raw, DMat4::IDENTITY).unwrap()
}

fn estimators() -> Vec<(String, TrackerSettings)> {
    let s = |tracker, no_absorption_events| {
        let mut t = TrackerSettings {
            tracker,
            scheme: SchemeKind::HistAvg,
            ..TrackerSettings::default()
        };
        t.options.no_absorption_events = no_absorption_events;
        t
    };
    vec![
        ("delta".into(), s(TrackerKind::Delta, false)),
        ("naive-delta".into(), s(TrackerKind::NaiveDelta, false)),
        (
            "spectral-decomposition/hist-avg".into(),
            s(TrackerKind::SpectralDecomposition, false),
        ),
        (
            "spectral-decomposition/hist-avg, no absorption events".into(),
            s(TrackerKind::SpectralDecomposition, true),
        ),
        ("ratio-select".into(), s(TrackerKind::RatioSelect, false)),
    ]
}

/// Per-channel mean and standard error of `n` paths through the image centre, and the
/// summed counters.
fn estimate(setup: &Setup, s: &TrackerSettings, n: usize) -> ([(f64, f64); 3], Counters) {
    let p = paths(setup, s, 4.5, 4.5, n);
    let mut totals = Counters::default();
    p.iter().for_each(|(_, c)| totals.add(c));
    let ms = [0, 1, 2].map(|c| mean_se(&p.iter().map(|(rgb, _)| rgb[c]).collect::<Vec<_>>()));
    (ms, totals)
}

fn z_diff(a: &[(f64, f64); 3], b: &[(f64, f64); 3]) -> [f64; 3] {
    [0, 1, 2].map(|c| (a[c].0 - b[c].0) / (a[c].1.powi(2) + b[c].1.powi(2)).sqrt().max(1e-12))
}

/// The albedo grid is the medium it models: a cube (side 1, σa = (0.2, 0.3, 0.1),
/// σs = (1.2, 1.0, 1.4), g = 0.3, in a constant environment (0.6, 0.8, 1.0)) with a
/// constant albedo grid c = (0.3, 0.6, 0.9) renders like the same cube without the grid
/// and σs' = c·σs, σa' = σa + (1 − c)·σs (same extinction).
/// Estimator: the path tracer (NEE + MIS to the environment, max depth 64, Russian
/// roulette), for delta, naive delta, spectral decomposition (hist-avg; with and
/// without absorption events) and ratio-select; N = 40,000 independent paths through the image centre
/// per medium and estimator, seeds 5 (grid) and 6 (reference); z = difference of the
/// means over the standard error of the difference (sample variances); |z| < 4 per
/// channel. Power: the grid medium *without* the scatter weight (no albedo grid) must
/// differ from the reference by |z| > 8 in some channel.
#[test]
fn albedo_grid_matches_equivalent_coefficients() {
    let sigma_a = [0.2, 0.3, 0.1];
    let sigma_s = [1.2, 1.0, 1.4];
    let g = 0.3;
    let mut with_grid = common::unit_cube(1.0, sigma_a, sigma_s, g);
    with_grid.set_albedo(Some(constant_albedo(C)));
    let without_weight = common::unit_cube(1.0, sigma_a, sigma_s, g);
    let sa2 = [0, 1, 2].map(|c| sigma_a[c] + (1.0 - C[c]) * sigma_s[c]);
    let ss2 = [0, 1, 2].map(|c| C[c] * sigma_s[c]);
    let reference = common::unit_cube(1.0, sa2, ss2, g);
    let lights = Lights {
        environment: [0.6, 0.8, 1.0],
        ..Default::default()
    };
    let cam = common::camera_on_z(10.0, 1000.0, 10.0, 9, 9);
    let setup = |medium, seed| Setup {
        medium,
        lights: &lights,
        camera: &cam,
        width: 9,
        height: 9,
        spp: 1,
        max_depth: 64,
        seed,
    };
    const N: usize = 40_000;
    for (name, s) in estimators() {
        let (a, ca) = estimate(&setup(&with_grid, 5), &s, N);
        let (r, cr) = estimate(&setup(&reference, 6), &s, N);
        let (u, _) = estimate(&setup(&without_weight, 5), &s, N);
        let z = z_diff(&a, &r);
        let z_power = z_diff(&u, &r);
        eprintln!(
            "{name}: grid {:.4?} reference {:.4?} z {z:.2?}; without the scatter weight z {z_power:.1?}; albedo lookups {} (real collisions {})",
            a.map(|m| m.0),
            r.map(|m| m.0),
            ca.albedo_lookups,
            ca.real_collisions
        );
        assert!(
            z.iter().all(|z| z.abs() < 4.0),
            "{name}: z = {z:?} ({a:?} vs {r:?})"
        );
        assert!(
            z_power.iter().any(|z| z.abs() > 8.0),
            "{name}: no power: {z_power:?}"
        );
        // One lookup per scatter event: some, never more than the real collisions, and
        // none without a grid.
        assert!(ca.albedo_lookups > 0 && ca.albedo_lookups <= ca.real_collisions);
        assert_eq!(cr.albedo_lookups, 0);
    }
}

/// Lookups happen at scatter events only: a purely absorbing cube (σs = 0) never scatters
/// and makes no albedo lookup; with scattering, analog delta tracking looks the grid up
/// once per scatter event, i.e. at most once per real collision, and never at null
/// collisions (a sample with null collisions but no scatter event has no lookup).
#[test]
fn albedo_lookups_only_at_scatter_events() {
    let lights = Lights {
        environment: [1.0; 3],
        ..Default::default()
    };
    let cam = common::camera_on_z(10.0, 1000.0, 10.0, 9, 9);
    let s = TrackerSettings {
        tracker: TrackerKind::Delta,
        ..TrackerSettings::default()
    };
    let mut absorbing = common::unit_cube(1.0, [1.0; 3], [0.0; 3], 0.0);
    absorbing.set_albedo(Some(constant_albedo(C)));
    let setup = Setup {
        medium: &absorbing,
        lights: &lights,
        camera: &cam,
        width: 9,
        height: 9,
        spp: 1,
        max_depth: 64,
        seed: 3,
    };
    let p = paths(&setup, &s, 4.5, 4.5, 2000);
    assert!(p.iter().all(|(_, c)| c.albedo_lookups == 0));
    assert!(p
        .iter()
        .any(|(_, c)| c.null_collisions > 0 || c.real_collisions > 0));
    // Majorant 2× the density: plenty of null collisions. σs = 1 with c = 1: no absorption.
    let mut scattering = common::unit_cube(1.0, [0.0; 3], [1.0; 3], 0.0);
    scattering.set_albedo(Some(constant_albedo([1.0; 3])));
    let setup = Setup {
        medium: &scattering,
        ..setup
    };
    let s = TrackerSettings {
        majorant_scale: 2.0,
        ..s
    };
    let p = paths(&setup, &s, 4.5, 4.5, 2000);
    // At most one lookup per real collision, none in a path with only null collisions.
    for (_, c) in &p {
        assert!(c.albedo_lookups <= c.real_collisions, "{c:?}");
    }
    assert!(p
        .iter()
        .any(|(_, c)| c.null_collisions > 0 && c.real_collisions == 0 && c.albedo_lookups == 0));
    assert!(p.iter().any(|(_, c)| c.albedo_lookups > 1));
}

/// Values outside [0,1] and non-finite values are clamped (NaN → 0) and counted.
#[test]
fn albedo_values_are_clamped() {
    let mut raw: [RawGrid; 3] =
        std::array::from_fn(|_| grid_from_fn("Cd", [8, 8, 8], DVec3::ZERO, 1.0, |_| 0.5));
    raw[0].leaves[0].values[0] = 1.5;
    raw[1].leaves[0].values[1] = -0.25;
    raw[2].leaves[0].values[2] = f32::NAN;
    raw[2].background = f32::INFINITY;
    let a = Albedo::new("/V", "test", "Cd", raw, DMat4::IDENTITY).unwrap();
    assert_eq!(a.clamped_values, 4);
    let mut c = Counters::default();
    assert_eq!(a.sample(DVec3::ZERO, &mut c), [1.0, 0.5, 0.5]);
    assert_eq!(a.sample(DVec3::new(0.0, 0.0, 1.0), &mut c), [0.5, 0.0, 0.5]);
    assert_eq!(a.sample(DVec3::new(0.0, 0.0, 2.0), &mut c), [0.5, 0.5, 0.0]);
    assert_eq!(a.sample(DVec3::splat(100.0), &mut c), [0.0, 0.0, 1.0]);
    assert_eq!(c.albedo_lookups, 4);
    assert_eq!(c.density_lookups, 0);
}

// ----- stages ------------------------------------------------------------------------------

/// A stage with a volume `/V` whose fields `density`, `Cd` and `grey` are the grids of one
/// file `grids.vdb`; `attrs` go on the volume.
fn albedo_stage(dir: &Path, attrs: &str) -> PathBuf {
    common::grids_stage(dir, "albedo", &["density", "Cd", "grey"], attrs)
}

/// density (16³ over the unit cube), Cd = (0.3, 0.6, 0.9) with one voxel of each
/// component out of range, grey = 0.4.
fn stage_grids(dir: &Path, with_cd: bool) {
    let n = 16;
    let vs = 1.0 / n as f64;
    let density = grid_from_fn(
        "density",
        [n, n, n],
        DVec3::splat(-0.5 + 0.5 * vs),
        vs,
        |_| 1.0,
    );
    let mut cd = C.map(|v| grid_from_fn("Cd", [14, 14, 14], DVec3::splat(-0.8125), 0.125, |_| v));
    cd[0].leaves[0].values[0] = 2.0;
    cd[1].leaves[0].values[0] = -1.0;
    cd[2].leaves[0].values[0] = f32::NAN;
    let grey = grid_from_fn("grey", [14, 14, 14], DVec3::splat(-0.8125), 0.125, |_| 0.4);
    let mut grids = vec![WriteGrid::Float(&density)];
    if with_cd {
        grids.push(WriteGrid::Vec3s(&cd));
    }
    grids.push(WriteGrid::Float(&grey));
    write_grids(&dir.join("grids.vdb"), &grids).unwrap();
}

/// `nimbus:albedoField` reaches the medium: a Vec3s `Cd` is looked up per channel (out of
/// range voxels clamped), a float grid is a grey albedo, and without the attribute the
/// `Cd` field is not used (no grid loaded, constant albedo in the analysis).
#[test]
fn stage_albedo_reaches_the_medium() {
    use nimbus::render::analysis::Analysis;
    let dir = tempfile::tempdir().unwrap();
    stage_grids(dir.path(), true);
    let at = DVec3::new(0.1, -0.2, 0.05);

    let plain = albedo_stage(dir.path(), "");
    let scene = load_stage(&plain, &LoadOptions::default()).unwrap();
    assert!(scene.volumes[0].albedo.is_none());
    let m = medium_for_scene(&scene, 8).unwrap();
    assert!(m.albedo.is_none());
    let cam = common::camera_on_z(10.0, 1000.0, 10.0, 9, 9);
    let a = Analysis::of_media(std::slice::from_ref(&m), &Lights::default(), &cam, (9, 9));
    assert!(a.constant_albedo && a.albedo_field.is_none());

    let grey = albedo_stage(dir.path(), "    token nimbus:albedoField = \"grey\"");
    let scene = load_stage(&grey, &LoadOptions::default()).unwrap();
    let m = medium_for_scene(&scene, 8).unwrap();
    let c = m
        .albedo
        .as_ref()
        .unwrap()
        .sample(at, &mut Counters::default());
    assert_eq!(c, [0.4f32; 3]);

    let stage = albedo_stage(dir.path(), "    token nimbus:albedoField = \"Cd\"");
    let scene = load_stage(&stage, &LoadOptions::default()).unwrap();
    assert_eq!(scene.volumes[0].albedo.as_ref().unwrap().0, "Cd");
    let m = medium_for_scene(&scene, 8).unwrap();
    let albedo = m.albedo.as_ref().unwrap();
    assert_eq!(albedo.clamped_values, 3);
    let c = albedo.sample(at, &mut Counters::default());
    for k in 0..3 {
        assert!((c[k] as f64 - C[k]).abs() < 1e-6, "{c:?}");
    }
    // The clamped corner voxel (index (0,0,0) at world −0.8125): 2 → 1, −1 → 0, NaN → 0.
    let corner = albedo.sample(DVec3::splat(-0.8125), &mut Counters::default());
    assert_eq!(corner, [1.0, 0.0, 0.0]);
    let a = Analysis::of_media(std::slice::from_ref(&m), &Lights::default(), &cam, (9, 9));
    assert!(!a.constant_albedo);
    assert_eq!(a.albedo_field.as_deref(), Some("Cd"));
}

/// A field name with no relationship: the error names the prim, the attribute and the
/// missing relationship, and lists the volume's fields.
#[test]
fn missing_albedo_field_lists_the_fields() {
    let dir = tempfile::tempdir().unwrap();
    stage_grids(dir.path(), true);
    let stage = albedo_stage(dir.path(), "    token nimbus:albedoField = \"colour\"");
    let msg = common::load_message(&stage);
    assert_mentions(
        &msg,
        &[
            "/V",
            "nimbus:albedoField",
            "field:colour",
            "field:Cd, field:density, field:grey",
        ],
    );
}

/// A grid the file does not hold is an error naming the volume, the attribute, the field
/// prim and the grids the file has.
#[test]
fn albedo_grid_missing_from_file() {
    let dir = tempfile::tempdir().unwrap();
    stage_grids(dir.path(), false);
    let stage = albedo_stage(dir.path(), "    token nimbus:albedoField = \"Cd\"");
    let msg = common::load_message(&stage);
    assert_mentions(
        &msg,
        &[
            "/V",
            "nimbus:albedoField",
            "/V/Cd",
            "grids.vdb",
            "\"density\", \"grey\"",
        ],
    );
}

/// End to end: `nimbus render --stats` with a `Cd` albedo field reports albedo lookups,
/// the clamped values and the analysis' albedo field; `nimbus info` prints the field.
/// Without the attribute the same stage makes no albedo lookup.
#[test]
fn render_stats_and_info_report_the_albedo_field() {
    let dir = tempfile::tempdir().unwrap();
    stage_grids(dir.path(), true);
    let run = |attrs: &str| {
        let stage = albedo_stage(dir.path(), attrs);
        let out = dir.path().join("out.exr");
        let stats = dir.path().join("stats.json");
        let o = std::process::Command::new(env!("CARGO_BIN_EXE_nimbus"))
            .args([
                "render",
                stage.to_str().unwrap(),
                "-o",
                out.to_str().unwrap(),
                "--res",
                "16x16",
                "--spp",
                "4",
                "--stats",
                stats.to_str().unwrap(),
            ])
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr).into_owned();
        assert!(o.status.success(), "{err}");
        let s: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&stats).unwrap()).unwrap();
        let info = std::process::Command::new(env!("CARGO_BIN_EXE_nimbus"))
            .args(["info", stage.to_str().unwrap()])
            .output()
            .unwrap();
        (s, err, String::from_utf8_lossy(&info.stdout).into_owned())
    };
    let (s, err, info) = run("    token nimbus:albedoField = \"Cd\"");
    eprintln!("{info}");
    assert!(s["albedo_lookups"].as_u64().unwrap() > 0, "{s}");
    assert_eq!(s["clamped_albedo_values"], 3);
    assert_eq!(s["analysis"]["albedo_field"], "Cd");
    assert_eq!(s["analysis"]["constant_albedo"], false);
    assert_mentions(
        &err,
        &["albedo grid 'Cd' has 3 component values outside [0, 1]"],
    );
    assert_mentions(
        &info,
        &[
            "albedo: albedoField Cd (/V/Cd)",
            "constant albedo false (albedo field Cd)",
        ],
    );
    let (s, err, info) = run("");
    assert_eq!(s["albedo_lookups"], 0);
    assert_eq!(s["analysis"]["albedo_field"], serde_json::Value::Null);
    assert!(!err.contains("albedo grid"), "{err}");
    assert_mentions(
        &info,
        &["albedo: constant (no albedoField, nimbus:albedo not connected)"],
    );
}
