//! The integrator and everything a sample needs: camera rays, the sampler, the phase
//! function, lights, holdout geometry (ray queries), and the film that accumulates
//! pixels and AOVs.

pub mod adaptive;
pub mod analysis;
pub mod camera;
pub mod dome;
pub mod equiangular;
pub mod film;
pub mod guiding;
pub mod holdouts;
pub mod integrator;
pub mod job;
pub mod light_choice;
pub mod light_motion;
pub mod lights;
pub mod media_index;
pub mod phase;
pub mod progressive;
pub mod sampler;
pub mod session;
pub mod splits;
pub mod texture;
pub mod tiles;
