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

/// The blend types compiled (Blender's `blend_type` identifiers): every one.
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
    "HUE",
    "SATURATION",
    "VALUE",
    "COLOR",
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
        // Where B has a saturation: interp(a, a with B's hue (and, for Color, its
        // saturation), t); else a.
        "HUE" | "COLOR" => {
            let hsv_b = rgb_to_hsv(bl, b)?;
            let hsv_a = rgb_to_hsv(bl, a)?;
            let [hb, sb] = [0, 1].map(|k| bl.component(hsv_b, k));
            let (hb, sb) = (hb?, sb?);
            let sa = bl.component(hsv_a, 1)?;
            let va = bl.component(hsv_a, 2)?;
            let s = if blend == "COLOR" { sb } else { sa };
            let hsv = bl.combine3(hb, s, va)?;
            let tmp = hsv_to_rgb(bl, hsv)?;
            let v = interp(bl, a, tmp, t)?;
            let z = nonzero(bl, sb)?;
            select(bl, z, v, a)?
        }
        // Where a has a saturation: a with its saturation blended towards B's,
        // tm·s_a + t·s_b; else a.
        "SATURATION" => {
            let hsv_a = rgb_to_hsv(bl, a)?;
            let hsv_b = rgb_to_hsv(bl, b)?;
            let [ha, sa, va] = [0, 1, 2].map(|k| bl.component(hsv_a, k));
            let (ha, sa, va) = (ha?, sa?, va?);
            let sb = bl.component(hsv_b, 1)?;
            let s = blend_weights(bl, tm, sa, t, sb)?;
            let hsv = bl.combine3(ha, s, va)?;
            let v = hsv_to_rgb(bl, hsv)?;
            let z = nonzero(bl, sa)?;
            select(bl, z, v, a)?
        }
        // a with its value blended towards B's, tm·v_a + t·v_b.
        "VALUE" => {
            let hsv_a = rgb_to_hsv(bl, a)?;
            let hsv_b = rgb_to_hsv(bl, b)?;
            let [ha, sa, va] = [0, 1, 2].map(|k| bl.component(hsv_a, k));
            let (ha, sa, va) = (ha?, sa?, va?);
            let vb = bl.component(hsv_b, 2)?;
            let v = blend_weights(bl, tm, va, t, vb)?;
            let hsv = bl.combine3(ha, sa, v)?;
            hsv_to_rgb(bl, hsv)?
        }
        _ => return Ok(None),
    };
    Ok(Some(v))
}

/// u·x + w·y.
fn blend_weights(bl: &mut Builder, u: Reg, x: Reg, w: Reg, y: Reg) -> Result<Reg, GraphError> {
    let x = bl.binary(Binary::Mul, u, x)?;
    let y = bl.binary(Binary::Mul, w, y)?;
    bl.binary(Binary::Add, x, y)
}

/// 1 where `a` ≠ 0, else 0 (NaN counts as 0).
pub fn nonzero(bl: &mut Builder, a: Reg) -> Result<Reg, GraphError> {
    let zero = bl.constant(0.0)?;
    let size = bl.unary(Unary::Abs, a)?;
    bl.binary(Binary::Greater, size, zero)
}

/// 1 where `a` = `b`, else 0 (for values that are not NaN).
fn equal(bl: &mut Builder, a: Reg, b: Reg) -> Result<Reg, GraphError> {
    let one = bl.constant(1.0)?;
    let below = bl.binary(Binary::Less, a, b)?;
    let above = bl.binary(Binary::Greater, a, b)?;
    let below = bl.binary(Binary::Sub, one, below)?;
    let above = bl.binary(Binary::Sub, one, above)?;
    bl.binary(Binary::Mul, below, above)
}

/// The largest and least of a colour's channels (Cycles' fmaxf and min).
fn extremes(bl: &mut Builder, c: Reg) -> Result<([Reg; 3], Reg, Reg), GraphError> {
    let [r, g, b] = [0, 1, 2].map(|k| bl.component(c, k));
    let (r, g, b) = (r?, g?, b?);
    let max = bl.binary(Binary::Max, g, b)?;
    let max = bl.binary(Binary::Max, r, max)?;
    let min = bl.binary(Binary::Min, g, b)?;
    let min = bl.binary(Binary::Min, r, min)?;
    Ok(([r, g, b], max, min))
}

