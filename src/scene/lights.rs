//! UsdLux lights → plain [`Scene`](super::Scene) light types.
//!
//! Kept apart from `stage.rs` (which finds the prims and evaluates their world
//! transforms) so light reading is one concept in one place. Every property reads
//! its UsdLux schema fallback when unauthored (the registry knows UsdLux), so the
//! `unwrap_or` values below only matter for stages the registry cannot type.
//!
//! Values are checked where they are read: a non-finite number is an error naming the
//! prim and attribute; a negative intensity or colour and an emission beyond what a
//! 32-bit image holds are warnings (they render as authored); and what a light asks
//! for that Nimbus does not render (filters, shadow colour and distance, IES profiles,
//! textures on lights other than domes, collection expressions) is a warning naming
//! the prim and attribute.

use super::attrs::{
    authored, prim_error, read_asset, read_f64, read_string, read_value, read_vec3, targets,
    wrong_type, SceneError,
};
use super::description::{
    Collection, CylinderLight, DiskLight, DistantLight, DomeLight, LightControls, RectLight,
    Shaping, SphereLight,
};
use super::diagnostics::Diagnostics;
use super::schema::tokens;
use crate::motion::TransformMotion;
use glam::{DMat4, DVec3};
use openusd::sdf::Value;
use openusd::usd::{Prim, TimeCode};

/// Schema type names of the lights Nimbus reads.
const DISTANT_LIGHT: &str = "DistantLight";
const DOME_LIGHT: &str = "DomeLight";
const SPHERE_LIGHT: &str = "SphereLight";
const RECT_LIGHT: &str = "RectLight";
const DISK_LIGHT: &str = "DiskLight";
const CYLINDER_LIGHT: &str = "CylinderLight";

const READ: [&str; 6] = [
    DISTANT_LIGHT,
    DOME_LIGHT,
    SPHERE_LIGHT,
    RECT_LIGHT,
    DISK_LIGHT,
    CYLINDER_LIGHT,
];

/// The lights of a stage, by type.
#[derive(Default)]
pub(super) struct StageLights {
    pub distant: Vec<DistantLight>,
    pub dome: Vec<DomeLight>,
    pub sphere: Vec<SphereLight>,
    pub rect: Vec<RectLight>,
    pub disk: Vec<DiskLight>,
    pub cylinder: Vec<CylinderLight>,
}

/// Whether `prim` is a light type Nimbus reads.
pub(super) fn is_light(prim: &Prim) -> Result<bool, openusd::Error> {
    for ty in READ {
        if prim.is_a(ty)? {
            return Ok(true);
        }
    }
    Ok(false)
}

/// UsdLux's light base classes and the API schemas that make any prim a light: a prim
/// matching one is a light to its author, whether or not Nimbus renders it.
const LIGHT_BASES: [&str; 3] = ["BoundableLightBase", "NonboundableLightBase", "PluginLight"];
// The specific APIs first: each includes LightAPI.
const LIGHT_APIS: [&str; 3] = ["MeshLightAPI", "VolumeLightAPI", "LightAPI"];

/// Whether `prim` is a light of any kind (read by Nimbus or not): a stage with one gets
/// no default lights.
pub(super) fn is_any_light(prim: &Prim) -> Result<bool, openusd::Error> {
    Ok(is_light_type(prim)? || light_api(prim)?.is_some())
}

/// Whether `prim`'s type is a UsdLux light (of any kind, read or not).
pub(super) fn is_light_type(prim: &Prim) -> Result<bool, openusd::Error> {
    for ty in LIGHT_BASES {
        if prim.is_a(ty)? {
            return Ok(true);
        }
    }
    Ok(false)
}

/// The light API schema applied to `prim`, if any.
pub(super) fn light_api(prim: &Prim) -> Result<Option<&'static str>, openusd::Error> {
    for api in LIGHT_APIS {
        if prim.has_api_schema(api)? {
            return Ok(Some(api));
        }
    }
    Ok(None)
}

