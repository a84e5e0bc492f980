//! The scene as plain data: what [`load_stage`](super::stage::load_stage) returns —
//! camera, lights, volumes and their fields, holdout geometry, render settings, products
//! and vars — with
//! world-space transforms already evaluated and asset paths already resolved.

use super::diagnostics::Diagnostics;
use crate::motion::TransformMotion;
use crate::volume::asset::AssetLocation;
use crate::volume::emission::{EmissionKind, EmissionParams};
use glam::DMat4;
use std::path::PathBuf;

/// A composed, evaluated scene at one time code.
#[derive(Clone, Debug)]
pub struct Scene {
    /// The stage file this scene was loaded from.
    pub stage_path: PathBuf,
    /// The time code the scene was evaluated at.
    pub time: f64,
    pub camera: Camera,
    pub distant_lights: Vec<DistantLight>,
    pub dome_lights: Vec<DomeLight>,
    pub sphere_lights: Vec<SphereLight>,
    pub rect_lights: Vec<RectLight>,
    pub disk_lights: Vec<DiskLight>,
    pub cylinder_lights: Vec<CylinderLight>,
    pub volumes: Vec<Volume>,
    /// The visible UsdGeom gprims rendered as black matte occluders (empty when the
    /// stage has none).
    pub holdouts: Vec<HoldoutMesh>,
    pub settings: RenderSettings,
    /// Light prims on the stage of any type, read or not, visible or not: a stage with
    /// one gets no default lights, even when Nimbus cannot render it.
    pub light_prims: usize,
    /// What the stage asks for that the render does not show as authored.
    pub warnings: Diagnostics,
}

/// Something that puts light into the scene, as the light-group AOVs name it: a UsdLux
/// light or an emissive volume.
#[derive(Clone, Copy, Debug)]
pub struct Emitter<'a> {
    pub prim_path: &'a str,
    pub light_group: Option<&'a str>,
}

impl Scene {
    /// The scene's lights in the order distant, dome, sphere, rect, disk, cylinder
    /// (each in stage order): a light's index here is its light id in the renderer.
    pub fn lights(&self) -> Vec<Emitter<'_>> {
        let mut out = Vec::new();
        macro_rules! push {
            ($list:expr) => {
                for l in &$list {
                    out.push(Emitter {
                        prim_path: &l.prim_path,
                        light_group: l.light_group.as_deref(),
                    });
                }
            };
        }
        push!(self.distant_lights);
        push!(self.dome_lights);
        push!(self.sphere_lights);
        push!(self.rect_lights);
        push!(self.disk_lights);
        push!(self.cylinder_lights);
        out
    }
}

/// A UsdGeomCamera. Lengths in the stage's units as USD defines them: focal length and
/// apertures in tenths of a scene unit ("mm" when the unit is cm), the clipping range
/// and focus distance in scene units. A perspective pinhole depends only on the ratios
/// of focal length and apertures; an orthographic view is `aperture / 10` units wide,
/// and a thin lens is `focalLength / 10 / fStop` units across (see `render::camera`).
#[derive(Clone, Debug)]
pub struct Camera {
    pub prim_path: String,
    /// Camera → world. The camera looks down its local −Z with +Y up.
    pub camera_to_world: DMat4,
    /// `projection`: perspective or orthographic.
    pub projection: Projection,
    pub focal_length: f64,
    pub horizontal_aperture: f64,
    pub vertical_aperture: f64,
    pub horizontal_aperture_offset: f64,
    pub vertical_aperture_offset: f64,
    /// (near, far) clipping range.
    pub clipping_range: (f64, f64),
    /// `fStop`: 0 is a pinhole (everything in focus).
    pub f_stop: f64,
    /// `focusDistance`: depth of the plane in focus (used when `f_stop` > 0).
    pub focus_distance: f64,
    /// `shutter:open`, `shutter:close` (time codes from the frame) when open < close.
    pub shutter: Option<(f64, f64)>,
    /// `camera_to_world` over the shutter, when it moves while the shutter is open
    /// (`camera_to_world` is its value at the frame).
    pub motion: Option<TransformMotion>,
}

