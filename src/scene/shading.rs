//! Volume parameters from a bound UsdShade material, for stages written by other
//! tools (no `NimbusVolumeAPI`). Two volume shaders exporters write are understood:
//!
//! - RenderMan's `PxrVolume` (RenderMan for Houdini/Maya/Katana/Blender write it into
//!   USD as `info:id = "PxrVolume"` on the material's `outputs:ri:volume`):
//!   `densityFloatPrimVar` names the density field, `densityFloat` is the extinction
//!   coefficient, `diffuseColor` the single-scattering albedo, `anisotropy` the HG g.
//! - MaterialX `anisotropic_vdf` (`ND_anisotropic_vdf`; Houdini's Karma and MaterialX
//!   exporters): `absorption` and `scattering` coefficients and `anisotropy`, reached
//!   from the material through `volumematerial` / `volume` nodes.
//!
//! Both map exactly onto Nimbus' per-unit-density σa, σs and g; see `docs/usd.md` for
//! the inputs read and their defaults. Only constant inputs (values, or connections to
//! the material's own interface inputs) are read: an input driven by another shader
//! is refused with an error naming it, not silently replaced by a default.

use super::attrs::{prim_error, read_value, shader_id, split_property, SceneError};
use openusd::sdf::{self, Value};
use openusd::usd::{Prim, Stage, TimeCode};

/// Nimbus' volume parameters as a material defines them.
#[derive(Clone, Debug, PartialEq)]
pub struct MaterialVolume {
    /// The shader prim they were read from, and its `info:id`.
    pub shader: String,
    pub shader_id: String,
    /// The `field:*` relationship holding the density.
    pub density_field: String,
    pub density_scale: f64,
    pub absorption: [f64; 3],
    pub scattering: [f64; 3],
    pub anisotropy: f64,
    /// A MaterialX graph driving the coefficients: the density is its value, the
    /// coefficients above are per unit of it.
    pub density_graph: Option<super::materialx_graph::MaterialXDensity>,
    /// A MaterialX `volume`'s emission (its `edf`), when it has one.
    pub emission: Option<super::materialx_graph::MaterialXEmission>,
}

/// Material outputs a volume shader hangs from, by renderer context, most specific
/// first ("" is the universal context).
const VOLUME_OUTPUTS: [&str; 4] = [
    "outputs:ri:volume",
    "outputs:mtlx:volume",
    "outputs:kma:volume",
    "outputs:volume",
];
/// Links followed from a material output to the volume shader (volumematerial →
/// volume → vdf, interface inputs): a bound against connection cycles.
const MAX_HOPS: usize = 8;

/// The material bound to `volume` (its own `material:binding`, else its nearest
/// ancestor's; the `full` purpose before the all-purpose binding), read into volume
/// parameters. `Ok(None)` when nothing is bound or the material has no volume output.
pub fn bound_volume_material(
    stage: &Stage,
    volume: &Prim,
    time: Option<TimeCode>,
) -> Result<Option<MaterialVolume>, SceneError> {
    let Some(material) = bound_material(stage, volume)? else {
        return Ok(None);
    };
    for output in VOLUME_OUTPUTS {
        let attr = material.attribute(output);
        let sources = attr
            .connections()
            .map_err(|e| prim_error(material.path(), format!("{output}: {e}")))?;
        if let Some(source) = sources.first() {
            let mut volume_node = None;
            let shader = volume_shader(stage, &material, source, &mut volume_node)?;
            let mut m = read_shader(&shader, time)?;
            if let Some(volume) = volume_node {
                let network = super::materialx_graph::usd_network(&volume, time)?;
                m.emission =
                    super::materialx_graph::volume_emission(&network, volume.path().as_str())?;
            }
            return Ok(Some(m));
        }
    }
    Ok(None)
}

/// The path of the material bound to `volume` (as [`bound_volume_material`] finds it),
/// whether or not it has a volume output.
pub fn bound_material_path(stage: &Stage, volume: &Prim) -> Result<Option<String>, SceneError> {
    Ok(bound_material(stage, volume)?.map(|m| m.path().to_string()))
}

