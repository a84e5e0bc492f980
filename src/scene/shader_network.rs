//! A material's shader network as every reader hands it over: nodes with an id and
//! inputs that hold a value or connect to another node's output. The USD reader walks
//! UsdShade prims into it (node graphs and interface inputs resolved); the Hydra
//! delegate copies Hydra's material network into it. [`super::materialx_graph`]
//! compiles a density graph from it, the same way for both.

/// An input's value.
#[derive(Clone, Debug, PartialEq)]
pub enum ParamValue {
    /// A number or a tuple (a colour, a vector).
    Numbers(Vec<f64>),
    /// A string or a token.
    Text(String),
}

/// Where an input's value comes from.
#[derive(Clone, Debug, PartialEq)]
pub enum Input {
    Value(ParamValue),
    /// The output `output` of the node at path `node`.
    Connection {
        node: String,
        output: String,
    },
}

#[derive(Clone, Debug, PartialEq)]
pub struct ShaderNode {
    /// The node's prim path (for messages, and what connections name).
    pub path: String,
    /// `info:id` (USD) or the node's identifier (Hydra).
    pub id: String,
    /// Authored inputs by name (without `inputs:`); unauthored ones take the node
    /// definition's defaults.
    pub inputs: Vec<(String, Input)>,
}

impl ShaderNode {
    pub fn input(&self, name: &str) -> Option<&Input> {
        self.inputs.iter().find(|(n, _)| n == name).map(|(_, i)| i)
    }
}

#[derive(Clone, Debug, Default, PartialEq)]
pub struct ShaderNetwork {
    pub nodes: Vec<ShaderNode>,
}

impl ShaderNetwork {
    pub fn node(&self, path: &str) -> Option<&ShaderNode> {
        self.nodes.iter().find(|n| n.path == path)
    }
}
