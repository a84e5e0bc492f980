//! Shader graphs compiled to a flat instruction list: the one evaluator every reader
//! (USD/MaterialX, the Blender add-on, Hydra) hands its graph to.
//!
//! A graph becomes a [`Program`] once, at scene build, through a [`Builder`] that the
//! readers call node by node; vectors are spread over consecutive scalar registers, so
//! every instruction works on `f32`s. Per lookup [`Program::eval`] runs the list over a
//! fixed register file on the stack: no allocation, no lock, and no dynamic dispatch —
//! one `match` per instruction, whose arms the compiler inlines (docs/shaders.md has the
//! cost per lookup). The same list evaluated over [`Interval`]s
//! ([`Program::bounds`]) is the range analysis the majorants are built from.
//!
//! Inputs, preloaded before the first instruction: the position in the graph's
//! coordinate space (registers 0, 1, 2: object space for MaterialX's `position`) and one
//! attribute (register 3: the value of the volume's own density field at the point,
//! MaterialX's `geompropvalue`). The output is one register.

use super::interval::{
    blender_noise_bound, blender_noise_bound_shifted, cell_noise_3d_bound, perlin_3d_bound,
    Interval,
};
use super::materialx_noise::{cell_noise_3d, perlin_noise_3d};
use super::math;
use super::noise::{white_noise_color, white_noise_value, NoiseTexture};
use super::voronoi::{VoronoiOutput, VoronoiTexture, VoronoiValues};

/// A register index.
pub type Reg = u16;

/// Registers a program may use. Registers are not reused (each value has its own), so
/// a Blender tree of a few dozen nodes on vectors can pass 64, and one converting
/// colours through HSV (a Mix of Hue: two conversions there and one back) 256.
pub const MAX_REGISTERS: usize = 1024;

/// The register file is a stack array, zeroed per lookup: programs that fit in this many
/// registers (most) run with the small one (256 bytes), the others with the medium one
/// (1 KiB) or, past it, [`MAX_REGISTERS`] (4 KiB).
const SMALL_REGISTERS: usize = 64;
const MEDIUM_REGISTERS: usize = 256;

/// The position's registers (x, y, z).
pub const POSITION: Reg = 0;
/// The attribute's register.
pub const ATTRIBUTE: Reg = 3;
const INPUTS: Reg = 4;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Unary {
    Copy,
    Neg,
    Abs,
    Sqrt,
    Floor,
    /// Blender's Math operations of one operand ([`super::math`]: Cycles' semantics).
    Ceil,
    Round,
    Trunc,
    Fract,
    Sign,
    Exp,
    InverseSqrt,
    Sin,
    Cos,
    Tan,
    Asin,
    Acos,
    Atan,
    Sinh,
    Cosh,
    Tanh,
    /// Blender's Map Range Smoother Step of its factor: `x` clamped to [0, 1], then
    /// x³ (x (6x − 15) + 10) ([`math::smootherstep`]).
    Smootherstep,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Binary {
    Add,
    Sub,
    Mul,
    Div,
    Min,
    Max,
    /// Cycles' `safe_divide`: 0 where the divisor is 0 (Blender's Math Divide).
    SafeDiv,
    /// 1 where a < b, else 0 (Blender's Math Less Than).
    Less,
    /// 1 where a > b, else 0 (Blender's Math Greater Than).
    Greater,
    /// Blender's Math Power, Logarithm, Truncated and Floored Modulo
    /// ([`super::math`]: Cycles' safe functions).
    Pow,
    Log,
    Mod,
    FlooredMod,
    /// Blender's Math Arctan2: atan2(a, b).
    Atan2,
}

/// One instruction. Noise instructions read a position from three consecutive
/// registers starting at `p`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Instr {
    Const {
        dst: Reg,
        value: f32,
    },
    Unary {
        op: Unary,
        dst: Reg,
        a: Reg,
    },
    Binary {
        op: Binary,
        dst: Reg,
        a: Reg,
        b: Reg,
    },
    /// `x` clamped to `[lo, hi]` (MaterialX `clamp`: `min(max(x, lo), hi)`).
    Clamp {
        dst: Reg,
        x: Reg,
        lo: Reg,
        hi: Reg,
    },
    /// MaterialX `smoothstep`: 0 at or below `lo`, 1 at or above `hi`, Hermite between.
    Smoothstep {
        dst: Reg,
        x: Reg,
        lo: Reg,
        hi: Reg,
    },
    /// GLSL's `mix(a, b, t)`: `a (1 − t) + b t` (MaterialX `mix`, and the ramps
    /// `ramplr`/`ramp4` built of it).
    Mix {
        dst: Reg,
        a: Reg,
        b: Reg,
        t: Reg,
    },
    /// Blender's White Noise Texture of `dims` (1 to 4) coordinates read from `at`
    /// (x, y, z, w; 1D reads w only): its Value, or with `color` its Color in three
    /// registers.
    WhiteNoise {
        dst: Reg,
        at: [Reg; 4],
        dims: u8,
        color: bool,
    },
    /// Blender's Blackbody node: Cycles' Rec.709 colour of the temperature `t` (kelvin)
    /// in three registers.
    Blackbody {
        dst: Reg,
        t: Reg,
    },
    /// MaterialX `cellnoise3d` (float): the hash of the cell `floor(p)` in [0, 1].
    MxCellNoise3d {
        dst: Reg,
        p: Reg,
    },
    /// MaterialX `noise3d` (float): `perlin(p) · amplitude + pivot`.
    MxNoise3d {
        dst: Reg,
        p: Reg,
        amplitude: Reg,
        pivot: Reg,
    },
    /// MaterialX `fractal3d` (float): `amplitude · Σ diminish^i perlin(p · lacunarity^i)`
    /// over `octaves` octaves. The octave parameters must be constants: they decide the
    /// loop and the range analysis.
    MxFractal3d {
        dst: Reg,
        p: Reg,
        amplitude: Reg,
        octaves: i32,
        lacunarity: f32,
        diminish: f32,
    },
    /// Blender's Noise Texture (Fac) at the Vector `p` and `w` (4D), its properties and
    /// unconnected inputs in the program's table (`noise`: the index there).
    BlenderNoise {
        dst: Reg,
        p: Reg,
        w: Reg,
        noise: u16,
    },
    /// The Noise Texture's Color (three registers from `dst`): Fac, and the fractal at
    /// two fixed offsets for green and blue.
    BlenderNoiseColor {
        dst: Reg,
        p: Reg,
        w: Reg,
        noise: u16,
    },
    /// Blender's Voronoi Texture (3D, F1, Euclidean) at the Vector `p`: its Distance
    /// (one register) or its Color or Position (three), the node in the program's
    /// table (`voronoi`: the index there).
    BlenderVoronoi {
        dst: Reg,
        p: Reg,
        voronoi: u16,
        output: VoronoiOutput,
    },
    /// A lookup table over [0, 1] (Blender's Color Ramp as Cycles evaluates it: the
    /// ramp sampled at i / (n − 1), linearly interpolated between samples or not):
    /// `table` indexes the program's ramps.
    Ramp {
        dst: Reg,
        x: Reg,
        table: u16,
        interpolate: bool,
    },
}