/// Cycles' `rgb_to_hsv` (util/color.h) of the colour `c`: (hue, saturation, value),
/// hue in [0, 1) from the largest channel's sector, 0 where the saturation is 0. The
/// divisions are safe divisions where Cycles' branches avoid dividing by 0.
pub fn rgb_to_hsv(bl: &mut Builder, c: Reg) -> Result<Reg, GraphError> {
    let c = bl.splat3(c)?;
    let ([r, g, _], max, min) = extremes(bl, c)?;
    let delta = bl.binary(Binary::Sub, max, min)?;
    let s = bl.binary(Binary::SafeDiv, delta, max)?;
    let toward = bl.binary(Binary::Sub, max, c)?;
    let q = bl.binary(Binary::SafeDiv, toward, delta)?;
    let [qx, qy, qz] = [0, 1, 2].map(|k| bl.component(q, k));
    let (qx, qy, qz) = (qx?, qy?, qz?);
    let hr = bl.binary(Binary::Sub, qz, qy)?;
    let two = bl.constant(2.0)?;
    let hg = bl.binary(Binary::Add, two, qx)?;
    let hg = bl.binary(Binary::Sub, hg, qz)?;
    let four = bl.constant(4.0)?;
    let hb = bl.binary(Binary::Add, four, qy)?;
    let hb = bl.binary(Binary::Sub, hb, qx)?;
    let one = bl.constant(1.0)?;
    // r == max and g == max, as "not below the largest".
    let zr = bl.binary(Binary::Less, r, max)?;
    let zr = bl.binary(Binary::Sub, one, zr)?;
    let zg = bl.binary(Binary::Less, g, max)?;
    let zg = bl.binary(Binary::Sub, one, zg)?;
    let h = select(bl, zg, hg, hb)?;
    let h = select(bl, zr, hr, h)?;
    let six = bl.constant(6.0)?;
    let h = bl.binary(Binary::Div, h, six)?;
    let zero = bl.constant(0.0)?;
    let negative = bl.binary(Binary::Less, h, zero)?;
    let wrapped = bl.binary(Binary::Add, h, one)?;
    let h = select(bl, negative, wrapped, h)?;
    let chromatic = nonzero(bl, s)?;
    let h = select(bl, chromatic, h, zero)?;
    bl.combine3(h, s, max)
}

/// Cycles' `hsv_to_rgb` of (hue, saturation, value): the hue's sector i = floor(6h)
/// (a hue of 1 is 0) picks the arrangement of v, p, q, t; grey (v, v, v) where the
/// saturation is 0.
pub fn hsv_to_rgb(bl: &mut Builder, hsv: Reg) -> Result<Reg, GraphError> {
    let [h, s, v] = [0, 1, 2].map(|k| bl.component(hsv, k));
    let (h, s, v) = (h?, s?, v?);
    let (zero, one) = (bl.constant(0.0)?, bl.constant(1.0)?);
    let at_one = equal(bl, h, one)?;
    let h = select(bl, at_one, zero, h)?;
    let six = bl.constant(6.0)?;
    let h = bl.binary(Binary::Mul, h, six)?;
    let i = bl.unary(Unary::Floor, h)?;
    let f = bl.binary(Binary::Sub, h, i)?;
    let ns = bl.binary(Binary::Sub, one, s)?;
    let p = bl.binary(Binary::Mul, v, ns)?;
    let sf = bl.binary(Binary::Mul, s, f)?;
    let nsf = bl.binary(Binary::Sub, one, sf)?;
    let q = bl.binary(Binary::Mul, v, nsf)?;
    let nf = bl.binary(Binary::Sub, one, f)?;
    let snf = bl.binary(Binary::Mul, s, nf)?;
    let nsnf = bl.binary(Binary::Sub, one, snf)?;
    let t = bl.binary(Binary::Mul, v, nsnf)?;
    let sectors = [[v, t, p], [q, v, p], [p, v, t], [p, q, v], [t, p, v]];
    let [x, y, z] = [v, p, q];
    let mut rgb = bl.combine3(x, y, z)?;
    for (k, [x, y, z]) in sectors.into_iter().enumerate().rev() {
        let here = bl.constant(k as f32)?;
        let z_k = equal(bl, i, here)?;
        let c = bl.combine3(x, y, z)?;
        rgb = select(bl, z_k, c, rgb)?;
    }
    let grey = bl.combine3(v, v, v)?;
    let chromatic = nonzero(bl, s)?;
    select(bl, chromatic, rgb, grey)
}

