//! A minimal OpenVDB writer: float (and Vec3s) grids, uncompressed, file format 224.
//!
//! Nimbus generates its example scenes' volumes with this so they can be read
//! without OpenVDB installed. The layout is what OpenVDB 10's `io::File` writes with
//! compression off: a `Tree_float_5_4_3`, full 32-bit values, every node value
//! written (`NO_MASK_AND_ALL_VALS`), and a (Uniform)ScaleTranslateMap transform (a
//! matrix that is not scale + translation is an error: Nimbus' generators never need
//! one, and the writer stays small).
//!
//! Vec3s grids (`Tree_vec3s_5_4_3`, e.g. a colour `Cd`) are written the same way with
//! three floats per value, from three float grids of one topology ([`WriteGrid::Vec3s`]).
//! Both readers (OpenVDB and Nimbus' own) read everything written here.

use super::error::VdbError;
use crate::volume::grid::{RawGrid, BRICK_VOXELS};
use glam::{DMat4, DVec3};
use std::collections::BTreeMap;
use std::path::Path;

const FILE_VERSION: u32 = 224;
const LIBRARY_VERSION: (u32, u32) = (10, 0);
/// Node metadata byte meaning "every value follows, no mask compression".
const NO_MASK_AND_ALL_VALS: u8 = 6;

/// Writes `grid` to `path` as a single-grid VDB file.
pub fn write_float_grid(path: &Path, grid: &RawGrid) -> Result<(), VdbError> {
    write_float_grids(path, std::slice::from_ref(grid))
}

/// The bytes of a single-grid VDB file holding `grid`.
pub fn write_float_grid_bytes(grid: &RawGrid) -> Result<Vec<u8>, VdbError> {
    write_float_grids_bytes(std::slice::from_ref(grid))
}

/// Writes several float grids (in this order) to one VDB file at `path`. Grids may
/// share a name; readers tell them apart by index (USD `fieldIndex`).
pub fn write_float_grids(path: &Path, grids: &[RawGrid]) -> Result<(), VdbError> {
    let grids: Vec<WriteGrid> = grids.iter().map(WriteGrid::Float).collect();
    write_grids(path, &grids)
}

/// The bytes of a VDB file holding `grids`, as [`write_float_grids`] writes them.
pub fn write_float_grids_bytes(grids: &[RawGrid]) -> Result<Vec<u8>, VdbError> {
    let grids: Vec<WriteGrid> = grids.iter().map(WriteGrid::Float).collect();
    write_grids_bytes(&grids)
}

/// A grid to write.
#[derive(Clone, Copy, Debug)]
pub enum WriteGrid<'a> {
    Float(&'a RawGrid),
    /// A Vec3s grid given as its x, y and z components: three float grids with the same
    /// leaves (origins and active masks), tiles (origins, sizes, active flags) and
    /// transform. Name and class come from the first.
    Vec3s(&'a [RawGrid; 3]),
}

/// Writes a single Vec3s grid (components `grid[0..3]`) to `path`.
pub fn write_vec3s_grid(path: &Path, grid: &[RawGrid; 3]) -> Result<(), VdbError> {
    write_grids(path, &[WriteGrid::Vec3s(grid)])
}

/// Writes float and Vec3s grids (in this order) to one VDB file at `path`.
pub fn write_grids(path: &Path, grids: &[WriteGrid]) -> Result<(), VdbError> {
    let bytes = encode(grids).map_err(|message| VdbError::Write {
        file: path.display().to_string(),
        message,
    })?;
    std::fs::write(path, bytes).map_err(|e| VdbError::Write {
        file: path.display().to_string(),
        message: e.to_string(),
    })
}

/// The bytes of a VDB file holding `grids`, as [`write_grids`] writes them.
pub fn write_grids_bytes(grids: &[WriteGrid]) -> Result<Vec<u8>, VdbError> {
    encode(grids).map_err(|message| VdbError::Write {
        file: "<in-memory VDB>".into(),
        message,
    })
}

impl<'a> WriteGrid<'a> {
    /// The components: one grid, or three.
    fn channels(&self) -> &'a [RawGrid] {
        match *self {
            WriteGrid::Float(g) => std::slice::from_ref(g),
            WriteGrid::Vec3s(g) => g.as_slice(),
        }
    }
}

