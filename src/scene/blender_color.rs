//! Blender's colour-mixing nodes as graph instructions: the Mix node in Color mode and
//! the older MixRGB (`blend_type`), and Invert Color. The operations are Cycles' (its
//! `svm_mix_*` functions), in the same order, so that a density or colour driven
//! through them is the value Cycles renders: floating-point order is part of the
//! function (a + t(b − a) and a(1 − t) + bt differ in the last bit).
//!
//! Cycles branches per channel in Overlay, Divide, Dodge and Burn; a graph has no
//! branches, so each branch is computed and one is kept by [`select`], which is exact
//! for finite values.

use crate::shader::graph::{Binary, Builder, GraphError, Unary, Value as Reg};

/// The blend types compiled (Blender's `blend_type` identifiers). Hue, Saturation,
/// Color and Value, which go through HSV, are not.
pub const BLEND_TYPES: &[&str] = &[
    "MIX",
    "DARKEN",
    "MULTIPLY",
    "BURN",
    "LIGHTEN",
    "SCREEN",
    "DODGE",
    "ADD",
    "OVERLAY",
    "SOFT_LIGHT",
    "LINEAR_LIGHT",
    "DIFFERENCE",
    "EXCLUSION",
    "SUBTRACT",
    "DIVIDE",
];

/// `z·v + (1 − z)·c` for z ∈ {0, 1} (a comparison's result): exactly `v` or `c`
/// where both are finite (0·x and x + 0 change nothing), so every branch must stay
/// finite (divisions are safe divisions).
pub fn select(bl: &mut Builder, z: Reg, v: Reg, c: Reg) -> Result<Reg, GraphError> {
    let one = bl.constant(1.0)?;
    let y = bl.binary(Binary::Sub, one, z)?;
    let v = bl.binary(Binary::Mul, z, v)?;
    let c = bl.binary(Binary::Mul, y, c)?;
    bl.binary(Binary::Add, v, c)
}

/// Cycles' `interp(a, b, t)`: a + t·(b − a).
fn interp(bl: &mut Builder, a: Reg, b: Reg, t: Reg) -> Result<Reg, GraphError> {
    let d = bl.binary(Binary::Sub, b, a)?;
    let d = bl.binary(Binary::Mul, t, d)?;
    bl.binary(Binary::Add, a, d)
}

/// Each component of `v` clamped into [0, 1] (Cycles' `saturate`).
pub fn saturate(bl: &mut Builder, v: Reg) -> Result<Reg, GraphError> {
    let (zero, one) = (bl.constant(0.0)?, bl.constant(1.0)?);
    bl.clamp(v, zero, one)
}