fn bound_material(stage: &Stage, volume: &Prim) -> Result<Option<Prim>, SceneError> {
    let mut prim = Some(volume.clone());
    while let Some(p) = prim {
        for rel in ["material:binding:full", "material:binding"] {
            let targets = p
                .relationship(rel)
                .targets()
                .map_err(|e| prim_error(p.path(), format!("{rel}: {e}")))?;
            if let Some(target) = targets.first() {
                let material = stage
                    .prim(target.clone())
                    .map_err(|e| prim_error(p.path(), e))?;
                let valid = material
                    .is_valid()
                    .map_err(|e| prim_error(material.path(), e))?;
                if !valid {
                    return Err(prim_error(
                        p.path(),
                        format!("{rel} targets {target}, which does not exist"),
                    ));
                }
                return Ok(Some(material));
            }
        }
        prim = p.parent();
    }
    Ok(None)
}

/// Follows `source` (a material output's connection) to a volume shader Nimbus
/// reads, through MaterialX's `volumematerial` and `volume` nodes; the `volume` node
/// passed (whose `edf` is the emission) goes into `volume_node`.
fn volume_shader(
    stage: &Stage,
    material: &Prim,
    source: &sdf::Path,
    volume_node: &mut Option<Prim>,
) -> Result<Prim, SceneError> {
    let mut source = source.clone();
    for _ in 0..MAX_HOPS {
        let (path, _) = split_property(&source);
        let shader = stage
            .prim(path.clone())
            .map_err(|e| prim_error(material.path(), e))?;
        let id = shader_id(&shader)?;
        let next_input = match id.as_str() {
            "PxrVolume" | "ND_anisotropic_vdf" => return Ok(shader),
            "ND_volumematerial" => "inputs:volumeshader".to_string(),
            "ND_volume" => {
                *volume_node = Some(shader.clone());
                "inputs:vdf".to_string()
            }
            // No id: a NodeGraph (or Material) output forwarding to a shader.
            "" => split_property(&source).1,
            other => {
                return Err(prim_error(
                    shader.path(),
                    format!(
                        "volume shader `{other}` bound through {} is not one Nimbus reads \
                         (PxrVolume, ND_anisotropic_vdf); apply NimbusVolumeAPI instead",
                        material.path()
                    ),
                ))
            }
        };
        let next = shader
            .attribute(next_input.as_str())
            .connections()
            .map_err(|e| prim_error(shader.path(), e))?;
        match next.first() {
            Some(n) if *n != source => source = n.clone(),
            _ => {
                return Err(prim_error(
                    shader.path(),
                    format!(
                        "`{next_input}` is not connected, so {} defines no volume shader",
                        material.path()
                    ),
                ))
            }
        }
    }
    Err(prim_error(
        material.path(),
        "volume output connections do not reach a shader (cycle or too deep)",
    ))
}

fn read_shader(shader: &Prim, time: Option<TimeCode>) -> Result<MaterialVolume, SceneError> {
    let id = shader_id(shader)?;
    let input = |name: &str| constant_input(shader, name, time);
    let base =
        |density_field: String, density_scale, absorption, scattering, anisotropy| MaterialVolume {
            shader: shader.path().to_string(),
            shader_id: id.clone(),
            density_field,
            density_scale,
            absorption,
            scattering,
            anisotropy,
            density_graph: None,
            emission: None,
        };
    if id == "PxrVolume" {
        // RenderMan: extinction `densityFloat` (overridden by the primvar when one is
        // named), albedo `diffuseColor`, so σs = albedo, σa = 1 − albedo per unit of
        // extinction. Nimbus has no homogeneous volumes: without a primvar the
        // `density` field is used, scaled by densityFloat.
        let primvar = input("densityFloatPrimVar")?
            .map(|v| as_string(shader, "densityFloatPrimVar", v))
            .transpose()?
            .filter(|s| !s.is_empty());
        let density_float = input("densityFloat")?
            .map(|v| as_f64(shader, "densityFloat", v))
            .transpose()?
            .unwrap_or(1.0);
        let multiplier = input("densityMultiplier")?
            .map(|v| as_f64(shader, "densityMultiplier", v))
            .transpose()?
            .unwrap_or(1.0);
        let albedo = input("diffuseColor")?
            .map(|v| as_vec3(shader, "diffuseColor", v))
            .transpose()?
            .unwrap_or([1.0; 3]);
        let anisotropy = input("anisotropy")?
            .map(|v| as_f64(shader, "anisotropy", v))
            .transpose()?
            .unwrap_or(0.0);
        let (field, scale) = match primvar {
            Some(name) => (name, multiplier),
            None => ("density".to_string(), multiplier * density_float),
        };
        return Ok(base(
            field,
            scale,
            albedo.map(|a| (1.0 - a).max(0.0)),
            albedo,
            anisotropy,
        ));
    }
    // MaterialX anisotropic_vdf: coefficients per unit density of the `density` field,
    // or per unit of a graph driving them.
    let network = super::materialx_graph::usd_network(shader, time)?;
    if let Some(graph) = super::materialx_graph::vdf_density(&network, shader.path().as_str())? {
        let anisotropy = input("anisotropy")?
            .map(|v| as_f64(shader, "anisotropy", v))
            .transpose()?
            .unwrap_or(0.0);
        let mut m = base(
            graph
                .geomprop
                .clone()
                .unwrap_or_else(|| "density".to_string()),
            1.0,
            graph.absorption,
            graph.scattering,
            anisotropy,
        );
        m.density_graph = Some(graph);
        return Ok(m);
    }
    let absorption = input("absorption")?
        .map(|v| as_vec3(shader, "absorption", v))
        .transpose()?
        .unwrap_or([0.0; 3]);
    let scattering = input("scattering")?
        .map(|v| as_vec3(shader, "scattering", v))
        .transpose()?
        .unwrap_or([0.0; 3]);
    let anisotropy = input("anisotropy")?
        .map(|v| as_f64(shader, "anisotropy", v))
        .transpose()?
        .unwrap_or(0.0);
    Ok(base(
        "density".to_string(),
        1.0,
        absorption,
        scattering,
        anisotropy,
    ))
}

