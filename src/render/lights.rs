//! Lights as the integrator sees them, with UsdLux's units already applied.
//!
//! Every UsdLux light's emission scale is `intensity · 2^exposure · color` (nits when
//! not normalized). `inputs:normalize` divides it by the light's size so its power does
//! not depend on that size:
//!
//! - SphereLight: by its world-space surface area 4πr²; RectLight: by its world-space
//!   area (the parallelogram its transformed edges span); DiskLight: by its world-space
//!   area (π |x × y| for its transformed radius vectors x, y: the ellipse a transform
//!   makes of it); CylinderLight: by its world-space side area (the caps do not emit);
//! - DistantLight: by UsdLux's `sizeFactor(θmax) = π sin²θmax` (θmax ≤ π/2, else
//!   `π (2 − sin²θmax)`), θmax = angle/2: the projected solid angle of the sun disk, so
//!   `intensity` becomes the illuminance on a surface facing the light. A zero angle is a
//!   delta light whose illuminance is the scale, normalized or not;
//! - DomeLight: not affected.
//!
//! With `inputs:enableColorTemperature`, the scale is also multiplied by UsdLux's colour
//! of `inputs:colorTemperature` ([`usd_blackbody_rgb`]).
//!
//! A light of no area (a zero-radius sphere or cylinder) has no size to normalize by:
//! it emits what the normalized light of its shape emits, whatever `normalize` says
//! (UsdLux: lights without a size take sizeFactor = 1), so a point is a sphere of
//! intensity s/4 and a line a cylinder of intensity s·sin θ/π. `treatAsPoint` and
//! `treatAsLine` on a light with a size keep its far field: s·πr² (s/4 normalized) for
//! a point, s·2rℓ·sin θ (s·sin θ/π normalized) for a line. `inputs:diffuse`
//! multiplies every light but a dome (volume scattering is the medium's diffuse
//! response). ShapingAPI ([`Shaping`]) multiplies the emission leaving in each
//! direction; linking ([`Link`]) says which volumes a light lights and which
//! volumes and holdouts shadow it.
//!
//! Sphere, rect, disk and cylinder lights are reached by next-event estimation only:
//! they do not occlude the medium and camera or scattered rays do not see them.

use crate::color::{emission_scale, luminance, usd_blackbody_rgb};
use crate::motion::TransformMotion;
pub use crate::render::dome::EnvMap;
use crate::render::equiangular::{Cone, LocalLight};
use crate::render::holdouts::Holdouts;
use crate::render::light_motion::LightMotion;
use crate::render::phase::{azimuth, orthonormal_basis, sample_sphere, INV_4PI};
use crate::scene::{Collection, LightControls, Scene};
use glam::{DMat3, DMat4, DVec3};
use std::f64::consts::PI;

/// A distant light (sun): a disk of directions of half-angle θmax around `direction`.
pub struct Sun {
    pub direction: DVec3,
    /// ∫ L dω over the disk: what next-event estimation multiplies by phase × transmittance
    /// (for a small disk, the irradiance on a surface facing the light).
    pub irradiance: [f64; 3],
    /// cos θmax (1 = a delta direction).
    pub cos_half_angle: f64,
    pub shaping: Option<Shaping>,
    pub link: Link,
}

impl Default for Sun {
    /// A delta sun straight up with no light.
    fn default() -> Self {
        Sun {
            direction: DVec3::Y,
            irradiance: [0.0; 3],
            cos_half_angle: 1.0,
            shaping: None,
            link: Link::default(),
        }
    }
}

/// A spherical emitter (or, with `radius` 0, a point with `intensity` L·πr²).
#[derive(Default)]
pub struct SphereEmitter {
    pub center: DVec3,
    /// World-space radius (0 for a point).
    pub radius: f64,
    /// Radiance of the surface; for a point, the radiant intensity (per steradian).
    pub radiance: [f64; 3],
    /// Whether points inside the sphere see its radiance (`nimbus:lightsInterior`):
    /// from every direction, as if its surface also emitted inwards (never a point's).
    pub interior: bool,
    pub shaping: Option<Shaping>,
    pub link: Link,
    /// How it moves over the shutter, when it does.
    pub motion: Option<LightMotion>,
}

/// A one-sided rectangular emitter: corner `center − (edge_u + edge_v)/2`.
#[derive(Default)]
pub struct RectEmitter {
    pub center: DVec3,
    pub edge_u: DVec3,
    pub edge_v: DVec3,
    /// Unit normal of the emitting side (the light's world −Z).
    pub normal: DVec3,
    pub area: f64,
    pub radiance: [f64; 3],
    pub shaping: Option<Shaping>,
    pub link: Link,
    /// How it moves over the shutter, when it does.
    pub motion: Option<LightMotion>,
}