/// Cycles' `svm_mix` of blend type `blend` (a `blend_type` identifier) with factor
/// `t` (a float, already clamped where the node clamps it) of the colours `a` and `b`
/// (floats are grey colours); `None` for a blend type not compiled.
pub fn mix_color(
    bl: &mut Builder,
    blend: &str,
    t: Reg,
    a: Reg,
    b: Reg,
) -> Result<Option<Reg>, GraphError> {
    let a = bl.splat3(a)?;
    let b = bl.splat3(b)?;
    let one = bl.constant(1.0)?;
    let tm = bl.binary(Binary::Sub, one, t)?;
    let v = match blend {
        "MIX" => interp(bl, a, b, t)?,
        "ADD" => {
            let s = bl.binary(Binary::Add, a, b)?;
            interp(bl, a, s, t)?
        }
        "MULTIPLY" => {
            let s = bl.binary(Binary::Mul, a, b)?;
            interp(bl, a, s, t)?
        }
        "SUBTRACT" => {
            let s = bl.binary(Binary::Sub, a, b)?;
            interp(bl, a, s, t)?
        }
        "DIFFERENCE" => {
            let s = bl.binary(Binary::Sub, a, b)?;
            let s = bl.unary(Unary::Abs, s)?;
            interp(bl, a, s, t)?
        }
        "DARKEN" => {
            let s = bl.binary(Binary::Min, a, b)?;
            interp(bl, a, s, t)?
        }
        "LIGHTEN" => {
            let s = bl.binary(Binary::Max, a, b)?;
            interp(bl, a, s, t)?
        }
        // max(interp(a, a + b − 2·a·b, t), 0).
        "EXCLUSION" => {
            let s = bl.binary(Binary::Add, a, b)?;
            let two = bl.constant(2.0)?;
            let ab = bl.binary(Binary::Mul, two, a)?;
            let ab = bl.binary(Binary::Mul, ab, b)?;
            let s = bl.binary(Binary::Sub, s, ab)?;
            let v = interp(bl, a, s, t)?;
            let zero = bl.constant(0.0)?;
            bl.binary(Binary::Max, v, zero)?
        }
        // 1 − (tm + t·(1 − b))·(1 − a).
        "SCREEN" => {
            let nb = bl.binary(Binary::Sub, one, b)?;
            let w = bl.binary(Binary::Mul, t, nb)?;
            let w = bl.binary(Binary::Add, tm, w)?;
            let na = bl.binary(Binary::Sub, one, a)?;
            let w = bl.binary(Binary::Mul, w, na)?;
            bl.binary(Binary::Sub, one, w)?
        }
        // Per channel: a·(tm + 2t·b) where a < 0.5, else 1 − (tm + 2t·(1 − b))·(1 − a).
        "OVERLAY" => {
            let two = bl.constant(2.0)?;
            let t2 = bl.binary(Binary::Mul, two, t)?;
            let w = bl.binary(Binary::Mul, t2, b)?;
            let w = bl.binary(Binary::Add, tm, w)?;
            let low = bl.binary(Binary::Mul, a, w)?;
            let nb = bl.binary(Binary::Sub, one, b)?;
            let w = bl.binary(Binary::Mul, t2, nb)?;
            let w = bl.binary(Binary::Add, tm, w)?;
            let na = bl.binary(Binary::Sub, one, a)?;
            let w = bl.binary(Binary::Mul, w, na)?;
            let high = bl.binary(Binary::Sub, one, w)?;
            let half = bl.constant(0.5)?;
            let z = bl.binary(Binary::Less, a, half)?;
            select(bl, z, low, high)?
        }
        // Per channel: tm·a + t·a/b where b ≠ 0, else a.
        "DIVIDE" => {
            let ta = bl.binary(Binary::Mul, t, a)?;
            let q = bl.binary(Binary::SafeDiv, ta, b)?;
            let w = bl.binary(Binary::Mul, tm, a)?;
            let v = bl.binary(Binary::Add, w, q)?;
            let zero = bl.constant(0.0)?;
            let size = bl.unary(Unary::Abs, b)?;
            let z = bl.binary(Binary::Greater, size, zero)?;
            select(bl, z, v, a)?
        }
        // Per channel where a ≠ 0: with d = 1 − t·b, 1 where d ≤ 0, else min(a/d, 1);
        // a (that is 0) elsewhere.
        "DODGE" => {
            let d = bl.binary(Binary::Mul, t, b)?;
            let d = bl.binary(Binary::Sub, one, d)?;
            let q = bl.binary(Binary::SafeDiv, a, d)?;
            let q = bl.binary(Binary::Min, q, one)?;
            let zero = bl.constant(0.0)?;
            let positive = bl.binary(Binary::Greater, d, zero)?;
            let v = select(bl, positive, q, one)?;
            let size = bl.unary(Unary::Abs, a)?;
            let z = bl.binary(Binary::Greater, size, zero)?;
            select(bl, z, v, a)?
        }
        // Per channel: with d = tm + t·b, 0 where d ≤ 0, else 1 − (1 − a)/d clamped
        // into [0, 1].
        "BURN" => {
            let d = bl.binary(Binary::Mul, t, b)?;
            let d = bl.binary(Binary::Add, tm, d)?;
            let na = bl.binary(Binary::Sub, one, a)?;
            let q = bl.binary(Binary::SafeDiv, na, d)?;
            let q = bl.binary(Binary::Sub, one, q)?;
            let q = saturate(bl, q)?;
            let zero = bl.constant(0.0)?;
            let positive = bl.binary(Binary::Greater, d, zero)?;
            select(bl, positive, q, zero)?
        }
        // tm·a + t·((1 − a)·b·a + a·(1 − (1 − b)·(1 − a))).
        "SOFT_LIGHT" => {
            let nb = bl.binary(Binary::Sub, one, b)?;
            let na = bl.binary(Binary::Sub, one, a)?;
            let scr = bl.binary(Binary::Mul, nb, na)?;
            let scr = bl.binary(Binary::Sub, one, scr)?;
            let u = bl.binary(Binary::Mul, na, b)?;
            let u = bl.binary(Binary::Mul, u, a)?;
            let w = bl.binary(Binary::Mul, a, scr)?;
            let u = bl.binary(Binary::Add, u, w)?;
            let u = bl.binary(Binary::Mul, t, u)?;
            let w = bl.binary(Binary::Mul, tm, a)?;
            bl.binary(Binary::Add, w, u)?
        }
        // a + t·(2b + (−1)).
        "LINEAR_LIGHT" => {
            let two = bl.constant(2.0)?;
            let w = bl.binary(Binary::Mul, two, b)?;
            let m = bl.constant(-1.0)?;
            let w = bl.binary(Binary::Add, w, m)?;
            let w = bl.binary(Binary::Mul, t, w)?;
            bl.binary(Binary::Add, a, w)?
        }
        _ => return Ok(None),
    };
    Ok(Some(v))
}

/// Cycles' Mix of two floats or vectors with factor `t` (a float, or per component a
/// vector, already clamped where the node clamps it): a·(1 − t) + b·t.
pub fn mix_linear(bl: &mut Builder, t: Reg, a: Reg, b: Reg) -> Result<Reg, GraphError> {
    if let (Reg::Float(_), Reg::Float(_), Reg::Float(_)) = (t, a, b) {
        return bl.mix(a, b, t);
    }
    let one = bl.constant(1.0)?;
    let tm = bl.binary(Binary::Sub, one, t)?;
    let a = bl.binary(Binary::Mul, a, tm)?;
    let b = bl.binary(Binary::Mul, b, t)?;
    bl.binary(Binary::Add, a, b)
}

/// Cycles' Invert Color: interp(c, 1 − c, fac).
pub fn invert(bl: &mut Builder, fac: Reg, c: Reg) -> Result<Reg, GraphError> {
    let c = bl.splat3(c)?;
    let one = bl.constant(1.0)?;
    let n = bl.binary(Binary::Sub, one, c)?;
    interp(bl, c, n, fac)
}

/// Cycles' Clamp node: `value` into [min, max]; Range clamps into [max, min] when min
/// > max (the same as into [min(min, max), max(min, max)]), Min Max gives max there.
pub fn clamp(
    bl: &mut Builder,
    range: bool,
    value: Reg,
    min: Reg,
    max: Reg,
) -> Result<Reg, GraphError> {
    if !range {
        return bl.clamp(value, min, max);
    }
    let lo = bl.binary(Binary::Min, min, max)?;
    let hi = bl.binary(Binary::Max, min, max)?;
    bl.clamp(value, lo, hi)
}
