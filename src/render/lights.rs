//! Lights as the integrator sees them: radiance already multiplied out
//! (intensity · 2^exposure · colour).

use crate::scene::Scene;
use glam::DVec3;

/// A distant light (sun). `irradiance` is what a surface facing the light receives:
/// Nimbus reads UsdLux `intensity · 2^exposure · color` of a DistantLight as that
/// irradiance, whatever the angle; the angle only spreads its directions over a cone.
pub struct Sun {
    pub direction: DVec3,
    pub irradiance: [f64; 3],
    /// cos of the half-angle of the cone (1 = a delta direction).
    pub cos_half_angle: f64,
}

/// Everything lighting the medium: suns and a constant environment (the sum of the
/// dome lights' radiance).
pub struct Lights {
    pub suns: Vec<Sun>,
    pub environment: [f64; 3],
}

impl Lights {
    pub fn from_scene(scene: &Scene) -> Lights {
        let scale = |i: f64, e: f64, c: [f64; 3]| c.map(|v| v * i * e.exp2());
        let suns = scene
            .distant_lights
            .iter()
            .map(|l| Sun {
                direction: DVec3::from_array(l.direction).normalize_or(DVec3::Z),
                irradiance: scale(l.intensity, l.exposure, l.color),
                cos_half_angle: (l.angle_degrees.clamp(0.0, 180.0).to_radians() * 0.5).cos(),
            })
            .filter(|s| s.irradiance.iter().any(|&v| v != 0.0))
            .collect();
        let mut environment = [0.0; 3];
        for d in &scene.dome_lights {
            let r = scale(d.intensity, d.exposure, d.color);
            for c in 0..3 {
                environment[c] += r[c];
            }
        }
        Lights { suns, environment }
    }

    pub fn has_environment(&self) -> bool {
        self.environment.iter().any(|&v| v != 0.0)
    }
}

impl Sun {
    /// A direction towards the sun, uniform over its cone.
    pub fn sample_direction(&self, u1: f64, u2: f64) -> DVec3 {
        if self.cos_half_angle >= 1.0 {
            return self.direction;
        }
        let cos_t = 1.0 - u1 * (1.0 - self.cos_half_angle);
        let sin_t = (1.0 - cos_t * cos_t).max(0.0).sqrt();
        let phi = 2.0 * std::f64::consts::PI * u2;
        let (t, b) = super::phase::orthonormal_basis(self.direction);
        (t * (sin_t * phi.cos()) + b * (sin_t * phi.sin()) + self.direction * cos_t).normalize()
    }
}