/// A one-sided disk emitter, or the ellipse a transform makes of it: the points
/// `center + x·a + y·b` with x² + y² ≤ 1.
#[derive(Default)]
pub struct DiskEmitter {
    pub center: DVec3,
    /// The transformed radius vectors along the light's local X and Y.
    pub a: DVec3,
    pub b: DVec3,
    /// Unit normal of the emitting side (the light's world −Z).
    pub normal: DVec3,
    /// World-space area π |a × b|.
    pub area: f64,
    pub radiance: [f64; 3],
    pub shaping: Option<Shaping>,
    pub link: Link,
    /// How it moves over the shutter, when it does.
    pub motion: Option<LightMotion>,
}

/// The side of a cylinder (or the elliptic cylinder a transform makes of it):
/// `center + axis·(u − ½) + y·cos φ + z·sin φ`, u ∈ [0, 1], φ ∈ [0, 2π), emitting
/// outwards. With zero `y` and `z` it is a line: see [`CylinderEmitter::line`].
#[derive(Default)]
pub struct CylinderEmitter {
    pub center: DVec3,
    /// The whole length, along the light's local X.
    pub axis: DVec3,
    /// `axis` normalized, once, for the line's sin θ per sample.
    pub axis_unit: DVec3,
    /// The transformed radius vectors along the light's local Y and Z.
    pub y: DVec3,
    pub z: DVec3,
    /// World-space side area.
    pub area: f64,
    /// Radiance of the side.
    pub radiance: [f64; 3],
    /// A line (`treatAsLine` or zero radius): the radiant intensity leaving the whole
    /// line at angle θ to its axis is `line_intensity · sin θ`, spread evenly along it.
    pub line: bool,
    pub line_intensity: [f64; 3],
    pub shaping: Option<Shaping>,
    pub link: Link,
    /// How it moves over the shutter, when it does.
    pub motion: Option<LightMotion>,
}

/// UsdLuxShapingAPI as a factor on the emission leaving a light in direction e
/// (the docs of `inputs:shaping:*`, as adopted from the UsdLux clarification):
///
/// - focus: focusFactor = |e · axis|^focus, focusColor = lerp(focusFactor, focusTint, 1);
/// - cone: θ = acos(e · axis), θcutoff = coneAngle, θsmoothStart = lerp(softness,
///   θcutoff, 0); the emission is multiplied by 1 − smoothstep(θ, θsmoothStart,
///   θcutoff), which is exactly 0 past the cutoff (and, with softness 0, exactly 1
///   inside it).
///
/// `axis` is the light's world −Z, for every light type, as hdEmbree (OpenUSD's
/// reference implementation) takes it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Shaping {
    pub axis: DVec3,
    /// `focus` (0 = none).
    pub focus: f64,
    pub focus_tint: [f64; 3],
    /// θcutoff and θsmoothStart, radians (cutoff ≥ π: no cone).
    pub cutoff: f64,
    pub smooth_start: f64,
}

impl Shaping {
    /// The shaping of a light with `light_to_world`; `None` when it changes nothing
    /// (no focus, a cone of 180° or more).
    pub fn new(s: &crate::scene::Shaping, light_to_world: &DMat4) -> Option<Shaping> {
        let axis = light_to_world
            .transform_vector3(DVec3::NEG_Z)
            .try_normalize()?;
        let cutoff = s.cone_angle.to_radians();
        let softness = s.cone_softness.clamp(0.0, 1.0);
        let shaping = Shaping {
            axis,
            focus: s.focus.max(0.0),
            focus_tint: s.focus_tint,
            cutoff,
            smooth_start: cutoff * (1.0 - softness),
        };
        (shaping.focus > 0.0 || shaping.cutoff < PI).then_some(shaping)
    }

    /// The factor on emission leaving along unit `e` (each channel).
    #[inline]
    pub fn factor(&self, e: DVec3) -> [f64; 3] {
        let cos = e.dot(self.axis).clamp(-1.0, 1.0);
        let cone = if self.cutoff < PI {
            1.0 - smoothstep(cos.acos(), self.smooth_start, self.cutoff)
        } else {
            1.0
        };
        if self.focus > 0.0 {
            let f = cos.abs().powf(self.focus);
            self.focus_tint.map(|t| cone * (t + f * (1.0 - t)))
        } else {
            [cone; 3]
        }
    }
}

