//! What Hydra hands over, as the scene description the USD reader builds
//! ([`nimbus::scene::Scene`]): the second reader of the one render pipeline. The
//! conversions follow the USD reader's (`nimbus::scene::stage`): world transforms, UsdLux
//! parameters with schema fallbacks, NimbusVolumeAPI's fallback coefficients, holdout
//! meshes fan-triangulated, fog boxes (meshes with NimbusVolumeAPI's primvars or a volume
//! material) and world fog (`nimbus:fill = "world"`). Also the render settings the delegate reads (`settings`)
//! and offers the host with their defaults (`setting_descriptors`), side by side.

// Only the bridge's plain structs. cxx declares shared structs only inside the
// #[cxx::bridge] module, and that module's parent (`crate::ffi`) must also hold the
// extern "Rust" entry points, which call down into this module: hence the one cycle of
// files, ffi -> scene -> ffi::bridge. No code of ffi is used here, only its data.
use crate::ffi::bridge::{
    CameraDesc, FieldDesc, LightDesc, MeshDesc, ParamDesc, SceneDesc, SettingDesc,
    SettingDescriptor, ShaderNodeDesc, VolumeDesc, XformSample,
};
use anyhow::{anyhow, bail, Result};
use glam::{DMat4, DVec3};
use nimbus::motion::TransformMotion;
use nimbus::scene::materialx_graph;
use nimbus::scene::schema::tokens;
use nimbus::scene::shader_network::{Input, ParamValue, ShaderNetwork, ShaderNode};
use nimbus::scene::{
    fog, fold_albedo, Camera, Collection, CylinderLight, DensityGraph, DiskLight, DistantLight,
    DomeLight, Field, FogParams, HoldoutMesh, LightControls, Projection, RectLight, RenderSettings,
    Scene, Shaping, SphereLight, Volume, VolumeEmission, VolumeShape,
};
use nimbus::shader::graph::Program;
use nimbus::volume::asset::AssetLocation;
use nimbus::volume::emission::EmissionKind;
use std::collections::BTreeMap;
use std::path::PathBuf;

/// What the errors and warnings of a Hydra render name as their "stage".
pub const STAGE_NAME: &str = "hdNimbus";

/// UsdGeomCamera's lengths are tenths of a scene unit; Hydra's are scene units.
const APERTURE_UNIT: f64 = 10.0;

/// The scene Hydra describes, and the warnings about what it does not render as given.
pub fn scene_of(desc: &SceneDesc) -> Result<(Scene, Vec<String>)> {
    let mut warnings = Vec::new();
    for l in &desc.unsupported_lights {
        warnings.push(format!(
            "light {l}: a light type Nimbus does not render; it is left out"
        ));
    }
    let mut scene = Scene {
        stage_path: PathBuf::from(STAGE_NAME),
        time: f64::NAN,
        camera: nimbus::scene::defaults::placeholder_camera(),
        distant_lights: Vec::new(),
        dome_lights: Vec::new(),
        sphere_lights: Vec::new(),
        rect_lights: Vec::new(),
        disk_lights: Vec::new(),
        cylinder_lights: Vec::new(),
        volumes: Vec::new(),
        holdouts: Vec::new(),
        settings: settings(&desc.settings, (desc.width, desc.height))?,
        light_prims: desc.lights.len() + desc.unsupported_lights.len(),
        warnings: Default::default(),
    };
    let shutter = shutter(desc);
    if desc.has_camera {
        scene.camera = camera(&desc.camera, shutter)?;
    } else {
        scene.camera.shutter = shutter;
    }
    // Hydra syncs prims in no particular order; sort so a light's id (its index in
    // the renderer) and the image do not depend on the host's threads.
    let links = Links::of(desc);
    let mut lights: Vec<&LightDesc> = desc.lights.iter().collect();
    lights.sort_by(|a, b| a.path.cmp(&b.path));
    for l in lights {
        add_light(&mut scene, l, &links, shutter, &mut warnings)?;
    }
    let mut volumes: Vec<&VolumeDesc> = desc.volumes.iter().collect();
    volumes.sort_by(|a, b| a.path.cmp(&b.path));
    for v in volumes {
        scene.volumes.push(volume(v, shutter, &mut warnings)?);
    }
    let mut meshes: Vec<&MeshDesc> = desc.meshes.iter().collect();
    meshes.sort_by(|a, b| a.path.cmp(&b.path));
    for m in meshes {
        warn_if_moving("mesh", &m.path, &m.xform_samples, shutter, &mut warnings)?;
        mesh(m, &mut scene, &mut warnings)?;
    }
    Ok((scene, warnings))
}

fn matrix(m: &[f64; 16]) -> DMat4 {
    DMat4::from_cols_array(m)
}

fn finite_matrix(path: &str, m: &[f64; 16]) -> Result<DMat4> {
    if m.iter().all(|v| v.is_finite()) {
        Ok(matrix(m))
    } else {
        bail!("{path}: its transform has a non-finite entry")
    }
}

/// The shutter interval the render blurs over (time codes from the frame): the
/// camera's when it is open (open < close), else the render settings prim's
/// `shutterInterval` when that is open (as hdPrman falls back), else none. As the USD
/// reader's, whatever moves within it is blurred: the camera and the volumes.
fn shutter(desc: &SceneDesc) -> Option<(f64, f64)> {
    let open = |a: f64, b: f64| (a.is_finite() && b.is_finite() && a < b).then_some((a, b));
    let camera = desc
        .has_camera
        .then(|| open(desc.camera.shutter_open, desc.camera.shutter_close))
        .flatten();
    let settings = || {
        desc.has_settings_shutter
            .then(|| open(desc.settings_shutter[0], desc.settings_shutter[1]))
            .flatten()
    };
    camera.or_else(settings)
}

/// A prim's motion over `shutter` from the transform samples Hydra handed over
/// (`SampleTransform`: the authored samples, with UsdImaging the shutter's ends too):
/// keys at the shutter's two ends and at every sample between, a missing end
/// interpolated between the samples around it (held beyond the first and the last, as
/// USD holds time samples), component-wise as [`TransformMotion`] interpolates. None
/// without a shutter, or when nothing moves within it.
fn motion(
    path: &str,
    samples: &[XformSample],
    shutter: Option<(f64, f64)>,
) -> Result<Option<TransformMotion>> {
    let Some((open, close)) = shutter else {
        return Ok(None);
    };
    let mut sampled = Vec::with_capacity(samples.len());
    for s in samples {
        if !s.time.is_finite() {
            bail!("{path}: a transform sample at time {}", s.time);
        }
        sampled.push((s.time, finite_matrix(path, &s.xform)?));
    }
    sampled.sort_by(|a, b| a.0.total_cmp(&b.0));
    sampled.dedup_by(|later, earlier| later.0 == earlier.0);
    // Every sample, as one motion (None: fewer than two, or all the same).
    let Some(all) = TransformMotion::new(sampled) else {
        return Ok(None);
    };
    let inside = all.keys().iter().filter(|k| k.0 > open && k.0 < close);
    let keys = std::iter::once((open, all.at(open)))
        .chain(inside.copied())
        .chain([(close, all.at(close))])
        .collect();
    Ok(TransformMotion::new(keys))
}

/// A warning when the transform of `path` (a `kind` Nimbus does not blur) changes
/// while the shutter is open, as the USD reader warns.
fn warn_if_moving(
    kind: &str,
    path: &str,
    samples: &[XformSample],
    shutter: Option<(f64, f64)>,
    warnings: &mut Vec<String>,
) -> Result<()> {
    if let (Some((open, close)), Some(_)) = (shutter, motion(path, samples, shutter)?) {
        warnings.push(format!(
            "motion blur: {kind} {path}: its transform changes while the camera's shutter is open ({open} to {close}): Nimbus blurs the transforms of the camera, volumes and sphere, rect, disk and cylinder lights, not a {kind}'s; it is rendered at the frame's time"
        ));
    }
    Ok(())
}

fn camera(c: &CameraDesc, shutter: Option<(f64, f64)>) -> Result<Camera> {
    Ok(Camera {
        prim_path: c.path.clone(),
        camera_to_world: matrix(&c.xform),
        projection: match c.orthographic {
            true => Projection::Orthographic,
            false => Projection::Perspective,
        },
        focal_length: c.focal_length * APERTURE_UNIT,
        horizontal_aperture: c.horizontal_aperture * APERTURE_UNIT,
        vertical_aperture: c.vertical_aperture * APERTURE_UNIT,
        horizontal_aperture_offset: c.horizontal_aperture_offset * APERTURE_UNIT,
        vertical_aperture_offset: c.vertical_aperture_offset * APERTURE_UNIT,
        clipping_range: (c.near, c.far),
        f_stop: c.f_stop,
        focus_distance: c.focus_distance,
        shutter,
        motion: motion(&c.path, &c.xform_samples, shutter)?,
    })
}

/// Hydra's light linking: a light names its `lightLink` / `shadowLink` collection (an
/// empty name: every prim) and each rprim lists the collections it is in as its
/// categories. The USD reader's collections are membership rules over prim paths; a
/// Hydra collection becomes the rule that includes exactly its members' paths
/// (`includeRoot` off, `explicitOnly`), which the renderer's linking evaluates over the
/// volumes and holdouts as it evaluates the reader's.
struct Links {
    members: BTreeMap<String, Vec<String>>,
}

impl Links {
    fn of(desc: &SceneDesc) -> Links {
        let mut members: BTreeMap<String, Vec<String>> = BTreeMap::new();
        let prims = desc
            .volumes
            .iter()
            .map(|v| (&v.path, &v.categories))
            .chain(desc.meshes.iter().map(|m| (&m.path, &m.categories)));
        for (path, categories) in prims {
            for c in categories {
                members.entry(c.clone()).or_default().push(path.clone());
            }
        }
        for paths in members.values_mut() {
            paths.sort();
            paths.dedup();
        }
        Links { members }
    }