/// The value of `inputs:<name>`: its own value, or the value of the interface input
/// (on a Material or NodeGraph) it is connected to. A connection to a shader output
/// (a texture, a primvar reader) is not a constant: refused.
fn constant_input(
    shader: &Prim,
    name: &str,
    time: Option<TimeCode>,
) -> Result<Option<Value>, SceneError> {
    let stage = shader.stage();
    let mut prim = shader.clone();
    let mut property = format!("inputs:{name}");
    for _ in 0..MAX_HOPS {
        let attr = prim.attribute(property.as_str());
        let sources = attr
            .connections()
            .map_err(|e| prim_error(prim.path(), format!("{property}: {e}")))?;
        let Some(source) = sources.first() else {
            return read_value(&prim, &property, time);
        };
        let (path, source_property) = split_property(source);
        if !source_property.starts_with("inputs:") {
            return Err(prim_error(
                shader.path(),
                format!(
                    "`inputs:{name}` is driven by {source}; Nimbus reads only constant \
                     material inputs (apply NimbusVolumeAPI to set the volume's parameters)"
                ),
            ));
        }
        prim = stage.prim(path).map_err(|e| prim_error(shader.path(), e))?;
        property = source_property;
    }
    Err(prim_error(
        shader.path(),
        format!("`inputs:{name}` connections do not end (cycle or too deep)"),
    ))
}

fn wrong(shader: &Prim, name: &str, expected: &str, v: &Value) -> SceneError {
    prim_error(
        shader.path(),
        format!("`inputs:{name}` should be {expected}, found {v:?}"),
    )
}

fn as_f64(shader: &Prim, name: &str, v: Value) -> Result<f64, SceneError> {
    match v {
        Value::Float(x) => Ok(f64::from(x)),
        Value::Double(x) => Ok(x),
        Value::Half(x) => Ok(f64::from(x)),
        Value::Int(x) => Ok(f64::from(x)),
        other => Err(wrong(shader, name, "a number", &other)),
    }
}

fn as_vec3(shader: &Prim, name: &str, v: Value) -> Result<[f64; 3], SceneError> {
    match v {
        Value::Vec3f(x) => Ok([x.x, x.y, x.z].map(f64::from)),
        Value::Vec3d(x) => Ok([x.x, x.y, x.z]),
        Value::Vec3h(x) => Ok([x.x, x.y, x.z].map(f64::from)),
        // A grey coefficient written as one float.
        Value::Float(x) => Ok([f64::from(x); 3]),
        Value::Double(x) => Ok([x; 3]),
        other => Err(wrong(shader, name, "a colour/vector3", &other)),
    }
}

fn as_string(shader: &Prim, name: &str, v: Value) -> Result<String, SceneError> {
    match v {
        Value::String(s) => Ok(s),
        Value::Token(t) => Ok(t.to_string()),
        other => Err(wrong(shader, name, "a string", &other)),
    }
}
