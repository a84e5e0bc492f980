//! Blender shader node trees driving a medium's density (issue 47), as the Blender
//! add-on writes them into its USD overlay, compiled into a [`Program`].
//!
//! The add-on writes each node of the tree upstream of a volume shader's Density as a
//! UsdShade `Shader` whose `info:id` is the node's Blender type (`ShaderNodeTexNoise`,
//! `ShaderNodeMath`…), its properties (operation, noise type…) and unlinked inputs as
//! `inputs:` values and its links as connections; inputs and outputs are named by the
//! socket's identifier with every character outside `[A-Za-z0-9_]` made `_` (Math's
//! second input is `Value_001`, Map Range's `From Min` is `From_Min`). It then
//! connects the medium's `nimbus:densityScale` to the graph's output: the density is
//! the medium's density field times that value (a fog: the value itself).
//!
//! The semantics are Cycles' (`intern/cycles/kernel/svm/`), so that the add-on's image
//! is Cycles' image: `safe_divide` for Divide, the Color Ramp as the 257-entry table
//! Cycles bakes (the add-on evaluates the ramp with Blender's own `ColorRamp.evaluate`
//! and writes the table: Nimbus never re-implements the ramp's interpolation), colours
//! read as floats by their luminance (the add-on converts the table).
//! [`NODES`] lists what is compiled; any other node is an error naming it.

use super::attrs::{prim_error_str, SceneError};
use super::blender_color::{
    brightness_contrast, clamp, gamma, hsl_to_rgb, hsv_to_rgb, hue_saturation_value, invert,
    mix_color, mix_linear, nonzero, rgb_to_hsl, rgb_to_hsv, saturate, select,
};
use super::materialx_graph::{colour, number, usd_network};
use super::shader_network::{Input, ParamValue, ShaderNetwork, ShaderNode};
use crate::shader::graph::{Binary, Builder, GraphError, Program, Unary, Value as Reg};
use crate::shader::noise::{Dimensions, NoiseTexture, NoiseType};
use crate::shader::voronoi::{VoronoiFeature, VoronoiMetric, VoronoiOutput, VoronoiTexture};
use openusd::usd::{Prim, TimeCode};
use std::collections::HashMap;

/// The Blender node types compiled.
pub const NODES: &[&str] = &[
    "ShaderNodeTexCoord",
    "ShaderNodeTexNoise",
    "ShaderNodeTexVoronoi",
    "ShaderNodeTexGradient",
    "ShaderNodeValToRGB",
    "ShaderNodeRGBToBW",
    "ShaderNodeCombineXYZ",
    "ShaderNodeMath",
    "ShaderNodeMapRange",
    "ShaderNodeVectorMath",
    "ShaderNodeMapping",
    "ShaderNodeVectorRotate",
    "ShaderNodeSeparateXYZ",
    "ShaderNodeAttribute",
    "ShaderNodeValue",
    "ShaderNodeClamp",
    "ShaderNodeMix",
    "ShaderNodeMixRGB",
    "ShaderNodeInvert",
    "ShaderNodeVolumeInfo",
    "ShaderNodeFloatCurve",
    "ShaderNodeSeparateColor",
    "ShaderNodeCombineColor",
    "ShaderNodeHueSaturation",
    "ShaderNodeRGBCurve",
    "ShaderNodeVectorCurve",
    "ShaderNodeGamma",
    "ShaderNodeBrightContrast",
    "ShaderNodeTexWhiteNoise",
    "ShaderNodeBlackbody",
    "ShaderNodeTexWave",
    "ShaderNodeTexMagic",
];

/// A density graph read from Blender nodes.
#[derive(Clone, Debug, PartialEq)]
pub struct BlenderDensity {
    /// The graph's value (the attribute register holds the field named by `attribute`,
    /// when the graph reads one).
    pub program: Program,
    /// The field an Attribute node reads (one per graph).
    pub attribute: Option<String>,
}

/// The colour graph whose output `output` of the shader prim `shader` is connected to
/// a medium's emission colour (read with [`Program::eval_rgb`]).
pub fn usd_color(
    shader: &Prim,
    output: &str,
    time: Option<TimeCode>,
) -> Result<BlenderDensity, SceneError> {
    let network = usd_network(shader, time)?;
    let node = shader.path().as_str();
    let mut reader = Reader::new(&network);
    let v = reader.output(&(node.to_string(), output.to_string()))?;
    let attribute = reader.attribute.take();
    let program = reader
        .builder
        .finish_rgb(v)
        .map_err(|e| prim_error_str(node, e))?;
    Ok(BlenderDensity { program, attribute })
}

/// Blender's Math node operation `op` (its `operation` identifier) of `a`, `b` and `c`
/// (the third input, read by Multiply Add and Compare), with Cycles' semantics
/// ([`crate::shader::math`]); `None` for an operation not compiled.
pub fn math(bl: &mut Builder, op: &str, a: Reg, b: Reg, c: Reg) -> Result<Option<Reg>, GraphError> {
    let binary = match op {
        "ADD" => Some(Binary::Add),
        "SUBTRACT" => Some(Binary::Sub),
        "MULTIPLY" => Some(Binary::Mul),
        "DIVIDE" => Some(Binary::SafeDiv),
        "MINIMUM" => Some(Binary::Min),
        "MAXIMUM" => Some(Binary::Max),
        "LESS_THAN" => Some(Binary::Less),
        "GREATER_THAN" => Some(Binary::Greater),
        "POWER" => Some(Binary::Pow),
        "LOGARITHM" => Some(Binary::Log),
        "MODULO" => Some(Binary::Mod),
        "FLOORED_MODULO" => Some(Binary::FlooredMod),
        "ARCTAN2" => Some(Binary::Atan2),
        _ => None,
    };
    if let Some(o) = binary {
        return bl.binary(o, a, b).map(Some);
    }
    let unary = match op {
        "ABSOLUTE" => Some(Unary::Abs),
        "SQRT" => Some(Unary::Sqrt),
        "INVERSE_SQRT" => Some(Unary::InverseSqrt),
        "EXPONENT" => Some(Unary::Exp),
        "SIGN" => Some(Unary::Sign),
        "ROUND" => Some(Unary::Round),
        "FLOOR" => Some(Unary::Floor),
        "CEIL" => Some(Unary::Ceil),
        "TRUNC" => Some(Unary::Trunc),
        "FRACT" => Some(Unary::Fract),
        "SINE" => Some(Unary::Sin),
        "COSINE" => Some(Unary::Cos),
        "TANGENT" => Some(Unary::Tan),
        "ARCSINE" => Some(Unary::Asin),
        "ARCCOSINE" => Some(Unary::Acos),
        "ARCTANGENT" => Some(Unary::Atan),
        "SINH" => Some(Unary::Sinh),
        "COSH" => Some(Unary::Cosh),
        "TANH" => Some(Unary::Tanh),
        _ => None,
    };
    if let Some(o) = unary {
        return bl.unary(o, a).map(Some);
    }
    Ok(match op {
        "MULTIPLY_ADD" => {
            let m = bl.binary(Binary::Mul, a, b)?;
            Some(bl.binary(Binary::Add, m, c)?)
        }
        // Cycles: 1 where a == b or |a − b| ≤ max(c, FLT_EPSILON), else 0; written as
        // 1 − (|a − b| > max(c, ε)), the same for every a and b (a == b gives
        // |a − b| = 0, or NaN for equal infinities, and NaN > m is false).
        "COMPARE" => {
            let d = bl.binary(Binary::Sub, a, b)?;
            let d = bl.unary(Unary::Abs, d)?;
            let eps = bl.constant(f32::EPSILON)?;
            let m = bl.binary(Binary::Max, c, eps)?;
            let far = bl.binary(Binary::Greater, d, m)?;
            let one = bl.constant(1.0)?;
            Some(bl.binary(Binary::Sub, one, far)?)
        }
        // Cycles: a · (π/180) and a · (180/π), the constants in float.
        "RADIANS" => {
            let k = bl.constant(std::f32::consts::PI / 180.0)?;
            Some(bl.binary(Binary::Mul, a, k)?)
        }
        "DEGREES" => {
            let k = bl.constant(180.0 / std::f32::consts::PI)?;
            Some(bl.binary(Binary::Mul, a, k)?)
        }
        // Cycles' smoothminf: h = max(c − |a − b|, 0)/c, min(a, b) − h·h·h·c·(1/6), and
        // min(a, b) at c = 0 (a safe division gives h = 0 there); the same operations
        // in the same order.
        "SMOOTH_MIN" | "SMOOTH_MAX" => {
            let (a, b) = match op {
                "SMOOTH_MAX" => (bl.unary(Unary::Neg, a)?, bl.unary(Unary::Neg, b)?),
                _ => (a, b),
            };
            let d = bl.binary(Binary::Sub, a, b)?;
            let d = bl.unary(Unary::Abs, d)?;
            let zero = bl.constant(0.0)?;
            let h = bl.binary(Binary::Sub, c, d)?;
            let h = bl.binary(Binary::Max, h, zero)?;
            let h = bl.binary(Binary::SafeDiv, h, c)?;
            let m = bl.binary(Binary::Min, a, b)?;
            let t = bl.binary(Binary::Mul, h, h)?;
            let t = bl.binary(Binary::Mul, t, h)?;
            let t = bl.binary(Binary::Mul, t, c)?;
            let sixth = bl.constant(1.0 / 6.0)?;
            let t = bl.binary(Binary::Mul, t, sixth)?;
            let v = bl.binary(Binary::Sub, m, t)?;
            Some(match op {
                "SMOOTH_MAX" => bl.unary(Unary::Neg, v)?,
                _ => v,
            })
        }
        // Cycles: floor(safe_divide(a, b)) · b.
        "SNAP" => {
            let q = bl.binary(Binary::SafeDiv, a, b)?;
            let q = bl.unary(Unary::Floor, q)?;
            Some(bl.binary(Binary::Mul, q, b)?)
        }
        // Cycles' wrapf(a, b, c): with r = b − c, a − r·floor((a − c)/r) where r ≠ 0,
        // else c. The choice is written as z·v + (1 − z)·c with z = (|r| > 0): exactly v
        // or c (0·v and 0·c add nothing), the safe division giving a finite v at r = 0.
        "WRAP" => {
            let r = bl.binary(Binary::Sub, b, c)?;
            let n = bl.binary(Binary::Sub, a, c)?;
            let q = bl.binary(Binary::SafeDiv, n, r)?;
            let q = bl.unary(Unary::Floor, q)?;
            let q = bl.binary(Binary::Mul, r, q)?;
            let v = bl.binary(Binary::Sub, a, q)?;
            let zero = bl.constant(0.0)?;
            let size = bl.unary(Unary::Abs, r)?;
            let z = bl.binary(Binary::Greater, size, zero)?;
            Some(select(bl, z, v, c)?)
        }
        // Cycles' pingpongf: |fract((a − b)/(2b))·b·2 − b|, 0 at b = 0 (the safe
        // division gives fract(0) = 0 and so 0 there).
        "PINGPONG" => {
            let two = bl.constant(2.0)?;
            let n = bl.binary(Binary::Sub, a, b)?;
            let w = bl.binary(Binary::Mul, b, two)?;
            let t = bl.binary(Binary::SafeDiv, n, w)?;
            let f = bl.unary(Unary::Fract, t)?;
            let f = bl.binary(Binary::Mul, f, b)?;
            let f = bl.binary(Binary::Mul, f, two)?;
            let f = bl.binary(Binary::Sub, f, b)?;
            Some(bl.unary(Unary::Abs, f)?)
        }
        _ => None,
    })
}