    /// The collection named `name` ("": everything; a name no rprim lists: nothing).
    fn collection(&self, name: &str) -> Collection {
        if name.is_empty() {
            return Collection::default();
        }
        Collection {
            include_root: false,
            includes: self.members.get(name).cloned().unwrap_or_default(),
            excludes: Vec::new(),
            explicit_only: true,
        }
    }
}

fn controls(l: &LightDesc, links: &Links) -> LightControls {
    LightControls {
        diffuse: l.diffuse,
        shaping: l.has_shaping.then(|| Shaping {
            focus: l.shaping_focus.max(0.0),
            focus_tint: l.shaping_focus_tint,
            cone_angle: l.shaping_cone_angle,
            cone_softness: l.shaping_cone_softness.clamp(0.0, 1.0),
            ies_file: (!l.shaping_ies_file.is_empty()).then(|| l.shaping_ies_file.clone()),
            ies_angle_scale: l.shaping_ies_angle_scale,
            ies_normalize: l.shaping_ies_normalize,
        }),
        light_link: links.collection(&l.light_link),
        shadow_link: links.collection(&l.shadow_link),
        unshadowed: !l.shadow_enable,
    }
}

/// The motion of a local (sphere, rect, disk, cylinder) light over `shutter`, as the
/// USD reader keeps it: only a light that turns and slides is blurred; one whose size
/// changes warns and renders at the frame.
fn light_motion(
    l: &LightDesc,
    to_world: &DMat4,
    shutter: Option<(f64, f64)>,
    warnings: &mut Vec<String>,
) -> Result<Option<TransformMotion>> {
    let Some(m) = motion(&l.path, &l.xform_samples, shutter)? else {
        return Ok(None);
    };
    if m.is_rigid_from(to_world) {
        return Ok(Some(m));
    }
    let (open, close) = shutter.unwrap_or_default();
    warnings.push(format!(
        "motion blur: light {}: it changes size or shape while the camera's shutter is open ({open} to {close}): Nimbus blurs a light that turns and slides, not one that scales; it is rendered at the frame's time",
        l.path
    ));
    Ok(None)
}

fn add_light(
    scene: &mut Scene,
    l: &LightDesc,
    links: &Links,
    shutter: Option<(f64, f64)>,
    warnings: &mut Vec<String>,
) -> Result<()> {
    let to_world = finite_matrix(&l.path, &l.xform)?;
    // Distant and dome lights are not blurred (as the USD reader's).
    let motion = match l.kind.as_str() {
        "sphereLight" | "rectLight" | "diskLight" | "cylinderLight" => {
            light_motion(l, &to_world, shutter, warnings)?
        }
        _ => {
            warn_if_moving("light", &l.path, &l.xform_samples, shutter, warnings)?;
            None
        }
    };
    let temperature = l.enable_color_temperature.then_some(l.color_temperature);
    let group = (!l.light_group.is_empty()).then(|| l.light_group.clone());
    let path = l.path.clone();
    match l.kind.as_str() {
        "distantLight" => {
            let d = to_world.transform_vector3(DVec3::Z);
            if d.length_squared() == 0.0 {
                bail!("{}: its transform collapses its direction", l.path);
            }
            scene.distant_lights.push(DistantLight {
                prim_path: path,
                controls: controls(l, links),
                light_group: group,
                direction: d.normalize().to_array(),
                intensity: l.intensity,
                exposure: l.exposure,
                color: l.color,
                normalize: l.normalize,
                color_temperature: temperature,
                angle_degrees: l.angle,
            })
        }
        "domeLight" => scene.dome_lights.push(DomeLight {
            prim_path: path,
            controls: controls(l, links),
            light_group: group,
            light_to_world: to_world,
            intensity: l.intensity,
            exposure: l.exposure,
            color: l.color,
            color_temperature: temperature,
            texture_file: (!l.texture_file.is_empty()).then(|| l.texture_file.clone()),
            texture_format: match l.texture_format.is_empty() {
                true => "automatic".to_string(),
                false => l.texture_format.clone(),
            },
        }),
        "sphereLight" => scene.sphere_lights.push(SphereLight {
            prim_path: path,
            controls: controls(l, links),
            light_group: group,
            light_to_world: to_world,
            motion,
            intensity: l.intensity,
            exposure: l.exposure,
            color: l.color,
            normalize: l.normalize,
            color_temperature: temperature,
            radius: l.radius,
            treat_as_point: l.treat_as_point,
            lights_interior: l.lights_interior,
        }),
        "rectLight" => scene.rect_lights.push(RectLight {
            prim_path: path,
            controls: controls(l, links),
            light_group: group,
            light_to_world: to_world,
            motion,
            intensity: l.intensity,
            exposure: l.exposure,
            color: l.color,
            normalize: l.normalize,
            color_temperature: temperature,
            width: l.width,
            height: l.height,
        }),
        "diskLight" => scene.disk_lights.push(DiskLight {
            prim_path: path,
            controls: controls(l, links),
            light_group: group,
            light_to_world: to_world,
            motion,
            intensity: l.intensity,
            exposure: l.exposure,
            color: l.color,
            normalize: l.normalize,
            color_temperature: temperature,
            radius: l.radius,
        }),
        "cylinderLight" => scene.cylinder_lights.push(CylinderLight {
            prim_path: path,
            controls: controls(l, links),
            light_group: group,
            light_to_world: to_world,
            motion,
            intensity: l.intensity,
            exposure: l.exposure,
            color: l.color,
            normalize: l.normalize,
            color_temperature: temperature,
            length: l.length,
            radius: l.radius,
            treat_as_line: l.treat_as_line,
        }),
        other => warnings.push(format!(
            "light {}: type {other} is not one Nimbus renders; it is left out",
            l.path
        )),
    }
    Ok(())
}

/// NimbusVolumeAPI's names, read as constant primvars (`primvars:nimbus:…`).
fn param<'a>(params: &'a [ParamDesc], name: &str) -> Option<&'a ParamDesc> {
    params
        .iter()
        .find(|p| p.name == name || p.name.strip_prefix("primvars:") == Some(name))
}

fn scalar(path: &str, params: &[ParamDesc], name: &str) -> Result<Option<f64>> {
    match param(params, name) {
        None => Ok(None),
        Some(p) if p.numbers.len() == 1 && p.numbers[0].is_finite() => Ok(Some(p.numbers[0])),
        Some(p) => bail!(
            "{path}: {name} must be one finite number, got {:?}",
            p.numbers
        ),
    }
}

fn color3(path: &str, params: &[ParamDesc], name: &str) -> Result<Option<[f64; 3]>> {
    match param(params, name) {
        None => Ok(None),
        Some(p) if p.numbers.len() == 3 && p.numbers.iter().all(|v| v.is_finite()) => {
            Ok(Some([p.numbers[0], p.numbers[1], p.numbers[2]]))
        }
        Some(p) if p.numbers.len() == 1 && p.numbers[0].is_finite() => Ok(Some([p.numbers[0]; 3])),
        Some(p) => bail!("{path}: {name} must be a colour, got {:?}", p.numbers),
    }
}

fn text<'a>(params: &'a [ParamDesc], name: &str) -> Option<&'a str> {
    param(params, name)
        .map(|p| p.text.as_str())
        .filter(|t| !t.is_empty())
}

fn field(volume: &str, f: &FieldDesc) -> Result<Field> {
    if f.prim_type != "openvdbAsset" {
        bail!(
            "{volume}: field {} ({}) is a {}; Nimbus reads only openvdbAsset fields",
            f.name,
            f.path,
            f.prim_type
        );
    }
    if f.file.is_empty() {
        bail!("{volume}: field {} ({}) has no filePath", f.name, f.path);
    }
    Ok(Field {
        prim_path: f.path.clone(),
        file: AssetLocation::File(PathBuf::from(&f.file)),
        field_name: f.grid.clone(),
        field_index: (f.index >= 0).then_some(f.index),
    })
}

/// A volume shader's coefficients, as the USD reader maps PxrVolume and MaterialX's
/// `ND_volume`/`ND_anisotropic_vdf` (see `nimbus::scene::shading`): extinction and
/// albedo become σs = albedo · density, σa = (1 − albedo) · density.
struct ShaderCoefficients {
    density_field: Option<String>,
    density_scale: f64,
    absorption: [f64; 3],
    scattering: [f64; 3],
    anisotropy: f64,
    /// A MaterialX density graph driving `absorption` and `scattering` (the USD
    /// reader's rule: `nimbus::scene::materialx_graph`), compiled from the network.
    density_graph: Option<Program>,
}

/// An rprim's bound material as handed over: its path and its volume shader
/// (`HdNimbusMaterial` keeps a PxrVolume or ND_anisotropic_vdf node wherever it sits,
/// else the volume terminal's first node; no shader when the material has no volume
/// terminal).
struct Material<'a> {
    path: &'a str,
    shader_path: &'a str,
    shader_id: &'a str,
    params: &'a [ParamDesc],
    network: &'a [ShaderNodeDesc],
}

impl<'a> Material<'a> {
    /// The emission of the network's MaterialX `volume` node (its `edf`), read as the
    /// USD reader reads it (`nimbus::scene::materialx_graph::volume_emission`).
    fn emission(&self) -> Result<Option<materialx_graph::MaterialXEmission>> {
        match self.network.iter().find(|n| n.id == "ND_volume") {
            None => Ok(None),
            Some(n) => Ok(materialx_graph::volume_emission(
                &self.shader_network(),
                &n.path,
            )?),
        }
    }

