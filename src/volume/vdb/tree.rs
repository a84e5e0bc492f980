//! Nimbus' own OpenVDB tree reader: the pure-Rust reader ([`Reader::Rust`]).
//!
//! A `Tree_float_5_4_3` or `Tree_vec3s_5_4_3` is a root node (a sorted map of tiles
//! and children), internal nodes of 32³ and 16³ slots, and 8³ leaves. A grid's bytes
//! hold it in two passes, as OpenVDB's `Tree::readTopology` and `Tree::readBuffers`
//! write it: first the topology (root tiles; each internal node's masks and tile
//! values, then its children; each leaf's value mask), then every leaf's values in the
//! same order. This module reads both passes from one in-memory copy of the grid's
//! bytes (see [`stream`](super::stream)) and returns the [`RawGrid`]s the OpenVDB
//! bridge returns, in the same order; [`values`](super::values) decodes each node's
//! value record.
//!
//! [`validate`](super::validate) has already checked the header, the transform and
//! every size in the tree, but this reader checks each read again: it must never
//! panic or read out of bounds, even if the file changed in between.
//!
//! [`Reader::Rust`]: super::Reader::Rust

use super::stream::{bit, Stream};
use super::validate::{FileInfo, GridDesc};
use super::values::{read_values, Storage};
use crate::volume::asset::AssetLocation;
use crate::volume::grid::{RawGrid, RawLeaf, RawTile, BRICK_VOXELS};
use std::io::{Read, Seek, SeekFrom};

/// The oldest file format whose tree layout this reader knows: 222 introduced the
/// per-node metadata byte and per-grid compression. (Older files also store each
/// leaf's origin and buffer count with its values, and internal nodes only their
/// tile values; no file Nimbus was given uses that layout.)
const MIN_VERSION: u32 = 222;

/// Log2 of the slots per axis of the two internal levels and the leaves.
const LOG2_UPPER: u32 = 5;
const LOG2_LOWER: u32 = 4;
const LOG2_LEAF: u32 = 3;

/// Why the Rust reader cannot read the (validated, linear) grid `desc`, if it cannot.
pub(crate) fn unsupported_reason(info: &FileInfo, desc: &GridDesc) -> Option<String> {
    if !desc.instance_parent.is_empty() {
        Some(format!(
            "grid {:?} is an instance of grid {:?} (shares its tree), which Nimbus' VDB reader \
             does not read",
            desc.name, desc.instance_parent
        ))
    } else if info.file_version < MIN_VERSION {
        Some(format!(
            "grid {:?}: file format version {} predates the tree layout Nimbus' VDB reader \
             reads ({MIN_VERSION} to 224)",
            desc.name, info.file_version
        ))
    } else {
        None
    }
}

/// Reads the grid `desc` of the validated file at `loc` as `N` float grids of one
/// topology (N = 1: a float grid; N = 3: a Vec3s grid's x, y, z). `Err` is a message
/// without the file name, which the caller adds.
pub(crate) fn read_grid<const N: usize>(
    loc: &AssetLocation,
    info: &FileInfo,
    desc: &GridDesc,
) -> Result<[RawGrid; N], String> {
    if let Some(why) = unsupported_reason(info, desc) {
        return Err(why);
    }
    // Validation walks the tree of every grid it sets `root` for; read only those.
    let (Some(index_to_world), Some(_)) = (desc.index_to_world, &desc.root) else {
        return Err(format!(
            "grid {:?}: its transform or tree was not validated",
            desc.name
        ));
    };
    let storage = Storage {
        compression: desc.compression.unwrap_or(info.archive_compression),
        half: desc.half_float,
    };
    let label = |e: String| format!("grid {:?}: {e}", desc.name);
    let (start, end) = (desc.tree_pos, desc.end_pos);
    let len = end
        .checked_sub(start)
        .and_then(|n| usize::try_from(n).ok())
        .ok_or_else(|| label("corrupt grid offsets".into()))?;
    let grids = match loc {
        AssetLocation::File(path) => {
            // Only the grid's own bytes, which validation has bounded by the file size.
            let mut f = std::fs::File::open(path).map_err(|e| e.to_string())?;
            f.seek(SeekFrom::Start(start)).map_err(|e| e.to_string())?;
            let mut bytes = vec![0u8; len];
            f.read_exact(&mut bytes)
                .map_err(|e| label(format!("reading {len} bytes at offset {start}: {e}")))?;
            read_tree::<N>(&mut Stream::new(&bytes, start), storage, desc.block_pos)
        }
        AssetLocation::Packaged { bytes, .. } => {
            let bytes = usize::try_from(start)
                .ok()
                .and_then(|s| bytes.get(s..s.checked_add(len)?))
                .ok_or_else(|| label("grid data lies outside the file".into()))?;
            read_tree::<N>(&mut Stream::new(bytes, start), storage, desc.block_pos)
        }
    };
    let mut grids = grids.map_err(label)?;
    for g in &mut grids {
        g.name = desc.name.clone();
        g.class = grid_class(&desc.class).into();
        g.index_to_world = index_to_world;
    }
    Ok(grids)
}

