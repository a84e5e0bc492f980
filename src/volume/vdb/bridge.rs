//! cxx bindings to `cpp/vdb_bridge.cc` (compiled only with `cfg(nimbus_openvdb)`).
//!
//! The C++ side only copies data out of OpenVDB; [`to_raw_grid`] turns the flat
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

    struct FloatGridData {
        name: String,
        class_name: String,
        background: f32,
        /// 3 ints per leaf.
        leaf_origins: Vec<i32>,
        /// 512 values per leaf, x-major.
        leaf_values: Vec<f32>,
        /// 8 words per leaf.
        leaf_masks: Vec<u64>,
        tile_origins: Vec<i32>,
        tile_dims: Vec<i32>,
        tile_values: Vec<f32>,
        tile_active: Vec<u8>,
        /// OpenVDB's (row-vector) index-to-world matrix, row-major, 16 values.
        index_to_world_row_major: Vec<f64>,
    }

    unsafe extern "C++" {
        include!("nimbus/cpp/vdb_bridge.h");

        fn list_grids(path: &str) -> Result<Vec<GridListEntry>>;
        fn read_float_grid(path: &str, lookup_name: &str) -> Result<FloatGridData>;
    }
}

/// Converts the bridge's buffers; `Err` carries a description of an inconsistent shape.
pub(crate) fn to_raw_grid(d: ffi::FloatGridData) -> Result<RawGrid, String> {
    let leaf_count = d.leaf_origins.len() / 3;
    if !d.leaf_origins.len().is_multiple_of(3)
        || d.leaf_values.len() != leaf_count * BRICK_VOXELS
        || d.leaf_masks.len() != leaf_count * 8
    {
        return Err("bridge returned inconsistent leaf buffers".into());
    }
    let tile_count = d.tile_dims.len();
    if d.tile_origins.len() != tile_count * 3
        || d.tile_values.len() != tile_count
        || d.tile_active.len() != tile_count
    {
        return Err("bridge returned inconsistent tile buffers".into());
    }
    if d.index_to_world_row_major.len() != 16 {
        return Err("bridge returned a malformed transform".into());
    }
    let leaves = (0..leaf_count)
        .map(|i| {
            let mut active = [0u64; 8];
            active.copy_from_slice(&d.leaf_masks[i * 8..i * 8 + 8]);
            RawLeaf {
                origin: [
                    d.leaf_origins[i * 3],
                    d.leaf_origins[i * 3 + 1],
                    d.leaf_origins[i * 3 + 2],
                ],
                values: d.leaf_values[i * BRICK_VOXELS..(i + 1) * BRICK_VOXELS].to_vec(),
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
            value: d.tile_values[i],
            active: d.tile_active[i] != 0,
        })
        .collect();
    // Row-major storage of OpenVDB's row-vector matrix is column-major storage of its
    // transpose, which is exactly the column-vector matrix glam wants.
    let mut cols = [0.0f64; 16];
    cols.copy_from_slice(&d.index_to_world_row_major);
    Ok(RawGrid {
        name: d.name,
        class: d.class_name,
        background: d.background,
        leaves,
        tiles,
        index_to_world: DMat4::from_cols_array(&cols),
    })
}
