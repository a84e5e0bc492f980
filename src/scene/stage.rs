//! Loading a USD stage into a [`Scene`].
//! STUB (to be implemented).

use super::*;
use std::path::Path;

#[derive(Clone, Debug, Default)]
pub struct LoadOptions {
    /// Time code to evaluate at (`--frame`); `None` = the stage's default time.
    pub frame: Option<f64>,
    /// Camera prim path override (`--camera`).
    pub camera: Option<String>,
}

#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    #[error("{path}: {message}")]
    Stage { path: String, message: String },
    #[error("{prim}: {message}")]
    Prim { prim: String, message: String },
}

pub fn load_stage(path: &Path, _opts: &LoadOptions) -> Result<Scene, SceneError> {
    Err(SceneError::Stage {
        path: path.display().to_string(),
        message: "not implemented".into(),
    })
}