/// A compiled graph.
#[derive(Clone, Debug, PartialEq)]
pub struct Program {
    instrs: Vec<Instr>,
    /// The instructions a lookup runs: `instrs` without the constants, which
    /// `initial` already holds.
    body: Vec<Instr>,
    /// The register file a lookup starts from: the constants in their registers (each
    /// register is written by one instruction only, so a constant can be in place
    /// before the others run), 0 elsewhere; as long as the registers used.
    initial: Vec<f32>,
    /// The Noise Texture nodes [`Instr::BlenderNoise`] evaluates (kept aside: they are
    /// larger than any instruction).
    noises: Vec<NoiseTexture>,
    /// The Voronoi Texture nodes [`Instr::BlenderVoronoi`] evaluates.
    voronois: Vec<VoronoiTexture>,
    /// The tables [`Instr::Ramp`] reads.
    ramps: Vec<Vec<f32>>,
    registers: usize,
    output: Reg,
    /// 1 (a float: a density) or 3 (a colour: [`Program::eval_rgb`]).
    output_width: u16,
    /// Whether any instruction reads the attribute: the grid's value then bounds the
    /// result (else the grid only says where the medium is).
    reads_attribute: bool,
    /// The name of the node that made each instruction, for messages.
    nodes: Vec<String>,
}

/// Why a graph cannot be compiled.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum GraphError {
    #[error("the graph needs more than {MAX_REGISTERS} registers")]
    TooLarge,
    #[error("{node}: {message}")]
    Node { node: String, message: String },
}

/// A scalar or a 3-vector value of the graph being built: its first register.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Value {
    Float(Reg),
    Vector3(Reg),
}

impl Value {
    pub fn width(self) -> u16 {
        match self {
            Value::Float(_) => 1,
            Value::Vector3(_) => 3,
        }
    }

    pub fn reg(self) -> Reg {
        match self {
            Value::Float(r) | Value::Vector3(r) => r,
        }
    }
}

/// Builds a [`Program`] node by node. Each method appends the instructions of one node
/// and returns the value it outputs; `node` names the node in error messages.
pub struct Builder {
    instrs: Vec<Instr>,
    noises: Vec<NoiseTexture>,
    voronois: Vec<VoronoiTexture>,
    ramps: Vec<Vec<f32>>,
    nodes: Vec<String>,
    next: usize,
    node: String,
    reads_attribute: bool,
}

impl Default for Builder {
    fn default() -> Self {
        Builder {
            instrs: Vec::new(),
            noises: Vec::new(),
            voronois: Vec::new(),
            ramps: Vec::new(),
            nodes: Vec::new(),
            next: INPUTS as usize,
            node: String::new(),
            reads_attribute: false,
        }
    }
}

impl Builder {
    /// Names the node whose instructions follow (for messages).
    pub fn node(&mut self, name: &str) {
        self.node = name.to_string();
    }

    fn alloc(&mut self, width: usize) -> Result<Reg, GraphError> {
        let r = self.next;
        self.next += width;
        if self.next > MAX_REGISTERS {
            return Err(GraphError::TooLarge);
        }
        Ok(r as Reg)
    }

    fn push(&mut self, i: Instr) {
        self.instrs.push(i);
        self.nodes.push(self.node.clone());
    }

    fn error(&self, message: impl Into<String>) -> GraphError {
        GraphError::Node {
            node: self.node.clone(),
            message: message.into(),
        }
    }

    pub fn position(&self) -> Value {
        Value::Vector3(POSITION)
    }

    pub fn attribute(&mut self) -> Value {
        self.reads_attribute = true;
        Value::Float(ATTRIBUTE)
    }

    pub fn constant(&mut self, value: f32) -> Result<Value, GraphError> {
        let dst = self.alloc(1)?;
        self.push(Instr::Const { dst, value });
        Ok(Value::Float(dst))
    }

    pub fn vector3(&mut self, v: [f32; 3]) -> Result<Value, GraphError> {
        let dst = self.alloc(3)?;
        for (k, value) in v.into_iter().enumerate() {
            self.push(Instr::Const {
                dst: dst + k as Reg,
                value,
            });
        }
        Ok(Value::Vector3(dst))
    }

    /// A float made a 3-vector (MaterialX's `convert`, and a float input of a vector
    /// operation).
    pub fn splat3(&mut self, v: Value) -> Result<Value, GraphError> {
        match v {
            Value::Vector3(_) => Ok(v),
            Value::Float(r) => {
                let dst = self.alloc(3)?;
                for k in 0..3 {
                    self.push(Instr::Unary {
                        op: Unary::Copy,
                        dst: dst + k,
                        a: r,
                    });
                }
                Ok(Value::Vector3(dst))
            }
        }
    }

    /// A vector of three floats (Blender's Combine XYZ; a colour of three channels).
    pub fn combine3(&mut self, x: Value, y: Value, z: Value) -> Result<Value, GraphError> {
        let dst = self.alloc(3)?;
        for (k, v) in [x, y, z].into_iter().enumerate() {
            let a = self.float(v, "a component")?;
            self.push(Instr::Unary {
                op: Unary::Copy,
                dst: dst + k as Reg,
                a,
            });
        }
        Ok(Value::Vector3(dst))
    }

    /// One component of a vector (a float passes through).
    pub fn component(&mut self, v: Value, k: u16) -> Result<Value, GraphError> {
        match v {
            Value::Float(_) => Ok(v),
            Value::Vector3(r) if k < 3 => Ok(Value::Float(r + k)),
            Value::Vector3(_) => Err(self.error(format!("no component {k} in a vector3"))),
        }
    }

    /// Widths must agree, except that a float meets a vector by broadcast (MaterialX's
    /// `vector3FA` variants).
    fn widths(&mut self, a: Value, b: Value) -> Result<(Value, Value), GraphError> {
        Ok(match (a, b) {
            (Value::Vector3(_), Value::Float(_)) => (a, self.splat3(b)?),
            (Value::Float(_), Value::Vector3(_)) => (self.splat3(a)?, b),
            _ => (a, b),
        })
    }

    fn like(&mut self, v: Value) -> Result<Value, GraphError> {
        Ok(match v {
            Value::Float(_) => Value::Float(self.alloc(1)?),
            Value::Vector3(_) => Value::Vector3(self.alloc(3)?),
        })
    }

    pub fn unary(&mut self, op: Unary, a: Value) -> Result<Value, GraphError> {
        let out = self.like(a)?;
        for k in 0..a.width() {
            self.push(Instr::Unary {
                op,
                dst: out.reg() + k,
                a: a.reg() + k,
            });
        }
        Ok(out)
    }

    pub fn binary(&mut self, op: Binary, a: Value, b: Value) -> Result<Value, GraphError> {
        let (a, b) = self.widths(a, b)?;
        let out = self.like(a)?;
        for k in 0..a.width() {
            self.push(Instr::Binary {
                op,
                dst: out.reg() + k,
                a: a.reg() + k,
                b: b.reg() + k,
            });
        }
        Ok(out)
    }

    pub fn clamp(&mut self, x: Value, lo: Value, hi: Value) -> Result<Value, GraphError> {
        self.between(x, lo, hi, |dst, x, lo, hi| Instr::Clamp { dst, x, lo, hi })
    }

    pub fn smoothstep(&mut self, x: Value, lo: Value, hi: Value) -> Result<Value, GraphError> {
        self.between(x, lo, hi, |dst, x, lo, hi| Instr::Smoothstep {
            dst,
            x,
            lo,
            hi,
        })
    }