/// Reads every (visible) light prim, given with its local → world transform at the
/// frame and, for a local light that moves while the shutter is open, its motion;
/// what the render will not show as authored goes to `warnings`.
pub(super) fn read_lights(
    prims: Vec<(Prim, DMat4, Option<TransformMotion>)>,
    time: Option<TimeCode>,
    warnings: &mut Diagnostics,
) -> Result<StageLights, SceneError> {
    let mut lights = StageLights::default();
    for (prim, to_world, motion) in prims {
        let is = |ty: &str| prim.is_a(ty).map_err(|e| prim_error(prim.path(), e));
        let mut r = Reader {
            prim: &prim,
            t: time,
            warnings: &mut *warnings,
        };
        let to_world = &to_world;
        if is(DISTANT_LIGHT)? {
            lights.distant.push(r.distant_light(to_world)?);
        } else if is(DOME_LIGHT)? {
            lights.dome.push(r.dome_light(to_world)?);
        } else if is(SPHERE_LIGHT)? {
            lights.sphere.push(r.sphere_light(to_world, motion)?);
        } else if is(RECT_LIGHT)? {
            lights.rect.push(r.rect_light(to_world, motion)?);
        } else if is(DISK_LIGHT)? {
            lights.disk.push(r.disk_light(to_world, motion)?);
        } else if is(CYLINDER_LIGHT)? {
            lights.cylinder.push(r.cylinder_light(to_world, motion)?);
        }
    }
    Ok(lights)
}

/// Whether `prim` is a light whose motion Nimbus blurs: a local light (sphere, rect,
/// disk, cylinder). Distant and dome lights render at the frame's time.
pub(super) fn is_local_light(prim: &Prim) -> Result<bool, SceneError> {
    for ty in [SPHERE_LIGHT, RECT_LIGHT, DISK_LIGHT, CYLINDER_LIGHT] {
        if prim.is_a(ty).map_err(|e| prim_error(prim.path(), e))? {
            return Ok(true);
        }
    }
    Ok(false)
}

/// The LightAPI inputs every light has.
struct Common {
    intensity: f64,
    exposure: f64,
    color: [f64; 3],
    normalize: bool,
    color_temperature: Option<f64>,
    light_group: Option<String>,
    controls: LightControls,
}

/// Reads one light prim at one time.
struct Reader<'a> {
    prim: &'a Prim,
    t: Option<TimeCode>,
    warnings: &'a mut Diagnostics,
}

/// The largest emission an image can hold: the film is written as 32-bit floats.
const FILM_MAX: f64 = f32::MAX as f64;

