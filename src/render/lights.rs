//! Lights as the integrator sees them, with UsdLux's units already applied.
//!
//! Every UsdLux light's emission scale is `intensity · 2^exposure · color` (nits when
//! not normalized). `inputs:normalize` divides it by the light's size so its power does
//! not depend on that size:
//!
//! - SphereLight: by its world-space surface area 4πr²; RectLight: by its world-space
//!   area (the parallelogram its transformed edges span);
//! - DistantLight: by UsdLux's `sizeFactor(θmax) = π sin²θmax` (θmax ≤ π/2, else
//!   `π (2 − sin²θmax)`), θmax = angle/2: the projected solid angle of the sun disk, so
//!   `intensity` becomes the illuminance on a surface facing the light. A zero angle is a
//!   delta light whose illuminance is the scale, normalized or not;
//! - DomeLight: not affected.
//!
//! With `inputs:enableColorTemperature`, the scale is also multiplied by UsdLux's colour
//! of `inputs:colorTemperature` ([`usd_blackbody_rgb`]).
//!
//! Sphere and rect lights are reached by next-event estimation only: they do not
//! occlude the medium and camera or scattered rays do not see them.

use crate::color::{emission_scale, luminance, usd_blackbody_rgb};
pub use crate::render::dome::EnvMap;
use crate::render::phase::{azimuth, orthonormal_basis, sample_sphere, INV_4PI};
use crate::scene::Scene;
use glam::{DMat3, DVec3};
use std::f64::consts::PI;

/// A distant light (sun): a disk of directions of half-angle θmax around `direction`.
pub struct Sun {
    pub direction: DVec3,
    /// ∫ L dω over the disk: what next-event estimation multiplies by phase × transmittance
    /// (for a small disk, the irradiance on a surface facing the light).
    pub irradiance: [f64; 3],
    /// cos θmax (1 = a delta direction).
    pub cos_half_angle: f64,
}

/// A spherical emitter (or, with `radius` 0, a point with `intensity` L·πr²).
pub struct SphereEmitter {
    pub center: DVec3,
    /// World-space radius (0 for a point).
    pub radius: f64,
    /// Radiance of the surface; for a point, the radiant intensity (per steradian).
    pub radiance: [f64; 3],
}

/// A one-sided rectangular emitter: corner `center − (edge_u + edge_v)/2`.
pub struct RectEmitter {
    pub center: DVec3,
    pub edge_u: DVec3,
    pub edge_v: DVec3,
    /// Unit normal of the emitting side (the light's world −Z).
    pub normal: DVec3,
    pub area: f64,
    pub radiance: [f64; 3],
}

/// Everything lighting the medium. The environment is `environment` (the sum of
/// untextured dome lights) plus every textured dome in `env_maps`.
#[derive(Default)]
pub struct Lights {
    pub suns: Vec<Sun>,
    pub environment: [f64; 3],
    pub env_maps: Vec<EnvMap>,
    pub spheres: Vec<SphereEmitter>,
    pub rects: Vec<RectEmitter>,
    /// Which scene light each emitter came from, for the light-group AOVs.
    pub sources: LightSources,
}

/// The scene light (its index in [`Scene::lights`]) behind each emitter of [`Lights`],
/// list by list; the untextured domes keep their own emission so the environment's
/// constant part can be split among them. Empty for lights built by hand (tests):
/// their contributions then feed no split layer.
#[derive(Clone, Debug, Default)]
pub struct LightSources {
    pub suns: Vec<usize>,
    pub spheres: Vec<usize>,
    pub rects: Vec<usize>,
    pub env_maps: Vec<usize>,
    /// (source, emission scale) of each untextured dome, which `environment` sums.
    pub constant_domes: Vec<(usize, [f64; 3])>,
}

/// A source index no split layer gathers.
pub const NO_SOURCE: usize = usize::MAX;

impl LightSources {
    pub fn sun(&self, i: usize) -> usize {
        self.suns.get(i).copied().unwrap_or(NO_SOURCE)
    }

    pub fn sphere(&self, i: usize) -> usize {
        self.spheres.get(i).copied().unwrap_or(NO_SOURCE)
    }