    /// An instruction of `x` and two edges per component (`make(dst, x, lo, hi)`), the
    /// edges broadcast when they are floats.
    fn between(
        &mut self,
        x: Value,
        lo: Value,
        hi: Value,
        make: impl Fn(Reg, Reg, Reg, Reg) -> Instr,
    ) -> Result<Value, GraphError> {
        let (x, lo) = self.widths(x, lo)?;
        let (x, hi) = self.widths(x, hi)?;
        let out = self.like(x)?;
        for k in 0..x.width() {
            let c = |v: Value| v.reg() + if v.width() == 1 { 0 } else { k };
            self.push(make(out.reg() + k, x.reg() + k, c(lo), c(hi)));
        }
        Ok(out)
    }

    /// MaterialX `remap`: `outlow + (x − inlow)·(outhigh − outlow)/(inhigh − inlow)`.
    pub fn remap(
        &mut self,
        x: Value,
        in_lo: Value,
        in_hi: Value,
        out_lo: Value,
        out_hi: Value,
    ) -> Result<Value, GraphError> {
        let a = self.binary(Binary::Sub, x, in_lo)?;
        let b = self.binary(Binary::Sub, out_hi, out_lo)?;
        let c = self.binary(Binary::Sub, in_hi, in_lo)?;
        let ab = self.binary(Binary::Mul, a, b)?;
        let q = self.binary(Binary::Div, ab, c)?;
        self.binary(Binary::Add, out_lo, q)
    }

    /// MaterialX `dot` of two vector3s.
    pub fn dot(&mut self, a: Value, b: Value) -> Result<Value, GraphError> {
        let (a, b) = self.widths(a, b)?;
        let p = self.binary(Binary::Mul, a, b)?;
        let mut sum = self.component(p, 0)?;
        for k in 1..p.width() {
            let c = self.component(p, k)?;
            sum = self.binary(Binary::Add, sum, c)?;
        }
        Ok(sum)
    }

    /// MaterialX `magnitude` of a vector3.
    pub fn magnitude(&mut self, a: Value) -> Result<Value, GraphError> {
        let d = self.dot(a, a)?;
        self.unary(Unary::Sqrt, d)
    }

    fn position3(&mut self, p: Value) -> Result<Reg, GraphError> {
        match p {
            Value::Vector3(r) => Ok(r),
            Value::Float(_) => Err(self.error("position must be a vector3")),
        }
    }

    fn float(&mut self, v: Value, what: &str) -> Result<Reg, GraphError> {
        match v {
            Value::Float(r) => Ok(r),
            Value::Vector3(_) => Err(self.error(format!("{what} must be a float"))),
        }
    }

    /// GLSL's `mix(a, b, t)` of three floats.
    pub fn mix(&mut self, a: Value, b: Value, t: Value) -> Result<Value, GraphError> {
        let a = self.float(a, "mix's first value")?;
        let b = self.float(b, "mix's second value")?;
        let t = self.float(t, "mix's weight")?;
        let dst = self.alloc(1)?;
        self.push(Instr::Mix { dst, a, b, t });
        Ok(Value::Float(dst))
    }

    /// Blender's White Noise Texture of `dims` coordinates: `p`'s x, y, z and `w`
    /// (1D reads `w` only, 2D x and y, 3D x, y and z); its Value, or with `color` its
    /// Color.
    pub fn white_noise(
        &mut self,
        p: Value,
        w: Value,
        dims: u8,
        color: bool,
    ) -> Result<Value, GraphError> {
        let p = self.position3(p)?;
        let w = self.float(w, "White Noise's W")?;
        if !(1..=4).contains(&dims) {
            return Err(self.error(format!("White Noise of {dims} dimensions")));
        }
        let dst = self.alloc(if color { 3 } else { 1 })?;
        self.push(Instr::WhiteNoise {
            dst,
            at: [p, p + 1, p + 2, w],
            dims,
            color,
        });
        Ok(match color {
            true => Value::Vector3(dst),
            false => Value::Float(dst),
        })
    }

    /// Blender's Blackbody colour of the temperature `t` (kelvin).
    pub fn blackbody(&mut self, t: Value) -> Result<Value, GraphError> {
        let t = self.float(t, "Blackbody's temperature")?;
        let dst = self.alloc(3)?;
        self.push(Instr::Blackbody { dst, t });
        Ok(Value::Vector3(dst))
    }

    /// MaterialX `cellnoise3d` (float) at `p`.
    pub fn mx_cellnoise3d(&mut self, p: Value) -> Result<Value, GraphError> {
        let p = self.position3(p)?;
        let dst = self.alloc(1)?;
        self.push(Instr::MxCellNoise3d { dst, p });
        Ok(Value::Float(dst))
    }

    pub fn mx_noise3d(
        &mut self,
        p: Value,
        amplitude: Value,
        pivot: Value,
    ) -> Result<Value, GraphError> {
        let p = self.position3(p)?;
        let amplitude = self.float(amplitude, "amplitude")?;
        let pivot = self.float(pivot, "pivot")?;
        let dst = self.alloc(1)?;
        self.push(Instr::MxNoise3d {
            dst,
            p,
            amplitude,
            pivot,
        });
        Ok(Value::Float(dst))
    }

    pub fn mx_fractal3d(
        &mut self,
        p: Value,
        amplitude: Value,
        octaves: i32,
        lacunarity: f32,
        diminish: f32,
    ) -> Result<Value, GraphError> {
        let p = self.position3(p)?;
        let amplitude = self.float(amplitude, "amplitude")?;
        if !(0..=32).contains(&octaves) {
            return Err(self.error(format!("octaves must lie in [0, 32], got {octaves}")));
        }
        if !(lacunarity.is_finite() && diminish.is_finite()) {
            return Err(self.error("lacunarity and diminish must be finite"));
        }
        let dst = self.alloc(1)?;
        self.push(Instr::MxFractal3d {
            dst,
            p,
            amplitude,
            octaves,
            lacunarity,
            diminish,
        });
        Ok(Value::Float(dst))
    }

    /// Blender's Noise Texture node's Fac at the Vector `p` (a vector3) and `w` (a float,
    /// read in 4D only), of any type ([`blender_noise_bound`] bounds them all).
    pub fn blender_noise(
        &mut self,
        p: Value,
        w: Value,
        node: NoiseTexture,
    ) -> Result<Value, GraphError> {
        let (p, w, noise) = self.noise_inputs(p, w, node)?;
        let dst = self.alloc(1)?;
        self.push(Instr::BlenderNoise { dst, p, w, noise });
        Ok(Value::Float(dst))
    }

    /// The Noise Texture's Color output (a vector3: Fac, and the fractal at two fixed
    /// offsets for green and blue), as [`blender_noise`](Self::blender_noise) its Fac.
    pub fn blender_noise_color(
        &mut self,
        p: Value,
        w: Value,
        node: NoiseTexture,
    ) -> Result<Value, GraphError> {
        let (p, w, noise) = self.noise_inputs(p, w, node)?;
        let dst = self.alloc(3)?;
        self.push(Instr::BlenderNoiseColor { dst, p, w, noise });
        Ok(Value::Vector3(dst))
    }

