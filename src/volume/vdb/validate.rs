//! Header validation in Rust, before any reader sees a file.
//!
//! OpenVDB trusts the lengths and offsets in a file: a corrupt header once made it
//! allocate 6 GB and return a 1.5 GB error message. So every length, count and offset
//! of the archive header, the file metadata, each grid descriptor and each grid's
//! preamble (compression, metadata, transform, root node) and tree is read here with
//! bounds checks against the file length before anything is allocated. The parsed
//! facts (grid types, half-float storage, compression, transform, where the tree
//! starts) are what Nimbus' own tree reader (`tree.rs`) starts from.

use glam::{DMat4, DVec3, DVec4};
use std::io::{Read, Seek, SeekFrom};

/// `"VDB "` as a little-endian 64-bit integer: the first 8 bytes of every VDB file.
pub(crate) const MAGIC: [u8; 8] = [0x20, 0x42, 0x44, 0x56, 0, 0, 0, 0];
/// Oldest layout parsed here (root-node map, OpenVDB 1.0-era files).
pub(crate) const MIN_FILE_VERSION: u32 = 213;
/// Newest layout known (OpenVDB 6 through 11 write 224).
pub(crate) const MAX_FILE_VERSION: u32 = 224;

const V_GRID_INSTANCING: u32 = 216;
const V_BOOST_UUID: u32 = 218;
const V_NEW_TRANSFORM: u32 = 219;
const V_SELECTIVE_COMPRESSION: u32 = 220;
const V_NODE_MASK_COMPRESSION: u32 = 222;

/// Caps on header fields. Real files are far below them; corrupt ones are far above.
const MAX_NAME_LEN: u64 = 64 * 1024;
/// Grid names end up in error messages, so they get a tighter cap.
const MAX_GRID_NAME_LEN: u64 = 1024;
const MAX_TYPE_NAME_LEN: u64 = 1024;
const MAX_GRIDS: u64 = 100_000;
const MAX_METADATA_ENTRIES: u64 = 100_000;
const MAX_METADATA_VALUE_LEN: u64 = 256 * 1024 * 1024;
/// Separator OpenVDB puts between a grid name and its duplicate index ("name\x1eN").
const UNIQUE_SEP: char = '\u{1e}';
const HALF_FLOAT_SUFFIX: &str = "_HalfFloat";

/// What validation learned about a file.
#[derive(Clone, Debug)]
pub(crate) struct FileInfo {
    pub file_version: u32,
    /// Archive-wide compression flags, which files before 222 use for every grid
    /// (from 222 on each grid has its own, [`GridDesc::compression`]).
    pub archive_compression: u32,
    pub grids: Vec<GridDesc>,
}

/// One grid descriptor plus what its preamble told us.
#[derive(Clone, Debug)]
pub(crate) struct GridDesc {
    /// The name as the user knows it (duplicate-index suffix removed).
    pub name: String,
    /// The name stored in the file (`name\x1eN` for the N-th duplicate).
    pub unique_name: String,
    /// Tree type without the `_HalfFloat` suffix, e.g. `Tree_float_5_4_3`.
    pub grid_type: String,
    /// Values are stored as 16-bit halves (type suffix or `is_saved_as_half_float`).
    pub half_float: bool,
    pub instance_parent: String,
    /// Per-grid compression flags (file version >= 222).
    pub compression: Option<u32>,
    /// `class` metadata ("fog volume", "level set", ...), "unknown" if absent.
    pub class: String,
    /// `file_voxel_count` metadata.
    pub active_voxels: Option<u64>,
    /// Transform map type, e.g. `UniformScaleTranslateMap` (empty for pre-219 files).
    pub map_type: String,
    /// Index → world, column-vector convention, for linear maps.
    pub index_to_world: Option<DMat4>,
    /// Root-node facts, parsed for float and Vec3s grids with a known, linear transform.
    pub root: Option<RootInfo>,
    /// File offset of the tree (its buffer count), right after the transform.
    pub tree_pos: u64,
    /// File offset of the leaf buffers (the end of the topology).
    pub block_pos: u64,
    /// File offset of the end of the grid's data.
    pub end_pos: u64,
    /// Why a Vec3s grid's tree failed validation. Unlike a float tree's, this does not
    /// fail the whole file: only reading this grid as Vec3s is refused (so the float
    /// grids of a file with an odd colour grid stay readable).
    pub tree_error: Option<String>,
}