/// An internal node's entry that is not a child: a tile (`index` into `grid.tiles`).
#[derive(Clone, Copy)]
struct Tile {
    index: usize,
    active: bool,
}

#[derive(Default)]
struct Node4 {
    /// Position in the 16³ table → index into `grid.leaves`.
    leaves: BTreeMap<u32, usize>,
    tiles: BTreeMap<u32, Tile>,
}

#[derive(Default)]
struct Node5 {
    children: BTreeMap<u32, Node4>,
    tiles: BTreeMap<u32, Tile>,
}

/// Root table, keyed like OpenVDB's `std::map<Coord, ...>` (lexicographic x, y, z),
/// whose iteration order fixes the order nodes are written in.
#[derive(Default)]
struct Root {
    children: BTreeMap<(i32, i32, i32), Node5>,
    tiles: BTreeMap<(i32, i32, i32), Tile>,
}

fn key5(p: [i32; 3]) -> (i32, i32, i32) {
    (p[0] & !4095, p[1] & !4095, p[2] & !4095)
}
fn idx5(p: [i32; 3]) -> u32 {
    let f = |v: i32| ((v & 4095) >> 7) as u32;
    (f(p[0]) << 10) | (f(p[1]) << 5) | f(p[2])
}
fn idx4(p: [i32; 3]) -> u32 {
    let f = |v: i32| ((v & 127) >> 3) as u32;
    (f(p[0]) << 8) | (f(p[1]) << 4) | f(p[2])
}

fn build_tree(grid: &RawGrid) -> Result<Root, String> {
    let mut root = Root::default();
    for (i, leaf) in grid.leaves.iter().enumerate() {
        if leaf.origin.iter().any(|v| v & 7 != 0) {
            return Err(format!(
                "leaf {i} origin {:?} is not a multiple of 8",
                leaf.origin
            ));
        }
        if leaf.values.len() != BRICK_VOXELS {
            return Err(format!(
                "leaf {i} has {} values, expected {BRICK_VOXELS}",
                leaf.values.len()
            ));
        }
        let n4 = root
            .children
            .entry(key5(leaf.origin))
            .or_default()
            .children
            .entry(idx5(leaf.origin))
            .or_default();
        if n4.leaves.insert(idx4(leaf.origin), i).is_some() {
            return Err(format!("two leaves at {:?}", leaf.origin));
        }
    }
    for (index, t) in grid.tiles.iter().enumerate() {
        let bad_origin = || {
            format!(
                "tile at {:?} is not aligned to its size {}",
                t.origin, t.dim
            )
        };
        if !matches!(t.dim, 8 | 128 | 4096) {
            return Err(format!(
                "tile at {:?} has size {}; OpenVDB tiles are 8, 128 or 4096",
                t.origin, t.dim
            ));
        }
        if t.origin.iter().any(|v| v & (t.dim - 1) != 0) {
            return Err(bad_origin());
        }
        let tile = Tile {
            index,
            active: t.active,
        };
        let clash = || {
            format!(
                "tile at {:?} (size {}) overlaps other data",
                t.origin, t.dim
            )
        };
        match t.dim {
            4096 => {
                let k = key5(t.origin);
                if root.children.contains_key(&k) || root.tiles.insert(k, tile).is_some() {
                    return Err(clash());
                }
            }
            128 => {
                let n5 = root.children.entry(key5(t.origin)).or_default();
                let i = idx5(t.origin);
                if n5.children.contains_key(&i) || n5.tiles.insert(i, tile).is_some() {
                    return Err(clash());
                }
            }
            _ => {
                let n4 = root
                    .children
                    .entry(key5(t.origin))
                    .or_default()
                    .children
                    .entry(idx5(t.origin))
                    .or_default();
                let i = idx4(t.origin);
                if n4.leaves.contains_key(&i) || n4.tiles.insert(i, tile).is_some() {
                    return Err(clash());
                }
            }
        }
    }
    // A 128 or 8 tile may have created a node where a root tile already sits.
    if root.tiles.keys().any(|k| root.children.contains_key(k)) {
        return Err("a root tile (size 4096) overlaps leaves or smaller tiles".into());
    }
    Ok(root)
}

