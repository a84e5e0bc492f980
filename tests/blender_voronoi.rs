//! Blender's Voronoi Texture (3D; F1 Euclidean, and since stop 64 F2, Smooth
//! F1, Distance to Edge, N-Sphere Radius and the other metrics; since stop 65 with
//! Detail) against Blender 5.0.1:
//! `tests/fixtures/blender_voronoi_values.py` has Geometry Nodes evaluate the node at
//! random points (stored in point attributes, read back with foreach_get) and
//! `nimbus::shader::voronoi` must give the same Distance, Color and Position.
//!
//! Geometry Nodes runs blenlib's Voronoi, the same algorithm as Cycles' SVM
//! (`kernel/svm/voronoi.h`, the PCG hash of `util/hash.h`). Measured for F1: 7 sets of
//! 20,000 points, every row equal to the bit in all 10 values; the other features'
//! figures are printed (docs/shaders.md quotes them). The tolerances allow what a
//! different floating-point order could change: a relative 1e-5 per value, and at most
//! 1 in 1000 points taking another, equally near point (counted by Color; the distances
//! must still agree).
//!
//! The Python that imports bpy is `NIMBUS_BPY_PYTHON`; without it the test prints one
//! `SKIPPED` line, or fails under `NIMBUS_REQUIRE_DATA=1`.

mod common;

use std::path::Path;

use nimbus::shader::voronoi::{VoronoiFeature, VoronoiMetric, VoronoiTexture};

const N: usize = 20_000;

struct Case {
    name: &'static str,
    points: &'static str,
    seed: u64,
    node: VoronoiTexture,
}

fn cases() -> Vec<Case> {
    let node = |scale, randomness, normalize| VoronoiTexture {
        scale,
        randomness,
        normalize,
        ..Default::default()
    };
    let with = |feature, smoothness, n: VoronoiTexture| VoronoiTexture {
        feature,
        smoothness,
        ..n
    };
    let metric = |metric, n: VoronoiTexture| VoronoiTexture { metric, ..n };
    let octaves = |detail, roughness, lacunarity, n: VoronoiTexture| VoronoiTexture {
        detail,
        roughness,
        lacunarity,
        ..n
    };
    let case = |name, points, seed, node| Case {
        name,
        points,
        seed,
        node,
    };
    use VoronoiFeature::*;
    use VoronoiMetric::*;
    vec![
        case("defaults", "box", 1, node(5.0, 1.0, false)),
        case("scale_1_7_random_0_4", "box", 2, node(1.7, 0.4, false)),
        case("randomness_0", "box", 3, node(3.0, 0.0, false)),
        case("normalize", "box", 4, node(2.0, 0.8, true)),
        case("negative", "negative", 5, node(1.3, 1.0, false)),
        case("large", "large", 6, node(0.9, 0.7, false)),
        case("negative_scale", "box", 7, node(-2.5, 0.6, false)),
        // Stop 64: the other features.
        case("f2", "box", 8, with(F2, 1.0, node(5.0, 1.0, false))),
        case(
            "f2_normalize",
            "negative",
            9,
            with(F2, 1.0, node(2.0, 0.8, true)),
        ),
        case(
            "smooth_f1",
            "box",
            10,
            with(SmoothF1, 1.0, node(3.0, 1.0, false)),
        ),
        case(
            "smooth_f1_0_3_normalize",
            "box",
            11,
            with(SmoothF1, 0.3, node(2.0, 0.7, true)),
        ),
        case(
            "distance_to_edge",
            "box",
            12,
            with(DistanceToEdge, 1.0, node(3.0, 1.0, false)),
        ),
        case(
            "distance_to_edge_normalize",
            "negative",
            13,
            with(DistanceToEdge, 1.0, node(1.3, 0.6, true)),
        ),
        case(
            "n_sphere_radius",
            "box",
            14,
            with(NSphereRadius, 1.0, node(2.5, 0.9, false)),
        ),
        // Stop 64: the other metrics.
        case(
            "f1_manhattan",
            "box",
            15,
            metric(Manhattan, node(2.0, 1.0, false)),
        ),
        case(
            "f1_chebychev_normalize",
            "box",
            16,
            metric(Chebychev, node(3.0, 0.7, true)),
        ),
        case(
            "f1_minkowski_0_5",
            "negative",
            17,
            metric(Minkowski(0.5), node(1.5, 1.0, false)),
        ),
        case(
            "f2_minkowski_2_5_normalize",
            "box",
            18,
            metric(Minkowski(2.5), with(F2, 1.0, node(2.0, 0.9, true))),
        ),
        case(
            "smooth_f1_manhattan",
            "box",
            19,
            metric(Manhattan, with(SmoothF1, 0.8, node(3.0, 1.0, false))),
        ),
        // Stop 65: Detail above 0 (fractal Voronoi), a fractional Detail blending in a
        // partial octave.
        case(
            "f1_detail_2",
            "box",
            20,
            octaves(2.0, 0.5, 2.0, node(2.0, 1.0, false)),
        ),
        case(
            "f1_detail_2_5_normalize",
            "box",
            21,
            octaves(2.5, 0.6, 2.3, node(1.5, 0.8, true)),
        ),
        case(
            "f2_detail_1_5_chebychev",
            "negative",
            22,
            metric(
                Chebychev,
                octaves(1.5, 0.7, 1.8, with(F2, 1.0, node(1.2, 1.0, false))),
            ),
        ),
        case(
            "smooth_f1_detail_1",
            "box",
            23,
            octaves(1.0, 0.5, 2.0, with(SmoothF1, 0.6, node(2.0, 1.0, false))),
        ),
        case(
            "distance_to_edge_detail_3_normalize",
            "box",
            24,
            octaves(
                3.0,
                0.5,
                2.0,
                with(DistanceToEdge, 1.0, node(2.0, 1.0, true)),
            ),
        ),
        case(
            "distance_to_edge_detail_1_5",
            "negative",
            25,
            octaves(
                1.5,
                0.8,
                2.5,
                with(DistanceToEdge, 1.0, node(1.1, 0.9, false)),
            ),
        ),
    ]
}