#[derive(Clone, Debug)]
pub(crate) struct RootInfo {
    pub child_count: u32,
}

impl GridDesc {
    pub fn is_float(&self) -> bool {
        self.grid_type == "Tree_float_5_4_3"
    }
    pub fn is_vec3s(&self) -> bool {
        self.grid_type == "Tree_vec3s_5_4_3"
    }
    /// A short human name of the value type for error messages.
    pub fn value_type_label(&self) -> String {
        let t = self
            .grid_type
            .strip_prefix("Tree_")
            .unwrap_or(&self.grid_type);
        let t = t.strip_suffix("_5_4_3").unwrap_or(t);
        match t {
            "vec3s" => "Vec3s".into(),
            "vec3d" => "Vec3d".into(),
            "vec3i" => "Vec3i".into(),
            other => other.to_string(),
        }
    }
    /// The name OpenVDB's `File::readGrid` resolves to this grid: `name` or `name[N]`.
    #[cfg_attr(not(nimbus_openvdb), allow(dead_code))]
    pub fn openvdb_lookup_name(&self) -> String {
        match self.unique_name.split_once(UNIQUE_SEP) {
            Some((base, idx)) => format!("{base}[{idx}]"),
            None => self.unique_name.clone(),
        }
    }
}

/// Bounds-checked little-endian reader over a seekable source of known length.
struct Src<'a, R: Read + Seek> {
    r: &'a mut R,
    len: u64,
    pos: u64,
}

impl<'a, R: Read + Seek> Src<'a, R> {
    fn remaining(&self) -> u64 {
        self.len.saturating_sub(self.pos)
    }

    fn need(&self, n: u64, what: &str) -> Result<(), String> {
        if n > self.remaining() {
            Err(format!(
                "truncated or corrupt: {what} needs {n} bytes at offset {} but the file has {} bytes",
                self.pos, self.len
            ))
        } else {
            Ok(())
        }
    }

    fn bytes(&mut self, n: u64, what: &str) -> Result<Vec<u8>, String> {
        self.need(n, what)?;
        let mut buf = vec![0u8; n as usize];
        self.r
            .read_exact(&mut buf)
            .map_err(|e| format!("read error in {what} at offset {}: {e}", self.pos))?;
        self.pos += n;
        Ok(buf)
    }

    fn array<const N: usize>(&mut self, what: &str) -> Result<[u8; N], String> {
        self.need(N as u64, what)?;
        let mut buf = [0u8; N];
        self.r
            .read_exact(&mut buf)
            .map_err(|e| format!("read error in {what} at offset {}: {e}", self.pos))?;
        self.pos += N as u64;
        Ok(buf)
    }

    fn skip(&mut self, n: u64, what: &str) -> Result<(), String> {
        self.need(n, what)?;
        self.seek(self.pos + n, what)
    }

    fn seek(&mut self, to: u64, what: &str) -> Result<(), String> {
        if to > self.len {
            return Err(format!(
                "corrupt: {what} at offset {to} is beyond the end of the file ({} bytes)",
                self.len
            ));
        }
        self.r
            .seek(SeekFrom::Start(to))
            .map_err(|e| format!("seek error ({what}): {e}"))?;
        self.pos = to;
        Ok(())
    }

    fn u8(&mut self, what: &str) -> Result<u8, String> {
        Ok(self.array::<1>(what)?[0])
    }
    fn u32(&mut self, what: &str) -> Result<u32, String> {
        Ok(u32::from_le_bytes(self.array(what)?))
    }
    fn i32(&mut self, what: &str) -> Result<i32, String> {
        Ok(i32::from_le_bytes(self.array(what)?))
    }
    fn i64(&mut self, what: &str) -> Result<i64, String> {
        Ok(i64::from_le_bytes(self.array(what)?))
    }
    fn f64(&mut self, what: &str) -> Result<f64, String> {
        Ok(f64::from_le_bytes(self.array(what)?))
    }
    fn dvec3(&mut self, what: &str) -> Result<DVec3, String> {
        Ok(DVec3::new(
            self.f64(what)?,
            self.f64(what)?,
            self.f64(what)?,
        ))
    }

