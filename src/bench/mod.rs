//! Benchmark machinery behind `nimbus bench` (measurements and their statistics); the
//! CLI (`cli::bench*`) parses the arguments and prints what these return.

pub mod cumulus;
pub mod error;
pub mod grid;
pub mod octree_tables;
pub mod reference;
pub mod stats;
