//! hdNimbus: Nimbus as a Hydra render delegate.
//!
//! The C++ half (`cpp/hydra/*.cc`, built when `NIMBUS_HYDRA` finds a USD SDK: see
//! `build.rs`) is the plug-in a host loads: the renderer plugin, render delegate, render
//! pass, render buffers and the prims Hydra syncs. It turns what Hydra hands over into
//! the plain structs of [`ffi`] and nothing more. This Rust half builds the same
//! [`nimbus::scene::Scene`] the USD reader builds ([`scene`]) and renders it through the
//! same [`nimbus::render::session::Session`] ([`renderer`]): one render pipeline, two
//! readers.
//!
//! The modules, from the boundary down:
//! - [`ffi`]: the cxx bridge (the plain structs and the entry points C++ calls); thin
//!   functions that convert and call down, under a panic guard
//! - [`renderer`]: the progressive render of a scene; it uses nothing of the bridge
//! - [`scene`]: the bridge's structs as a `Scene`, and the render settings read
//!
//! `scene` uses the bridge's structs, which cxx makes live in `ffi`'s child module
//! `ffi::bridge`: the one cycle of files, explained where `scene` imports them.

pub mod ffi;
pub mod renderer;
pub mod scene;

pub use ffi::{is_aov, new_renderer, setting_descriptors, Renderer};