    /// A `u32` length followed by that many bytes, capped at `cap`.
    fn string(&mut self, cap: u64, what: &str) -> Result<String, String> {
        let len = self.u32(what)? as u64;
        if len > cap {
            return Err(format!(
                "corrupt: {what} at offset {} claims {len} bytes (limit {cap})",
                self.pos - 4
            ));
        }
        let bytes = self.bytes(len, what)?;
        Ok(String::from_utf8_lossy(&bytes).into_owned())
    }

    /// A count that must be <= `cap` and whose items (each >= `min_item` bytes) fit.
    fn checked_count(&self, n: u64, cap: u64, min_item: u64, what: &str) -> Result<(), String> {
        if n > cap || n.saturating_mul(min_item) > self.remaining() {
            return Err(format!(
                "truncated or corrupt: {what} count {n} at offset {} is impossible for a file of {} bytes",
                self.pos.saturating_sub(4),
                self.len
            ));
        }
        Ok(())
    }
}

/// A parsed metadata map: only the entries Nimbus cares about are kept.
#[derive(Default)]
struct Meta {
    class: Option<String>,
    voxel_count: Option<i64>,
    half_float: bool,
}

fn read_meta<R: Read + Seek>(s: &mut Src<R>, what: &str) -> Result<Meta, String> {
    let count = s.u32(what)? as u64;
    // Each entry has at least three u32 lengths.
    s.checked_count(count, MAX_METADATA_ENTRIES, 12, what)?;
    let mut meta = Meta::default();
    for _ in 0..count {
        let name = s.string(MAX_NAME_LEN, "metadata name")?;
        let ty = s.string(MAX_TYPE_NAME_LEN, "metadata type name")?;
        let size = s.u32("metadata value size")? as u64;
        if size > MAX_METADATA_VALUE_LEN {
            return Err(format!("corrupt: metadata {name:?} claims {size} bytes"));
        }
        // Fixed-size types must have their size: OpenVDB's TypedMetadata::readValue
        // reads them without looking at the stored size and would lose its place in
        // the file otherwise.
        let fixed = match ty.as_str() {
            "bool" => Some(1),
            "int32" | "float" => Some(4),
            "int64" | "double" => Some(8),
            "vec3i" | "vec3s" => Some(12),
            "vec3d" => Some(24),
            _ => None,
        };
        if let Some(n) = fixed {
            if size != n {
                return Err(format!(
                    "corrupt: metadata {name:?} of type {ty} has size {size}, expected {n}"
                ));
            }
        }
        let value = s.bytes(size, "metadata value")?;
        match (name.as_str(), ty.as_str()) {
            ("class", "string") => meta.class = Some(String::from_utf8_lossy(&value).into_owned()),
            ("file_voxel_count", "int64") => {
                meta.voxel_count = value.as_slice().try_into().ok().map(i64::from_le_bytes)
            }
            ("is_saved_as_half_float", "bool") => meta.half_float = value.first() == Some(&1),
            _ => {}
        }
    }
    Ok(meta)
}

/// Reads a transform: map type name and, for linear maps, the index → world matrix.
fn read_transform<R: Read + Seek>(s: &mut Src<R>) -> Result<(String, Option<DMat4>), String> {
    let map_type = s.string(MAX_TYPE_NAME_LEN, "transform type name")?;
    let scale_translate = |scale: DVec3, t: DVec3| {
        DMat4::from_cols(
            DVec4::new(scale.x, 0.0, 0.0, 0.0),
            DVec4::new(0.0, scale.y, 0.0, 0.0),
            DVec4::new(0.0, 0.0, scale.z, 0.0),
            t.extend(1.0),
        )
    };
    let m = match map_type.as_str() {
        // Layouts as written by OpenVDB's Map::write (math/Maps.h).
        "UniformScaleMap" | "ScaleMap" => {
            let scale = s.dvec3("scale map")?;
            s.skip(4 * 24, "scale map")?;
            Some(scale_translate(scale, DVec3::ZERO))
        }
        "UniformScaleTranslateMap" | "ScaleTranslateMap" => {
            let t = s.dvec3("scale-translate map")?;
            let scale = s.dvec3("scale-translate map")?;
            s.skip(4 * 24, "scale-translate map")?;
            Some(scale_translate(scale, t))
        }
        "TranslationMap" => Some(scale_translate(DVec3::ONE, s.dvec3("translation map")?)),
        "AffineMap" | "UnitaryMap" => {
            let mut a = [0.0f64; 16];
            for v in a.iter_mut() {
                *v = s.f64("affine map")?;
            }
            // Row-major row-vector matrix read as columns = its transpose.
            Some(DMat4::from_cols_array(&a))
        }
        // Frustum and unknown maps: not linear (or unknown), nothing more to parse.
        _ => None,
    };
    if let Some(m) = m {
        if !m.is_finite() {
            return Err(format!("corrupt: {map_type} has non-finite values"));
        }
    }
    Ok((map_type, m))
}