/// Whether Vector Math's operation `op` reads its second and third vectors.
pub fn vector_math_operands(op: &str) -> (bool, bool) {
    match op {
        "MULTIPLY_ADD" | "WRAP" | "FACEFORWARD" => (true, true),
        "ABSOLUTE" | "FLOOR" | "CEIL" | "FRACTION" | "SINE" | "COSINE" | "TANGENT" | "SIGN"
        | "LENGTH" | "NORMALIZE" | "SCALE" => (false, false),
        _ => (true, false),
    }
}

/// Blender's Vector Math node, operation `op` (its identifier) of the vectors `a`, `b`,
/// `c` (sockets Vector, Vector_001, Vector_002) and the float `scale`, as Cycles'
/// `svm_vector_math` computes it (every operation of Blender 5.0; `None` for an
/// identifier it does not have). The entry-wise operations are the Math node's ([`math`]) on each
/// component, as Cycles defines them (Fraction is Math's Fract). Cross Product, Project,
/// Normalize, Faceforward, Reflect and Refract are written out with Cycles' definitions
/// (`util/math_float3.h`):
/// `project(a, b)` = (a·b / b·b) b, 0 where b·b = 0; `safe_normalize(a)` = a / |a|, 0 at
/// |a| = 0 (a itself there, which is 0 but for vectors whose squared length
/// underflows); faceforward = a where b·c < 0, else −a. tests/blender_math.rs checks
/// every operation against bpy 5.0.1.
pub fn vector_math(
    bl: &mut Builder,
    op: &str,
    a: Reg,
    b: Reg,
    c: Reg,
    scale: Reg,
) -> Result<Option<Reg>, GraphError> {
    let entrywise = match op {
        "ADD" | "SUBTRACT" | "MULTIPLY" | "DIVIDE" | "MULTIPLY_ADD" | "MINIMUM" | "MAXIMUM"
        | "ABSOLUTE" | "FLOOR" | "CEIL" | "MODULO" | "WRAP" | "SNAP" | "SINE" | "COSINE"
        | "TANGENT" | "POWER" | "SIGN" => Some(op),
        "FRACTION" => Some("FRACT"),
        _ => None,
    };
    if let Some(m) = entrywise {
        return math(bl, m, a, b, c);
    }
    Ok(match op {
        "SCALE" => Some(bl.binary(Binary::Mul, a, scale)?),
        "LENGTH" => Some(bl.magnitude(a)?),
        "DOT_PRODUCT" => Some(bl.dot(a, b)?),
        "DISTANCE" => {
            let d = bl.binary(Binary::Sub, a, b)?;
            Some(bl.magnitude(d)?)
        }
        "CROSS_PRODUCT" => {
            // (a.y b.z − a.z b.y, a.z b.x − a.x b.z, a.x b.y − a.y b.x)
            let mut out = [a; 3];
            for (k, out) in out.iter_mut().enumerate() {
                let (i, j) = (((k + 1) % 3) as u16, ((k + 2) % 3) as u16);
                let (ai, aj) = (bl.component(a, i)?, bl.component(a, j)?);
                let (bi, bj) = (bl.component(b, i)?, bl.component(b, j)?);
                let p = bl.binary(Binary::Mul, ai, bj)?;
                let q = bl.binary(Binary::Mul, aj, bi)?;
                *out = bl.binary(Binary::Sub, p, q)?;
            }
            Some(bl.combine3(out[0], out[1], out[2])?)
        }
        "PROJECT" => {
            let ab = bl.dot(a, b)?;
            let bb = bl.dot(b, b)?;
            let f = bl.binary(Binary::SafeDiv, ab, bb)?;
            Some(bl.binary(Binary::Mul, f, b)?)
        }
        "NORMALIZE" => Some(safe_normalize(bl, a)?),
        "REFLECT" => {
            // a − 2 (a·n) n with n = safe_normalize(b).
            let n = safe_normalize(bl, b)?;
            let d = bl.dot(a, n)?;
            let two = bl.constant(2.0)?;
            let d2 = bl.binary(Binary::Mul, d, two)?;
            let t = bl.binary(Binary::Mul, d2, n)?;
            Some(bl.binary(Binary::Sub, a, t)?)
        }
        "REFRACT" => {
            // With n = safe_normalize(b), d = n·a and η = Scale (the IOR socket):
            // k = 1 − η² (1 − d²); 0 where k < 0 (total internal reflection), else
            // η a − (η d + √k) n. The zero is a product with the keep mask (the
            // graph's √ is of max(k, 0), so no NaN reaches it).
            let n = safe_normalize(bl, b)?;
            let d = bl.dot(n, a)?;
            let one = bl.constant(1.0)?;
            let zero = bl.constant(0.0)?;
            let eta2 = bl.binary(Binary::Mul, scale, scale)?;
            let dd = bl.binary(Binary::Mul, d, d)?;
            let sin2 = bl.binary(Binary::Sub, one, dd)?;
            let e = bl.binary(Binary::Mul, eta2, sin2)?;
            let k = bl.binary(Binary::Sub, one, e)?;
            let total = bl.binary(Binary::Less, k, zero)?;
            let keep = bl.binary(Binary::Sub, one, total)?;
            let root = bl.unary(Unary::Sqrt, k)?;
            let ea = bl.binary(Binary::Mul, scale, a)?;
            let ed = bl.binary(Binary::Mul, scale, d)?;
            let f = bl.binary(Binary::Add, ed, root)?;
            let fn_ = bl.binary(Binary::Mul, f, n)?;
            let v = bl.binary(Binary::Sub, ea, fn_)?;
            Some(bl.binary(Binary::Mul, v, keep)?)
        }
        "FACEFORWARD" => {
            // s = 1 − 2 (b·c < 0 ? 0 : 1): ±1, then s·a.
            let d = bl.dot(b, c)?;
            let zero = bl.constant(0.0)?;
            let front = bl.binary(Binary::Less, d, zero)?;
            let one = bl.constant(1.0)?;
            let back = bl.binary(Binary::Sub, one, front)?;
            let two = bl.constant(2.0)?;
            let flip = bl.binary(Binary::Mul, back, two)?;
            let sign = bl.binary(Binary::Sub, one, flip)?;
            Some(bl.binary(Binary::Mul, a, sign)?)
        }
        _ => None,
    })
}

/// Cycles' rotation matrix of the Euler angles `e` (radians, XYZ order: about X, then
/// Y, then Z), computed in float as `euler_to_transform` does: row `i` gives component
/// `i` of the rotated vector.
pub fn euler_xyz(e: [f32; 3]) -> [[f32; 3]; 3] {
    let (sx, cx) = e[0].sin_cos();
    let (sy, cy) = e[1].sin_cos();
    let (sz, cz) = e[2].sin_cos();
    [
        [cy * cz, sy * sx * cz - cx * sz, sy * cx * cz + sx * sz],
        [cy * sz, sy * sx * sz + cx * cz, sy * cx * sz - sx * cz],
        [-sy, cy * sx, cy * cx],
    ]
}

/// `m` (or its transpose) times `v`, each component the dot product of a row (a
/// column) with `v`, summed x + y, then + z as Cycles' `transform_direction`. The range
/// analysis bounds each component exactly: a constant times an interval, summed.
fn rotate(bl: &mut Builder, m: [[f32; 3]; 3], v: Reg, transposed: bool) -> Result<Reg, GraphError> {
    let mut rows = [v; 3];
    for (i, r) in rows.iter_mut().enumerate() {
        *r = match transposed {
            false => bl.vector3(m[i])?,
            true => bl.vector3([m[0][i], m[1][i], m[2][i]])?,
        };
    }
    times_rows(bl, rows, v)
}

/// The vector of the dot products of each of `rows` with `v`.
fn times_rows(bl: &mut Builder, rows: [Reg; 3], v: Reg) -> Result<Reg, GraphError> {
    let mut out = [v; 3];
    for (o, row) in out.iter_mut().zip(rows) {
        *o = bl.dot(v, row)?;
    }
    bl.combine3(out[0], out[1], out[2])
}

/// A rotation by Euler angles (XYZ, radians): constant, a matrix computed once; or
/// the value of a linked socket, a matrix computed per lookup.
#[derive(Clone, Copy, Debug)]
pub enum Rotation {
    Constant([f32; 3]),
    Linked(Reg),
}

impl Rotation {
    /// `v` rotated (by the inverse, the transposed matrix, with `inverse`). A zero
    /// constant rotation is left out (Cycles multiplies by the identity, which changes
    /// no finite value).
    fn apply(self, bl: &mut Builder, v: Reg, inverse: bool) -> Result<Reg, GraphError> {
        match self {
            Rotation::Constant(e) if e == [0.0; 3] => Ok(v),
            Rotation::Constant(e) => rotate(bl, euler_xyz(e), v, inverse),
            Rotation::Linked(e) => {
                let m = euler_xyz_of(bl, e)?;
                let mut rows = [v; 3];
                for (i, r) in rows.iter_mut().enumerate() {
                    *r = match inverse {
                        false => bl.combine3(m[i][0], m[i][1], m[i][2])?,
                        true => bl.combine3(m[0][i], m[1][i], m[2][i])?,
                    };
                }
                times_rows(bl, rows, v)
            }
        }
    }
}

/// [`euler_xyz`] of angles the graph computes: the same products in the same order,
/// per lookup (the range analysis bounds them through sine, cosine and the products'
/// intervals).
fn euler_xyz_of(bl: &mut Builder, e: Reg) -> Result<[[Reg; 3]; 3], GraphError> {
    let e = bl.splat3(e)?;
    let mut sin = [e; 3];
    let mut cos = [e; 3];
    for k in 0..3 {
        let a = bl.component(e, k as u16)?;
        sin[k] = bl.unary(Unary::Sin, a)?;
        cos[k] = bl.unary(Unary::Cos, a)?;
    }
    let ([sx, sy, sz], [cx, cy, cz]) = (sin, cos);
    let mul = |bl: &mut Builder, a: Reg, b: Reg| bl.binary(Binary::Mul, a, b);
    let cy_cz = mul(bl, cy, cz)?;
    let sy_sx = mul(bl, sy, sx)?;
    let sy_cx = mul(bl, sy, cx)?;
    let (t, u) = (mul(bl, sy_sx, cz)?, mul(bl, cx, sz)?);
    let m01 = bl.binary(Binary::Sub, t, u)?;
    let (t, u) = (mul(bl, sy_cx, cz)?, mul(bl, sx, sz)?);
    let m02 = bl.binary(Binary::Add, t, u)?;
    let m10 = mul(bl, cy, sz)?;
    let (t, u) = (mul(bl, sy_sx, sz)?, mul(bl, cx, cz)?);
    let m11 = bl.binary(Binary::Add, t, u)?;
    let (t, u) = (mul(bl, sy_cx, sz)?, mul(bl, sx, cz)?);
    let m12 = bl.binary(Binary::Sub, t, u)?;
    let m20 = bl.unary(Unary::Neg, sy)?;
    let m21 = mul(bl, cy, sx)?;
    let m22 = mul(bl, cy, cx)?;
    Ok([[cy_cz, m01, m02], [m10, m11, m12], [m20, m21, m22]])
}