    pub fn rect(&self, i: usize) -> usize {
        self.rects.get(i).copied().unwrap_or(NO_SOURCE)
    }
}

#[derive(Debug, thiserror::Error)]
#[error("{prim}: {message}")]
pub struct LightError {
    pub prim: String,
    pub message: String,
}

/// [`emission_scale`] times, when `inputs:enableColorTemperature` is on, the colour
/// of `colorTemperature` ([`usd_blackbody_rgb`]).
pub fn light_scale(
    intensity: f64,
    exposure: f64,
    color: [f64; 3],
    kelvin: Option<f64>,
) -> [f64; 3] {
    let s = emission_scale(intensity, exposure, color);
    match kelvin {
        Some(k) => {
            let t = usd_blackbody_rgb(k);
            [0, 1, 2].map(|c| s[c] * t[c])
        }
        None => s,
    }
}

/// UsdLux's normalization factor for a distant light of half-angle `theta_max`.
pub fn distant_size_factor(theta_max: f64) -> f64 {
    let s2 = theta_max.sin().powi(2);
    if theta_max <= 0.0 {
        1.0
    } else if theta_max <= PI / 2.0 {
        PI * s2
    } else {
        PI * (2.0 - s2)
    }
}

fn nonzero(c: &[f64; 3]) -> bool {
    c.iter().any(|&v| v != 0.0)
}

impl Lights {
    /// The scene's lights; reads dome textures (errors name the light and the file).
    pub fn from_scene(scene: &Scene) -> Result<Lights, LightError> {
        let mut lights = Lights::default();
        // Scene light indices in `Scene::lights` order: distant, dome, sphere, rect.
        let mut next = 0..;
        for l in &scene.distant_lights {
            let source = next.next().unwrap_or(NO_SOURCE);
            let s = light_scale(l.intensity, l.exposure, l.color, l.color_temperature);
            let theta = l.angle_degrees.clamp(0.0, 360.0).to_radians() * 0.5;
            let cos_half_angle = theta.cos();
            let irradiance = if theta <= 0.0 {
                s
            } else {
                let radiance = match l.normalize {
                    true => s.map(|v| v / distant_size_factor(theta)),
                    false => s,
                };
                let solid_angle = 2.0 * PI * (1.0 - cos_half_angle);
                radiance.map(|v| v * solid_angle)
            };
            if nonzero(&irradiance) {
                lights.sources.suns.push(source);
                lights.suns.push(Sun {
                    direction: DVec3::from_array(l.direction).normalize_or(DVec3::Z),
                    irradiance,
                    cos_half_angle,
                });
            }
        }
        for d in &scene.dome_lights {
            let source = next.next().unwrap_or(NO_SOURCE);
            let s = light_scale(d.intensity, d.exposure, d.color, d.color_temperature);
            let map = match &d.texture_file {
                None => None,
                Some(file) => Some(EnvMap::load(d, file, s).map_err(|message| LightError {
                    prim: d.prim_path.clone(),
                    message,
                })?),
            };
            // A texture of one colour is the constant dome of that colour, bit for bit.
            let (s, map) = match map {
                Some(map) => map.constant().map_or((s, Some(map)), |c| (c, None)),
                None => (s, None),
            };
            match map {
                None => {
                    for c in 0..3 {
                        lights.environment[c] += s[c];
                    }
                    lights.sources.constant_domes.push((source, s));
                }
                Some(map) => {
                    if map.power > 0.0 {
                        lights.sources.env_maps.push(source);
                        lights.env_maps.push(map);
                    }
                }
            }
        }
        for l in &scene.sphere_lights {
            let source = next.next().unwrap_or(NO_SOURCE);
            let m = l.light_to_world;
            let scale = DMat3::from_mat4(m).determinant().abs().cbrt();
            let r = l.radius * scale;
            let s = light_scale(l.intensity, l.exposure, l.color, l.color_temperature);
            let point = l.treat_as_point || r == 0.0;
            let radiance = match (point, l.normalize) {
                // Surface radiance, divided by the area 4πr² when normalized.
                (false, true) => s.map(|v| v / (4.0 * PI * r * r)),
                (false, false) => s,
                // A point keeps the sphere's far field, intensity L·πr²: s/4 when
                // normalized (whatever r), s·πr² otherwise.
                (true, true) => s.map(|v| v / 4.0),
                (true, false) => s.map(|v| v * PI * r * r),
            };
            let emitter = SphereEmitter {
                center: m.transform_point3(DVec3::ZERO),
                radius: if point { 0.0 } else { r },
                radiance,
            };
            if nonzero(&emitter.radiance) {
                lights.sources.spheres.push(source);
                lights.spheres.push(emitter);
            }
        }
        for l in &scene.rect_lights {
            let source = next.next().unwrap_or(NO_SOURCE);
            let m = l.light_to_world;
            let edge_u = m.transform_vector3(DVec3::X * l.width);
            let edge_v = m.transform_vector3(DVec3::Y * l.height);
            let cross = edge_u.cross(edge_v);
            let area = cross.length();
            let s = light_scale(l.intensity, l.exposure, l.color, l.color_temperature);
            let radiance = match l.normalize {
                true if area > 0.0 => s.map(|v| v / area),
                _ => s,
            };
            if area > 0.0 && nonzero(&radiance) {
                lights.sources.rects.push(source);
                lights.rects.push(RectEmitter {
                    center: m.transform_point3(DVec3::ZERO),
                    edge_u,
                    edge_v,
                    // Emits along its local −Z.
                    normal: -cross / area,
                    area,
                    radiance,
                });
            }
        }
        Ok(lights)
    }

