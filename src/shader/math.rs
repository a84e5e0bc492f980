//! Blender's Math node operations as Cycles evaluates them (`svm_math_util.h`: the
//! "safe" functions, 0 where the operation is undefined), each with its interval bound
//! for the range analysis ([`super::graph::Program::bounds`]). Tested value for value
//! against bpy 5.0.1's Geometry Nodes, which evaluates the same definitions
//! (`tests/blender_math.rs`): equal, or within 2 ulps where the operation calls a
//! transcendental function of the C library (powf, expf, logf).

use super::interval::Interval;

/// The smallest positive f32: where `ln` and `1/√` of a positive operand are largest.
const TINY: f32 = f32::from_bits(1);
/// The smallest nonzero |ln b| of an f32 b (b = 1 − 2⁻²⁴): bounds a quotient by ln b.
const LN_NEAREST_ONE: f32 = 5.960_464_5e-8;
/// Relative room for a transcendental function's rounding (a few ulps).
const ULPS: f32 = 1e-6;

/// Power: `a^b`, 0 for a negative base with a non-integer exponent (`safe_powf`).
#[inline]
pub fn pow(a: f32, b: f32) -> f32 {
    if a < 0.0 && b != b.trunc() {
        0.0
    } else {
        a.powf(b)
    }
}

/// Logarithm of `a` to base `b`, 0 where either is not positive or ln b is 0
/// (`safe_logf`).
#[inline]
pub fn log(a: f32, b: f32) -> f32 {
    if a <= 0.0 || b <= 0.0 {
        return 0.0;
    }
    let lb = b.ln();
    if lb != 0.0 {
        a.ln() / lb
    } else {
        0.0
    }
}

/// Inverse square root, 0 where `a ≤ 0` (`inversesqrtf`).
#[inline]
pub fn inverse_sqrt(a: f32) -> f32 {
    if a > 0.0 {
        1.0 / a.sqrt()
    } else {
        0.0
    }
}

/// Sign: −1, 0 or 1 (`compatible_signf`).
#[inline]
pub fn sign(a: f32) -> f32 {
    if a == 0.0 {
        0.0
    } else if a < 0.0 {
        -1.0
    } else {
        1.0
    }
}

/// Round: `floor(a + 0.5)` (halves up, as Cycles, not away from zero).
#[inline]
pub fn round(a: f32) -> f32 {
    (a + 0.5).floor()
}

/// Truncate towards zero.
#[inline]
pub fn trunc(a: f32) -> f32 {
    if a >= 0.0 {
        a.floor()
    } else {
        a.ceil()
    }
}

/// Fraction: `a − floor(a)`.
#[inline]
pub fn fract(a: f32) -> f32 {
    a - a.floor()
}

/// Truncated modulo: `fmod(a, b)`, 0 where b is 0 (`safe_modulo`).
#[inline]
pub fn modulo(a: f32, b: f32) -> f32 {
    if b != 0.0 {
        a % b
    } else {
        0.0
    }
}

/// Floored modulo: `a − floor(a/b)·b`, 0 where b is 0 (`safe_floored_modulo`).
#[inline]
pub fn floored_modulo(a: f32, b: f32) -> f32 {
    if b != 0.0 {
        a - (a / b).floor() * b
    } else {
        0.0
    }
}

/// Bound of [`pow`]. On |a| ≥ 0 the power is monotone in each argument, so its
/// extremes over the box are at the corners; a negative base gives ± that magnitude (an
/// integer exponent) or 0.
pub fn pow_bound(a: Interval, b: Interval) -> Interval {
    let m = a.abs();
    let corners = [
        pow(m.lo, b.lo),
        pow(m.lo, b.hi),
        pow(m.hi, b.lo),
        pow(m.hi, b.hi),
    ];
    if corners.iter().any(|c| !c.is_finite()) {
        return Interval::EVERYTHING;
    }
    let lo = corners.iter().copied().fold(f32::INFINITY, f32::min);
    let hi = corners.iter().copied().fold(f32::NEG_INFINITY, f32::max);
    let r = if a.lo >= 0.0 {
        Interval::new(lo, hi)
    } else {
        Interval::new(-hi, hi)
    };
    r.widened(ULPS, 0.0)
}

/// Bound of [`log`]: ln over the operands' positive parts (a positive f32 is at least
/// [`TINY`]), their quotient where ln b keeps one sign, else ± the largest |ln a| over
/// the smallest nonzero |ln b|; and 0 where an operand can be ≤ 0 or ln b 0.
pub fn log_bound(a: Interval, b: Interval) -> Interval {
    let zero = Interval::point(0.0);
    if a.hi <= 0.0 || b.hi <= 0.0 {
        return zero;
    }
    let ln = |x: Interval| Interval::new(x.lo.max(TINY).ln(), x.hi.ln());
    let (la, lb) = (ln(a), ln(b));
    let q = if lb.lo > 0.0 || lb.hi < 0.0 {
        la.div(lb)
    } else {
        let m = la.lo.abs().max(la.hi.abs()) / LN_NEAREST_ONE;
        Interval::new(-m, m)
    };
    let q = q.widened(ULPS, 0.0);
    if a.lo <= 0.0 || b.lo <= 0.0 || (lb.lo <= 0.0 && lb.hi >= 0.0) {
        q.hull(zero)
    } else {
        q
    }
}

