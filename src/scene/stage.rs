//! Loading a USD stage into a [`Scene`].
//!
//! The stage is composed by openusd (sublayers, references, payloads, variants)
//! with a schema registry that knows UsdGeom/UsdLux/UsdRender/UsdVol and Nimbus'
//! own API schemas, so every unauthored property reads its schema fallback.
//! Everything is evaluated at one time code and converted to plain Rust types:
//! transforms become column-vector [`DMat4`]s, asset paths become resolved files
//! (or the bytes of a .usdz member).

use super::attrs::*;
use super::blender_graph;
use super::camera;
use super::defaults;
use super::description::*;
use super::diagnostics::Diagnostics;
use super::fog;
use super::geometry;
use super::instancer;
use super::lights;
use super::motion;
use super::schema::{self, tokens};
use super::shading;
use super::unsupported;
use crate::motion::TransformMotion;
use crate::volume::emission::EmissionKind;
use glam::DMat4;
use openusd::sdf;
use openusd::usd::{Prim, PrimPredicate, Stage, TimeCode};
use openusd_schemas::geom::{self, ImageableExt};
use openusd_schemas::render::StageMetadata;
use std::cell::RefCell;
use std::path::Path;

#[derive(Clone, Debug, Default)]
pub struct LoadOptions {
    /// Time code to evaluate at (`--frame`); `None` = the stage's default time.
    pub frame: Option<f64>,
    /// Camera prim path override (`--camera`).
    pub camera: Option<String>,
}

/// Schema type names this loader looks for (registry identifiers, so derived
/// types match too through `is_a`).
mod types {
    pub const VOLUME: &str = "Volume";
    pub const OPENVDB_ASSET: &str = "OpenVDBAsset";
    pub const CAMERA: &str = "Camera";
    pub const RENDER_SETTINGS: &str = "RenderSettings";
    pub const RENDER_PRODUCT: &str = "RenderProduct";
    pub const RENDER_VAR: &str = "RenderVar";
    /// Every UsdGeom gprim (Mesh, Sphere, …; also Volume, matched first).
    pub const GPRIM: &str = "Gprim";
    pub const POINT_INSTANCER: &str = "PointInstancer";
}

/// The camera attributes whose change during the exposure would blur the image.
const LENS_ATTRIBUTES: [&str; 7] = [
    "focalLength",
    "horizontalAperture",
    "verticalAperture",
    "horizontalApertureOffset",
    "verticalApertureOffset",
    "fStop",
    "focusDistance",
];

/// Prefix of a volume's field relationships (`field:density`).
const FIELD_PREFIX: &str = "field:";
/// Density field used when `nimbus:densityField` resolves no value at all.
const DEFAULT_DENSITY_FIELD: &str = "density";

/// Opens `path` and extracts everything the renderer needs at `opts.frame`.
pub fn load_stage(path: &Path, opts: &LoadOptions) -> Result<Scene, SceneError> {
    let stage = open_stage(path)?;
    let loader = Loader {
        stage: &stage,
        time: opts.frame.map(TimeCode::new),
        xforms: geom::XformCache::new(opts.frame.map(TimeCode::new)),
        warnings: RefCell::default(),
        shutter: None,
    };
    let scene = loader.load(path, opts);
    // Reference and payload diagnostics accrue while prims are composed, so they
    // are only complete after the traversal. A composition error means the
    // scene is missing pieces its author meant to be there: refuse to render it,
    // and prefer that explanation over whatever symptom it caused.
    check_composition(&stage, path)?;
    scene.map_err(|e| in_stage(e, path))
}

/// Prim errors name the prim; add the stage file so a message read out of
/// context (a render farm log) still says where to look.
fn in_stage(error: SceneError, path: &Path) -> SceneError {
    match error {
        SceneError::Prim { prim, message } => SceneError::Prim {
            prim,
            message: format!("{message} (in {})", path.display()),
        },
        other => other,
    }
}

fn open_stage(path: &Path) -> Result<Stage, SceneError> {
    if !path.is_file() {
        return Err(stage_error(path, "stage file not found"));
    }
    let path_str = path
        .to_str()
        .ok_or_else(|| stage_error(path, "path is not valid UTF-8"))?;
    let registry = schema::registry().map_err(|e| stage_error(path, e))?;
    let stage = Stage::builder()
        .schema_registry(registry)
        .open(path_str)
        .map_err(|e| stage_error(path, format!("cannot open stage: {}", error_chain(&e))))?;
    check_composition(&stage, path)?;
    Ok(stage)
}

fn check_composition(stage: &Stage, path: &Path) -> Result<(), SceneError> {
    let errors = stage.composition_errors();
    if errors.is_empty() {
        return Ok(());
    }
    let list: Vec<String> = errors.iter().map(|e| e.to_string()).collect();
    Err(stage_error(
        path,
        format!("composition errors: {}", list.join("; ")),
    ))
}

/// The prims of interest, gathered in one traversal (in namespace order).
#[derive(Default)]
struct Inventory {
    volumes: Vec<Prim>,
    cameras: Vec<Prim>,
    lights: Vec<Prim>,
    render_settings: Vec<Prim>,
    /// Gprims other than volumes: candidates for holdouts.
    gprims: Vec<Prim>,
    /// PointInstancers: the gprims beneath them are prototypes, drawn only where the
    /// instancer places them (which Nimbus does not read), never in place.
    point_instancers: Vec<Prim>,
    /// Light prims of every kind, read or not (see [`Scene::light_prims`]).
    light_prims: usize,
    /// Light prims of a type Nimbus does not read (each gets a warning).
    unread_lights: Vec<Prim>,
}

struct Loader<'a> {
    stage: &'a Stage,
    time: Option<TimeCode>,
    xforms: geom::XformCache,
    /// What the stage asks for that the render will not show as authored; readers
    /// that only borrow the loader add to it too.
    warnings: RefCell<Diagnostics>,
    /// The render camera's shutter interval, when it is open (set before any other
    /// prim's transform is read): what moves within it warns ([`motion`]).
    shutter: Option<(f64, f64)>,
}

