//! hdNimbus: Nimbus as a Hydra render delegate.
//!
//! The C++ half (`cpp/hydra/*.cc`, built when `NIMBUS_HYDRA` finds a USD SDK: see
//! `build.rs`) is the plug-in a host loads: the renderer plugin, render delegate, render
//! pass, render buffers and the prims Hydra syncs. It turns what Hydra hands over into
//! the plain structs of [`ffi`] and nothing more. This Rust half builds the same
//! [`nimbus::scene::Scene`] the USD reader builds ([`scene`]) and renders it through the
//! same [`nimbus::render::session::Session`] ([`renderer`]): one render pipeline, two
//! readers.

pub mod ffi;
pub mod renderer;
pub mod scene;

pub use renderer::{is_aov, new_renderer, setting_descriptors, Renderer};
