//! OpenVDB file reading: validation first, then either the C++ OpenVDB bridge
//! (preferred) or the pure-Rust `vdb-rs` fallback. Both produce a [`RawGrid`].
//!
//! STUB (to be implemented): see the interface below.

use crate::scene::AssetLocation;
use crate::volume::grid::RawGrid;

/// Which reader decodes VDB files in this build.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Reader {
    /// OpenVDB through the C++ bridge in `cpp/`.
    OpenVdb,
    /// The pure-Rust `vdb-rs` crate.
    VdbRs,
}

impl Reader {
    pub fn name(self) -> &'static str {
        match self {
            Reader::OpenVdb => "openvdb",
            Reader::VdbRs => "vdb-rs",
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

#[derive(Debug, thiserror::Error)]
pub enum VdbError {
    #[error("{file}: {message}")]
    Invalid { file: String, message: String },
}

/// The reader this build uses by default.
pub fn active_reader() -> Reader {
    Reader::VdbRs
}

/// Lists the grids of a file.
pub fn list_grids(loc: &AssetLocation) -> Result<Vec<GridInfo>, VdbError> {
    Err(VdbError::Invalid {
        file: loc.to_string(),
        message: "not implemented".into(),
    })
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
    _reader: Reader,
    loc: &AssetLocation,
    _name: &str,
    _index: Option<i32>,
) -> Result<RawGrid, VdbError> {
    Err(VdbError::Invalid {
        file: loc.to_string(),
        message: "not implemented".into(),
    })
}