impl Loader<'_> {
    fn load(mut self, path: &Path, opts: &LoadOptions) -> Result<Scene, SceneError> {
        let inventory = self.inventory().map_err(|e| stage_error(path, e))?;
        let settings_prim = self.settings_prim(&inventory, path)?;
        let settings = match &settings_prim {
            Some(prim) => self.render_settings(prim)?,
            None => RenderSettings::default(),
        };
        let camera = match self.choose_camera(opts, settings_prim.as_ref(), &inventory)? {
            Some(prim) => self.camera(&prim)?,
            // No camera named and none on the stage: the session frames the volumes.
            None => defaults::placeholder_camera(),
        };
        // Volumes beneath a PointInstancer are its prototypes: placed by it, not drawn
        // where they are.
        let in_instancer = |p: &Prim| {
            inventory
                .point_instancers
                .iter()
                .any(|instancer| p.path().has_prefix(instancer.path()))
        };
        let plain: Vec<Prim> = inventory
            .volumes
            .iter()
            .filter(|p| !in_instancer(p))
            .cloned()
            .collect();
        let volumes = self.visible(&plain)?;
        let lights = self.lights(&inventory)?;
        for prim in &inventory.unread_lights {
            self.unread_light(prim)?;
        }
        let (holdouts, fog_boxes) = self.gprims(&inventory)?;
        self.unsupported(&inventory, settings_prim.as_ref())?;
        let mut volumes: Vec<Volume> = volumes
            .iter()
            .map(|p| self.volume(p))
            .collect::<Result<_, _>>()?;
        volumes.extend(self.instanced_volumes(&inventory)?);
        volumes.extend(fog_boxes);
        Ok(Scene {
            stage_path: path.to_path_buf(),
            // USD's default time code is NaN (`UsdTimeCode::Default()`).
            time: opts.frame.unwrap_or(f64::NAN),
            camera,
            distant_lights: lights.distant,
            dome_lights: lights.dome,
            sphere_lights: lights.sphere,
            rect_lights: lights.rect,
            disk_lights: lights.disk,
            cylinder_lights: lights.cylinder,
            volumes,
            holdouts,
            settings,
            light_prims: inventory.light_prims,
            warnings: self.warnings.into_inner(),
        })
    }

    fn inventory(&self) -> Result<Inventory, openusd::Error> {
        let mut paths = Vec::new();
        // Instance proxies included: a volume inside an instanced asset renders.
        self.stage
            .traverse(PrimPredicate::DEFAULT.with_instance_proxies(true), |p| {
                paths.push(p.clone())
            })?;
        let mut inventory = Inventory::default();
        for path in paths {
            let prim = self.stage.prim(path)?;
            if lights::is_any_light(&prim)? {
                inventory.light_prims += 1;
                if !lights::is_light(&prim)? {
                    inventory.unread_lights.push(prim.clone());
                }
            }
            let bucket = if prim.is_a(types::VOLUME)? {
                &mut inventory.volumes
            } else if prim.is_a(types::CAMERA)? {
                &mut inventory.cameras
            } else if lights::is_light(&prim)? {
                &mut inventory.lights
            } else if prim.is_a(types::RENDER_SETTINGS)? {
                &mut inventory.render_settings
            } else if prim.is_a(types::GPRIM)? {
                &mut inventory.gprims
            } else if prim.is_a(types::POINT_INSTANCER)? {
                &mut inventory.point_instancers
            } else {
                continue;
            };
            bucket.push(prim);
        }
        Ok(inventory)
    }

    /// A light prim of a type (or a light API on a prim) Nimbus does not render: one
    /// warning naming its type, so the render is never lit differently without a word.
    fn unread_light(&self, prim: &Prim) -> Result<(), SceneError> {
        let err = |e| prim_error(prim.path(), e);
        let ty = prim
            .type_name()
            .map_err(err)?
            .map(|t| t.to_string())
            .filter(|t| !t.is_empty())
            .unwrap_or_else(|| "untyped prim".to_string());
        let (kind, message) = match lights::light_api(prim).map_err(err)? {
            Some(api) if !lights::is_light_type(prim).map_err(err)? => (
                format!("{api} on a {ty}"),
                format!("{api} makes this {ty} a light; Nimbus does not render its emission"),
            ),
            _ => (
                format!("{ty} light"),
                format!("{ty} lights are not supported: this light is left out of the render"),
            ),
        };
        self.warnings
            .borrow_mut()
            .warn(kind, prim.path().to_string(), None, message);
        Ok(())
    }

    /// Warnings for what the stage authors besides lights and holdout gprims that the
    /// render does not show ([`unsupported`]): point instancers, and render settings
    /// and products asking for what the render does not do.
    fn unsupported(
        &self,
        inventory: &Inventory,
        settings: Option<&Prim>,
    ) -> Result<(), SceneError> {
        let mut warnings = self.warnings.borrow_mut();
        for prim in self.visible(&inventory.point_instancers)? {
            let prototypes = targets(&prim, "prototypes")?;
            let gprims = inventory
                .gprims
                .iter()
                .filter(|g| prototypes.iter().any(|root| g.path().has_prefix(root)))
                .count();
            if gprims > 0 {
                unsupported::point_instancer(&prim, gprims, &mut warnings);
            }
        }
        if let Some(settings) = settings {
            unsupported::render_settings_base(settings, false, self.time, &mut warnings)?;
            for target in targets(settings, "products")? {
                let product = self.target_prim(settings, &target, types::RENDER_PRODUCT)?;
                unsupported::render_settings_base(&product, true, self.time, &mut warnings)?;
            }
        }
        Ok(())
    }

    /// The visible lights, read by [`lights`] with their world transforms.
    fn lights(&mut self, inventory: &Inventory) -> Result<lights::StageLights, SceneError> {
        let mut prims = Vec::new();
        for prim in self.visible(&inventory.lights)? {
            let (to_world, motion) = match lights::is_local_light(&prim)? {
                true => self.blurred_light_transform(&prim)?,
                false => (self.world_transform(&prim)?, None),
            };
            prims.push((prim, to_world, motion));
        }
        lights::read_lights(prims, self.time, &mut self.warnings.borrow_mut())
    }

    /// The visible gprims of a type Nimbus reads, with the `default` or `render`
    /// purpose (`proxy` and `guide` are stand-ins a final render leaves out), as
    /// world-space triangles: fog boxes (a gprim with `NimbusVolumeAPI`, or bound to a
    /// material with a volume output Nimbus reads) and holdouts (the others whose
    /// `nimbus:holdout` is not false; the attribute is read whether or not
    /// `NimbusHoldoutAPI` is applied).
    fn gprims(
        &mut self,
        inventory: &Inventory,
    ) -> Result<(Vec<HoldoutMesh>, Vec<Volume>), SceneError> {
        let mut holdouts = Vec::new();
        let mut fog_boxes = Vec::new();
        for prim in self.visible(&inventory.gprims)? {
            let prototype = inventory
                .point_instancers
                .iter()
                .any(|instancer| prim.path().has_prefix(instancer.path()));
            if prototype {
                continue;
            }
            let purpose = match geom::Imageable::from_prim(prim.clone())
                .map_err(|e| prim_error(prim.path(), e))?
            {
                Some(im) => im
                    .compute_purpose()
                    .map_err(|e| prim_error(prim.path(), format!("purpose: {e}")))?,
                None => geom::Purpose::Default,
            };
            if !matches!(purpose, geom::Purpose::Default | geom::Purpose::Render) {
                continue;
            }
            let fog = self.medium_params(&prim)?;
            if fog.is_none() && read_bool(&prim, tokens::HOLDOUT, self.time)? == Some(false) {
                continue;
            }
            let Some(prim_type) = geometry::holdout_type(&prim)? else {
                unsupported::unread_gprim(&prim, &mut self.warnings.borrow_mut())?;
                continue;
            };
            let to_world = self.world_transform(&prim)?;
            let mesh = geometry::read_holdout(&prim, prim_type, &to_world, self.time)?;
            match fog {
                None => holdouts.push(mesh),
                Some(params) => fog_boxes.push(self.fog_box(&prim, mesh, params, &to_world)?),
            }
        }
        Ok((holdouts, fog_boxes))
    }

    /// The volumes every visible PointInstancer places: for each instance, each Volume
    /// beneath its prototype root, read once per prototype and placed by the
    /// instance's transform (the prototype root's own transform included, as
    /// UsdGeomPointInstancer's `IncludeProtoXform`). Instances keep their prototype
    /// volume's path (light groups and linking name the prototype).
    fn instanced_volumes(&mut self, inventory: &Inventory) -> Result<Vec<Volume>, SceneError> {
        let mut out = Vec::new();
        for instancer in self.visible(&inventory.point_instancers)? {
            let placed = instancer::instances(&instancer, self.time)?;
            let instancer_world = self.world_transform(&instancer)?;
            // Per prototype: its volumes and their transforms relative to the
            // prototype root's parent (root transform included).
            let mut prototypes: Vec<Vec<(Volume, DMat4)>> = Vec::new();
            let mut to_parents = Vec::new();
            for root in &placed.prototypes {
                let parent_world = match root.parent().filter(|p| !p.is_abs_root()) {
                    Some(parent) => {
                        let parent = self
                            .stage
                            .prim(parent.clone())
                            .map_err(|e| prim_error(instancer.path(), e))?;
                        self.world_transform(&parent)?
                    }
                    None => DMat4::IDENTITY,
                };
                let to_parent = parent_world.inverse();
                to_parents.push(to_parent);
                let mut volumes = Vec::new();
                for prim in inventory
                    .volumes
                    .iter()
                    .filter(|v| v.path().has_prefix(root))
                {
                    let volume = self.volume(prim)?;
                    let relative = to_parent * volume.volume_to_world;
                    volumes.push((volume, relative));
                }
                prototypes.push(volumes);
            }
            for (proto, m) in placed.placed {
                for (volume, relative) in &prototypes[proto] {
                    let mut v = volume.clone();
                    let place = instancer_world * m * to_parents[proto];
                    v.volume_to_world = instancer_world * m * *relative;
                    // The prototype's own motion, carried by the instance's placement.
                    v.motion = v.motion.map(|motion| motion.placed(place));
                    out.push(v);
                }
            }
        }
        Ok(out)
    }

    /// The medium of a fog box or of world fog (`prim` a gprim, or a Volume with
    /// `nimbus:fill = "world"`): from `NimbusVolumeAPI`, else from a bound material
    /// with a volume output Nimbus reads; `None` when the prim has neither (a gprim is
    /// then a holdout). Fog has no grids: a `nimbus:*Field` naming one is an error.
    fn medium_params(&self, prim: &Prim) -> Result<Option<FogParams>, SceneError> {
        let t = self.time;
        let nimbus_api = prim
            .has_api_schema(schema::VOLUME_API)
            .map_err(|e| prim_error(prim.path(), e))?;
        if nimbus_api {
            for attr in [
                tokens::TEMPERATURE_FIELD,
                tokens::EMISSION_FIELD,
                tokens::ALBEDO_FIELD,
            ] {
                if let Some(name) = read_string(prim, attr, t)?.filter(|n| !n.is_empty()) {
                    return Err(prim_error(
                        prim.path(),
                        format!(
                            "{attr} = \"{name}\": fog (a gprim with {}, or nimbus:fill = \"world\") has no fields; its density is 1 and its emission, with nimbus:emissionKind \"source\", the constant emissionColor × emissionScale",
                            schema::VOLUME_API
                        ),
                    ));
                }
            }
            let graph = self.density_scale_graph(prim, false)?;
            if let Some((g, source)) = &graph {
                if let Some(a) = &g.attribute {
                    return Err(prim_error(
                        prim.path(),
                        format!("{source}: its density graph reads the field `{a}` (an Attribute node); fog has no fields"),
                    ));
                }
            }
            let density_scale = match graph {
                Some(_) => 1.0,
                None => read_f64(prim, tokens::DENSITY_SCALE, t)?.unwrap_or(1.0),
            };
            let mut absorption = read_vec3(prim, tokens::ABSORPTION, t)?.unwrap_or([0.1; 3]);
            let mut scattering = read_vec3(prim, tokens::SCATTERING, t)?.unwrap_or([0.9; 3]);
            let albedo_graph = self.albedo(prim, &mut absorption, &mut scattering)?;
            return Ok(Some(FogParams {
                density_scale,
                absorption,
                scattering,
                anisotropy: read_f64(prim, tokens::ANISOTROPY, t)?.unwrap_or(0.0),
                emission: self.emission(prim, &[])?,
                material_shader: None,
                density_graph: graph.map(|(g, source)| DensityGraph {
                    program: g.program,
                    shading_to_world: DMat4::IDENTITY,
                    source,
                }),
                albedo_graph,
            }));
        }
        let Some(m) = shading::bound_volume_material(self.stage, prim, t)? else {
            return Ok(None);
        };
        let source = format!("{} ({})", m.shader, m.shader_id);
        let emission = match m.emission.clone() {
            None => VolumeEmission::default(),
            Some(e) => {
                if let Some(field) = &e.field {
                    return Err(prim_error(
                        prim.path(),
                        format!("{}: its emission colour reads the field `{field}` (ND_geompropvalue_float); fog has no fields", e.edf),
                    ));
                }
                e.volume_emission(None)
            }
        };
        // Placed in the gprim's space by the caller (world fog refuses it).
        let density_graph = m.density_graph.map(|g| DensityGraph {
            program: g.program,
            shading_to_world: DMat4::IDENTITY,
            source: source.clone(),
        });
        if density_graph
            .as_ref()
            .is_some_and(|g| g.program.reads_attribute())
        {
            return Err(prim_error(
                prim.path(),
                format!("{source}: its density graph reads the field `{}` (ND_geompropvalue_float); fog has no fields", m.density_field),
            ));
        }
        if density_graph.is_none() && m.density_field != DEFAULT_DENSITY_FIELD {
            self.warnings.borrow_mut().warn(
                "fog density primvar",
                prim.path().to_string(),
                Some("material:binding"),
                format!(
                    "{} names the density primvar `{}`; fog has none: its density is 1 (times the shader's density scale)",
                    m.shader, m.density_field
                ),
            );
        }
        Ok(Some(FogParams {
            density_scale: m.density_scale,
            absorption: m.absorption,
            scattering: m.scattering,
            anisotropy: m.anisotropy,
            emission,
            material_shader: Some(source),
            density_graph,
            albedo_graph: None,
        }))
    }

    /// A fog box: `mesh` (the gprim's triangles) checked for a closed, consistently
    /// oriented surface, and wound outwards.
    fn fog_box(
        &self,
        prim: &Prim,
        mesh: HoldoutMesh,
        p: FogParams,
        to_world: &DMat4,
    ) -> Result<Volume, SceneError> {
        let left_handed =
            read_string(prim, "orientation", self.time)?.as_deref() == Some("leftHanded");
        let mirrored =
            (mesh.prim_type == "Mesh").then_some(left_handed != (to_world.determinant() < 0.0));
        let (fog, problem) = fog::fog_mesh(mesh, mirrored);
        let mut p = p;
        if let Some(g) = &mut p.density_graph {
            g.shading_to_world = *to_world;
        }
        if let Some(g) = &mut p.emission.color_graph {
            g.shading_to_world = *to_world;
        }
        if let Some(g) = &mut p.albedo_graph {
            g.shading_to_world = *to_world;
        }
        if let Some(problem) = problem {
            self.warnings
                .borrow_mut()
                .warn("fog surface", prim.path().to_string(), None, problem);
        }
        Ok(p.volume(
            &prim.path().to_string(),
            self.light_group(prim)?,
            VolumeShape::Mesh(fog),
        ))
    }

    /// Drops prims whose computed visibility (inherited down namespace) is
    /// `invisible` at the scene time.
    fn visible(&self, prims: &[Prim]) -> Result<Vec<Prim>, SceneError> {
        let mut out = Vec::new();
        for prim in prims {
            let imageable =
                geom::Imageable::from_prim(prim.clone()).map_err(|e| prim_error(prim.path(), e))?;
            let invisible = match imageable {
                Some(im) => {
                    im.compute_visibility(self.time)
                        .map_err(|e| prim_error(prim.path(), e))?
                        == geom::Visibility::Invisible
                }
                None => false,
            };
            if !invisible {
                out.push(prim.clone());
            }
        }
        Ok(out)
    }

    /// Local → world of `prim` as a column-vector matrix. Every prim the render uses
    /// (camera, volumes, lights, holdouts) comes through here or through
    /// [`Self::blurred_transform`], so this is where a transform that moves while the
    /// shutter is open, and is not blurred, warns.
    fn world_transform(&mut self, prim: &Prim) -> Result<DMat4, SceneError> {
        if let Some(shutter) = self.shutter {
            if let Some((owner, op)) = motion::moving_op(prim, self.time, shutter)? {
                self.motion_warning(&owner, &op, shutter);
            }
        }
        self.frame_transform(prim)
    }

    /// Local → world of a prim Nimbus blurs (the camera, a UsdVolVolume, a local light): its
    /// transform at the frame and, when it moves while the shutter is open, its motion
    /// over the shutter. Without a frame (`--frame`) there is no shutter interval to
    /// sample: it warns as any moving prim does.
    fn blurred_transform(
        &mut self,
        prim: &Prim,
    ) -> Result<(DMat4, Option<TransformMotion>), SceneError> {
        let (Some(time), Some(shutter)) = (self.time, self.shutter) else {
            return Ok((self.world_transform(prim)?, None));
        };
        let m = self.frame_transform(prim)?;
        Ok((m, motion::transform_motion(prim, time, shutter)?))
    }

    /// [`Self::blurred_transform`] of a local light: its samples are drawn where it is
    /// at the frame and carried along with it, which holds for a light that turns and
    /// slides; one whose size changes over the shutter warns and renders at the frame.
    fn blurred_light_transform(
        &mut self,
        prim: &Prim,
    ) -> Result<(DMat4, Option<TransformMotion>), SceneError> {
        let (m, motion) = self.blurred_transform(prim)?;
        let Some(motion) = motion else {
            return Ok((m, None));
        };
        if motion.is_rigid_from(&m) {
            return Ok((m, Some(motion)));
        }
        let shutter = self.shutter.unwrap_or_default();
        let (owner, op) = motion::moving_op(prim, self.time, shutter)?
            .unwrap_or_else(|| (prim.clone(), "xformOpOrder".to_string()));
        self.warnings.borrow_mut().warn(
            "motion blur",
            owner.path().to_string(),
            Some(&op),
            format!(
                "the light {} changes size or shape while the camera's shutter is open ({} to {}): Nimbus blurs a light that turns and slides, not one that scales; it is rendered at the frame's time",
                prim.path(),
                shutter.0,
                shutter.1
            ),
        );
        Ok((m, None))
    }

    /// Local → world of `prim` at the scene's time, refused when not finite.
    fn frame_transform(&mut self, prim: &Prim) -> Result<DMat4, SceneError> {
        let m = self
            .xforms
            .local_to_world_transform(prim)
            .map_err(|e| prim_error(prim.path(), format!("cannot compute transform: {e}")))?;
        let m = to_dmat4(&m);
        // Every prim the render uses gets its transform here: a NaN or infinite one
        // would make the prim vanish (rays miss it) or poison every sample, so it is
        // refused, naming the prim.
        if !m.is_finite() {
            return Err(prim_error(
                prim.path(),
                "its world transform is not finite (a NaN or infinite value in its xformOps or an ancestor's)",
            ));
        }
        Ok(m)
    }

    // ----- camera -------------------------------------------------------------

    fn choose_camera(
        &self,
        opts: &LoadOptions,
        settings: Option<&Prim>,
        inventory: &Inventory,
    ) -> Result<Option<Prim>, SceneError> {
        if let Some(requested) = &opts.camera {
            let prim = self
                .stage
                .prim(requested.as_str())
                .map_err(|e| prim_error_str(requested, format!("invalid camera path: {e}")))?;
            return self
                .require_type(&prim, types::CAMERA, "requested camera")
                .map(Some);
        }
        if let Some(settings) = settings {
            if let Some(target) = first_target(settings, "camera")? {
                let prim = self
                    .stage
                    .prim(target)
                    .map_err(|e| prim_error(settings.path(), e))?;
                return self
                    .require_type(&prim, types::CAMERA, "render settings camera")
                    .map(Some);
            }
        }
        Ok(inventory.cameras.first().cloned())
    }

    /// The render camera (read first: its shutter decides whether moving prims warn).
    fn camera(&mut self, prim: &Prim) -> Result<Camera, SceneError> {
        self.shutter = camera::shutter(prim, self.time)?;
        if let Some(shutter) = self.shutter {
            if let Some(name) =
                motion::moving_attribute(prim, &LENS_ATTRIBUTES, self.time, shutter)?
            {
                self.motion_warning(prim, name, shutter);
            }
        }
        let (to_world, motion) = self.blurred_transform(prim)?;
        let mut camera =
            camera::read_camera(prim, self.time, to_world, &mut self.warnings.borrow_mut())?;
        camera.shutter = self.shutter;
        camera.motion = motion;
        Ok(camera)
    }

    /// One "motion blur" warning: `attribute` of `prim` changes while the shutter is
    /// open and is rendered at the frame's time.
    fn motion_warning(&self, prim: &Prim, attribute: &str, (open, close): (f64, f64)) {
        let why = match self.time {
            None => "no frame was given (--frame), so there is no shutter interval to blur over and nothing is blurred",
            Some(_) => "Nimbus blurs the transforms of the camera, UsdVolVolumes and sphere, rect, disk and cylinder lights, not this one (nor lens attributes, distant and dome lights, holdouts, fog boxes or instancers)",
        };
        self.warnings.borrow_mut().warn(
            "motion blur",
            prim.path().to_string(),
            Some(attribute),
            format!("time-sampled, and it changes while the camera's shutter is open ({open} to {close}): {why}; it is rendered at the frame's time"),
        );
    }

    // ----- volumes ------------------------------------------------------------

    /// `nimbus:lightGroup` of a volume (its emission's light group), if set.
    fn light_group(&self, prim: &Prim) -> Result<Option<String>, SceneError> {
        Ok(read_string(prim, tokens::LIGHT_GROUP, self.time)?.filter(|g| !g.is_empty()))
    }

    fn volume(&mut self, prim: &Prim) -> Result<Volume, SceneError> {
        let t = self.time;
        match read_string(prim, tokens::FILL, t)?.as_deref() {
            None | Some("field") => {}
            Some("world") => return self.world_fog(prim),
            Some(other) => {
                return Err(prim_error(
                    prim.path(),
                    format!(
                        "{} = \"{other}\" is not one of \"field\", \"world\"",
                        tokens::FILL
                    ),
                ))
            }
        }
        let (fields, relationship_count) = self.fields(prim)?;
        if relationship_count == 0 {
            return Err(prim_error(
                prim.path(),
                "volume has no field:* relationships with targets",
            ));
        }
        // Nimbus' schema when applied; else a bound material's volume shader, if
        // one Nimbus reads; else the schema fallbacks.
        let nimbus_api = prim
            .has_api_schema(schema::VOLUME_API)
            .map_err(|e| prim_error(prim.path(), e))?;
        let material = match nimbus_api {
            true => None,
            false => shading::bound_volume_material(self.stage, prim, t)?,
        };
        if !nimbus_api && material.is_none() {
            if let Some(bound) = shading::bound_material_path(self.stage, prim)? {
                unsupported::unread_material(prim, &bound, &mut self.warnings.borrow_mut());
            }
        }
        if let Some(m) = material {
            let density = self.density_field(prim, &m.density_field, &fields)?;
            let (volume_to_world, motion) = self.blurred_transform(prim)?;
            let emission = match m.emission.clone() {
                None => VolumeEmission::default(),
                Some(e) => {
                    let field = match &e.field {
                        None => None,
                        Some(name) => Some(self.material_field(prim, &e.edf, name, &fields)?),
                    };
                    let mut emission = e.volume_emission(field);
                    if let Some(g) = &mut emission.color_graph {
                        g.shading_to_world = volume_to_world;
                    }
                    emission
                }
            };
            let velocity = self.velocity(prim, &fields)?;
            let source = format!("{} ({})", m.shader, m.shader_id);
            return Ok(Volume {
                prim_path: prim.path().to_string(),
                light_group: self.light_group(prim)?,
                volume_to_world,
                motion,
                shape: VolumeShape::Field(density),
                density_scale: m.density_scale,
                absorption: m.absorption,
                scattering: m.scattering,
                anisotropy: m.anisotropy,
                fields,
                emission,
                albedo: None,
                albedo_graph: None,
                velocity,
                density_graph: m.density_graph.map(|g| DensityGraph {
                    program: g.program,
                    shading_to_world: volume_to_world,
                    source: source.clone(),
                }),
                material_shader: Some(source),
            });
        }
        let density_name = read_string(prim, tokens::DENSITY_FIELD, t)?
            .unwrap_or_else(|| DEFAULT_DENSITY_FIELD.to_string());
        let density = self.density_field(prim, &density_name, &fields)?;
        let mut emission = self.emission(prim, &fields)?;
        let albedo = self.named_field(prim, tokens::ALBEDO_FIELD, &fields)?;
        let mut absorption = read_vec3(prim, tokens::ABSORPTION, t)?.unwrap_or([0.1; 3]);
        let mut scattering = read_vec3(prim, tokens::SCATTERING, t)?.unwrap_or([0.9; 3]);
        let mut albedo_graph = self.albedo(prim, &mut absorption, &mut scattering)?;
        if let (Some((name, _)), Some(g)) = (&albedo, &albedo_graph) {
            return Err(prim_error(
                prim.path(),
                format!(
                    "{} names the field `{name}` and {} is connected to {}: one albedo multiplier may vary in space, not two",
                    tokens::ALBEDO_FIELD,
                    tokens::ALBEDO,
                    g.source
                ),
            ));
        }
        let (volume_to_world, motion) = self.blurred_transform(prim)?;
        let velocity = self.velocity(prim, &fields)?;
        if let Some(g) = &mut emission.color_graph {
            g.shading_to_world = volume_to_world;
        }
        if let Some(g) = &mut albedo_graph {
            g.shading_to_world = volume_to_world;
        }
        let graph = self.density_scale_graph(prim, true)?;
        if let Some((g, source)) = &graph {
            if let Some(a) = g.attribute.as_ref().filter(|a| **a != density_name) {
                return Err(prim_error(
                    prim.path(),
                    format!("{source}: its density graph reads the field `{a}` (an Attribute node) where the density field is `{density_name}`; Nimbus reads one field per density graph"),
                ));
            }
        }
        let density_scale = match graph {
            Some(_) => 1.0,
            None => read_f64(prim, tokens::DENSITY_SCALE, t)?.unwrap_or(1.0),
        };
        Ok(Volume {
            prim_path: prim.path().to_string(),
            light_group: self.light_group(prim)?,
            volume_to_world,
            motion,
            shape: VolumeShape::Field(density),
            density_scale,
            absorption,
            scattering,
            anisotropy: read_f64(prim, tokens::ANISOTROPY, t)?.unwrap_or(0.0),
            fields,
            velocity,
            emission,
            albedo,
            albedo_graph,
            material_shader: None,
            density_graph: graph.map(|(g, source)| DensityGraph {
                program: g.program,
                shading_to_world: volume_to_world,
                source,
            }),
        })
    }

    /// The density graph `nimbus:densityScale` is connected to (the Blender add-on's
    /// node trees, [`blender_graph`]), with a description of its source; `times_field`:
    /// the program multiplies the graph by the density field's value (a Volume; fog
    /// has none).
    fn density_scale_graph(
        &self,
        prim: &Prim,
        times_field: bool,
    ) -> Result<Option<(blender_graph::BlenderDensity, String)>, SceneError> {
        let Some((shader, output, source)) = self.connected_shader(prim, tokens::DENSITY_SCALE)?
        else {
            return Ok(None);
        };
        let graph = blender_graph::usd_density(&shader, &output, self.time, times_field)?;
        Ok(Some((graph, source)))
    }

    /// The colour graph `nimbus:emissionColor` is connected to (the Blender add-on's
    /// node trees), placed in the prim's object space by the caller.
    fn emission_color_graph(&self, prim: &Prim) -> Result<Option<DensityGraph>, SceneError> {
        self.color_graph(prim, tokens::EMISSION_COLOR, "emission")
    }

    /// The Blender colour graph `attr` of `prim` is connected to (`None` when it is
    /// not), in the prim's object space (placed by the caller). A graph reading a field
    /// is refused: colour graphs read none. `what` names the colour in messages.
    fn color_graph(
        &self,
        prim: &Prim,
        attr: &str,
        what: &str,
    ) -> Result<Option<DensityGraph>, SceneError> {
        let Some((shader, output, source)) = self.connected_shader(prim, attr)? else {
            return Ok(None);
        };
        let graph = blender_graph::usd_color(&shader, &output, self.time)?;
        if let Some(a) = graph.attribute {
            return Err(prim_error(
                prim.path(),
                format!("{source}: the {what} colour graph reads the field `{a}` (an Attribute node); Nimbus reads fields in density graphs only"),
            ));
        }
        Ok(Some(DensityGraph {
            program: graph.program,
            shading_to_world: DMat4::IDENTITY,
            source,
        }))
    }

    /// The shader prim and output `attr` of `prim` is connected to, and a description
    /// of it for messages; `None` when it is not connected.
    fn connected_shader(
        &self,
        prim: &Prim,
        attr: &str,
    ) -> Result<Option<(Prim, String, String)>, SceneError> {
        let sources = prim
            .attribute(attr)
            .connections()
            .map_err(|e| prim_error(prim.path(), format!("{attr}: {e}")))?;
        let Some(source) = sources.first() else {
            return Ok(None);
        };
        let (path, property) = split_property(source);
        let Some(output) = property.strip_prefix("outputs:") else {
            return Err(prim_error(
                prim.path(),
                format!("{attr} is connected to {source}, which is not a shader output"),
            ));
        };
        let shader = self
            .stage
            .prim(path.clone())
            .map_err(|e| prim_error(prim.path(), format!("{attr}: {e}")))?;
        Ok(Some((
            shader,
            output.to_string(),
            format!("{path} (Blender nodes)"),
        )))
    }

    /// `nimbus:albedo`: the colour graph it is connected to (in the prim's object
    /// space, placed by the caller), or its constant value, folded here into the
    /// coefficients (σs → c·σs, σa → σa + (1 − c)·σs, c clamped into [0,1]; the
    /// fallback (1, 1, 1) changes nothing). A graph reading a field is refused.
    fn albedo(
        &self,
        prim: &Prim,
        absorption: &mut [f64; 3],
        scattering: &mut [f64; 3],
    ) -> Result<Option<DensityGraph>, SceneError> {
        if let Some(graph) = self.color_graph(prim, tokens::ALBEDO, "albedo")? {
            return Ok(Some(graph));
        }
        let c = read_vec3(prim, tokens::ALBEDO, self.time)?.unwrap_or([1.0; 3]);
        if c.iter().any(|v| !v.is_finite()) {
            return Err(prim_error(
                prim.path(),
                format!("{} = {c:?} is not finite", tokens::ALBEDO),
            ));
        }
        fold_albedo(c, absorption, scattering);
        Ok(None)
    }

    /// World fog: a Volume with `nimbus:fill = "world"` (its fields are not read).
    fn world_fog(&mut self, prim: &Prim) -> Result<Volume, SceneError> {
        let Some(p) = self.medium_params(prim)? else {
            return Err(prim_error(
                prim.path(),
                format!(
                    "{} = \"world\" needs the medium's parameters: apply {} or bind a volume material",
                    tokens::FILL,
                    schema::VOLUME_API
                ),
            ));
        };
        if let Some(g) = &p.density_graph {
            return Err(prim_error(
                prim.path(),
                format!("{}: a density graph on world fog is not read yet (it would fill all space); bind it to a closed gprim (a fog box) instead", g.source),
            ));
        }
        let (_, relationship_count) = self.fields(prim)?;
        if relationship_count > 0 {
            self.warnings.borrow_mut().warn(
                "world fog fields",
                prim.path().to_string(),
                Some(tokens::FILL),
                "world fog has density 1 everywhere: its field:* relationships are not read",
            );
        }
        Ok(p.volume(
            &prim.path().to_string(),
            self.light_group(prim)?,
            VolumeShape::World,
        ))
    }

    /// The density field: the relationship `field:<name>`, which must exist and
    /// target an OpenVDBAsset (the only field type the renderer reads).
    fn density_field(
        &self,
        prim: &Prim,
        name: &str,
        fields: &[(String, Field)],
    ) -> Result<Field, SceneError> {
        if let Some((_, field)) = fields.iter().find(|(n, _)| n == name) {
            return Ok(field.clone());
        }
        let rel = format!("{FIELD_PREFIX}{name}");
        match first_target(prim, &rel)? {
            None => Err(prim_error(
                prim.path(),
                format!(
                    "density field relationship `{rel}` (from {}) is missing or has no target",
                    tokens::DENSITY_FIELD
                ),
            )),
            Some(target) => Err(prim_error(
                prim.path(),
                format!(
                    "density field `{rel}` targets {target}, which is not an OpenVDBAsset prim"
                ),
            )),
        }
    }

    /// The field a material's shader `shader` reads by `name` (a MaterialX
    /// `geompropvalue`): one of the volume's `field:*` relationships, or an error
    /// naming the shader and listing them.
    fn material_field(
        &self,
        prim: &Prim,
        shader: &str,
        name: &str,
        fields: &[(String, Field)],
    ) -> Result<(String, Field), SceneError> {
        match fields.iter().find(|(n, _)| n == name) {
            Some(f) => Ok(f.clone()),
            None => Err(prim_error(
                prim.path(),
                format!(
                    "{shader} reads the field `{name}`, which the volume does not have (its fields: {})",
                    fields.iter().map(|(n, _)| n.as_str()).collect::<Vec<_>>().join(", ")
                ),
            )),
        }
    }

    /// The emission configuration of a volume with `NimbusVolumeAPI`: the fields
    /// `nimbus:temperatureField` and `nimbus:emissionField` name (empty = none) and
    /// their parameters (checked when the medium is built).
    fn emission(
        &self,
        prim: &Prim,
        fields: &[(String, Field)],
    ) -> Result<VolumeEmission, SceneError> {
        let t = self.time;
        let d = VolumeEmission::default();
        Ok(VolumeEmission {
            temperature: self.named_field(prim, tokens::TEMPERATURE_FIELD, fields)?,
            temperature_scale: read_f64(prim, tokens::TEMPERATURE_SCALE, t)?
                .unwrap_or(d.temperature_scale),
            blackbody_intensity: read_f64(prim, tokens::BLACKBODY_INTENSITY, t)?
                .unwrap_or(d.blackbody_intensity),
            emission: self.named_field(prim, tokens::EMISSION_FIELD, fields)?,
            emission_color: read_vec3(prim, tokens::EMISSION_COLOR, t)?.unwrap_or(d.emission_color),
            emission_scale: read_f64(prim, tokens::EMISSION_SCALE, t)?.unwrap_or(d.emission_scale),
            color_graph: self.emission_color_graph(prim)?,
            kind: match read_string(prim, tokens::EMISSION_KIND, t)? {
                None => d.kind,
                Some(k) => EmissionKind::from_token(&k).ok_or_else(|| {
                    prim_error(
                        prim.path(),
                        format!(
                            "{} = \"{k}\" is not one of \"radiance\", \"source\"",
                            tokens::EMISSION_KIND
                        ),
                    )
                })?,
            },
        })
    }

    /// The field a token attribute names (`attr` = "flames" → `field:flames`), `None`
    /// when the attribute is empty or unset. A name with no OpenVDBAsset field is an
    /// error listing the volume's fields.
    /// The velocity field that blurs `prim`'s fields over the shutter:
    /// `nimbus:velocityField` when it names one, else a field `vel` or `velocity` (the
    /// names Houdini and Blender write). None without a frame and an open shutter, or
    /// with a velocity scale of 0.
    fn velocity(
        &self,
        prim: &Prim,
        fields: &[(String, Field)],
    ) -> Result<Option<Velocity>, SceneError> {
        let t = self.time;
        if t.is_none() || self.shutter.is_none() {
            return Ok(None);
        }
        let scale = read_f64(prim, tokens::VELOCITY_SCALE, t)?.unwrap_or(1.0);
        let blur = read_f64(prim, "motion:blurScale", t)?.unwrap_or(1.0);
        for (name, v) in [(tokens::VELOCITY_SCALE, scale), ("motion:blurScale", blur)] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(prim_error(
                    prim.path(),
                    format!("{name} = {v}: it must be finite and not negative"),
                ));
            }
        }
        if scale * blur == 0.0 {
            return Ok(None);
        }
        let named = read_string(prim, tokens::VELOCITY_FIELD, t)?.unwrap_or_default();
        let field = match named.is_empty() {
            true => ["vel", "velocity"]
                .iter()
                .find_map(|n| fields.iter().find(|(f, _)| f == n))
                .cloned(),
            false => self.named_field(prim, tokens::VELOCITY_FIELD, fields)?,
        };
        let per_second = self.stage.time_codes_per_second();
        Ok(field.map(|field| Velocity {
            field,
            seconds_per_time_code: scale * blur / per_second,
        }))
    }

    fn named_field(
        &self,
        prim: &Prim,
        attr: &str,
        fields: &[(String, Field)],
    ) -> Result<Option<(String, Field)>, SceneError> {
        let name = read_string(prim, attr, self.time)?.unwrap_or_default();
        if name.is_empty() {
            return Ok(None);
        }
        if let Some((n, field)) = fields.iter().find(|(n, _)| *n == name) {
            return Ok(Some((n.clone(), field.clone())));
        }
        let rel = format!("{FIELD_PREFIX}{name}");
        let known: Vec<String> = fields
            .iter()
            .map(|(n, _)| format!("{FIELD_PREFIX}{n}"))
            .collect();
        let known = if known.is_empty() {
            "none".to_string()
        } else {
            known.join(", ")
        };
        let problem = match first_target(prim, &rel)? {
            None => format!("the volume has no relationship `{rel}` with a target"),
            Some(target) => format!("`{rel}` targets {target}, which is not an OpenVDBAsset prim"),
        };
        Err(prim_error(
            prim.path(),
            format!("{attr} = \"{name}\": {problem}; the volume's OpenVDB fields: {known}"),
        ))
    }

    /// Every `field:*` relationship whose target is an OpenVDBAsset. A target that
    /// does not exist is an error (the stage is broken); a field of another type
    /// (e.g. Field3DAsset) is left out, since Nimbus cannot read it. Also returns
    /// how many targeted `field:*` relationships there were, of any type.
    fn fields(&self, prim: &Prim) -> Result<(Vec<(String, Field)>, usize), SceneError> {
        let mut fields = Vec::new();
        let mut relationship_count = 0;
        let rels = prim
            .relationships()
            .map_err(|e| prim_error(prim.path(), e))?;
        for rel in rels {
            let Some(name) = rel.name().strip_prefix(FIELD_PREFIX).map(str::to_string) else {
                continue;
            };
            let Some(target) = rel
                .targets()
                .map_err(|e| prim_error(rel.path(), e))?
                .into_iter()
                .next()
            else {
                continue;
            };
            relationship_count += 1;
            let target_prim = self
                .stage
                .prim(target.clone())
                .map_err(|e| prim_error(rel.path(), e))?;
            if !is_valid(&target_prim)? {
                return Err(prim_error(
                    prim.path(),
                    format!(
                        "field relationship `{}` targets {target}, which does not exist",
                        rel.name()
                    ),
                ));
            }
            if target_prim
                .is_a(types::OPENVDB_ASSET)
                .map_err(|e| prim_error(&target, e))?
            {
                fields.push((name, self.field(&target_prim)?));
            } else {
                unsupported::unread_field(
                    prim,
                    rel.name(),
                    &target_prim,
                    &mut self.warnings.borrow_mut(),
                )?;
            }
        }
        fields.sort_by(|a, b| a.0.cmp(&b.0));
        Ok((fields, relationship_count))
    }

    fn field(&self, prim: &Prim) -> Result<Field, SceneError> {
        let t = self.time;
        let asset = read_asset(prim, "filePath", t)?
            .filter(|a| !a.authored_path.is_empty())
            .ok_or_else(|| unauthored_file_path(prim, t))?;
        let index_attr = prim.attribute("fieldIndex");
        let field_index = match authored(&index_attr, prim)? {
            true => read_i64(prim, "fieldIndex", t)?
                .map(|i| {
                    i32::try_from(i).map_err(|_| {
                        prim_error(prim.path(), format!("fieldIndex {i} out of range"))
                    })
                })
                .transpose()?,
            false => None,
        };
        Ok(Field {
            prim_path: prim.path().to_string(),
            file: asset_location(prim, &asset)?,
            field_name: read_string(prim, "fieldName", t)?.unwrap_or_default(),
            field_index,
        })
    }

    // ----- render settings ----------------------------------------------------

    /// The prim `renderSettingsPrimPath` names, else the first RenderSettings prim.
    fn settings_prim(
        &self,
        inventory: &Inventory,
        path: &Path,
    ) -> Result<Option<Prim>, SceneError> {
        let named = self
            .stage
            .render_settings_prim_path()
            .map_err(|e| stage_error(path, format!("renderSettingsPrimPath: {e}")))?
            .filter(|p| !p.is_empty());
        match named {
            Some(named) => {
                let prim = self.stage.prim(named.as_str()).map_err(|e| {
                    stage_error(path, format!("renderSettingsPrimPath `{named}`: {e}"))
                })?;
                self.require_type(&prim, types::RENDER_SETTINGS, "renderSettingsPrimPath")
                    .map(Some)
            }
            None => Ok(inventory.render_settings.first().cloned()),
        }
    }

    fn render_settings(&self, prim: &Prim) -> Result<RenderSettings, SceneError> {
        let t = self.time;
        let defaults = RenderSettings::default();
        let resolution = match read_int2(prim, "resolution", t)? {
            Some([w, h]) => (
                to_u32(prim, "resolution", w)?,
                to_u32(prim, "resolution", h)?,
            ),
            None => defaults.resolution,
        };
        let samples = read_i64(prim, tokens::SAMPLES, t)?;
        let min_samples = read_i64(prim, tokens::MIN_SAMPLES, t)?;
        let noise_threshold = read_f64(prim, tokens::NOISE_THRESHOLD, t)?;
        if let Some(v) = noise_threshold.filter(|v| !(v.is_finite() && *v >= 0.0)) {
            return Err(prim_error(
                prim.path(),
                format!(
                    "{} = {v}: must be 0 (off) or positive",
                    tokens::NOISE_THRESHOLD
                ),
            ));
        }
        let max_depth = read_i64(prim, tokens::MAX_DEPTH, t)?;
        let seed = read_i64(prim, tokens::SEED, t)?;
        Ok(RenderSettings {
            prim_path: Some(prim.path().to_string()),
            resolution,
            samples: samples
                .map(|v| to_u32(prim, tokens::SAMPLES, v))
                .transpose()?
                .unwrap_or(defaults.samples),
            min_samples: min_samples
                .map(|v| to_u32(prim, tokens::MIN_SAMPLES, v))
                .transpose()?
                .unwrap_or(defaults.min_samples),
            noise_threshold: noise_threshold.unwrap_or(defaults.noise_threshold),
            max_depth: max_depth
                .map(|v| to_u32(prim, tokens::MAX_DEPTH, v))
                .transpose()?
                .unwrap_or(defaults.max_depth),
            seed: seed
                .map(|v| {
                    u64::try_from(v).map_err(|_| {
                        prim_error(prim.path(), format!("{} = {v} is negative", tokens::SEED))
                    })
                })
                .transpose()?
                .unwrap_or(defaults.seed),
            products: self.products(prim)?,
            // Only what the stage authors: a schema fallback names no choice, so
            // `--tracker auto` stays free to pick the scheme and shadow-ray estimator.
            tracker: if_authored(prim, tokens::TRACKER, || {
                read_string(prim, tokens::TRACKER, t)
            })?,
            scheme: if_authored(prim, tokens::SCHEME, || {
                read_string(prim, tokens::SCHEME, t)
            })?,
            transmittance: if_authored(prim, tokens::TRANSMITTANCE, || {
                read_string(prim, tokens::TRANSMITTANCE, t)
            })?,
            control: if_authored(prim, tokens::CONTROL, || read_f64(prim, tokens::CONTROL, t))?,
            octree_depth: if_authored(prim, tokens::OCTREE_DEPTH, || {
                read_i64(prim, tokens::OCTREE_DEPTH, t)
            })?,
            strict: read_bool(prim, tokens::STRICT, t)?.unwrap_or(defaults.strict),
            denoise: read_bool(prim, tokens::DENOISE, t)?.unwrap_or(defaults.denoise),
        })
    }

    fn products(&self, settings: &Prim) -> Result<Vec<RenderProduct>, SceneError> {
        let mut products = Vec::new();
        for target in targets(settings, "products")? {
            let prim = self.target_prim(settings, &target, types::RENDER_PRODUCT)?;
            let product_name =
                read_string(&prim, "productName", self.time)?.filter(|n| !n.is_empty());
            let preview_name =
                read_string(&prim, tokens::PREVIEW_NAME, self.time)?.filter(|n| !n.is_empty());
            let mut vars = Vec::new();
            for var_path in targets(&prim, "orderedVars")? {
                let var = self.target_prim(&prim, &var_path, types::RENDER_VAR)?;
                vars.push(RenderVar {
                    prim_path: var.path().to_string(),
                    source_name: read_string(&var, "sourceName", self.time)?.unwrap_or_default(),
                    source_type: read_string(&var, "sourceType", self.time)?
                        .unwrap_or_else(|| "raw".to_string()),
                    data_type: read_string(&var, "dataType", self.time)?.unwrap_or_default(),
                });
            }
            products.push(RenderProduct {
                prim_path: prim.path().to_string(),
                product_type: read_string(&prim, "productType", self.time)?
                    .filter(|t| !t.is_empty())
                    .unwrap_or_else(|| "raster".to_string()),
                product_name,
                preview_name,
                vars,
            });
        }
        Ok(products)
    }

    // ----- prim lookups ---------------------------------------------------------

    /// The prim a relationship of `owner` targets, which must exist and be a `ty`.
    fn target_prim(&self, owner: &Prim, target: &sdf::Path, ty: &str) -> Result<Prim, SceneError> {
        let prim = self
            .stage
            .prim(target.clone())
            .map_err(|e| prim_error(owner.path(), e))?;
        self.require_type(&prim, ty, &format!("target of {}", owner.path()))
    }

    fn require_type(&self, prim: &Prim, ty: &str, role: &str) -> Result<Prim, SceneError> {
        if !is_valid(prim)? {
            return Err(prim_error(prim.path(), format!("{role}: no such prim")));
        }
        if !prim.is_a(ty).map_err(|e| prim_error(prim.path(), e))? {
            let actual = prim
                .type_name()
                .ok()
                .flatten()
                .map(|t| t.to_string())
                .unwrap_or_default();
            return Err(prim_error(
                prim.path(),
                format!("{role}: expected a {ty} prim, found type `{actual}`"),
            ));
        }
        Ok(prim.clone())
    }
}
