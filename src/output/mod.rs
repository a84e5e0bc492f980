//! Writing results: the EXR image with its AOV channels, deep EXR images, and the stats
//! JSON; and the reports `nimbus info` (`describe`) and `nimbus compare` (`compare`)
//! print and the Python module returns. Files are written to a temporary file beside
//! the target and renamed into place, so a failed render never leaves a partial file
//! or clobbers an existing one.

pub mod compare;
pub mod deep;
#[cfg(nimbus_openexr)]
mod deep_bridge;
pub mod denoise;
pub mod denoise_mix;
pub mod describe;
pub mod exr;
pub mod merge;
pub mod preview;
pub mod products;
pub mod stats;

use std::io::Write;
use std::path::Path;

#[derive(Debug, thiserror::Error)]
pub enum OutputError {
    #[error("cannot write {path}: {message}")]
    Write { path: String, message: String },
    #[error("cannot read {path}: {message}")]
    Read { path: String, message: String },
}

/// Writes `path` atomically: `fill` writes into a temporary file in the same folder,
/// which is then renamed over `path` only if everything succeeded.
pub fn write_atomically(
    path: &Path,
    fill: impl FnOnce(&mut std::fs::File) -> Result<(), String>,
) -> Result<(), OutputError> {
    let err = |message: String| OutputError::Write {
        path: path.display().to_string(),
        message,
    };
    let dir = target_dir(path).map_err(err)?;
    let mut builder = tempfile::Builder::new();
    builder.prefix(".nimbus-").suffix(".tmp");
    if let Some(mode) = output_permissions(path) {
        builder.permissions(mode);
    }
    let mut tmp = builder.tempfile_in(dir).map_err(|e| {
        err(format!(
            "cannot create a temporary file in {}: {e}",
            dir.display()
        ))
    })?;
    fill(tmp.as_file_mut()).map_err(err)?;
    tmp.as_file_mut().flush().map_err(|e| err(e.to_string()))?;
    tmp.as_file().sync_all().map_err(|e| err(e.to_string()))?;
    tmp.persist(path).map_err(|e| err(e.error.to_string()))?;
    Ok(())
}

/// The mode of a result file: an existing file's own (replacing it keeps its mode),
/// else (Unix) rw-r--r-- like a file a user creates — not the temporary file's private
/// 0600. `None`: the temporary file's default.
fn output_permissions(path: &Path) -> Option<std::fs::Permissions> {
    if let Ok(meta) = std::fs::metadata(path) {
        return Some(meta.permissions());
    }
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        Some(std::fs::Permissions::from_mode(0o644))
    }
    #[cfg(not(unix))]
    {
        None
    }
}

/// Checks up front that `path` can be written (its folder exists and accepts a file),
/// so a long render does not fail only at the end.
pub fn check_writable(path: &Path) -> Result<(), OutputError> {
    let err = |message: String| OutputError::Write {
        path: path.display().to_string(),
        message,
    };
    let dir = target_dir(path).map_err(err)?;
    tempfile::Builder::new()
        .prefix(".nimbus-check-")
        .tempfile_in(dir)
        .map(drop)
        .map_err(|e| {
            err(format!(
                "the folder {} does not accept new files: {e}",
                dir.display()
            ))
        })
}

/// The folder a new `path` goes into; an existing directory at `path` is an error.
fn target_dir(path: &Path) -> Result<&Path, String> {
    if path.is_dir() {
        return Err("it is a directory".into());
    }
    Ok(match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    })
}
