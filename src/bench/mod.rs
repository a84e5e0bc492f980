pub mod error;
pub mod grid;
pub mod reference;
pub mod stats;