/// Cycles' `rgb_to_hsl` of the colour `c`: (hue, saturation, lightness), lightness
/// at most 1; hue and saturation 0 where the channels are equal.
pub fn rgb_to_hsl(bl: &mut Builder, c: Reg) -> Result<Reg, GraphError> {
    let c = bl.splat3(c)?;
    let ([r, g, b], max, min) = extremes(bl, c)?;
    let (zero, one, two) = (bl.constant(0.0)?, bl.constant(1.0)?, bl.constant(2.0)?);
    let sum = bl.binary(Binary::Add, max, min)?;
    let l = bl.binary(Binary::Div, sum, two)?;
    let l = bl.binary(Binary::Min, one, l)?;
    let delta = bl.binary(Binary::Sub, max, min)?;
    // s = Δ / (2 − max − min) where l > ½, else Δ / (max + min).
    let far = bl.binary(Binary::Sub, two, max)?;
    let far = bl.binary(Binary::Sub, far, min)?;
    let s_high = bl.binary(Binary::SafeDiv, delta, far)?;
    let s_low = bl.binary(Binary::SafeDiv, delta, sum)?;
    let half = bl.constant(0.5)?;
    let high = bl.binary(Binary::Greater, l, half)?;
    let s = select(bl, high, s_high, s_low)?;
    let gb = bl.binary(Binary::Sub, g, b)?;
    let hr = bl.binary(Binary::SafeDiv, gb, delta)?;
    let wraps = bl.binary(Binary::Less, g, b)?;
    let six = bl.constant(6.0)?;
    let wrap = bl.binary(Binary::Mul, wraps, six)?;
    let hr = bl.binary(Binary::Add, hr, wrap)?;
    let br = bl.binary(Binary::Sub, b, r)?;
    let hg = bl.binary(Binary::SafeDiv, br, delta)?;
    let hg = bl.binary(Binary::Add, hg, two)?;
    let rg = bl.binary(Binary::Sub, r, g)?;
    let hb = bl.binary(Binary::SafeDiv, rg, delta)?;
    let four = bl.constant(4.0)?;
    let hb = bl.binary(Binary::Add, hb, four)?;
    let zr = equal(bl, max, r)?;
    let zg = equal(bl, max, g)?;
    let h = select(bl, zg, hg, hb)?;
    let h = select(bl, zr, hr, h)?;
    let grey = equal(bl, max, min)?;
    let h = select(bl, grey, zero, h)?;
    let s = select(bl, grey, zero, s)?;
    let h = bl.binary(Binary::Div, h, six)?;
    bl.combine3(h, s, l)
}

/// Cycles' `hsl_to_rgb` of (hue, saturation, lightness).
pub fn hsl_to_rgb(bl: &mut Builder, hsl: Reg) -> Result<Reg, GraphError> {
    let [h, s, l] = [0, 1, 2].map(|k| bl.component(hsl, k));
    let (h, s, l) = (h?, s?, l?);
    let (zero, one, two) = (bl.constant(0.0)?, bl.constant(1.0)?, bl.constant(2.0)?);
    let six = bl.constant(6.0)?;
    let h6 = bl.binary(Binary::Mul, h, six)?;
    let channel = |bl: &mut Builder, shift: f32, rising: bool| {
        let k = bl.constant(shift)?;
        let d = bl.binary(Binary::Sub, h6, k)?;
        let d = bl.unary(Unary::Abs, d)?;
        let v = match rising {
            true => bl.binary(Binary::Sub, d, one)?,
            false => bl.binary(Binary::Sub, two, d)?,
        };
        bl.clamp(v, zero, one)
    };
    let nr = channel(bl, 3.0, true)?;
    let ng = channel(bl, 2.0, false)?;
    let nb = channel(bl, 4.0, false)?;
    let l2 = bl.binary(Binary::Mul, two, l)?;
    let l2 = bl.binary(Binary::Sub, l2, one)?;
    let l2 = bl.unary(Unary::Abs, l2)?;
    let chroma = bl.binary(Binary::Sub, one, l2)?;
    let chroma = bl.binary(Binary::Mul, chroma, s)?;
    let half = bl.constant(0.5)?;
    let n = bl.combine3(nr, ng, nb)?;
    let n = bl.binary(Binary::Sub, n, half)?;
    let n = bl.binary(Binary::Mul, n, chroma)?;
    bl.binary(Binary::Add, n, l)
}