    /// A Noise Texture's position and W registers, and its index in the node table
    /// (the node checked and added there).
    fn noise_inputs(
        &mut self,
        p: Value,
        w: Value,
        node: NoiseTexture,
    ) -> Result<(Reg, Reg, u16), GraphError> {
        let p = self.position3(p)?;
        let w = self.float(w, "W")?;
        let finite = [
            node.scale,
            node.lacunarity,
            node.distortion,
            node.offset,
            node.gain,
        ];
        if !finite.iter().all(|v| v.is_finite()) {
            return Err(self.error("Scale, Lacunarity, Distortion, Offset and Gain must be finite"));
        }
        let index = u16::try_from(self.noises.len()).map_err(|_| GraphError::TooLarge)?;
        self.noises.push(node);
        Ok((p, w, index))
    }

    /// Blender's Voronoi Texture node (3D, Euclidean, one octave) at the Vector `p`:
    /// its `output` (Distance and Radius floats, Color and Position vector3s).
    pub fn blender_voronoi(
        &mut self,
        p: Value,
        node: VoronoiTexture,
        output: VoronoiOutput,
    ) -> Result<Value, GraphError> {
        let p = self.position3(p)?;
        if !(node.scale.is_finite() && node.randomness.is_finite()) {
            return Err(self.error("Scale and Randomness must be finite"));
        }
        let index = u16::try_from(self.voronois.len()).map_err(|_| GraphError::TooLarge)?;
        self.voronois.push(node);
        let (dst, v) = match output {
            VoronoiOutput::Distance | VoronoiOutput::Radius => {
                let r = self.alloc(1)?;
                (r, Value::Float(r))
            }
            _ => {
                let r = self.alloc(3)?;
                (r, Value::Vector3(r))
            }
        };
        self.push(Instr::BlenderVoronoi {
            dst,
            p,
            voronoi: index,
            output,
        });
        Ok(v)
    }

    /// A lookup of `x` in `table` (at least 2 finite entries, sampled at i / (n − 1)
    /// over [0, 1]; `x` clamped to [0, 1]), interpolated linearly or not.
    pub fn ramp(
        &mut self,
        x: Value,
        table: Vec<f32>,
        interpolate: bool,
    ) -> Result<Value, GraphError> {
        let x = self.float(x, "the ramp's input")?;
        if table.len() < 2 || table.len() > 4096 || !table.iter().all(|v| v.is_finite()) {
            return Err(self.error(format!(
                "a ramp table needs 2 to 4096 finite entries, got {}",
                table.len()
            )));
        }
        let index = u16::try_from(self.ramps.len()).map_err(|_| GraphError::TooLarge)?;
        self.ramps.push(table);
        let dst = self.alloc(1)?;
        self.push(Instr::Ramp {
            dst,
            x,
            table: index,
            interpolate,
        });
        Ok(Value::Float(dst))
    }

    /// The program computing `output` (a float).
    pub fn finish(self, output: Value) -> Result<Program, GraphError> {
        let Value::Float(_) = output else {
            return Err(self.error("the graph's output must be a float"));
        };
        self.finish_any(output)
    }

    /// The program computing the colour `output` (a vector3, or a float as grey), read
    /// with [`Program::eval_rgb`].
    pub fn finish_rgb(mut self, output: Value) -> Result<Program, GraphError> {
        let output = self.splat3(output)?;
        self.finish_any(output)
    }

    fn finish_any(self, output: Value) -> Result<Program, GraphError> {
        let (output_width, output) = (output.width(), output.reg());
        let mut initial = vec![0.0f32; self.next];
        let mut body = Vec::with_capacity(self.instrs.len());
        for i in &self.instrs {
            match *i {
                Instr::Const { dst, value } => initial[dst as usize] = value,
                other => body.push(other),
            }
        }
        Ok(Program {
            output_width,
            body,
            initial,
            instrs: self.instrs,
            noises: self.noises,
            voronois: self.voronois,
            ramps: self.ramps,
            registers: self.next,
            output,
            reads_attribute: self.reads_attribute,
            nodes: self.nodes,
        })
    }
}

#[inline(always)]
fn smoothstep(x: f32, lo: f32, hi: f32) -> f32 {
    if x >= hi {
        1.0
    } else if x <= lo {
        0.0
    } else {
        let t = (x - lo) / (hi - lo);
        t * t * (3.0 - 2.0 * t)
    }
}

/// Cycles' table lookup (`float_ramp_lookup` without extrapolation): `x` clamped to
/// [0, 1] and scaled to the table's index range; NaN reads the first entry.
#[inline(always)]
fn ramp_lookup(table: &[f32], x: f32, interpolate: bool) -> f32 {
    let last = table.len() - 1;
    let f = if x > 0.0 { x.min(1.0) } else { 0.0 } * last as f32;
    let i = (f as usize).min(last);
    let t = f - i as f32;
    let a = table[i];
    if interpolate && t > 0.0 {
        (1.0 - t) * a + t * table[(i + 1).min(last)]
    } else {
        a
    }
}

/// The range of [`ramp_lookup`] over `x`: the entries the clamped index range touches
/// (an interpolated value lies between its two entries).
fn ramp_bound(table: &[f32], x: Interval) -> Interval {
    let last = table.len() - 1;
    let scaled = |v: f32| if v > 0.0 { v.min(1.0) } else { 0.0 } * last as f32;
    let (lo, hi) = if x.lo.is_nan() || x.hi.is_nan() {
        (0, last)
    } else {
        let lo = (scaled(x.lo) as usize).min(last);
        (lo, (scaled(x.hi).floor() as usize + 1).min(last))
    };
    let slice = &table[lo..=hi.max(lo)];
    let min = slice.iter().copied().fold(f32::INFINITY, f32::min);
    let max = slice.iter().copied().fold(f32::NEG_INFINITY, f32::max);
    Interval::new(min, max)
}

impl Program {
    pub fn len(&self) -> usize {
        self.instrs.len()
    }

    pub fn is_empty(&self) -> bool {
        self.instrs.is_empty()
    }

    pub fn reads_attribute(&self) -> bool {
        self.reads_attribute
    }

    /// Whether the output is a colour ([`Program::eval_rgb`]) rather than a float.
    pub fn outputs_rgb(&self) -> bool {
        self.output_width == 3
    }

    /// The graph's value at `position` with the attribute `attribute`.
    #[inline]
    pub fn eval(&self, position: [f32; 3], attribute: f32) -> f32 {
        self.outputs(position, attribute)[0]
    }

    /// A colour graph's value ([`Builder::finish_rgb`]) at `position`.
    #[inline]
    pub fn eval_rgb(&self, position: [f32; 3], attribute: f32) -> [f32; 3] {
        self.outputs(position, attribute)
    }

    /// The output register and the two after it (0 past the file's end), run on the
    /// smallest register file the program fits. Only these three leave `run`: the
    /// register file itself is not copied out (a 4 KiB copy per lookup in the
    /// largest file).
    #[inline(always)]
    fn outputs(&self, position: [f32; 3], attribute: f32) -> [f32; 3] {
        match self.registers {
            n if n <= SMALL_REGISTERS => self.run::<SMALL_REGISTERS>(position, attribute),
            n if n <= MEDIUM_REGISTERS => self.run::<MEDIUM_REGISTERS>(position, attribute),
            _ => self.run::<MAX_REGISTERS>(position, attribute),
        }
    }