/// Splits `m` into per-axis scale and translation, if it is exactly that.
fn scale_translate(m: &DMat4) -> Result<(DVec3, DVec3), String> {
    let a = m.to_cols_array_2d();
    for (c, col) in a.iter().enumerate() {
        for (r, v) in col.iter().enumerate() {
            let off_diagonal = r != c && !(c == 3 && r < 3);
            if !v.is_finite() || (off_diagonal && *v != 0.0) {
                return Err(format!(
                    "index_to_world is not a scale + translation ({m:?}); the VDB writer \
                     writes only scale-translate maps"
                ));
            }
        }
    }
    if a[3][3] != 1.0 {
        return Err("index_to_world is projective".into());
    }
    let scale = DVec3::new(a[0][0], a[1][1], a[2][2]);
    if scale.cmpeq(DVec3::ZERO).any() {
        return Err("index_to_world has a zero scale".into());
    }
    Ok((scale, DVec3::new(a[3][0], a[3][1], a[3][2])))
}

#[derive(Default)]
struct Out(Vec<u8>);

impl Out {
    fn u8(&mut self, v: u8) {
        self.0.push(v);
    }
    fn u32(&mut self, v: u32) {
        self.0.extend_from_slice(&v.to_le_bytes());
    }
    fn i32(&mut self, v: i32) {
        self.0.extend_from_slice(&v.to_le_bytes());
    }
    fn i64(&mut self, v: i64) {
        self.0.extend_from_slice(&v.to_le_bytes());
    }
    fn f32(&mut self, v: f32) {
        self.0.extend_from_slice(&v.to_le_bytes());
    }
    fn dvec3(&mut self, v: DVec3) {
        for c in v.to_array() {
            self.0.extend_from_slice(&c.to_le_bytes());
        }
    }
    fn coord(&mut self, p: [i32; 3]) {
        p.iter().for_each(|&c| self.i32(c));
    }
    fn string(&mut self, s: &str) {
        self.u32(s.len() as u32);
        self.0.extend_from_slice(s.as_bytes());
    }
    fn mask(&mut self, bits: &[bool]) {
        for chunk in bits.chunks(64) {
            let w = chunk
                .iter()
                .enumerate()
                .fold(0u64, |w, (i, &b)| w | ((b as u64) << i));
            self.0.extend_from_slice(&w.to_le_bytes());
        }
    }
    fn meta_string(&mut self, name: &str, v: &str) {
        self.string(name);
        self.string("string");
        self.string(v);
    }
    fn meta_i64(&mut self, name: &str, v: i64) {
        self.string(name);
        self.string("int64");
        self.u32(8);
        self.i64(v);
    }
    fn meta_vec3i(&mut self, name: &str, v: [i32; 3]) {
        self.string(name);
        self.string("vec3i");
        self.u32(12);
        self.coord(v);
    }
    fn meta_bool(&mut self, name: &str, v: bool) {
        self.string(name);
        self.string("bool");
        self.u32(1);
        self.u8(v as u8);
    }
}