/// The grid class as OpenVDB reports it (`GridBase::getGridClass`): the `class`
/// metadata trimmed and lower-cased if it is one of the three known classes,
/// "unknown" otherwise.
fn grid_class(meta: &str) -> &'static str {
    match meta.trim().to_lowercase().as_str() {
        "level set" => "level set",
        "fog volume" => "fog volume",
        "staggered" => "staggered",
        _ => "unknown",
    }
}

/// An upper internal node (32³ slots of 16³-slot children) after the topology pass.
struct Upper<const N: usize> {
    origin: [i32; 3],
    tiles: Vec<(usize, [f32; N], bool)>,
    children: Vec<Lower<N>>,
}

/// A lower internal node (16³ slots of leaves) after the topology pass.
struct Lower<const N: usize> {
    origin: [i32; 3],
    tiles: Vec<(usize, [f32; N], bool)>,
    /// Leaf origins and value masks, in slot order (the order of their buffers).
    leaves: Vec<([i32; 3], [u64; 8])>,
}

/// Reads a tree (topology, then leaf buffers) starting at its buffer count.
fn read_tree<const N: usize>(
    s: &mut Stream,
    storage: Storage,
    block_pos: u64,
) -> Result<[RawGrid; N], String> {
    let buffers = s.i32("tree buffer count")?;
    if buffers != 1 {
        return Err(format!("corrupt: tree buffer count {buffers}, expected 1"));
    }
    // Root node (RootNode::readTopology): background, tiles, children; full precision.
    let background: [f32; N] = s.value("background")?;
    let tile_count = s.u32("root tile count")? as usize;
    let child_count = s.u32("root child count")? as usize;
    // Each root tile takes 13 + 4·N bytes, each child at least its origin and masks.
    if tile_count > s.remaining() / (13 + 4 * N) || child_count > s.remaining() / (12 + 8192) {
        return Err(format!(
            "corrupt: {tile_count} root tiles and {child_count} children cannot fit in the grid's data"
        ));
    }
    let mut root_tiles = Vec::with_capacity(tile_count);
    for _ in 0..tile_count {
        let origin = s.coord("root tile")?;
        let value: [f32; N] = s.value("root tile")?;
        let active = s.u8("root tile")? != 0;
        root_tiles.push((origin, value, active));
    }
    let mut uppers = Vec::with_capacity(child_count);
    for _ in 0..child_count {
        let origin = s.coord("internal node origin")?;
        uppers.push(read_upper(s, storage, background, origin)?);
    }
    if s.offset() != block_pos {
        return Err(format!(
            "corrupt: tree topology ends at offset {} but the grid's blocks start at {block_pos}",
            s.offset()
        ));
    }
    // The root is a map sorted by origin: OpenVDB iterates it, and reads the leaf
    // buffers, in that order whatever order the file listed its entries in.
    root_tiles.sort_by_key(|t| t.0);
    uppers.sort_by_key(|u| u.origin);
    let mut keys: Vec<[i32; 3]> = root_tiles.iter().map(|t| t.0).collect();
    keys.extend(uppers.iter().map(|u| u.origin));
    keys.sort_unstable();
    if let Some(w) = keys.windows(2).find(|w| w[0] == w[1]) {
        return Err(format!("corrupt: two root entries at {:?}", w[0]));
    }

    let mut out: [RawGrid; N] = std::array::from_fn(|c| RawGrid {
        name: String::new(),
        class: String::new(),
        background: background[c],
        leaves: Vec::new(),
        tiles: Vec::new(),
        index_to_world: glam::DMat4::IDENTITY,
    });
    let mut tile = |origin: [i32; 3], dim: i32, value: [f32; N], active: bool| {
        // As the bridge: inactive tiles holding the background carry nothing.
        if !active && value == background {
            return;
        }
        for (c, g) in out.iter_mut().enumerate() {
            g.tiles.push(RawTile {
                origin,
                dim,
                value: value[c],
                active,
            });
        }
    };
    for &(origin, value, active) in &root_tiles {
        tile(origin, 4096, value, active);
    }
    let mut leaves = Vec::new();
    for upper in &uppers {
        for &(i, value, active) in &upper.tiles {
            tile(
                child_origin(upper.origin, i, LOG2_UPPER, 128),
                128,
                value,
                active,
            );
        }
        for lower in &upper.children {
            for &(i, value, active) in &lower.tiles {
                tile(
                    child_origin(lower.origin, i, LOG2_LOWER, 8),
                    8,
                    value,
                    active,
                );
            }
            leaves.extend(lower.leaves.iter().copied());
        }
    }
    drop(tile);
    // Second pass (LeafNode::readBuffers): each leaf's mask again, then its values.
    for g in out.iter_mut() {
        g.leaves.reserve_exact(leaves.len());
    }
    let mut values = vec![0.0f32; BRICK_VOXELS * N];
    for (origin, mask) in leaves {
        // OpenVDB seeks over the stored copy of the mask and keeps the topology's.
        s.take(64, "leaf value mask")?;
        read_values::<N>(s, storage, background, &mask, &mut values)?;
        for (c, g) in out.iter_mut().enumerate() {
            g.leaves.push(RawLeaf {
                origin,
                values: values.iter().skip(c).step_by(N).copied().collect(),
                active: mask,
            });
        }
    }
    // Bytes after the last leaf are ignored, as OpenVDB ignores them (it seeks to
    // the next grid's offset).
    Ok(out)
}