    /// Runs the program on a register file of `N` and returns [`outputs`](Self::outputs).
    #[inline(always)]
    fn run<const N: usize>(&self, position: [f32; 3], attribute: f32) -> [f32; 3] {
        let mut r = [0.0f32; N];
        r[..self.initial.len()].copy_from_slice(&self.initial);
        r[0] = position[0];
        r[1] = position[1];
        r[2] = position[2];
        r[3] = attribute;
        // A Voronoi node whose Distance, Color and Position are all used is one
        // instruction per output: the last evaluation is kept, so the same node at the
        // same point is searched once per lookup.
        let mut last_voronoi: Option<(u16, [f32; 3], VoronoiValues)> = None;
        for i in &self.body {
            match *i {
                Instr::Const { dst, value } => r[dst as usize] = value,
                Instr::Unary { op, dst, a } => {
                    let a = r[a as usize];
                    r[dst as usize] = match op {
                        Unary::Copy => a,
                        Unary::Neg => -a,
                        Unary::Abs => a.abs(),
                        Unary::Sqrt => a.max(0.0).sqrt(),
                        Unary::Floor => a.floor(),
                        Unary::Ceil => a.ceil(),
                        Unary::Round => math::round(a),
                        Unary::Trunc => math::trunc(a),
                        Unary::Fract => math::fract(a),
                        Unary::Sign => math::sign(a),
                        Unary::Exp => a.exp(),
                        Unary::InverseSqrt => math::inverse_sqrt(a),
                        Unary::Sin => a.sin(),
                        Unary::Cos => a.cos(),
                        Unary::Tan => a.tan(),
                        Unary::Asin => math::asin(a),
                        Unary::Acos => math::acos(a),
                        Unary::Atan => a.atan(),
                        Unary::Sinh => a.sinh(),
                        Unary::Cosh => a.cosh(),
                        Unary::Tanh => a.tanh(),
                        Unary::Smootherstep => math::smootherstep(a),
                    }
                }
                Instr::Binary { op, dst, a, b } => {
                    let (a, b) = (r[a as usize], r[b as usize]);
                    r[dst as usize] = match op {
                        Binary::Add => a + b,
                        Binary::Sub => a - b,
                        Binary::Mul => a * b,
                        Binary::Div => a / b,
                        Binary::Min => a.min(b),
                        Binary::Max => a.max(b),
                        Binary::SafeDiv => {
                            if b != 0.0 {
                                a / b
                            } else {
                                0.0
                            }
                        }
                        Binary::Less => f32::from(u8::from(a < b)),
                        Binary::Greater => f32::from(u8::from(a > b)),
                        Binary::Pow => math::pow(a, b),
                        Binary::Log => math::log(a, b),
                        Binary::Mod => math::modulo(a, b),
                        Binary::FlooredMod => math::floored_modulo(a, b),
                        Binary::Atan2 => a.atan2(b),
                    }
                }
                Instr::Ramp {
                    dst,
                    x,
                    table,
                    interpolate,
                } => {
                    r[dst as usize] =
                        ramp_lookup(&self.ramps[table as usize], r[x as usize], interpolate)
                }
                Instr::Clamp { dst, x, lo, hi } => {
                    r[dst as usize] = r[x as usize].max(r[lo as usize]).min(r[hi as usize])
                }
                Instr::Smoothstep { dst, x, lo, hi } => {
                    r[dst as usize] = smoothstep(r[x as usize], r[lo as usize], r[hi as usize])
                }
                Instr::Mix { dst, a, b, t } => {
                    let t = r[t as usize];
                    r[dst as usize] = r[a as usize] * (1.0 - t) + r[b as usize] * t;
                }
                Instr::WhiteNoise {
                    dst,
                    at,
                    dims,
                    color,
                } => {
                    let k = at.map(|a| r[a as usize]);
                    let dst = dst as usize;
                    match color {
                        true => {
                            let c = white_noise_color(k, dims);
                            r[dst..dst + 3].copy_from_slice(&c)
                        }
                        false => r[dst] = white_noise_value(k, dims),
                    }
                }
                Instr::Blackbody { dst, t } => {
                    let dst = dst as usize;
                    let c = math::blackbody(r[t as usize]);
                    r[dst..dst + 3].copy_from_slice(&c);
                }
                Instr::MxCellNoise3d { dst, p } => {
                    let p = p as usize;
                    r[dst as usize] = cell_noise_3d([r[p], r[p + 1], r[p + 2]]);
                }
                Instr::MxNoise3d {
                    dst,
                    p,
                    amplitude,
                    pivot,
                } => {
                    let p = p as usize;
                    let n = perlin_noise_3d([r[p], r[p + 1], r[p + 2]]);
                    r[dst as usize] = n * r[amplitude as usize] + r[pivot as usize];
                }
                Instr::MxFractal3d {
                    dst,
                    p,
                    amplitude,
                    octaves,
                    lacunarity,
                    diminish,
                } => {
                    let p = p as usize;
                    let f = super::materialx_noise::fractal_noise_3d(
                        [r[p], r[p + 1], r[p + 2]],
                        octaves,
                        lacunarity,
                        diminish,
                    );
                    r[dst as usize] = f * r[amplitude as usize];
                }
                Instr::BlenderNoise { dst, p, w, noise } => {
                    let p = p as usize;
                    let node = &self.noises[noise as usize];
                    r[dst as usize] = node.fac([r[p], r[p + 1], r[p + 2]], r[w as usize]);
                }
                Instr::BlenderNoiseColor { dst, p, w, noise } => {
                    let (p, dst) = (p as usize, dst as usize);
                    let node = &self.noises[noise as usize];
                    let (_, c) = node.eval([r[p], r[p + 1], r[p + 2]], r[w as usize]);
                    r[dst..dst + 3].copy_from_slice(&c);
                }
                Instr::BlenderVoronoi {
                    dst,
                    p,
                    voronoi,
                    output,
                } => {
                    let (p, dst) = (p as usize, dst as usize);
                    let at = [r[p], r[p + 1], r[p + 2]];
                    let v = match last_voronoi {
                        Some((node, q, v)) if node == voronoi && q == at => v,
                        _ => {
                            let v = self.voronois[voronoi as usize].eval(at);
                            last_voronoi = Some((voronoi, at, v));
                            v
                        }
                    };
                    match output {
                        VoronoiOutput::Distance => r[dst] = v.distance,
                        VoronoiOutput::Color => r[dst..dst + 3].copy_from_slice(&v.color),
                        VoronoiOutput::Position => r[dst..dst + 3].copy_from_slice(&v.position),
                        VoronoiOutput::Radius => r[dst] = v.radius,
                    }
                }
            }
        }
        let o = self.output as usize;
        [o, o + 1, o + 2].map(|k| r.get(k).copied().unwrap_or(0.0))
    }

