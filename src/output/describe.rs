//! What Nimbus reads from a file, as data: a stage (camera, lights, render settings,
//! holdouts, volumes with their fields and grids, the scene analysis and what `auto`
//! picks), a VDB file (its grids) or a deep EXR (its sample counts). `nimbus info`
//! prints a [`Description`] as text or, with `--json`, as JSON; `nimbus.info` returns
//! the same JSON as Python objects — one implementation.
//!
//! A part that cannot be read (a field's grids, the analysis of a stage that loads but
//! cannot be rendered) is described by its error message instead of failing the whole
//! description; a file that cannot be opened at all is an error.

use crate::output::deep::{is_deep_exr, read_deep_exr};
use crate::render::analysis::{Analysis, Given};
use crate::render::holdouts::{HoldoutStats, Holdouts};
use crate::render::session::{Overrides, Session};
use crate::scene::{load_stage, Field, LoadOptions, Scene};
use crate::track::select::TrackerSettings;
use crate::volume::asset::AssetLocation;
use crate::volume::grid::{Grid, RawGrid};
use crate::volume::majorant::{MajorantSpec, MajorantTree, MAX_DEPTH};
use crate::volume::vdb;
use anyhow::Result;
use glam::DMat4;
use serde::{Serialize, Serializer};
use std::path::Path;

/// What to evaluate a stage with.
#[derive(Clone, Copy, Debug)]
pub struct DescribeOptions {
    /// Time code (`None`: the stage's default time).
    pub frame: Option<f64>,
    /// Depth of the majorant octree built for each field and the analysis (clamped to
    /// 1..=[`MAX_DEPTH`]).
    pub octree_depth: u32,
}

impl Default for DescribeOptions {
    fn default() -> Self {
        DescribeOptions {
            frame: None,
            octree_depth: 8,
        }
    }
}

/// A described file; the JSON's `kind` says which.
#[derive(Serialize, Debug, Clone)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Description {
    Stage(StageDescription),
    Vdb(VdbDescription),
    DeepExr(DeepExrDescription),
}

/// Describes `path`: a `.vdb` file, a deep EXR, or else a USD stage.
pub fn describe(path: &Path, o: &DescribeOptions) -> Result<Description> {
    if path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("vdb"))
    {
        return Ok(Description::Vdb(describe_vdb(path)?));
    }
    if is_deep_exr(path) {
        return Ok(Description::DeepExr(describe_deep_exr(path)?));
    }
    Ok(Description::Stage(describe_stage(path, o)?))
}

// ----- a stage --------------------------------------------------------------------------

#[derive(Serialize, Debug, Clone)]
pub struct StageDescription {
    pub stage: String,
    /// The time code evaluated; `None` for the stage's default time.
    pub time: Option<f64>,
    pub vdb_reader: &'static str,
    pub camera: CameraDescription,
    /// Every light, in the renderer's order (distant, dome, sphere, rect, disk,
    /// cylinder, each in stage order).
    pub lights: Vec<LightDescription>,
    pub render_settings: RenderSettingsDescription,
    /// The depth of the majorant octrees built for the fields and the analysis.
    pub octree_depth: u32,
    /// The holdout geometry and its BVH; `None` when the stage has none.
    pub holdouts: Option<HoldoutsDescription>,
    pub volumes: Vec<VolumeDescription>,
    /// The scene analysis as `render` makes it (`None` when the stage cannot be
    /// rendered: see `analysis_error`).
    pub analysis: Option<Analysis>,
    /// What `render --tracker auto` would pick without flags.
    pub auto: Option<AutoChoice>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub analysis_error: Option<String>,
    /// What `render` would warn about (defaults it would add, …).
    pub warnings: Vec<String>,
}