    fn of_volume(v: &'a VolumeDesc) -> Material<'a> {
        Material {
            path: &v.material_path,
            shader_path: &v.shader_path,
            shader_id: &v.shader_id,
            params: &v.shader_params,
            network: &v.shader_network,
        }
    }

    fn of_mesh(m: &'a MeshDesc) -> Material<'a> {
        Material {
            path: &m.material_path,
            shader_path: &m.shader_path,
            shader_id: &m.shader_id,
            params: &m.shader_params,
            network: &m.shader_network,
        }
    }

    /// The material's network as the core reads it: parameters with numbers are
    /// numbers, others text; connections as they were handed over.
    fn shader_network(&self) -> ShaderNetwork {
        let value = |p: &ParamDesc| match p.numbers.is_empty() {
            false => ParamValue::Numbers(p.numbers.clone()),
            true => ParamValue::Text(p.text.clone()),
        };
        ShaderNetwork {
            nodes: self
                .network
                .iter()
                .map(|n| ShaderNode {
                    path: n.path.clone(),
                    id: n.id.clone(),
                    inputs: n
                        .params
                        .iter()
                        .map(|p| (p.name.clone(), Input::Value(value(p))))
                        .chain(n.connections.iter().map(|c| {
                            (
                                c.input.clone(),
                                Input::Connection {
                                    node: c.node.clone(),
                                    output: c.output.clone(),
                                },
                            )
                        }))
                        .collect(),
                })
                .collect(),
        }
    }

    /// "shader (id)", as the USD reader names a volume's material shader.
    fn shader_name(&self) -> String {
        format!("{} ({})", self.shader_path, self.shader_id)
    }

    /// The coefficients of the volume shader, when it is one Nimbus reads.
    fn coefficients(&self) -> Result<Option<ShaderCoefficients>> {
        let p = self.params;
        let at = |n: &str| format!("{} ({})", self.shader_path, n);
        match self.shader_id {
            "PxrVolume" => {
                // As the USD reader: the primvar's field scaled by densityMultiplier,
                // else the `density` field scaled by densityFloat too; albedo
                // diffuseColor.
                let density = scalar(&at("densityFloat"), p, "densityFloat")?.unwrap_or(1.0);
                let multiplier =
                    scalar(&at("densityMultiplier"), p, "densityMultiplier")?.unwrap_or(1.0);
                let albedo = color3(&at("diffuseColor"), p, "diffuseColor")?.unwrap_or([1.0; 3]);
                let g = scalar(&at("anisotropy"), p, "anisotropy")?.unwrap_or(0.0);
                let field = text(p, "densityFloatPrimVar").map(str::to_string);
                let scale = match field {
                    Some(_) => multiplier,
                    None => multiplier * density,
                };
                Ok(Some(ShaderCoefficients {
                    density_field: field,
                    density_scale: scale,
                    absorption: albedo.map(|a| (1.0 - a).max(0.0)),
                    scattering: albedo,
                    anisotropy: g,
                    density_graph: None,
                }))
            }
            "ND_anisotropic_vdf" => {
                let g = scalar(&at("anisotropy"), p, "anisotropy")?.unwrap_or(0.0);
                // A network handed over without the shader in it (no graph to read)
                // leaves the constant inputs.
                let in_network = self.network.iter().any(|n| n.path == self.shader_path);
                let network = self.shader_network();
                let graph = match in_network {
                    true => materialx_graph::vdf_density(&network, self.shader_path)?,
                    false => None,
                };
                if let Some(d) = graph {
                    return Ok(Some(ShaderCoefficients {
                        density_field: d.geomprop,
                        density_scale: 1.0,
                        absorption: d.absorption,
                        scattering: d.scattering,
                        anisotropy: g,
                        density_graph: Some(d.program),
                    }));
                }
                let absorption = color3(&at("absorption"), p, "absorption")?.unwrap_or([0.0; 3]);
                let scattering = color3(&at("scattering"), p, "scattering")?.unwrap_or([0.0; 3]);
                let g = scalar(&at("anisotropy"), p, "anisotropy")?.unwrap_or(0.0);
                Ok(Some(ShaderCoefficients {
                    density_field: None,
                    density_scale: 1.0,
                    absorption,
                    scattering,
                    anisotropy: g,
                    density_graph: None,
                }))
            }
            _ => Ok(None),
        }
    }
}

/// NimbusVolumeAPI's medium attributes. Hydra has no applied schemas: an rprim that
/// carries one of them as a primvar is read as having the API applied (as the USD
/// reader reads a prim with `NimbusVolumeAPI`). `nimbus:fill` (which says what a
/// Volume is, not what its medium is) and `nimbus:lightGroup` (NimbusLightAPI's) do
/// not count, nor does `nimbus:holdout`.
const VOLUME_API_PRIMVARS: [&str; 14] = [
    tokens::DENSITY_FIELD,
    tokens::DENSITY_SCALE,
    tokens::ABSORPTION,
    tokens::SCATTERING,
    tokens::ANISOTROPY,
    tokens::ALBEDO_FIELD,
    tokens::ALBEDO,
    tokens::TEMPERATURE_FIELD,
    tokens::TEMPERATURE_SCALE,
    tokens::BLACKBODY_INTENSITY,
    tokens::EMISSION_FIELD,
    tokens::EMISSION_COLOR,
    tokens::EMISSION_SCALE,
    tokens::EMISSION_KIND,
];

fn has_volume_api(primvars: &[ParamDesc]) -> bool {
    VOLUME_API_PRIMVARS
        .iter()
        .any(|name| param(primvars, name).is_some())
}

/// The emission of `nimbus:*` primvars; the fields by the names `named` resolves.
fn emission(
    path: &str,
    pv: &[ParamDesc],
    named: &dyn Fn(&str) -> Result<Option<(String, Field)>>,
) -> Result<VolumeEmission> {
    let defaults = VolumeEmission::default();
    Ok(VolumeEmission {
        temperature: named(tokens::TEMPERATURE_FIELD)?,
        temperature_scale: scalar(path, pv, tokens::TEMPERATURE_SCALE)?
            .unwrap_or(defaults.temperature_scale),
        blackbody_intensity: scalar(path, pv, tokens::BLACKBODY_INTENSITY)?
            .unwrap_or(defaults.blackbody_intensity),
        emission: named(tokens::EMISSION_FIELD)?,
        emission_color: color3(path, pv, tokens::EMISSION_COLOR)?
            .unwrap_or(defaults.emission_color),
        emission_scale: scalar(path, pv, tokens::EMISSION_SCALE)?
            .unwrap_or(defaults.emission_scale),
        kind: match text(pv, tokens::EMISSION_KIND) {
            None => defaults.kind,
            Some(t) => EmissionKind::from_token(t).ok_or_else(|| {
                anyhow!(
                    "volume {path}: primvars:nimbus:emissionKind `{t}` is neither \"radiance\" nor \"source\""
                )
            })?,
        },
        // Hydra hands materials over as networks (MaterialX): no colour graph here.
        color_graph: None,
    })
}

/// The medium of a fog box or of world fog at `path`: from NimbusVolumeAPI's primvars,
/// else from a material whose volume shader Nimbus reads; `None` when it has neither.
/// Fog has no fields: a temperature, emission or albedo field named is an error; a
/// PxrVolume's density primvar is a warning (its density is 1 × the shader's scale).
fn fog_medium(
    path: &str,
    pv: &[ParamDesc],
    material: &Material,
    warnings: &mut Vec<String>,
) -> Result<Option<FogParams>> {
    if has_volume_api(pv) {
        return api_medium(path, pv).map(Some);
    }
    let Some(m) = material.coefficients()? else {
        return Ok(None);
    };
    let emission = match material.emission()? {
        None => VolumeEmission::default(),
        Some(e) => {
            if let Some(field) = &e.field {
                bail!(
                    "{path}: {}: its emission colour reads the field `{field}` (ND_geompropvalue_float); fog has no fields",
                    e.edf
                );
            }
            e.volume_emission(None)
        }
    };
    if let (Some(field), Some(_)) = (&m.density_field, &m.density_graph) {
        bail!(
            "{path}: {}: its density graph reads the field `{field}` (ND_geompropvalue_float); fog has no fields",
            material.shader_name()
        );
    }
    if let Some(field) = &m.density_field {
        warnings.push(format!(
            "{path}: {} names the density primvar `{field}`; fog has none: its density is 1 (times the shader's density scale)",
            material.shader_path
        ));
    }
    Ok(Some(FogParams {
        density_scale: m.density_scale,
        absorption: m.absorption,
        scattering: m.scattering,
        anisotropy: m.anisotropy,
        emission,
        albedo_graph: None,
        material_shader: Some(material.shader_name()),
        // Placed in the mesh's object space by `mesh` (world fog refuses it).
        density_graph: m.density_graph.map(|program| DensityGraph {
            program,
            shading_to_world: DMat4::IDENTITY,
            source: material.shader_name(),
        }),
    }))
}

/// NimbusVolumeAPI's medium of fog from the `nimbus:*` primvars, schema fallbacks for
/// those absent (as the USD reader reads a gprim with the API).
fn api_medium(path: &str, pv: &[ParamDesc]) -> Result<FogParams> {
    for attr in [
        tokens::TEMPERATURE_FIELD,
        tokens::EMISSION_FIELD,
        tokens::ALBEDO_FIELD,
    ] {
        if let Some(name) = text(pv, attr) {
            bail!(
                "{path}: {attr} = \"{name}\": fog (a mesh with NimbusVolumeAPI's primvars, or nimbus:fill = \"world\") has no fields; its density is 1 and its emission, with nimbus:emissionKind \"source\", the constant emissionColor × emissionScale"
            );
        }
    }
    let (absorption, scattering) = api_coefficients(path, pv)?;
    Ok(FogParams {
        density_scale: scalar(path, pv, tokens::DENSITY_SCALE)?.unwrap_or(1.0),
        absorption,
        scattering,
        anisotropy: scalar(path, pv, tokens::ANISOTROPY)?.unwrap_or(0.0),
        emission: emission(path, pv, &|_| Ok(None))?,
        material_shader: None,
        density_graph: None,
        albedo_graph: None,
    })
}

/// `nimbus:absorption` and `nimbus:scattering` with a constant `nimbus:albedo` folded
/// in (as the USD reader does; a primvar cannot carry a colour graph's connection).
fn api_coefficients(path: &str, pv: &[ParamDesc]) -> Result<([f64; 3], [f64; 3])> {
    let mut absorption = color3(path, pv, tokens::ABSORPTION)?.unwrap_or([0.1; 3]);
    let mut scattering = color3(path, pv, tokens::SCATTERING)?.unwrap_or([0.9; 3]);
    if let Some(c) = color3(path, pv, tokens::ALBEDO)? {
        if c.iter().any(|v| !v.is_finite()) {
            bail!("{path}: {} = {c:?} is not finite", tokens::ALBEDO);
        }
        fold_albedo(c, &mut absorption, &mut scattering);
    }
    Ok((absorption, scattering))
}

/// The warning for an rprim whose material is not one Nimbus reads (`what` it is read
/// as instead).
fn unread_material(kind: &str, path: &str, material: &Material, what: &str) -> String {
    format!(
        "{kind} {path}: material {} ({}) is not one Nimbus reads (PxrVolume, ND_anisotropic_vdf or nimbus:* primvars); {what}",
        material.path,
        match material.shader_id.is_empty() {
            true => "no volume shader",
            false => material.shader_id,
        }
    )
}

/// World fog: a Volume rprim with `nimbus:fill = "world"`, its medium as a fog box's,
/// else NimbusVolumeAPI's fallbacks (the primvar `nimbus:fill` is NimbusVolumeAPI's, so
/// the API is there); fields are not read (a warning if it has any).
fn world_fog(v: &VolumeDesc, warnings: &mut Vec<String>) -> Result<Volume> {
    let path = v.path.as_str();
    let pv = &v.primvars;
    let material = Material::of_volume(v);
    let medium = match fog_medium(path, pv, &material, warnings)? {
        Some(m) => m,
        None => {
            if !v.material_path.is_empty() {
                warnings.push(unread_material(
                    "volume",
                    path,
                    &material,
                    "the schema's fallback coefficients are used",
                ));
            }
            api_medium(path, pv)?
        }
    };
    if let Some(g) = &medium.density_graph {
        bail!(
            "volume {path}: {}: a density graph on world fog is not read yet (it would fill all space); bind it to a closed mesh (a fog box) instead",
            g.source
        );
    }
    if !v.fields.is_empty() {
        warnings.push(format!(
            "volume {path}: world fog has density 1 everywhere: its fields are not read"
        ));
    }
    let light_group = text(pv, tokens::LIGHT_GROUP).map(str::to_string);
    Ok(medium.volume(path, light_group, VolumeShape::World))
}

fn volume(
    v: &VolumeDesc,
    shutter: Option<(f64, f64)>,
    warnings: &mut Vec<String>,
) -> Result<Volume> {
    let path = v.path.as_str();
    match text(&v.primvars, tokens::FILL) {
        None | Some("field") => {}
        Some("world") => return world_fog(v, warnings),
        Some(other) => bail!(
            "{path}: {} = \"{other}\" is not one of \"field\", \"world\"",
            tokens::FILL
        ),
    }
    if v.fields.is_empty() {
        bail!("{path}: volume has no fields");
    }
    let fields: Vec<(String, Field)> = v
        .fields
        .iter()
        .map(|f| Ok((f.name.clone(), field(path, f)?)))
        .collect::<Result<_>>()?;
    let named = |name: &str| -> Result<Field> {
        fields
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, f)| f.clone())
            .ok_or_else(|| {
                anyhow!(
                    "{path}: no field named {name} (fields: {})",
                    fields
                        .iter()
                        .map(|(n, _)| n.as_str())
                        .collect::<Vec<_>>()
                        .join(", ")
                )
            })
    };
    let pv = &v.primvars;
    let has_nimbus = has_volume_api(pv);
    let material = Material::of_volume(v);
    let coefficients = match has_nimbus {
        true => None,
        false => material.coefficients()?,
    };
    if !has_nimbus && coefficients.is_none() && !v.material_path.is_empty() {
        warnings.push(unread_material(
            "volume",
            path,
            &material,
            "the schema's fallback coefficients are used",
        ));
    }
    let volume_to_world = finite_matrix(path, &v.xform)?;
    let material_emission = match coefficients.is_some() {
        false => None,
        true => material.emission()?,
    };
    let motion = motion(path, &v.xform_samples, shutter)?;
    // A velocity field (as the USD reader finds one) is not read through Hydra.
    let velocity = text(&v.primvars, tokens::VELOCITY_FIELD).or_else(|| {
        ["vel", "velocity"]
            .into_iter()
            .find(|n| fields.iter().any(|f| f.0 == *n))
    });
    if let (Some(name), Some((open, close))) = (velocity, shutter) {
        warnings.push(format!(
            "motion blur: volume {path}: its velocity field `{name}` would blur it while the camera's shutter is open ({open} to {close}), but hdNimbus reads no velocity fields (only transforms are blurred); its fields are rendered as they are at the frame"
        ));
    }
    // `nimbus:lightGroup` (NimbusLightAPI) whether the medium is the material's or not,
    // as the USD reader reads it.
    let light_group = text(pv, tokens::LIGHT_GROUP).map(str::to_string);
    if let Some(m) = coefficients {
        let density_name = m.density_field.unwrap_or_else(|| "density".to_string());
        let emission = match material_emission {
            None => VolumeEmission::default(),
            Some(e) => {
                let field = match &e.field {
                    None => None,
                    Some(name) => Some((name.clone(), named(name)?)),
                };
                let mut emission = e.volume_emission(field);
                if let Some(g) = &mut emission.color_graph {
                    g.shading_to_world = volume_to_world;
                }
                emission
            }
        };
        return Ok(Volume {
            prim_path: v.path.clone(),
            light_group,
            volume_to_world,
            motion,
            shape: VolumeShape::Field(named(&density_name)?),
            density_scale: m.density_scale,
            absorption: m.absorption,
            scattering: m.scattering,
            anisotropy: m.anisotropy,
            fields,
            emission,
            albedo: None,
            albedo_graph: None,
            velocity: None,
            material_shader: Some(material.shader_name()),
            density_graph: m.density_graph.map(|program| DensityGraph {
                program,
                shading_to_world: volume_to_world,
                source: material.shader_name(),
            }),
        });
    }
    let density_name = text(pv, tokens::DENSITY_FIELD).unwrap_or("density");
    let optional = |attr: &str| -> Result<Option<(String, Field)>> {
        match text(pv, attr) {
            None => Ok(None),
            Some(n) => Ok(Some((n.to_string(), named(n)?))),
        }
    };
    let emission = emission(path, pv, &optional)?;
    let density = named(density_name)?;
    let albedo = optional(tokens::ALBEDO_FIELD)?;
    let (absorption, scattering) = api_coefficients(path, pv)?;
    Ok(Volume {
        prim_path: v.path.clone(),
        light_group,
        volume_to_world,
        motion,
        shape: VolumeShape::Field(density),
        density_scale: scalar(path, pv, tokens::DENSITY_SCALE)?.unwrap_or(1.0),
        absorption,
        scattering,
        anisotropy: scalar(path, pv, tokens::ANISOTROPY)?.unwrap_or(0.0),
        fields,
        emission,
        albedo,
        albedo_graph: None,
        velocity: None,
        material_shader: None,
        density_graph: None,
    })
}