    /// Bounds of the graph's value over the position box `[lo, hi]` with the attribute
    /// in `attribute`, widened for rounding. Unbounded (a division by an interval
    /// holding 0, say) comes back with infinite ends.
    pub fn bounds(&self, lo: [f32; 3], hi: [f32; 3], attribute: Interval) -> Interval {
        let mut r = vec![Interval::point(0.0); self.registers.max(INPUTS as usize)];
        for a in 0..3 {
            r[a] = Interval::new(lo[a], hi[a]);
        }
        r[3] = attribute;
        for i in &self.instrs {
            match *i {
                Instr::Const { dst, value } => r[dst as usize] = Interval::point(value),
                Instr::Unary { op, dst, a } => {
                    let a = r[a as usize];
                    r[dst as usize] = match op {
                        Unary::Copy => a,
                        Unary::Neg => a.neg(),
                        Unary::Abs => a.abs(),
                        Unary::Sqrt => a.monotone(|x| x.max(0.0).sqrt()),
                        Unary::Floor => a.monotone(f32::floor),
                        Unary::Ceil => a.monotone(f32::ceil),
                        Unary::Round => a.monotone(math::round),
                        Unary::Trunc => a.monotone(math::trunc),
                        Unary::Fract => math::fract_bound(a),
                        Unary::Sign => a.monotone(math::sign),
                        Unary::Exp => math::exp_bound(a),
                        Unary::InverseSqrt => math::inverse_sqrt_bound(a),
                        Unary::Sin => math::sin_bound(a, 0.0),
                        Unary::Cos => math::sin_bound(a, std::f64::consts::FRAC_PI_2),
                        Unary::Tan => math::tan_bound(a),
                        // Increasing (asin, atan, sinh, tanh) or decreasing (acos).
                        Unary::Asin => a.monotone(math::asin).widened(1e-6, 0.0),
                        Unary::Acos => {
                            Interval::new(math::acos(a.hi), math::acos(a.lo)).widened(1e-6, 0.0)
                        }
                        Unary::Atan => a.monotone(f32::atan).widened(1e-6, 0.0),
                        Unary::Sinh => a.monotone(f32::sinh).widened(1e-6, 0.0),
                        Unary::Cosh => math::cosh_bound(a),
                        Unary::Tanh => a.monotone(f32::tanh).widened(1e-6, 0.0),
                        // Non-decreasing; the rounding of the polynomial is within 1e-6.
                        Unary::Smootherstep => a.monotone(math::smootherstep).widened(1e-6, 0.0),
                    }
                }
                Instr::Binary { op, dst, a, b } => {
                    let (a, b) = (r[a as usize], r[b as usize]);
                    r[dst as usize] = match op {
                        Binary::Add => a.add(b),
                        Binary::Sub => a.sub(b),
                        Binary::Mul => a.mul(b),
                        Binary::Div => a.div(b),
                        Binary::Min => a.min(b),
                        Binary::Max => a.max(b),
                        Binary::SafeDiv => {
                            if b.lo == 0.0 && b.hi == 0.0 {
                                Interval::point(0.0)
                            } else if b.lo > 0.0 || b.hi < 0.0 {
                                a.div(b)
                            } else {
                                // A divisor range through 0 (not only 0): unbounded.
                                Interval::new(f32::NEG_INFINITY, f32::INFINITY)
                            }
                        }
                        Binary::Less | Binary::Greater => {
                            let (lo, hi) = if op == Binary::Less { (a, b) } else { (b, a) };
                            // lo < hi surely, never, or either.
                            if lo.hi < hi.lo {
                                Interval::point(1.0)
                            } else if lo.lo >= hi.hi {
                                Interval::point(0.0)
                            } else {
                                Interval::new(0.0, 1.0)
                            }
                        }
                        Binary::Pow => math::pow_bound(a, b),
                        Binary::Log => math::log_bound(a, b),
                        Binary::Mod => math::modulo_bound(a, b),
                        Binary::FlooredMod => math::floored_modulo_bound(a, b),
                        Binary::Atan2 => Interval::new(-std::f32::consts::PI, std::f32::consts::PI)
                            .widened(1e-6, 0.0),
                    }
                }
                Instr::Ramp { dst, x, table, .. } => {
                    r[dst as usize] = ramp_bound(&self.ramps[table as usize], r[x as usize])
                }
                Instr::Clamp { dst, x, lo, hi } => {
                    r[dst as usize] = r[x as usize].max(r[lo as usize]).min(r[hi as usize])
                }
                Instr::Smoothstep { dst, x, lo, hi } => {
                    let (x, lo, hi) = (r[x as usize], r[lo as usize], r[hi as usize]);
                    // Non-decreasing in x for fixed edges lo < hi; other edges: [0, 1].
                    r[dst as usize] = if lo.lo == lo.hi && hi.lo == hi.hi && lo.lo < hi.lo {
                        x.monotone(|v| smoothstep(v, lo.lo, hi.lo))
                    } else {
                        Interval::new(0.0, 1.0)
                    };
                }
                Instr::Mix { dst, a, b, t } => {
                    let (a, b, t) = (r[a as usize], r[b as usize], r[t as usize]);
                    // A weight in [0, 1] (the ramps clamp theirs) makes a convex
                    // combination: it lies between a and b. Else the plain arithmetic.
                    r[dst as usize] = if t.lo >= 0.0 && t.hi <= 1.0 {
                        a.hull(b)
                    } else {
                        a.mul(Interval::point(1.0).sub(t)).add(b.mul(t))
                    };
                }
                // Hashes: anywhere in [0, 1].
                Instr::WhiteNoise { dst, color, .. } => {
                    let n = if color { 3 } else { 1 };
                    for k in 0..n {
                        r[dst as usize + k] = Interval::new(0.0, 1.0);
                    }
                }
                Instr::Blackbody { dst, t } => {
                    let t = r[t as usize];
                    for (k, &(lo, hi)) in math::BLACKBODY_RANGE.iter().enumerate() {
                        r[dst as usize + k] = if t.lo == t.hi {
                            Interval::point(math::blackbody(t.lo)[k])
                        } else {
                            Interval::new(lo, hi)
                        };
                    }
                }
                Instr::MxCellNoise3d { dst, p } => {
                    let p = p as usize;
                    r[dst as usize] = cell_noise_3d_bound(
                        [r[p].lo, r[p + 1].lo, r[p + 2].lo],
                        [r[p].hi, r[p + 1].hi, r[p + 2].hi],
                    );
                }
                Instr::MxNoise3d {
                    dst,
                    p,
                    amplitude,
                    pivot,
                } => {
                    let n = noise_bound(&r, p, 1.0);
                    r[dst as usize] = n.mul(r[amplitude as usize]).add(r[pivot as usize]);
                }
                Instr::MxFractal3d {
                    dst,
                    p,
                    amplitude,
                    octaves,
                    lacunarity,
                    diminish,
                } => {
                    let mut sum = Interval::point(0.0);
                    let (mut freq, mut amp) = (1.0f32, 1.0f32);
                    for _ in 0..octaves {
                        let n = noise_bound(&r, p, freq);
                        sum = sum.add(n.mul(Interval::point(amp)));
                        amp *= diminish;
                        freq *= lacunarity;
                    }
                    r[dst as usize] = sum.mul(r[amplitude as usize]);
                }
                Instr::BlenderNoise { dst, p, w, noise } => {
                    let p = p as usize;
                    let node = &self.noises[noise as usize];
                    r[dst as usize] =
                        blender_noise_bound(node, [r[p], r[p + 1], r[p + 2], r[w as usize]]);
                }
                Instr::BlenderNoiseColor { dst, p, w, noise } => {
                    let (p, dst) = (p as usize, dst as usize);
                    let node = &self.noises[noise as usize];
                    let at = [r[p], r[p + 1], r[p + 2], r[w as usize]];
                    let [g, b] = node.color_offsets();
                    r[dst] = blender_noise_bound(node, at);
                    r[dst + 1] = blender_noise_bound_shifted(node, at, g);
                    r[dst + 2] = blender_noise_bound_shifted(node, at, b);
                }
                Instr::BlenderVoronoi {
                    dst,
                    p,
                    voronoi,
                    output,
                } => {
                    let (p, dst) = (p as usize, dst as usize);
                    let b = self.voronois[voronoi as usize].bounds(
                        [r[p].lo, r[p + 1].lo, r[p + 2].lo],
                        [r[p].hi, r[p + 1].hi, r[p + 2].hi],
                    );
                    match output {
                        VoronoiOutput::Distance => r[dst] = b.distance,
                        VoronoiOutput::Color => r[dst..dst + 3].copy_from_slice(&b.color),
                        VoronoiOutput::Position => r[dst..dst + 3].copy_from_slice(&b.position),
                        VoronoiOutput::Radius => r[dst] = b.radius,
                    }
                }
            }
        }
        // Room for f32 rounding of the evaluation: a relative 2⁻¹² of the largest value
        // and an absolute 2⁻²⁰ (both far above the few ulps a short program loses).
        r[self.output as usize].widened(1.0 / 4096.0, 1.0 / 1_048_576.0)
    }