/// Hermite smoothstep of `t` over [lo, hi]; with lo = hi, 0 up to and including lo and
/// 1 past it (as hdEmbree decides the degenerate case).
fn smoothstep(t: f64, lo: f64, hi: f64) -> f64 {
    let len = hi - lo;
    if len <= 0.0 {
        return if t <= lo { 0.0 } else { 1.0 };
    }
    let x = ((t - lo) / len).clamp(0.0, 1.0);
    x * x * (3.0 - 2.0 * x)
}

/// Light and shadow linking of one light, over the render's media (bit i = medium i,
/// at most 64) and holdouts. The default links everything: a stage without linking
/// pays one mask test per light sample.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Link {
    /// Media the light illuminates (`collection:lightLink`).
    pub lit: u64,
    /// Media that shadow it (`collection:shadowLink`; none with `shadow:enable` off).
    pub shadowing: u64,
    /// Holdouts that shadow it.
    pub holdouts: HoldoutSet,
}

/// Whether medium `id` is in a link mask: bit `id`, or past the 64th medium the whole
/// mask ([`check_link_masks`] allows only masks of every medium there).
#[inline(always)]
pub fn in_mask(mask: u64, id: usize) -> bool {
    if id < 64 {
        mask >> id & 1 == 1
    } else {
        mask == u64::MAX
    }
}

/// Which holdouts a shadow ray tests.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum HoldoutSet {
    /// All of them (the render's holdout BVH).
    All,
    None,
    /// [`Lights::holdout_sets`]`[k]` (a BVH of its own).
    Subset(usize),
}

impl Default for Link {
    fn default() -> Self {
        Link::ALL
    }
}

impl Link {
    /// No linking: the light lights every medium, and every medium and holdout
    /// shadows it.
    pub const ALL: Link = Link {
        lit: u64::MAX,
        shadowing: u64::MAX,
        holdouts: HoldoutSet::All,
    };

    /// Whether the light illuminates medium `id`.
    #[inline(always)]
    pub fn lights(&self, id: usize) -> bool {
        in_mask(self.lit, id)
    }

    pub fn is_everything(&self) -> bool {
        *self == Link::default()
    }
}

/// A dome light with linking: kept out of the environment that escaping paths see
/// (the phase-sampled continuation is traced through every occluder, so it cannot
/// honour a shadow link), and sampled by next-event estimation alone at every
/// scattering vertex. Camera rays still see it.
pub struct LinkedDome {
    /// Radiance of an untextured dome.
    pub constant: [f64; 3],
    /// A textured dome.
    pub map: Option<EnvMap>,
    pub link: Link,
}

impl LinkedDome {
    #[inline]
    pub fn radiance(&self, w: DVec3) -> [f64; 3] {
        match &self.map {
            Some(m) => m.radiance(w),
            None => self.constant,
        }
    }

    /// A direction, its radiance and density: the map's importance sampling, or
    /// uniform over the sphere.
    pub fn sample(&self, u1: f64, u2: f64) -> (DVec3, [f64; 3], f64) {
        match &self.map {
            Some(m) => {
                let w = m.sample(u1, u2);
                (w, m.radiance(w), m.pdf(w))
            }
            None => (sample_sphere(u1, u2), self.constant, INV_4PI),
        }
    }
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
    pub disks: Vec<DiskEmitter>,
    pub cylinders: Vec<CylinderEmitter>,
    /// Dome lights with linking (not part of `environment` and `env_maps`).
    pub linked_domes: Vec<LinkedDome>,
    /// The holdouts of each distinct shadow-link set that is neither all nor none of
    /// them, each in a BVH of its own: [`HoldoutSet::Subset`] indexes this.
    pub holdout_sets: Vec<Holdouts>,
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
    pub disks: Vec<usize>,
    pub cylinders: Vec<usize>,
    pub linked_domes: Vec<usize>,
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

    pub fn disk(&self, i: usize) -> usize {
        self.disks.get(i).copied().unwrap_or(NO_SOURCE)
    }

    pub fn cylinder(&self, i: usize) -> usize {
        self.cylinders.get(i).copied().unwrap_or(NO_SOURCE)
    }