/// Cycles' Hue/Saturation/Value node (`svm_node_hsv`): the colour's hue shifted by
/// hue − ½ (wrapped into [0, 1)), its saturation scaled and clamped into [0, 1], its
/// value scaled; blended with the input by `fac`, negative channels clamped to 0.
pub fn hue_saturation_value(
    bl: &mut Builder,
    [hue, sat, val, fac]: [Reg; 4],
    c: Reg,
) -> Result<Reg, GraphError> {
    let c = bl.splat3(c)?;
    let hsv = rgb_to_hsv(bl, c)?;
    let [h, s, v] = [0, 1, 2].map(|k| bl.component(hsv, k));
    let (h, s, v) = (h?, s?, v?);
    let h = bl.binary(Binary::Add, h, hue)?;
    let half = bl.constant(0.5)?;
    let h = bl.binary(Binary::Add, h, half)?;
    let h = bl.unary(Unary::Fract, h)?;
    let s = bl.binary(Binary::Mul, s, sat)?;
    let s = saturate(bl, s)?;
    let v = bl.binary(Binary::Mul, v, val)?;
    let hsv = bl.combine3(h, s, v)?;
    let rgb = hsv_to_rgb(bl, hsv)?;
    let one = bl.constant(1.0)?;
    let keep = bl.binary(Binary::Sub, one, fac)?;
    let rgb = blend_weights(bl, fac, rgb, keep, c)?;
    let zero = bl.constant(0.0)?;
    bl.binary(Binary::Max, rgb, zero)
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

/// Cycles' Gamma node (`svm_math_gamma_color`): each channel above 0 raised to
/// `gamma` (powf), the others kept; white wherever `gamma` is 0. The power's base is
/// chosen as 1 where the channel is not above 0, so the branch not taken is finite and
/// [`select`] exact.
pub fn gamma(bl: &mut Builder, c: Reg, gamma: Reg) -> Result<Reg, GraphError> {
    let c = bl.splat3(c)?;
    let (zero, one) = (bl.constant(0.0)?, bl.constant(1.0)?);
    let above = bl.binary(Binary::Greater, c, zero)?;
    let base = select(bl, above, c, one)?;
    let raised = bl.binary(Binary::Pow, base, gamma)?;
    let v = select(bl, above, raised, c)?;
    let white = equal(bl, gamma, zero)?;
    select(bl, white, one, v)
}

/// Cycles' Brightness/Contrast node (`svm_brightness_contrast`): each channel
/// max((1 + contrast)·c + (brightness − contrast·0.5), 0).
pub fn brightness_contrast(
    bl: &mut Builder,
    c: Reg,
    brightness: Reg,
    contrast: Reg,
) -> Result<Reg, GraphError> {
    let c = bl.splat3(c)?;
    let (zero, one, half) = (bl.constant(0.0)?, bl.constant(1.0)?, bl.constant(0.5)?);
    let a = bl.binary(Binary::Add, one, contrast)?;
    let b = bl.binary(Binary::Mul, contrast, half)?;
    let b = bl.binary(Binary::Sub, brightness, b)?;
    let v = bl.binary(Binary::Mul, a, c)?;
    let v = bl.binary(Binary::Add, v, b)?;
    bl.binary(Binary::Max, v, zero)
}
