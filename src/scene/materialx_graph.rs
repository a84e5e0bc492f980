//! MaterialX node graphs driving a volume's density (issue 47), read from UsdShade
//! into a [`Program`].
//!
//! MaterialX has no density input: a volume's coefficients are its `anisotropic_vdf`'s
//! `absorption` and `scattering` colours, and a heterogeneous medium drives them with a
//! graph. Nimbus' media are a density times constant per-unit coefficients, so the two
//! inputs are read as one float graph g(x) times a constant colour each:
//!
//! - an input connected to `ND_multiply_color3FA` (colour × float) with a constant
//!   colour and a float graph, or to `ND_convert_float_color3` of a float graph (colour
//!   1), or to a float graph directly;
//! - both connected inputs must reach the same float output (a constant input must then
//!   be 0); anything else is refused with an error naming the shader and input.
//!
//! Both readers hand the network over as a [`ShaderNetwork`] ([`usd_network`] walks the
//! UsdShade prims; the Hydra delegate copies Hydra's network), and [`vdf_density`]
//! compiles it. The float graph is compiled node by node ([`NODES`] lists the ids read);
//! `ND_position_vector3` is the position in object space, `ND_geompropvalue_float` the
//! value of the volume's field of that name (one field per graph).
//!
//! A MaterialX `volume`'s emission, its `edf`, is read the same way
//! ([`volume_emission`]): a `uniform_edf` whose `color` is a constant colour, a colour
//! times one field, or a colour times a float graph, taken as the source term.

use super::attrs::{prim_error, prim_error_str, read_value, shader_id, split_property, SceneError};
use super::shader_network::{Input, ParamValue, ShaderNetwork, ShaderNode};
use crate::shader::graph::{Binary, Builder, Program, Unary, Value as Reg};
use openusd::sdf::Value;
use openusd::usd::{Prim, TimeCode};
use std::collections::HashMap;

/// A density graph read from a MaterialX volume shader.
#[derive(Clone, Debug, PartialEq)]
pub struct MaterialXDensity {
    pub program: Program,
    /// σa and σs per unit of the graph's value.
    pub absorption: [f64; 3],
    pub scattering: [f64; 3],
    /// The field `ND_geompropvalue_float` reads, if the graph reads one.
    pub geomprop: Option<String>,
}

/// The node ids compiled (float and vector3 variants; `FA`: a float second operand).
pub const NODES: &[&str] = &[
    "ND_position_vector3",
    "ND_constant_float",
    "ND_constant_vector3",
    "ND_geompropvalue_float",
    "ND_noise3d_float",
    "ND_fractal3d_float",
    "ND_cellnoise3d_float",
    "ND_ramplr_float",
    "ND_ramp4_float",
    "ND_add_float",
    "ND_subtract_float",
    "ND_multiply_float",
    "ND_divide_float",
    "ND_min_float",
    "ND_max_float",
    "ND_absval_float",
    "ND_add_vector3",
    "ND_add_vector3FA",
    "ND_subtract_vector3",
    "ND_subtract_vector3FA",
    "ND_multiply_vector3",
    "ND_multiply_vector3FA",
    "ND_clamp_float",
    "ND_smoothstep_float",
    "ND_remap_float",
    "ND_dot_vector3",
    "ND_magnitude_vector3",
];

/// Links followed through node graph outputs and interface inputs: a bound against
/// connection cycles.
const MAX_HOPS: usize = 16;