/// UsdGeomCamera's `projection`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Projection {
    #[default]
    Perspective,
    Orthographic,
}

/// UsdLuxDistantLight. Its emission scale is `intensity · 2^exposure · color`: radiance
/// (nits) over a disk of angular diameter `angle`, or, with `normalize` (or a zero
/// angle), the illuminance delivered to a surface facing the light (see
/// `render::lights`).
#[derive(Clone, Debug)]
pub struct DistantLight {
    pub prim_path: String,
    /// Shaping, linking and shadow controls.
    pub controls: LightControls,
    /// `nimbus:lightGroup`: the light group its light-group AOVs gather it under.
    pub light_group: Option<String>,
    /// Unit world-space direction *towards* the light (the light shines along its local −Z,
    /// so this is the light's world +Z axis).
    pub direction: [f64; 3],
    pub intensity: f64,
    pub exposure: f64,
    pub color: [f64; 3],
    /// `inputs:normalize`.
    pub normalize: bool,
    /// `inputs:colorTemperature` when `inputs:enableColorTemperature` is on.
    pub color_temperature: Option<f64>,
    /// Angular diameter in degrees (`inputs:angle`).
    pub angle_degrees: f64,
}

/// UsdLuxDomeLight: a constant colour, or a lat-long texture times that colour.
#[derive(Clone, Debug)]
pub struct DomeLight {
    pub prim_path: String,
    /// Shaping, linking and shadow controls.
    pub controls: LightControls,
    /// `nimbus:lightGroup`: the light group its light-group AOVs gather it under.
    pub light_group: Option<String>,
    /// Light → world; the texture's +Y pole and +Z (longitude 0) are the light's local
    /// axes.
    pub light_to_world: DMat4,
    pub intensity: f64,
    pub exposure: f64,
    pub color: [f64; 3],
    pub color_temperature: Option<f64>,
    /// `inputs:texture:file`, resolved against its layer, if authored.
    pub texture_file: Option<String>,
    /// `inputs:texture:format` (`automatic`, `latlong`, …).
    pub texture_format: String,
}

/// UsdLuxSphereLight: a sphere of `radius` at the light's origin, emitting outwards.
#[derive(Clone, Debug)]
pub struct SphereLight {
    pub prim_path: String,
    /// Shaping, linking and shadow controls.
    pub controls: LightControls,
    /// `nimbus:lightGroup`: the light group its light-group AOVs gather it under.
    pub light_group: Option<String>,
    pub light_to_world: DMat4,
    /// `light_to_world` over the shutter, when the light moves (rigidly) while it is
    /// open (`light_to_world` is its value at the frame).
    pub motion: Option<TransformMotion>,
    pub intensity: f64,
    pub exposure: f64,
    pub color: [f64; 3],
    pub normalize: bool,
    pub color_temperature: Option<f64>,
    /// `inputs:radius` (local units).
    pub radius: f64,
    /// `treatAsPoint`.
    pub treat_as_point: bool,
    /// `nimbus:lightsInterior`: the sphere also lights what lies inside it, its
    /// radiance arriving from every direction there (Cycles' point, spot and sphere
    /// lights; UsdLux's sphere emits outwards only, the default).
    pub lights_interior: bool,
}

/// UsdLuxRectLight: a `width` × `height` rectangle in the light's local XY plane,
/// emitting from one side along its local −Z.
#[derive(Clone, Debug)]
pub struct RectLight {
    pub prim_path: String,
    /// Shaping, linking and shadow controls.
    pub controls: LightControls,
    /// `nimbus:lightGroup`: the light group its light-group AOVs gather it under.
    pub light_group: Option<String>,
    pub light_to_world: DMat4,
    /// `light_to_world` over the shutter, when the light moves (rigidly) while it is
    /// open (`light_to_world` is its value at the frame).
    pub motion: Option<TransformMotion>,
    pub intensity: f64,
    pub exposure: f64,
    pub color: [f64; 3],
    pub normalize: bool,
    pub color_temperature: Option<f64>,
    /// `inputs:width` (local X) and `inputs:height` (local Y).
    pub width: f64,
    pub height: f64,
}