/// `p` rotated by `angle` about the unit `axis` as Cycles' `rotate_around_axis`: each
/// entry (1 − cos)·a_i·a_j ± a_k·sin (cos + (1 − cos)·a_i² on the diagonal), each row's
/// products summed x + y, then + z.
fn rotate_around_axis(bl: &mut Builder, p: Reg, axis: Reg, angle: Reg) -> Result<Reg, GraphError> {
    let c = bl.unary(Unary::Cos, angle)?;
    let s = bl.unary(Unary::Sin, angle)?;
    let one = bl.constant(1.0)?;
    let k = bl.binary(Binary::Sub, one, c)?;
    let a = [
        bl.component(axis, 0)?,
        bl.component(axis, 1)?,
        bl.component(axis, 2)?,
    ];
    let entry = |bl: &mut Builder, i: usize, j: usize| -> Result<Reg, GraphError> {
        // (1 − cos)·a_x·a_y, never ·a_y·a_x: the lower axis first, as Cycles writes
        // both entries (the same rounding on each side of the diagonal).
        let ka = bl.binary(Binary::Mul, k, a[i.min(j)])?;
        let kaa = bl.binary(Binary::Mul, ka, a[i.max(j)])?;
        if i == j {
            return bl.binary(Binary::Add, c, kaa);
        }
        // The sine term, a_k·sin (k the third axis): added at (x, z), (y, x), (z, y),
        // subtracted at the others, a right-handed rotation by `angle`.
        let other = 3 - i - j;
        let sine = bl.binary(Binary::Mul, a[other], s)?;
        let plus = matches!((i, j), (1, 0) | (2, 1) | (0, 2));
        let op = if plus { Binary::Add } else { Binary::Sub };
        bl.binary(op, kaa, sine)
    };
    let mut rows = [p; 3];
    for (i, row) in rows.iter_mut().enumerate() {
        let r = [entry(bl, i, 0)?, entry(bl, i, 1)?, entry(bl, i, 2)?];
        *row = bl.combine3(r[0], r[1], r[2])?;
    }
    times_rows(bl, rows, p)
}

/// Blender's Vector Rotate node of `rotation_type` `ty` on `v` about `center`, as
/// Cycles' `svm_node_vector_rotate`: Euler XYZ rotates v − center by the matrix of
/// `rotation` (its transpose with `invert`); Axis Angle about `axis` normalized (v
/// itself where the axis has no length), X, Y and Z Axis about those, by `angle`
/// (−angle with `invert`); then + center. `None` for another type.
#[allow(clippy::too_many_arguments)]
pub fn vector_rotate(
    bl: &mut Builder,
    ty: &str,
    invert: bool,
    v: Reg,
    center: Reg,
    axis: Reg,
    angle: Reg,
    rotation: Rotation,
) -> Result<Option<Reg>, GraphError> {
    let fixed = match ty {
        "X_AXIS" => Some([1.0, 0.0, 0.0]),
        "Y_AXIS" => Some([0.0, 1.0, 0.0]),
        "Z_AXIS" => Some([0.0, 0.0, 1.0]),
        "AXIS_ANGLE" | "EULER_XYZ" => None,
        _ => return Ok(None),
    };
    let d = bl.binary(Binary::Sub, v, center)?;
    if ty == "EULER_XYZ" {
        let r = rotation.apply(bl, d, invert)?;
        return Ok(Some(bl.binary(Binary::Add, r, center)?));
    }
    let angle = match invert {
        true => bl.unary(Unary::Neg, angle)?,
        false => angle,
    };
    if let Some(a) = fixed {
        let a = bl.vector3(a)?;
        let r = rotate_around_axis(bl, d, a, angle)?;
        return Ok(Some(bl.binary(Binary::Add, r, center)?));
    }
    let length = bl.magnitude(axis)?;
    let unit = bl.binary(Binary::SafeDiv, axis, length)?;
    let r = rotate_around_axis(bl, d, unit, angle)?;
    let r = bl.binary(Binary::Add, r, center)?;
    let zero = bl.constant(0.0)?;
    let some = bl.binary(Binary::Greater, length, zero)?;
    Ok(Some(select(bl, some, r, v)?))
}

/// Blender's Mapping node of type `ty` (its `vector_type`) on `v`, as Cycles'
/// `svm_mapping`, with R the rotation `rotation`:
/// Point R(v × scale) + location; Texture R⁻¹(v − location) ÷ scale (0 where a scale is
/// 0); Vector R(v × scale); Normal the unit vector of R(v ÷ scale) (0 stays 0). `None`
/// for another type. tests/blender_math.rs checks each against bpy 5.0.1.
pub fn mapping(
    bl: &mut Builder,
    ty: &str,
    v: Reg,
    location: Reg,
    rotation: Rotation,
    scale: Reg,
) -> Result<Option<Reg>, GraphError> {
    Ok(Some(match ty {
        "POINT" => {
            let vs = bl.binary(Binary::Mul, v, scale)?;
            let r = rotation.apply(bl, vs, false)?;
            bl.binary(Binary::Add, r, location)?
        }
        "TEXTURE" => {
            let d = bl.binary(Binary::Sub, v, location)?;
            let r = rotation.apply(bl, d, true)?;
            bl.binary(Binary::SafeDiv, r, scale)?
        }
        "VECTOR" => {
            let vs = bl.binary(Binary::Mul, v, scale)?;
            rotation.apply(bl, vs, false)?
        }
        "NORMAL" => {
            let vs = bl.binary(Binary::SafeDiv, v, scale)?;
            let r = rotation.apply(bl, vs, false)?;
            safe_normalize(bl, r)?
        }
        _ => return Ok(None),
    }))
}

/// Blender's Float Curve as Cycles evaluates it (`svm_node_curve`): the curve sampled
/// into `table` at min + (i / (n − 1))·(max − min) (the add-on evaluates Blender's own
/// curve there, as Cycles' `curvemapping_float_to_array` does), read at (value − min) /
/// (max − min) linearly between entries, clamped into the table or, with
/// `extrapolate`, continued along its first or last segment; then (1 − fac)·value +
/// fac·curve. The extrapolated branches are chosen by [`select`], exact where they
/// are finite (the reader refuses a curve with no x range, where they are not).
pub fn float_curve(
    bl: &mut Builder,
    table: Vec<f32>,
    (min, max): (f32, f32),
    extrapolate: bool,
    fac: Reg,
    value: Reg,
) -> Result<Reg, GraphError> {
    let n = table.len();
    let ends = (n >= 2).then(|| (table[0], table[1], table[n - 1], table[n - 2]));
    let lo = bl.constant(min)?;
    let range = bl.constant(max - min)?;
    let rel = bl.binary(Binary::Sub, value, lo)?;
    let rel = bl.binary(Binary::Div, rel, range)?;
    let mut v = bl.ramp(rel, table, true)?;
    if let (true, Some((first, second, last, before))) = (extrapolate, ends) {
        let steps = bl.constant((n - 1) as f32)?;
        let one = bl.constant(1.0)?;
        let zero = bl.constant(0.0)?;
        // Below 0: first + (first − second)·(−rel)·(n − 1).
        let below = bl.unary(Unary::Neg, rel)?;
        let dy = bl.constant(first - second)?;
        let below = bl.binary(Binary::Mul, dy, below)?;
        let below = bl.binary(Binary::Mul, below, steps)?;
        let t0 = bl.constant(first)?;
        let below = bl.binary(Binary::Add, t0, below)?;
        // Above 1: last + (last − before)·(rel − 1)·(n − 1).
        let above = bl.binary(Binary::Sub, rel, one)?;
        let dy = bl.constant(last - before)?;
        let above = bl.binary(Binary::Mul, dy, above)?;
        let above = bl.binary(Binary::Mul, above, steps)?;
        let t1 = bl.constant(last)?;
        let above = bl.binary(Binary::Add, t1, above)?;
        let z = bl.binary(Binary::Greater, rel, one)?;
        v = select(bl, z, above, v)?;
        let z = bl.binary(Binary::Less, rel, zero)?;
        v = select(bl, z, below, v)?;
    }
    bl.mix(value, v, fac)
}

/// Blender's RGB Curves and Vector Curves (Cycles' `svm_node_curves`): each channel of
/// `c` through its own table, as [`float_curve`] does one value, over the range
/// (min, max) the tables share (the x extent of every curve), then mixed with `c` by
/// `fac`. The add-on writes the tables as Cycles bakes them
/// (`curvemapping_color_to_array`): RGB Curves' combined curve is applied first.
pub fn curves(
    bl: &mut Builder,
    tables: [Vec<f32>; 3],
    range: (f32, f32),
    extrapolate: bool,
    fac: Reg,
    c: Reg,
) -> Result<Reg, GraphError> {
    let c = bl.splat3(c)?;
    let [r, g, b] = tables;
    let mut out = Vec::with_capacity(3);
    for (k, table) in [r, g, b].into_iter().enumerate() {
        let x = bl.component(c, k as u16)?;
        out.push(float_curve(bl, table, range, extrapolate, fac, x)?);
    }
    bl.combine3(out[0], out[1], out[2])
}

