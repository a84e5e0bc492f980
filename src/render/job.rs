//! A render job: a medium, lights, a camera and settings, turned into a film by the
//! integrator instantiated for the selected estimators.

use crate::render::camera::CameraRays;
use crate::render::film::Film;
use crate::render::integrator::Integrator;
use crate::render::lights::Lights;
use crate::track::{
    self, Dispatch, FreePathSampler, TrackerKind, TrackerSettings, TransmittanceEstimator,
};
use crate::volume::medium::Medium;

pub struct RenderJob<'a> {
    pub medium: &'a Medium,
    pub lights: &'a Lights,
    pub camera: &'a CameraRays,
    pub width: u32,
    pub height: u32,
    pub spp: u32,
    pub max_depth: u32,
    pub seed: u64,
    pub tracking: TrackerSettings,
}

impl RenderJob<'_> {
    /// Renders on the current rayon pool; `progress` is called once per finished row.
    pub fn render(&self, progress: &(dyn Fn() + Sync)) -> Film {
        struct Run<'j, 'p> {
            job: &'j RenderJob<'j>,
            progress: &'p (dyn Fn() + Sync),
        }
        impl Dispatch<Film> for Run<'_, '_> {
            fn run<F: FreePathSampler, E: TransmittanceEstimator>(
                self,
                free_path: F,
                transmittance: E,
            ) -> Film {
                let j = self.job;
                Integrator {
                    free_path,
                    transmittance,
                    single_channel: j.tracking.tracker == TrackerKind::NaiveDelta,
                    majorant_scale: j.tracking.majorant_scale,
                    medium: j.medium,
                    lights: j.lights,
                    camera: j.camera,
                    width: j.width,
                    height: j.height,
                    spp: j.spp,
                    max_depth: j.max_depth,
                    seed: j.seed,
                }
                .render(self.progress)
            }
        }
        track::dispatch(
            &self.tracking,
            Run {
                job: self,
                progress,
            },
        )
    }
}
