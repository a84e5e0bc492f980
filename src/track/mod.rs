//! Free-path sampling and transmittance estimation: the null-collision family of
//! Kutz et al. 2017 (see `../shared/docs/tracking.md`).
//!
//! Every tracker walks the [`Segment`](crate::volume::majorant::Segment)s the majorant
//! structure hands out (the exponential is memoryless, so sampling restarts at every
//! cell boundary) and decides at each tentative collision between absorption,
//! scattering and a null collision. Trackers implement [`FreePathSampler`](free_path::FreePathSampler), shadow-ray
//! estimators [`TransmittanceEstimator`](free_path::TransmittanceEstimator); tracker
//! selection and dispatch are in [`select`]; the integrator is generic over both and is
//! instantiated once per render, so the collision loops have no dynamic dispatch.

pub mod collision_select;
pub mod decomposition;
pub mod delta;
pub mod free_path;
pub mod grey;
pub mod race;
pub mod ratio;
pub mod scheme;
pub mod select;
pub mod spectral;
pub mod spectral_mis;
pub mod telescoping;
pub mod track_length;