/// The shader network upstream of `shader` (a UsdShade prim): every node its inputs
/// reach, with NodeGraph outputs and interface inputs (of NodeGraphs and Materials)
/// followed to the node or value behind them.
pub fn usd_network(shader: &Prim, time: Option<TimeCode>) -> Result<ShaderNetwork, SceneError> {
    let mut network = ShaderNetwork::default();
    let mut pending = vec![shader.clone()];
    while let Some(prim) = pending.pop() {
        let path = prim.path().to_string();
        if network.node(&path).is_some() {
            continue;
        }
        let mut node = ShaderNode {
            path,
            id: shader_id(&prim)?,
            inputs: Vec::new(),
        };
        let names = prim
            .authored_property_names()
            .map_err(|e| prim_error(prim.path(), e))?;
        for name in names {
            let Some(input) = name.as_str().strip_prefix("inputs:") else {
                continue;
            };
            let value = match resolve(&prim, name.as_str(), time)? {
                Resolved::Value(None) => continue,
                Resolved::Value(Some(v)) => Input::Value(param_value(&prim, input, v)?),
                Resolved::Output(upstream, output) => {
                    let node = upstream.path().to_string();
                    pending.push(upstream);
                    Input::Connection { node, output }
                }
            };
            node.inputs.push((input.to_string(), value));
        }
        network.nodes.push(node);
    }
    Ok(network)
}

enum Resolved {
    Value(Option<Value>),
    /// A node's output (its prim and the output's name, without `outputs:`).
    Output(Prim, String),
}

/// Follows `property` of `prim` through interface inputs and NodeGraph outputs to a
/// value or a node's output.
fn resolve(prim: &Prim, property: &str, time: Option<TimeCode>) -> Result<Resolved, SceneError> {
    let stage = prim.stage();
    let mut prim = prim.clone();
    let mut property = property.to_string();
    for _ in 0..MAX_HOPS {
        let sources = prim
            .attribute(property.as_str())
            .connections()
            .map_err(|e| prim_error(prim.path(), format!("{property}: {e}")))?;
        let Some(source) = sources.first() else {
            if property.starts_with("outputs:") {
                return Err(prim_error(
                    prim.path(),
                    format!("`{property}` is not connected to a node"),
                ));
            }
            return Ok(Resolved::Value(read_value(&prim, &property, time)?));
        };
        let (path, source_property) = split_property(source);
        let upstream = stage.prim(path).map_err(|e| prim_error(prim.path(), e))?;
        if let Some(output) = source_property.strip_prefix("outputs:") {
            if !shader_id(&upstream)?.is_empty() {
                return Ok(Resolved::Output(upstream, output.to_string()));
            }
        }
        // An interface input, or a NodeGraph's output: follow it.
        prim = upstream;
        property = source_property;
    }
    Err(prim_error(
        prim.path(),
        format!("`{property}` connections do not end (cycle or too deep)"),
    ))
}

fn param_value(prim: &Prim, name: &str, v: Value) -> Result<ParamValue, SceneError> {
    Ok(match v {
        Value::Float(x) => ParamValue::Numbers(vec![f64::from(x)]),
        Value::Double(x) => ParamValue::Numbers(vec![x]),
        Value::Half(x) => ParamValue::Numbers(vec![f64::from(x)]),
        Value::Int(x) => ParamValue::Numbers(vec![f64::from(x)]),
        Value::Bool(x) => ParamValue::Numbers(vec![f64::from(u8::from(x))]),
        // vector2s (a ramp's constant `texcoord`).
        Value::Vec2f(x) => ParamValue::Numbers([x.x, x.y].map(f64::from).to_vec()),
        Value::Vec2d(x) => ParamValue::Numbers(vec![x.x, x.y]),
        Value::Vec2h(x) => ParamValue::Numbers([x.x, x.y].map(f64::from).to_vec()),
        Value::Vec3f(x) => ParamValue::Numbers([x.x, x.y, x.z].map(f64::from).to_vec()),
        Value::Vec3d(x) => ParamValue::Numbers(vec![x.x, x.y, x.z]),
        Value::Vec3h(x) => ParamValue::Numbers([x.x, x.y, x.z].map(f64::from).to_vec()),
        Value::String(s) => ParamValue::Text(s),
        Value::Token(t) => ParamValue::Text(t.to_string()),
        Value::AssetPath(a) => ParamValue::Text(a.as_str().to_string()),
        // Tables (the Blender add-on's ramps).
        Value::FloatVec(v) => ParamValue::Numbers(v.into_iter().map(f64::from).collect()),
        Value::DoubleVec(v) => ParamValue::Numbers(v),
        other => {
            return Err(prim_error(
                prim.path(),
                format!("`inputs:{name}` holds {other:?}, which no node Nimbus compiles takes"),
            ))
        }
    })
}

