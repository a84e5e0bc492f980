//! Volumes in a shot (issue 18, acceptance): a pxr-authored stage
//! (`tests/fixtures/make_shot_stage.py`) with a homogeneous cube volume seen from far
//! down −Z, a holdout cube in front of its left part, a wall between the sun (shining
//! along −X) and its upper half, a ground quad under it, and a sphere light inside a
//! closed box. Rendered with single scattering (`--max-depth 1`), delta tracking, seed
//! 7, 48×48 pixels.

use glam::DVec3;
use std::path::Path;

mod common;

use common::cli::{channel, channels, nimbus, stderr};
use common::data::pxr_fixtures;

/// The stage's fixtures and the slab VDB: a 32³ grid of density 1 over [-1, 1]³.
fn shot() -> Option<tempfile::TempDir> {
    let (dir, _) = pxr_fixtures(
        "make_shot_stage.py",
        &["pxr"],
        common::data::SETUP_PYTHON,
        true,
    )?;
    let vs = 2.0 / 32.0;
    let grid = nimbus::volume::procedural::grid_from_fn(
        "density",
        [32; 3],
        DVec3::splat(-1.0 + 0.5 * vs),
        vs,
        |_| 1.0,
    );
    nimbus::volume::vdb::write_float_grid(&dir.path().join("slab.vdb"), &grid).unwrap();
    Some(dir)
}

const SPP: u32 = 64;

fn render(stage: &Path, out: &Path) -> Vec<(String, Vec<f32>)> {
    let spp = SPP.to_string();
    let o = nimbus(&[
        "render",
        stage.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--spp",
        &spp,
        "--seed",
        "7",
        "--max-depth",
        "1",
        "--tracker",
        "delta",
        "--aovs",
        "lightgroup:/World/Bulb,lightgroup:/World/Sun",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    channels(out)
}

/// World (x, y) of pixel (px, py)'s centre on the plane z = 0: the camera at z = 50
/// sees [-1.5, 1.5]² there over 48×48 pixels (y up, rows down).
fn pixel_xy(px: usize, py: usize) -> (f64, f64) {
    let s = 3.0 / 48.0;
    (-1.5 + (px as f64 + 0.5) * s, 1.5 - (py as f64 + 0.5) * s)
}

#[test]
fn holdouts_hide_shadow_and_enclose() {
    let Some(dir) = shot() else { return };
    let d = dir.path();
    let with = render(&d.join("shot.usda"), &d.join("with.exr"));
    let open = render(&d.join("shot_no_wall.usda"), &d.join("no_wall.exr"));
    let no_box = render(&d.join("shot_no_box.usda"), &d.join("no_box.exr"));
    let (r, a, bulb, sun) = (
        channel(&with, "R"),
        channel(&with, "A"),
        channel(&with, "lightgroup__World_Bulb.R"),
        channel(&with, "lightgroup__World_Sun.R"),
    );
    let (r_open, bulb_open) = (
        channel(&open, "R"),
        channel(&no_box, "lightgroup__World_Bulb.R"),
    );

    let (mut hidden, mut shadowed, mut lit) = (0, 0, 0);
    let (mut alpha_sum, mut alpha_n) = (0.0, 0usize);
    for py in 0..48 {
        for px in 0..48 {
            let i = py * 48 + px;
            let (x, y) = pixel_xy(px, py);
            // The front cube (edge 1 at (-1, 0, 3), 47 units from the camera) covers
            // x ∈ [-1.6, -0.53], |y| < 0.53 on the plane z = 0; these pixels lie inside.
            if (-1.4..=-0.75).contains(&x) && y.abs() < 0.35 {
                assert_eq!(
                    (r[i], a[i]),
                    (0.0, 0.0),
                    "pixel {px},{py} behind the front cube"
                );
                hidden += 1;
                continue;
            }
            // Its edge, and what lies outside the slab, take no part below.
            let near_cube = (-1.7..=-0.45).contains(&x) && y.abs() < 0.6;
            if near_cube || x.abs() > 0.9 || y.abs() > 0.9 {
                continue;
            }
            // Inside the slab, uncovered: the camera ray crosses 2 units of σt = 1.
            alpha_sum += a[i] as f64;
            alpha_n += 1;
            if y > 0.1 {
                // The wall blocks the sun for y > 0, and the box the bulb: nothing.
                assert_eq!(r[i], 0.0, "pixel {px},{py} in the wall's shadow");
                assert!(
                    r_open[i] > 0.0,
                    "pixel {px},{py} is black without the wall too"
                );
                shadowed += 1;
            } else if y < -0.1 {
                // Below the wall's edge nothing changes: the same shadow rays are traced
                // with the same random numbers, so the pixel is the same bit for bit.
                assert_eq!(r[i].to_bits(), r_open[i].to_bits(), "pixel {px},{py} lit");
                assert!(r[i] > 0.0);
                lit += 1;
            }
        }
    }
    assert!(
        hidden >= 50 && shadowed >= 200 && lit >= 200,
        "{hidden} {shadowed} {lit}"
    );
    // The enclosed bulb lights nothing; without the box it does (the check has power).
    assert!(
        bulb.iter().all(|&v| v == 0.0),
        "light escapes the closed box"
    );
    assert!(bulb_open.iter().any(|&v| v > 0.0));
    assert!(sun.iter().any(|&v| v > 0.0));

    // Alpha against the analytic transmittance: each sample's alpha is 1 when delta
    // tracking collides on the camera ray, with probability p = 1 − e^{−2} (the
    // trilinear ramps at the faces integrate to the same optical depth 2; the rays
    // are within 1.3° of parallel, which lengthens the path by < 3e-4). The mean over
    // n = pixels × SPP independent Bernoulli samples has standard error √(p(1−p)/n).
    let p = 1.0 - (-2.0f64).exp();
    let n = (alpha_n as u32 * SPP) as f64;
    let mean = alpha_sum / alpha_n as f64;
    let z = (mean - p) / (p * (1.0 - p) / n).sqrt();
    assert!(
        z.abs() < 4.0,
        "alpha {mean} vs {p}: z = {z:.2} over {n} samples"
    );
}

/// The ground, the wall, the front cube and the box are read as holdouts; `info` and
/// the stats report them.
#[test]
fn stats_report_the_holdouts() {
    let Some(dir) = shot() else { return };
    let d = dir.path();
    let stats = d.join("s.json");
    let o = nimbus(&[
        "render",
        d.join("shot.usda").to_str().unwrap(),
        "-o",
        d.join("x.exr").to_str().unwrap(),
        "--spp",
        "1",
        "--res",
        "8x8",
        "--stats",
        stats.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&stats).unwrap()).unwrap();
    let h = &v["holdouts"];
    assert_eq!(h["meshes"], 4, "{h}");
    // Two quads (2 triangles each) and two cubes (12 each).
    assert_eq!(h["triangles"], 28, "{h}");
    assert!(h["bytes"].as_u64().unwrap() > 0 && h["build_seconds"].as_f64().unwrap() >= 0.0);
}
