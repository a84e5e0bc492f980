//! The pure-Rust reader: `vdb-rs` 0.6, behind guards.
//!
//! vdb-rs reads plain float grids bit-identically to OpenVDB, but as published it
//! aborts the process on half-float files, silently returns empty trees for Vec3s
//! grids, panics on transforms other than (uniform) scale(-translate) maps, never
//! rejects a wrong magic number and ignores root-node tiles. So this module only
//! calls it for grids that [`validate`](super::validate) has shown it can read, takes
//! the background and root tiles from the validated header, and wraps the call in
//! `catch_unwind` as a second line of defence.

use super::validate::{FileInfo, GridDesc};
use crate::volume::grid::{RawGrid, RawLeaf, RawTile, BRICK_VOXELS};
use std::io::{Read, Seek};
use std::panic::{catch_unwind, AssertUnwindSafe};

/// Maps vdb-rs reads without panicking (see `VdbReader::read_transform`).
const SUPPORTED_MAPS: [&str; 3] = [
    "UniformScaleMap",
    "UniformScaleTranslateMap",
    "ScaleTranslateMap",
];
/// vdb-rs reaches an unimplemented branch (a todo macro) before 216 and mis-indexes internal-node values before 222.
const MIN_VERSION: u32 = 222;

/// Why vdb-rs cannot read `desc`, if it cannot. The message ends with the advice to
/// install OpenVDB, which reads all of these.
pub(crate) fn unsupported_reason(info: &FileInfo, desc: &GridDesc) -> Option<String> {
    let why = if desc.half_float {
        format!("grid {:?} stores half floats", desc.name)
    } else if !desc.instance_parent.is_empty() {
        format!(
            "grid {:?} is an instance of grid {:?}",
            desc.name, desc.instance_parent
        )
    } else if info.file_version < MIN_VERSION {
        format!(
            "file format version {} is older than {MIN_VERSION}",
            info.file_version
        )
    } else if !SUPPORTED_MAPS.contains(&desc.map_type.as_str()) {
        format!("grid {:?} has a {} transform", desc.name, desc.map_type)
    } else if desc.root.is_none() {
        format!("grid {:?} has an unreadable tree header", desc.name)
    } else {
        return None;
    };
    Some(format!(
        "{why}, which the vdb-rs reader does not support; install OpenVDB (libopenvdb-dev) \
         and rebuild Nimbus to read this file"
    ))
}

/// Reads the float grid `desc` with vdb-rs. `source` must be the validated file.
pub(crate) fn read_float_grid<R: Read + Seek>(
    source: R,
    info: &FileInfo,
    desc: &GridDesc,
) -> Result<RawGrid, String> {
    if let Some(why) = unsupported_reason(info, desc) {
        return Err(why);
    }
    let (Some(root_info), Some(index_to_world)) = (desc.root.as_ref(), desc.index_to_world) else {
        return Err("internal error: grid header was not parsed".into());
    };
    let result = catch_unwind(AssertUnwindSafe(|| -> Result<RawGrid, String> {
        let mut reader = vdb_rs::VdbReader::new(source).map_err(|e| format!("vdb-rs: {e}"))?;
        let grid = reader
            .read_grid::<f32>(&desc.unique_name)
            .map_err(|e| format!("vdb-rs: {e}"))?;
        convert(&grid.tree, root_info.background)
    }));
    let mut raw = match result {
        Ok(r) => r?,
        Err(panic) => {
            let msg = panic
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| panic.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "unknown panic".into());
            let mut msg: String = msg.chars().take(512).collect();
            msg.insert_str(0, "vdb-rs failed: ");
            return Err(msg);
        }
    };
    raw.name = desc.name.clone();
    raw.class = desc.class.clone();
    raw.index_to_world = index_to_world;
    // vdb-rs skips root tiles; the validator read them.
    raw.tiles.extend(root_info.tiles.iter().cloned());
    Ok(raw)
}

/// vdb-rs tree → RawGrid leaves and internal-node tiles, with shape checks.
fn convert(tree: &vdb_rs::Tree<f32>, background: f32) -> Result<RawGrid, String> {
    use vdb_rs::{Index, Node};
    let mut leaves = Vec::new();
    let mut tiles = Vec::new();
    let mut tile = |origin: [i32; 3], dim: i32, value: f32, active: bool| {
        // Same rule as the C++ bridge: inactive background tiles carry nothing.
        if active || value != background {
            tiles.push(RawTile {
                origin,
                dim,
                value,
                active,
            });
        }
    };
    for n5 in &tree.root_nodes {
        if n5.data.len() != 32768 || n5.child_mask.len() != 32768 {
            return Err("vdb-rs returned a malformed internal node".into());
        }
        for idx in n5.child_mask.iter_zeros() {
            let o = n5.offset_to_global_coord(Index(idx as u32)).0;
            tile([o.x, o.y, o.z], 128, n5.data[idx], n5.value_mask[idx]);
        }
        for idx in n5.child_mask.iter_ones() {
            let n4 = n5
                .nodes
                .get(&(idx as u32))
                .ok_or("vdb-rs lost an internal node")?;
            if n4.data.len() != 4096 || n4.child_mask.len() != 4096 {
                return Err("vdb-rs returned a malformed internal node".into());
            }
            for i in n4.child_mask.iter_zeros() {
                let o = n4.offset_to_global_coord(Index(i as u32)).0;
                tile([o.x, o.y, o.z], 8, n4.data[i], n4.value_mask[i]);
            }
            for i in n4.child_mask.iter_ones() {
                let leaf = n4.nodes.get(&(i as u32)).ok_or("vdb-rs lost a leaf node")?;
                let words = leaf.value_mask.as_raw_slice();
                if leaf.buffer.len() != BRICK_VOXELS || words.len() != 8 {
                    return Err("vdb-rs returned a malformed leaf node".into());
                }
                let mut active = [0u64; 8];
                active.copy_from_slice(words);
                leaves.push(RawLeaf {
                    origin: [leaf.origin.x, leaf.origin.y, leaf.origin.z],
                    values: leaf.buffer.clone(),
                    active,
                });
            }
        }
    }
    Ok(RawGrid {
        name: String::new(),
        class: String::new(),
        background,
        leaves,
        tiles,
        index_to_world: glam::DMat4::IDENTITY,
    })
}
