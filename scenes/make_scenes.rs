//! Generates the example scenes' VDB files with Nimbus' own code (no OpenVDB needed):
//!
//!     cargo run --release --ignore-rust-version --example make_scenes
//!
//! Writes scenes/cloud/cloud.vdb and scenes/chromatic/chromatic.vdb (uncompressed float
//! grids that both OpenVDB and vdb-rs read). The .usda files beside them are hand-written.

use glam::DVec3;
use nimbus::volume::procedural::{cloud_density, fbm, grid_from_fn};
use nimbus::volume::vdb::write_float_grid;
use std::path::Path;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");

    // The cloud: 64³ voxels over [-1, 1]³.
    let n = 64;
    let voxel = 2.0 / n as f64;
    let origin = DVec3::splat(-1.0 + 0.5 * voxel);
    let cloud = grid_from_fn("density", [n, n, n], origin, voxel, cloud_density);
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
    Ok(())
}
