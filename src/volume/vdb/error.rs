//! The one error type of VDB reading and writing; every variant names the file.

/// Errors of VDB reading and writing. Every variant names the file.
#[derive(Debug, thiserror::Error)]
pub enum VdbError {
    /// The file is not a valid VDB file (empty, truncated, bad magic, corrupt header).
    #[error("{file}: {message}")]
    Invalid { file: String, message: String },
    /// The file could not be opened or read.
    #[error("{file}: {message}")]
    Io { file: String, message: String },
    /// No grid matches the requested name / index.
    #[error("{file}: grid {wanted} not found; available grids: {}", list_or_none(.available))]
    GridNotFound {
        file: String,
        wanted: String,
        available: Vec<String>,
    },
    /// The grid exists but does not hold the expected values ("float", "Vec3s", ...).
    #[error("{file}: grid {grid:?} is {found}, expected {expected}")]
    WrongType {
        file: String,
        grid: String,
        found: String,
        expected: &'static str,
    },
    /// The chosen reader cannot read this (valid) file; the message says what to do.
    #[error("{file}: {message}")]
    Unsupported { file: String, message: String },
    /// The reader failed on a file that passed validation.
    #[error("{file}: {reader} failed: {message}")]
    Reader {
        file: String,
        reader: &'static str,
        message: String,
    },
    /// Writing a VDB file failed.
    #[error("{file}: cannot write VDB: {message}")]
    Write { file: String, message: String },
}

fn list_or_none(names: &[String]) -> String {
    // A file may hold thousands of grids; keep the message readable.
    const SHOWN: usize = 20;
    if names.is_empty() {
        return "(none)".into();
    }
    let mut list = names
        .iter()
        .take(SHOWN)
        .map(|n| format!("{n:?}"))
        .collect::<Vec<_>>()
        .join(", ");
    if names.len() > SHOWN {
        list += &format!(" and {} more", names.len() - SHOWN);
    }
    list
}