#[derive(Serialize, Debug, Clone)]
pub struct CameraDescription {
    pub prim_path: String,
    /// "Perspective" or "Orthographic".
    pub projection: String,
    pub focal_length: f64,
    pub horizontal_aperture: f64,
    pub vertical_aperture: f64,
    pub clipping_range: (f64, f64),
    /// `fStop` and `focusDistance`: depth of field when both are positive.
    pub f_stop: f64,
    pub focus_distance: f64,
    /// `shutter:open`, `shutter:close` when open (time codes from the frame).
    pub shutter: Option<(f64, f64)>,
    /// Keys of the camera's transform over the shutter (0: it does not move).
    pub motion_keys: usize,
}

/// A light as the renderer lists it ([`Scene::lights`], whose index is the light id),
/// with the parameters Nimbus reads of it.
#[derive(Serialize, Debug, Clone)]
pub struct LightDescription {
    pub prim_path: String,
    /// `nimbus:lightGroup`: the light group its light-group AOVs gather it under.
    pub light_group: Option<String>,
    /// The light's type (`type` in the JSON) and parameters.
    #[serde(flatten)]
    pub params: LightParams,
    /// Keys of the light's transform over the shutter (0: it does not move).
    pub motion_keys: usize,
}

/// A UsdLux light's parameters by type; `position` is the light's origin in world
/// space.
#[derive(Serialize, Debug, Clone)]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum LightParams {
    Distant {
        direction: [f64; 3],
        intensity: f64,
        exposure: f64,
        color: [f64; 3],
        normalize: bool,
        angle: f64,
    },
    Dome {
        intensity: f64,
        exposure: f64,
        color: [f64; 3],
        texture_file: Option<String>,
        texture_format: String,
    },
    Sphere {
        position: [f64; 3],
        radius: f64,
        intensity: f64,
        exposure: f64,
        color: [f64; 3],
        normalize: bool,
        treat_as_point: bool,
        lights_interior: bool,
    },
    Rect {
        position: [f64; 3],
        width: f64,
        height: f64,
        intensity: f64,
        exposure: f64,
        color: [f64; 3],
        normalize: bool,
    },
    Disk {
        position: [f64; 3],
        radius: f64,
        intensity: f64,
        exposure: f64,
        color: [f64; 3],
        normalize: bool,
    },
    Cylinder {
        position: [f64; 3],
        length: f64,
        radius: f64,
        intensity: f64,
        exposure: f64,
        color: [f64; 3],
        normalize: bool,
        treat_as_line: bool,
    },
    /// A light type the renderer lights and this description does not list the
    /// parameters of yet (`type` "other"): it is listed all the same.
    Other,
}

#[derive(Serialize, Debug, Clone)]
pub struct RenderSettingsDescription {
    pub prim_path: Option<String>,
    pub resolution: [u32; 2],
    pub samples: u32,
    pub max_depth: u32,
    pub seed: u64,
    /// Adaptive sampling (`nimbus:noiseThreshold`, 0 = off; `nimbus:minSamples`, 0 =
    /// the default minimum).
    pub noise_threshold: f64,
    pub min_samples: u32,
    /// `nimbus:denoise`.
    pub denoise: bool,
    pub tracker: Option<String>,
    pub products: Vec<ProductDescription>,
}

#[derive(Serialize, Debug, Clone)]
pub struct ProductDescription {
    pub prim_path: String,
    pub product_name: Option<String>,
    pub preview_name: Option<String>,
    /// The vars' `sourceName`s.
    pub vars: Vec<String>,
}

#[derive(Serialize, Debug, Clone)]
pub struct HoldoutsDescription {
    pub stats: HoldoutStats,
    pub meshes: Vec<HoldoutMeshDescription>,
}

#[derive(Serialize, Debug, Clone)]
pub struct HoldoutMeshDescription {
    pub prim_path: String,
    pub prim_type: String,
    pub triangles: usize,
    pub degenerate_triangles: usize,
}