/// Validates `r` (of `len` bytes) as a VDB file. Errors are messages without the file
/// name, which the caller adds.
pub(crate) fn validate<R: Read + Seek>(r: &mut R, len: u64) -> Result<FileInfo, String> {
    if len == 0 {
        return Err("empty file (zero bytes), not a VDB file".into());
    }
    let mut s = Src { r, len, pos: 0 };
    s.seek(0, "start")?;
    if len < 8 {
        return Err(format!(
            "not a VDB file ({len} bytes, too short for the header)"
        ));
    }
    let magic: [u8; 8] = s.array("magic number")?;
    if magic != MAGIC {
        return Err("not a VDB file (bad magic number)".into());
    }
    let file_version = s.u32("file version")?;
    if !(MIN_FILE_VERSION..=MAX_FILE_VERSION).contains(&file_version) {
        return Err(format!(
            "unsupported VDB file format version {file_version} (supported: {MIN_FILE_VERSION} to {MAX_FILE_VERSION})"
        ));
    }
    // Library version (major, minor): informational only.
    s.skip(8, "library version")?;
    let has_grid_offsets = s.u8("grid offsets flag")?;
    if has_grid_offsets != 1 {
        return Err("file has no grid offsets (written as a stream); not supported".into());
    }
    // As OpenVDB's Archive::readHeader: before 220 every file is zlib-compressed with
    // active masks; 220 and 221 store an on/off flag.
    let mut archive_compression = COMPRESS_ZIP | COMPRESS_ACTIVE_MASK;
    if (V_SELECTIVE_COMPRESSION..V_NODE_MASK_COMPRESSION).contains(&file_version) {
        archive_compression = if s.u8("compression flag")? != 0 {
            COMPRESS_ZIP
        } else {
            0
        };
    }
    let uuid_len = if file_version >= V_BOOST_UUID { 36 } else { 16 };
    s.skip(uuid_len, "file UUID")?;
    read_meta(&mut s, "file metadata")?;

    let grid_count = s.i32("grid count")?;
    if grid_count < 0 {
        return Err(format!("corrupt: negative grid count {grid_count}"));
    }
    s.checked_count(grid_count as u64, MAX_GRIDS, 36, "grid")?;
    let mut grids = Vec::with_capacity(grid_count as usize);
    for i in 0..grid_count {
        let desc_start = s.pos;
        let unique_name = s.string(MAX_GRID_NAME_LEN, "grid name")?;
        let raw_type = s.string(MAX_TYPE_NAME_LEN, "grid type")?;
        let instance_parent = if file_version >= V_GRID_INSTANCING {
            s.string(MAX_GRID_NAME_LEN, "grid instance parent")?
        } else {
            String::new()
        };
        let grid_pos = s.i64("grid offset")?;
        let block_pos = s.i64("grid block offset")?;
        let end_pos = s.i64("grid end offset")?;
        let label = unique_name.replace(UNIQUE_SEP, "#");
        let bad_offsets = grid_pos < s.pos as i64
            || block_pos < grid_pos
            || end_pos < block_pos
            || end_pos as u64 > len
            || grid_pos < 0;
        if bad_offsets {
            return Err(format!(
                "corrupt or truncated: grid {i} ({label:?}, descriptor at offset {desc_start}) has offsets \
                 grid={grid_pos} blocks={block_pos} end={end_pos}, outside the file ({len} bytes)"
            ));
        }
        let (grid_pos, block_pos, end_pos) = (grid_pos as u64, block_pos as u64, end_pos as u64);
        let (grid_type, suffix_half) = match raw_type.strip_suffix(HALF_FLOAT_SUFFIX) {
            Some(t) => (t.to_string(), true),
            None => (raw_type.clone(), false),
        };
        let name = unique_name
            .split(UNIQUE_SEP)
            .next()
            .unwrap_or("")
            .to_string();

        // The grid's own preamble, bounded by its end offset.
        let mut g = Src {
            r: &mut *s.r,
            len: end_pos,
            pos: 0,
        };
        g.seek(grid_pos, "grid data")?;
        let compression = if file_version >= V_NODE_MASK_COMPRESSION {
            let c = g.u32("grid compression flags")?;
            if c & !0x7 != 0 {
                return Err(format!(
                    "corrupt: grid {label:?} has invalid compression flags {c:#x}"
                ));
            }
            Some(c)
        } else {
            None
        };
        let meta =
            read_meta(&mut g, "grid metadata").map_err(|e| format!("grid {label:?}: {e}"))?;
        let (map_type, index_to_world) = if file_version >= V_NEW_TRANSFORM {
            read_transform(&mut g).map_err(|e| format!("grid {label:?}: {e}"))?
        } else {
            (String::new(), None)
        };
        let mut desc = GridDesc {
            name,
            unique_name,
            grid_type,
            half_float: suffix_half || meta.half_float,
            instance_parent,
            compression,
            class: meta.class.unwrap_or_else(|| "unknown".into()),
            active_voxels: meta.voxel_count.and_then(|v| u64::try_from(v).ok()),
            map_type,
            index_to_world,
            root: None,
            tree_pos: g.pos,
            block_pos,
            end_pos,
            tree_error: None,
        };
        let parse_tree = desc.instance_parent.is_empty() && desc.index_to_world.is_some();
        if desc.is_float() && parse_tree {
            let root = read_root(&mut g, 1).map_err(|e| format!("grid {label:?}: {e}"))?;
            if let Some(flags) = desc.compression {
                walk_tree(&mut g, flags, desc.half_float, 1, &root, block_pos, end_pos)
                    .map_err(|e| format!("grid {label:?}: {e}"))?;
            }
            desc.root = Some(root);
        } else if desc.is_vec3s() && parse_tree {
            let tree = read_root(&mut g, 3).and_then(|root| {
                if let Some(flags) = desc.compression {
                    walk_tree(&mut g, flags, desc.half_float, 3, &root, block_pos, end_pos)?;
                }
                Ok(root)
            });
            match tree {
                Ok(root) => desc.root = Some(root),
                Err(e) => desc.tree_error = Some(format!("grid {label:?}: {e}")),
            }
        }
        grids.push(desc);
        s.seek(end_pos, "next grid descriptor")?;
    }
    Ok(FileInfo {
        file_version,
        archive_compression,
        grids,
    })
}