/// Blender's Wave Texture (Cycles' `svm_wave`) at `co` scaled by `scale`: bands along
/// an axis or the diagonal, or rings around an axis or a point, 20 per unit, shifted by
/// `phase` and by `distortion` × (2·fBM − 1) (`detail`, the fBM of the Noise Texture at
/// Scale `detail_scale`, Lacunarity 2, normalized; skipped where `distortion` is the
/// constant 0, where it adds 0), through a sine, saw or triangle profile in [0, 1].
/// Each operation rounded on its own, in Cycles' order (its SSE4.2 kernel; the AVX2
/// kernel fuses the scaling and the profile's multiply-adds).
#[allow(clippy::too_many_arguments)]
pub fn wave(
    bl: &mut Builder,
    co: Reg,
    scale: Reg,
    (kind, direction, profile): (&str, &str, &str),
    distortion: Option<Reg>,
    detail: NoiseTexture,
    phase: Reg,
) -> Result<Option<Reg>, GraphError> {
    let co = bl.splat3(co)?;
    // Cycles' guard against precision issues on unit coordinates.
    let p = bl.binary(Binary::Mul, co, scale)?;
    let tiny = bl.constant(1e-6)?;
    let p = bl.binary(Binary::Add, p, tiny)?;
    let shrink = bl.constant(0.999_999)?;
    let p = bl.binary(Binary::Mul, p, shrink)?;
    let axis = |d: &str| match d {
        "X" => Some(0u16),
        "Y" => Some(1),
        "Z" => Some(2),
        _ => None,
    };
    let n = match (kind, direction) {
        ("BANDS", "DIAGONAL") => {
            let [x, y, z] = [0, 1, 2].map(|k| bl.component(p, k));
            let s = bl.binary(Binary::Add, x?, y?)?;
            let s = bl.binary(Binary::Add, s, z?)?;
            let ten = bl.constant(10.0)?;
            bl.binary(Binary::Mul, s, ten)?
        }
        ("BANDS", d) => {
            let Some(k) = axis(d) else { return Ok(None) };
            let v = bl.component(p, k)?;
            let twenty = bl.constant(20.0)?;
            bl.binary(Binary::Mul, v, twenty)?
        }
        ("RINGS", d) => {
            // The ring's axis component multiplied by 0 (so ±0), as Cycles does.
            let keep = match (d, axis(d)) {
                ("SPHERICAL", _) => [1.0; 3],
                (_, Some(k)) => std::array::from_fn(|a| if a == k as usize { 0.0 } else { 1.0 }),
                _ => return Ok(None),
            };
            let keep = bl.vector3(keep)?;
            let rp = bl.binary(Binary::Mul, p, keep)?;
            let sq = bl.binary(Binary::Mul, rp, rp)?;
            let [x, y, z] = [0, 1, 2].map(|k| bl.component(sq, k));
            let s = bl.binary(Binary::Add, x?, y?)?;
            let s = bl.binary(Binary::Add, s, z?)?;
            let len = bl.unary(Unary::Sqrt, s)?;
            let twenty = bl.constant(20.0)?;
            bl.binary(Binary::Mul, len, twenty)?
        }
        _ => return Ok(None),
    };
    let mut n = bl.binary(Binary::Add, n, phase)?;
    if let Some(d) = distortion {
        let w = bl.constant(0.0)?;
        let fb = bl.blender_noise(p, w, detail)?;
        let t = bl.binary(Binary::Add, fb, fb)?;
        let one = bl.constant(1.0)?;
        let t = bl.binary(Binary::Sub, t, one)?;
        let t = bl.binary(Binary::Mul, d, t)?;
        n = bl.binary(Binary::Add, n, t)?;
    }
    let half = bl.constant(0.5)?;
    let inv_two_pi = bl.constant(0.159_154_94)?;
    Ok(Some(match profile {
        "SIN" => {
            let quarter = bl.constant(std::f32::consts::FRAC_PI_2)?;
            let a = bl.binary(Binary::Sub, n, quarter)?;
            let s = bl.unary(Unary::Sin, a)?;
            let s = bl.binary(Binary::Mul, s, half)?;
            bl.binary(Binary::Add, s, half)?
        }
        "SAW" => {
            let m = bl.binary(Binary::Mul, n, inv_two_pi)?;
            let f = bl.unary(Unary::Floor, m)?;
            bl.binary(Binary::Sub, m, f)?
        }
        "TRI" => {
            let m = bl.binary(Binary::Mul, n, inv_two_pi)?;
            let mh = bl.binary(Binary::Add, m, half)?;
            let f = bl.unary(Unary::Floor, mh)?;
            let d = bl.binary(Binary::Sub, m, f)?;
            let d = bl.unary(Unary::Abs, d)?;
            let two = bl.constant(2.0)?;
            bl.binary(Binary::Mul, d, two)?
        }
        _ => return Ok(None),
    }))
}

/// Blender's Magic Texture (Cycles' `svm_magic`) at `co` (each component taken modulo
/// 2π first (fmodf), against the loss of precision of sin and cos far out), scaled by `scale` inside the first
/// sines: three trigonometric waves, then `depth` (0 to 10) rounds of turbulence, each
/// multiplied by `distortion`, divided by 2·distortion unless it is 0: the Color (0.5 −
/// x, 0.5 − y, 0.5 − z). Each operation rounded on its own, in Cycles' order (its
/// SSE4.2 kernel, which multiplies by 0.5 / distortion where the source divides).
pub fn magic(bl: &mut Builder, co: Reg, scale: Reg, depth: u32, d: Reg) -> Result<Reg, GraphError> {
    let co = bl.splat3(co)?;
    let period = bl.constant(6.283_185_5)?;
    let p = bl.binary(Binary::Mod, co, period)?;
    let [px, py, pz] = [0, 1, 2].map(|k| bl.component(p, k));
    let (px, py, pz) = (px?, py?, pz?);
    let five = bl.constant(5.0)?;
    // One argument of the first waves: ((a + b) + c) · 5 · scale.
    let wave = |bl: &mut Builder, a: Reg, b: Reg, c: Reg, op: Unary, negate: bool| {
        let s = bl.binary(Binary::Add, a, b)?;
        let s = bl.binary(Binary::Add, s, c)?;
        let s = bl.binary(Binary::Mul, s, five)?;
        let s = bl.binary(Binary::Mul, s, scale)?;
        let v = bl.unary(op, s)?;
        match negate {
            true => bl.unary(Unary::Neg, v),
            false => Ok(v),
        }
    };
    let (npx, npz) = (bl.unary(Unary::Neg, px)?, bl.unary(Unary::Neg, pz)?);
    let mut x = wave(bl, px, py, pz, Unary::Sin, false)?;
    // (py − px) − pz and (−px − py) + pz as sums of negated terms: the same roundings.
    let mut y = wave(bl, py, npx, npz, Unary::Cos, false)?;
    let npy = bl.unary(Unary::Neg, py)?;
    let mut z = wave(bl, npx, npy, pz, Unary::Cos, true)?;
    // One round: f(±a ± b ± c) · d, the signs of x, y, z in `signs`.
    let round = |bl: &mut Builder,
                 [x, y, z]: [Reg; 3],
                 order: [usize; 3],
                 signs: [bool; 3],
                 op: Unary,
                 negate: bool|
     -> Result<Reg, GraphError> {
        let v = [x, y, z];
        let term = |bl: &mut Builder, k: usize| match signs[k] {
            true => Ok(v[order[k]]),
            false => bl.unary(Unary::Neg, v[order[k]]),
        };
        let a = term(bl, 0)?;
        let b = term(bl, 1)?;
        let c = term(bl, 2)?;
        let s = bl.binary(Binary::Add, a, b)?;
        let s = bl.binary(Binary::Add, s, c)?;
        let f = bl.unary(op, s)?;
        let f = match negate {
            true => bl.unary(Unary::Neg, f)?,
            false => f,
        };
        bl.binary(Binary::Mul, f, d)
    };
    if depth > 0 {
        let x1 = bl.binary(Binary::Mul, x, d)?;
        let z1 = bl.binary(Binary::Mul, z, d)?;
        let yd = bl.binary(Binary::Mul, y, d)?;
        let arg = bl.binary(Binary::Sub, x1, yd)?;
        let arg = bl.binary(Binary::Add, arg, z1)?;
        let c = bl.unary(Unary::Cos, arg)?;
        let c = bl.unary(Unary::Neg, c)?;
        y = bl.binary(Binary::Mul, c, d)?;
        (x, z) = (x1, z1);
    }
    // Rounds 2 to 10: (which of x, y, z it writes; the terms' order and signs; cos or
    // sin; negated).
    type Round = (usize, [usize; 3], [bool; 3], bool, bool);
    const ROUNDS: [Round; 9] = [
        (0, [0, 1, 2], [true, false, false], true, false),
        (2, [0, 1, 2], [false, false, false], false, false),
        (0, [1, 0, 2], [true, false, false], true, true),
        (1, [1, 0, 2], [true, false, true], false, true),
        (1, [1, 0, 2], [true, false, true], true, true),
        (0, [0, 1, 2], [true, true, true], true, false),
        (2, [0, 1, 2], [true, true, false], false, false),
        (0, [0, 1, 2], [false, false, true], true, true),
        (1, [0, 1, 2], [true, false, true], false, true),
    ];
    for &(out, order, signs, cos, negate) in ROUNDS.iter().take(depth.saturating_sub(1) as usize) {
        let op = if cos { Unary::Cos } else { Unary::Sin };
        let v = round(bl, [x, y, z], order, signs, op, negate)?;
        match out {
            0 => x = v,
            1 => y = v,
            _ => z = v,
        }
    }
    // Divided by 2·d where d ≠ 0 (at every depth), as 0.5 / d times each: r is 1
    // where d is 0, so the branch not taken stays finite and the select exact.
    let (one, half) = (bl.constant(1.0)?, bl.constant(0.5)?);
    let divides = nonzero(bl, d)?;
    let r = bl.binary(Binary::SafeDiv, half, d)?;
    let r = select(bl, divides, r, one)?;
    let v = bl.combine3(x, y, z)?;
    let v = bl.binary(Binary::Mul, v, r)?;
    bl.binary(Binary::Sub, half, v)
}

/// The Magic Texture's Fac: ((r + g) + b) · 0.33333334 of its Color.
pub fn magic_fac(bl: &mut Builder, color: Reg) -> Result<Reg, GraphError> {
    let [r, g, b] = [0, 1, 2].map(|k| bl.component(color, k));
    let s = bl.binary(Binary::Add, r?, g?)?;
    let s = bl.binary(Binary::Add, s, b?)?;
    let third = bl.constant(0.333_333_34)?;
    bl.binary(Binary::Mul, s, third)
}