#[derive(Serialize, Debug, Clone)]
pub struct VolumeDescription {
    pub prim_path: String,
    /// What the density is: the density field's OpenVDBAsset prim, or for fog
    /// "fog box (N triangles, closed|not closed)" / "world fog".
    pub density_field: String,
    pub density_scale: f64,
    pub absorption: [f64; 3],
    pub scattering: [f64; 3],
    pub anisotropy: f64,
    /// The names (keys of `fields`) of the temperature, emission and albedo fields.
    pub temperature_field: Option<String>,
    pub temperature_scale: f64,
    pub blackbody_intensity: f64,
    pub emission_field: Option<String>,
    pub emission_color: [f64; 3],
    pub emission_scale: f64,
    /// `nimbus:emissionKind`: "radiance" or "source".
    pub emission_kind: &'static str,
    /// The colour graph in place of `emission_color` (`nimbus:emissionColor`
    /// connected, or a MaterialX edf's colour graph), as its source shader.
    pub emission_graph: Option<String>,
    pub albedo_field: Option<String>,
    /// The colour graph `nimbus:albedo` is connected to, as its source shader.
    pub albedo_graph: Option<String>,
    /// Keys of the volume's transform over the shutter (0: it does not move).
    pub motion_keys: usize,
    /// The velocity field (a key of `fields`) that advects the fields over the shutter,
    /// and its seconds of flow per time code.
    pub velocity_field: Option<String>,
    pub velocity_seconds_per_time_code: f64,
    /// The bound material's volume shader the parameters come from, if any.
    pub material_shader: Option<String>,
    /// The shader graph the density goes through, if any: its source and size.
    pub density_graph: Option<DensityGraphDescription>,
    /// Every `field:NAME` of the volume, by NAME, in stage order.
    #[serde(serialize_with = "as_map")]
    pub fields: Vec<(String, FieldDescription)>,
}

/// A volume's density graph as `nimbus info` reports it.
#[derive(Serialize, Debug, Clone)]
pub struct DensityGraphDescription {
    pub source: String,
    /// Instructions of the compiled program (each evaluated per density lookup).
    pub instructions: usize,
    /// Whether it reads the density field (else the field only says where it is).
    pub reads_field: bool,
}

impl VolumeDescription {
    /// The field named `name`.
    pub fn field(&self, name: &str) -> Option<&FieldDescription> {
        self.fields.iter().find(|f| f.0 == name).map(|f| &f.1)
    }
}

#[derive(Serialize, Debug, Clone)]
pub struct FieldDescription {
    /// The OpenVDBAsset prim.
    pub prim_path: String,
    pub file: String,
    pub field_name: String,
    pub field_index: Option<i32>,
    /// The grids of the file; `None` when they cannot be listed (`grids_error`).
    pub grids: Option<Vec<GridDescription>>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub grids_error: Option<String>,
    /// The grid as Nimbus loads it; `None` when it cannot be loaded (`load_error`).
    pub loaded: Option<LoadedField>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub load_error: Option<String>,
}

/// A grid as a VDB file lists it.
#[derive(Serialize, Debug, Clone)]
pub struct GridDescription {
    pub name: String,
    /// OpenVDB tree type, e.g. "Tree_float_5_4_3".
    #[serde(rename = "type")]
    pub value_type: String,
    pub active_voxels: Option<u64>,
}

/// A field's grid as loaded: the albedo field as three channels, any other as a
/// density-like float grid with its bricks and majorant octree.
#[derive(Serialize, Debug, Clone)]
#[serde(tag = "as", rename_all = "snake_case")]
pub enum LoadedField {
    Albedo {
        grid: String,
        active_voxels: u64,
        leaves: usize,
        tiles: usize,
        background: [f32; 3],
    },
    Float {
        grid: String,
        active_voxels: u64,
        leaves: usize,
        tiles: usize,
        background: f32,
        bricks: usize,
        memory_bytes: usize,
        sanitized_voxels: u64,
        /// World-space bounds of the active voxel centres.
        world_bounds: Option<[[f64; 3]; 2]>,
        octree: OctreeDescription,
    },
}

/// A majorant octree built over a grid.
#[derive(Serialize, Debug, Clone)]
pub struct OctreeDescription {
    pub depth: u32,
    pub levels: usize,
    /// Leaf cells along x, y, z.
    pub dims: [i32; 3],
    /// A leaf cell's edge in voxels.
    pub leaf_edge: [f32; 3],
    pub max_density: f32,
    pub build_seconds: f64,
    pub memory_bytes: usize,
}

