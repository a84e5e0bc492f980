//! The majorant octree: bounds hold for the reconstructed field, the walk covers rays
//! exactly once with the right bounds, and the trackers give the same answers at every
//! depth.

mod common;

use glam::{DMat4, DVec3, Vec3};
use nimbus::track::decomposition::Decomposition;
use nimbus::track::delta::Delta;
use nimbus::track::free_path::{FreePath, FreePathSampler, Query, TransmittanceEstimator};
use nimbus::track::ratio::Ratio;
use nimbus::track::scheme::{Avg, SchemeOptions};
use nimbus::volume::asset::AssetLocation;
use nimbus::volume::counters::Counters;
use nimbus::volume::grid::Grid;
use nimbus::volume::majorant::{MajorantSpec, MajorantTree};
use nimbus::volume::medium::Medium;
use nimbus::volume::procedural::grid_from_fn;
use proptest::prelude::*;
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg32;

/// A lumpy sparse field: random blobs with empty space between them, a constant
/// plateau (so lossless merging is exercised) and sharp edges.
fn blob_grid(seed: u64, dims: i32) -> Grid {
    let mut rng = Pcg32::seed_from_u64(seed);
    let blobs: Vec<(DVec3, f64, f64)> = (0..6)
        .map(|_| {
            let c = DVec3::new(
                rng.gen_range(0.0..dims as f64),
                rng.gen_range(0.0..dims as f64),
                rng.gen_range(0.0..dims as f64),
            );
            (
                c,
                rng.gen_range(2.0..dims as f64 / 3.0),
                rng.gen_range(0.1..3.0),
            )
        })
        .collect();
    let d = dims as f64;
    let raw = grid_from_fn("density", [dims; 3], DVec3::ZERO, 1.0, move |p| {
        if p.x > 0.7 * d && p.y < 0.3 * d {
            return 1.5; // plateau
        }
        blobs
            .iter()
            .map(|&(c, r, a)| {
                let s = (p - c).length() / r;
                if s < 1.0 {
                    a * (1.0 - s) * (1.0 + 0.3 * (p.x * 1.7).sin())
                } else {
                    0.0
                }
            })
            .sum()
    });
    Grid::from_raw(&raw).unwrap()
}

/// The real grids the bounds are checked on, or none (with a message) if the shared
/// data is absent (a failure under `NIMBUS_REQUIRE_DATA=1`). A file that is there must
/// read, with either VDB reader.
fn real_grids() -> Vec<(String, Grid)> {
    let files = [
        ("openvdb_samples/smoke.vdb", "density"),
        ("openusd_blender_smoke/smoke_000003.vdb", "density"),
        ("embergen_fire_a/embergen_fire_a_50.vdb", "flames"),
    ];
    let mut out = Vec::new();
    for (f, grid) in files {
        let Some(path) = common::shared_file(f) else {
            continue;
        };
        match nimbus::volume::vdb::read_float_grid(&AssetLocation::File(path), grid, None) {
            Ok(raw) => out.push((f.to_string(), Grid::from_raw(&raw).unwrap())),
            Err(e) => panic!("{f} does not read: {e}"),
        }
    }
    out
}