/// UsdLuxDiskLight: a disk of `radius` in the light's local XY plane, emitting from one
/// side along its local −Z.
#[derive(Clone, Debug)]
pub struct DiskLight {
    pub prim_path: String,
    /// Shaping, linking and shadow controls.
    pub controls: LightControls,
    /// `nimbus:lightGroup`: the light group its light-group AOVs gather it under.
    pub light_group: Option<String>,
    pub light_to_world: DMat4,
    /// `light_to_world` over the shutter, when the light moves (rigidly) while it is
    /// open (`light_to_world` is its value at the frame).
    pub motion: Option<TransformMotion>,
    pub intensity: f64,
    pub exposure: f64,
    pub color: [f64; 3],
    pub normalize: bool,
    pub color_temperature: Option<f64>,
    /// `inputs:radius` (local units).
    pub radius: f64,
}

/// UsdLuxCylinderLight: a cylinder of `length` along the light's local X axis and
/// `radius`, centred at its origin, emitting outwards from its side (not its caps).
#[derive(Clone, Debug)]
pub struct CylinderLight {
    pub prim_path: String,
    /// Shaping, linking and shadow controls.
    pub controls: LightControls,
    /// `nimbus:lightGroup`: the light group its light-group AOVs gather it under.
    pub light_group: Option<String>,
    pub light_to_world: DMat4,
    /// `light_to_world` over the shutter, when the light moves (rigidly) while it is
    /// open (`light_to_world` is its value at the frame).
    pub motion: Option<TransformMotion>,
    pub intensity: f64,
    pub exposure: f64,
    pub color: [f64; 3],
    pub normalize: bool,
    pub color_temperature: Option<f64>,
    /// `inputs:length` (local X) and `inputs:radius` (local units).
    pub length: f64,
    pub radius: f64,
    /// `treatAsLine`.
    pub treat_as_line: bool,
}

/// What UsdLux's ShapingAPI, ShadowAPI and linking collections add to a light. The
/// default changes nothing: no shaping, shadows on, every prim lit and shadowing.
#[derive(Clone, Debug, PartialEq)]
pub struct LightControls {
    /// `inputs:diffuse`: multiplies the light's illumination of the volume (volume
    /// scattering is the medium's diffuse response).
    pub diffuse: f64,
    /// ShapingAPI, when applied or authored.
    pub shaping: Option<Shaping>,
    /// `collection:lightLink`: the prims the light illuminates.
    pub light_link: Collection,
    /// `collection:shadowLink`: the prims that cast shadows from the light.
    pub shadow_link: Collection,
    /// `inputs:shadow:enable` = false (ShadowAPI): nothing shadows the light.
    pub unshadowed: bool,
}

impl Default for LightControls {
    fn default() -> Self {
        LightControls {
            diffuse: 1.0,
            shaping: None,
            light_link: Collection::default(),
            shadow_link: Collection::default(),
            unshadowed: false,
        }
    }
}

/// UsdLuxShapingAPI's inputs, schema fallbacks applied (angles in degrees).
#[derive(Clone, Debug, PartialEq)]
pub struct Shaping {
    /// `inputs:shaping:focus` (values < 0 are ignored, as 0).
    pub focus: f64,
    /// `inputs:shaping:focusTint`.
    pub focus_tint: [f64; 3],
    /// `inputs:shaping:cone:angle`: the largest angle off the light's −Z axis it emits
    /// at (fallback 90).
    pub cone_angle: f64,
    /// `inputs:shaping:cone:softness`, clamped to [0, 1].
    pub cone_softness: f64,
    /// `inputs:shaping:ies:file`, resolved, when authored.
    pub ies_file: Option<String>,
    /// `inputs:shaping:ies:angleScale`.
    pub ies_angle_scale: f64,
    /// `inputs:shaping:ies:normalize`.
    pub ies_normalize: bool,
}

impl Default for Shaping {
    /// The schema's fallbacks: no focus, a 90° cone without softness, no profile.
    fn default() -> Self {
        Shaping {
            focus: 0.0,
            focus_tint: [0.0; 3],
            cone_angle: 90.0,
            cone_softness: 0.0,
            ies_file: None,
            ies_angle_scale: 0.0,
            ies_normalize: false,
        }
    }
}

