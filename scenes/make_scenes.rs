//! Generates the example scenes' VDB files with Nimbus' own code (no OpenVDB needed):
//!
//!     cargo run --release --ignore-rust-version --example make_scenes
//!
//! Writes scenes/cloud/cloud.vdb, scenes/chromatic/chromatic.vdb and scenes/fire/fire.vdb
//! (uncompressed float grids that both OpenVDB and Nimbus' own reader read). The .usda files beside
//! them are hand-written.

use glam::DVec3;
use nimbus::volume::procedural::{cumulus, fbm, grid_from_fn};
use nimbus::volume::vdb::{write_float_grid, write_float_grids};
use std::path::Path;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");

    // The cloud: a cumulus, 128³ voxels over [-1, 1]³ (see `cumulus`; `nimbus bench
    // cumulus` renders the same field at production size).
    let n = 128;
    let voxel = 2.0 / n as f64;
    let origin = DVec3::splat(-1.0 + 0.5 * voxel);
    let cloud = grid_from_fn("density", [n, n, n], origin, voxel, cumulus);
    write_float_grid(&root.join("cloud/cloud.vdb"), &cloud)?;
    println!(
        "cloud: {} leaves, {} active voxels",
        cloud.leaves.len(),
        cloud.active_voxel_count()
    );

    // The chromatic medium: a heterogeneous puff, 48³ voxels over [-1, 1]³, density
    // in [0, 1] with strong variation so the spectral schemes differ.
    let n = 48;
    let voxel = 2.0 / n as f64;
    let origin = DVec3::splat(-1.0 + 0.5 * voxel);
    let puff = grid_from_fn("density", [n, n, n], origin, voxel, |p| {
        let r = p.length();
        let shell = (1.0 - r / 0.9).clamp(0.0, 1.0);
        let n = fbm(p * 2.5 + DVec3::new(3.1, 7.7, 1.3), 4);
        (shell * (0.4 + 1.2 * n)).clamp(0.0, 1.0)
    });
    write_float_grid(&root.join("chromatic/chromatic.vdb"), &puff)?;
    println!(
        "chromatic: {} leaves, {} active voxels",
        puff.leaves.len(),
        puff.active_voxel_count()
    );

    // The fire: a plume of smoke (`density`) rising from a hot base, and a `temperature`
    // grid (0 to 1, scaled to Kelvin by nimbus:temperatureScale) hottest in the core
    // of the base and cooling with height; 40 × 64 × 40 voxels over [-0.625, 0.625] ×
    // [-1, 1] × [-0.625, 0.625].
    let voxel = 2.0 / 64.0;
    let dims = [40, 64, 40];
    let origin = DVec3::new(
        -0.625 + 0.5 * voxel,
        -1.0 + 0.5 * voxel,
        -0.625 + 0.5 * voxel,
    );
    // Height h in [0, 1] from the base; the plume's radius narrows with a wobble.
    let plume = |p: DVec3| {
        let h = ((p.y + 1.0) / 2.0).clamp(0.0, 1.0);
        let sway = 0.12 * h * (fbm(DVec3::new(0.0, p.y * 1.5, 5.0), 3) - 0.5);
        let r = ((p.x - sway).powi(2) + p.z * p.z).sqrt();
        let radius = 0.12 + 0.38 * (1.0 - h).powf(0.6) * h.powf(0.15).max(0.35);
        let n = fbm(p * 4.0 + DVec3::new(2.3, -6.0 * h, 8.1), 4);
        (h, (1.0 - r / radius + (n - 0.5) * 0.6).clamp(0.0, 1.0))
    };
    let smoke = grid_from_fn("density", dims, origin, voxel, |p| {
        let (h, s) = plume(p);
        // Thin at the base (flames), denser smoke above.
        let v = s * (0.35 + 0.65 * h);
        if v < 0.02 {
            0.0
        } else {
            v
        }
    });
    let temperature = grid_from_fn("temperature", dims, origin, voxel, |p| {
        let (h, s) = plume(p);
        let v = s.powf(0.7) * (1.0 - h / 0.65).clamp(0.0, 1.0);
        if v < 0.02 {
            0.0
        } else {
            v
        }
    });
    write_float_grids(
        &root.join("fire/fire.vdb"),
        &[smoke.clone(), temperature.clone()],
    )?;
    println!(
        "fire: density {} active voxels, temperature {} active voxels",
        smoke.active_voxel_count(),
        temperature.active_voxel_count()
    );
    Ok(())
}