/// What `render --tracker auto` picks for the stage and why.
#[derive(Serialize, Debug, Clone)]
pub struct AutoChoice {
    pub tracker: &'static str,
    pub scheme: &'static str,
    pub transmittance: &'static str,
    pub no_absorption_events: bool,
    pub reason: String,
    /// One global majorant per volume instead of an octree (a homogeneous medium).
    pub one_global_majorant: bool,
    /// What `--light-sampling auto` does with the local lights, and why.
    pub light_sampling: String,
}

fn as_map<S: Serializer, T: Serialize>(v: &[(String, T)], s: S) -> Result<S::Ok, S::Error> {
    s.collect_map(v.iter().map(|(k, v)| (k, v)))
}

fn bounds(b: Option<(glam::DVec3, glam::DVec3)>) -> Option<[[f64; 3]; 2]> {
    b.map(|(lo, hi)| [lo.to_array(), hi.to_array()])
}

/// Describes the stage at `path` as authored (no default camera or lights: the
/// warnings say what `render` would add), with the analysis `render` would make.
pub fn describe_stage(path: &Path, o: &DescribeOptions) -> Result<StageDescription> {
    let depth = o.octree_depth.clamp(1, MAX_DEPTH);
    let scene = load_stage(
        path,
        &LoadOptions {
            frame: o.frame,
            camera: None,
        },
    )?;
    let c = &scene.camera;
    let s = &scene.settings;
    let mut d = StageDescription {
        stage: scene.stage_path.display().to_string(),
        time: (!scene.time.is_nan()).then_some(scene.time),
        vdb_reader: vdb::active_reader().name(),
        camera: CameraDescription {
            prim_path: c.prim_path.clone(),
            projection: format!("{:?}", c.projection),
            focal_length: c.focal_length,
            horizontal_aperture: c.horizontal_aperture,
            vertical_aperture: c.vertical_aperture,
            clipping_range: c.clipping_range,
            f_stop: c.f_stop,
            focus_distance: c.focus_distance,
            shutter: c.shutter,
            motion_keys: c.motion.as_ref().map_or(0, |m| m.keys().len()),
        },
        lights: lights(&scene),
        render_settings: RenderSettingsDescription {
            prim_path: s.prim_path.clone(),
            resolution: [s.resolution.0, s.resolution.1],
            samples: s.samples,
            max_depth: s.max_depth,
            seed: s.seed,
            noise_threshold: s.noise_threshold,
            min_samples: s.min_samples,
            denoise: s.denoise,
            tracker: s.tracker.clone(),
            products: s
                .products
                .iter()
                .map(|p| ProductDescription {
                    prim_path: p.prim_path.clone(),
                    product_name: p.product_name.clone(),
                    preview_name: p.preview_name.clone(),
                    vars: p.vars.iter().map(|v| v.source_name.clone()).collect(),
                })
                .collect(),
        },
        octree_depth: depth,
        holdouts: holdouts(&scene),
        volumes: scene.volumes.iter().map(|v| volume(v, depth)).collect(),
        analysis: None,
        auto: None,
        analysis_error: None,
        warnings: Vec::new(),
    };
    // The session loads the grids and analyses as `render` does (a stage without a
    // camera or lights gets the defaults `render` would give it).
    let overrides = Overrides {
        frame: o.frame,
        octree_depth: Some(depth),
        ..Overrides::default()
    };
    // From the scene read above: one read of the stage (a deep hierarchy's cost).
    match Session::from_scene(path, scene.clone(), &overrides) {
        Ok(session) => {
            let light_sampling = session.job(false).light_sampling_summary();
            let a = session.analysis;
            // What `render` would do without flags: the stage may name the structure.
            let given = Given {
                majorants: s.octree_depth.is_some(),
                ..Given::default()
            };
            let (t, reason) = a.choose(TrackerSettings::default(), given);
            d.auto = Some(AutoChoice {
                tracker: t.tracker.name(),
                scheme: t.scheme.name(),
                transmittance: t.transmittance.name(),
                no_absorption_events: t.options.no_absorption_events,
                reason,
                one_global_majorant: a.majorants(given)
                    == Some(MajorantSpec::Uniform { cell_voxels: 0 }),
                light_sampling,
            });
            d.analysis = Some(a);
            d.warnings = session.warnings;
        }
        Err(e) => d.analysis_error = Some(format!("{e:#}")),
    }
    Ok(d)
}