/// One internal node's masks and values (`InternalNode::writeTopology`): child mask,
/// value mask, then the metadata byte and every value (zero under children), each
/// value one float per channel.
fn write_internal(
    out: &mut Out,
    size: usize,
    child: impl Fn(u32) -> bool,
    tile: impl Fn(u32) -> Option<Tile>,
    chans: &[RawGrid],
) {
    let child_bits: Vec<bool> = (0..size as u32).map(&child).collect();
    let value_bits: Vec<bool> = (0..size as u32)
        .map(|i| tile(i).is_some_and(|t| t.active))
        .collect();
    out.mask(&child_bits);
    out.mask(&value_bits);
    out.u8(NO_MASK_AND_ALL_VALS);
    for i in 0..size as u32 {
        for ch in chans {
            let v = if child_bits[i as usize] {
                0.0
            } else {
                tile(i).map_or(ch.background, |t| ch.tiles[t.index].value)
            };
            out.f32(v);
        }
    }
}

/// Checks that the components of a Vec3s grid share the first one's topology.
fn same_topology(chans: &[RawGrid]) -> Result<(), String> {
    let g = &chans[0];
    for (c, o) in chans.iter().enumerate().skip(1) {
        let leaves_match = o.leaves.len() == g.leaves.len()
            && o.leaves.iter().zip(&g.leaves).all(|(a, b)| {
                a.origin == b.origin && a.active == b.active && a.values.len() == b.values.len()
            });
        let tiles_match = o.tiles.len() == g.tiles.len()
            && o.tiles
                .iter()
                .zip(&g.tiles)
                .all(|(a, b)| a.origin == b.origin && a.dim == b.dim && a.active == b.active);
        if !leaves_match || !tiles_match || o.index_to_world != g.index_to_world {
            return Err(format!(
                "component {c} of a Vec3s grid does not have the topology and transform of component 0"
            ));
        }
    }
    Ok(())
}

fn encode(grids: &[WriteGrid]) -> Result<Vec<u8>, String> {
    if grids.is_empty() {
        return Err("no grids to write".into());
    }
    let mut out = Out::default();

    // Archive header.
    out.0.extend_from_slice(&super::validate::MAGIC);
    out.u32(FILE_VERSION);
    out.u32(LIBRARY_VERSION.0);
    out.u32(LIBRARY_VERSION.1);
    out.u8(1); // has grid offsets
               // A UUID derived from the content, so identical grids give identical files.
    let sum = grids
        .iter()
        .flat_map(|g| g.channels())
        .fold(0u64, |a, g| a.rotate_left(7) ^ g.checksum());
    let count = grids
        .iter()
        .map(|g| g.channels()[0].leaves.len() as u64)
        .sum::<u64>();
    let h = format!("{sum:016x}{:016x}", count ^ 0x4e49_4d42_5553_0000);
    let uuid = format!(
        "{}-{}-4{}-8{}-{}",
        &h[0..8],
        &h[8..12],
        &h[13..16],
        &h[17..20],
        &h[20..32]
    );
    out.0.extend_from_slice(uuid.as_bytes());
    out.u32(0); // file metadata entries
    out.i32(i32::try_from(grids.len()).map_err(|_| "too many grids")?);

    let mut seen: Vec<&str> = Vec::new();
    for (i, write) in grids.iter().enumerate() {
        let grid = &write.channels()[0];
        // Duplicate names get OpenVDB's "name\x1eN" suffix (N = 1, 2, ... in file
        // order), which is how OpenVDB itself keeps descriptor names unique.
        let dup = seen.iter().filter(|n| **n == grid.name).count();
        seen.push(&grid.name);
        let unique = if dup == 0 {
            grid.name.clone()
        } else {
            format!("{}\u{1e}{dup}", grid.name)
        };
        encode_grid(&mut out, *write, &unique)
            .map_err(|e| format!("grid {i} ({:?}): {e}", grid.name))?;
    }
    Ok(out.0)
}