impl Reader<'_> {
    fn error(&self, message: impl std::fmt::Display) -> SceneError {
        prim_error(self.prim.path(), message)
    }

    fn warn(&mut self, kind: &str, attribute: &str, message: impl Into<String>) {
        self.warnings
            .warn(kind, self.prim.path().to_string(), Some(attribute), message);
    }

    /// A number (schema fallback `fallback` when unauthored) that must be finite.
    fn number(&self, name: &str, fallback: f64) -> Result<f64, SceneError> {
        let v = read_f64(self.prim, name, self.t)?.unwrap_or(fallback);
        if !v.is_finite() {
            return Err(self.error(format!("{name} = {v}: must be a finite number")));
        }
        Ok(v)
    }

    /// A length: finite and ≥ 0.
    fn length(&self, name: &str, fallback: f64) -> Result<f64, SceneError> {
        let v = self.number(name, fallback)?;
        if v < 0.0 {
            return Err(self.error(format!("{name} = {v}: must be ≥ 0")));
        }
        Ok(v)
    }

    /// A colour whose components must be finite.
    fn colour(&self, name: &str, fallback: [f64; 3]) -> Result<[f64; 3], SceneError> {
        let c = read_vec3(self.prim, name, self.t)?.unwrap_or(fallback);
        if c.iter().any(|v| !v.is_finite()) {
            return Err(self.error(format!("{name} = {c:?}: must be finite")));
        }
        Ok(c)
    }

    fn bool(&self, name: &str) -> Result<Option<bool>, SceneError> {
        read_bool(self.prim, name, self.t)
    }

    fn is_authored(&self, name: &str) -> Result<bool, SceneError> {
        authored(&self.prim.attribute(name), self.prim)
    }

    /// The LightAPI inputs, checked: non-finite values are errors; negative intensity
    /// or colour warn, and so does an emission scale beyond what an image holds (naming
    /// the attribute that overflows).
    fn common(&mut self, intensity_fallback: f64) -> Result<Common, SceneError> {
        let enable_temperature = self.bool("inputs:enableColorTemperature")?.unwrap_or(false);
        let color_temperature = match enable_temperature {
            true => Some(self.number("inputs:colorTemperature", 6500.0)?),
            false => None,
        };
        let intensity = self.number("inputs:intensity", intensity_fallback)?;
        let exposure = self.number("inputs:exposure", 0.0)?;
        let color = self.colour("inputs:color", [1.0; 3])?;
        if intensity < 0.0 {
            self.warn(
                "negative light intensity",
                "inputs:intensity",
                format!("inputs:intensity = {intensity} is negative: rendered as authored, the light takes light away (its contributions are subtracted)"),
            );
        }
        if color.iter().any(|&c| c < 0.0) {
            self.warn(
                "negative light colour",
                "inputs:color",
                format!("inputs:color = {color:?} has a negative component: rendered as authored, that channel is subtracted"),
            );
        }
        // Normalization divides by the light's size but keeps its power, so what
        // reaches the film scales with the unnormalized emission.
        let scale =
            (intensity * exposure.exp2()).abs() * color.iter().fold(0.0, |m, c| c.abs().max(m));
        if !(scale <= FILM_MAX) {
            let attr = if exposure.abs() >= 64.0 {
                "inputs:exposure"
            } else {
                "inputs:intensity"
            };
            self.warn(
                "light emission overflows the film",
                attr,
                format!(
                    "intensity · 2^exposure · color = {scale:e} (inputs:intensity = {intensity}, inputs:exposure = {exposure}) is beyond what a 32-bit image holds ({FILM_MAX:e}): pixels this light reaches may be infinite and are dropped"
                ),
            );
        }
        let diffuse = self.number("inputs:diffuse", 1.0)?;
        Ok(Common {
            intensity,
            exposure,
            color,
            normalize: self.bool("inputs:normalize")?.unwrap_or(false),
            color_temperature,
            light_group: read_string(self.prim, tokens::LIGHT_GROUP, self.t)?
                .filter(|g| !g.is_empty()),
            controls: LightControls {
                diffuse,
                ..self.controls()?
            },
        })
    }

    /// ShapingAPI, ShadowAPI, the linking collections and light filters.
    fn controls(&mut self) -> Result<LightControls, SceneError> {
        let shaping = self.shaping()?;
        let shadow_enable = self.bool("inputs:shadow:enable")?.unwrap_or(true);
        self.unhonoured_shadow_controls()?;
        let filters = match self.prim.relationship("light:filters").targets() {
            Ok(t) => t,
            Err(e) => return Err(self.error(format!("light:filters: {e}"))),
        };
        if !filters.is_empty() {
            self.warn(
                "light filter",
                "light:filters",
                format!(
                    "light filters ({}) are not supported: the light is rendered unfiltered",
                    filters
                        .iter()
                        .map(|p| p.to_string())
                        .collect::<Vec<_>>()
                        .join(", ")
                ),
            );
        }
        Ok(LightControls {
            diffuse: 1.0,
            shaping,
            light_link: self.collection("lightLink")?,
            shadow_link: self.collection("shadowLink")?,
            unshadowed: !shadow_enable,
        })
    }

    /// ShadowAPI's non-physical controls Nimbus does not render (shadows are always
    /// black and unlimited), when authored to something other than their fallback.
    fn unhonoured_shadow_controls(&mut self) -> Result<(), SceneError> {
        let color = read_vec3(self.prim, "inputs:shadow:color", self.t)?;
        if color.is_some_and(|c| c != [0.0; 3]) {
            self.warn(
                "shadow colour",
                "inputs:shadow:color",
                "shadow colour is not supported: shadows are black (what the volume and holdouts block)",
            );
        }
        for (name, fallback) in [
            ("inputs:shadow:distance", -1.0),
            ("inputs:shadow:falloff", -1.0),
            ("inputs:shadow:falloffGamma", 1.0),
        ] {
            let v = read_f64(self.prim, name, self.t)?;
            if v.is_some_and(|v| v != fallback) {
                self.warn(
                    "shadow distance or falloff",
                    name,
                    format!("{name} is not supported: shadows are cast at every distance without falloff"),
                );
            }
        }
        Ok(())
    }

    /// The first authored of `inputs:shaping:NAME` and the pre-connectable
    /// `shaping:NAME`, or the former (its schema fallback) when neither is authored.
    fn shaping_name(&self, name: &str) -> Result<String, SceneError> {
        let new = format!("inputs:shaping:{name}");
        let old = format!("shaping:{name}");
        if !self.is_authored(&new)? && self.is_authored(&old)? {
            return Ok(old);
        }
        Ok(new)
    }

    /// ShapingAPI, when applied or any of its inputs is authored.
    fn shaping(&mut self) -> Result<Option<Shaping>, SceneError> {
        const NAMES: [&str; 7] = [
            "focus",
            "focusTint",
            "cone:angle",
            "cone:softness",
            "ies:file",
            "ies:angleScale",
            "ies:normalize",
        ];
        let applied = self
            .prim
            .has_api_schema("ShapingAPI")
            .map_err(|e| self.error(e))?;
        let mut any = applied;
        for n in NAMES {
            any = any || self.is_authored(&self.shaping_name(n)?)?;
        }
        if !any {
            return Ok(None);
        }
        let d = Shaping::default();
        let focus_name = self.shaping_name("focus")?;
        let softness_name = self.shaping_name("cone:softness")?;
        let mut s = Shaping {
            focus: self.number(&focus_name, d.focus)?,
            focus_tint: self.colour(&self.shaping_name("focusTint")?, d.focus_tint)?,
            cone_angle: self.number(&self.shaping_name("cone:angle")?, d.cone_angle)?,
            cone_softness: self.number(&softness_name, d.cone_softness)?,
            ies_file: None,
            ies_angle_scale: self.number(&self.shaping_name("ies:angleScale")?, 0.0)?,
            ies_normalize: self
                .bool(&self.shaping_name("ies:normalize")?)?
                .unwrap_or(false),
        };
        if s.focus < 0.0 {
            self.warn(
                "negative shaping focus",
                &focus_name,
                format!(
                    "{focus_name} = {} is negative: ignored, as UsdLux says (no focus)",
                    s.focus
                ),
            );
            s.focus = 0.0;
        }
        if !(0.0..=1.0).contains(&s.cone_softness) {
            self.warn(
                "shaping softness out of range",
                &softness_name,
                format!(
                    "{softness_name} = {} is outside [0, 1]: clamped, as UsdLux says",
                    s.cone_softness
                ),
            );
            s.cone_softness = s.cone_softness.clamp(0.0, 1.0);
        }
        let ies_name = self.shaping_name("ies:file")?;
        s.ies_file = self.asset(&ies_name)?;
        if let Some(file) = &s.ies_file {
            self.warn(
                "IES profile",
                &ies_name,
                format!("IES profile not supported: rendered without it ({file}; the cone and focus still apply)"),
            );
        }
        Ok(Some(s))
    }

    /// An asset attribute's resolved path (the authored one when it does not
    /// resolve), when authored and not empty.
    fn asset(&self, name: &str) -> Result<Option<String>, SceneError> {
        if !self.is_authored(name)? {
            return Ok(None);
        }
        Ok(read_asset(self.prim, name, self.t)?
            .filter(|a| !a.authored_path.is_empty())
            .map(|a| {
                a.resolved_path()
                    .filter(|r| !r.is_empty())
                    .unwrap_or(a.authored_path.as_str())
                    .to_string()
            }))
    }

    /// `collection:NAME` (UsdCollectionAPI) as a membership rule; what it cannot
    /// evaluate (a membership expression, collections included by collections) warns.
    fn collection(&mut self, name: &str) -> Result<Collection, SceneError> {
        let base = format!("collection:{name}");
        let include_root = self.bool(&format!("{base}:includeRoot"))?.unwrap_or(true);
        let mut paths = |rel: &str| -> Result<Vec<String>, SceneError> {
            let rel = format!("{base}:{rel}");
            let mut out = Vec::new();
            for t in targets(self.prim, &rel)? {
                if t.is_prim_path() {
                    out.push(t.to_string());
                } else {
                    self.warnings.warn(
                        "collection of collections",
                        self.prim.path().to_string(),
                        Some(rel.as_str()),
                        format!("{rel} targets {t}, not a prim: collections that include other collections are not supported (that target is ignored)"),
                    );
                }
            }
            Ok(out)
        };
        let includes = paths("includes")?;
        let excludes = paths("excludes")?;
        let rule_name = format!("{base}:expansionRule");
        let rule = read_string(self.prim, &rule_name, self.t)?;
        let explicit_only = rule.as_deref() == Some("explicitOnly");
        let expr = format!("{base}:membershipExpression");
        if self.is_authored(&expr)? {
            self.warn(
                "collection membership expression",
                &expr,
                format!("{expr} is not supported: membership is decided by includeRoot, includes and excludes only"),
            );
        }
        Ok(Collection {
            include_root,
            includes,
            excludes,
            explicit_only,
        })
    }

    /// `inputs:texture:file` on a light that is not a dome: rendered untextured.
    fn untextured(&mut self, ty: &str) -> Result<(), SceneError> {
        if self.asset("inputs:texture:file")?.is_some() {
            self.warn(
                "light texture",
                "inputs:texture:file",
                format!("{ty} textures are not supported: the light is rendered with its constant colour"),
            );
        }
        Ok(())
    }

    fn distant_light(&mut self, to_world: &DMat4) -> Result<DistantLight, SceneError> {
        // The light emits along its local −Z, so the direction towards it is +Z.
        let z = to_world.transform_vector3(DVec3::Z);
        let direction = z
            .try_normalize()
            .ok_or_else(|| self.error("degenerate transform (zero Z axis)"))?;
        let c = self.common(50000.0)?;
        self.untextured("DistantLight")?;
        Ok(DistantLight {
            prim_path: self.prim.path().to_string(),
            light_group: c.light_group.clone(),
            direction: direction.to_array(),
            intensity: c.intensity,
            exposure: c.exposure,
            color: c.color,
            normalize: c.normalize,
            color_temperature: c.color_temperature,
            angle_degrees: self.number("inputs:angle", 0.53)?,
            controls: c.controls,
        })
    }

    fn dome_light(&mut self, to_world: &DMat4) -> Result<DomeLight, SceneError> {
        let texture_file = self.asset("inputs:texture:file")?;
        let c = self.common(1.0)?;
        if c.controls.diffuse != 1.0 {
            self.warn(
                "dome diffuse multiplier",
                "inputs:diffuse",
                format!("inputs:diffuse = {} on a dome is not supported: the dome lights the volume as it is seen", c.controls.diffuse),
            );
        }
        if c.controls.shaping.is_some() {
            self.warn(
                "dome shaping",
                "inputs:shaping:cone:angle",
                "ShapingAPI on a dome light is not supported: the dome is unshaped",
            );
        }
        Ok(DomeLight {
            prim_path: self.prim.path().to_string(),
            light_group: c.light_group,
            light_to_world: *to_world,
            intensity: c.intensity,
            exposure: c.exposure,
            color: c.color,
            color_temperature: c.color_temperature,
            texture_file,
            texture_format: read_string(self.prim, "inputs:texture:format", self.t)?
                .unwrap_or_else(|| "automatic".to_string()),
            controls: LightControls {
                shaping: None,
                diffuse: 1.0,
                ..c.controls
            },
        })
    }

    fn sphere_light(
        &mut self,
        to_world: &DMat4,
        motion: Option<TransformMotion>,
    ) -> Result<SphereLight, SceneError> {
        let c = self.common(1.0)?;
        self.untextured("SphereLight")?;
        Ok(SphereLight {
            prim_path: self.prim.path().to_string(),
            light_group: c.light_group.clone(),
            light_to_world: *to_world,
            motion,
            intensity: c.intensity,
            exposure: c.exposure,
            color: c.color,
            normalize: c.normalize,
            color_temperature: c.color_temperature,
            radius: self.length("inputs:radius", 0.5)?,
            treat_as_point: self.bool("treatAsPoint")?.unwrap_or(false),
            lights_interior: self.bool(tokens::LIGHTS_INTERIOR)?.unwrap_or(false),
            controls: c.controls,
        })
    }

    fn rect_light(
        &mut self,
        to_world: &DMat4,
        motion: Option<TransformMotion>,
    ) -> Result<RectLight, SceneError> {
        let c = self.common(1.0)?;
        self.untextured("RectLight")?;
        Ok(RectLight {
            prim_path: self.prim.path().to_string(),
            light_group: c.light_group.clone(),
            light_to_world: *to_world,
            motion,
            intensity: c.intensity,
            exposure: c.exposure,
            color: c.color,
            normalize: c.normalize,
            color_temperature: c.color_temperature,
            width: self.length("inputs:width", 1.0)?,
            height: self.length("inputs:height", 1.0)?,
            controls: c.controls,
        })
    }

    fn disk_light(
        &mut self,
        to_world: &DMat4,
        motion: Option<TransformMotion>,
    ) -> Result<DiskLight, SceneError> {
        let c = self.common(1.0)?;
        self.untextured("DiskLight")?;
        Ok(DiskLight {
            prim_path: self.prim.path().to_string(),
            light_group: c.light_group.clone(),
            light_to_world: *to_world,
            motion,
            intensity: c.intensity,
            exposure: c.exposure,
            color: c.color,
            normalize: c.normalize,
            color_temperature: c.color_temperature,
            radius: self.length("inputs:radius", 0.5)?,
            controls: c.controls,
        })
    }

    fn cylinder_light(
        &mut self,
        to_world: &DMat4,
        motion: Option<TransformMotion>,
    ) -> Result<CylinderLight, SceneError> {
        let c = self.common(1.0)?;
        self.untextured("CylinderLight")?;
        Ok(CylinderLight {
            prim_path: self.prim.path().to_string(),
            light_group: c.light_group.clone(),
            light_to_world: *to_world,
            motion,
            intensity: c.intensity,
            exposure: c.exposure,
            color: c.color,
            normalize: c.normalize,
            color_temperature: c.color_temperature,
            length: self.length("inputs:length", 1.0)?,
            radius: self.length("inputs:radius", 0.5)?,
            treat_as_line: self.bool("treatAsLine")?.unwrap_or(false),
            controls: c.controls,
        })
    }
}

fn read_bool(prim: &Prim, name: &str, time: Option<TimeCode>) -> Result<Option<bool>, SceneError> {
    let Some(value) = read_value(prim, name, time)? else {
        return Ok(None);
    };
    match value {
        Value::Bool(b) => Ok(Some(b)),
        Value::Int(v) => Ok(Some(v != 0)),
        other => Err(wrong_type(prim, name, "a bool", &other)),
    }
}
