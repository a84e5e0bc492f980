//! USD stage → [`Scene`]: everything the renderer needs, in plain Rust types
//! ([`description`]), with world-space transforms already evaluated and asset paths
//! already resolved.
//!
//! Loading lives in [`stage`] (UsdLux lights in `lights`, other tools' volume materials
//! in [`shading`], holdout gprims in [`geometry`], what it does not read besides lights
//! in `unsupported`, the attribute readers and errors they share in `attrs`); Nimbus' codeless schema (see `schemas/`) is registered by
//! [`schema`].

mod attrs;
pub mod blender_color;
pub mod blender_graph;
mod camera;
pub mod defaults;
pub mod description;
pub mod diagnostics;
pub mod fog;
pub mod geometry;
mod instancer;
mod lights;
pub mod materialx_graph;
mod motion;
pub mod schema;
pub mod shader_network;
pub mod shading;
pub mod stage;
mod unsupported;

pub use attrs::SceneError;
pub use description::*;
pub use diagnostics::{Diagnostics, StageWarning};
pub use stage::{load_stage, LoadOptions};