/// The density graph behind the `anisotropic_vdf` node `vdf` of `network`: its
/// `absorption` and `scattering` read as constant colours times one float graph.
/// `None` when neither is connected to a node.
pub fn vdf_density(
    network: &ShaderNetwork,
    vdf: &str,
) -> Result<Option<MaterialXDensity>, SceneError> {
    let Some(shader) = network.node(vdf) else {
        return Err(prim_error_str(
            vdf,
            "the volume shader is not in its network",
        ));
    };
    let mut reader = GraphReader::new(network);
    let abs = reader.coefficient(shader, "absorption")?;
    let sca = reader.coefficient(shader, "scattering")?;
    let graph = match (&abs, &sca) {
        (Coefficient::Constant(_), Coefficient::Constant(_)) => return Ok(None),
        (Coefficient::Graph(_, a), Coefficient::Graph(_, b)) if a != b => {
            return Err(prim_error_str(
                vdf,
                format!("`inputs:absorption` and `inputs:scattering` are driven by different graphs ({} and {}); Nimbus reads one density graph times a constant colour for each", a.0, b.0),
            ))
        }
        (Coefficient::Graph(_, g), _) | (_, Coefficient::Graph(_, g)) => g.clone(),
    };
    let colour = |c: &Coefficient, name: &str| -> Result<[f64; 3], SceneError> {
        match c {
            Coefficient::Graph(k, _) => Ok(*k),
            Coefficient::Constant(k) if k.iter().all(|&x| x == 0.0) => Ok(*k),
            Coefficient::Constant(_) => Err(prim_error_str(
                vdf,
                format!("`inputs:{name}` is a non-zero constant while the other coefficient is driven by {}; Nimbus needs both proportional to one density graph (multiply the constant by the same graph, or set it to 0)", graph.0),
            )),
        }
    };
    let absorption = colour(&abs, "absorption")?;
    let scattering = colour(&sca, "scattering")?;
    let out = reader.output(&graph)?;
    let program = reader
        .builder
        .finish(out)
        .map_err(|e| prim_error_str(vdf, e))?;
    Ok(Some(MaterialXDensity {
        program,
        absorption,
        scattering,
        geomprop: reader.geomprop,
    }))
}

/// A MaterialX `volume`'s emission: its `edf`, a `uniform_edf` whose `color` is read
/// like a vdf coefficient (a constant colour, or a constant colour times a float graph).
/// MaterialX does not say what a volume's emission is per; Nimbus reads the colour as
/// the source term, radiance per unit length (`EmissionKind::Source`), as Cycles reads
/// an Emission closure in a volume.
#[derive(Clone, Debug, PartialEq)]
pub struct MaterialXEmission {
    /// The edf node: where the emission was read from.
    pub edf: String,
    /// The colour, times the field or the graph below where there is one.
    pub color: [f64; 3],
    /// The volume's field of this name (the float graph is one `ND_geompropvalue_float`).
    pub field: Option<String>,
    /// The colour times a float graph of the position (one reading no field), as a
    /// colour program.
    pub program: Option<Program>,
}

impl MaterialXEmission {
    /// The volume's emission: the source term `color`, times `field` (the volume's
    /// field [`Self::field`] names, resolved by the caller) or the colour program
    /// (in the prim's object space; placed in the world by the caller, as the density
    /// graph is).
    pub fn volume_emission(
        self,
        field: Option<(String, super::description::Field)>,
    ) -> super::description::VolumeEmission {
        let source = format!("{} (ND_uniform_edf)", self.edf);
        super::description::VolumeEmission {
            emission: field,
            emission_color: self.color,
            emission_scale: 1.0,
            kind: crate::volume::emission::EmissionKind::Source,
            color_graph: self
                .program
                .map(|program| super::description::DensityGraph {
                    program,
                    shading_to_world: glam::DMat4::IDENTITY,
                    source,
                }),
            ..Default::default()
        }
    }
}