    pub fn has_environment(&self) -> bool {
        nonzero(&self.environment) || !self.env_maps.is_empty()
    }

    /// Whether scattering vertices sample the environment (next-event estimation,
    /// combined with phase sampling by MIS): only a textured dome needs it. A constant
    /// environment is left to the phase-sampled ray that continues the path, whose
    /// density is proportional to what it collects.
    pub fn environment_nee(&self) -> bool {
        !self.env_maps.is_empty()
    }

    /// Radiance arriving from world direction `w` (unit) from the environment.
    #[inline]
    pub fn environment_radiance(&self, w: DVec3) -> [f64; 3] {
        let mut l = self.environment;
        for m in &self.env_maps {
            let t = m.radiance(w);
            for c in 0..3 {
                l[c] += t[c];
            }
        }
        l
    }

    /// Calls `part(source, radiance)` for each dome's share of
    /// [`Lights::environment_radiance`] in direction `w`: each untextured dome, then
    /// each textured one. With no sources recorded (lights built by hand), nothing.
    pub fn environment_parts(&self, w: DVec3, mut part: impl FnMut(usize, [f64; 3])) {
        for &(source, le) in &self.sources.constant_domes {
            part(source, le);
        }
        for (m, &source) in self.env_maps.iter().zip(&self.sources.env_maps) {
            part(source, m.radiance(w));
        }
    }

    /// Selection weights of the environment's sampling strategies: the constant part
    /// first, then each map, proportional to their power (∫ luminance dω).
    fn constant_power(&self) -> f64 {
        if nonzero(&self.environment) {
            (luminance(self.environment).abs() * 4.0 * PI).max(1e-300)
        } else {
            0.0
        }
    }

    fn total_power(&self) -> f64 {
        self.constant_power() + self.env_maps.iter().map(|m| m.power).sum::<f64>()
    }

    /// Density (per steradian) with which [`Lights::sample_environment`] picks `w`.
    pub fn environment_pdf(&self, w: DVec3) -> f64 {
        if self.env_maps.is_empty() {
            return INV_4PI;
        }
        let total = self.total_power();
        let mut pdf = self.constant_power() / total * INV_4PI;
        for m in &self.env_maps {
            pdf += m.power / total * m.pdf(w);
        }
        pdf
    }