/// Every light the renderer lights, in its order: [`Scene::lights`] is the one list of
/// them, so a light type added to the scene is described (at least by its prim path
/// and light group) without an edit here.
fn lights(scene: &Scene) -> Vec<LightDescription> {
    scene
        .lights()
        .into_iter()
        .map(|e| LightDescription {
            prim_path: e.prim_path.to_string(),
            light_group: e.light_group.map(str::to_string),
            params: light_params(scene, e.prim_path),
            motion_keys: light_motion_keys(scene, e.prim_path),
        })
        .collect()
}

/// The transform keys of the (local) light at `prim_path`, 0 when it does not move.
fn light_motion_keys(scene: &Scene, prim_path: &str) -> usize {
    let keys = |path: &str, m: &Option<crate::motion::TransformMotion>| {
        (path == prim_path).then(|| m.as_ref().map_or(0, |m| m.keys().len()))
    };
    (scene
        .sphere_lights
        .iter()
        .find_map(|l| keys(&l.prim_path, &l.motion)))
    .or_else(|| {
        scene
            .rect_lights
            .iter()
            .find_map(|l| keys(&l.prim_path, &l.motion))
    })
    .or_else(|| {
        scene
            .disk_lights
            .iter()
            .find_map(|l| keys(&l.prim_path, &l.motion))
    })
    .or_else(|| {
        scene
            .cylinder_lights
            .iter()
            .find_map(|l| keys(&l.prim_path, &l.motion))
    })
    .unwrap_or(0)
}

/// The parameters of the light at `prim_path`, found in the scene's list of its type.
fn light_params(scene: &Scene, prim_path: &str) -> LightParams {
    let position = |m: &DMat4| m.w_axis.truncate().to_array();
    if let Some(l) = scene
        .distant_lights
        .iter()
        .find(|l| l.prim_path == prim_path)
    {
        return LightParams::Distant {
            direction: l.direction,
            intensity: l.intensity,
            exposure: l.exposure,
            color: l.color,
            normalize: l.normalize,
            angle: l.angle_degrees,
        };
    }
    if let Some(l) = scene.dome_lights.iter().find(|l| l.prim_path == prim_path) {
        return LightParams::Dome {
            intensity: l.intensity,
            exposure: l.exposure,
            color: l.color,
            texture_file: l.texture_file.clone(),
            texture_format: l.texture_format.clone(),
        };
    }
    if let Some(l) = scene
        .sphere_lights
        .iter()
        .find(|l| l.prim_path == prim_path)
    {
        return LightParams::Sphere {
            position: position(&l.light_to_world),
            radius: l.radius,
            intensity: l.intensity,
            exposure: l.exposure,
            color: l.color,
            normalize: l.normalize,
            treat_as_point: l.treat_as_point,
            lights_interior: l.lights_interior,
        };
    }
    if let Some(l) = scene.rect_lights.iter().find(|l| l.prim_path == prim_path) {
        return LightParams::Rect {
            position: position(&l.light_to_world),
            width: l.width,
            height: l.height,
            intensity: l.intensity,
            exposure: l.exposure,
            color: l.color,
            normalize: l.normalize,
        };
    }
    if let Some(l) = scene.disk_lights.iter().find(|l| l.prim_path == prim_path) {
        return LightParams::Disk {
            position: position(&l.light_to_world),
            radius: l.radius,
            intensity: l.intensity,
            exposure: l.exposure,
            color: l.color,
            normalize: l.normalize,
        };
    }
    if let Some(l) = scene
        .cylinder_lights
        .iter()
        .find(|l| l.prim_path == prim_path)
    {
        return LightParams::Cylinder {
            position: position(&l.light_to_world),
            length: l.length,
            radius: l.radius,
            intensity: l.intensity,
            exposure: l.exposure,
            color: l.color,
            normalize: l.normalize,
            treat_as_line: l.treat_as_line,
        };
    }
    LightParams::Other
}