/// A UsdCollectionAPI membership rule over prim paths (`collection:NAME:…`). The
/// default includes every prim: the fallback `includeRoot = true` the LightAPI gives
/// its `lightLink` and `shadowLink` collections.
#[derive(Clone, Debug, PartialEq)]
pub struct Collection {
    /// `includeRoot`: the root path (and so every prim) is included.
    pub include_root: bool,
    /// `includes` and `excludes` targets (prim paths).
    pub includes: Vec<String>,
    pub excludes: Vec<String>,
    /// `expansionRule` = `explicitOnly`: only the targets themselves, not their
    /// descendants.
    pub explicit_only: bool,
}

impl Default for Collection {
    fn default() -> Self {
        Collection {
            include_root: true,
            includes: Vec::new(),
            excludes: Vec::new(),
            explicit_only: false,
        }
    }
}

impl Collection {
    /// Whether the rule includes every prim (the fallback): no evaluation needed.
    pub fn is_everything(&self) -> bool {
        self.include_root && self.excludes.is_empty()
    }

    /// Whether the prim at `path` is a member, as UsdCollectionAPI's membership query
    /// decides: the nearest target at or above the prim (only the prim itself with
    /// `explicitOnly`) decides, an exclude beating an include of the same path; the root
    /// counts as an include when `includeRoot` is on; nothing matching excludes it.
    pub fn contains(&self, path: &str) -> bool {
        let mut best: Option<(usize, bool)> = None;
        let mut consider = |target: &str, included: bool| {
            let depth = match self.explicit_only {
                true if target == path => Some(target.len()),
                true => None,
                false => prefix_depth(target, path),
            };
            if let Some(d) = depth {
                // Deeper wins; at equal depth an exclude wins.
                let better = match best {
                    None => true,
                    Some((bd, bi)) => d > bd || (d == bd && bi && !included),
                };
                if better {
                    best = Some((d, included));
                }
            }
        };
        if self.include_root && !self.explicit_only {
            consider("/", true);
        }
        for t in &self.includes {
            consider(t, true);
        }
        for t in &self.excludes {
            consider(t, false);
        }
        best.is_some_and(|(_, included)| included)
    }
}

/// The length of `prefix` when it is `path` or one of its ancestors (the root `/` is
/// everything's), else `None`.
fn prefix_depth(prefix: &str, path: &str) -> Option<usize> {
    let p = prefix.trim_end_matches('/');
    if p.is_empty() {
        return Some(0);
    }
    (path == p
        || path
            .strip_prefix(p)
            .is_some_and(|rest| rest.starts_with('/')))
    .then_some(p.len())
}

/// A medium of the scene with Nimbus' volume parameters resolved (schema fallbacks
/// applied): a UsdVolVolume with a density field, a fog box (a closed gprim with a
/// volume material) or world fog ([`VolumeShape`]).
#[derive(Clone, Debug)]
pub struct Volume {
    pub prim_path: String,
    /// `nimbus:lightGroup` of an emissive volume: the light group of its emission.
    pub light_group: Option<String>,
    /// Volume → world (the prim's local-to-world transform at the scene's time).
    pub volume_to_world: DMat4,
    /// `volume_to_world` over the camera's shutter, when the volume moves while it is
    /// open (a UsdVolVolume's; fog boxes and world fog are not blurred).
    pub motion: Option<TransformMotion>,
    /// What the density is and where the medium is.
    pub shape: VolumeShape,
    /// `nimbus:densityScale`: extinction per unit density is scaled by this.
    pub density_scale: f64,
    /// σa per unit density, per channel (`nimbus:absorption`).
    pub absorption: [f64; 3],
    /// σs per unit density, per channel (`nimbus:scattering`).
    pub scattering: [f64; 3],
    /// Henyey–Greenstein g (`nimbus:anisotropy`).
    pub anisotropy: f64,
    /// All `field:*` relationships of the volume, for `nimbus info`.
    pub fields: Vec<(String, Field)>,
    /// Emission (`nimbus:temperatureField`, `nimbus:emissionField` and their
    /// parameters); `VolumeEmission::default()` (no fields) when the volume emits nothing.
    pub emission: VolumeEmission,
    /// `nimbus:albedoField`: the relationship name and its field, if set (a Vec3s or
    /// float grid, an albedo multiplier c ∈ [0,1]³: σs → c·σs, σa → σa + (1 − c)·σs).
    /// `None` = constant albedo; a `Cd` field is not used unless named.
    pub albedo: Option<(String, Field)>,
    /// The colour graph `nimbus:albedo` is connected to (issue 47): the same
    /// multiplier, evaluated at scatter events; at most one of it and `albedo`.
    pub albedo_graph: Option<DensityGraph>,
    /// The velocity field whose flow blurs the volume's fields over the shutter
    /// (`nimbus:velocityField`, else a field `vel` or `velocity`), and the seconds of
    /// flow per time code from the frame (`nimbus:velocityScale` × `motion:blurScale`
    /// / `timeCodesPerSecond`). `None` without an open shutter and a frame.
    pub velocity: Option<Velocity>,
    /// When the parameters come from a bound material (no `NimbusVolumeAPI`): the
    /// volume shader read, as "prim path (info:id)".
    pub material_shader: Option<String>,
    /// A shader graph the density goes through (issue 47): the medium's density is the
    /// graph's value, reading the density field (or 1 in fog) as its attribute.
    pub density_graph: Option<DensityGraph>,
}

