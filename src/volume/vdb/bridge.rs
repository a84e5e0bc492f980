//! cxx bindings to `cpp/vdb_bridge.cc` (compiled only with `cfg(nimbus_openvdb)`).
//!
//! The C++ side only copies data out of OpenVDB; [`to_raw_grids`] turns the flat
//! buffers into a [`RawGrid`] and checks their shapes rather than trusting them.

use crate::volume::grid::{RawGrid, RawLeaf, RawTile, BRICK_VOXELS};
use glam::DMat4;

#[cxx::bridge(namespace = "nimbus_vdb")]
pub(crate) mod ffi {
    struct GridListEntry {
        name: String,
        value_type: String,
        /// `file_voxel_count` metadata, -1 when absent.
        active_voxels: i64,
    }

    /// A grid's buffers, with N floats per value: 1 for a float grid, 3 (x, y, z) for
    /// a Vec3s grid.
    struct GridData {
        name: String,
        class_name: String,
        /// N values.
        background: Vec<f32>,
        /// 3 ints per leaf.
        leaf_origins: Vec<i32>,
        /// N × 512 values per leaf, x-major, components interleaved.
        leaf_values: Vec<f32>,
        /// 8 words per leaf.
        leaf_masks: Vec<u64>,
        tile_origins: Vec<i32>,
        tile_dims: Vec<i32>,
        /// N values per tile.
        tile_values: Vec<f32>,
        tile_active: Vec<u8>,
        /// OpenVDB's (row-vector) index-to-world matrix, row-major, 16 values.
        index_to_world_row_major: Vec<f64>,
    }

    unsafe extern "C++" {
        include!("nimbus/cpp/vdb_bridge.h");

        fn list_grids(path: &str) -> Result<Vec<GridListEntry>>;
        fn read_float_grid(path: &str, lookup_name: &str) -> Result<GridData>;
        fn read_vec3s_grid(path: &str, lookup_name: &str) -> Result<GridData>;
        /// OpenVDB's own in-memory size (`GridBase::memUsage`) of a float grid.
        fn float_grid_mem_usage(path: &str, lookup_name: &str) -> Result<u64>;
    }
}

/// Converts the bridge's buffers of `N` interleaved floats per value into `N` float
/// grids of one topology (one for a float grid, x, y, z for a Vec3s grid); `Err`
/// describes an inconsistent shape.
pub(crate) fn to_raw_grids<const N: usize>(d: ffi::GridData) -> Result<[RawGrid; N], String> {
    let leaf_count = d.leaf_origins.len() / 3;
    if !d.leaf_origins.len().is_multiple_of(3)
        || d.leaf_values.len() != leaf_count * BRICK_VOXELS * N
        || d.leaf_masks.len() != leaf_count * 8
    {
        return Err("bridge returned inconsistent leaf buffers".into());
    }
    let tile_count = d.tile_dims.len();
    if d.tile_origins.len() != tile_count * 3
        || d.tile_values.len() != tile_count * N
        || d.tile_active.len() != tile_count
    {
        return Err("bridge returned inconsistent tile buffers".into());
    }
    if d.background.len() != N {
        return Err("bridge returned a malformed background".into());
    }
    if d.index_to_world_row_major.len() != 16 {
        return Err("bridge returned a malformed transform".into());
    }
    // Row-major storage of OpenVDB's row-vector matrix is column-major storage of its
    // transpose, which is exactly the column-vector matrix glam wants.
    let mut cols = [0.0f64; 16];
    cols.copy_from_slice(&d.index_to_world_row_major);
    let index_to_world = DMat4::from_cols_array(&cols);
    Ok(std::array::from_fn(|c| {
        use rayon::prelude::*;
        let leaves = (0..leaf_count)
            .into_par_iter()
            .with_min_len(256)
            .map(|i| {
                let mut active = [0u64; 8];
                active.copy_from_slice(&d.leaf_masks[i * 8..i * 8 + 8]);
                let values = &d.leaf_values[i * BRICK_VOXELS * N..(i + 1) * BRICK_VOXELS * N];
                RawLeaf {
                    origin: [
                        d.leaf_origins[i * 3],
                        d.leaf_origins[i * 3 + 1],
                        d.leaf_origins[i * 3 + 2],
                    ],
                    values: if N == 1 {
                        values.to_vec()
                    } else {
                        values.iter().skip(c).step_by(N).copied().collect()
                    },
                    active,
                }
            })
            .collect();
        let tiles = (0..tile_count)
            .map(|i| RawTile {
                origin: [
                    d.tile_origins[i * 3],
                    d.tile_origins[i * 3 + 1],
                    d.tile_origins[i * 3 + 2],
                ],
                dim: d.tile_dims[i],
                value: d.tile_values[i * N + c],
                active: d.tile_active[i] != 0,
            })
            .collect();
        RawGrid {
            name: d.name.clone(),
            class: d.class_name.clone(),
            background: d.background[c],
            leaves,
            tiles,
            index_to_world,
        }
    }))
}