/// The node's `distance` identifier and Exponent.
fn metric_name(m: VoronoiMetric) -> (&'static str, f32) {
    match m {
        VoronoiMetric::Euclidean => ("EUCLIDEAN", 0.5),
        VoronoiMetric::Manhattan => ("MANHATTAN", 0.5),
        VoronoiMetric::Chebychev => ("CHEBYCHEV", 0.5),
        VoronoiMetric::Minkowski(e) => ("MINKOWSKI", e),
    }
}

/// The node's `feature` identifier.
fn feature_name(f: VoronoiFeature) -> &'static str {
    match f {
        VoronoiFeature::F1 => "F1",
        VoronoiFeature::F2 => "F2",
        VoronoiFeature::SmoothF1 => "SMOOTH_F1",
        VoronoiFeature::DistanceToEdge => "DISTANCE_TO_EDGE",
        VoronoiFeature::NSphereRadius => "N_SPHERE_RADIUS",
    }
}

fn cases_json(cases: &[Case]) -> String {
    let items: Vec<String> = cases
        .iter()
        .map(|c| {
            format!(
                "{{\"name\": \"{}\", \"points\": \"{}\", \"seed\": {}, \"n\": {N}, \
                 \"scale\": {:?}, \"randomness\": {:?}, \"normalize\": {}, \
                 \"feature\": \"{}\", \"smoothness\": {:?}, \"distance\": \"{}\", \
                 \"exponent\": {:?}, \"detail\": {:?}, \"roughness\": {:?}, \
                 \"lacunarity\": {:?}}}",
                c.name,
                c.points,
                c.seed,
                c.node.scale,
                c.node.randomness,
                c.node.normalize,
                feature_name(c.node.feature),
                c.node.smoothness,
                metric_name(c.node.metric).0,
                metric_name(c.node.metric).1,
                c.node.detail,
                c.node.roughness,
                c.node.lacunarity
            )
        })
        .collect();
    format!("[\n{}\n]\n", items.join(",\n"))
}

fn read_rows(path: &Path) -> Vec<[f32; 10]> {
    let bytes = std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    assert_eq!(bytes.len(), N * 40, "{}: size", path.display());
    bytes
        .chunks_exact(40)
        .map(|row| {
            std::array::from_fn(|i| f32::from_le_bytes(row[4 * i..4 * i + 4].try_into().unwrap()))
        })
        .collect()
}

/// Relative error with a floor of 1e-3 on the reference's magnitude (Distance reaches
/// 0 at the points themselves).
fn rel(ours: f32, theirs: f32) -> f64 {
    (ours as f64 - theirs as f64).abs() / (theirs.abs() as f64).max(1e-3)
}