    /// A direction towards the environment, its radiance and its density: one strategy
    /// is chosen by power with `u1` (rescaled and reused), then sampled.
    pub fn sample_environment(&self, u1: f64, u2: f64) -> (DVec3, [f64; 3], f64) {
        if self.env_maps.is_empty() {
            let w = sample_sphere(u1, u2);
            return (w, self.environment, INV_4PI);
        }
        let total = self.total_power();
        let mut acc = self.constant_power() / total;
        let w = if u1 < acc {
            sample_sphere(u1 / acc, u2)
        } else {
            let mut chosen = self.env_maps.len() - 1;
            let mut lo = acc;
            for (i, m) in self.env_maps.iter().enumerate() {
                let p = m.power / total;
                if u1 < acc + p || i + 1 == self.env_maps.len() {
                    chosen = i;
                    lo = acc;
                    acc += p;
                    break;
                }
                acc += p;
            }
            let u = ((u1 - lo) / (acc - lo).max(1e-300)).clamp(0.0, 1.0 - f64::EPSILON);
            self.env_maps[chosen].sample(u, u2)
        };
        (w, self.environment_radiance(w), self.environment_pdf(w))
    }
}

impl Sun {
    /// A direction towards the sun, uniform over its disk.
    pub fn sample_direction(&self, u1: f64, u2: f64) -> DVec3 {
        if self.cos_half_angle >= 1.0 {
            return self.direction;
        }
        cone_direction(self.direction, self.cos_half_angle, u1, u2)
    }
}

/// A direction uniform over the cone of `cos_max` around unit `axis`.
fn cone_direction(axis: DVec3, cos_max: f64, u1: f64, u2: f64) -> DVec3 {
    let cos_t = 1.0 - u1 * (1.0 - cos_max);
    let sin_t = (1.0 - cos_t * cos_t).max(0.0).sqrt();
    let (cos_phi, sin_phi) = azimuth(u2);
    let (t, b) = orthonormal_basis(axis);
    (t * (sin_t * cos_phi) + b * (sin_t * sin_phi) + axis * cos_t).normalize()
}

/// One light sample seen from a point: direction, distance to the emitter, and the
/// radiance already divided by the direction's density (0 when the sample misses).
pub struct LightSample {
    pub wi: DVec3,
    pub distance: f64,
    pub weight: [f64; 3],
}

impl SphereEmitter {
    /// Samples the sphere from `p`: uniform over the cone it subtends (exact for the
    /// radiance a uniform sphere sends), or the point itself. Points inside the
    /// sphere see no emission (it emits outwards).
    pub fn sample(&self, p: DVec3, u1: f64, u2: f64) -> Option<LightSample> {
        let to_c = self.center - p;
        let d2 = to_c.length_squared();
        let d = d2.sqrt();
        if d <= self.radius || d == 0.0 {
            return None;
        }
        let axis = to_c / d;
        if self.radius == 0.0 {
            return Some(LightSample {
                wi: axis,
                distance: d,
                weight: self.radiance.map(|v| v / d2),
            });
        }
        let sin2_max = (self.radius * self.radius / d2).min(1.0);
        let cos_max = (1.0 - sin2_max).sqrt();
        let wi = cone_direction(axis, cos_max, u1, u2);
        let cos_t = wi.dot(axis);
        // Nearest intersection with the sphere along wi.
        let disc = (self.radius * self.radius - d2 * (1.0 - cos_t * cos_t)).max(0.0);
        let distance = (d * cos_t - disc.sqrt()).max(0.0);
        let solid_angle = 2.0 * PI * (1.0 - cos_max);
        Some(LightSample {
            wi,
            distance,
            weight: self.radiance.map(|v| v * solid_angle),
        })
    }
}

impl RectEmitter {
    /// Samples a point uniformly on the rectangle; density converted to solid angle.
    pub fn sample(&self, p: DVec3, u1: f64, u2: f64) -> Option<LightSample> {
        let q = self.center + self.edge_u * (u1 - 0.5) + self.edge_v * (u2 - 0.5);
        let v = q - p;
        let d2 = v.length_squared();
        if d2 == 0.0 {
            return None;
        }
        let d = d2.sqrt();
        let wi = v / d;
        let cos_l = -wi.dot(self.normal);
        if cos_l <= 0.0 {
            // The back of the rectangle does not emit.
            return None;
        }
        let g = cos_l * self.area / d2;
        Some(LightSample {
            wi,
            distance: d,
            weight: self.radiance.map(|r| r * g),
        })
    }
}
