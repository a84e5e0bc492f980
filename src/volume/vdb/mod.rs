//! OpenVDB file reading: validation first, then either the C++ OpenVDB bridge or
//! Nimbus' own pure-Rust tree reader ([`tree`]). Both produce the same [`RawGrid`]s,
//! bit for bit (`tests/vdb_readers.rs` checks every shared production file).
//!
//! Every file is first parsed by [`validate`] in Rust: OpenVDB trusts the lengths and
//! offsets it finds, so a corrupt header must never reach it. Grid selection (name,
//! duplicate index) and type checks also happen here, so both readers report the
//! same errors.

#[cfg(nimbus_openvdb)]
mod bridge;
mod error;
mod stream;
mod tree;
mod validate;
mod values;
mod writer;

pub use error::VdbError;
pub use writer::{
    write_float_grid, write_float_grid_bytes, write_float_grids, write_float_grids_bytes,
    write_grids, write_grids_bytes, write_vec3s_grid, WriteGrid,
};

use crate::volume::asset::AssetLocation;
use crate::volume::grid::RawGrid;
use std::io::Cursor;
use validate::{FileInfo, GridDesc};

/// Which reader decodes VDB files in this build.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Reader {
    /// OpenVDB through the C++ bridge in `cpp/`.
    OpenVdb,
    /// Nimbus' own pure-Rust reader (`tree.rs`), in every build.
    Rust,
}

impl Reader {
    pub fn name(self) -> &'static str {
        match self {
            Reader::OpenVdb => "openvdb",
            Reader::Rust => "rust",
        }
    }

    /// Whether this reader is compiled into this build.
    pub fn available(self) -> bool {
        match self {
            Reader::OpenVdb => cfg!(nimbus_openvdb),
            Reader::Rust => true,
        }
    }
}

/// A grid as listed in a file's header.
#[derive(Clone, Debug)]
pub struct GridInfo {
    pub name: String,
    /// OpenVDB tree type, e.g. "Tree_float_5_4_3".
    pub value_type: String,
    pub active_voxels: Option<u64>,
}

/// Environment variable that picks the reader: `rust` or `openvdb` (default: OpenVDB
/// when this build has it, else Rust). Both read the same grids bit for bit; the
/// switch exists to show that (and to time them).
pub const READER_ENV: &str = "NIMBUS_VDB_READER";

/// The reader VDB files are read with: [`READER_ENV`] if set, else OpenVDB when this
/// build has it, else the Rust reader. An unknown value is reported once on stderr
/// and ignored.
pub fn active_reader() -> Reader {
    let default = if cfg!(nimbus_openvdb) {
        Reader::OpenVdb
    } else {
        Reader::Rust
    };
    match std::env::var(READER_ENV) {
        Ok(v) if v == "rust" => Reader::Rust,
        Ok(v) if v == "openvdb" => Reader::OpenVdb,
        Ok(v) if !v.is_empty() => {
            static WARNED: std::sync::Once = std::sync::Once::new();
            WARNED.call_once(|| {
                eprintln!(
                    "nimbus: warning: {READER_ENV}={v:?} is neither \"rust\" nor \"openvdb\"; \
                     using {}",
                    default.name()
                )
            });
            default
        }
        _ => default,
    }
}

/// Lists the grids of a file (from its validated header; no trees are read).
pub fn list_grids(loc: &AssetLocation) -> Result<Vec<GridInfo>, VdbError> {
    let info = validate_location(loc)?;
    Ok(info
        .grids
        .iter()
        .map(|g| GridInfo {
            name: g.name.clone(),
            value_type: g.grid_type.clone(),
            active_voxels: g.active_voxels,
        })
        .collect())
}

/// As [`list_grids`], but asking OpenVDB itself (after validation) when `reader` is
/// [`Reader::OpenVdb`]; for cross-checks.
pub fn list_grids_with(reader: Reader, loc: &AssetLocation) -> Result<Vec<GridInfo>, VdbError> {
    match reader {
        Reader::Rust => list_grids(loc),
        Reader::OpenVdb => {
            validate_location(loc)?;
            openvdb_list(loc)
        }
    }
}

/// Reads one float grid: by name (empty = any), and by index among the grids with
/// that name when `index` is given (OpenVDB asset `fieldIndex`).
pub fn read_float_grid(
    loc: &AssetLocation,
    name: &str,
    index: Option<i32>,
) -> Result<RawGrid, VdbError> {
    read_float_grid_with(active_reader(), loc, name, index)
}

/// As [`read_float_grid`], with a chosen reader (for cross-checks).
pub fn read_float_grid_with(
    reader: Reader,
    loc: &AssetLocation,
    name: &str,
    index: Option<i32>,
) -> Result<RawGrid, VdbError> {
    with_selected(loc, name, index, |info, desc| {
        float_from(reader, loc, info, desc)
    })
}