/// The root node's topology header: background, tiles, child count, for values of
/// `words` 32-bit floats (1: float trees, 3: Vec3s trees); checks that the tiles and
/// children can fit.
fn read_root<R: Read + Seek>(g: &mut Src<R>, words: u64) -> Result<RootInfo, String> {
    let buffers = g.i32("tree buffer count")?;
    if buffers != 1 {
        return Err(format!("corrupt: tree buffer count {buffers}, expected 1"));
    }
    g.skip(4 * words, "background")?;
    let tile_count = g.u32("root tile count")? as u64;
    let child_count = g.u32("root child count")?;
    // A tile is 12 + 4·words + 1 bytes; a child is at least its origin and two 4 KB masks.
    let tile_bytes = 13 + 4 * words;
    g.checked_count(tile_count, u32::MAX as u64, tile_bytes, "root tile")?;
    g.checked_count(
        child_count as u64 + tile_count,
        u32::MAX as u64,
        17,
        "root child",
    )?;
    g.skip(tile_count * tile_bytes, "root tiles")?;
    if (child_count as u64).saturating_mul(12 + 2 * 4096) > g.remaining() {
        return Err(format!(
            "corrupt: root child count {child_count} does not fit in the grid's data"
        ));
    }
    Ok(RootInfo { child_count })
}

/// OpenVDB's compression flags (io/Compression.h).
pub(crate) const COMPRESS_ZIP: u32 = 0x1;
pub(crate) const COMPRESS_ACTIVE_MASK: u32 = 0x2;
pub(crate) const COMPRESS_BLOSC: u32 = 0x4;