    pub fn linked_dome(&self, i: usize) -> usize {
        self.linked_domes.get(i).copied().unwrap_or(NO_SOURCE)
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

/// `s` with the light's `inputs:diffuse` multiplier applied.
fn lit_scale(s: [f64; 3], controls: &LightControls) -> [f64; 3] {
    s.map(|v| v * controls.diffuse)
}

fn shaping(controls: &LightControls, light_to_world: &DMat4) -> Option<Shaping> {
    controls
        .shaping
        .as_ref()
        .and_then(|s| Shaping::new(s, light_to_world))
}

/// The side area of the cylinder `axis·u + y·cos φ + z·sin φ`: ℓ ∫ |axis × (−y sin φ +
/// z cos φ)| dφ / ℓ by the trapezoid rule, which converges geometrically for a smooth
/// periodic integrand (2π|axis||y| exactly for a circular, upright one).
/// The render's motion of a light the scene moves (`frame`: its transform at the
/// frame).
fn light_motion(motion: &Option<TransformMotion>, frame: &DMat4) -> Option<LightMotion> {
    motion.as_ref().map(|m| LightMotion::new(m, frame))
}

fn cylinder_area(axis: DVec3, y: DVec3, z: DVec3) -> f64 {
    const N: usize = 256;
    let step = 2.0 * PI / N as f64;
    (0..N)
        .map(|i| {
            let (sin, cos) = (i as f64 * step).sin_cos();
            axis.cross(z * cos - y * sin).length()
        })
        .sum::<f64>()
        * step
}

/// Evaluates the linking collections of each light against the scene's volumes (in
/// media order) and holdouts, and collects the distinct holdout subsets.
/// Link masks hold one bit per medium, so linking that picks some of more than 64 volumes
/// is refused, naming the light (linking every volume, the default, always works).
fn check_link_masks(scene: &Scene) -> Result<(), LightError> {
    if scene.volumes.len() <= 64 {
        return Ok(());
    }
    let all = |c: &Collection| scene.volumes.iter().all(|v| c.contains(&v.prim_path));
    let mut lights: Vec<(&str, &LightControls)> = Vec::new();
    macro_rules! push {
        ($($list:expr),*) => {
            $(for l in &$list {
                lights.push((&l.prim_path, &l.controls));
            })*
        };
    }
    push!(
        scene.distant_lights,
        scene.dome_lights,
        scene.sphere_lights,
        scene.rect_lights,
        scene.disk_lights,
        scene.cylinder_lights
    );
    for (prim, c) in lights {
        for (name, collection) in [("lightLink", &c.light_link), ("shadowLink", &c.shadow_link)] {
            if !all(collection) {
                return Err(LightError {
                    prim: prim.to_string(),
                    message: format!(
                        "collection:{name} picks some of the stage's {} volumes; light and shadow linking works over at most 64 volumes (link all of them, or fewer volumes)",
                        scene.volumes.len()
                    ),
                });
            }
        }
    }
    Ok(())
}

struct Linker<'a> {
    volumes: Vec<&'a str>,
    holdouts: Vec<&'a str>,
    sets: Vec<Vec<usize>>,
}

impl<'a> Linker<'a> {
    fn new(scene: &'a Scene) -> Linker<'a> {
        Linker {
            volumes: scene.volumes.iter().map(|v| v.prim_path.as_str()).collect(),
            holdouts: scene
                .holdouts
                .iter()
                .map(|h| h.prim_path.as_str())
                .collect(),
            sets: Vec::new(),
        }
    }

    fn link(&mut self, c: &LightControls) -> Link {
        let lit = self.mask(&c.light_link);
        if c.unshadowed {
            return Link {
                lit,
                shadowing: 0,
                holdouts: HoldoutSet::None,
            };
        }
        Link {
            lit,
            shadowing: self.mask(&c.shadow_link),
            holdouts: self.holdout_set(&c.shadow_link),
        }
    }

    /// Bit i: volume i is in the collection; every bit when all are.
    fn mask(&self, c: &Collection) -> u64 {
        if c.is_everything() {
            return u64::MAX;
        }
        let mut mask = 0u64;
        for (i, v) in self.volumes.iter().enumerate().take(64) {
            if c.contains(v) {
                mask |= 1 << i;
            }
        }
        match self.volumes.iter().all(|v| c.contains(v)) {
            true => u64::MAX,
            false => mask,
        }
    }

    fn holdout_set(&mut self, c: &Collection) -> HoldoutSet {
        if c.is_everything() {
            return HoldoutSet::All;
        }
        let members: Vec<usize> = (0..self.holdouts.len())
            .filter(|&i| c.contains(self.holdouts[i]))
            .collect();
        if members.len() == self.holdouts.len() {
            return HoldoutSet::All;
        }
        if members.is_empty() {
            return HoldoutSet::None;
        }
        let k = match self.sets.iter().position(|s| *s == members) {
            Some(k) => k,
            None => {
                self.sets.push(members);
                self.sets.len() - 1
            }
        };
        HoldoutSet::Subset(k)
    }
}

impl Lights {
    /// The scene's lights; reads dome textures (errors name the light and the file).
    pub fn from_scene(scene: &Scene) -> Result<Lights, LightError> {
        check_link_masks(scene)?;
        let mut lights = Lights::default();
        let mut linker = Linker::new(scene);
        // Scene light indices in `Scene::lights` order: distant, dome, sphere, rect,
        // disk, cylinder.
        let mut next = 0..;
        for l in &scene.distant_lights {
            let source = next.next().unwrap_or(NO_SOURCE);
            let s = lit_scale(
                light_scale(l.intensity, l.exposure, l.color, l.color_temperature),
                &l.controls,
            );
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
                // The sun's world −Z is the negated direction towards it.
                let direction = DVec3::from_array(l.direction).normalize_or(DVec3::Z);
                let to_world = DMat4::from_cols(
                    glam::DVec4::X,
                    glam::DVec4::Y,
                    direction.extend(0.0),
                    glam::DVec4::W,
                );
                lights.sources.suns.push(source);
                lights.suns.push(Sun {
                    direction,
                    irradiance,
                    cos_half_angle,
                    shaping: shaping(&l.controls, &to_world),
                    link: linker.link(&l.controls),
                });
            }
        }
        for d in &scene.dome_lights {
            let source = next.next().unwrap_or(NO_SOURCE);
            let s = light_scale(d.intensity, d.exposure, d.color, d.color_temperature);
            let link = linker.link(&d.controls);
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
            if !link.is_everything() {
                lights.sources.linked_domes.push(source);
                lights.linked_domes.push(LinkedDome {
                    constant: s,
                    map,
                    link,
                });
                continue;
            }
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
            let s = lit_scale(
                light_scale(l.intensity, l.exposure, l.color, l.color_temperature),
                &l.controls,
            );
            let point = l.treat_as_point || r == 0.0;
            let radiance = match (point, l.normalize) {
                // Surface radiance, divided by the area 4πr² when normalized.
                (false, true) => s.map(|v| v / (4.0 * PI * r * r)),
                (false, false) => s,
                // A point keeps the sphere's far field, intensity L·πr²: s/4 when
                // normalized (whatever r), s·πr² otherwise; a zero-radius sphere has
                // no size to normalize by and emits as the normalized one does.
                (true, true) => s.map(|v| v / 4.0),
                (true, false) if r == 0.0 => s.map(|v| v / 4.0),
                (true, false) => s.map(|v| v * PI * r * r),
            };
            let emitter = SphereEmitter {
                center: m.transform_point3(DVec3::ZERO),
                radius: if point { 0.0 } else { r },
                radiance,
                interior: l.lights_interior && !point,
                shaping: shaping(&l.controls, &m),
                link: linker.link(&l.controls),
                motion: light_motion(&l.motion, &m),
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
            let s = lit_scale(
                light_scale(l.intensity, l.exposure, l.color, l.color_temperature),
                &l.controls,
            );
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
                    shaping: shaping(&l.controls, &m),
                    link: linker.link(&l.controls),
                    motion: light_motion(&l.motion, &m),
                });
            }
        }
        for l in &scene.disk_lights {
            let source = next.next().unwrap_or(NO_SOURCE);
            let m = l.light_to_world;
            let a = m.transform_vector3(DVec3::X * l.radius);
            let b = m.transform_vector3(DVec3::Y * l.radius);
            let cross = a.cross(b);
            let area = PI * cross.length();
            let s = lit_scale(
                light_scale(l.intensity, l.exposure, l.color, l.color_temperature),
                &l.controls,
            );
            let radiance = match l.normalize {
                true if area > 0.0 => s.map(|v| v / area),
                _ => s,
            };
            if area > 0.0 && nonzero(&radiance) {
                lights.sources.disks.push(source);
                lights.disks.push(DiskEmitter {
                    center: m.transform_point3(DVec3::ZERO),
                    a,
                    b,
                    // Emits along its local −Z.
                    normal: -cross / cross.length(),
                    area,
                    radiance,
                    shaping: shaping(&l.controls, &m),
                    link: linker.link(&l.controls),
                    motion: light_motion(&l.motion, &m),
                });
            }
        }
        for l in &scene.cylinder_lights {
            let source = next.next().unwrap_or(NO_SOURCE);
            let m = l.light_to_world;
            let axis = m.transform_vector3(DVec3::X * l.length);
            let y = m.transform_vector3(DVec3::Y * l.radius);
            let z = m.transform_vector3(DVec3::Z * l.radius);
            let area = cylinder_area(axis, y, z);
            let s = lit_scale(
                light_scale(l.intensity, l.exposure, l.color, l.color_temperature),
                &l.controls,
            );
            let line = l.treat_as_line || area == 0.0;
            let mut e = CylinderEmitter {
                center: m.transform_point3(DVec3::ZERO),
                axis,
                axis_unit: axis.normalize_or_zero(),
                y,
                z,
                area,
                line,
                shaping: shaping(&l.controls, &m),
                link: linker.link(&l.controls),
                motion: light_motion(&l.motion, &m),
                ..Default::default()
            };
            if line {
                // Far field of the side: L × its projected area, 2·r·ℓ·sin θ for a
                // circular cylinder (r: the radius of the circle of the cross-section's
                // area). Normalized, or of no area: s·2rℓ/A = s/π for a circle.
                let length = axis.length();
                let r = y.cross(z).length().sqrt();
                let projected = 2.0 * r * length;
                e.line_intensity = match l.normalize || area == 0.0 {
                    true if area > 0.0 => s.map(|v| v * projected / area),
                    true => s.map(|v| v / PI),
                    false => s.map(|v| v * projected),
                };
                if length > 0.0 && nonzero(&e.line_intensity) {
                    lights.sources.cylinders.push(source);
                    lights.cylinders.push(e);
                }
            } else {
                e.radiance = match l.normalize {
                    true => s.map(|v| v / area),
                    false => s,
                };
                if nonzero(&e.radiance) {
                    lights.sources.cylinders.push(source);
                    lights.cylinders.push(e);
                }
            }
        }
        lights.holdout_sets = linker
            .sets
            .iter()
            .map(|set| {
                let meshes: Vec<_> = set.iter().map(|&i| scene.holdouts[i].clone()).collect();
                Holdouts::build(&meshes)
            })
            .collect();
        Ok(lights)
    }

    /// The sphere, rect, disk and cylinder lights (next-event estimation's order) as
    /// equiangular sampling sees them: their centres, powers (mean over channels) and
    /// spots' cones. Index k of this list is the one [`Self::sample_local`] takes.
    /// A moving light is seen where it is at the frame: equiangular sampling only
    /// proposes points (its density and the collisions' weights use these same
    /// centres), and the light sample at the point is taken where the light is at the
    /// path's time, so the estimate stays unbiased; it is less efficient the farther a
    /// light strays from its frame place over the shutter.
    pub fn locals(&self) -> Vec<LocalLight> {
        let mean = |v: &[f64; 3]| (v[0] + v[1] + v[2]) / 3.0;
        // A spot lights only its cone: its equiangular samples are drawn on the
        // stretch of a segment inside it, and its power is the share of the sphere of
        // directions the cone passes. (Focus and softness are left out: the choice
        // among lights only needs proportions.)
        let local = |center: DVec3, radius: f64, power: f64, shaping: &Option<Shaping>| {
            let cone = shaping
                .as_ref()
                .and_then(|s| Cone::new(center, s.axis, s.cutoff, radius));
            let share = shaping
                .as_ref()
                .filter(|s| s.cutoff < PI)
                .map_or(1.0, |s| 0.5 * (1.0 - s.cutoff.cos()));
            LocalLight {
                center,
                power: power * share,
                radius,
                cone,
                chord: None,
            }
        };
        let mut out = Vec::new();
        for e in &self.spheres {
            // A point's intensity over the sphere of directions; a sphere's π L from
            // each of its 4π r² of surface.
            let r = e.radius;
            let power = match r > 0.0 {
                false => 4.0 * PI * mean(&e.radiance),
                true => 4.0 * PI * PI * r * r * mean(&e.radiance),
            };
            out.push(local(e.center, r, power, &e.shaping));
        }
        for e in &self.rects {
            let half_diagonal = 0.5
                * (e.edge_u + e.edge_v)
                    .length()
                    .max((e.edge_u - e.edge_v).length());
            let power = PI * e.area * mean(&e.radiance);
            out.push(local(e.center, half_diagonal, power, &e.shaping));
        }
        for e in &self.disks {
            let radius = e.a.length().max(e.b.length());
            let power = PI * e.area * mean(&e.radiance);
            out.push(local(e.center, radius, power, &e.shaping));
        }
        for e in &self.cylinders {
            let power = match e.line {
                // ∫ sin θ dΩ = π² over the sphere of directions.
                true => PI * PI * mean(&e.line_intensity),
                false => PI * e.area * mean(&e.radiance),
            };
            let reach = 0.5 * e.axis.length() + e.y.length().max(e.z.length());
            out.push(local(e.center, reach, power, &e.shaping));
        }
        out
    }

    /// Samples local light `k` ([`Self::locals`]' order) from `p`: the sample, the
    /// light's link and its source (for the split layers).
    #[inline]
    pub fn sample_local(
        &self,
        k: usize,
        p: DVec3,
        time: f64,
        (u1, u2): (f64, f64),
    ) -> (Option<LightSample>, &Link, usize) {
        let mut k = k;
        if k < self.spheres.len() {
            let e = &self.spheres[k];
            return (
                e.sample_at(p, time, u1, u2),
                &e.link,
                self.sources.sphere(k),
            );
        }
        k -= self.spheres.len();
        if k < self.rects.len() {
            let e = &self.rects[k];
            return (e.sample_at(p, time, u1, u2), &e.link, self.sources.rect(k));
        }
        k -= self.rects.len();
        if k < self.disks.len() {
            let e = &self.disks[k];
            return (e.sample_at(p, time, u1, u2), &e.link, self.sources.disk(k));
        }
        k -= self.disks.len();
        let e = &self.cylinders[k];
        (
            e.sample_at(p, time, u1, u2),
            &e.link,
            self.sources.cylinder(k),
        )
    }

    /// Whether a local light moves over the shutter.
    pub fn moves(&self) -> bool {
        self.spheres.iter().any(|e| e.motion.is_some())
            || self.rects.iter().any(|e| e.motion.is_some())
            || self.disks.iter().any(|e| e.motion.is_some())
            || self.cylinders.iter().any(|e| e.motion.is_some())
    }

    /// Whether any light has linking (its media masks or holdout sets differ from
    /// "everything").
    pub fn has_linking(&self) -> bool {
        let linked = |l: &Link| !l.is_everything();
        self.suns.iter().any(|e| linked(&e.link))
            || self.spheres.iter().any(|e| linked(&e.link))
            || self.rects.iter().any(|e| linked(&e.link))
            || self.disks.iter().any(|e| linked(&e.link))
            || self.cylinders.iter().any(|e| linked(&e.link))
            || !self.linked_domes.is_empty()
    }

    pub fn has_environment(&self) -> bool {
        nonzero(&self.environment) || !self.env_maps.is_empty()
    }

    /// Whether any light comes from afar: a sun with irradiance, the environment, a
    /// linked dome.
    pub fn has_distant_light(&self) -> bool {
        self.has_environment()
            || !self.linked_domes.is_empty()
            || self.suns.iter().any(|s| nonzero(&s.irradiance))
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
    /// sphere see no emission (it emits outwards), unless it lights its interior.
    pub fn sample(&self, p: DVec3, u1: f64, u2: f64) -> Option<LightSample> {
        let to_c = self.center - p;
        let d2 = to_c.length_squared();
        let d = d2.sqrt();
        if d <= self.radius || d == 0.0 {
            return self.sample_inside(to_c, d2, u1, u2);
        }
        let axis = to_c / d;
        if self.radius == 0.0 {
            let sample = LightSample {
                wi: axis,
                distance: d,
                weight: self.radiance.map(|v| v / d2),
            };
            return shaped(sample, &self.shaping);
        }
        let sin2_max = (self.radius * self.radius / d2).min(1.0);
        let cos_max = (1.0 - sin2_max).sqrt();
        let wi = cone_direction(axis, cos_max, u1, u2);
        let cos_t = wi.dot(axis);
        // Nearest intersection with the sphere along wi.
        let disc = (self.radius * self.radius - d2 * (1.0 - cos_t * cos_t)).max(0.0);
        let distance = (d * cos_t - disc.sqrt()).max(0.0);
        let solid_angle = 2.0 * PI * (1.0 - cos_max);
        shaped(
            LightSample {
                wi,
                distance,
                weight: self.radiance.map(|v| v * solid_angle),
            },
            &self.shaping,
        )
    }

    /// From a point inside a sphere that lights its interior (`to_c` = centre − p):
    /// a direction uniform over the sphere of directions, every one of which meets
    /// the surface (radiance L, pdf 1/4π), at the far root of |p + t·wi − c| = r.
    /// Uniform rather than by the phase function: the interior is lit evenly, and
    /// the sample stays the light's own, whatever the medium.
    fn sample_inside(&self, to_c: DVec3, d2: f64, u1: f64, u2: f64) -> Option<LightSample> {
        if !self.interior || self.radius == 0.0 {
            return None;
        }
        let wi = sample_sphere(u1, u2);
        let b = to_c.dot(wi);
        let distance = b + (b * b + self.radius * self.radius - d2).max(0.0).sqrt();
        shaped(
            LightSample {
                wi,
                distance,
                weight: self.radiance.map(|v| v * 4.0 * PI),
            },
            &self.shaping,
        )
    }
}

