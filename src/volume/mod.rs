//! Volume data: sparse grids read from OpenVDB files, the media built on them,
//! and the majorant structure the trackers walk.

pub mod albedo;
pub mod asset;
pub mod boundary;
pub mod color_graph;
pub mod convex;
pub mod counters;
pub mod emission;
pub mod graph_density;
pub mod grid;
pub mod majorant;
pub mod medium;
pub mod procedural;
pub mod ticks;
pub mod upsample;
pub mod vdb;
pub mod velocity;