/// Interpolated density at random points of random leaf cells lies in the cell's
/// [min, max]. Trilinear interpolation is a convex combination, so the only slack
/// allowed is f32 rounding of the lerps.
fn check_bounds(grid: &Grid, tree: &MajorantTree, rng: &mut Pcg32, cells: usize, points: usize) {
    let dims = tree.dims();
    for _ in 0..cells {
        let c = [0, 1, 2].map(|a| rng.gen_range(0..dims[a]));
        let (mn, mx) = tree.leaf_bounds(c).unwrap();
        let (lo, hi) = tree.leaf_box(c).unwrap();
        for _ in 0..points {
            let u = Vec3::new(rng.gen(), rng.gen(), rng.gen());
            let p = lo + (hi - lo) * u;
            let v = grid.sample_trilinear(p.to_array());
            let tol = 1e-5 * mx.abs().max(1.0);
            assert!(
                v >= mn - tol && v <= mx + tol,
                "cell {c:?} bounds [{mn}, {mx}] but density {v} at {p:?} ({:?})",
                tree.spec()
            );
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]
    #[test]
    fn bounds_hold_on_generated_grids(seed in 0u64..1_000_000, depth in 1u32..8, dims in 9i32..40) {
        let grid = blob_grid(seed, dims);
        let mut rng = Pcg32::seed_from_u64(seed ^ 0x5eed);
        for spec in [MajorantSpec::Octree { depth }, MajorantSpec::Uniform { cell_voxels: depth * 2 - 1 }] {
            let tree = MajorantTree::build(&grid, spec);
            check_bounds(&grid, &tree, &mut rng, 64, 16);
        }
    }
}

#[test]
fn bounds_hold_on_real_grids() {
    let grids = real_grids();
    if grids.is_empty() {
        eprintln!("no shared data grids found; only generated grids were checked");
        return;
    }
    let mut rng = Pcg32::seed_from_u64(7);
    for (name, grid) in &grids {
        for depth in [1, 3, 6, 9, 16] {
            let tree = MajorantTree::build(grid, MajorantSpec::Octree { depth });
            eprintln!(
                "{name} depth {depth}: {} levels, leaves {:?}, {:.3} s, {} bytes",
                tree.levels(),
                tree.dims(),
                tree.build_seconds(),
                tree.memory_bytes()
            );
            check_bounds(grid, &tree, &mut rng, 2000, 8);
        }
    }
}

/// Brute-force (min, max) over the voxels leaf `c`'s bounds are taken from: for the
/// octree the exact trilinear support of the closed cell, widened by the tree's margin;
/// for the flat grid the support dilated by one voxel on each side.
fn brute_bounds(grid: &Grid, tree: &MajorantTree, c: [i32; 3]) -> (f32, f32) {
    let (lo, hi) = tree.leaf_box(c).unwrap();
    let pad = match tree.spec() {
        MajorantSpec::Octree { .. } => 0,
        MajorantSpec::Uniform { .. } => 1,
    };
    let vlo = [0, 1, 2].map(|a| lo[a].round() as i32 - pad);
    let vhi = [0, 1, 2].map(|a| hi[a].round() as i32 + pad);
    let (mut mn, mut mx) = (f32::INFINITY, f32::NEG_INFINITY);
    for x in vlo[0]..=vhi[0] {
        for y in vlo[1]..=vhi[1] {
            for z in vlo[2]..=vhi[2] {
                let v = grid.voxel([x, y, z]);
                mn = mn.min(v);
                mx = mx.max(v);
            }
        }
    }
    if mx > 0.0 {
        ((mn - tree.margin()).max(0.0), mx + tree.margin())
    } else {
        (mn, mx)
    }
}

/// Segments along random rays are contiguous, in order, cover exactly the ray's overlap
/// with the region, and carry the brute-force bounds of the leaf containing their
/// midpoint. Slivers shorter than 1e-3 voxels (rounding at faces, see `TreeWalk`) are
/// only checked for contiguity.
#[test]
fn walk_covers_rays_once_with_leaf_bounds() {
    let grid = blob_grid(3, 37);
    let mut rng = Pcg32::seed_from_u64(11);
    let mut checked = 0u64;
    let mut merged = 0u64;
    for depth in [1, 2, 4, 6, 8] {
        let tree = MajorantTree::build(&grid, MajorantSpec::Octree { depth });
        let (rlo, rhi) = tree.index_region().unwrap();
        for _ in 0..400 {
            let o = Vec3::new(
                rng.gen_range(-10.0..50.0),
                rng.gen_range(-10.0..50.0),
                rng.gen_range(-10.0..50.0),
            );
            let mut d = Vec3::new(
                rng.gen_range(-1.0..1.0),
                rng.gen_range(-1.0..1.0),
                rng.gen_range(-1.0..1.0),
            );
            // Some axis-parallel rays too.
            if rng.gen_bool(0.1) {
                d.y = 0.0;
                d.z = 0.0;
            }
            if d.length() < 1e-3 {
                continue;
            }
            d *= rng.gen_range(0.3..3.0);
            let (tmin, tmax) = (rng.gen_range(0.0..5.0), rng.gen_range(5.0..100.0));
            // The expected coverage: the slab test in f64.
            let (mut e0, mut e1) = (tmin as f64, tmax as f64);
            for a in 0..3 {
                if d[a] == 0.0 {
                    if !(o[a] >= rlo[a] && o[a] < rhi[a]) {
                        e1 = -1.0;
                    }
                    continue;
                }
                let ta = (rlo[a] as f64 - o[a] as f64) / d[a] as f64;
                let tb = (rhi[a] as f64 - o[a] as f64) / d[a] as f64;
                e0 = e0.max(ta.min(tb));
                e1 = e1.min(ta.max(tb));
            }
            let segs: Vec<_> = tree.walk(o, d, tmin, tmax).collect();
            if !(e0 < e1) || (e1 - e0) < 1e-4 {
                assert!(segs.iter().map(|s| s.t1 - s.t0).sum::<f32>() < 1e-3);
                continue;
            }
            assert!(!segs.is_empty(), "ray {o:?} {d:?} missed the region");
            let scale = 1e-4 * (1.0 + e1.abs());
            assert!(
                (segs[0].t0 as f64 - e0).abs() < scale,
                "{} vs {e0}",
                segs[0].t0
            );
            assert!((segs.last().unwrap().t1 as f64 - e1).abs() < scale);
            for w in segs.windows(2) {
                assert_eq!(w[0].t1, w[1].t0, "gap or overlap");
            }
            for s in &segs {
                assert!(s.t1 > s.t0, "empty or reversed segment {s:?}");
                if ((s.t1 - s.t0) * d.length()) < 1e-3 {
                    continue;
                }
                let mid = o + d * (0.5 * (s.t0 + s.t1));
                let c = tree.leaf_at(mid).expect("midpoint in the region");
                assert_eq!(
                    (s.dmin, s.dmax),
                    brute_bounds(&grid, &tree, c),
                    "depth {depth} segment {s:?} leaf {c:?}"
                );
                checked += 1;
            }
            // Merged empty/constant nodes: fewer segments than leaves crossed.
            merged += segs.len() as u64;
        }
    }
    assert!(checked > 1000, "only {checked} segments checked");
    eprintln!("checked {checked} segments ({merged} in all)");
}

/// Empty space costs one step per merged node: a ray through a grid that is empty
/// except in one corner visits far fewer segments at depth 8 than there are leaves
/// along it.
#[test]
fn empty_space_is_crossed_in_large_steps() {
    let raw = grid_from_fn("density", [64; 3], DVec3::ZERO, 1.0, |p| {
        if p.x < 4.0 && p.y < 4.0 && p.z < 4.0 || p.x > 60.0 && p.y > 60.0 && p.z > 60.0 {
            1.0
        } else {
            0.0
        }
    });
    let grid = Grid::from_raw(&raw).unwrap();
    let tree = MajorantTree::build(&grid, MajorantSpec::Octree { depth: 8 });
    assert_eq!(tree.leaf_edge(), [1.0; 3]);
    let segs: Vec<_> = tree
        .walk(Vec3::new(-1.0, 30.0, 30.0), Vec3::X, 0.0, 100.0)
        .collect();
    assert!(segs.iter().all(|s| s.dmax == 0.0));
    assert!(segs.len() < 12, "{} segments for 66 leaves", segs.len());
}

fn medium(grid: Grid, depth: u32) -> Medium {
    Medium::with_majorants(
        "/test",
        grid,
        DMat4::IDENTITY,
        1.0,
        [0.02, 0.03, 0.06],
        [0.11, 0.12, 0.10],
        0.0,
        MajorantSpec::Octree { depth },
    )
    .unwrap()
}

/// Per-sample estimates of (escape probability of delta, of decomposition, ratio
/// transmittance) along random rays through the medium.
fn estimates(m: &Medium, n: usize, seed: u64) -> [(f64, f64); 3] {
    let mut rng = Pcg32::seed_from_u64(seed);
    let mut sums = [[0f64; 2]; 3];
    let dec = Decomposition::<Avg>::new(0.0, SchemeOptions::default());
    let mut c = Counters::default();
    for _ in 0..n {
        // A fixed ray family: from a random point on the -x face towards +x with a tilt,
        // so every estimate has the same expectation at every depth.
        let mut r = Pcg32::seed_from_u64(rng.gen_range(0..64));
        let o = DVec3::new(-2.0, r.gen_range(2.0..30.0), r.gen_range(2.0..30.0));
        let dir = DVec3::new(1.0, r.gen_range(-0.3..0.3), r.gen_range(-0.3..0.3));
        let ray = m.index_ray(o, dir);
        let q = Query {
            medium: m,
            sigma: &m.sigma,
            ray: &ray,
            tmin: 0.0,
            tmax: 40.0,
            majorant_scale: 1.0,
        };
        let mut w = [1.0f32; 3];
        let a = matches!(Delta.sample(&q, &mut w, &mut rng, &mut c), FreePath::Escape) as u8 as f64;
        let mut w = [1.0f32; 3];
        let b = matches!(dec.sample(&q, &mut w, &mut rng, &mut c), FreePath::Escape) as u8 as f64;
        let t = Ratio.transmittance(&q, &mut rng, &mut c)[0] as f64;
        for (s, x) in sums.iter_mut().zip([a, b, t]) {
            s[0] += x;
            s[1] += x * x;
        }
    }
    sums.map(|[s, s2]| {
        let nf = n as f64;
        let mean = s / nf;
        (mean, ((s2 / nf - mean * mean).max(0.0) / (nf - 1.0)).sqrt())
    })
}

/// Two-sample z-test of each estimate of `e` against `reference`: |z| < 4.
fn assert_agree(what: &str, reference: &[(f64, f64); 3], e: &[(f64, f64); 3]) {
    for (k, name) in ["delta escape", "decomposition escape", "ratio T"]
        .iter()
        .enumerate()
    {
        let ((m0, s0), (m1, s1)) = (reference[k], e[k]);
        let se = (s0 * s0 + s1 * s1).sqrt();
        let z = if se > 0.0 { (m1 - m0) / se } else { 0.0 };
        eprintln!("{what} {name}: {m1:.5} vs {m0:.5} (z {z:.2})");
        assert!(z.abs() < 4.0, "{what} {name}: {m1} vs {m0}, z {z}");
    }
}

/// Delta, decomposition and ratio tracking at depths 2, 4, 6 and 8 agree with depth 1
/// (N = 40000 samples per estimate, seeds 100+depth vs 1; |z| < 4).
#[test]
fn trackers_agree_across_depths() {
    let n = 40_000;
    let grid = || blob_grid(5, 32);
    let reference = estimates(&medium(grid(), 1), n, 1);
    for depth in [2, 4, 6, 8] {
        let e = estimates(&medium(grid(), depth), n, 100 + depth as u64);
        assert_agree(&format!("depth {depth}"), &reference, &e);
    }
}

/// Pruning (`--octree-prune`) only stops the walk higher up: on random rays through a
/// pruned depth-8 tree the segments still tile the ray in order, every point inside a
/// segment has its reconstructed density within the segment's bounds (5 points per
/// segment, 1000 rays), the walk takes fewer steps than unpruned, and delta,
/// decomposition and ratio tracking agree with the depth-1 estimates (N = 40000, seed
/// 300 vs 1, |z| < 4).
#[test]
fn pruned_octree_keeps_bounds_and_estimates() {
    use nimbus::volume::majorant::PruneCost;
    let grid = blob_grid(3, 37);
    let full = MajorantTree::build(&grid, MajorantSpec::Octree { depth: 8 });
    let mut tree = MajorantTree::build(&grid, MajorantSpec::Octree { depth: 8 });
    let merged = tree.prune(PruneCost {
        optical_per_voxel: 0.3,
        crossing_lookups: 4.0,
        residual: false,
    });
    assert!(merged > 0, "nothing pruned");
    let mut rng = Pcg32::seed_from_u64(12);
    let (mut steps_full, mut steps_pruned, mut points) = (0usize, 0usize, 0u64);
    for _ in 0..1000 {
        let o = Vec3::new(-5.0, rng.gen_range(0.0..37.0), rng.gen_range(0.0..37.0));
        let d = Vec3::new(1.0, rng.gen_range(-0.5..0.5), rng.gen_range(-0.5..0.5));
        steps_full += full.walk(o, d, 0.0, 100.0).count();
        let segs: Vec<_> = tree.walk(o, d, 0.0, 100.0).collect();
        steps_pruned += segs.len();
        for w in segs.windows(2) {
            assert_eq!(w[0].t1, w[1].t0, "gap or overlap");
        }
        for s in &segs {
            for k in 1..=5 {
                let t = s.t0 + (s.t1 - s.t0) * k as f32 / 6.0;
                let v = grid.sample_trilinear((o + d * t).to_array());
                assert!(
                    v >= s.dmin - 1e-6 && v <= s.dmax + 1e-6,
                    "density {v} outside {s:?}"
                );
                points += 1;
            }
        }
    }
    assert!(points > 10_000, "only {points} points checked");
    assert!(
        steps_pruned < steps_full,
        "{steps_pruned} vs {steps_full} steps"
    );
    eprintln!("{merged} nodes pruned: {steps_pruned} vs {steps_full} walk steps");

    let n = 40_000;
    let reference = estimates(&medium(blob_grid(5, 32), 1), n, 1);
    let mut m = medium(blob_grid(5, 32), 8);
    assert!(m.prune_majorants(4.0, true) > 0);
    let e = estimates(&m, n, 300);
    assert_agree("pruned", &reference, &e);
}

/// `nimbus bench octree --csv` writes exactly the documented columns, one row per
/// (depth, tracker) with exact integer counts; `render --octree-depth --stats` reports
/// the octree's depth, build time and memory.
#[test]
fn bench_csv_and_render_stats() {
    use std::process::Command;
    let stage = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/cloud/cloud.usda");
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("bench.csv");
    let out = Command::new(env!("CARGO_BIN_EXE_nimbus"))
        .args(["bench", "octree", stage, "--depths", "1,3", "--spp", "1"])
        .args(["--res", "8x6", "--csv"])
        .arg(&csv)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = std::fs::read_to_string(&csv).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(
        lines[0],
        "depth,tracker,cells_visited,density_lookups,lookup_seconds,traversal_seconds,other_seconds,total_seconds"
    );
    assert_eq!(lines.len(), 5);
    for (line, (depth, tracker)) in lines[1..].iter().zip([
        ("1", "delta"),
        ("1", "decomposition"),
        ("3", "delta"),
        ("3", "decomposition"),
    ]) {
        let f: Vec<&str> = line.split(',').collect();
        assert_eq!(f.len(), 8, "{line}");
        assert_eq!((f[0], f[1]), (depth, tracker));
        f[2].parse::<u64>().unwrap();
        assert!(f[3].parse::<u64>().unwrap() > 0);
        // The time split: thread-seconds, present and non-negative.
        for x in &f[4..7] {
            let v: f64 = x.parse().unwrap_or_else(|_| panic!("{line}"));
            assert!(v.is_finite() && v >= 0.0, "{line}");
        }
        assert!(f[7].parse::<f64>().unwrap() > 0.0);
    }
    let stats = dir.path().join("stats.json");
    let out = Command::new(env!("CARGO_BIN_EXE_nimbus"))
        .args([
            "render",
            stage,
            "--spp",
            "1",
            "--res",
            "8x6",
            "--octree-depth",
            "5",
        ])
        .arg("-o")
        .arg(dir.path().join("x.exr"))
        .arg("--stats")
        .arg(&stats)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&stats).unwrap()).unwrap();
    assert_eq!(json["octree_depth"], 5);
    assert_eq!(json["octree_levels"], 5);
    assert!(json["octree_build_seconds"].as_f64().unwrap() >= 0.0);
    assert!(json["octree_memory_bytes"].as_u64().unwrap() > 0);
    assert!(json["cells_visited"].as_u64().unwrap() > 0);
    assert!(json["density_lookups"].as_u64().unwrap() > 0);
    assert!(
        json["lookup_seconds"].is_null(),
        "timers are off by default"
    );

    // `--profile` times the trackers without changing a single random decision: the
    // same seed gives the same counts, and the split is reported.
    let profiled = dir.path().join("profiled.json");
    let out = Command::new(env!("CARGO_BIN_EXE_nimbus"))
        .args(["render", stage, "--spp", "1", "--res", "8x6"])
        .args(["--octree-depth", "5", "--profile", "-o"])
        .arg(dir.path().join("y.exr"))
        .arg("--stats")
        .arg(&profiled)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let p: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&profiled).unwrap()).unwrap();
    for key in [
        "density_lookups",
        "cells_visited",
        "real_collisions",
        "null_collisions",
    ] {
        assert_eq!(p[key], json[key], "{key}");
    }
    for key in [
        "lookup_seconds",
        "traversal_seconds",
        "other_tracker_seconds",
        "timer_empty_region_ns",
    ] {
        let v = p[key]
            .as_f64()
            .unwrap_or_else(|| panic!("{key}: {}", p[key]));
        assert!(v.is_finite() && v >= 0.0, "{key} = {v}");
    }
}