/// `sample(p)` of a light that may move: at frame-relative `time`, the sample its
/// frame placement gives the point p is seen from, carried back to the world
/// ([`LightMotion`]); a still light samples from `p` itself.
#[inline(always)]
fn sample_moving(
    motion: &Option<LightMotion>,
    p: DVec3,
    time: f64,
    sample: impl FnOnce(DVec3) -> Option<LightSample>,
) -> Option<LightSample> {
    let Some(m) = motion else {
        return sample(p);
    };
    let (q, linear) = m.seen_from_frame(p, time);
    let mut s = sample(q)?;
    (s.wi, s.distance) = LightMotion::back_to_world(&linear, s.wi, s.distance);
    Some(s)
}

/// `sample_at(p, time, u1, u2)` of each local emitter: its `sample`, wherever the
/// light is at `time`.
macro_rules! sample_at {
    ($($emitter:ty),*) => {$(
        impl $emitter {
            #[inline]
            pub fn sample_at(&self, p: DVec3, time: f64, u1: f64, u2: f64) -> Option<LightSample> {
                sample_moving(&self.motion, p, time, |q| self.sample(q, u1, u2))
            }
        }
    )*};
}

sample_at!(SphereEmitter, RectEmitter, DiskEmitter, CylinderEmitter);

/// `sample` with its weight multiplied by the shaping of the emission leaving towards
/// the point (−wi); `None` when that is zero in every channel (no shadow ray).
#[inline(always)]
fn shaped(mut sample: LightSample, shaping: &Option<Shaping>) -> Option<LightSample> {
    if let Some(s) = shaping {
        let f = s.factor(-sample.wi);
        if f == [0.0; 3] {
            return None;
        }
        for c in 0..3 {
            sample.weight[c] *= f[c];
        }
    }
    Some(sample)
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
        shaped(
            LightSample {
                wi,
                distance: d,
                weight: self.radiance.map(|r| r * g),
            },
            &self.shaping,
        )
    }
}