    /// The node that made the instruction computing the output (for messages).
    pub fn output_node(&self) -> &str {
        self.nodes.last().map(String::as_str).unwrap_or("")
    }
}

/// MaterialX's signed Perlin noise (0.9820 × the unscaled noise) over the box held in
/// registers `p..p+3`, scaled by `freq` (the fractal's octave frequency).
fn noise_bound(r: &[Interval], p: Reg, freq: f32) -> Interval {
    let p = p as usize;
    let lo = [0, 1, 2].map(|a| r[p + a].lo * freq);
    let hi = [0, 1, 2].map(|a| r[p + a].hi * freq);
    // A negative frequency flips the box.
    let (lo, hi) = (
        [0, 1, 2].map(|a| lo[a].min(hi[a])),
        [0, 1, 2].map(|a| lo[a].max(hi[a])),
    );
    perlin_3d_bound(lo, hi).mul(Interval::point(0.9820))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// x + 1 + 1 … (`n` additions, each a constant and a sum: 2n + 4 registers).
    fn chain(n: usize) -> Result<Program, GraphError> {
        let mut b = Builder::default();
        let mut v = b.component(b.position(), 0)?;
        for _ in 0..n {
            let one = b.constant(1.0)?;
            v = b.binary(Binary::Add, v, one)?;
        }
        b.finish(v)
    }

    /// A program past the small register file runs with the medium one, and past that
    /// with the large one, to the same values; past [`MAX_REGISTERS`] it is refused.
    #[test]
    fn programs_of_every_register_count_up_to_the_limit_run() {
        for n in [10, 29, 30, 31, 100, 125, 126, 127, 400, 510] {
            let program = chain(n).unwrap();
            for x in [-3.0f32, 0.25, 7.0] {
                assert_eq!(
                    program.eval([x, 0.0, 0.0], 0.0),
                    x + n as f32,
                    "{n} additions"
                );
            }
        }
        assert!(matches!(chain(511), Err(GraphError::TooLarge)));
    }

    /// The blackbody's range bounds it at every temperature from 0 to 13,000 K in
    /// steps of 1/512 K (every piece of the fit, both constant ends), and is tight to
    /// within 2e-4 of what those values reach.
    #[test]
    fn the_blackbody_range_bounds_every_temperature() {
        let mut seen = [(f32::INFINITY, f32::NEG_INFINITY); 3];
        for i in 0..13_000 * 512 {
            let c = math::blackbody(i as f32 / 512.0);
            for k in 0..3 {
                let (lo, hi) = math::BLACKBODY_RANGE[k];
                assert!(c[k] >= lo && c[k] <= hi, "{c:?} at {} K", i as f32 / 512.0);
                seen[k] = (seen[k].0.min(c[k]), seen[k].1.max(c[k]));
            }
        }
        for k in 0..3 {
            let (lo, hi) = math::BLACKBODY_RANGE[k];
            assert!(
                seen[k].0 - lo < 2e-4 && hi - seen[k].1 < 2e-4,
                "{k}: {seen:?}"
            );
        }
    }

    fn fbm_graph() -> Program {
        let mut b = Builder::default();
        b.node("/Mat/fractal");
        let p = b.position();
        let two = b.constant(2.0).unwrap();
        let p2 = b.binary(Binary::Mul, p, two).unwrap();
        let amp = b.constant(1.0).unwrap();
        let f = b.mx_fractal3d(p2, amp, 4, 2.0, 0.5).unwrap();
        let half = b.constant(0.5).unwrap();
        let zero = b.constant(0.0).unwrap();
        let one = b.constant(1.0).unwrap();
        let s = b.binary(Binary::Add, f, half).unwrap();
        let c = b.clamp(s, zero, one).unwrap();
        let d = b.attribute();
        let out = b.binary(Binary::Mul, c, d).unwrap();
        b.finish(out).unwrap()
    }

    #[test]
    fn evaluates_as_the_nodes_do() {
        let prog = fbm_graph();
        let p = [0.3f32, -0.7, 1.1];
        let f = super::super::materialx_noise::fractal_noise_3d(p.map(|c| c * 2.0), 4, 2.0, 0.5);
        assert_eq!(prog.eval(p, 0.5), (f + 0.5).clamp(0.0, 1.0) * 0.5);
        assert!(prog.reads_attribute());
    }

    #[test]
    fn bounds_hold_over_boxes() {
        let prog = fbm_graph();
        let mut s = 5u32;
        let mut next = || {
            s = crate::shader::noise::hash_uint2(s, 0x9e37_79b9);
            s as f32 / u32::MAX as f32
        };
        for _ in 0..500 {
            let lo: [f32; 3] = std::array::from_fn(|_| (next() - 0.5) * 8.0);
            let size = 0.5 * next();
            let hi = lo.map(|c| c + size);
            let b = prog.bounds(lo, hi, Interval::new(0.2, 0.9));
            for _ in 0..100 {
                let p: [f32; 3] = std::array::from_fn(|a| lo[a] + (hi[a] - lo[a]) * next());
                let v = prog.eval(p, 0.2 + 0.7 * next());
                assert!(v >= b.lo && v <= b.hi, "{v} outside {b:?}");
            }
        }
    }

    /// Blender's Noise Texture in a graph: the node's own Fac, and bounds that hold over
    /// random boxes for fBM in 3D and 4D, normalized or not, with fractional Detail and
    /// Distortion; the other types are refused.
    #[test]
    fn blender_noise_evaluates_and_is_bounded() {
        use crate::shader::noise::{Dimensions, NoiseType};
        let nodes = [
            NoiseTexture {
                scale: 2.0,
                detail: 4.0,
                ..NoiseTexture::default()
            },
            NoiseTexture {
                scale: 3.5,
                detail: 2.6,
                roughness: 0.7,
                distortion: 0.4,
                ..NoiseTexture::default()
            },
            NoiseTexture {
                normalize: false,
                detail: 1.3,
                lacunarity: 2.5,
                ..NoiseTexture::default()
            },
            NoiseTexture {
                dimensions: Dimensions::D4,
                scale: 1.5,
                detail: 3.0,
                ..NoiseTexture::default()
            },
            // The other types: their bounds also hold, and are finite.
            NoiseTexture {
                kind: NoiseType::Multifractal,
                scale: 2.0,
                detail: 3.4,
                roughness: 0.6,
                ..NoiseTexture::default()
            },
            NoiseTexture {
                kind: NoiseType::HeteroTerrain,
                scale: 2.5,
                detail: 2.5,
                offset: 0.3,
                distortion: 0.2,
                ..NoiseTexture::default()
            },
            NoiseTexture {
                kind: NoiseType::HybridMultifractal,
                scale: 3.0,
                detail: 4.7,
                offset: 0.2,
                gain: 2.5,
                ..NoiseTexture::default()
            },
            NoiseTexture {
                kind: NoiseType::HybridMultifractal,
                scale: 1.0,
                detail: 6.0,
                offset: -0.3,
                gain: 1.0,
                ..NoiseTexture::default()
            },
            NoiseTexture {
                kind: NoiseType::RidgedMultifractal,
                scale: 2.0,
                detail: 5.0,
                offset: 1.0,
                gain: 2.0,
                ..NoiseTexture::default()
            },
            NoiseTexture {
                kind: NoiseType::RidgedMultifractal,
                dimensions: Dimensions::D4,
                detail: 3.0,
                offset: 0.8,
                gain: 3.0,
                ..NoiseTexture::default()
            },
            // 1D (W = the position's x) and 2D: the global bounds per octave.
            NoiseTexture {
                dimensions: Dimensions::D1,
                scale: 3.0,
                detail: 2.5,
                distortion: 0.6,
                ..NoiseTexture::default()
            },
            NoiseTexture {
                dimensions: Dimensions::D2,
                scale: 2.0,
                detail: 3.0,
                distortion: 0.4,
                ..NoiseTexture::default()
            },
            NoiseTexture {
                kind: NoiseType::HeteroTerrain,
                dimensions: Dimensions::D2,
                detail: 2.5,
                offset: 0.3,
                ..NoiseTexture::default()
            },
        ];
        let mut s = 17u32;
        let mut next = || {
            s = crate::shader::noise::hash_uint2(s, 0x9e37_79b9);
            s as f32 / u32::MAX as f32
        };
        for node in nodes {
            let w_of = |b: &mut Builder, p| match node.dimensions {
                Dimensions::D1 => b.component(p, 0).unwrap(),
                _ => b.constant(0.37).unwrap(),
            };
            let mut b = Builder::default();
            let p = b.position();
            let w = w_of(&mut b, p);
            let f = b.blender_noise(p, w, node).unwrap();
            let prog = b.finish(f).unwrap();
            // The Color output: three channels, each bounded per channel. The program
            // bounds its output's first register; a Separate-XYZ-like component of the
            // colour picks green or blue.
            let channel = |k: u16| {
                let mut b = Builder::default();
                let p = b.position();
                let w = w_of(&mut b, p);
                let c = b.blender_noise_color(p, w, node).unwrap();
                let v = b.component(c, k).unwrap();
                b.finish(v).unwrap()
            };
            let colour = [channel(0), channel(1), channel(2)];
            for _ in 0..300 {
                let lo: [f32; 3] = std::array::from_fn(|_| (next() - 0.5) * 6.0);
                let size = 0.3 * next();
                let hi = lo.map(|c| c + size);
                let bound = prog.bounds(lo, hi, Interval::point(0.0));
                assert!(bound.is_bounded(), "{node:?}: {bound:?}");
                let colour_bounds = colour
                    .each_ref()
                    .map(|c| c.bounds(lo, hi, Interval::point(0.0)));
                for _ in 0..50 {
                    let q: [f32; 3] = std::array::from_fn(|a| lo[a] + (hi[a] - lo[a]) * next());
                    let w = match node.dimensions {
                        Dimensions::D1 => q[0],
                        _ => 0.37,
                    };
                    let v = prog.eval(q, 0.0);
                    assert_eq!(v, node.fac(q, w));
                    assert!(
                        v >= bound.lo && v <= bound.hi,
                        "{node:?}: {v} outside {bound:?}"
                    );
                    let (_, rgb) = node.eval(q, w);
                    for k in 0..3 {
                        let c = colour[k].eval(q, 0.0);
                        let cb = colour_bounds[k];
                        assert_eq!(c, rgb[k]);
                        assert!(
                            cb.is_bounded() && c >= cb.lo && c <= cb.hi,
                            "{node:?}: channel {k} {c} outside {cb:?}"
                        );
                    }
                }
            }
        }
        let mut b = Builder::default();
        let p = b.position();
        let w = b.constant(0.0).unwrap();
        let odd = NoiseTexture {
            gain: f32::NAN,
            ..NoiseTexture::default()
        };
        assert!(b.blender_noise(p, w, odd).is_err());
    }

    /// MaterialX's cell noise and a ramp (mix with a clamped weight) of it: bounds
    /// hold over random boxes of every size, and are the exact value in a box inside
    /// one cell.
    #[test]
    fn cell_noise_and_mix_are_bounded() {
        let mut b = Builder::default();
        let p = b.position();
        let c = b.mx_cellnoise3d(p).unwrap();
        let x = b.component(p, 0).unwrap();
        let (zero, one) = (b.constant(0.0).unwrap(), b.constant(1.0).unwrap());
        let t = b.clamp(x, zero, one).unwrap();
        let two = b.constant(2.0).unwrap();
        let m = b.mix(c, two, t).unwrap();
        let prog = b.finish(m).unwrap();
        let mut s = 23u32;
        let mut next = || {
            s = crate::shader::noise::hash_uint2(s, 0x9e37_79b9);
            s as f32 / u32::MAX as f32
        };
        for k in 0..2000 {
            let size = [0.05f32, 0.5, 3.0, 20.0][k % 4];
            let lo: [f32; 3] = std::array::from_fn(|_| (next() - 0.5) * 40.0);
            let hi: [f32; 3] = std::array::from_fn(|a| lo[a] + size * next());
            let bound = prog.bounds(lo, hi, Interval::point(0.0));
            for _ in 0..50 {
                let q: [f32; 3] = std::array::from_fn(|a| lo[a] + (hi[a] - lo[a]) * next());
                let v = prog.eval(q, 0.0);
                assert!(v >= bound.lo && v <= bound.hi, "{v} outside {bound:?}");
            }
        }
        let cell = super::super::interval::cell_noise_3d_bound([1.2, -3.5, 7.1], [1.9, -3.1, 7.8]);
        let v = cell_noise_3d([1.5, -3.3, 7.5]);
        assert_eq!((cell.lo, cell.hi), (v, v));
    }

    #[test]
    fn division_by_a_range_holding_zero_is_unbounded() {
        let mut b = Builder::default();
        let one = b.constant(1.0).unwrap();
        let p = b.position();
        let x = b.component(p, 0).unwrap();
        let q = b.binary(Binary::Div, one, x).unwrap();
        let prog = b.finish(q).unwrap();
        assert!(!prog
            .bounds([-1.0; 3], [1.0; 3], Interval::point(0.0))
            .is_bounded());
        assert!(prog
            .bounds([1.0; 3], [2.0; 3], Interval::point(0.0))
            .is_bounded());
    }
}