/// A mesh rprim: a fog box when it carries NimbusVolumeAPI's primvars or its material's
/// volume shader is one Nimbus reads (the medium inside its surface, checked and wound
/// outwards by `nimbus::scene::fog::fog_mesh`, whose warning is the mesh's), else a
/// holdout (a warning when its material has a volume shader Nimbus does not read).
fn mesh(m: &MeshDesc, scene: &mut Scene, warnings: &mut Vec<String>) -> Result<()> {
    let path = m.path.as_str();
    let material = Material::of_mesh(m);
    let medium = fog_medium(path, &m.primvars, &material, warnings)?;
    let Some(medium) = medium else {
        if !m.shader_id.is_empty() {
            warnings.push(unread_material(
                "mesh",
                path,
                &material,
                "the mesh is a holdout",
            ));
        }
        if let Some(h) = holdout(m)? {
            scene.holdouts.push(h);
        }
        return Ok(());
    };
    let Some(surface) = holdout(m)? else {
        warnings.push(format!(
            "mesh {path}: a fog box without a face that is not degenerate; it is left out"
        ));
        return Ok(());
    };
    // The authored winding runs clockwise seen from outside: a left-handed topology,
    // or a mirroring transform (both handed over, unlike the implicit shape a
    // tessellated Cube or Sphere was).
    let mirrored = m.left_handed != (matrix(&m.xform).determinant() < 0.0);
    let (fog, problem) = fog::fog_mesh(surface, Some(mirrored));
    if let Some(problem) = problem {
        warnings.push(format!("mesh {path}: {problem}"));
    }
    let light_group = text(&m.primvars, tokens::LIGHT_GROUP).map(str::to_string);
    let mut medium = medium;
    let to_world = finite_matrix(path, &m.xform)?;
    if let Some(g) = &mut medium.density_graph {
        g.shading_to_world = to_world;
    }
    if let Some(g) = &mut medium.emission.color_graph {
        g.shading_to_world = to_world;
    }
    scene
        .volumes
        .push(medium.volume(path, light_group, VolumeShape::Mesh(fog)));
    Ok(())
}