/// The sample towards light point `q` (emitting side `normal`) seen from `p`, with area
/// density 1/`inverse_pdf` converted to solid angle; `None` behind it.
#[inline(always)]
fn area_sample(
    p: DVec3,
    q: DVec3,
    normal: DVec3,
    inverse_pdf: f64,
    radiance: &[f64; 3],
    shaping: &Option<Shaping>,
) -> Option<LightSample> {
    let v = q - p;
    let d2 = v.length_squared();
    if d2 == 0.0 {
        return None;
    }
    let d = d2.sqrt();
    let wi = v / d;
    let cos_l = -wi.dot(normal);
    if cos_l <= 0.0 {
        return None;
    }
    let g = cos_l * inverse_pdf / d2;
    shaped(
        LightSample {
            wi,
            distance: d,
            weight: radiance.map(|r| r * g),
        },
        shaping,
    )
}

impl DiskEmitter {
    /// Samples a point uniformly on the disk (a linear map keeps the density uniform
    /// on the ellipse); density converted to solid angle.
    pub fn sample(&self, p: DVec3, u1: f64, u2: f64) -> Option<LightSample> {
        let r = u1.sqrt();
        let (cos, sin) = azimuth(u2);
        let q = self.center + self.a * (r * cos) + self.b * (r * sin);
        area_sample(p, q, self.normal, self.area, &self.radiance, &self.shaping)
    }
}

