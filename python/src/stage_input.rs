//! The stage argument of `render` and `info`: a path, or usda text. The library reads
//! stages from files only (relative asset paths resolve against the file's folder), so
//! text becomes a temporary file where the caller says its assets are.

use crate::errors::{OutputError, SettingsError};
use pyo3::prelude::*;
use std::path::PathBuf;

/// A stage given as usda text: written to a hidden temporary `.usda` in `base_dir`
/// (default: the working directory) so relative asset paths resolve against it; the
/// file is removed when this is dropped (right after the stage is read).
pub fn stage_file(
    stage: Option<PathBuf>,
    stage_text: Option<String>,
    base_dir: Option<PathBuf>,
) -> PyResult<(PathBuf, Option<tempfile::NamedTempFile>)> {
    match (stage, stage_text) {
        (Some(p), None) => Ok((p, None)),
        (None, Some(text)) => {
            let dir = base_dir.unwrap_or_else(|| PathBuf::from("."));
            let mut f = tempfile::Builder::new()
                .prefix(".nimbus-stage-")
                .suffix(".usda")
                .tempfile_in(&dir)
                .map_err(|e| {
                    OutputError::new_err(format!(
                        "cannot write the stage text to a temporary file in {}: {e}",
                        dir.display()
                    ))
                })?;
            use std::io::Write;
            f.write_all(text.as_bytes())
                .and_then(|_| f.flush())
                .map_err(|e| OutputError::new_err(format!("{}: {e}", f.path().display())))?;
            Ok((f.path().to_path_buf(), Some(f)))
        }
        (Some(_), Some(_)) => Err(SettingsError::new_err(
            "give either a stage path or stage_text, not both",
        )),
        (None, None) => Err(SettingsError::new_err(
            "no stage: give a path or stage_text",
        )),
    }
}