/// Validates the file at `loc` once, selects the grid (`name`, `index`) as
/// [`read_float_grid`] describes, and hands both to `read`.
fn with_selected<T>(
    loc: &AssetLocation,
    name: &str,
    index: Option<i32>,
    read: impl FnOnce(&FileInfo, &GridDesc) -> Result<T, VdbError>,
) -> Result<T, VdbError> {
    let info = validate_location(loc)?;
    let desc = select(&info, &loc.to_string(), name, index)?;
    read(&info, desc)
}

/// A float grid with a linear transform: what the float readers accept.
fn check_float(info: &FileInfo, desc: &GridDesc, file: &str) -> Result<(), VdbError> {
    if !desc.is_float() {
        return Err(VdbError::WrongType {
            file: file.to_string(),
            grid: desc.name.clone(),
            found: desc.value_type_label(),
            expected: "float",
        });
    }
    check_linear(info, desc, file)
}

/// Reads the float grid `desc` of the validated file `info`.
fn float_from(
    reader: Reader,
    loc: &AssetLocation,
    info: &FileInfo,
    desc: &GridDesc,
) -> Result<RawGrid, VdbError> {
    let file = loc.to_string();
    check_float(info, desc, &file)?;
    match reader {
        Reader::Rust => {
            let [grid] = rust_read::<1>(loc, info, desc)?;
            Ok(grid)
        }
        Reader::OpenVdb => openvdb_read(loc, desc),
    }
}

/// Reads `desc` with the Rust reader, after its refusals ([`tree::unsupported_reason`]).
fn rust_read<const N: usize>(
    loc: &AssetLocation,
    info: &FileInfo,
    desc: &GridDesc,
) -> Result<[RawGrid; N], VdbError> {
    let file = loc.to_string();
    if let Some(message) = tree::unsupported_reason(info, desc) {
        return Err(VdbError::Unsupported { file, message });
    }
    tree::read_grid::<N>(loc, info, desc).map_err(|message| VdbError::Reader {
        file,
        reader: Reader::Rust.name(),
        message,
    })
}

/// OpenVDB's own in-memory size in bytes (`GridBase::memUsage`) of the float grid
/// [`read_float_grid`] would read; needs the OpenVDB bridge (benchmarks compare
/// Nimbus' layout against it).
pub fn openvdb_mem_usage(
    loc: &AssetLocation,
    name: &str,
    index: Option<i32>,
) -> Result<u64, VdbError> {
    with_selected(loc, name, index, |info, desc| {
        check_float(info, desc, &loc.to_string())?;
        openvdb_mem(loc, desc)
    })
}

#[cfg(nimbus_openvdb)]
fn openvdb_mem(loc: &AssetLocation, desc: &GridDesc) -> Result<u64, VdbError> {
    let file = loc.to_string();
    with_openvdb_path(loc, |p| {
        bridge::ffi::float_grid_mem_usage(p, &desc.openvdb_lookup_name()).map_err(|e| {
            VdbError::Reader {
                file: file.clone(),
                reader: "openvdb",
                message: e.what().to_string(),
            }
        })
    })
}

#[cfg(not(nimbus_openvdb))]
fn openvdb_mem(loc: &AssetLocation, _desc: &GridDesc) -> Result<u64, VdbError> {
    Err(openvdb_unavailable(loc))
}

/// Reads one Vec3s grid (selected as in [`read_float_grid`]) as three float grids of
/// one topology: component x, y, z (for a colour grid such as Houdini's `Cd`: r, g, b).
pub fn read_vec3s_grid(
    loc: &AssetLocation,
    name: &str,
    index: Option<i32>,
) -> Result<[RawGrid; 3], VdbError> {
    read_vec3s_grid_with(active_reader(), loc, name, index)
}

/// As [`read_vec3s_grid`], with a chosen reader.
pub fn read_vec3s_grid_with(
    reader: Reader,
    loc: &AssetLocation,
    name: &str,
    index: Option<i32>,
) -> Result<[RawGrid; 3], VdbError> {
    with_selected(loc, name, index, |info, desc| {
        vec3s_from(reader, loc, info, desc)
    })
}

/// A colour grid: a Vec3s grid as [`read_vec3s_grid`] reads it, or a float grid as a
/// grey one (the same grid in all three channels).
pub fn read_color_grid(
    loc: &AssetLocation,
    name: &str,
    index: Option<i32>,
) -> Result<[RawGrid; 3], VdbError> {
    read_color_grid_with(active_reader(), loc, name, index)
}