/// Blender's Map Range on floats with interpolation `kind` (its identifier) of `x` from
/// [from min, from max] to [to min, to max] (`v`, in that order): the factor
/// safe_divide(x − from min, from max − from min) shaped by the interpolation, then to
/// min + factor × (to max − to min), clamped between the two for Linear and Stepped
/// when `clamp` (as Cycles and Geometry Nodes). Stepped: floor(factor (steps + 1)) /
/// steps, 0 for steps ≤ 0; 0 before the clamp where from min = from max (both as
/// Cycles' `svm_node_map_range`). `None` for another kind.
/// tests/blender_math.rs checks each against bpy 5.0.1.
pub fn map_range(
    b: &mut Builder,
    kind: &str,
    v: [Reg; 5],
    steps: f32,
    clamp: bool,
) -> Result<Option<Reg>, GraphError> {
    let [x, fmin, fmax, tmin, tmax] = v;
    let num = b.binary(Binary::Sub, x, fmin)?;
    let den = b.binary(Binary::Sub, fmax, fmin)?;
    let mut f = b.binary(Binary::SafeDiv, num, den)?;
    match kind {
        "LINEAR" => {}
        "SMOOTHSTEP" => {
            let (zero, one) = (b.constant(0.0)?, b.constant(1.0)?);
            f = b.smoothstep(f, zero, one)?;
        }
        "SMOOTHERSTEP" => f = b.unary(Unary::Smootherstep, f)?,
        "STEPPED" if steps > 0.0 => {
            let k = b.constant(steps + 1.0)?;
            let n = b.constant(steps)?;
            let scaled = b.binary(Binary::Mul, f, k)?;
            let floor = b.unary(Unary::Floor, scaled)?;
            f = b.binary(Binary::Div, floor, n)?;
        }
        "STEPPED" => f = b.constant(0.0)?,
        _ => return Ok(None),
    }
    let span = b.binary(Binary::Sub, tmax, tmin)?;
    let scaled = b.binary(Binary::Mul, f, span)?;
    let mapped = b.binary(Binary::Add, tmin, scaled)?;
    // Cycles' result is 0 where from min = from max (Geometry Nodes' is to min): the
    // mapped value times (from min ≠ from max), 1 or 0. Constant edges (the common
    // case) give a point interval, so the bound does not widen.
    let below = b.binary(Binary::Less, fmin, fmax)?;
    let above = b.binary(Binary::Greater, fmin, fmax)?;
    let distinct = b.binary(Binary::Add, below, above)?;
    let r = b.binary(Binary::Mul, mapped, distinct)?;
    if !(clamp && matches!(kind, "LINEAR" | "STEPPED")) {
        return Ok(Some(r));
    }
    // Between to min and to max, whichever is larger (the smooth kinds stay there by
    // construction and are not clamped).
    let lo = b.binary(Binary::Min, tmin, tmax)?;
    let hi = b.binary(Binary::Max, tmin, tmax)?;
    Ok(Some(b.clamp(r, lo, hi)?))
}

/// Blender's Gradient Texture of type `kind` (its identifier) at the vector `p`: its Fac,
/// as Cycles' `svm_gradient` computes it then saturated; `None` for a type Blender does
/// not have. tests/blender_math.rs checks every type against bpy 5.0.1.
pub fn gradient(bl: &mut Builder, kind: &str, p: Reg) -> Result<Option<Reg>, GraphError> {
    let x = bl.component(p, 0)?;
    let zero = bl.constant(0.0)?;
    let one = bl.constant(1.0)?;
    let g = match kind {
        "LINEAR" => x,
        "QUADRATIC" => {
            let r = bl.binary(Binary::Max, x, zero)?;
            bl.binary(Binary::Mul, r, r)?
        }
        "EASING" => {
            // r = saturate(x), t = r²: 3t − 2t r.
            let r = bl.clamp(x, zero, one)?;
            let t = bl.binary(Binary::Mul, r, r)?;
            let three = bl.constant(3.0)?;
            let two = bl.constant(2.0)?;
            let a = bl.binary(Binary::Mul, three, t)?;
            let b = bl.binary(Binary::Mul, two, t)?;
            let b = bl.binary(Binary::Mul, b, r)?;
            bl.binary(Binary::Sub, a, b)?
        }
        "DIAGONAL" => {
            let y = bl.component(p, 1)?;
            let s = bl.binary(Binary::Add, x, y)?;
            let half = bl.constant(0.5)?;
            bl.binary(Binary::Mul, s, half)?
        }
        "RADIAL" => {
            // atan2(y, x) / 2π + 1/2: the angle about z in turns, 0 and 1 along −x.
            let y = bl.component(p, 1)?;
            let a = bl.binary(Binary::Atan2, y, x)?;
            let turn = bl.constant(std::f32::consts::TAU)?;
            let a = bl.binary(Binary::Div, a, turn)?;
            let half = bl.constant(0.5)?;
            bl.binary(Binary::Add, a, half)?
        }
        "SPHERICAL" | "QUADRATIC_SPHERE" => {
            // Cycles biases the radius by 1e-6, so a unit vector gives exactly 0.
            let len = bl.magnitude(p)?;
            let edge = bl.constant(0.999_999)?;
            let d = bl.binary(Binary::Sub, edge, len)?;
            let r = bl.binary(Binary::Max, d, zero)?;
            match kind {
                "SPHERICAL" => r,
                _ => bl.binary(Binary::Mul, r, r)?,
            }
        }
        _ => return Ok(None),
    };
    Ok(Some(bl.clamp(g, zero, one)?))
}

/// Cycles' `safe_normalize`: a / |a|, 0 where |a| = 0.
fn safe_normalize(bl: &mut Builder, a: Reg) -> Result<Reg, GraphError> {
    let length = bl.magnitude(a)?;
    bl.binary(Binary::SafeDiv, a, length)
}

/// The Blender graph whose output `output` of the shader prim `shader` is connected
/// to a medium's density scale.
/// `times_field`: the program multiplies the graph by the density field's value (a
/// Principled Volume's Density times its Density Attribute).
pub fn usd_density(
    shader: &Prim,
    output: &str,
    time: Option<TimeCode>,
    times_field: bool,
) -> Result<BlenderDensity, SceneError> {
    let network = usd_network(shader, time)?;
    compile(&network, shader.path().as_str(), output, times_field)
}

/// Compiles the output `output` of node `node` of `network` into a program.
pub fn compile(
    network: &ShaderNetwork,
    node: &str,
    output: &str,
    times_field: bool,
) -> Result<BlenderDensity, SceneError> {
    let mut reader = Reader::new(network);
    let v = reader.output(&(node.to_string(), output.to_string()))?;
    let mut v = reader.scalar(node, v)?;
    if times_field {
        let e = |e| prim_error_str(node, e);
        let field = reader.builder.attribute();
        v = reader.builder.binary(Binary::Mul, v, field).map_err(e)?;
    }
    let attribute = reader.attribute.take();
    let program = reader
        .builder
        .finish(v)
        .map_err(|e| prim_error_str(node, e))?;
    Ok(BlenderDensity { program, attribute })
}

type Output = (String, String);

struct Reader<'a> {
    network: &'a ShaderNetwork,
    builder: Builder,
    done: HashMap<Output, Reg>,
    attribute: Option<String>,
    depth: usize,
}

/// Cycles' luminance weights of its working space (linear Rec. 709, Blender's default
/// scene-linear space): RGB to BW, and a colour linked into a float socket (the add-on
/// writes that conversion as an RGB to BW node).
const LUMINANCE: [f32; 3] = [0.212_672_9, 0.715_152_2, 0.072_175];

impl<'a> Reader<'a> {
    fn new(network: &'a ShaderNetwork) -> Self {
        Reader {
            network,
            builder: Builder::default(),
            done: HashMap::new(),
            attribute: None,
            depth: 0,
        }
    }

