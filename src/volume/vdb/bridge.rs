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
        /// One value.
        background: Vec<f32>,
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

    /// As [`FloatGridData`] with three floats (x, y, z) per value: `background` 3,
    /// `leaf_values` 3 × 512 per leaf, `tile_values` 3 per tile.
    struct Vec3sGridData {
        name: String,
        class_name: String,
        background: Vec<f32>,
        leaf_origins: Vec<i32>,
        leaf_values: Vec<f32>,
        leaf_masks: Vec<u64>,
        tile_origins: Vec<i32>,
        tile_dims: Vec<i32>,
        tile_values: Vec<f32>,
        tile_active: Vec<u8>,
        index_to_world_row_major: Vec<f64>,
    }

    unsafe extern "C++" {
        include!("nimbus/cpp/vdb_bridge.h");

        fn list_grids(path: &str) -> Result<Vec<GridListEntry>>;
        fn read_float_grid(path: &str, lookup_name: &str) -> Result<FloatGridData>;
        fn read_vec3s_grid(path: &str, lookup_name: &str) -> Result<Vec3sGridData>;
    }
}

/// Converts the bridge's buffers; `Err` carries a description of an inconsistent shape.
pub(crate) fn to_raw_grid(d: ffi::FloatGridData) -> Result<RawGrid, String> {
    let parts = Parts {
        name: d.name,
        class: d.class_name,
        background: &d.background,
        leaf_origins: &d.leaf_origins,
        leaf_values: &d.leaf_values,
        leaf_masks: &d.leaf_masks,
        tile_origins: &d.tile_origins,
        tile_dims: &d.tile_dims,
        tile_values: &d.tile_values,
        tile_active: &d.tile_active,
        index_to_world_row_major: &d.index_to_world_row_major,
    };
    let [grid] = split::<1>(parts)?;
    Ok(grid)
}

/// Converts a Vec3s grid's buffers into one float grid per component (same topology).
pub(crate) fn to_raw_vec3_grid(d: ffi::Vec3sGridData) -> Result<[RawGrid; 3], String> {
    split::<3>(Parts {
        name: d.name,
        class: d.class_name,
        background: &d.background,
        leaf_origins: &d.leaf_origins,
        leaf_values: &d.leaf_values,
        leaf_masks: &d.leaf_masks,
        tile_origins: &d.tile_origins,
        tile_dims: &d.tile_dims,
        tile_values: &d.tile_values,
        tile_active: &d.tile_active,
        index_to_world_row_major: &d.index_to_world_row_major,
    })
}

/// The buffers of either bridge struct.
struct Parts<'a> {
    name: String,
    class: String,
    background: &'a [f32],
    leaf_origins: &'a [i32],
    leaf_values: &'a [f32],
    leaf_masks: &'a [u64],
    tile_origins: &'a [i32],
    tile_dims: &'a [i32],
    tile_values: &'a [f32],
    tile_active: &'a [u8],
    index_to_world_row_major: &'a [f64],
}

/// Splits buffers of `N` interleaved floats per value into `N` float grids.
fn split<const N: usize>(d: Parts) -> Result<[RawGrid; N], String> {
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
    cols.copy_from_slice(d.index_to_world_row_major);
    let index_to_world = DMat4::from_cols_array(&cols);
    Ok(std::array::from_fn(|c| {
        let leaves = (0..leaf_count)
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
                    values: values.iter().skip(c).step_by(N).copied().collect(),
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
            class: d.class.clone(),
            background: d.background[c],
            leaves,
            tiles,
            index_to_world,
        }
    }))
}