/// As [`read_color_grid`], with a chosen reader.
pub fn read_color_grid_with(
    reader: Reader,
    loc: &AssetLocation,
    name: &str,
    index: Option<i32>,
) -> Result<[RawGrid; 3], VdbError> {
    with_selected(loc, name, index, |info, desc| {
        if desc.is_float() {
            let g = float_from(reader, loc, info, desc)?;
            return Ok([g.clone(), g.clone(), g]);
        }
        if !desc.is_vec3s() {
            return Err(VdbError::WrongType {
                file: loc.to_string(),
                grid: desc.name.clone(),
                found: desc.value_type_label(),
                expected: "float or Vec3s",
            });
        }
        vec3s_from(reader, loc, info, desc)
    })
}

fn vec3s_from(
    reader: Reader,
    loc: &AssetLocation,
    info: &FileInfo,
    desc: &GridDesc,
) -> Result<[RawGrid; 3], VdbError> {
    let file = loc.to_string();
    if !desc.is_vec3s() {
        return Err(VdbError::WrongType {
            file,
            grid: desc.name.clone(),
            found: desc.value_type_label(),
            expected: "Vec3s",
        });
    }
    check_linear(info, desc, &file)?;
    if let Some(message) = &desc.tree_error {
        return Err(VdbError::Invalid {
            file,
            message: message.clone(),
        });
    }
    if !desc.instance_parent.is_empty() {
        return Err(VdbError::Unsupported {
            file,
            message: format!(
                "grid {:?} is an instance of grid {:?}; Nimbus does not read instanced Vec3s grids",
                desc.name, desc.instance_parent
            ),
        });
    }
    match reader {
        Reader::Rust => rust_read::<3>(loc, info, desc),
        Reader::OpenVdb => openvdb_read_vec3s(loc, desc),
    }
}

/// Only grids whose transform and tree validation understood reach a reader: a
/// frustum (or unknown) map would leave the tree unchecked, and Nimbus cannot use
/// non-linear maps anyway.
fn check_linear(info: &FileInfo, desc: &GridDesc, file: &str) -> Result<(), VdbError> {
    let file = file.to_string();
    if desc.index_to_world.is_none() {
        let message = if desc.map_type.is_empty() {
            format!(
                "grid {:?}: file format version {} predates the transform layout Nimbus reads (219)",
                desc.name, info.file_version
            )
        } else {
            format!(
                "grid {:?} has a {} transform; only linear (affine) index-to-world transforms are supported",
                desc.name, desc.map_type
            )
        };
        return Err(VdbError::Unsupported { file, message });
    }
    Ok(())
}

/// Validates the file or package member behind `loc`.
fn validate_location(loc: &AssetLocation) -> Result<FileInfo, VdbError> {
    let file = loc.to_string();
    let result = match loc {
        AssetLocation::File(path) => {
            let f = std::fs::File::open(path).map_err(|e| VdbError::Io {
                file: file.clone(),
                message: e.to_string(),
            })?;
            let len = f
                .metadata()
                .map_err(|e| VdbError::Io {
                    file: file.clone(),
                    message: e.to_string(),
                })?
                .len();
            validate::validate(&mut std::io::BufReader::new(f), len)
        }
        AssetLocation::Packaged { bytes, .. } => {
            validate::validate(&mut Cursor::new(bytes.as_slice()), bytes.len() as u64)
        }
    };
    result.map_err(|message| VdbError::Invalid { file, message })
}

/// Picks the grid named `name` (any grid when empty), the `index`-th of those.
fn select<'a>(
    info: &'a FileInfo,
    file: &str,
    name: &str,
    index: Option<i32>,
) -> Result<&'a GridDesc, VdbError> {
    let not_found = |wanted: String| {
        // Distinct names in file order.
        let mut seen = std::collections::HashSet::new();
        let available: Vec<String> = info
            .grids
            .iter()
            .filter(|g| seen.insert(g.name.as_str()))
            .map(|g| g.name.clone())
            .collect();
        VdbError::GridNotFound {
            file: file.to_string(),
            wanted,
            available,
        }
    };
    let candidates: Vec<&GridDesc> = info
        .grids
        .iter()
        .filter(|g| name.is_empty() || g.name == name)
        .collect();
    let label = if name.is_empty() {
        "(any)".to_string()
    } else {
        format!("{name:?}")
    };
    match index {
        Some(i) => usize::try_from(i)
            .ok()
            .and_then(|i| candidates.get(i).copied())
            .ok_or_else(|| not_found(format!("{label} with index {i} (of {})", candidates.len()))),
        // No index: the first grid of that name; with no name either, the first float
        // grid (then the first grid, which yields a type error).
        None if name.is_empty() => candidates
            .iter()
            .find(|g| g.is_float())
            .or(candidates.first())
            .copied()
            .ok_or_else(|| not_found(label)),
        None => candidates.first().copied().ok_or_else(|| not_found(label)),
    }
}