impl CylinderEmitter {
    /// Samples the side uniformly in (u, φ) (its area density is 1/(2π J(φ)) with J
    /// the area element, exact for any linear transform), or a point uniformly along
    /// the line.
    pub fn sample(&self, p: DVec3, u1: f64, u2: f64) -> Option<LightSample> {
        if self.line {
            return self.sample_line(p, u1);
        }
        let (cos, sin) = azimuth(u2);
        let radial = self.y * cos + self.z * sin;
        let q = self.center + self.axis * (u1 - 0.5) + radial;
        let tangent = self.z * cos - self.y * sin;
        let n = tangent.cross(self.axis);
        let j = n.length();
        if j == 0.0 {
            return None;
        }
        // Outwards: away from the axis, whatever the transform's handedness.
        let normal = if n.dot(radial) >= 0.0 { n / j } else { -n / j };
        area_sample(p, q, normal, 2.0 * PI * j, &self.radiance, &self.shaping)
    }

    /// A point uniformly along the line; the intensity leaving it at angle θ to the
    /// axis is `line_intensity · sin θ / length` per unit length.
    fn sample_line(&self, p: DVec3, u: f64) -> Option<LightSample> {
        let q = self.center + self.axis * (u - 0.5);
        let v = q - p;
        let d2 = v.length_squared();
        if d2 == 0.0 {
            return None;
        }
        let d = d2.sqrt();
        let wi = v / d;
        let sin = wi.cross(self.axis_unit).length();
        shaped(
            LightSample {
                wi,
                distance: d,
                weight: self.line_intensity.map(|i| i * sin / d2),
            },
            &self.shaping,
        )
    }
}
