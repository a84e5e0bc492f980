//! Nimbus: a heterogeneous-volume renderer built around the free-path samplers of
//! Kutz et al. 2017 ("Spectral and Decomposition Tracking").
//!
//! The module tree follows the data flow:
//! USD stage → [`scene`] → [`volume`] grids → majorant structure → [`track`]ers →
//! [`render`] integrator → film/AOVs → [`output`] EXR.

/// Benchmark machinery (measurements and their statistics) behind `nimbus bench`.
pub mod bench;
pub mod cli;
pub mod color;
pub mod farm;
pub mod motion;
pub mod output;
pub mod render;
pub mod scene;
pub mod shader;
pub mod track;
pub mod volume;