/// The holdout geometry and what its BVH costs (built here as `render` builds it).
fn holdouts(scene: &Scene) -> Option<HoldoutsDescription> {
    let meshes = &scene.holdouts;
    if meshes.is_empty() {
        return None;
    }
    Some(HoldoutsDescription {
        stats: Holdouts::build(meshes).stats(),
        meshes: meshes
            .iter()
            .map(|m| HoldoutMeshDescription {
                prim_path: m.prim_path.clone(),
                prim_type: m.prim_type.clone(),
                triangles: m.triangles.len(),
                degenerate_triangles: m.degenerate_triangles,
            })
            .collect(),
    })
}

fn volume(v: &crate::scene::Volume, depth: u32) -> VolumeDescription {
    use crate::scene::VolumeShape;
    let e = &v.emission;
    let name = |f: &Option<(String, Field)>| f.as_ref().map(|(n, _)| n.clone());
    let albedo = name(&v.albedo);
    VolumeDescription {
        prim_path: v.prim_path.clone(),
        density_field: match &v.shape {
            VolumeShape::Field(f) => f.prim_path.clone(),
            VolumeShape::Mesh(m) => format!(
                "fog box ({} triangles, {})",
                m.mesh.triangles.len(),
                if m.closed { "closed" } else { "not closed" }
            ),
            VolumeShape::World => "world fog".to_string(),
        },
        density_scale: v.density_scale,
        absorption: v.absorption,
        scattering: v.scattering,
        anisotropy: v.anisotropy,
        temperature_field: name(&e.temperature),
        temperature_scale: e.temperature_scale,
        blackbody_intensity: e.blackbody_intensity,
        emission_field: name(&e.emission),
        emission_color: e.emission_color,
        emission_scale: e.emission_scale,
        emission_kind: e.kind.token(),
        emission_graph: e.color_graph.as_ref().map(|g| g.source.clone()),
        albedo_field: albedo.clone(),
        albedo_graph: v.albedo_graph.as_ref().map(|g| g.source.clone()),
        motion_keys: v.motion.as_ref().map_or(0, |m| m.keys().len()),
        velocity_field: v.velocity.as_ref().map(|x| x.field.0.clone()),
        velocity_seconds_per_time_code: v
            .velocity
            .as_ref()
            .map_or(0.0, |x| x.seconds_per_time_code),
        material_shader: v.material_shader.clone(),
        density_graph: v.density_graph.as_ref().map(|g| DensityGraphDescription {
            source: g.source.clone(),
            instructions: g.program.len(),
            reads_field: g.program.reads_attribute(),
        }),
        fields: v
            .fields
            .iter()
            .map(|(n, f)| {
                let is_albedo = albedo.as_deref() == Some(n.as_str());
                (n.clone(), field(f, is_albedo, v.volume_to_world, depth))
            })
            .collect(),
    }
}