#[test]
fn voronoi_f1_matches_blender() {
    let Some(python) = common::data::bpy_python("bpy, numpy") else {
        return;
    };
    let cases = cases();
    let dir = tempfile::tempdir().expect("temp dir");
    let spec = dir.path().join("cases.json");
    std::fs::write(&spec, cases_json(&cases)).unwrap();
    common::data::run_fixture(
        python,
        "blender_voronoi_values.py",
        [spec.as_os_str(), dir.path().as_os_str()],
    );
    let mut failed = Vec::new();
    for case in &cases {
        let rows = read_rows(&dir.path().join(format!("{}.f32", case.name)));
        let (mut d_rel, mut c_rel, mut p_rel) = (0f64, 0f64, 0f64);
        let (mut other_point, mut equal) = (0, 0);
        // Smooth F1's distance before Normalize divides it.
        let norm = match case.node.normalize {
            true => case.node.max_distance() as f64,
            false => 1.0,
        };
        for r in &rows {
            let mut v = case.node.eval([r[0], r[1], r[2]]);
            if case.node.feature == VoronoiFeature::NSphereRadius {
                // The fixture writes Radius in Distance's column.
                v.distance = v.radius;
            }
            if case.node.feature == VoronoiFeature::SmoothF1 || case.node.is_fractal() {
                // Smooth F1 blends with Cycles' mix, a + t (b − a), where Geometry Nodes
                // takes blenlib's a (1 − t) + b t: each step whose h is not 0 rounds
                // its blend differently, by up to an ulp of operands below 8 (the
                // distance's start) — 2⁻²³·8 ≈ 1e-6 — and the errors carry with weight
                // 1 − h ≤ 1. Only points within 2k of the running distance get h > 0, a
                // few of the 125; the tolerance, the 1e-5 below in absolute terms (the
                // position in the scaled cell units, the distance before Normalize),
                // allows ten such steps. (With blenlib's form every row was equal to the
                // bit; measured: Distance 2.6e-7, Color 5.4e-7, Position 1.4e-6.)
                //
                // Fractal Voronoi (stop 65) blends the octaves' positions, and a partial
                // octave's distance and colour, with the same two forms of mix; the
                // octaves' sums are computed alike. An ulp grows with the position's
                // magnitude (cell units, up to 48 on the "negative" points), so its
                // error is measured against max(8, |position|) / 8: the same 1e-5 of
                // ten ulps of 8.
                let abs = |a: f32, b: f32| (a as f64 - b as f64).abs();
                d_rel = d_rel.max(abs(v.distance, r[3]) * norm);
                let scale = case.node.scale.abs() as f64;
                for a in 0..3 {
                    c_rel = c_rel.max(abs(v.color[a], r[4 + a]));
                    let magnitude = (r[7 + a].abs() as f64 * scale / 8.0).max(1.0);
                    p_rel = p_rel.max(abs(v.position[a], r[7 + a]) * scale / magnitude);
                }
                continue;
            }
            let dr = rel(v.distance, r[3]);
            d_rel = d_rel.max(dr);
            let same_cell = (0..3).all(|a| rel(v.color[a], r[4 + a]) < 1e-3);
            if !same_cell {
                // Another point, as near to float precision.
                other_point += 1;
                continue;
            }
            for a in 0..3 {
                c_rel = c_rel.max(rel(v.color[a], r[4 + a]));
                p_rel = p_rel.max(rel(v.position[a], r[7 + a]));
            }
            let ours = [v.distance, v.color[0], v.color[1], v.color[2]]
                .into_iter()
                .chain(v.position);
            if ours.zip(&r[3..]).all(|(a, b)| a.to_bits() == b.to_bits()) {
                equal += 1;
            }
        }
        println!(
            "{:<22} max rel error: Distance {d_rel:.2e}, Color {c_rel:.2e}, Position {p_rel:.2e}; {equal}/{N} rows equal to the bit; {other_point} took another (equally near) point",
            case.name
        );
        if d_rel >= 1e-5 || c_rel >= 1e-5 || p_rel >= 1e-5 || other_point > N / 1000 {
            failed.push(case.name);
        }
    }
    assert!(failed.is_empty(), "{failed:?}");
}