/// A mesh as a holdout: world-space points, fan-triangulated faces without holes,
/// degenerate triangles left out (as `nimbus::scene::geometry` does).
fn holdout(m: &MeshDesc) -> Result<Option<HoldoutMesh>> {
    let path = &m.path;
    let to_world = finite_matrix(path, &m.xform)?;
    if m.points.len() % 3 != 0 {
        bail!("{path}: points are not triples");
    }
    let points: Vec<[f64; 3]> = m
        .points
        .chunks_exact(3)
        .map(|p| {
            to_world
                .transform_point3(DVec3::new(p[0], p[1], p[2]))
                .to_array()
        })
        .collect();
    if points.iter().flatten().any(|v| !v.is_finite()) {
        bail!("{path}: a point is not finite");
    }
    let n = points.len();
    let mut triangles = Vec::new();
    let (mut faces, mut degenerate, mut at) = (0usize, 0usize, 0usize);
    for (face, &count) in m.face_counts.iter().enumerate() {
        let count =
            usize::try_from(count).map_err(|_| anyhow!("{path}: negative face vertex count"))?;
        let idx = m.face_indices.get(at..at + count).ok_or_else(|| {
            anyhow!("{path}: faceVertexIndices shorter than faceVertexCounts ask")
        })?;
        at += count;
        if m.hole_indices.contains(&(face as i32)) || count < 3 {
            continue;
        }
        let idx: Vec<u32> = idx
            .iter()
            .map(|&i| match usize::try_from(i) {
                Ok(i) if i < n => Ok(i as u32),
                _ => Err(anyhow!(
                    "{path}: face vertex index {i} outside the {n} points"
                )),
            })
            .collect::<Result<_>>()?;
        faces += 1;
        for k in 1..count - 1 {
            let t = [idx[0], idx[k], idx[k + 1]];
            if is_degenerate(&points, t) {
                degenerate += 1;
            } else {
                triangles.push(t);
            }
        }
    }
    if triangles.is_empty() {
        return Ok(None);
    }
    Ok(Some(HoldoutMesh {
        prim_path: m.path.clone(),
        prim_type: "Mesh".to_string(),
        points,
        triangles,
        faces,
        degenerate_triangles: degenerate,
        double_sided: m.double_sided,
    }))
}

fn is_degenerate(points: &[[f64; 3]], [a, b, c]: [u32; 3]) -> bool {
    if a == b || b == c || a == c {
        return true;
    }
    let p = |i: u32| DVec3::from_array(points[i as usize]);
    (p(b) - p(a)).cross(p(c) - p(a)).length_squared() == 0.0
}

/// Render settings by the schema's names (`nimbus:samples`, …); unknown keys (the
/// host's own) are ignored.
fn settings(list: &[SettingDesc], (w, h): (u32, u32)) -> Result<RenderSettings> {
    let mut s = RenderSettings {
        prim_path: Some("render settings".to_string()),
        resolution: (w, h),
        ..RenderSettings::default()
    };
    for set in list {
        let key = set.key.as_str();
        let int = |lo: f64, hi: f64| -> Result<f64> {
            let v = set.number;
            if set.is_text || !(v.is_finite() && v.fract() == 0.0 && (lo..=hi).contains(&v)) {
                bail!(
                    "render setting {key} must be an integer in {lo}..={hi}, got {}",
                    shown(set)
                );
            }
            Ok(v)
        };
        let token = || -> Result<Option<String>> {
            match set.is_text {
                true => Ok(Some(set.text.clone()).filter(|t| !t.is_empty())),
                false => bail!("render setting {key} must be a token, got {}", shown(set)),
            }
        };
        match key {
            "nimbus:samples" => s.samples = int(1.0, u32::MAX as f64)? as u32,
            "nimbus:maxDepth" => s.max_depth = int(0.0, u32::MAX as f64)? as u32,
            "nimbus:seed" => s.seed = int(0.0, 2f64.powi(53))? as u64,
            "nimbus:octreeDepth" => s.octree_depth = Some(int(0.0, 64.0)? as i64),
            "nimbus:tracker" => s.tracker = token()?,
            "nimbus:scheme" => s.scheme = token()?,
            "nimbus:transmittance" => s.transmittance = token()?,
            "nimbus:control" if !set.is_text => s.control = Some(set.number),
            "nimbus:control" => bail!("render setting nimbus:control must be a number"),
            "nimbus:strict" => s.strict = !set.is_text && set.number != 0.0,
            "nimbus:denoise" => s.denoise = !set.is_text && set.number != 0.0,
            _ => {}
        }
    }
    Ok(s)
}

fn shown(s: &SettingDesc) -> String {
    match s.is_text {
        true => format!("{:?}", s.text),
        false => format!("{}", s.number),
    }
}