/// The emission of the MaterialX `volume` node at `volume`: `None` when its `edf` is
/// not connected or emits nothing (a black colour). An edf other than `uniform_edf`, a
/// colour Nimbus cannot read as a colour times a float graph, or a graph reading a
/// field anywhere but as the whole graph is an error naming the node.
pub fn volume_emission(
    network: &ShaderNetwork,
    volume: &str,
) -> Result<Option<MaterialXEmission>, SceneError> {
    let Some(node) = network.node(volume) else {
        return Err(prim_error_str(
            volume,
            "the volume node is not in its network",
        ));
    };
    let Source::Output((edf_path, _)) = GraphReader::input(node, "edf") else {
        return Ok(None);
    };
    let Some(edf) = network.node(&edf_path) else {
        return Err(prim_error_str(&edf_path, "the edf is not in its network"));
    };
    if edf.id != "ND_uniform_edf" {
        return Err(prim_error_str(
            &edf.path,
            format!(
                "`{}` drives `inputs:edf` of {volume}; Nimbus reads a volume's emission from ND_uniform_edf only",
                edf.id
            ),
        ));
    }
    let mut reader = GraphReader::new(network);
    // MaterialX's default colour is white.
    let colour = match GraphReader::input(edf, "color") {
        Source::Value(None) => Coefficient::Constant([1.0; 3]),
        _ => reader.coefficient(edf, "color")?,
    };
    let emission = |color, field, program| MaterialXEmission {
        edf: edf.path.clone(),
        color,
        field,
        program,
    };
    let (k, graph) = match colour {
        Coefficient::Constant(k) if k.iter().all(|&c| c == 0.0) => return Ok(None),
        Coefficient::Constant(k) => return Ok(Some(emission(k, None, None))),
        Coefficient::Graph(k, graph) => (k, graph),
    };
    let node = reader.node(&graph.0)?;
    if node.id == "ND_geompropvalue_float" {
        let name = GraphReader::text(node, "geomprop")?.unwrap_or_default();
        return Ok(Some(emission(k, Some(name), None)));
    }
    let g = reader.output(&graph)?;
    if let Some(field) = &reader.geomprop {
        return Err(prim_error_str(
            &edf.path,
            format!("its colour's graph ({}) reads the field `{field}` inside it; Nimbus reads an emission field only as a colour times one ND_geompropvalue_float", graph.0),
        ));
    }
    let err = |e| prim_error_str(&edf.path, e);
    let k32 = k.map(|c| c as f32);
    let kv = reader.builder.vector3(k32).map_err(err)?;
    let g3 = reader.builder.splat3(g).map_err(err)?;
    let rgb = reader.builder.binary(Binary::Mul, kv, g3).map_err(err)?;
    let program = reader.builder.finish_rgb(rgb).map_err(err)?;
    Ok(Some(emission(k, None, Some(program))))
}

/// A node output: the node's path and the output's name.
type Output = (String, String);

/// A vdf coefficient: a constant colour, or a constant colour times a float graph
/// output.
enum Coefficient {
    Constant([f64; 3]),
    Graph([f64; 3], Output),
}

struct GraphReader<'a> {
    network: &'a ShaderNetwork,
    builder: Builder,
    /// Outputs compiled already (a graph is a DAG: a shared node is compiled once).
    done: HashMap<Output, Reg>,
    geomprop: Option<String>,
    depth: usize,
}

/// An input as the compiler sees it: a value (`None` when unauthored) or a node output.
enum Source<'a> {
    Value(Option<&'a ParamValue>),
    Output(Output),
}

