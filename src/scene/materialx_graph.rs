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
//! The float graph is compiled node by node ([`NODES`] lists the `info:id`s read);
//! `ND_position_vector3` is the position in object space, `ND_geompropvalue_float` the
//! value of the volume's field of that name (one field per graph).

use super::attrs::{prim_error, read_value, SceneError};
use crate::shader::graph::{Binary, Builder, Program, Unary, Value as Reg};
use openusd::sdf::{self, Value};
use openusd::usd::{Prim, Stage, TimeCode};
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

/// The density graph behind an `anisotropic_vdf`'s `absorption` and `scattering`, or
/// `None` when neither is connected to a node.
pub fn vdf_density(
    shader: &Prim,
    time: Option<TimeCode>,
) -> Result<Option<MaterialXDensity>, SceneError> {
    let mut reader = GraphReader {
        stage: shader.stage(),
        time,
        builder: Builder::default(),
        done: HashMap::new(),
        geomprop: None,
        depth: 0,
    };
    let abs = reader.coefficient(shader, "absorption")?;
    let sca = reader.coefficient(shader, "scattering")?;
    let graph = match (&abs, &sca) {
        (Coefficient::Constant(_), Coefficient::Constant(_)) => return Ok(None),
        (Coefficient::Graph(_, a), Coefficient::Graph(_, b)) if a != b => {
            return Err(prim_error(
                shader.path(),
                format!("`inputs:absorption` and `inputs:scattering` are driven by different graphs ({a} and {b}); Nimbus reads one density graph times a constant colour for each"),
            ))
        }
        (Coefficient::Graph(_, g), _) | (_, Coefficient::Graph(_, g)) => g.clone(),
    };
    let colour = |c: &Coefficient, name: &str| -> Result<[f64; 3], SceneError> {
        match c {
            Coefficient::Graph(k, _) => Ok(*k),
            Coefficient::Constant(k) if k.iter().all(|&x| x == 0.0) => Ok(*k),
            Coefficient::Constant(_) => Err(prim_error(
                shader.path(),
                format!("`inputs:{name}` is a non-zero constant while the other coefficient is driven by {graph}; Nimbus needs both proportional to one density graph (multiply the constant by the same graph, or set it to 0)"),
            )),
        }
    };
    let absorption = colour(&abs, "absorption")?;
    let scattering = colour(&sca, "scattering")?;
    let out = reader.source(&graph)?;
    let program = reader
        .builder
        .finish(out)
        .map_err(|e| prim_error(shader.path(), e))?;
    Ok(Some(MaterialXDensity {
        program,
        absorption,
        scattering,
        geomprop: reader.geomprop,
    }))
}

/// A vdf coefficient: a constant colour, or a constant colour times the float graph
/// output named by its path.
enum Coefficient {
    Constant([f64; 3]),
    Graph([f64; 3], sdf::Path),
}

struct GraphReader<'a> {
    stage: &'a Stage,
    time: Option<TimeCode>,
    builder: Builder,
    /// Outputs compiled already (a graph is a DAG: a shared node is compiled once).
    done: HashMap<String, Reg>,
    geomprop: Option<String>,
    depth: usize,
}