    fn node(&self, path: &str) -> Result<&'a ShaderNode, SceneError> {
        self.network.node(path).ok_or_else(|| {
            prim_error_str(
                path,
                "a connection names this node, which is not in the network",
            )
        })
    }

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
        let v = self.compile(node, &output.1)?;
        self.depth -= 1;
        self.done.insert(output.clone(), v);
        Ok(v)
    }

    fn graph_error(at: &str) -> impl Fn(crate::shader::graph::GraphError) -> SceneError + '_ {
        move |e| prim_error_str(at, e)
    }

    /// A value read as a float. Every vector the compiled nodes output is a vector (a
    /// colour output reaches here as its luminance already: the ramp's table, the
    /// gradient's grey), which Cycles reads in a float socket as its average.
    fn scalar(&mut self, at: &str, v: Reg) -> Result<Reg, SceneError> {
        match v {
            Reg::Float(_) => Ok(v),
            Reg::Vector3(_) => {
                self.builder.node(at);
                let e = Self::graph_error(at);
                let ones = self.builder.vector3([1.0; 3]).map_err(&e)?;
                let sum = self.builder.dot(v, ones).map_err(&e)?;
                let third = self.builder.constant(1.0 / 3.0).map_err(&e)?;
                self.builder.binary(Binary::Mul, sum, third).map_err(&e)
            }
        }
    }

    fn source(node: &ShaderNode, name: &str) -> Option<Result<Output, ParamValue>> {
        match node.input(name)? {
            Input::Value(v) => Some(Err(v.clone())),
            Input::Connection { node, output } => Some(Ok((node.clone(), output.clone()))),
        }
    }

    /// A float input (linked: the linked output as a float; else its value, or
    /// `default`).
    fn float(&mut self, node: &ShaderNode, name: &str, default: f32) -> Result<Reg, SceneError> {
        match Self::source(node, name) {
            Some(Ok(o)) => {
                let v = self.output(&o)?;
                self.scalar(&node.path, v)
            }
            value => {
                let x = match value {
                    Some(Err(v)) => number(node, name, &v)? as f32,
                    _ => default,
                };
                self.builder.node(&node.path);
                self.builder
                    .constant(x)
                    .map_err(Self::graph_error(&node.path))
            }
        }
    }

    /// A vector input; unauthored: `default`, or the object-space position when that
    /// is `None` (a texture's Vector: Blender's default there is Generated coordinates,
    /// which the add-on always writes as a link).
    fn vector(
        &mut self,
        node: &ShaderNode,
        name: &str,
        default: Option<[f32; 3]>,
    ) -> Result<Reg, SceneError> {
        match Self::source(node, name) {
            Some(Ok(o)) => {
                let v = self.output(&o)?;
                self.builder.node(&node.path);
                self.builder
                    .splat3(v)
                    .map_err(Self::graph_error(&node.path))
            }
            Some(Err(v)) => {
                let c = colour(node, name, &v)?;
                self.builder.node(&node.path);
                self.builder
                    .vector3(c.map(|x| x as f32))
                    .map_err(Self::graph_error(&node.path))
            }
            None => match default {
                None => Ok(self.builder.position()),
                Some(c) => {
                    self.builder.node(&node.path);
                    self.builder
                        .vector3(c)
                        .map_err(Self::graph_error(&node.path))
                }
            },
        }
    }

    /// An input that shapes the program (a noise's Detail, a ramp's table): a value.
    fn constant(&self, node: &ShaderNode, name: &str, default: f64) -> Result<f64, SceneError> {
        match Self::source(node, name) {
            Some(Ok(o)) => Err(prim_error_str(
                &node.path,
                format!(
                    "`inputs:{name}` is linked to {}.outputs:{}; Nimbus needs it unlinked",
                    o.0, o.1
                ),
            )),
            Some(Err(v)) => number(node, name, &v),
            None => Ok(default),
        }
    }

    fn text(node: &ShaderNode, name: &str, default: &str) -> Result<String, SceneError> {
        match node.input(name) {
            None => Ok(default.to_string()),
            Some(Input::Value(ParamValue::Text(t))) => Ok(t.clone()),
            Some(_) => Err(prim_error_str(
                &node.path,
                format!("`inputs:{name}` should be a constant token"),
            )),
        }
    }

    fn table(node: &ShaderNode, name: &str) -> Result<Vec<f32>, SceneError> {
        match node.input(name) {
            Some(Input::Value(ParamValue::Numbers(v))) => {
                Ok(v.iter().map(|&x| x as f32).collect())
            }
            _ => Err(prim_error_str(
                &node.path,
                format!("`inputs:{name}` should be a float[] table (the add-on writes the ramp sampled at i/256)"),
            )),
        }
    }

    /// RGB to BW of a Color Ramp's Color, compiled as one lookup in the table of the
    /// channels' luminance (the ramp is linear in its entries, so this is the same
    /// function to rounding); `None` when the input is anything else.
    fn ramp_luminance(&mut self, node: &ShaderNode) -> Result<Option<Reg>, SceneError> {
        let Some(Ok((path, out))) = Self::source(node, "Color") else {
            return Ok(None);
        };
        let ramp = self.node(&path)?;
        if ramp.id != "ShaderNodeValToRGB" || out != "Color" {
            return Ok(None);
        }
        let [r, g, b] = ["red_table", "green_table", "blue_table"].map(|t| Self::table(ramp, t));
        let (r, g, b) = (r?, g?, b?);
        if r.len() != g.len() || r.len() != b.len() {
            return Err(prim_error_str(
                &ramp.path,
                "the ramp's channel tables differ in length",
            ));
        }
        let table = (0..r.len())
            .map(|i| LUMINANCE[0] * r[i] + LUMINANCE[1] * g[i] + LUMINANCE[2] * b[i])
            .collect();
        let interpolate = self.constant(ramp, "interpolate", 1.0)? != 0.0;
        let x = self.float(ramp, "Fac", 0.5)?;
        self.builder.node(&node.path);
        self.builder
            .ramp(x, table, interpolate)
            .map(Some)
            .map_err(Self::graph_error(&node.path))
    }

    /// A node's `Rotation` (Euler XYZ): a constant matrix where the socket has a value
    /// (or none: no rotation), the graph's value per lookup where it is linked.
    fn rotation(&mut self, node: &ShaderNode) -> Result<Rotation, SceneError> {
        Ok(match node.input("Rotation") {
            None => Rotation::Constant([0.0; 3]),
            Some(Input::Value(v)) => {
                Rotation::Constant(colour(node, "Rotation", v)?.map(|x| x as f32))
            }
            Some(_) => Rotation::Linked(self.vector(node, "Rotation", None)?),
        })
    }

    /// The register of the volume's field `name` (an Attribute or Volume Info node):
    /// one field per graph.
    fn field(&mut self, node: &ShaderNode, name: String) -> Result<Reg, SceneError> {
        match &self.attribute {
            Some(a) if *a != name => {
                return Err(prim_error_str(
                    &node.path,
                    format!("reads `{name}` where the graph already reads `{a}`; Nimbus reads one field per density graph"),
                ))
            }
            _ => self.attribute = Some(name),
        }
        Ok(self.builder.attribute())
    }

    /// Blender's Mix node (3.4 and later) of floats, vectors or colours
    /// (`data_type`); its output is named by the type (`Result_Float`…).
    fn mix(&mut self, node: &ShaderNode, output: &str) -> Result<Reg, SceneError> {
        let at = node.path.clone();
        let err = Self::graph_error(&at);
        let ty = Self::text(node, "data_type", "FLOAT")?;
        let expected = match ty.as_str() {
            "FLOAT" => "Result_Float",
            "VECTOR" => "Result_Vector",
            "RGBA" => "Result_Color",
            _ => return Err(Self::refuse(node, "data_type", &ty)),
        };
        if output != expected {
            return Err(prim_error_str(
                &node.path,
                format!(
                    "{}: output `{output}` is not compiled (a {ty} Mix gives {expected})",
                    node.id
                ),
            ));
        }
        let clamp_factor = self.constant(node, "clamp_factor", 1.0)? != 0.0;
        let non_uniform =
            ty == "VECTOR" && Self::text(node, "factor_mode", "UNIFORM")? == "NON_UNIFORM";
        let t = match non_uniform {
            true => self.vector(node, "Factor_Vector", Some([0.5; 3]))?,
            false => self.float(node, "Factor_Float", 0.5)?,
        };
        let (a, b) = match ty.as_str() {
            "FLOAT" => (
                self.float(node, "A_Float", 0.0)?,
                self.float(node, "B_Float", 0.0)?,
            ),
            "VECTOR" => (
                self.vector(node, "A_Vector", Some([0.0; 3]))?,
                self.vector(node, "B_Vector", Some([0.0; 3]))?,
            ),
            _ => (
                self.vector(node, "A_Color", Some([0.5; 3]))?,
                self.vector(node, "B_Color", Some([0.5; 3]))?,
            ),
        };
        self.builder.node(&at);
        let bl = &mut self.builder;
        let t = match clamp_factor {
            true => saturate(bl, t).map_err(&err)?,
            false => t,
        };
        if ty != "RGBA" {
            return mix_linear(bl, t, a, b).map_err(&err);
        }
        let blend = Self::text(node, "blend_type", "MIX")?;
        let clamp_result = self.constant(node, "clamp_result", 0.0)? != 0.0;
        let bl = &mut self.builder;
        let v = mix_color(bl, &blend, t, a, b)
            .map_err(&err)?
            .ok_or_else(|| Self::refuse(node, "blend_type", &blend))?;
        match clamp_result {
            true => saturate(bl, v).map_err(&err),
            false => Ok(v),
        }
    }

    fn refuse(node: &ShaderNode, what: &str, value: &str) -> SceneError {
        prim_error_str(
            &node.path,
            format!("{} {what} `{value}` is not compiled", node.id),
        )
    }

    fn compile(&mut self, node: &ShaderNode, output: &str) -> Result<Reg, SceneError> {
        if !NODES.contains(&node.id.as_str()) {
            return Err(prim_error_str(
                &node.path,
                format!(
                    "node `{}` is not one Nimbus compiles into a density graph (it reads: {})",
                    node.id,
                    NODES.join(", ")
                ),
            ));
        }
        let at = node.path.clone();
        let err = Self::graph_error(&at);
        let wrong_output = || {
            prim_error_str(
                &node.path,
                format!("{}: output `{output}` is not compiled", node.id),
            )
        };
        let v = match node.id.as_str() {
            "ShaderNodeTexCoord" => match output {
                "Object" => self.builder.position(),
                "Generated" => {
                    // Cycles' generated coordinates of a mesh: the object-space position
                    // through the texture space, p × scale − offset (the add-on computes
                    // both from the mesh's texture space as Cycles does).
                    if node.input("generated_scale").is_none()
                        || node.input("generated_offset").is_none()
                    {
                        return Err(prim_error_str(
                            &node.path,
                            "Generated needs `inputs:generated_scale` and `inputs:generated_offset` (the texture space, which the add-on writes)",
                        ));
                    }
                    let scale = self.vector(node, "generated_scale", None)?;
                    let offset = self.vector(node, "generated_offset", None)?;
                    let p = self.builder.position();
                    self.builder.node(&at);
                    let s = self.builder.binary(Binary::Mul, p, scale).map_err(&err)?;
                    self.builder.binary(Binary::Sub, s, offset).map_err(&err)?
                }
                _ => return Err(wrong_output()),
            },
            "ShaderNodeTexNoise" => {
                if output != "Fac" && output != "Color" {
                    return Err(wrong_output());
                }
                let dims = Self::text(node, "noise_dimensions", "3D")?;
                let dimensions = match dims.as_str() {
                    "1D" => Dimensions::D1,
                    "2D" => Dimensions::D2,
                    "3D" => Dimensions::D3,
                    "4D" => Dimensions::D4,
                    d => return Err(Self::refuse(node, "noise_dimensions", d)),
                };
                let kind = match Self::text(node, "noise_type", "FBM")?.as_str() {
                    "FBM" => NoiseType::Fbm,
                    "MULTIFRACTAL" => NoiseType::Multifractal,
                    "HETERO_TERRAIN" => NoiseType::HeteroTerrain,
                    "HYBRID_MULTIFRACTAL" => NoiseType::HybridMultifractal,
                    "RIDGED_MULTIFRACTAL" => NoiseType::RidgedMultifractal,
                    t => return Err(Self::refuse(node, "noise_type", t)),
                };
                let texture = NoiseTexture {
                    dimensions,
                    kind,
                    offset: self.constant(node, "Offset", 0.0)? as f32,
                    gain: self.constant(node, "Gain", 1.0)? as f32,
                    normalize: self.constant(node, "normalize", 1.0)? != 0.0,
                    scale: self.constant(node, "Scale", 5.0)? as f32,
                    detail: self.constant(node, "Detail", 2.0)? as f32,
                    roughness: self.constant(node, "Roughness", 0.5)? as f32,
                    lacunarity: self.constant(node, "Lacunarity", 2.0)? as f32,
                    distortion: self.constant(node, "Distortion", 0.0)? as f32,
                };
                let p = self.vector(node, "Vector", None)?;
                let w = self.float(node, "W", 0.0)?;
                self.builder.node(&at);
                match output {
                    "Color" => self.builder.blender_noise_color(p, w, texture),
                    _ => self.builder.blender_noise(p, w, texture),
                }
                .map_err(&err)?
            }
            "ShaderNodeTexVoronoi" => {
                let out = match output {
                    "Distance" => VoronoiOutput::Distance,
                    "Color" => VoronoiOutput::Color,
                    "Position" => VoronoiOutput::Position,
                    "Radius" => VoronoiOutput::Radius,
                    _ => return Err(wrong_output()),
                };
                let dims = Self::text(node, "voronoi_dimensions", "3D")?;
                if dims != "3D" {
                    return Err(Self::refuse(node, "voronoi_dimensions (only 3D)", &dims));
                }
                let name = Self::text(node, "feature", "F1")?;
                let feature = match name.as_str() {
                    "F1" => VoronoiFeature::F1,
                    "F2" => VoronoiFeature::F2,
                    "SMOOTH_F1" => VoronoiFeature::SmoothF1,
                    "DISTANCE_TO_EDGE" => VoronoiFeature::DistanceToEdge,
                    "N_SPHERE_RADIUS" => VoronoiFeature::NSphereRadius,
                    _ => return Err(Self::refuse(node, "feature", &name)),
                };
                // Distance to Edge and N-Sphere Radius are Euclidean whatever the
                // metric (Cycles); the others read it.
                let name = Self::text(node, "distance", "EUCLIDEAN")?;
                let metric = match name.as_str() {
                    "EUCLIDEAN" => VoronoiMetric::Euclidean,
                    "MANHATTAN" => VoronoiMetric::Manhattan,
                    "CHEBYCHEV" => VoronoiMetric::Chebychev,
                    "MINKOWSKI" => {
                        let e = self.constant(node, "Exponent", 0.5)? as f32;
                        if !(e.is_finite() && e > 0.0) {
                            return Err(Self::refuse(node, "Exponent (only > 0)", &e.to_string()));
                        }
                        VoronoiMetric::Minkowski(e)
                    }
                    _ => return Err(Self::refuse(node, "distance", &name)),
                };
                // Cycles clamps Detail into [0, 15] and Roughness into [0, 1]; one
                // octave when either is 0.
                let detail = self.constant(node, "Detail", 0.0)?.clamp(0.0, 15.0) as f32;
                let roughness = self.constant(node, "Roughness", 0.5)?.clamp(0.0, 1.0) as f32;
                let lacunarity = self.constant(node, "Lacunarity", 2.0)? as f32;
                let texture = VoronoiTexture {
                    scale: self.constant(node, "Scale", 5.0)? as f32,
                    randomness: self.constant(node, "Randomness", 1.0)? as f32,
                    normalize: self.constant(node, "normalize", 0.0)? != 0.0,
                    feature,
                    smoothness: match feature {
                        VoronoiFeature::SmoothF1 => self.constant(node, "Smoothness", 1.0)? as f32,
                        _ => 1.0,
                    },
                    metric,
                    detail,
                    roughness,
                    lacunarity,
                };
                let p = self.vector(node, "Vector", None)?;
                self.builder.node(&at);
                self.builder
                    .blender_voronoi(p, texture, out)
                    .map_err(&err)?
            }
            "ShaderNodeTexGradient" => {
                if output != "Fac" && output != "Color" {
                    return Err(wrong_output());
                }
                let p = self.vector(node, "Vector", None)?;
                let kind = Self::text(node, "gradient_type", "LINEAR")?;
                self.builder.node(&at);
                let fac = gradient(&mut self.builder, &kind, p)
                    .map_err(&err)?
                    .ok_or_else(|| Self::refuse(node, "gradient_type", &kind))?;
                match output {
                    "Color" => self.builder.splat3(fac).map_err(&err)?,
                    _ => fac,
                }
            }
            "ShaderNodeValToRGB" => {
                let interpolate = self.constant(node, "interpolate", 1.0)? != 0.0;
                let x = self.float(node, "Fac", 0.5)?;
                let tables = match output {
                    "Color" => vec![
                        Self::table(node, "red_table")?,
                        Self::table(node, "green_table")?,
                        Self::table(node, "blue_table")?,
                    ],
                    "Alpha" => vec![Self::table(node, "alpha_table")?],
                    _ => return Err(wrong_output()),
                };
                self.builder.node(&at);
                let mut channels = Vec::new();
                for t in tables {
                    channels.push(self.builder.ramp(x, t, interpolate).map_err(&err)?);
                }
                match channels[..] {
                    [r, g, b] => self.builder.combine3(r, g, b).map_err(&err)?,
                    _ => channels[0],
                }
            }
            "ShaderNodeRGBToBW" => {
                if output != "Val" {
                    return Err(wrong_output());
                }
                if let Some(ramp) = self.ramp_luminance(node)? {
                    ramp
                } else {
                    let c = self.vector(node, "Color", Some([0.5; 3]))?;
                    self.builder.node(&at);
                    let w = self.builder.vector3(LUMINANCE).map_err(&err)?;
                    self.builder.dot(c, w).map_err(&err)?
                }
            }
            "ShaderNodeCombineXYZ" => {
                if output != "Vector" {
                    return Err(wrong_output());
                }
                let x = self.float(node, "X", 0.0)?;
                let y = self.float(node, "Y", 0.0)?;
                let z = self.float(node, "Z", 0.0)?;
                self.builder.node(&at);
                self.builder.combine3(x, y, z).map_err(&err)?
            }
            "ShaderNodeMath" => {
                if output != "Value" {
                    return Err(wrong_output());
                }
                let op = Self::text(node, "operation", "ADD")?;
                let a = self.float(node, "Value", 0.5)?;
                let b = self.float(node, "Value_001", 0.5)?;
                let c = if matches!(
                    op.as_str(),
                    "MULTIPLY_ADD" | "COMPARE" | "SMOOTH_MIN" | "SMOOTH_MAX"
                ) {
                    Some(self.float(node, "Value_002", 0.5)?)
                } else {
                    None
                };
                let clamp = self.constant(node, "use_clamp", 0.0)? != 0.0;
                self.builder.node(&at);
                let bl = &mut self.builder;
                let v = math(bl, &op, a, b, c.unwrap_or(a))
                    .map_err(&err)?
                    .ok_or_else(|| Self::refuse(node, "operation", &op))?;
                if clamp {
                    let (zero, one) = (
                        bl.constant(0.0).map_err(&err)?,
                        bl.constant(1.0).map_err(&err)?,
                    );
                    bl.clamp(v, zero, one).map_err(&err)?
                } else {
                    v
                }
            }
            "ShaderNodeMapRange" => {
                if output != "Result" {
                    return Err(wrong_output());
                }
                let ty = Self::text(node, "data_type", "FLOAT")?;
                if ty != "FLOAT" {
                    return Err(Self::refuse(node, "data_type", &ty));
                }
                let interpolation = Self::text(node, "interpolation_type", "LINEAR")?;
                let x = self.float(node, "Value", 1.0)?;
                let fmin = self.float(node, "From_Min", 0.0)?;
                let fmax = self.float(node, "From_Max", 1.0)?;
                let tmin = self.float(node, "To_Min", 0.0)?;
                let tmax = self.float(node, "To_Max", 1.0)?;
                let clamp = self.constant(node, "clamp", 1.0)? != 0.0;
                let steps = match interpolation.as_str() {
                    "STEPPED" => self.constant(node, "Steps", 4.0)? as f32,
                    _ => 0.0,
                };
                self.builder.node(&at);
                match map_range(
                    &mut self.builder,
                    &interpolation,
                    [x, fmin, fmax, tmin, tmax],
                    steps,
                    clamp,
                )
                .map_err(&err)?
                {
                    Some(r) => r,
                    None => return Err(Self::refuse(node, "interpolation_type", &interpolation)),
                }
            }
            "ShaderNodeVectorMath" => {
                let op = Self::text(node, "operation", "ADD")?;
                let a = self.vector(node, "Vector", None)?;
                // Only the sockets the operation reads are compiled (an unused one may be
                // linked to anything, and its registers would be wasted).
                let (uses_b, uses_c) = vector_math_operands(&op);
                let b = match uses_b {
                    true => self.vector(node, "Vector_001", Some([0.0; 3]))?,
                    false => a,
                };
                let c = match uses_c {
                    true => self.vector(node, "Vector_002", Some([0.0; 3]))?,
                    false => a,
                };
                let scale = match op.as_str() {
                    // Refract's IOR is the Scale socket.
                    "SCALE" | "REFRACT" => self.float(node, "Scale", 1.0)?,
                    _ => a,
                };
                self.builder.node(&at);
                let v = vector_math(&mut self.builder, &op, a, b, c, scale)
                    .map_err(&err)?
                    .ok_or_else(|| Self::refuse(node, "operation", &op))?;
                match (output, v) {
                    ("Vector", Reg::Vector3(_)) | ("Value", Reg::Float(_)) => v,
                    _ => return Err(wrong_output()),
                }
            }
            "ShaderNodeMapping" => {
                if output != "Vector" {
                    return Err(wrong_output());
                }
                let ty = Self::text(node, "vector_type", "POINT")?;
                let rotation = self.rotation(node)?;
                let p = self.vector(node, "Vector", None)?;
                let s = self.vector(node, "Scale", Some([1.0; 3]))?;
                // Vector and Normal have no Location (Blender hides the socket).
                let l = match ty.as_str() {
                    "POINT" | "TEXTURE" => self.vector(node, "Location", Some([0.0; 3]))?,
                    _ => p,
                };
                self.builder.node(&at);
                mapping(&mut self.builder, &ty, p, l, rotation, s)
                    .map_err(&err)?
                    .ok_or_else(|| Self::refuse(node, "vector_type", &ty))?
            }
            "ShaderNodeVectorRotate" => {
                if output != "Vector" {
                    return Err(wrong_output());
                }
                let ty = Self::text(node, "rotation_type", "AXIS_ANGLE")?;
                let invert = self.constant(node, "invert", 0.0)? != 0.0;
                // Blender's Vector socket here has no implicit coordinates: unlinked, 0.
                let v = self.vector(node, "Vector", Some([0.0; 3]))?;
                let center = self.vector(node, "Center", Some([0.0; 3]))?;
                let axis = self.vector(node, "Axis", Some([0.0, 0.0, 1.0]))?;
                let angle = self.float(node, "Angle", 0.0)?;
                let rotation = self.rotation(node)?;
                self.builder.node(&at);
                vector_rotate(
                    &mut self.builder,
                    &ty,
                    invert,
                    v,
                    center,
                    axis,
                    angle,
                    rotation,
                )
                .map_err(&err)?
                .ok_or_else(|| Self::refuse(node, "rotation_type", &ty))?
            }
            "ShaderNodeSeparateXYZ" => {
                let k = match output {
                    "X" => 0,
                    "Y" => 1,
                    "Z" => 2,
                    _ => return Err(wrong_output()),
                };
                let p = self.vector(node, "Vector", None)?;
                self.builder.node(&at);
                self.builder.component(p, k).map_err(&err)?
            }
            "ShaderNodeAttribute" => {
                if output != "Fac" {
                    return Err(wrong_output());
                }
                let name = Self::text(node, "attribute_name", "")?;
                self.field(node, name)?
            }
            // Volume Info reads the grids Blender names density, flame and temperature
            // (Cycles: the attributes of those names), as Attribute nodes would.
            "ShaderNodeVolumeInfo" => match output {
                "Density" | "Flame" | "Temperature" => self.field(node, output.to_lowercase())?,
                _ => return Err(wrong_output()),
            },
            "ShaderNodeClamp" => {
                if output != "Result" {
                    return Err(wrong_output());
                }
                let kind = Self::text(node, "clamp_type", "MINMAX")?;
                let range = match kind.as_str() {
                    "MINMAX" => false,
                    "RANGE" => true,
                    _ => return Err(Self::refuse(node, "clamp_type", &kind)),
                };
                let x = self.float(node, "Value", 1.0)?;
                let lo = self.float(node, "Min", 0.0)?;
                let hi = self.float(node, "Max", 1.0)?;
                self.builder.node(&at);
                clamp(&mut self.builder, range, x, lo, hi).map_err(&err)?
            }
            "ShaderNodeMix" => self.mix(node, output)?,
            // The Mix node before Blender 3.4: its factor always clamped, its result
            // clamped with use_clamp (Cycles' MixNode).
            "ShaderNodeMixRGB" => {
                if output != "Color" {
                    return Err(wrong_output());
                }
                let blend = Self::text(node, "blend_type", "MIX")?;
                let clamp_result = self.constant(node, "use_clamp", 0.0)? != 0.0;
                let t = self.float(node, "Fac", 0.5)?;
                let a = self.vector(node, "Color1", Some([0.5; 3]))?;
                let b = self.vector(node, "Color2", Some([0.5; 3]))?;
                self.builder.node(&at);
                let bl = &mut self.builder;
                let t = saturate(bl, t).map_err(&err)?;
                let v = mix_color(bl, &blend, t, a, b)
                    .map_err(&err)?
                    .ok_or_else(|| Self::refuse(node, "blend_type", &blend))?;
                match clamp_result {
                    true => saturate(bl, v).map_err(&err)?,
                    false => v,
                }
            }
            // The add-on writes the curve as Cycles samples it: `table` (257 entries),
            // `min_x` and `max_x` (its first and last points' x) and `extrapolate`.
            "ShaderNodeFloatCurve" => {
                if output != "Value" {
                    return Err(wrong_output());
                }
                let table = Self::table(node, "table")?;
                let min = self.constant(node, "min_x", 0.0)? as f32;
                let max = self.constant(node, "max_x", 1.0)? as f32;
                if !(max - min > 0.0 && (max - min).is_finite()) {
                    return Err(prim_error_str(
                        &node.path,
                        format!("the curve's points span no x range ({min} .. {max})"),
                    ));
                }
                let extrapolate = self.constant(node, "extrapolate", 1.0)? != 0.0;
                let fac = self.float(node, "Factor", 1.0)?;
                let value = self.float(node, "Value", 1.0)?;
                self.builder.node(&at);
                float_curve(
                    &mut self.builder,
                    table,
                    (min, max),
                    extrapolate,
                    fac,
                    value,
                )
                .map_err(&err)?
            }
            // Cycles' svm_separate_color and svm_combine_color: RGB as it is, HSV and
            // HSL through util/color.h's conversions.
            "ShaderNodeSeparateColor" => {
                let k = match output {
                    "Red" => 0,
                    "Green" => 1,
                    "Blue" => 2,
                    _ => return Err(wrong_output()),
                };
                let mode = Self::text(node, "mode", "RGB")?;
                let c = self.vector(node, "Color", Some([0.8; 3]))?;
                self.builder.node(&at);
                let bl = &mut self.builder;
                let c = match mode.as_str() {
                    "RGB" => c,
                    "HSV" => rgb_to_hsv(bl, c).map_err(&err)?,
                    "HSL" => rgb_to_hsl(bl, c).map_err(&err)?,
                    _ => return Err(Self::refuse(node, "mode", &mode)),
                };
                bl.component(c, k).map_err(&err)?
            }
            "ShaderNodeCombineColor" => {
                if output != "Color" {
                    return Err(wrong_output());
                }
                let mode = Self::text(node, "mode", "RGB")?;
                let r = self.float(node, "Red", 0.0)?;
                let g = self.float(node, "Green", 0.0)?;
                let b = self.float(node, "Blue", 0.0)?;
                self.builder.node(&at);
                let bl = &mut self.builder;
                let c = bl.combine3(r, g, b).map_err(&err)?;
                match mode.as_str() {
                    "RGB" => c,
                    "HSV" => hsv_to_rgb(bl, c).map_err(&err)?,
                    "HSL" => hsl_to_rgb(bl, c).map_err(&err)?,
                    _ => return Err(Self::refuse(node, "mode", &mode)),
                }
            }
            "ShaderNodeHueSaturation" => {
                if output != "Color" {
                    return Err(wrong_output());
                }
                let hue = self.float(node, "Hue", 0.5)?;
                let sat = self.float(node, "Saturation", 1.0)?;
                let val = self.float(node, "Value", 1.0)?;
                let fac = self.float(node, "Fac", 1.0)?;
                let c = self.vector(node, "Color", Some([0.8; 3]))?;
                self.builder.node(&at);
                hue_saturation_value(&mut self.builder, [hue, sat, val, fac], c).map_err(&err)?
            }
            // The add-on writes each channel's table as Cycles bakes it (257 entries,
            // `red_table`, `green_table`, `blue_table`), the x range every curve shares
            // (`min_x`, `max_x`) and `extrapolate`.
            "ShaderNodeRGBCurve" | "ShaderNodeVectorCurve" => {
                let rgb = node.id == "ShaderNodeRGBCurve";
                let (input, default) = match rgb {
                    true => ("Color", [1.0; 3]),
                    false => ("Vector", [0.0; 3]),
                };
                if output != input {
                    return Err(wrong_output());
                }
                let tables = [
                    Self::table(node, "red_table")?,
                    Self::table(node, "green_table")?,
                    Self::table(node, "blue_table")?,
                ];
                let min = self.constant(node, "min_x", 0.0)? as f32;
                let max = self.constant(node, "max_x", 1.0)? as f32;
                if !(max - min > 0.0 && (max - min).is_finite()) {
                    return Err(prim_error_str(
                        &node.path,
                        format!("the curves' points span no x range ({min} .. {max})"),
                    ));
                }
                if tables.iter().any(|t| t.len() < 2) {
                    return Err(prim_error_str(
                        &node.path,
                        "a curve's table has fewer than 2 entries".to_string(),
                    ));
                }
                let extrapolate = self.constant(node, "extrapolate", 1.0)? != 0.0;
                let fac = self.float(node, "Fac", 1.0)?;
                let c = self.vector(node, input, Some(default))?;
                self.builder.node(&at);
                curves(&mut self.builder, tables, (min, max), extrapolate, fac, c).map_err(&err)?
            }
            "ShaderNodeGamma" => {
                if output != "Color" {
                    return Err(wrong_output());
                }
                let c = self.vector(node, "Color", Some([1.0; 3]))?;
                let g = self.float(node, "Gamma", 1.0)?;
                self.builder.node(&at);
                gamma(&mut self.builder, c, g).map_err(&err)?
            }
            "ShaderNodeBrightContrast" => {
                if output != "Color" {
                    return Err(wrong_output());
                }
                let c = self.vector(node, "Color", Some([1.0; 3]))?;
                let bright = self.float(node, "Bright", 0.0)?;
                let contrast = self.float(node, "Contrast", 0.0)?;
                self.builder.node(&at);
                brightness_contrast(&mut self.builder, c, bright, contrast).map_err(&err)?
            }
            // Cycles' White Noise: an unlinked Vector is (0, 0, 0) (not a texture
            // space: the node has none), as the add-on writes it.
            "ShaderNodeTexWhiteNoise" => {
                let color = match output {
                    "Value" => false,
                    "Color" => true,
                    _ => return Err(wrong_output()),
                };
                let dims = Self::text(node, "noise_dimensions", "3D")?;
                let dims = match dims.as_str() {
                    "1D" => 1,
                    "2D" => 2,
                    "3D" => 3,
                    "4D" => 4,
                    _ => return Err(Self::refuse(node, "noise_dimensions", &dims)),
                };
                let p = self.vector(node, "Vector", Some([0.0; 3]))?;
                let w = self.float(node, "W", 0.0)?;
                self.builder.node(&at);
                self.builder.white_noise(p, w, dims, color).map_err(&err)?
            }
            "ShaderNodeBlackbody" => {
                if output != "Color" {
                    return Err(wrong_output());
                }
                let t = self.float(node, "Temperature", 6500.0)?;
                self.builder.node(&at);
                self.builder.blackbody(t).map_err(&err)?
            }
            // Scale, Distortion and Phase Offset may be linked; the fBM's Detail,
            // Detail Scale and Detail Roughness shape the noise and must be constants.
            "ShaderNodeTexWave" => {
                if output != "Fac" && output != "Color" {
                    return Err(wrong_output());
                }
                let kind = Self::text(node, "wave_type", "BANDS")?;
                let direction = match kind.as_str() {
                    "RINGS" => Self::text(node, "rings_direction", "X")?,
                    _ => Self::text(node, "bands_direction", "X")?,
                };
                let profile = Self::text(node, "wave_profile", "SIN")?;
                let detail = self.constant(node, "Detail", 2.0)? as f32;
                let roughness = self.constant(node, "Detail_Roughness", 0.5)? as f32;
                if !(0.0..=15.0).contains(&detail) || roughness.is_nan() || roughness < 0.0 {
                    return Err(prim_error_str(
                        &node.path,
                        format!("Detail {detail} (Nimbus compiles 0 to 15) or Detail Roughness {roughness} (from 0)"),
                    ));
                }
                let texture = NoiseTexture {
                    dimensions: Dimensions::D3,
                    kind: NoiseType::Fbm,
                    normalize: true,
                    scale: self.constant(node, "Detail_Scale", 1.0)? as f32,
                    detail,
                    roughness,
                    lacunarity: 2.0,
                    distortion: 0.0,
                    ..NoiseTexture::default()
                };
                let distortion = match Self::source(node, "Distortion") {
                    None => None,
                    Some(Err(_)) if self.constant(node, "Distortion", 0.0)? == 0.0 => None,
                    Some(_) => Some(self.float(node, "Distortion", 0.0)?),
                };
                let co = self.vector(node, "Vector", None)?;
                let scale = self.float(node, "Scale", 5.0)?;
                let phase = self.float(node, "Phase_Offset", 0.0)?;
                self.builder.node(&at);
                let Some(v) = wave(
                    &mut self.builder,
                    co,
                    scale,
                    (kind.as_str(), direction.as_str(), profile.as_str()),
                    distortion,
                    texture,
                    phase,
                )
                .map_err(&err)?
                else {
                    return Err(prim_error_str(
                        &node.path,
                        format!("a Wave Texture of type {kind}, direction {direction}, profile {profile}: not one Nimbus compiles"),
                    ));
                };
                match output {
                    "Color" => self.builder.splat3(v).map_err(&err)?,
                    _ => v,
                }
            }
            "ShaderNodeTexMagic" => {
                if output != "Fac" && output != "Color" {
                    return Err(wrong_output());
                }
                let depth = self.constant(node, "turbulence_depth", 2.0)?;
                if !(0.0..=10.0).contains(&depth) {
                    return Err(Self::refuse(node, "turbulence_depth", &depth.to_string()));
                }
                let co = self.vector(node, "Vector", None)?;
                let scale = self.float(node, "Scale", 5.0)?;
                let d = self.float(node, "Distortion", 1.0)?;
                self.builder.node(&at);
                let c = magic(&mut self.builder, co, scale, depth as u32, d).map_err(&err)?;
                match output {
                    "Fac" => magic_fac(&mut self.builder, c).map_err(&err)?,
                    _ => c,
                }
            }
            "ShaderNodeInvert" => {
                if output != "Color" {
                    return Err(wrong_output());
                }
                let fac = self.float(node, "Fac", 1.0)?;
                let c = self.vector(node, "Color", Some([0.0; 3]))?;
                self.builder.node(&at);
                invert(&mut self.builder, fac, c).map_err(&err)?
            }
            "ShaderNodeValue" => {
                if output != "Value" {
                    return Err(wrong_output());
                }
                self.float(node, "value", 0.0)?
            }
            _ => unreachable!("every id of NODES is compiled above"),
        };
        Ok(v)
    }
}