/// The origin of slot `i` of an internal node at `origin` with 2^`log2` slots per
/// axis of `child_dim` voxels each (OpenVDB's `offsetToGlobalCoord`: x-major).
fn child_origin(origin: [i32; 3], i: usize, log2: u32, child_dim: i32) -> [i32; 3] {
    let n = 1usize << log2;
    let (x, y, z) = (i >> (2 * log2), (i >> log2) & (n - 1), i & (n - 1));
    [
        origin[0] + x as i32 * child_dim,
        origin[1] + y as i32 * child_dim,
        origin[2] + z as i32 * child_dim,
    ]
}

/// One internal node's topology: child mask, value mask, all slot values; returns
/// the child mask and the tiles (slots without a child) that are active or hold
/// something other than the background.
#[allow(clippy::type_complexity)]
fn read_internal<const N: usize>(
    s: &mut Stream,
    storage: Storage,
    background: [f32; N],
    log2: u32,
) -> Result<(Vec<u64>, Vec<(usize, [f32; N], bool)>), String> {
    let slots = 1usize << (3 * log2);
    let what = if log2 == LOG2_UPPER {
        "internal node (level 2)"
    } else {
        "internal node (level 1)"
    };
    let child_mask = s.mask(slots / 64, what)?;
    let value_mask = s.mask(slots / 64, what)?;
    let mut values = vec![0.0f32; slots * N];
    read_values::<N>(s, storage, background, &value_mask, &mut values)?;
    // Only tiles that carry something are kept (see `read_tree`'s `tile`): a node
    // mostly holds inactive background.
    let tiles = (0..slots)
        .filter(|&i| !bit(&child_mask, i))
        .map(|i| {
            let mut v = [0.0f32; N];
            v.copy_from_slice(&values[i * N..(i + 1) * N]);
            (i, v, bit(&value_mask, i))
        })
        .filter(|&(_, v, active)| active || v != background)
        .collect();
    Ok((child_mask, tiles))
}

fn read_upper<const N: usize>(
    s: &mut Stream,
    storage: Storage,
    background: [f32; N],
    origin: [i32; 3],
) -> Result<Upper<N>, String> {
    // InternalNode's constructor aligns the origin to the node's size (4096).
    let origin = origin.map(|v| v & !4095);
    let (child_mask, tiles) = read_internal(s, storage, background, LOG2_UPPER)?;
    let mut children = Vec::new();
    for i in (0..1usize << (3 * LOG2_UPPER)).filter(|&i| bit(&child_mask, i)) {
        let lower_origin = child_origin(origin, i, LOG2_UPPER, 128);
        let (mask, tiles) = read_internal(s, storage, background, LOG2_LOWER)?;
        let mut leaves = Vec::new();
        for j in (0..1usize << (3 * LOG2_LOWER)).filter(|&j| bit(&mask, j)) {
            let leaf_origin = child_origin(lower_origin, j, LOG2_LOWER, 1 << LOG2_LEAF);
            let words = s.mask(8, "leaf value mask")?;
            let mut active = [0u64; 8];
            active.copy_from_slice(&words);
            leaves.push((leaf_origin, active));
        }
        children.push(Lower {
            origin: lower_origin,
            tiles,
            leaves,
        });
    }
    Ok(Upper {
        origin,
        tiles,
        children,
    })
}