#[cfg(nimbus_openvdb)]
fn with_openvdb_path<T>(
    loc: &AssetLocation,
    f: impl FnOnce(&str) -> Result<T, VdbError>,
) -> Result<T, VdbError> {
    let file = loc.to_string();
    let io_err = |e: std::io::Error| VdbError::Io {
        file: file.clone(),
        message: e.to_string(),
    };
    match loc {
        AssetLocation::File(path) => {
            let p = path.to_str().ok_or_else(|| VdbError::Io {
                file: file.clone(),
                message: "path is not valid UTF-8, which the OpenVDB bridge needs".into(),
            })?;
            f(p)
        }
        // OpenVDB reads files, so a package member goes through a temporary file.
        AssetLocation::Packaged { bytes, .. } => {
            use std::io::Write;
            let mut tmp = tempfile::Builder::new()
                .prefix("nimbus-")
                .suffix(".vdb")
                .tempfile()
                .map_err(io_err)?;
            tmp.write_all(bytes)
                .and_then(|_| tmp.flush())
                .map_err(io_err)?;
            let p = tmp.path().to_str().ok_or_else(|| VdbError::Io {
                file: file.clone(),
                message: "temporary path is not valid UTF-8".into(),
            })?;
            f(p)
        }
    }
}

#[cfg(nimbus_openvdb)]
fn openvdb_read(loc: &AssetLocation, desc: &GridDesc) -> Result<RawGrid, VdbError> {
    let [grid] = openvdb_read_n(loc, desc, bridge::ffi::read_float_grid)?;
    Ok(grid)
}

#[cfg(nimbus_openvdb)]
fn openvdb_read_vec3s(loc: &AssetLocation, desc: &GridDesc) -> Result<[RawGrid; 3], VdbError> {
    openvdb_read_n(loc, desc, bridge::ffi::read_vec3s_grid)
}

/// Reads `desc` with the bridge function `read` (N floats per value) into N grids
/// named as the file names the grid.
#[cfg(nimbus_openvdb)]
fn openvdb_read_n<const N: usize>(
    loc: &AssetLocation,
    desc: &GridDesc,
    read: fn(&str, &str) -> Result<bridge::ffi::GridData, cxx::Exception>,
) -> Result<[RawGrid; N], VdbError> {
    let file = loc.to_string();
    let err = |message: String| VdbError::Reader {
        file: file.clone(),
        reader: "openvdb",
        message,
    };
    let data = with_openvdb_path(loc, |p| {
        read(p, &desc.openvdb_lookup_name()).map_err(|e| err(e.what().to_string()))
    })?;
    let mut grids = bridge::to_raw_grids::<N>(data).map_err(err)?;
    for g in &mut grids {
        g.name = desc.name.clone();
    }
    Ok(grids)
}

#[cfg(nimbus_openvdb)]
fn openvdb_list(loc: &AssetLocation) -> Result<Vec<GridInfo>, VdbError> {
    let file = loc.to_string();
    let list = with_openvdb_path(loc, |p| {
        bridge::ffi::list_grids(p).map_err(|e| VdbError::Reader {
            file: file.clone(),
            reader: "openvdb",
            message: e.what().to_string(),
        })
    })?;
    Ok(list
        .into_iter()
        .map(|e| GridInfo {
            name: e.name,
            value_type: e.value_type,
            active_voxels: u64::try_from(e.active_voxels).ok(),
        })
        .collect())
}

#[cfg(not(nimbus_openvdb))]
fn openvdb_unavailable(loc: &AssetLocation) -> VdbError {
    VdbError::Unsupported {
        file: loc.to_string(),
        message: "this build of Nimbus has no OpenVDB reader; install OpenVDB (libopenvdb-dev) \
                  and rebuild (NIMBUS_OPENVDB=require)"
            .into(),
    }
}

#[cfg(not(nimbus_openvdb))]
fn openvdb_read(loc: &AssetLocation, _desc: &GridDesc) -> Result<RawGrid, VdbError> {
    Err(openvdb_unavailable(loc))
}

#[cfg(not(nimbus_openvdb))]
fn openvdb_read_vec3s(loc: &AssetLocation, _desc: &GridDesc) -> Result<[RawGrid; 3], VdbError> {
    Err(openvdb_unavailable(loc))
}

#[cfg(not(nimbus_openvdb))]
fn openvdb_list(loc: &AssetLocation) -> Result<Vec<GridInfo>, VdbError> {
    Err(openvdb_unavailable(loc))
}