/// Appends one grid: descriptor, then metadata, transform, topology and buffers.
fn encode_grid(out: &mut Out, write: WriteGrid, unique_name: &str) -> Result<(), String> {
    let chans = write.channels();
    let grid = &chans[0];
    same_topology(chans)?;
    let root = build_tree(grid)?;
    let (scale, translation) = scale_translate(&grid.index_to_world)?;

    // Grid descriptor; the three offsets are patched once known.
    out.string(unique_name);
    out.string(match write {
        WriteGrid::Float(_) => "Tree_float_5_4_3",
        WriteGrid::Vec3s(_) => "Tree_vec3s_5_4_3",
    });
    out.string(""); // instance parent
    let offsets_at = out.0.len();
    out.i64(0);
    out.i64(0);
    out.i64(0);

    let grid_pos = out.0.len();
    out.u32(0); // compression: none
    let bounds = grid.active_index_bounds();
    let class = if grid.class.is_empty() {
        "unknown"
    } else {
        grid.class.as_str()
    };
    out.u32(if bounds.is_some() { 6 } else { 4 });
    out.meta_string("class", class);
    // OpenVDB only names grids read via readAllGridMetadata from this entry.
    out.meta_string("name", &grid.name);
    out.meta_i64(
        "file_voxel_count",
        grid.active_voxel_count().min(i64::MAX as u64) as i64,
    );
    out.meta_bool("is_saved_as_half_float", false);
    if let Some((lo, hi)) = bounds {
        out.meta_vec3i("file_bbox_min", lo);
        out.meta_vec3i("file_bbox_max", hi);
    }
    // Transform (`ScaleTranslateMap::write`): translation, scale, voxel size, inverse
    // scale, inverse squared scale, inverse twice scale.
    let uniform = scale.x == scale.y && scale.y == scale.z;
    out.string(if uniform {
        "UniformScaleTranslateMap"
    } else {
        "ScaleTranslateMap"
    });
    out.dvec3(translation);
    out.dvec3(scale);
    out.dvec3(scale);
    out.dvec3(DVec3::ONE / scale);
    out.dvec3(DVec3::ONE / (scale * scale));
    out.dvec3(DVec3::ONE / (2.0 * scale));

    // Topology.
    out.i32(1); // buffer count
    chans.iter().for_each(|c| out.f32(c.background));
    out.u32(root.tiles.len() as u32);
    out.u32(root.children.len() as u32);
    for (k, t) in &root.tiles {
        out.coord([k.0, k.1, k.2]);
        chans.iter().for_each(|c| out.f32(c.tiles[t.index].value));
        out.u8(t.active as u8);
    }
    for (k, n5) in &root.children {
        out.coord([k.0, k.1, k.2]);
        write_internal(
            out,
            32768,
            |i| n5.children.contains_key(&i),
            |i| n5.tiles.get(&i).copied(),
            chans,
        );
        for n4 in n5.children.values() {
            write_internal(
                out,
                4096,
                |i| n4.leaves.contains_key(&i),
                |i| n4.tiles.get(&i).copied(),
                chans,
            );
            for &l in n4.leaves.values() {
                out.0
                    .extend(grid.leaves[l].active.iter().flat_map(|w| w.to_le_bytes()));
            }
        }
    }

    // Buffers: every leaf again, in the same order, with its values.
    let block_pos = out.0.len();
    for n5 in root.children.values() {
        for n4 in n5.children.values() {
            for &l in n4.leaves.values() {
                let leaf = &grid.leaves[l];
                out.0
                    .extend(leaf.active.iter().flat_map(|w| w.to_le_bytes()));
                out.u8(NO_MASK_AND_ALL_VALS);
                for v in 0..BRICK_VOXELS {
                    chans.iter().for_each(|c| out.f32(c.leaves[l].values[v]));
                }
            }
        }
    }
    let end_pos = out.0.len();
    for (i, pos) in [grid_pos, block_pos, end_pos].into_iter().enumerate() {
        let at = offsets_at + 8 * i;
        out.0[at..at + 8].copy_from_slice(&(pos as i64).to_le_bytes());
    }
    Ok(())
}
