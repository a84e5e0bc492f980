//! Procedural shader graphs (issue 47); this is the noise they use.
//!
//! [`noise`] is Blender's Noise Texture node as Cycles 5.0 evaluates it (Perlin noise, fBM
//! and the other fractal types, Distortion, the Color output), tested value for value
//! against Blender itself in `tests/blender_noise.rs`; docs/shaders.md has the measured
//! errors and costs. [`materialx_noise`] is MaterialX's `noise3d` and `fractal3d` on the
//! same lattice noise.

pub mod materialx_noise;
pub mod noise;