/// Bound of [`inverse_sqrt`] (decreasing on the positive part; 0 where a ≤ 0).
pub fn inverse_sqrt_bound(a: Interval) -> Interval {
    if a.hi <= 0.0 {
        return Interval::point(0.0);
    }
    let lo = if a.lo <= 0.0 { 0.0 } else { inverse_sqrt(a.hi) };
    Interval::new(lo, inverse_sqrt(a.lo.max(TINY))).widened(ULPS, 0.0)
}

/// Bound of `exp` (increasing; unbounded where it overflows).
pub fn exp_bound(a: Interval) -> Interval {
    a.monotone(f32::exp).widened(ULPS, 0.0)
}

/// Bound of [`fract`]: increasing within one integer step, else [0, 1] (1 itself is
/// reached by rounding: a − floor(a) of a tiny negative a).
pub fn fract_bound(a: Interval) -> Interval {
    if a.lo.floor() == a.hi.floor() {
        a.monotone(fract)
    } else {
        Interval::new(0.0, 1.0)
    }
}

/// Bound of [`modulo`]: exact (fmod rounds nothing); the sign of a, and a magnitude
/// below both |a| and |b|.
pub fn modulo_bound(a: Interval, b: Interval) -> Interval {
    let bmax = b.lo.abs().max(b.hi.abs());
    let lo = if a.lo < 0.0 { -(-a.lo).min(bmax) } else { 0.0 };
    let hi = if a.hi > 0.0 { a.hi.min(bmax) } else { 0.0 };
    Interval::new(lo, hi)
}

/// Bound of [`floored_modulo`]: [0, b] for b > 0, [b, 0] for b < 0, and 0 at b = 0;
/// widened by a few ulps of |a|, since a/b rounded to an integer can leave a − floor(a/b)·b
/// a rounding error below 0 (or past b).
pub fn floored_modulo_bound(a: Interval, b: Interval) -> Interval {
    let r = Interval::new(b.lo.min(0.0), b.hi.max(0.0));
    let amax = a.lo.abs().max(a.hi.abs());
    r.widened(0.0, ULPS * (amax + r.lo.abs().max(r.hi)))
}

/// Arcsine of `a` clamped into [-1, 1] (`safe_asinf`).
#[inline]
/// Blender's Map Range Smoother Step of the factor `a` (Geometry Nodes'
/// `map_smootherstep`, Cycles' `smootherstep` of the normalised value): `a` clamped to
/// [0, 1], then x³ (x (6x − 15) + 10), in that order of operations.
pub fn smootherstep(a: f32) -> f32 {
    let x = a.clamp(0.0, 1.0);
    x * x * x * (x * (x * 6.0 - 15.0) + 10.0)
}

pub fn asin(a: f32) -> f32 {
    a.clamp(-1.0, 1.0).asin()
}

/// Arccosine of `a` clamped into [-1, 1] (`safe_acosf`).
#[inline]
pub fn acos(a: f32) -> f32 {
    a.clamp(-1.0, 1.0).acos()
}

/// Bound of `sin` over `a`: ±1 where the interval holds a crest (π/2 + 2πk) or a
/// trough (−π/2 + 2πk), else the ends' values; `phase` shifts it (π/2 gives `cos`).
pub fn sin_bound(a: Interval, phase: f64) -> Interval {
    let (lo, hi) = (a.lo as f64 + phase, a.hi as f64 + phase);
    if !(lo.is_finite() && hi.is_finite()) || hi - lo >= std::f64::consts::TAU {
        return Interval::new(-1.0, 1.0);
    }
    let holds = |x0: f64| {
        // Some x0 + 2πk in [lo, hi]?
        let k = ((lo - x0) / std::f64::consts::TAU).ceil();
        x0 + k * std::f64::consts::TAU <= hi
    };
    let ends = Interval::new(lo.sin() as f32, hi.sin() as f32);
    let top = if holds(std::f64::consts::FRAC_PI_2) {
        1.0
    } else {
        ends.hi
    };
    let bottom = if holds(-std::f64::consts::FRAC_PI_2) {
        -1.0
    } else {
        ends.lo
    };
    // The f32 evaluation is within an ulp or two of the f64 one here.
    let w = Interval::new(bottom, top).widened(0.0, 1e-6);
    Interval::new(w.lo.max(-1.0), w.hi.min(1.0))
}

