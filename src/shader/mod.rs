//! Procedural shader graphs (issue 47): the noise they use, and the graph evaluator.
//!
//! [`noise`] is Blender's Noise Texture node as Cycles 5.0 evaluates it (Perlin noise, fBM
//! and the other fractal types, Distortion, the Color output), tested value for value
//! against Blender itself in `tests/blender_noise.rs`; docs/shaders.md has the measured
//! errors and costs. [`materialx_noise`] is MaterialX's `noise3d` and `fractal3d` on the
//! same lattice noise, and its `cellnoise3d`. [`voronoi`] is Blender's Voronoi Texture (3D
//! F1 Euclidean) as Cycles evaluates it; [`math`] its Math node's operations. [`graph`] compiles a reader's node graph into a flat program,
//! evaluated per density lookup and, over [`interval`]s, per majorant cell.

pub mod graph;
pub mod interval;
pub mod materialx_noise;
pub mod math;
pub mod noise;
pub mod voronoi;