/// Walks a float tree's topology and buffers (file version >= 222) without
/// decompressing anything, checking that every mask, value array and compressed
/// chunk lies inside the grid's data. Compressed chunk sizes are what OpenVDB
/// allocates from, so a corrupt one must be caught here.
fn walk_tree<R: Read + Seek>(
    g: &mut Src<R>,
    flags: u32,
    half: bool,
    words: u64,
    root: &RootInfo,
    block_pos: u64,
    end_pos: u64,
) -> Result<(), String> {
    // Topology must end at the block offset.
    g.len = block_pos;
    let mut leaves: u64 = 0;
    for _ in 0..root.child_count {
        g.skip(12, "internal node origin")?;
        let (children5, active5) = read_masks(g, 32768, "internal node (level 2)")?;
        skip_values(g, flags, half, words, 32768, active5)?;
        for _ in 0..children5 {
            let (children4, active4) = read_masks(g, 4096, "internal node (level 1)")?;
            skip_values(g, flags, half, words, 4096, active4)?;
            // Leaf topology: just the value mask.
            g.skip(children4 * 64, "leaf masks")?;
            leaves += children4;
        }
    }
    if g.pos != block_pos {
        return Err(format!(
            "corrupt: tree topology ends at offset {} but the grid's blocks start at {block_pos}",
            g.pos
        ));
    }
    g.len = end_pos;
    for _ in 0..leaves {
        let mask = g.bytes(64, "leaf value mask")?;
        let active: u64 = mask.iter().map(|b| b.count_ones() as u64).sum();
        skip_values(g, flags, half, words, 512, active)?;
    }
    Ok(())
}

/// Reads a child mask and a value mask of `bits` bits; returns their popcounts.
fn read_masks<R: Read + Seek>(g: &mut Src<R>, bits: u64, what: &str) -> Result<(u64, u64), String> {
    let child = g.bytes(bits / 8, what)?;
    let value = g.bytes(bits / 8, what)?;
    let ones = |m: &[u8]| m.iter().map(|b| b.count_ones() as u64).sum::<u64>();
    Ok((ones(&child), ones(&value)))
}

/// Skips one `io::writeCompressedValues` record of `num` values (`active` of them
/// active) of `words` floats each, checking its sizes.
fn skip_values<R: Read + Seek>(
    g: &mut Src<R>,
    flags: u32,
    half: bool,
    words: u64,
    num: u64,
    active: u64,
) -> Result<(), String> {
    let metadata = g.u8("node metadata")?;
    if metadata > 6 {
        return Err(format!(
            "corrupt: node metadata {metadata} at offset {}",
            g.pos - 1
        ));
    }
    // Inactive values are stored at full precision.
    match metadata {
        2 | 4 => g.skip(4 * words, "inactive value")?,
        5 => g.skip(8 * words, "inactive values")?,
        _ => {}
    }
    if matches!(metadata, 3..=5) {
        g.skip(num / 8, "selection mask")?;
    }
    let count = if flags & COMPRESS_ACTIVE_MASK != 0 && metadata != 6 {
        active
    } else {
        num
    };
    // OpenVDB's HalfReader/HalfWriter skip empty arrays entirely (no size field);
    // full-precision arrays always get one.
    if half && count == 0 {
        return Ok(());
    }
    let bytes = count * words * if half { 2 } else { 4 };
    if flags & (COMPRESS_BLOSC | COMPRESS_ZIP) != 0 {
        let stored = g.i64("compressed size")?;
        if stored <= 0 {
            // Stored uncompressed.
            if stored.unsigned_abs() != bytes {
                return Err(format!(
                    "corrupt: uncompressed chunk of {} bytes at offset {} where {bytes} were expected",
                    stored.unsigned_abs(),
                    g.pos - 8
                ));
            }
            g.skip(bytes, "values")?;
        } else if flags & COMPRESS_BLOSC != 0 {
            // c-blosc trusts the sizes in its header, so it must describe exactly
            // this chunk.
            let stored = stored as u64;
            let header = g.bytes(16.min(stored), "blosc header")?;
            let field = |i: usize| {
                header
                    .get(i..i + 4)
                    .and_then(|b| b.try_into().ok())
                    .map(u32::from_le_bytes)
            };
            let (nbytes, cbytes) = (field(4), field(12));
            if nbytes != Some(bytes as u32) || cbytes != Some(stored as u32) {
                return Err(format!(
                    "corrupt: blosc chunk at offset {} declares {nbytes:?} bytes ({cbytes:?} compressed); \
                     expected {bytes} ({stored} compressed)",
                    g.pos - header.len() as u64
                ));
            }
            g.skip(stored - header.len() as u64, "compressed values")?;
        } else {
            g.skip(stored as u64, "compressed values")?;
        }
    } else {
        g.skip(bytes, "values")?;
    }
    Ok(())
}