/// A field: its file's grids, and its grid loaded as `render` loads it — the albedo
/// field as three channels (a Vec3s, or a float read as grey), any other as a float
/// grid in bricks with a majorant octree of `depth`.
fn field(f: &Field, is_albedo: bool, volume_to_world: DMat4, depth: u32) -> FieldDescription {
    let (grids, grids_error) = match vdb::list_grids(&f.file) {
        Ok(gs) => (
            Some(
                gs.into_iter()
                    .map(|g| GridDescription {
                        name: g.name,
                        value_type: g.value_type,
                        active_voxels: g.active_voxels,
                    })
                    .collect(),
            ),
            None,
        ),
        Err(e) => (None, Some(e.to_string())),
    };
    // Error messages as `{:#}` of what failed (the VDB error, or the chain of the
    // brick build's).
    let loaded = if is_albedo {
        vdb::read_color_grid(&f.file, &f.field_name, f.field_index)
            .map(|raw| LoadedField::Albedo {
                grid: raw[0].name.clone(),
                active_voxels: raw[0].active_voxel_count(),
                leaves: raw[0].leaves.len(),
                tiles: raw[0].tiles.len(),
                background: raw.each_ref().map(|g| g.background),
            })
            .map_err(|e| format!("{e:#}"))
    } else {
        vdb::read_float_grid(&f.file, &f.field_name, f.field_index)
            .map_err(anyhow::Error::from)
            .and_then(|raw| {
                let g = Grid::from_raw(&raw)?;
                Ok(float_field(&raw, &g, volume_to_world, depth))
            })
            .map_err(|e| format!("{e:#}"))
    };
    let (loaded, load_error) = match loaded {
        Ok(l) => (Some(l), None),
        Err(e) => (None, Some(e)),
    };
    FieldDescription {
        prim_path: f.prim_path.clone(),
        file: f.file.to_string(),
        field_name: f.field_name.clone(),
        field_index: f.field_index,
        grids,
        grids_error,
        loaded,
        load_error,
    }
}

fn float_field(raw: &RawGrid, g: &Grid, volume_to_world: DMat4, depth: u32) -> LoadedField {
    let t = MajorantTree::build(g, MajorantSpec::Octree { depth });
    LoadedField::Float {
        grid: raw.name.clone(),
        active_voxels: raw.active_voxel_count(),
        leaves: raw.leaves.len(),
        tiles: raw.tiles.len(),
        background: raw.background,
        bricks: g.brick_count(),
        memory_bytes: g.memory_bytes(),
        sanitized_voxels: g.sanitized_voxels,
        world_bounds: bounds(raw.world_bounds(volume_to_world)),
        octree: OctreeDescription {
            depth,
            levels: t.levels(),
            dims: t.dims(),
            leaf_edge: t.leaf_edge(),
            max_density: t.max_density(),
            build_seconds: t.build_seconds(),
            memory_bytes: t.memory_bytes(),
        },
    }
}

// ----- a VDB file -----------------------------------------------------------------------

#[derive(Serialize, Debug, Clone)]
pub struct VdbDescription {
    pub vdb: String,
    pub vdb_reader: &'static str,
    pub grids: Vec<VdbGridDescription>,
}

/// A grid of a VDB file and, for float and Vec3s grids, what loading it gives.
#[derive(Serialize, Debug, Clone)]
pub struct VdbGridDescription {
    #[serde(flatten)]
    pub grid: GridDescription,
    /// One channel for a float grid, x, y, z for a Vec3s grid; empty for other types
    /// (not loaded) or when loading failed (`load_error`).
    pub channels: Vec<VdbChannelDescription>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub load_error: Option<String>,
}

#[derive(Serialize, Debug, Clone)]
pub struct VdbChannelDescription {
    pub name: String,
    /// "x", "y" or "z" for a Vec3s grid's channels.
    pub component: Option<&'static str>,
    pub active_voxels: u64,
    pub leaves: usize,
    pub tiles: usize,
    pub background: f32,
    /// Smallest and largest active value (voxels and tiles) as stored, NaNs skipped;
    /// (inf, -inf), in JSON (null, null), when no value is active.
    pub value_range: [f32; 2],
    /// World-space bounds of the active voxel centres (the grid's own transform).
    pub world_bounds: Option<[[f64; 3]; 2]>,
}