/// A volume's velocity field, as read.
#[derive(Clone, Debug, PartialEq)]
pub struct Velocity {
    /// The relationship name (`field:<name>`) and its field.
    pub field: (String, Field),
    /// Seconds of flow per time code from the frame.
    pub seconds_per_time_code: f64,
}

/// A compiled shader graph for a volume's density, as a reader found it.
#[derive(Clone, Debug, PartialEq)]
pub struct DensityGraph {
    pub program: crate::shader::graph::Program,
    /// The graph's position space (object space: the prim's local space) → world.
    pub shading_to_world: DMat4,
    /// The shader it was read from, "prim path (info:id)".
    pub source: String,
}

/// What a volume's density is and where it is.
#[derive(Clone, Debug, PartialEq)]
pub enum VolumeShape {
    /// A UsdVolVolume: the field the density is read from (the relationship
    /// `field:<density_field>`), where its grid is.
    Field(Field),
    /// A fog box: density 1 inside a gprim's surface (world-space triangles, wound so
    /// that e1 × e2 points outwards when `closed`).
    Mesh(FogMesh),
    /// World fog (`nimbus:fill = "world"`): density 1 filling the scene's extent.
    World,
}

impl VolumeShape {
    /// The density field of a UsdVolVolume (`None` for fog).
    pub fn field(&self) -> Option<&Field> {
        match self {
            VolumeShape::Field(f) => Some(f),
            _ => None,
        }
    }
}

/// A fog medium's parameters, as a reader finds them (`NimbusVolumeAPI` or a bound
/// volume material): everything of a [`Volume`] but where it is, and no fields.
#[derive(Clone, Debug)]
pub struct FogParams {
    pub density_scale: f64,
    pub absorption: [f64; 3],
    pub scattering: [f64; 3],
    pub anisotropy: f64,
    pub emission: VolumeEmission,
    pub material_shader: Option<String>,
    pub density_graph: Option<DensityGraph>,
    pub albedo_graph: Option<DensityGraph>,
}

impl FogParams {
    /// The fog volume `prim_path` of `shape` (a fog box's surface is already in world
    /// space, world fog has none: no transform).
    pub fn volume(
        self,
        prim_path: &str,
        light_group: Option<String>,
        shape: VolumeShape,
    ) -> Volume {
        Volume {
            prim_path: prim_path.to_string(),
            light_group,
            volume_to_world: DMat4::IDENTITY,
            motion: None,
            shape,
            density_scale: self.density_scale,
            absorption: self.absorption,
            scattering: self.scattering,
            anisotropy: self.anisotropy,
            fields: Vec::new(),
            emission: self.emission,
            albedo: None,
            albedo_graph: self.albedo_graph,
            velocity: None,
            material_shader: self.material_shader,
            density_graph: self.density_graph,
        }
    }
}