impl<'a> GraphReader<'a> {
    fn node(&self, path: &str) -> Result<&'a ShaderNode, SceneError> {
        self.network.node(path).ok_or_else(|| {
            prim_error_str(
                path,
                "a connection names this node, which is not in the material's network",
            )
        })
    }

    fn new(network: &'a ShaderNetwork) -> GraphReader<'a> {
        GraphReader {
            network,
            builder: Builder::default(),
            done: HashMap::new(),
            geomprop: None,
            depth: 0,
        }
    }

    fn input<'n>(node: &'n ShaderNode, name: &str) -> Source<'n> {
        match node.input(name) {
            None => Source::Value(None),
            Some(Input::Value(v)) => Source::Value(Some(v)),
            Some(Input::Connection { node, output }) => {
                Source::Output((node.clone(), output.clone()))
            }
        }
    }

    fn coefficient(&mut self, vdf: &'a ShaderNode, name: &str) -> Result<Coefficient, SceneError> {
        let source = match Self::input(vdf, name) {
            Source::Value(v) => {
                return Ok(Coefficient::Constant(match v {
                    None => [0.0; 3],
                    Some(v) => colour(vdf, name, v)?,
                }))
            }
            Source::Output(o) => o,
        };
        let node = self.node(&source.0)?;
        match node.id.as_str() {
            "ND_multiply_color3FA" => {
                let Source::Value(k) = Self::input(node, "in1") else {
                    return Err(prim_error_str(
                        &node.path,
                        "`inputs:in1` (the colour) must be a constant for Nimbus to read the graph as a density times a colour",
                    ));
                };
                let k = k.map(|v| colour(node, "in1", v)).transpose()?.unwrap_or([0.0; 3]);
                match Self::input(node, "in2") {
                    Source::Output(g) => Ok(Coefficient::Graph(k, g)),
                    Source::Value(v) => {
                        let s = v.map(|v| number(node, "in2", v)).transpose()?.unwrap_or(1.0);
                        Ok(Coefficient::Constant(k.map(|c| c * s)))
                    }
                }
            }
            "ND_convert_float_color3" => match Self::input(node, "in") {
                Source::Output(g) => Ok(Coefficient::Graph([1.0; 3], g)),
                Source::Value(v) => {
                    let s = v.map(|v| number(node, "in", v)).transpose()?.unwrap_or(0.0);
                    Ok(Coefficient::Constant([s; 3]))
                }
            },
            id if id.ends_with("_float") => Ok(Coefficient::Graph([1.0; 3], source)),
            id => Err(prim_error_str(
                &node.path,
                format!("`{id}` drives `inputs:{name}` of {}; Nimbus reads a float graph, a float graph converted to color3, or a constant colour times a float graph (ND_multiply_color3FA)", vdf.path),
            )),
        }
    }

    /// The value of a node output (compiled once).
    fn output(&mut self, output: &Output) -> Result<Reg, SceneError> {
        if let Some(v) = self.done.get(output) {
            return Ok(*v);
        }
        self.depth += 1;
        if self.depth > 256 {
            return Err(prim_error_str(
                &output.0,
                "the graph is too deep (a cycle?)",
            ));
        }
        let node = self.node(&output.0)?;
        let v = self.compile(node)?;
        self.depth -= 1;
        self.done.insert(output.clone(), v);
        Ok(v)
    }

    /// A float input of `node` (its default when unauthored).
    fn float(&mut self, node: &ShaderNode, name: &str, default: f32) -> Result<Reg, SceneError> {
        match Self::input(node, name) {
            Source::Output(o) => self.output(&o),
            Source::Value(v) => {
                let x = v
                    .map(|v| number(node, name, v))
                    .transpose()?
                    .unwrap_or(default as f64);
                self.builder.node(&node.path);
                self.builder
                    .constant(x as f32)
                    .map_err(|e| prim_error_str(&node.path, e))
            }
        }
    }

    /// A constant input (one that decides the program's shape, such as octaves).
    fn constant(&mut self, node: &ShaderNode, name: &str, default: f64) -> Result<f64, SceneError> {
        match Self::input(node, name) {
            Source::Output(o) => Err(prim_error_str(
                &node.path,
                format!(
                    "`inputs:{name}` is driven by {}.outputs:{}; Nimbus needs it constant",
                    o.0, o.1
                ),
            )),
            Source::Value(v) => Ok(v
                .map(|v| number(node, name, v))
                .transpose()?
                .unwrap_or(default)),
        }
    }

    /// A vector3 input; a `None` default is the object-space position.
    fn vector3(
        &mut self,
        node: &ShaderNode,
        name: &str,
        default: Option<[f32; 3]>,
    ) -> Result<Reg, SceneError> {
        let err = |e| prim_error_str(&node.path, e);
        match Self::input(node, name) {
            Source::Output(o) => self.output(&o),
            Source::Value(Some(v)) => {
                let c = colour(node, name, v)?;
                self.builder.node(&node.path);
                self.builder.vector3(c.map(|x| x as f32)).map_err(err)
            }
            Source::Value(None) => match default {
                Some(c) => self.builder.vector3(c).map_err(err),
                None => Ok(self.builder.position()),
            },
        }
    }

    /// An operand of an arithmetic node: float or vector3 by the id's type suffix.
    fn operand(
        &mut self,
        node: &ShaderNode,
        name: &str,
        vector: bool,
        default: f32,
    ) -> Result<Reg, SceneError> {
        if vector {
            self.vector3(node, name, Some([default; 3]))
        } else {
            self.float(node, name, default)
        }
    }

    /// The two floats of a ramp's `texcoord` (a vector2): a constant, or an
    /// `ND_combine2_vector2` of two float graphs (Nimbus has no vector2 values: that node
    /// is read here, as the texcoord's two components). Unconnected, MaterialX reads the
    /// `UV0` geometric property, which a volume does not have: refused, naming the node.
    fn texcoord(&mut self, node: &ShaderNode) -> Result<(Reg, Reg), SceneError> {
        let at = |e| prim_error_str(&node.path, e);
        match Self::input(node, "texcoord") {
            Source::Value(None) => Err(prim_error_str(
                &node.path,
                format!("`{}` reads `inputs:texcoord`, which defaults to the UV0 texture coordinates; volumes have none, so Nimbus needs it connected to ND_combine2_vector2 of float graphs (e.g. components of the position) or set to a constant", node.id),
            )),
            Source::Value(Some(ParamValue::Numbers(v))) if v.len() == 2 => {
                self.builder.node(&node.path);
                let s = self.builder.constant(v[0] as f32).map_err(at)?;
                let t = self.builder.constant(v[1] as f32).map_err(at)?;
                Ok((s, t))
            }
            Source::Value(Some(other)) => Err(prim_error_str(
                &node.path,
                format!("`inputs:texcoord` should be a vector2, found {other:?}"),
            )),
            Source::Output(o) => {
                let upstream = self.node(&o.0)?;
                if upstream.id != "ND_combine2_vector2" {
                    return Err(prim_error_str(
                        &node.path,
                        format!("`inputs:texcoord` of `{}` is driven by `{}` ({}); Nimbus has no vector2 values and reads a texcoord only from ND_combine2_vector2 of two float graphs, or a constant", node.id, upstream.id, upstream.path),
                    ));
                }
                let s = self.float(upstream, "in1", 0.0)?;
                let t = self.float(upstream, "in2", 0.0)?;
                Ok((s, t))
            }
        }
    }

    fn text(node: &ShaderNode, name: &str) -> Result<Option<String>, SceneError> {
        match Self::input(node, name) {
            Source::Value(Some(ParamValue::Text(t))) => Ok(Some(t.clone())),
            Source::Value(None) => Ok(None),
            _ => Err(prim_error_str(
                &node.path,
                format!("`inputs:{name}` should be a constant string"),
            )),
        }
    }

    fn compile(&mut self, node: &ShaderNode) -> Result<Reg, SceneError> {
        let id = node.id.as_str();
        let at = node.path.clone();
        let err = |e: crate::shader::graph::GraphError| prim_error_str(&at, e);
        let (op, ty) = id
            .strip_prefix("ND_")
            .and_then(|rest| rest.rsplit_once('_'))
            .unwrap_or(("", ""));
        let vector = ty.starts_with("vector3");
        let fa = ty.ends_with("FA");
        if !NODES.contains(&id) {
            return Err(prim_error_str(
                &node.path,
                format!(
                    "node `{id}` is not one Nimbus compiles into a density graph (it reads: {})",
                    NODES.join(", ")
                ),
            ));
        }
        let v = match op {
            "position" => {
                let space = Self::text(node, "space")?.unwrap_or_else(|| "object".to_string());
                if space != "object" && space != "model" {
                    return Err(prim_error_str(
                        &node.path,
                        format!("`inputs:space` = \"{space}\": Nimbus reads positions in object (model) space only"),
                    ));
                }
                self.builder.position()
            }
            "constant" if vector => self.vector3(node, "value", Some([0.0; 3]))?,
            "constant" => self.float(node, "value", 0.0)?,
            "geompropvalue" => {
                let name = Self::text(node, "geomprop")?.unwrap_or_default();
                match &self.geomprop {
                    Some(g) if *g != name => {
                        return Err(prim_error_str(
                            &node.path,
                            format!("reads `{name}` where the graph already reads `{g}`; Nimbus reads one field per density graph"),
                        ))
                    }
                    _ => self.geomprop = Some(name),
                }
                self.builder.attribute()
            }
            "noise3d" => {
                let amplitude = self.float(node, "amplitude", 1.0)?;
                let pivot = self.float(node, "pivot", 0.0)?;
                let p = self.vector3(node, "position", None)?;
                self.builder.node(&node.path);
                self.builder.mx_noise3d(p, amplitude, pivot).map_err(err)?
            }
            "fractal3d" => {
                let amplitude = self.float(node, "amplitude", 1.0)?;
                let octaves = self.constant(node, "octaves", 3.0)?;
                let lacunarity = self.constant(node, "lacunarity", 2.0)?;
                let diminish = self.constant(node, "diminish", 0.5)?;
                let p = self.vector3(node, "position", None)?;
                self.builder.node(&node.path);
                self.builder
                    .mx_fractal3d(
                        p,
                        amplitude,
                        octaves as i32,
                        lacunarity as f32,
                        diminish as f32,
                    )
                    .map_err(err)?
            }
            "cellnoise3d" => {
                let p = self.vector3(node, "position", None)?;
                self.builder.node(&node.path);
                self.builder.mx_cellnoise3d(p).map_err(err)?
            }
            // mix(valuel, valuer, clamp(texcoord.x, 0, 1)) (mx_ramplr_float.glsl).
            "ramplr" => {
                let l = self.float(node, "valuel", 0.0)?;
                let r = self.float(node, "valuer", 0.0)?;
                let (s, _) = self.texcoord(node)?;
                self.builder.node(&node.path);
                let zero = self.builder.constant(0.0).map_err(err)?;
                let one = self.builder.constant(1.0).map_err(err)?;
                let s = self.builder.clamp(s, zero, one).map_err(err)?;
                self.builder.mix(l, r, s).map_err(err)?
            }
            // NG_ramp4_float: texcoord clamped to [0, 1]², then
            // mix(mix(valuebl, valuebr, s), mix(valuetl, valuetr, s), t).
            "ramp4" => {
                let tl = self.float(node, "valuetl", 0.0)?;
                let tr = self.float(node, "valuetr", 0.0)?;
                let bl = self.float(node, "valuebl", 0.0)?;
                let br = self.float(node, "valuebr", 0.0)?;
                let (s, t) = self.texcoord(node)?;
                self.builder.node(&node.path);
                let zero = self.builder.constant(0.0).map_err(err)?;
                let one = self.builder.constant(1.0).map_err(err)?;
                let s = self.builder.clamp(s, zero, one).map_err(err)?;
                let t = self.builder.clamp(t, zero, one).map_err(err)?;
                let top = self.builder.mix(tl, tr, s).map_err(err)?;
                let bottom = self.builder.mix(bl, br, s).map_err(err)?;
                self.builder.mix(bottom, top, t).map_err(err)?
            }
            "add" | "subtract" | "multiply" | "divide" | "min" | "max" => {
                let unit = if op == "multiply" || op == "divide" {
                    1.0
                } else {
                    0.0
                };
                let a = self.operand(node, "in1", vector, 0.0)?;
                let b = self.operand(node, "in2", vector && !fa, unit)?;
                let op = match op {
                    "add" => Binary::Add,
                    "subtract" => Binary::Sub,
                    "multiply" => Binary::Mul,
                    "divide" => Binary::Div,
                    "min" => Binary::Min,
                    _ => Binary::Max,
                };
                self.builder.node(&node.path);
                self.builder.binary(op, a, b).map_err(err)?
            }
            "absval" => {
                let a = self.float(node, "in", 0.0)?;
                self.builder.node(&node.path);
                self.builder.unary(Unary::Abs, a).map_err(err)?
            }
            "clamp" | "smoothstep" => {
                let x = self.float(node, "in", 0.0)?;
                let lo = self.float(node, "low", 0.0)?;
                let hi = self.float(node, "high", 1.0)?;
                self.builder.node(&node.path);
                match op {
                    "clamp" => self.builder.clamp(x, lo, hi),
                    _ => self.builder.smoothstep(x, lo, hi),
                }
                .map_err(err)?
            }
            "remap" => {
                let x = self.float(node, "in", 0.0)?;
                let il = self.float(node, "inlow", 0.0)?;
                let ih = self.float(node, "inhigh", 1.0)?;
                let ol = self.float(node, "outlow", 0.0)?;
                let oh = self.float(node, "outhigh", 1.0)?;
                self.builder.node(&node.path);
                self.builder.remap(x, il, ih, ol, oh).map_err(err)?
            }
            "dot" => {
                let a = self.vector3(node, "in1", Some([0.0; 3]))?;
                let b = self.vector3(node, "in2", Some([0.0; 3]))?;
                self.builder.node(&node.path);
                self.builder.dot(a, b).map_err(err)?
            }
            "magnitude" => {
                let a = self.vector3(node, "in", Some([0.0; 3]))?;
                self.builder.node(&node.path);
                self.builder.magnitude(a).map_err(err)?
            }
            _ => unreachable!("every id of NODES is compiled above"),
        };
        Ok(v)
    }
}

pub(super) fn number(node: &ShaderNode, name: &str, v: &ParamValue) -> Result<f64, SceneError> {
    match v {
        ParamValue::Numbers(x) if x.len() == 1 => Ok(x[0]),
        other => Err(prim_error_str(
            &node.path,
            format!("`inputs:{name}` should be a number, found {other:?}"),
        )),
    }
}

pub(super) fn colour(
    node: &ShaderNode,
    name: &str,
    v: &ParamValue,
) -> Result<[f64; 3], SceneError> {
    match v {
        ParamValue::Numbers(x) if x.len() == 3 => Ok([x[0], x[1], x[2]]),
        // A grey value written as one number.
        ParamValue::Numbers(x) if x.len() == 1 => Ok([x[0]; 3]),
        other => Err(prim_error_str(
            &node.path,
            format!("`inputs:{name}` should be a colour/vector3, found {other:?}"),
        )),
    }
}