/// The settings hdNimbus reads (the render-settings schema's names), with the defaults
/// a stage without them gets.
pub fn setting_descriptors() -> Vec<SettingDescriptor> {
    let d = RenderSettings::default();
    let number = |key: &str, name: &str, v: f64, is_int: bool| SettingDescriptor {
        key: key.to_string(),
        name: name.to_string(),
        is_text: false,
        is_int,
        number: v,
        text: String::new(),
    };
    let token = |key: &str, name: &str, v: &str| SettingDescriptor {
        key: key.to_string(),
        name: name.to_string(),
        is_text: true,
        is_int: false,
        number: 0.0,
        text: v.to_string(),
    };
    vec![
        number(
            "nimbus:samples",
            "Samples per pixel",
            d.samples as f64,
            true,
        ),
        number("nimbus:seed", "Seed", d.seed as f64, true),
        number(
            "nimbus:maxDepth",
            "Maximum scattering depth",
            d.max_depth as f64,
            true,
        ),
        token("nimbus:tracker", "Tracker", "auto"),
        token("nimbus:scheme", "Scheme", ""),
        token("nimbus:transmittance", "Transmittance estimator", ""),
        number(
            "nimbus:control",
            "Decomposition control",
            nimbus::track::select::TrackerSettings::default().control as f64,
            false,
        ),
        number(
            "nimbus:octreeDepth",
            "Majorant octree depth (0: flat grid)",
            0.0,
            true,
        ),
        number(
            "nimbus:denoise",
            "Denoise (Open Image Denoise, at the last pass)",
            d.denoise as u8 as f64,
            true,
        ),
    ]
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    pub(crate) fn identity() -> [f64; 16] {
        DMat4::IDENTITY.to_cols_array()
    }

    pub(crate) fn smoke_volume() -> VolumeDesc {
        VolumeDesc {
            path: "/smoke".into(),
            xform: identity(),
            fields: vec![FieldDesc {
                name: "density".into(),
                path: "/smoke/density".into(),
                prim_type: "openvdbAsset".into(),
                file: "/data/smoke.vdb".into(),
                grid: "density".into(),
                index: -1,
            }],
            ..VolumeDesc::default()
        }
    }

    pub(crate) fn light(kind: &str) -> LightDesc {
        LightDesc {
            kind: kind.into(),
            path: format!("/{kind}"),
            xform: identity(),
            intensity: 2.0,
            color: [1.0; 3],
            diffuse: 1.0,
            shadow_enable: true,
            ..LightDesc::default()
        }
    }

    /// A light type the core lacks is a warning naming it, and is left out; the types
    /// it has each land in their list.
    #[test]
    fn lights_by_type_and_an_unknown_one_warned() {
        let desc = SceneDesc {
            lights: [
                "distantLight",
                "sphereLight",
                "rectLight",
                "diskLight",
                "cylinderLight",
                "domeLight",
                "meshLight",
            ]
            .map(light)
            .to_vec(),
            unsupported_lights: vec!["/portal (portalLight)".into()],
            volumes: vec![smoke_volume()],
            width: 8,
            height: 8,
            ..SceneDesc::default()
        };
        let (scene, warnings) = scene_of(&desc).unwrap();
        assert_eq!(
            [
                scene.distant_lights.len(),
                scene.sphere_lights.len(),
                scene.rect_lights.len(),
                scene.disk_lights.len(),
                scene.cylinder_lights.len(),
                scene.dome_lights.len()
            ],
            [1; 6]
        );
        assert!(
            warnings
                .iter()
                .any(|w| w.contains("/meshLight") && w.contains("meshLight")),
            "{warnings:?}"
        );
        assert!(
            warnings.iter().any(|w| w.contains("/portal (portalLight)")),
            "{warnings:?}"
        );
        assert_eq!(scene.light_prims, 8);
        // A distant light shines along its local -Z: the direction towards it is +Z.
        assert_eq!(scene.distant_lights[0].direction, [0.0, 0.0, 1.0]);
    }

    /// A field of another type than openvdbAsset, or one never synced (no file), is an
    /// error naming the volume and the field.
    #[test]
    fn unsupported_or_unsynced_fields_are_errors() {
        let mut v = smoke_volume();
        v.fields[0].prim_type = "field3dAsset".into();
        let desc = SceneDesc {
            volumes: vec![v],
            ..SceneDesc::default()
        };
        let e = scene_of(&desc).unwrap_err().to_string();
        assert!(e.contains("/smoke") && e.contains("field3dAsset"), "{e}");
        let mut v = smoke_volume();
        v.fields[0].file = String::new();
        let desc = SceneDesc {
            volumes: vec![v],
            ..SceneDesc::default()
        };
        let e = scene_of(&desc).unwrap_err().to_string();
        assert!(
            e.contains("/smoke/density") && e.contains("filePath"),
            "{e}"
        );
    }

    /// Without nimbus:* primvars or a material, NimbusVolumeAPI's fallbacks (as the USD
    /// reader gives a volume with neither); nimbus:* primvars override them; a
    /// PxrVolume material maps as the USD reader maps it.
    #[test]
    fn volume_coefficients_from_fallbacks_primvars_and_pxr_volume() {
        let desc = |v: VolumeDesc| SceneDesc {
            volumes: vec![v],
            ..SceneDesc::default()
        };
        let (s, _) = scene_of(&desc(smoke_volume())).unwrap();
        let v = &s.volumes[0];
        assert_eq!(
            (v.density_scale, v.absorption, v.scattering),
            (1.0, [0.1; 3], [0.9; 3])
        );

        let mut pv = smoke_volume();
        pv.primvars = vec![
            ParamDesc {
                name: "primvars:nimbus:densityScale".into(),
                numbers: vec![4.0],
                text: String::new(),
            },
            ParamDesc {
                name: "nimbus:scattering".into(),
                numbers: vec![0.5, 0.6, 0.7],
                text: String::new(),
            },
        ];
        let (s, _) = scene_of(&desc(pv.clone())).unwrap();
        assert_eq!(s.volumes[0].density_scale, 4.0);
        assert_eq!(s.volumes[0].scattering, [0.5, 0.6, 0.7]);

        // A constant nimbus:albedo folds as the USD reader folds it: σs → c·σs,
        // σa → σa + (1 − c)·σs, c clamped into [0,1].
        pv.primvars.push(ParamDesc {
            name: "nimbus:albedo".into(),
            numbers: vec![0.5, 2.0, -1.0],
            text: String::new(),
        });
        let (s, _) = scene_of(&desc(pv)).unwrap();
        let v = &s.volumes[0];
        assert_eq!(v.scattering, [0.25, 0.6, 0.0]);
        assert_eq!(v.absorption, [0.1 + 0.25, 0.1, 0.1 + 0.7]);
        assert!(v.albedo_graph.is_none());

        let mut m = smoke_volume();
        m.material_path = "/mat".into();
        m.shader_path = "/mat/vol".into();
        m.shader_id = "PxrVolume".into();
        m.shader_params = vec![
            ParamDesc {
                name: "densityFloat".into(),
                numbers: vec![3.0],
                text: String::new(),
            },
            ParamDesc {
                name: "diffuseColor".into(),
                numbers: vec![0.8, 0.8, 0.8],
                text: String::new(),
            },
        ];
        let (s, _) = scene_of(&desc(m)).unwrap();
        let v = &s.volumes[0];
        assert_eq!(v.density_scale, 3.0);
        assert_eq!(v.scattering, [0.8; 3]);
        assert!((v.absorption[0] - 0.2).abs() < 1e-12);

        let mut other = smoke_volume();
        other.material_path = "/principled".into();
        other.shader_id = "UsdPreviewSurface".into();
        let (_, w) = scene_of(&desc(other)).unwrap();
        assert!(
            w.iter()
                .any(|w| w.contains("/principled") && w.contains("fallback")),
            "{w:?}"
        );
    }

    /// Hydra's camera lengths are scene units; UsdGeomCamera's (the Scene's) tenths.
    /// Hydra's linking: a light's `lightLink` / `shadowLink` name becomes the collection
    /// of exactly the rprims (volumes and meshes) that list it among their categories;
    /// an empty name is every prim, a name no rprim lists is none.
    #[test]
    fn linking_collections_from_categories() {
        let volume = |path: &str, categories: &[&str]| VolumeDesc {
            path: path.into(),
            categories: categories.iter().map(|c| c.to_string()).collect(),
            ..smoke_volume()
        };
        let linked = LightDesc {
            path: "/a".into(),
            light_link: "/a.collection:lightLink".into(),
            shadow_link: "/a.collection:shadowLink".into(),
            ..light("sphereLight")
        };
        let nowhere = LightDesc {
            path: "/b".into(),
            light_link: "/b.collection:lightLink".into(),
            ..light("sphereLight")
        };
        let desc = SceneDesc {
            lights: vec![nowhere, linked],
            volumes: vec![
                volume("/v2", &["/a.collection:lightLink"]),
                volume(
                    "/v1",
                    &["/a.collection:lightLink", "/a.collection:shadowLink"],
                ),
            ],
            meshes: vec![MeshDesc {
                path: "/m".into(),
                xform: identity(),
                categories: vec!["/a.collection:shadowLink".into()],
                ..MeshDesc::default()
            }],
            width: 8,
            height: 8,
            ..SceneDesc::default()
        };
        let (scene, _) = scene_of(&desc).unwrap();
        let only = |paths: &[&str]| Collection {
            include_root: false,
            includes: paths.iter().map(|p| p.to_string()).collect(),
            excludes: Vec::new(),
            explicit_only: true,
        };
        let (a, b) = (&scene.sphere_lights[0], &scene.sphere_lights[1]);
        assert_eq!(a.prim_path, "/a");
        assert_eq!(a.controls.light_link, only(&["/v1", "/v2"]));
        assert_eq!(a.controls.shadow_link, only(&["/m", "/v1"]));
        assert!(a.controls.light_link.contains("/v2") && !a.controls.light_link.contains("/m"));
        assert_eq!(b.controls.light_link, only(&[]));
        assert!(!b.controls.light_link.contains("/v1"));
        assert_eq!(b.controls.shadow_link, Collection::default());
    }

    #[test]
    fn camera_lengths_in_tenths() {
        let desc = SceneDesc {
            has_camera: true,
            camera: CameraDesc {
                path: "/cam".into(),
                xform: identity(),
                focal_length: 5.0,
                horizontal_aperture: 3.6,
                vertical_aperture: 2.4,
                near: 0.1,
                far: 100.0,
                ..CameraDesc::default()
            },
            ..SceneDesc::default()
        };
        let (s, _) = scene_of(&desc).unwrap();
        assert_eq!(s.camera.focal_length, 50.0);
        assert_eq!(s.camera.horizontal_aperture, 36.0);
        assert_eq!(s.camera.vertical_aperture, 24.0);
        assert_eq!(s.camera.clipping_range, (0.1, 100.0));
    }

    /// A translate of `x` along x as a transform sample at `time`.
    fn at_x(time: f64, x: f64) -> XformSample {
        XformSample {
            time,
            xform: DMat4::from_translation(DVec3::new(x, 0.0, 0.0)).to_cols_array(),
        }
    }

    /// Motion from Hydra's samples: keys at the shutter's ends (interpolated between
    /// the samples around them, held beyond) and the samples inside; none without an
    /// open shutter or when nothing moves within it. The camera's shutter first, the
    /// render settings' when the camera's is closed; the camera and the volumes carry
    /// the motion, a moving light and a moving mesh warn.
    #[test]
    fn motion_from_transform_samples_over_the_shutter() {
        // The keys' times and x translations (to 1e-9: interpolation rounds).
        let xs = |m: &TransformMotion| -> Vec<(f64, f64)> {
            let round = |x: f64| (x * 1e9).round() / 1e9;
            m.keys()
                .iter()
                .map(|(t, k)| (*t, round(k.w_axis.x)))
                .collect()
        };
        // Samples at frames 0 and 2 around frame 1 (−1, 1), out of order; shutter
        // −0.5 … 0.5: the ends interpolated.
        let s = [at_x(1.0, 0.4), at_x(-1.0, -0.4)];
        let m = motion("/p", &s, Some((-0.5, 0.5))).unwrap().unwrap();
        assert_eq!(xs(&m), [(-0.5, -0.2), (0.5, 0.2)]);
        // UsdImaging's samples: the ends and an authored one between.
        let s = [at_x(-0.25, 0.0), at_x(0.0, 1.0), at_x(0.25, 1.0)];
        let m = motion("/p", &s, Some((-0.25, 0.25))).unwrap().unwrap();
        assert_eq!(xs(&m), [(-0.25, 0.0), (0.0, 1.0), (0.25, 1.0)]);
        // Moving only before the shutter: held, nothing moves within it.
        let s = [at_x(-2.0, 0.0), at_x(-1.0, 1.0)];
        assert!(motion("/p", &s, Some((-0.5, 0.5))).unwrap().is_none());
        // One sample, no shutter, a non-finite matrix.
        assert!(motion("/p", &[at_x(0.0, 1.0)], Some((-0.5, 0.5)))
            .unwrap()
            .is_none());
        assert!(motion("/p", &[at_x(-1.0, 0.0), at_x(1.0, 1.0)], None)
            .unwrap()
            .is_none());
        let err = motion(
            "/p",
            &[at_x(-1.0, 0.0), at_x(1.0, f64::NAN)],
            Some((-0.5, 0.5)),
        )
        .unwrap_err()
        .to_string();
        assert!(err.contains("/p") && err.contains("non-finite"), "{err}");

        let moving = vec![at_x(-1.0, -0.4), at_x(1.0, 0.4)];
        let mut sun = light("distantLight");
        sun.xform_samples = moving.clone();
        // A sphere light sliding is blurred; a rect light growing warns.
        let mut bulb = light("sphereLight");
        bulb.xform_samples = moving.clone();
        let mut panel = light("rectLight");
        panel.xform_samples = [(-1.0, 1.0), (1.0, 2.0)]
            .map(|(time, k)| XformSample {
                time,
                xform: DMat4::from_scale(DVec3::splat(k)).to_cols_array(),
            })
            .to_vec();
        let desc = |camera_shutter: (f64, f64), settings: Option<[f64; 2]>| SceneDesc {
            has_camera: true,
            camera: CameraDesc {
                path: "/cam".into(),
                xform: identity(),
                focal_length: 5.0,
                horizontal_aperture: 3.6,
                vertical_aperture: 2.4,
                near: 0.1,
                far: 100.0,
                shutter_open: camera_shutter.0,
                shutter_close: camera_shutter.1,
                xform_samples: moving.clone(),
                ..CameraDesc::default()
            },
            volumes: vec![{
                let mut v = smoke_volume();
                v.xform_samples = moving.clone();
                let mut vel = v.fields[0].clone();
                vel.name = "vel".into();
                v.fields.push(vel);
                v
            }],
            meshes: vec![MeshDesc {
                path: "/wall".into(),
                xform: identity(),
                points: vec![0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0],
                face_counts: vec![3],
                face_indices: vec![0, 1, 2],
                xform_samples: moving.clone(),
                ..MeshDesc::default()
            }],
            lights: vec![sun.clone(), bulb.clone(), panel.clone()],
            has_settings_shutter: settings.is_some(),
            settings_shutter: settings.unwrap_or_default(),
            width: 8,
            height: 8,
            ..SceneDesc::default()
        };
        let (s, warnings) = scene_of(&desc((-0.5, 0.5), Some([0.0, 1.0]))).unwrap();
        assert_eq!(s.camera.shutter, Some((-0.5, 0.5)));
        assert_eq!(
            xs(s.camera.motion.as_ref().unwrap()),
            [(-0.5, -0.2), (0.5, 0.2)]
        );
        assert_eq!(
            xs(s.volumes[0].motion.as_ref().unwrap()),
            [(-0.5, -0.2), (0.5, 0.2)]
        );
        assert_eq!(
            xs(s.sphere_lights[0].motion.as_ref().unwrap()),
            [(-0.5, -0.2), (0.5, 0.2)]
        );
        assert!(s.rect_lights[0].motion.is_none());
        assert!(
            warnings
                .iter()
                .any(|w| w.contains("light /rectLight: it changes size")),
            "{warnings:?}"
        );
        assert!(!warnings.iter().any(|w| w.contains("/sphereLight")));
        // The transform at the frame stays the one handed over.
        assert_eq!(s.volumes[0].volume_to_world, DMat4::IDENTITY);
        for p in [
            "light /distantLight",
            "mesh /wall",
            "volume /smoke: its velocity field `vel`",
        ] {
            assert!(
                warnings
                    .iter()
                    .any(|w| w.contains(p) && w.contains("shutter is open (-0.5 to 0.5)")),
                "no warning about {p}: {warnings:?}"
            );
        }
        // The camera's shutter closed: the render settings'.
        let (s, _) = scene_of(&desc((0.0, 0.0), Some([0.0, 1.0]))).unwrap();
        assert_eq!(s.camera.shutter, Some((0.0, 1.0)));
        assert_eq!(
            xs(s.camera.motion.as_ref().unwrap()),
            [(0.0, 0.0), (1.0, 0.4)]
        );
        // Neither open: no motion, no warning.
        let (s, warnings) = scene_of(&desc((0.0, 0.0), None)).unwrap();
        assert_eq!(s.camera.shutter, None);
        assert!(s.camera.motion.is_none() && s.volumes[0].motion.is_none());
        assert!(
            !warnings.iter().any(|w| w.contains("shutter")),
            "{warnings:?}"
        );
    }

    /// A quad and a pentagon fan into 1 + 3 triangles in world space; a hole and a
    /// bad index.
    #[test]
    fn meshes_fan_triangulated_holes_skipped_bad_indices_refused() {
        let mut xform = identity();
        xform[14] = 2.0; // translate z by 2
        let mesh = MeshDesc {
            path: "/m".into(),
            xform,
            points: vec![
                0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 1.0, 1.0, 0.0, 0.0, 1.0, 0.0, 0.5, 1.5, 0.0,
            ],
            face_counts: vec![4, 5, 3],
            face_indices: vec![0, 1, 2, 3, 0, 1, 2, 4, 3, 0, 1, 2],
            hole_indices: vec![2],
            ..MeshDesc::default()
        };
        let desc = SceneDesc {
            meshes: vec![mesh.clone()],
            ..SceneDesc::default()
        };
        let (s, _) = scene_of(&desc).unwrap();
        let h = &s.holdouts[0];
        assert_eq!((h.faces, h.triangles.len()), (2, 5));
        assert_eq!(h.points[0], [0.0, 0.0, 2.0]);
        let mut bad = mesh;
        bad.face_indices[0] = 9;
        let desc = SceneDesc {
            meshes: vec![bad],
            ..SceneDesc::default()
        };
        let e = scene_of(&desc).unwrap_err().to_string();
        assert!(e.contains("/m") && e.contains("9"), "{e}");
    }

    fn p(name: &str, numbers: &[f64], text: &str) -> ParamDesc {
        ParamDesc {
            name: name.into(),
            numbers: numbers.to_vec(),
            text: text.into(),
        }
    }

    /// A unit cube's 6 quads, counter-clockwise seen from outside.
    pub(crate) fn cube_mesh(path: &str) -> MeshDesc {
        MeshDesc {
            path: path.into(),
            xform: identity(),
            points: [
                [0., 0., 0.],
                [1., 0., 0.],
                [1., 1., 0.],
                [0., 1., 0.],
                [0., 0., 1.],
                [1., 0., 1.],
                [1., 1., 1.],
                [0., 1., 1.],
            ]
            .concat(),
            face_counts: vec![4; 6],
            face_indices: vec![
                0, 3, 2, 1, 4, 5, 6, 7, 0, 1, 5, 4, 2, 3, 7, 6, 1, 2, 6, 5, 0, 4, 7, 3,
            ],
            ..MeshDesc::default()
        }
    }

    fn one_mesh(m: MeshDesc) -> Result<(Scene, Vec<String>)> {
        scene_of(&SceneDesc {
            meshes: vec![m],
            ..SceneDesc::default()
        })
    }

    /// A mesh with NimbusVolumeAPI's primvars is a fog box (fallbacks for the absent
    /// ones, the emission's, its light group), not a holdout; with only
    /// `nimbus:holdout` or `nimbus:lightGroup` it stays a holdout.
    #[test]
    fn meshes_with_volume_primvars_are_fog_boxes() {
        let mut m = cube_mesh("/box");
        m.primvars = vec![
            p("primvars:nimbus:densityScale", &[3.0], ""),
            p("nimbus:emissionKind", &[], "source"),
            p("nimbus:emissionColor", &[1.0, 0.5, 0.25], ""),
            p("primvars:nimbus:lightGroup", &[], "fog"),
            p("primvars:displayColor", &[0.5, 0.5, 0.5], ""),
        ];
        let (s, w) = one_mesh(m).unwrap();
        assert!(w.is_empty(), "{w:?}");
        assert!(s.holdouts.is_empty());
        let v = &s.volumes[0];
        let VolumeShape::Mesh(fog) = &v.shape else {
            panic!("{:?}", v.shape)
        };
        assert!(fog.closed);
        assert_eq!(fog.mesh.triangles.len(), 12);
        assert_eq!(
            (v.density_scale, v.absorption, v.scattering, v.anisotropy),
            (3.0, [0.1; 3], [0.9; 3], 0.0)
        );
        assert_eq!(v.emission.kind, EmissionKind::from_token("source").unwrap());
        assert_eq!(v.emission.emission_color, [1.0, 0.5, 0.25]);
        assert!(v.fields.is_empty() && v.material_shader.is_none());
        assert_eq!(v.light_group.as_deref(), Some("fog"));
        assert_eq!(v.volume_to_world, DMat4::IDENTITY);

        for other in ["primvars:nimbus:holdout", "primvars:nimbus:lightGroup"] {
            let mut m = cube_mesh("/wall");
            m.primvars = vec![p(other, &[1.0], "x")];
            let (s, w) = one_mesh(m).unwrap();
            assert!(w.is_empty(), "{w:?}");
            assert_eq!((s.holdouts.len(), s.volumes.len()), (1, 0), "{other}");
        }
    }

    /// A mesh whose material's volume shader Nimbus reads is a fog box with the
    /// shader's coefficients (a PxrVolume's density primvar is a warning: fog has none);
    /// one whose material's volume shader it does not read is a holdout and a warning
    /// naming the material; a material without a volume shader (a surface's) is a
    /// holdout without one.
    #[test]
    fn meshes_with_a_volume_material_are_fog_boxes() {
        let mut m = cube_mesh("/haze");
        m.material_path = "/mat".into();
        m.shader_path = "/mat/vdf".into();
        m.shader_id = "ND_anisotropic_vdf".into();
        m.shader_params = vec![
            p("absorption", &[0.1, 0.2, 0.3], ""),
            p("scattering", &[0.4, 0.5, 0.6], ""),
            p("anisotropy", &[0.3], ""),
        ];
        let (s, w) = one_mesh(m.clone()).unwrap();
        assert!(w.is_empty(), "{w:?}");
        let v = &s.volumes[0];
        assert!(matches!(v.shape, VolumeShape::Mesh(_)));
        assert_eq!(
            (v.absorption, v.scattering, v.anisotropy, v.density_scale),
            ([0.1, 0.2, 0.3], [0.4, 0.5, 0.6], 0.3, 1.0)
        );
        assert_eq!(
            v.material_shader.as_deref(),
            Some("/mat/vdf (ND_anisotropic_vdf)")
        );

        let mut pxr = m.clone();
        pxr.shader_id = "PxrVolume".into();
        pxr.shader_params = vec![
            p("densityFloat", &[2.0], ""),
            p("densityMultiplier", &[3.0], ""),
            p("densityFloatPrimVar", &[], "density"),
        ];
        let (s, w) = one_mesh(pxr).unwrap();
        assert_eq!(s.volumes[0].density_scale, 3.0);
        assert!(
            w.iter()
                .any(|w| w.contains("/haze") && w.contains("density primvar `density`")),
            "{w:?}"
        );

        let mut principled = m.clone();
        principled.shader_id = "principled_volume".into();
        let (s, w) = one_mesh(principled).unwrap();
        assert_eq!((s.holdouts.len(), s.volumes.len()), (1, 0));
        assert!(
            w.iter().any(|w| w.contains("/haze")
                && w.contains("/mat")
                && w.contains("principled_volume")
                && w.contains("holdout")),
            "{w:?}"
        );

        let mut surface = m;
        surface.shader_path.clear();
        surface.shader_id.clear();
        surface.shader_params.clear();
        let (s, w) = one_mesh(surface).unwrap();
        assert_eq!((s.holdouts.len(), s.volumes.len()), (1, 0));
        assert!(w.is_empty(), "{w:?}");
    }

    /// The authored winding against the topology's orientation and the transform's
    /// handedness: a right-handed cube wound outwards (counter-clockwise seen from
    /// outside) and a left-handed one wound inwards, each also mirrored by its
    /// transform, are read without a warning; a right-handed one wound inwards is read
    /// outwards with a warning naming it; an open one is read by parity with a warning. Every one comes
    /// out wound outwards (positive enclosed volume).
    #[test]
    fn fog_box_winding_orientation_and_mirroring() {
        let inverted = |m: &mut MeshDesc| {
            for f in m.face_indices.chunks_mut(4) {
                f.reverse();
            }
        };
        let mut mirror = identity();
        mirror[0] = -1.0;
        let case = |left_handed: bool, inward: bool, xform: [f64; 16], faces: usize| {
            let mut m = cube_mesh("/box");
            m.primvars = vec![p("nimbus:densityScale", &[1.0], "")];
            m.left_handed = left_handed;
            m.xform = xform;
            if inward {
                inverted(&mut m);
            }
            m.face_counts.truncate(faces);
            m.face_indices.truncate(4 * faces);
            let (s, w) = one_mesh(m).unwrap();
            let VolumeShape::Mesh(fog) = &s.volumes[0].shape else {
                panic!()
            };
            let pt = |i: u32| DVec3::from_array(fog.mesh.points[i as usize]);
            let volume: f64 = fog
                .mesh
                .triangles
                .iter()
                .map(|&[a, b, c]| pt(a).dot(pt(b).cross(pt(c))) / 6.0)
                .sum();
            (fog.closed, volume, w)
        };
        for (left, inward, xform) in [
            (false, false, identity()),
            (true, true, identity()),
            (false, false, mirror),
            (true, true, mirror),
        ] {
            let (closed, volume, w) = case(left, inward, xform, 6);
            assert!(closed && (volume - 1.0).abs() < 1e-12, "{volume}");
            assert!(w.is_empty(), "left {left} inward {inward}: {w:?}");
        }
        let (closed, volume, w) = case(false, true, identity(), 6);
        assert!(closed && (volume - 1.0).abs() < 1e-12, "{volume}");
        assert!(
            w.iter()
                .any(|w| w.contains("/box") && w.contains("faces point inwards")),
            "{w:?}"
        );
        let (closed, _, w) = case(false, false, identity(), 5);
        assert!(!closed);
        assert!(
            w.iter()
                .any(|w| w.contains("/box") && w.contains("not a closed")),
            "{w:?}"
        );
    }

    /// Fog has no fields: a temperature, emission or albedo field named on a fog box
    /// or on world fog is an error naming the prim and the attribute.
    #[test]
    fn fields_named_on_fog_are_errors() {
        for attr in [
            "nimbus:temperatureField",
            "nimbus:emissionField",
            "nimbus:albedoField",
        ] {
            let mut m = cube_mesh("/box");
            m.primvars = vec![p(&format!("primvars:{attr}"), &[], "heat")];
            let e = one_mesh(m).unwrap_err().to_string();
            assert!(
                e.contains("/box") && e.contains(attr) && e.contains("no fields"),
                "{e}"
            );
            let world = VolumeDesc {
                path: "/world".into(),
                xform: identity(),
                primvars: vec![
                    p("nimbus:fill", &[], "world"),
                    p(&format!("primvars:{attr}"), &[], "heat"),
                ],
                ..VolumeDesc::default()
            };
            let e = scene_of(&SceneDesc {
                volumes: vec![world],
                ..SceneDesc::default()
            })
            .unwrap_err()
            .to_string();
            assert!(e.contains("/world") && e.contains(attr), "{e}");
        }
    }

    /// A Volume rprim with `nimbus:fill = "world"` is world fog: without fields (its
    /// fields, if any, are a warning and not read), its medium from the primvars, else
    /// a material Nimbus reads, else NimbusVolumeAPI's fallbacks; "field" is an
    /// ordinary volume; another token is an error.
    #[test]
    fn world_fog_from_the_fill_primvar() {
        let world = |extra: Vec<ParamDesc>| VolumeDesc {
            path: "/world".into(),
            xform: identity(),
            primvars: [vec![p("primvars:nimbus:fill", &[], "world")], extra].concat(),
            ..VolumeDesc::default()
        };
        let run = |v: VolumeDesc| {
            scene_of(&SceneDesc {
                volumes: vec![v],
                ..SceneDesc::default()
            })
        };
        let (s, w) = run(world(vec![
            p("nimbus:densityScale", &[0.02], ""),
            p("nimbus:lightGroup", &[], "air"),
        ]))
        .unwrap();
        assert!(w.is_empty(), "{w:?}");
        let v = &s.volumes[0];
        assert_eq!(v.shape, VolumeShape::World);
        assert_eq!((v.density_scale, v.scattering), (0.02, [0.9; 3]));
        assert_eq!(v.light_group.as_deref(), Some("air"));
        assert!(v.fields.is_empty());

        let (s, w) = run(world(Vec::new())).unwrap();
        assert!(w.is_empty(), "{w:?}");
        assert_eq!(
            (s.volumes[0].density_scale, s.volumes[0].absorption),
            (1.0, [0.1; 3])
        );

        let mut m = world(Vec::new());
        m.material_path = "/mat".into();
        m.shader_path = "/mat/vdf".into();
        m.shader_id = "ND_anisotropic_vdf".into();
        m.shader_params = vec![p("scattering", &[0.5], "")];
        let (s, _) = run(m).unwrap();
        assert_eq!(s.volumes[0].scattering, [0.5; 3]);
        assert_eq!(s.volumes[0].shape, VolumeShape::World);

        let mut with_fields = smoke_volume();
        with_fields.primvars = vec![p("nimbus:fill", &[], "world")];
        let (s, w) = run(with_fields).unwrap();
        assert_eq!(s.volumes[0].shape, VolumeShape::World);
        assert!(
            w.iter()
                .any(|w| w.contains("/smoke") && w.contains("not read")),
            "{w:?}"
        );

        let mut field = smoke_volume();
        field.primvars = vec![p("nimbus:fill", &[], "field")];
        let (s, _) = run(field).unwrap();
        assert!(matches!(s.volumes[0].shape, VolumeShape::Field(_)));

        let mut sky = smoke_volume();
        sky.primvars = vec![p("nimbus:fill", &[], "sky")];
        let e = run(sky).unwrap_err().to_string();
        assert!(e.contains("/smoke") && e.contains("\"sky\""), "{e}");
    }

    /// A volume's `nimbus:lightGroup` (NimbusLightAPI's) does not hide its material
    /// (as the USD reader reads them: the material's coefficients and the group).
    #[test]
    fn a_light_group_keeps_the_volume_material() {
        let mut v = smoke_volume();
        v.primvars = vec![p("primvars:nimbus:lightGroup", &[], "smoke")];
        v.material_path = "/mat".into();
        v.shader_path = "/mat/vdf".into();
        v.shader_id = "ND_anisotropic_vdf".into();
        v.shader_params = vec![p("scattering", &[0.5], "")];
        let (s, w) = scene_of(&SceneDesc {
            volumes: vec![v],
            ..SceneDesc::default()
        })
        .unwrap();
        assert!(w.is_empty(), "{w:?}");
        assert_eq!(s.volumes[0].scattering, [0.5; 3]);
        assert_eq!(s.volumes[0].light_group.as_deref(), Some("smoke"));
    }

    /// Settings by the schema's names; a wrong kind of value names the setting.
    #[test]
    fn settings_by_schema_name() {
        let set = |key: &str, number: f64| SettingDesc {
            key: key.into(),
            is_text: false,
            number,
            text: String::new(),
        };
        let tok = |key: &str, text: &str| SettingDesc {
            key: key.into(),
            is_text: true,
            number: 0.0,
            text: text.into(),
        };
        let s = settings(
            &[
                set("nimbus:samples", 64.0),
                set("nimbus:seed", 7.0),
                tok("nimbus:tracker", "delta"),
                set("aovToken:Combined", 1.0),
            ],
            (32, 16),
        )
        .unwrap();
        assert_eq!((s.samples, s.seed, s.resolution), (64, 7, (32, 16)));
        assert_eq!(s.tracker.as_deref(), Some("delta"));
        assert!(!s.denoise);
        let s = settings(&[set("nimbus:denoise", 1.0)], (1, 1)).unwrap();
        assert!(s.denoise, "nimbus:denoise");
        let e = settings(&[set("nimbus:samples", 0.5)], (1, 1))
            .unwrap_err()
            .to_string();
        assert!(e.contains("nimbus:samples"), "{e}");
        let e = settings(&[set("nimbus:tracker", 1.0)], (1, 1))
            .unwrap_err()
            .to_string();
        assert!(e.contains("nimbus:tracker"), "{e}");
    }
}