/// Bound of `tan`: increasing between its poles (π/2 + πk); unbounded where the
/// interval comes within 1e-3 of one.
pub fn tan_bound(a: Interval) -> Interval {
    let (lo, hi) = (a.lo as f64, a.hi as f64);
    if !(lo.is_finite() && hi.is_finite()) {
        return Interval::EVERYTHING;
    }
    let pi = std::f64::consts::PI;
    let k = ((lo - std::f64::consts::FRAC_PI_2 - 1e-3) / pi).ceil();
    if std::f64::consts::FRAC_PI_2 + k * pi <= hi + 1e-3 {
        return Interval::EVERYTHING;
    }
    Interval::new(lo.tan() as f32, hi.tan() as f32).widened(ULPS, 0.0)
}

/// Bound of `cosh` (decreasing below 0, increasing above).
pub fn cosh_bound(a: Interval) -> Interval {
    let ends = Interval::new(a.lo.cosh(), a.hi.cosh());
    let lo = if a.lo <= 0.0 && a.hi >= 0.0 {
        1.0
    } else {
        ends.lo
    };
    Interval::new(lo, ends.hi).widened(ULPS, 0.0)
}

/// Cycles' blackbody colour of `t` kelvin in Rec.709 (`svm_math_blackbody_color_rec709`,
/// a piecewise rational fit with the coefficients of Cycles' `kernel/tables.h`), then
/// clamped at 0 as the Blackbody node does: constant below 800 K and from 12,000 K. Each
/// product rounded on its own (Cycles' SSE4.2 kernel and Geometry Nodes; its AVX2
/// kernel fuses some and differs in the last bits).
pub fn blackbody(t: f32) -> [f32; 3] {
    let rgb = if t >= 12000.0 {
        [0.826_295_5, 0.994_508, 1.566_307_7]
    } else if t < 800.0 {
        [5.413_294_3, -0.203_193_9, -0.082_253_52]
    } else {
        let i = BLACKBODY_BOUNDS.iter().filter(|&&b| t >= b).count();
        let (r, g, b) = (BLACKBODY_R[i], BLACKBODY_G[i], BLACKBODY_B[i]);
        let ti = 1.0 / t;
        [
            r[0] * ti + r[1] * t + r[2],
            g[0] * ti + g[1] * t + g[2],
            ((b[0] * t + b[1]) * t + b[2]) * t + b[3],
        ]
    };
    rgb.map(|c| if c > 0.0 { c } else { 0.0 })
}

/// The lower ends of the blackbody fit's pieces 1 to 6 (piece 0 starts at 800 K).
const BLACKBODY_BOUNDS: [f32; 6] = [965.0, 1167.0, 1449.0, 1902.0, 3315.0, 6365.0];

const BLACKBODY_R: [[f32; 3]; 7] = [
    [1.61919106e+03, -2.05010916e-03, 5.02995757e+00],
    [2.48845471e+03, -1.11330907e-03, 3.22621544e+00],
    [3.34143193e+03, -4.86551192e-04, 1.76486769e+00],
    [4.09461742e+03, -1.27446582e-04, 7.25731635e-01],
    [4.67028036e+03, 2.91258199e-05, 1.26703442e-01],
    [4.59509185e+03, 2.87495649e-05, 1.50345020e-01],
    [3.78717450e+03, 9.35907826e-06, 3.99075871e-01],
];

const BLACKBODY_G: [[f32; 3]; 7] = [
    [-4.88999748e+02, 6.04330754e-04, -7.55807526e-02],
    [-7.55994277e+02, 3.16730098e-04, 4.78306139e-01],
    [-1.02363977e+03, 1.20223470e-04, 9.36662319e-01],
    [-1.26571316e+03, 4.87340896e-06, 1.27054498e+00],
    [-1.42529332e+03, -4.01150431e-05, 1.43972784e+00],
    [-1.17554822e+03, -2.16378048e-05, 1.30408023e+00],
    [-5.00799571e+02, -4.59832026e-06, 1.09098763e+00],
];

const BLACKBODY_B: [[f32; 4]; 7] = [
    [
        5.96945309e-11,
        -4.85742887e-08,
        -9.70622247e-05,
        -4.07936148e-03,
    ],
    [
        2.40430366e-11,
        5.55021075e-08,
        -1.98503712e-04,
        2.89312858e-02,
    ],
    [
        -1.40949732e-11,
        1.89878968e-07,
        -3.56632824e-04,
        9.10767778e-02,
    ],
    [
        -3.61460868e-11,
        2.84822009e-07,
        -4.93211319e-04,
        1.56723440e-01,
    ],
    [
        -1.97075738e-11,
        1.75359352e-07,
        -2.50542825e-04,
        -2.22783266e-02,
    ],
    [
        -1.61997957e-13,
        -1.64216008e-08,
        3.86216271e-04,
        -7.38077418e-01,
    ],
    [
        6.72650283e-13,
        -2.73078809e-08,
        4.24098264e-04,
        -7.52335691e-01,
    ],
];

/// Bounds of [`blackbody`] over every temperature: its range, checked (and found tight
/// to 2e-4) at every 1/512 K up to 13,000 K by `the_blackbody_range_bounds_every_temperature`.
pub const BLACKBODY_RANGE: [(f32, f32); 3] =
    [(0.826_295_5, 5.413_87), (0.0, 0.995_03), (0.0, 1.566_9)];