/// Folds a constant albedo multiplier `c` (`nimbus:albedo`) into a medium's
/// coefficients: σs → c·σs and σa → σa + (1 − c)·σs, with c clamped into [0,1], so
/// extinction is unchanged (as for a varying multiplier, `volume::albedo`).
pub fn fold_albedo(c: [f64; 3], absorption: &mut [f64; 3], scattering: &mut [f64; 3]) {
    for ((a, s), c) in absorption.iter_mut().zip(scattering.iter_mut()).zip(c) {
        let c = c.clamp(0.0, 1.0);
        *a += (1.0 - c) * *s;
        *s *= c;
    }
}

/// The surface of a fog box, as read.
#[derive(Clone, Debug, PartialEq)]
pub struct FogMesh {
    pub mesh: HoldoutMesh,
    /// Closed and consistently oriented (every edge shared by two triangles that run
    /// along it in opposite directions): inside is decided by the triangles' outward
    /// orientation. Otherwise (after a stage warning) by the parity of crossings.
    pub closed: bool,
}

/// The emission configuration of a volume, as authored (schema fallbacks applied; the
/// numbers are checked when the medium is built). Emitted radiance at x is
///
/// Le(x) = blackbodyIntensity · (T/1000 K)⁴ · rgb(T) + emissionScale · emissionColor · e(x),
/// T = temperatureScale · temperature(x),
///
/// with rgb(T) UsdLux's colour-temperature colour (luminance 1); the source term of the
/// radiative transfer equation is μa(x)·Le(x), so nothing emits where the density is 0.
#[derive(Clone, Debug, PartialEq)]
pub struct VolumeEmission {
    /// `nimbus:temperatureField`: the relationship name and its field, if set.
    pub temperature: Option<(String, Field)>,
    /// `nimbus:temperatureScale` (Kelvin per grid unit).
    pub temperature_scale: f64,
    /// `nimbus:blackbodyIntensity`.
    pub blackbody_intensity: f64,
    /// `nimbus:emissionField`: the relationship name and its field, if set.
    pub emission: Option<(String, Field)>,
    /// `nimbus:emissionColor`.
    pub emission_color: [f64; 3],
    /// `nimbus:emissionScale`.
    pub emission_scale: f64,
    /// `nimbus:emissionKind`: whether the model's value is radiance (source μa·Le) or
    /// the source term itself.
    pub kind: EmissionKind,
    /// `nimbus:emissionColor` connected to a colour graph (the Blender add-on's node
    /// trees): it replaces the constant colour.
    pub color_graph: Option<DensityGraph>,
}

impl Default for VolumeEmission {
    /// No fields; the parameters at the schema's fallbacks ([`EmissionParams`]).
    fn default() -> Self {
        let p = EmissionParams::default();
        VolumeEmission {
            temperature: None,
            temperature_scale: p.temperature_scale,
            blackbody_intensity: p.blackbody_intensity,
            emission: None,
            emission_color: p.emission_color,
            emission_scale: p.emission_scale,
            kind: p.kind,
            color_graph: None,
        }
    }
}

impl VolumeEmission {
    /// The emission model's parameters.
    pub fn params(&self) -> EmissionParams {
        EmissionParams {
            temperature_scale: self.temperature_scale,
            blackbody_intensity: self.blackbody_intensity,
            emission_color: self.emission_color,
            emission_scale: self.emission_scale,
            kind: self.kind,
        }
    }

    /// Whether any emission field is configured (a source-kind emission without a
    /// field has the constant field 1).
    pub fn is_emissive(&self) -> bool {
        self.temperature.is_some() || self.emission.is_some() || self.kind == EmissionKind::Source
    }
}