/// The grids of a VDB file (name, type, active voxels) and, for float and Vec3s grids,
/// what loading them gives: voxel counts, value range, world bounds.
pub fn describe_vdb(path: &Path) -> Result<VdbDescription> {
    let loc = AssetLocation::File(path.to_path_buf());
    let grids = vdb::list_grids(&loc)?
        .into_iter()
        .map(|g| {
            let loaded = if g.value_type.contains("float") {
                Some(vdb::read_float_grid(&loc, &g.name, None).map(|r| vec![r]))
            } else if g.value_type.contains("vec3s") {
                Some(vdb::read_vec3s_grid(&loc, &g.name, None).map(Vec::from))
            } else {
                None
            };
            let (channels, load_error) = match loaded {
                None => (Vec::new(), None),
                Some(Ok(raws)) => {
                    let vector = raws.len() == 3;
                    let channels = raws
                        .iter()
                        .enumerate()
                        .map(|(c, raw)| {
                            let (lo, hi) = active_value_range(raw);
                            VdbChannelDescription {
                                name: raw.name.clone(),
                                component: vector.then(|| ["x", "y", "z"][c]),
                                active_voxels: raw.active_voxel_count(),
                                leaves: raw.leaves.len(),
                                tiles: raw.tiles.len(),
                                background: raw.background,
                                value_range: [lo, hi],
                                world_bounds: bounds(raw.world_bounds(DMat4::IDENTITY)),
                            }
                        })
                        .collect();
                    (channels, None)
                }
                Some(Err(e)) => (Vec::new(), Some(e.to_string())),
            };
            VdbGridDescription {
                grid: GridDescription {
                    name: g.name,
                    value_type: g.value_type,
                    active_voxels: g.active_voxels,
                },
                channels,
                load_error,
            }
        })
        .collect();
    Ok(VdbDescription {
        vdb: path.display().to_string(),
        vdb_reader: vdb::active_reader().name(),
        grids,
    })
}

/// Smallest and largest active value (voxels and tiles) as stored; NaNs are skipped
/// (`f32::min`/`max`); (inf, -inf) for a grid with no active value.
fn active_value_range(raw: &RawGrid) -> (f32, f32) {
    let mut r = (f32::INFINITY, f32::NEG_INFINITY);
    let mut add = |v: f32| r = (r.0.min(v), r.1.max(v));
    for l in &raw.leaves {
        for (i, &v) in l.values.iter().enumerate() {
            if l.active[i / 64] >> (i % 64) & 1 == 1 {
                add(v);
            }
        }
    }
    for t in raw.tiles.iter().filter(|t| t.active) {
        add(t.value);
    }
    r
}

// ----- a deep EXR -----------------------------------------------------------------------

#[derive(Serialize, Debug, Clone)]
pub struct DeepExrDescription {
    pub deep_exr: String,
    /// Data window, `x0..x1` × `y0..y1` (exclusive ends), y down.
    pub data_window: [u32; 4],
    pub display_window: [u32; 2],
    /// The first part's channels: (name, sample type).
    pub channels: Vec<(String, String)>,
    pub samples: usize,
    pub pixels: usize,
    pub samples_per_pixel_min: u32,
    pub samples_per_pixel_mean: f64,
    pub samples_per_pixel_max: u32,
    pub empty_pixels: usize,
}

/// Windows, channels and how the samples of a deep EXR are spread over its pixels.
pub fn describe_deep_exr(path: &Path) -> Result<DeepExrDescription> {
    let meta = ::exr::meta::MetaData::read_from_file(path, false)?;
    let channels = meta
        .headers
        .first()
        .map(|h| {
            h.channels
                .list
                .iter()
                .map(|c| (c.name.to_string(), format!("{:?}", c.sample_type)))
                .collect()
        })
        .unwrap_or_default();
    let image = read_deep_exr(path)?;
    let r = image.region;
    let counts = &image.counts;
    Ok(DeepExrDescription {
        deep_exr: path.display().to_string(),
        data_window: [r.x0, r.x1, r.y0, r.y1],
        display_window: [image.full.0, image.full.1],
        channels,
        samples: image.samples.len(),
        pixels: counts.len(),
        samples_per_pixel_min: counts.iter().min().copied().unwrap_or(0),
        samples_per_pixel_mean: image.samples.len() as f64 / counts.len().max(1) as f64,
        samples_per_pixel_max: counts.iter().max().copied().unwrap_or(0),
        empty_pixels: counts.iter().filter(|&&n| n == 0).count(),
    })
}