impl GraphReader<'_> {
    fn prim(&self, path: &sdf::Path) -> Result<Prim, SceneError> {
        self.stage
            .prim(path.prim_path())
            .map_err(|e| prim_error(path, e))
    }

    /// Where `inputs:<name>` of `prim` gets its value: its own value, an interface
    /// input's (followed up), or a node output (returned as `Err(path)` of that output).
    fn input(
        &self,
        prim: &Prim,
        name: &str,
    ) -> Result<Result<Option<Value>, sdf::Path>, SceneError> {
        let mut prim = prim.clone();
        let mut property = format!("inputs:{name}");
        for _ in 0..MAX_HOPS {
            let sources = prim
                .attribute(property.as_str())
                .connections()
                .map_err(|e| prim_error(prim.path(), format!("{property}: {e}")))?;
            let Some(source) = sources.first() else {
                return Ok(Ok(read_value(&prim, &property, self.time)?));
            };
            let (_, source_property) = split(source);
            if !source_property.starts_with("inputs:") {
                return Ok(Err(source.clone()));
            }
            prim = self.prim(source)?;
            property = source_property;
        }
        Err(prim_error(
            prim.path(),
            format!("`{property}` connections do not end (cycle or too deep)"),
        ))
    }

    fn coefficient(&mut self, vdf: &Prim, name: &str) -> Result<Coefficient, SceneError> {
        let source = match self.input(vdf, name)? {
            Ok(v) => {
                return Ok(Coefficient::Constant(match v {
                    None => [0.0; 3],
                    Some(v) => colour(vdf, name, v)?,
                }))
            }
            Err(source) => source,
        };
        let source = self.through_node_graphs(source)?;
        let node = self.prim(&source)?;
        let id = node_id(&node)?;
        match id.as_str() {
            "ND_multiply_color3FA" => {
                let k = match self.input(&node, "in1")? {
                    Ok(v) => v.map(|v| colour(&node, "in1", v)).transpose()?,
                    Err(_) => None,
                };
                let Some(k) = k else {
                    return Err(prim_error(
                        node.path(),
                        "`inputs:in1` (the colour) must be a constant for Nimbus to read the graph as a density times a colour",
                    ));
                };
                match self.input(&node, "in2")? {
                    Err(g) => Ok(Coefficient::Graph(k, self.through_node_graphs(g)?)),
                    Ok(v) => {
                        let s = v.map(|v| number(&node, "in2", v)).transpose()?.unwrap_or(1.0);
                        Ok(Coefficient::Constant(k.map(|c| c * s)))
                    }
                }
            }
            "ND_convert_float_color3" => match self.input(&node, "in")? {
                Err(g) => Ok(Coefficient::Graph([1.0; 3], self.through_node_graphs(g)?)),
                Ok(v) => {
                    let s = v.map(|v| number(&node, "in", v)).transpose()?.unwrap_or(0.0);
                    Ok(Coefficient::Constant([s; 3]))
                }
            },
            _ if id.ends_with("_float") => Ok(Coefficient::Graph([1.0; 3], source)),
            _ => Err(prim_error(
                node.path(),
                format!("`{id}` drives `inputs:{name}` of {}; Nimbus reads a float graph, a float graph converted to color3, or a constant colour times a float graph (ND_multiply_color3FA)", vdf.path()),
            )),
        }
    }

    /// Follows a connection into a NodeGraph's output to the node behind it.
    fn through_node_graphs(&self, mut source: sdf::Path) -> Result<sdf::Path, SceneError> {
        for _ in 0..MAX_HOPS {
            let prim = self.prim(&source)?;
            if !node_id(&prim)?.is_empty() {
                return Ok(source);
            }
            let (_, property) = split(&source);
            let next = prim
                .attribute(property.as_str())
                .connections()
                .map_err(|e| prim_error(prim.path(), e))?;
            match next.first() {
                Some(n) => source = n.clone(),
                None => {
                    return Err(prim_error(
                        prim.path(),
                        format!("`{property}` is not connected to a node"),
                    ))
                }
            }
        }
        Err(prim_error(
            &source,
            "node graph connections do not end (cycle or too deep)",
        ))
    }

    /// The value of a node output (compiled once).
    fn source(&mut self, source: &sdf::Path) -> Result<Reg, SceneError> {
        let source = self.through_node_graphs(source.clone())?;
        if let Some(v) = self.done.get(source.as_str()) {
            return Ok(*v);
        }
        self.depth += 1;
        if self.depth > 256 {
            return Err(prim_error(&source, "the graph is too deep (a cycle?)"));
        }
        let node = self.prim(&source)?;
        let v = self.node(&node)?;
        self.depth -= 1;
        self.done.insert(source.as_str().to_string(), v);
        Ok(v)
    }

    /// A float input of `node` (its default when unauthored).
    fn float(&mut self, node: &Prim, name: &str, default: f32) -> Result<Reg, SceneError> {
        match self.input(node, name)? {
            Err(source) => self.source(&source),
            Ok(v) => {
                let x = v
                    .map(|v| number(node, name, v))
                    .transpose()?
                    .unwrap_or(default as f64);
                self.builder.node(node.path().as_str());
                self.builder
                    .constant(x as f32)
                    .map_err(|e| prim_error(node.path(), e))
            }
        }
    }

    /// A constant float input (one that decides the program's shape, such as octaves).
    fn constant(&mut self, node: &Prim, name: &str, default: f64) -> Result<f64, SceneError> {
        match self.input(node, name)? {
            Err(source) => Err(prim_error(
                node.path(),
                format!("`inputs:{name}` is driven by {source}; Nimbus needs it constant"),
            )),
            Ok(v) => Ok(v
                .map(|v| number(node, name, v))
                .transpose()?
                .unwrap_or(default)),
        }
    }

    /// A vector3 input; `None` default = the object-space position.
    fn vector3(
        &mut self,
        node: &Prim,
        name: &str,
        default: Option<[f32; 3]>,
    ) -> Result<Reg, SceneError> {
        match self.input(node, name)? {
            Err(source) => self.source(&source),
            Ok(Some(v)) => {
                let c = colour(node, name, v)?;
                self.builder.node(node.path().as_str());
                self.builder
                    .vector3(c.map(|x| x as f32))
                    .map_err(|e| prim_error(node.path(), e))
            }
            Ok(None) => match default {
                Some(c) => self
                    .builder
                    .vector3(c)
                    .map_err(|e| prim_error(node.path(), e)),
                None => Ok(self.builder.position()),
            },
        }
    }

    /// An operand of an arithmetic node: float or vector3 by the id's type suffix.
    fn operand(
        &mut self,
        node: &Prim,
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

    fn node(&mut self, node: &Prim) -> Result<Reg, SceneError> {
        let id = node_id(node)?;
        let err = |e: crate::shader::graph::GraphError| prim_error(node.path(), e);
        let (op, ty) = id
            .strip_prefix("ND_")
            .and_then(|rest| rest.rsplit_once('_'))
            .unwrap_or(("", ""));
        let vector = ty.starts_with("vector3");
        let fa = ty.ends_with("FA");
        if !NODES.contains(&id.as_str()) {
            return Err(prim_error(
                node.path(),
                format!(
                    "node `{id}` is not one Nimbus compiles into a density graph (it reads: {})",
                    NODES.join(", ")
                ),
            ));
        }
        let v = match op {
            "position" => {
                let space = match self.input(node, "space")? {
                    Ok(Some(v)) => string(node, "space", v)?,
                    _ => "object".to_string(),
                };
                if space != "object" && space != "model" {
                    return Err(prim_error(
                        node.path(),
                        format!("`inputs:space` = \"{space}\": Nimbus reads positions in object (model) space only"),
                    ));
                }
                self.builder.position()
            }
            "constant" if vector => self.vector3(node, "value", Some([0.0; 3]))?,
            "constant" => self.float(node, "value", 0.0)?,
            "geompropvalue" => {
                let name = match self.input(node, "geomprop")? {
                    Ok(Some(v)) => string(node, "geomprop", v)?,
                    _ => String::new(),
                };
                match &self.geomprop {
                    Some(g) if *g != name => {
                        return Err(prim_error(
                            node.path(),
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
                self.builder.node(node.path().as_str());
                self.builder.mx_noise3d(p, amplitude, pivot).map_err(err)?
            }
            "fractal3d" => {
                let amplitude = self.float(node, "amplitude", 1.0)?;
                let octaves = self.constant(node, "octaves", 3.0)?;
                let lacunarity = self.constant(node, "lacunarity", 2.0)?;
                let diminish = self.constant(node, "diminish", 0.5)?;
                let p = self.vector3(node, "position", None)?;
                self.builder.node(node.path().as_str());
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
                self.builder.node(node.path().as_str());
                self.builder.binary(op, a, b).map_err(err)?
            }
            "absval" => {
                let a = self.float(node, "in", 0.0)?;
                self.builder.node(node.path().as_str());
                self.builder.unary(Unary::Abs, a).map_err(err)?
            }
            "clamp" | "smoothstep" => {
                let x = self.float(node, "in", 0.0)?;
                let lo = self.float(node, "low", 0.0)?;
                let hi = self.float(node, "high", 1.0)?;
                self.builder.node(node.path().as_str());
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
                self.builder.node(node.path().as_str());
                self.builder.remap(x, il, ih, ol, oh).map_err(err)?
            }
            "dot" => {
                let a = self.vector3(node, "in1", Some([0.0; 3]))?;
                let b = self.vector3(node, "in2", Some([0.0; 3]))?;
                self.builder.node(node.path().as_str());
                self.builder.dot(a, b).map_err(err)?
            }
            "magnitude" => {
                let a = self.vector3(node, "in", Some([0.0; 3]))?;
                self.builder.node(node.path().as_str());
                self.builder.magnitude(a).map_err(err)?
            }
            _ => unreachable!("every id of NODES is compiled above"),
        };
        Ok(v)
    }
}

fn split(path: &sdf::Path) -> (sdf::Path, String) {
    let prim = path.prim_path();
    let property = path
        .as_str()
        .strip_prefix(prim.as_str())
        .and_then(|rest| rest.strip_prefix('.'))
        .unwrap_or_default()
        .to_string();
    (prim, property)
}

fn node_id(prim: &Prim) -> Result<String, SceneError> {
    Ok(super::attrs::read_string(prim, "info:id", None)?.unwrap_or_default())
}

fn number(node: &Prim, name: &str, v: Value) -> Result<f64, SceneError> {
    match v {
        Value::Float(x) => Ok(f64::from(x)),
        Value::Double(x) => Ok(x),
        Value::Half(x) => Ok(f64::from(x)),
        Value::Int(x) => Ok(f64::from(x)),
        other => Err(prim_error(
            node.path(),
            format!("`inputs:{name}` should be a number, found {other:?}"),
        )),
    }
}

fn colour(node: &Prim, name: &str, v: Value) -> Result<[f64; 3], SceneError> {
    match v {
        Value::Vec3f(x) => Ok([x.x, x.y, x.z].map(f64::from)),
        Value::Vec3d(x) => Ok([x.x, x.y, x.z]),
        Value::Vec3h(x) => Ok([x.x, x.y, x.z].map(f64::from)),
        Value::Float(x) => Ok([f64::from(x); 3]),
        Value::Double(x) => Ok([x; 3]),
        other => Err(prim_error(
            node.path(),
            format!("`inputs:{name}` should be a colour/vector3, found {other:?}"),
        )),
    }
}

fn string(node: &Prim, name: &str, v: Value) -> Result<String, SceneError> {
    match v {
        Value::String(s) => Ok(s),
        Value::Token(t) => Ok(t.to_string()),
        other => Err(prim_error(
            node.path(),
            format!("`inputs:{name}` should be a string, found {other:?}"),
        )),
    }
}