/// A UsdGeom gprim read as a holdout: a black matte occluder, opaque from both sides,
/// as world-space triangles at the scene's time. Meshes are fan-triangulated (a
/// subdivision mesh is its control cage); the implicit gprims (Sphere, Cube, Cylinder,
/// Cone, Capsule, Plane) are tessellated (see `scene::geometry`).
#[derive(Clone, Debug, PartialEq)]
pub struct HoldoutMesh {
    pub prim_path: String,
    /// The schema type read: "Mesh", "Sphere", "Cube", "Cylinder", "Cone", "Capsule"
    /// or "Plane".
    pub prim_type: String,
    /// World-space vertex positions (all finite).
    pub points: Vec<[f64; 3]>,
    /// Triangles as indices into `points`, degenerate ones already left out.
    pub triangles: Vec<[u32; 3]>,
    /// Polygons read (a Mesh's faces less its holes; for an implicit gprim, the
    /// tessellation's triangles before degenerate ones are dropped).
    pub faces: usize,
    /// Triangles left out because they have zero area or repeat a vertex.
    pub degenerate_triangles: usize,
    /// `doubleSided`, recorded only: a holdout blocks rays from both sides regardless.
    pub double_sided: bool,
}

/// A UsdVolOpenVDBAsset prim, resolved.
#[derive(Clone, Debug, PartialEq)]
pub struct Field {
    pub prim_path: String,
    /// The resolved file path (absolute or relative to the working directory).
    /// For assets inside a .usdz, the package path and the member path.
    pub file: AssetLocation,
    /// `fieldName` (the grid name), empty when not authored.
    pub field_name: String,
    /// `fieldIndex`, when authored: which of the grids with that name (or, with no
    /// name, which grid of the file).
    pub field_index: Option<i32>,
}

/// Render settings: UsdRenderSettings plus Nimbus' render-settings schema.
#[derive(Clone, Debug)]
pub struct RenderSettings {
    /// The UsdRenderSettings prim these came from, if any.
    pub prim_path: Option<String>,
    pub resolution: (u32, u32),
    /// Samples per pixel (`nimbus:samples`).
    pub samples: u32,
    /// Adaptive sampling (`nimbus:noiseThreshold`, 0 = off; `nimbus:minSamples`, 0 =
    /// the default minimum).
    pub noise_threshold: f64,
    pub min_samples: u32,
    /// Denoise the frame with Open Image Denoise (`nimbus:denoise`).
    pub denoise: bool,
    /// Maximum scattering depth (`nimbus:maxDepth`).
    pub max_depth: u32,
    /// Random seed (`nimbus:seed`).
    pub seed: u64,
    /// Render products with their render vars (AOVs).
    pub products: Vec<RenderProduct>,
    /// `nimbus:tracker`, `nimbus:scheme`, `nimbus:transmittance` (token names as the
    /// CLI spells them) and `nimbus:control`, when the stage sets them.
    pub tracker: Option<String>,
    pub scheme: Option<String>,
    pub transmittance: Option<String>,
    pub control: Option<f64>,
    /// `nimbus:octreeDepth` when the stage sets it (0 = the flat majorant grid).
    pub octree_depth: Option<i64>,
    /// `nimbus:strict`: a stage warning is an error (as `--strict`).
    pub strict: bool,
}

impl Default for RenderSettings {
    fn default() -> Self {
        RenderSettings {
            prim_path: None,
            resolution: (640, 480),
            samples: 16,
            noise_threshold: 0.0,
            min_samples: 0,
            denoise: false,
            max_depth: 64,
            seed: 0,
            products: Vec::new(),
            tracker: None,
            scheme: None,
            transmittance: None,
            control: None,
            octree_depth: None,
            strict: false,
        }
    }
}

#[derive(Clone, Debug)]
pub struct RenderProduct {
    pub prim_path: String,
    /// `productName`, when authored.
    pub product_name: Option<String>,
    /// `productType` ("raster", or "deepRaster" for a deep EXR).
    pub product_type: String,
    /// `nimbus:previewName`, when authored: a tone-mapped sRGB PNG of the beauty to
    /// write beside the EXR.
    pub preview_name: Option<String>,
    pub vars: Vec<RenderVar>,
}

#[derive(Clone, Debug)]
pub struct RenderVar {
    pub prim_path: String,
    /// `sourceName` (e.g. "color", "lookups", a light path expression).
    pub source_name: String,
    /// `sourceType` ("raw", "lpe", …; the schema's fallback is "raw").
    pub source_type: String,
    pub data_type: String,
}
