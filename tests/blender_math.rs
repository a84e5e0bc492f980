//! Blender's Math node (and below, Vector Math and the Gradient Texture) against
//! Blender 5.0.1: `tests/fixtures/blender_math_values.py`
//! has Geometry Nodes evaluate each operation at 20,000 inputs (A, B, C the points'
//! coordinates, drawn so that every special case occurs: negative bases, integer and
//! zero B, B near A), and the program `nimbus::scene::blender_graph::math` compiles
//! must give the same value.
//!
//! Geometry Nodes runs blenlib's safe math functions, the definitions Cycles' SVM uses
//! (`svm_math_util.h`), but for Radians and Degrees (below). The operations of
//! arithmetic and rounding must be equal to the bit; those calling the C library
//! (powf, logf, expf, the trigonometric and hyperbolic functions) within 2.5e-7
//! relative (2 ulps; measured: every value equal to the bit). Each operation's
//! interval bound ([`Program::bounds`]) is checked too: over 2,000 random boxes of
//! (A, B, C), 50 points in each evaluate inside the box's bounds.
//!
//! The Python that imports bpy is `NIMBUS_BPY_PYTHON`; without it the test prints one
//! `SKIPPED` line, or fails under `NIMBUS_REQUIRE_DATA=1`.

mod common;

use nimbus::scene::blender_color::{self, BLEND_TYPES};
use nimbus::scene::blender_graph::{
    curves, float_curve, gradient, magic, map_range, mapping, math, vector_math, vector_rotate,
    wave, Rotation,
};
use nimbus::shader::graph::{Binary, Builder, Program};
use nimbus::shader::interval::Interval;

const N: usize = 20_000;

/// Relative tolerances: equal to the bit; a C library function (powf, sinf…), whose
/// last bit may differ between builds (none did: measured 0); and Radians and Degrees,
/// which Geometry Nodes computes in double (`DEG2RAD`) where Cycles' SVM, which Nimbus
/// follows, multiplies by `M_PI_F / 180.0f` in float: 1 ulp apart at some inputs
/// (measured 1.19e-7 at 1,852 and 13,351 of 20,000).
const EXACT: f64 = 0.0;
const LIBM: f64 = 2.5e-7;
const ONE_ULP: f64 = 1.2e-7;

/// The operations compiled since stop 59 (Wrap since stop 60), and their tolerance
/// against Geometry Nodes.
const OPERATIONS: [(&str, f64); 29] = [
    ("POWER", LIBM),
    ("LOGARITHM", LIBM),
    ("INVERSE_SQRT", EXACT),
    ("EXPONENT", LIBM),
    ("SIGN", EXACT),
    ("ROUND", EXACT),
    ("CEIL", EXACT),
    ("TRUNC", EXACT),
    ("FRACT", EXACT),
    ("MODULO", EXACT),
    ("FLOORED_MODULO", EXACT),
    ("COMPARE", EXACT),
    ("SINE", LIBM),
    ("COSINE", LIBM),
    ("TANGENT", LIBM),
    ("ARCSINE", LIBM),
    ("ARCCOSINE", LIBM),
    ("ARCTANGENT", LIBM),
    ("ARCTAN2", LIBM),
    ("SINH", LIBM),
    ("COSH", LIBM),
    ("TANH", LIBM),
    ("RADIANS", ONE_ULP),
    ("DEGREES", ONE_ULP),
    ("SMOOTH_MIN", EXACT),
    ("SMOOTH_MAX", EXACT),
    ("SNAP", EXACT),
    ("PINGPONG", EXACT),
    ("WRAP", EXACT),
];

/// The program of Math `op` with A, B, C the position's x, y, z.
fn program(op: &str) -> Program {
    let mut bl = Builder::default();
    let p = bl.position();
    let [a, b, c] = [0, 1, 2].map(|k| bl.component(p, k).unwrap());
    let v = math(&mut bl, op, a, b, c).unwrap().expect("compiled");
    bl.finish(v).unwrap()
}

/// Runs the bpy fixture `script` for the operations `ops`; it writes one `<op>.f32`
/// file each into the returned directory.
fn run_fixture(python: std::path::PathBuf, script: &str, ops: &[&str]) -> tempfile::TempDir {
    let dir = tempfile::tempdir().expect("temp dir");
    let ops = ops.join(",");
    common::data::run_fixture(
        python,
        script,
        [ops.as_str().as_ref(), dir.path().as_os_str()],
    );
    dir
}

/// The fixture's `N` rows of `W` little-endian floats from `<op>.f32` in `dir`.
fn read_rows<const W: usize>(dir: &std::path::Path, op: &str) -> Vec<[f32; W]> {
    let path = dir.join(format!("{op}.f32"));
    let bytes = std::fs::read(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    assert_eq!(bytes.len(), N * 4 * W, "{}: size", path.display());
    bytes
        .chunks_exact(4 * W)
        .map(|row| {
            std::array::from_fn(|i| f32::from_le_bytes(row[4 * i..4 * i + 4].try_into().unwrap()))
        })
        .collect()
}

/// A curve fixture's `<name>.table.f32` in `dir`: (min_x, max_x, extrapolate, the
/// table entries that follow).
fn read_curve_table(dir: &std::path::Path, name: &str) -> (f32, f32, bool, Vec<f32>) {
    let path = dir.join(format!("{name}.table.f32"));
    let raw = std::fs::read(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let head: Vec<f32> = raw
        .chunks_exact(4)
        .map(|b| f32::from_le_bytes(b.try_into().unwrap()))
        .collect();
    (head[0], head[1], head[2] != 0.0, head[3..].to_vec())
}

/// The largest difference of a 257-entry curve table over [min, max] from the exact
/// `points` (straight segments) at its sample positions; 0 without points.
fn table_error(table: &[f32], (min, max): (f32, f32), points: &[(f64, f64)]) -> f64 {
    if points.is_empty() {
        return 0.0;
    }
    table
        .iter()
        .enumerate()
        .map(|(i, v)| {
            let x = min as f64 + i as f64 / 256.0 * (max - min) as f64;
            (*v as f64 - polyline(points, x)).abs()
        })
        .fold(0.0, f64::max)
}

/// A curve lookup's error against Geometry Nodes over what the curve tests allow, at
/// input `x` (Factor `fac`) of a curve over [min, max] whose table is `eps` off the
/// exact curve: `MIX_ROUNDING` inside the range, plus beyond it, extrapolated, the
/// table's error amplified by the distance d in range units, (ε + 2ε·d·256)·|fac|; all
/// relative to max(1, |reference|). NaN counts as infinite.
fn curve_error(
    (ours, reference): (f32, f32),
    (x, fac): (f32, f32),
    (min, max): (f32, f32),
    extrapolate: bool,
    eps: f64,
) -> f64 {
    let d = ((min as f64 - x as f64).max(x as f64 - max as f64) / (max - min) as f64).max(0.0);
    let scale = (reference.abs() as f64).max(1.0);
    let allowed = MIX_ROUNDING
        + match extrapolate && d > 0.0 {
            true => (eps + 2.0 * eps * d * 256.0) * fac.abs() as f64 / scale,
            false => 0.0,
        };
    let e = (ours as f64 - reference as f64).abs() / scale / allowed;
    if e.is_nan() {
        f64::INFINITY
    } else {
        e
    }
}

/// `v` as a program: its component `k`, or the whole colour when `None`.
fn finish_component(
    mut bl: Builder,
    v: nimbus::shader::graph::Value,
    component: Option<u16>,
) -> Program {
    match component {
        Some(k) => {
            let c = bl.component(v, k).unwrap();
            bl.finish(c).unwrap()
        }
        None => bl.finish_rgb(v).unwrap(),
    }
}

#[test]
fn math_operations_match_blender() {
    let Some(python) = common::data::bpy_python("bpy, numpy") else {
        return;
    };
    let ops: Vec<&str> = OPERATIONS.iter().map(|(o, _)| *o).collect();
    let dir = run_fixture(python, "blender_math_values.py", &ops);
    let mut failed = Vec::new();
    for (op, allowed) in OPERATIONS {
        let prog = program(op);
        let (equal, worst) = against_rows(&prog, &read_rows::<4>(dir.path(), op));
        println!("{op:<15} {equal}/{N} equal to the bit; worst relative error {worst:.2e}");
        if worst > allowed {
            failed.push(op);
        }
    }
    assert!(failed.is_empty(), "{failed:?}");
}

/// The range analysis of each new operation bounds it: 2,000 boxes (corners drawn in
/// [-4, 4), a quarter of them with B fixed at an integer, as Power's negative bases
/// need), 50 uniform points in each, every value inside the box's bounds.
#[test]
fn math_operation_bounds_hold() {
    let mut uniform = xorshift(0x2545_f491_4f6c_dd1d);
    for (op, _) in OPERATIONS {
        let checked = assert_bounds_hold(op, &program(op), 4.0, true, &mut uniform);
        println!("{op:<15} {checked} points inside their boxes' bounds");
    }
}

/// Uniform floats in [lo, hi) from a xorshift stream seeded by `state`.
fn xorshift(mut state: u64) -> impl FnMut(f32, f32) -> f32 {
    move |lo, hi| {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        lo + (hi - lo) * ((state >> 40) as f32 / (1u64 << 24) as f32)
    }
}

/// Asserts that `prog`'s range analysis bounds it: 2,000 boxes with corners drawn in
/// [-r, r)^3, every other one narrow (5 % of the draw), and with `integer_b` every
/// fourth with its y fixed at an integer (Power's negative bases need one); 50 uniform
/// points in each inside the box's bounds. Returns the points checked.
fn assert_bounds_hold(
    name: &str,
    prog: &Program,
    r: f32,
    integer_b: bool,
    uniform: &mut impl FnMut(f32, f32) -> f32,
) -> usize {
    let mut checked = 0;
    for k in 0..2_000 {
        let mut lo = [0f32; 3];
        let mut hi = [0f32; 3];
        for d in 0..3 {
            let (x, y) = (uniform(-r, r), uniform(-r, r));
            // Narrow boxes as well as wide ones.
            let w = if k % 2 == 0 { 1.0 } else { 0.05 };
            lo[d] = x.min(x + w * (y - x));
            hi[d] = x.max(x + w * (y - x));
        }
        if integer_b && k % 4 == 0 {
            let n = uniform(-3.0, 4.0).floor();
            (lo[1], hi[1]) = (n, n);
        }
        let b = prog.bounds(lo, hi, Interval::point(0.0));
        for _ in 0..50 {
            let p: [f32; 3] = std::array::from_fn(|d| uniform(lo[d], hi[d]).clamp(lo[d], hi[d]));
            let v = prog.eval(p, 0.0);
            assert!(
                v >= b.lo && v <= b.hi,
                "{name}: {v} at {p:?} outside [{}, {}] of the box {lo:?} .. {hi:?}",
                b.lo,
                b.hi
            );
            checked += 1;
        }
    }
    checked
}

/// `prog` at each row's (x, y, z) against the row's value: how many are equal to the
/// bit (or both zero), and the worst relative error of the others (NaN counts as
/// infinite).
fn against_rows(prog: &Program, rows: &[[f32; 4]]) -> (usize, f64) {
    let (mut equal, mut worst) = (0, 0f64);
    for r in rows {
        let ours = prog.eval([r[0], r[1], r[2]], 0.0);
        if ours.to_bits() == r[3].to_bits() || ours == r[3] {
            equal += 1;
            continue;
        }
        let e = (ours as f64 - r[3] as f64).abs() / (r[3].abs() as f64).max(1e-30);
        worst = worst.max(if e.is_nan() { f64::INFINITY } else { e });
    }
    (equal, worst)
}

/// Vector Math's operations, and their tolerance against Geometry Nodes: equal to the
/// bit where Cycles and blenlib compute the same float operations in the same order;
/// the C library's functions within `LIBM` relative; and the operations that sum
/// products (Cross Product, Project, Normalize, Length, Distance, Dot Product) within
/// `SUMS` of the sum of the terms' magnitudes (module docs of `vector_math_match_blender`).
const VECTOR_OPERATIONS: [(&str, f64); 25] = [
    ("ADD", EXACT),
    ("SUBTRACT", EXACT),
    ("MULTIPLY", EXACT),
    ("DIVIDE", EXACT),
    ("MULTIPLY_ADD", EXACT),
    ("CROSS_PRODUCT", SUMS),
    ("PROJECT", SUMS),
    ("FACEFORWARD", EXACT),
    ("DOT_PRODUCT", SUMS),
    ("DISTANCE", SUMS),
    ("LENGTH", SUMS),
    ("SCALE", EXACT),
    ("NORMALIZE", SUMS),
    ("ABSOLUTE", EXACT),
    ("POWER", LIBM),
    ("SIGN", EXACT),
    ("MINIMUM", EXACT),
    ("MAXIMUM", EXACT),
    ("FLOOR", EXACT),
    ("CEIL", EXACT),
    ("FRACTION", EXACT),
    ("MODULO", EXACT),
    ("WRAP", EXACT),
    ("REFLECT", SUMS),
    ("REFRACT", SUMS),
];

/// Vector Math's remaining operations are compiled as well: Snap, Sine, Cosine and
/// Tangent reuse the Math node's definitions checked above, so they are listed here
/// only to be evaluated against Geometry Nodes too.
const VECTOR_LIBM: [(&str, f64); 4] = [
    ("SNAP", EXACT),
    ("SINE", LIBM),
    ("COSINE", LIBM),
    ("TANGENT", LIBM),
];

/// Where the reference sums products in another order or fused (Cycles' AVX2 kernel
/// contracts `a b − c d` into one rounding), each result may differ by a few roundings
/// of the largest term: 4 ulps of the sum of the terms' magnitudes.
const SUMS: f64 = 4.0 * f32::EPSILON as f64;

/// Vector Math `op` at A (the position) with B, C and Scale as constants: the graph
/// the add-on writes for a node whose other sockets are unlinked.
fn vector_program(op: &str, b: [f32; 3], c: [f32; 3], s: f32) -> Program {
    let mut bl = Builder::default();
    let a = bl.position();
    let (b, c, s) = (
        bl.vector3(b).unwrap(),
        bl.vector3(c).unwrap(),
        bl.constant(s).unwrap(),
    );
    let v = vector_math(&mut bl, op, a, b, c, s)
        .unwrap()
        .expect("compiled");
    match v.width() {
        1 => bl.finish(v).unwrap(),
        _ => bl.finish_rgb(v).unwrap(),
    }
}

/// Geometry Nodes evaluates Vector Math at 20,000 rows of A, B, C and Scale
/// (`tests/fixtures/blender_vector_math_values.py`: special cases drawn as for Math),
/// and every operation Nimbus compiles must give the same vector. Measured: see the
/// printed lines (docs/shaders.md quotes them). The error of the sums is taken against
/// the magnitude of their terms, |A|·|B| + |A| + |B| + |C| (a result that cancels is
/// only as exact as its terms), and relative to the value for the others.
#[test]
fn vector_math_operations_match_blender() {
    let Some(python) = common::data::bpy_python("bpy, numpy") else {
        return;
    };
    let all: Vec<(&str, f64)> = VECTOR_OPERATIONS.into_iter().chain(VECTOR_LIBM).collect();
    let ops: Vec<&str> = all.iter().map(|(o, _)| *o).collect();
    let dir = run_fixture(python, "blender_vector_math_values.py", &ops);
    let norm = |v: &[f32]| v.iter().map(|x| (*x as f64).powi(2)).sum::<f64>().sqrt();
    let mut failed = Vec::new();
    let mut modulo_by_zero = 0;
    for (op, allowed) in all {
        let rows = read_rows::<13>(dir.path(), op);
        let (mut equal, mut worst) = (0, 0f64);
        for r in &rows {
            let (a, b, c, s) = (
                [r[0], r[1], r[2]],
                [r[3], r[4], r[5]],
                [r[6], r[7], r[8]],
                r[9],
            );
            let prog = vector_program(op, b, c, s);
            let ours = match prog.outputs_rgb() {
                true => prog.eval_rgb(a, 0.0),
                false => [prog.eval(a, 0.0), 0.0, 0.0],
            };
            let mut reference = [r[10], r[11], r[12]];
            if op == "MODULO" {
                // Geometry Nodes' fmod is NaN where B is 0; Cycles' svm_vector_math takes
                // `safe_modulo`, 0 there, as Nimbus does.
                for k in 0..3 {
                    if b[k] == 0.0 {
                        assert!(reference[k].is_nan(), "MODULO by 0 in Geometry Nodes");
                        reference[k] = 0.0;
                        modulo_by_zero += 1;
                    }
                }
            }
            if (0..3)
                .all(|k| ours[k].to_bits() == reference[k].to_bits() || ours[k] == reference[k])
            {
                equal += 1;
                continue;
            }
            let terms = norm(&a) * norm(&b) + norm(&a) + norm(&b) + norm(&c);
            for k in 0..3 {
                let d = (ours[k] as f64 - reference[k] as f64).abs();
                let scale = match allowed == SUMS {
                    true => terms,
                    false => (reference[k].abs() as f64).max(1e-30),
                };
                let e = d / scale;
                worst = worst.max(if e.is_nan() { f64::INFINITY } else { e });
            }
        }
        println!("{op:<15} {equal}/{N} equal to the bit; worst error {worst:.2e} (allowed {allowed:.1e})");
        if worst > allowed {
            failed.push(op);
        }
    }
    println!(
        "MODULO: {modulo_by_zero} components by 0, NaN in Geometry Nodes, 0 in Cycles and Nimbus"
    );
    assert!(modulo_by_zero > 1000, "the inputs must divide by 0 often");
    assert!(failed.is_empty(), "{failed:?}");
}

/// Every Gradient Texture type, as `blender_graph::gradient` compiles it on Vector the
/// position, against Geometry Nodes at 20,000 points
/// (`tests/fixtures/blender_gradient_values.py`: uniform, on and near the unit sphere,
/// on the axes where atan2 turns, and across the saturation's ends). Equal to the bit,
/// but the spherical types, whose length sums squares (`SUMS` of the radius), and
/// Radial: Geometry Nodes divides atan2f(y, x) by `M_PI * 2.0f`, a double, so in
/// double, where Cycles' SVM (and Nimbus) divides by `M_2PI_F` in float; the two are
/// within an ulp of the sum's 1/2 (6e-8), so Radial is held to `LIBM` of 1, absolute.
#[test]
fn gradient_types_match_blender() {
    let Some(python) = common::data::bpy_python("bpy, numpy") else {
        return;
    };
    const TYPES: [(&str, f64); 7] = [
        ("LINEAR", EXACT),
        ("QUADRATIC", EXACT),
        ("EASING", EXACT),
        ("DIAGONAL", EXACT),
        ("RADIAL", LIBM),
        ("SPHERICAL", SUMS),
        ("QUADRATIC_SPHERE", SUMS),
    ];
    let kinds: Vec<&str> = TYPES.iter().map(|(k, _)| *k).collect();
    let dir = run_fixture(python, "blender_gradient_values.py", &kinds);
    let mut failed = Vec::new();
    for (kind, allowed) in TYPES {
        let mut bl = Builder::default();
        let p = bl.position();
        let fac = gradient(&mut bl, kind, p).unwrap().expect("compiled");
        let prog = bl.finish(fac).unwrap();
        let (mut equal, mut worst) = (0, 0f64);
        for r in read_rows::<4>(dir.path(), kind) {
            let ours = prog.eval([r[0], r[1], r[2]], 0.0);
            if ours.to_bits() == r[3].to_bits() || ours == r[3] {
                equal += 1;
                continue;
            }
            let scale = match (kind, allowed == SUMS) {
                ("RADIAL", _) => 1.0,
                (_, true) => 1.0 + (r[0] as f64).hypot(r[1] as f64).hypot(r[2] as f64),
                _ => (r[3].abs() as f64).max(1e-30),
            };
            let e = (ours as f64 - r[3] as f64).abs() / scale;
            worst = worst.max(if e.is_nan() { f64::INFINITY } else { e });
        }
        println!("{kind:<17} {equal}/{N} equal to the bit; worst error {worst:.2e} (allowed {allowed:.1e})");
        if worst > allowed {
            failed.push(kind);
        }
    }
    assert!(failed.is_empty(), "{failed:?}");
}

/// Map Range (Float) kinds against bpy 5.0.1's Geometry Nodes
/// (tests/fixtures/blender_map_range_values.py): Value = x mapped from [y, z] to
/// [-0.5, 2], Steps 4 with Clamp and 3.5 without. (kind, Clamp, Steps, tolerance).
const MAP_RANGES: [(&str, bool, f32, f64); 6] = [
    ("LINEAR", true, 4.0, EXACT),
    ("LINEAR_UNCLAMPED", false, 3.5, EXACT),
    ("STEPPED", true, 4.0, EXACT),
    ("STEPPED_UNCLAMPED", false, 3.5, EXACT),
    ("SMOOTHSTEP", true, 4.0, EXACT),
    ("SMOOTHERSTEP", true, 4.0, EXACT),
];

/// The Map Range of `kind` with Value, From Min and From Max the position's x, y, z.
fn map_range_program(kind: &str, clamp: bool, steps: f32) -> Program {
    let mut bl = Builder::default();
    let p = bl.position();
    let [x, y, z] = [0, 1, 2].map(|k| bl.component(p, k).unwrap());
    let (to_min, to_max) = (bl.constant(-0.5).unwrap(), bl.constant(2.0).unwrap());
    let interpolation = kind.trim_end_matches("_UNCLAMPED");
    let r = map_range(
        &mut bl,
        interpolation,
        [x, y, z, to_min, to_max],
        steps,
        clamp,
    )
    .unwrap()
    .expect("compiled");
    bl.finish(r).unwrap()
}

/// Every Map Range interpolation, clamped and not, equal to the bit to Geometry Nodes'
/// at 20,000 points (seed 17, uniform in [-2, 2)^3: a quarter of the ranges reversed,
/// many values outside them); and each one's range analysis bounds it: 2,000 boxes
/// of (x, y, z) in [-2, 2)^3, wide and narrow, 50 points in each inside the box's bounds.
#[test]
fn map_range_kinds_match_blender() {
    let Some(python) = common::data::bpy_python("bpy, numpy") else {
        return;
    };
    let kinds: Vec<&str> = MAP_RANGES.iter().map(|(k, ..)| *k).collect();
    let dir = run_fixture(python, "blender_map_range_values.py", &kinds);
    let mut failed = Vec::new();
    for (kind, clamp, steps, allowed) in MAP_RANGES {
        let prog = map_range_program(kind, clamp, steps);
        let (equal, worst) = against_rows(&prog, &read_rows::<4>(dir.path(), kind));
        println!("{kind:<18} {equal}/{N} equal to the bit; worst error {worst:.2e} (allowed {allowed:.1e})");
        if worst > allowed {
            failed.push(kind);
        }
    }
    assert!(failed.is_empty(), "{failed:?}");
    // An empty From range: Cycles' SVM gives 0 (then the clamp, here into [-0.5, 2]),
    // where Geometry Nodes gives To Min; Nimbus follows Cycles, the renderer.
    for (kind, clamp, steps, _) in MAP_RANGES {
        let v = map_range_program(kind, clamp, steps).eval([0.7, 0.3, 0.3], 0.0);
        assert_eq!(v, 0.0, "{kind} with From Min = From Max");
    }

    let mut uniform = xorshift(0x9e37_79b9_7f4a_7c15);
    for (kind, clamp, steps, _) in MAP_RANGES {
        let prog = map_range_program(kind, clamp, steps);
        assert_bounds_hold(kind, &prog, 2.0, false, &mut uniform);
    }
}

/// Mapping's constant parameter sets, as `SETS` in tests/fixtures/blender_mapping_values.py:
/// (name, Location, Rotation (XYZ Euler, radians), Scale). A rotates about all three
/// axes; B has a zero scale (the safe divisions) and a rotation about two; C none.
const MAPPING_SETS: [(&str, [f32; 3], [f32; 3], [f32; 3]); 3] = [
    ("A", [0.5, -0.25, 1.5], [0.3, -1.1, 2.5], [2.0, -0.5, 0.75]),
    ("B", [-1.0, 2.0, 0.25], [1.2, 0.0, -0.7], [1.5, 0.0, 1.0]),
    ("C", [0.125, 0.0, -3.0], [0.0, 0.0, 0.0], [0.5, 3.0, -2.0]),
];
const MAPPING_TYPES: [&str; 4] = ["POINT", "TEXTURE", "VECTOR", "NORMAL"];

/// The Mapping of `ty` with parameter set `set` on the position: its vector, or with
/// `component` one component (for the range analysis, which bounds floats).
fn mapping_program(ty: &str, set: usize, component: Option<u16>) -> Program {
    let (_, location, rotation, scale) = MAPPING_SETS[set];
    let mut bl = Builder::default();
    let p = bl.position();
    let (l, s) = (bl.vector3(location).unwrap(), bl.vector3(scale).unwrap());
    let v = mapping(&mut bl, ty, p, l, Rotation::Constant(rotation), s)
        .unwrap()
        .expect("compiled");
    finish_component(bl, v, component)
}

/// Every Mapping type (Point, Texture, Vector, Normal) with three parameter sets
/// against bpy 5.0.1 (tests/fixtures/blender_mapping_values.py, which composes each
/// type in Geometry Nodes from Vector Math and a Vector Rotate of type Euler XYZ) at
/// 20,000 points of [-4, 4)^3 (every 50th the zero vector). The rotation sums products,
/// so each component's error is taken against the magnitude of its terms, |p|·(|s| +
/// |1/s|) + |l| (1 for Normal, a unit vector), within `SUMS`; the unrotated set C must
/// be equal to the bit. Each component's range analysis bounds it: 2,000 boxes in
/// [-4, 4)^3, wide and narrow, 50 points in each.
#[test]
fn mapping_types_match_blender() {
    let Some(python) = common::data::bpy_python("bpy, numpy") else {
        return;
    };
    let kinds: Vec<String> = MAPPING_TYPES
        .iter()
        .flat_map(|t| {
            MAPPING_SETS
                .iter()
                .map(move |(set, ..)| format!("{t}_{set}"))
        })
        .collect();
    let names: Vec<&str> = kinds.iter().map(String::as_str).collect();
    let dir = run_fixture(python, "blender_mapping_values.py", &names);
    let norm = |v: [f32; 3]| v.iter().map(|x| (*x as f64).powi(2)).sum::<f64>().sqrt();
    let mut failed = Vec::new();
    for ty in MAPPING_TYPES {
        for (set, (name, location, rotation, scale)) in MAPPING_SETS.iter().enumerate() {
            let kind = format!("{ty}_{name}");
            let prog = mapping_program(ty, set, None);
            let inverse = scale.map(|s| if s == 0.0 { 0.0 } else { 1.0 / s });
            let allowed = match *rotation == [0.0; 3] {
                true => EXACT,
                false => SUMS,
            };
            let (mut equal, mut worst) = (0, 0f64);
            for r in read_rows::<6>(dir.path(), &kind) {
                let p = [r[0], r[1], r[2]];
                let ours = prog.eval_rgb(p, 0.0);
                let reference = [r[3], r[4], r[5]];
                if (0..3)
                    .all(|k| ours[k].to_bits() == reference[k].to_bits() || ours[k] == reference[k])
                {
                    equal += 1;
                    continue;
                }
                let terms = match ty {
                    "NORMAL" => 1.0,
                    _ => norm(p) * (norm(*scale) + norm(inverse)) + norm(*location),
                };
                for k in 0..3 {
                    let e = (ours[k] as f64 - reference[k] as f64).abs() / terms;
                    worst = worst.max(if e.is_nan() { f64::INFINITY } else { e });
                }
            }
            println!("{kind:<10} {equal}/{N} equal to the bit; worst error {worst:.2e} (allowed {allowed:.1e})");
            if worst > allowed {
                failed.push(kind);
            }
        }
    }
    assert!(failed.is_empty(), "{failed:?}");

    let mut uniform = xorshift(0x2545_f491_4f6c_dd1d);
    for ty in MAPPING_TYPES {
        for set in 0..MAPPING_SETS.len() {
            for k in 0..3 {
                let prog = mapping_program(ty, set, Some(k));
                let name = format!("{ty}_{} component {k}", MAPPING_SETS[set].0);
                assert_bounds_hold(&name, &prog, 4.0, false, &mut uniform);
            }
        }
    }
}

/// The Vector Rotate kinds of tests/fixtures/blender_vector_rotate_values.py: name,
/// rotation type, invert, and whether the axis is (0, 0, 0).
const ROTATE_KINDS: [(&str, &str, bool, bool); 8] = [
    ("AXIS_ANGLE", "AXIS_ANGLE", false, false),
    ("AXIS_ANGLE_INVERT", "AXIS_ANGLE", true, false),
    ("AXIS_ANGLE_ZERO", "AXIS_ANGLE", false, true),
    ("X_AXIS", "X_AXIS", false, false),
    ("Y_AXIS", "Y_AXIS", false, false),
    ("Z_AXIS_INVERT", "Z_AXIS", true, false),
    ("EULER_XYZ", "EULER_XYZ", false, false),
    ("EULER_XYZ_INVERT", "EULER_XYZ", true, false),
];
const ROTATE_CENTER: [f32; 3] = [0.25, -0.5, 1.0];
/// A rotation's error against Geometry Nodes, relative to the magnitude |v − center|
/// + |center| of its terms. Both sides compute each matrix entry from sin and cos
/// in a few roundings (Geometry Nodes through blenlib's `axis_angle_to_mat3` and
/// `eul_to_mat3`, in another order than Cycles' `rotate_around_axis` and
/// `euler_to_transform`, which Nimbus follows), normalise the axis (two or three
/// roundings) and sum three products (two): at most about 8 roundings of 2^-24 on
/// each side, 16 in all: 8 ulps of 1 (f32::EPSILON = 2^-23).
const ROTATIONS: f64 = 8.0 * f32::EPSILON as f64;

/// The Vector Rotate kind `kind` with the fixture's linked inputs: its vector, or one
/// component (for the range analysis, which bounds floats).
fn vector_rotate_program(kind: usize, component: Option<u16>) -> Program {
    let (_, ty, invert, zero_axis) = ROTATE_KINDS[kind];
    let mut bl = Builder::default();
    let p = bl.position();
    let center = bl.vector3(ROTATE_CENTER).unwrap();
    let axis = match zero_axis {
        true => bl.vector3([0.0; 3]).unwrap(),
        false => {
            let m = bl.vector3([0.5, -1.5, 0.75]).unwrap();
            let a = bl.binary(Binary::Mul, p, m).unwrap();
            let c = bl.vector3([0.3, 0.2, -0.1]).unwrap();
            bl.binary(Binary::Add, a, c).unwrap()
        }
    };
    let x = bl.component(p, 0).unwrap();
    let k = bl.constant(1.3).unwrap();
    let angle = bl.binary(Binary::Mul, x, k).unwrap();
    let s = bl.constant(0.6).unwrap();
    let rotation = Rotation::Linked(bl.binary(Binary::Mul, p, s).unwrap());
    let v = vector_rotate(&mut bl, ty, invert, p, center, axis, angle, rotation)
        .unwrap()
        .expect("compiled");
    finish_component(bl, v, component)
}

/// Vector Rotate of every rotation type (inverted or not, an axis of zero length)
/// with linked Axis, Angle and Rotation, against bpy 5.0.1's Geometry Nodes
/// (tests/fixtures/blender_vector_rotate_values.py) at 20,000 points of [-4, 4)^3
/// (every 50th the zero vector), within `ROTATIONS` of the terms' magnitude; with the
/// zero axis Nimbus' value is the Vector itself, bit for bit, as Cycles'. The same rotation code serves a Mapping
/// with a linked Rotation. Each component's range analysis bounds it: 2,000 boxes in
/// [-4, 4)^3, wide and narrow, 50 points in each.
#[test]
fn vector_rotate_types_match_blender() {
    let Some(python) = common::data::bpy_python("bpy, numpy") else {
        return;
    };
    let names: Vec<&str> = ROTATE_KINDS.iter().map(|k| k.0).collect();
    let dir = run_fixture(python, "blender_vector_rotate_values.py", &names);
    let norm = |v: [f32; 3]| v.iter().map(|x| (*x as f64).powi(2)).sum::<f64>().sqrt();
    let mut failed = Vec::new();
    for (kind, (name, _, _, zero_axis)) in ROTATE_KINDS.iter().enumerate() {
        let prog = vector_rotate_program(kind, None);
        let allowed = ROTATIONS;
        let (mut equal, mut worst) = (0, 0f64);
        for r in read_rows::<6>(dir.path(), name) {
            let p = [r[0], r[1], r[2]];
            let ours = prog.eval_rgb(p, 0.0);
            if *zero_axis {
                // Cycles returns the Vector itself; Geometry Nodes rotates v − Center
                // by the identity and adds Center back (a rounding or two).
                assert_eq!(
                    ours.map(f32::to_bits),
                    p.map(f32::to_bits),
                    "{name} at {p:?}"
                );
            }
            let reference = [r[3], r[4], r[5]];
            if (0..3)
                .all(|k| ours[k].to_bits() == reference[k].to_bits() || ours[k] == reference[k])
            {
                equal += 1;
                continue;
            }
            let d = [0, 1, 2].map(|k| p[k] - ROTATE_CENTER[k]);
            let terms = norm(d) + norm(ROTATE_CENTER);
            for k in 0..3 {
                let e = (ours[k] as f64 - reference[k] as f64).abs() / terms;
                worst = worst.max(if e.is_nan() { f64::INFINITY } else { e });
            }
        }
        println!("{name:<18} {equal}/{N} equal to the bit; worst error {worst:.2e} (allowed {allowed:.1e})");
        if worst > allowed {
            failed.push(*name);
        }
    }
    assert!(failed.is_empty(), "{failed:?}");

    let mut uniform = xorshift(0x9e37_79b9_7f4a_7c15);
    for (kind, (name, ..)) in ROTATE_KINDS.iter().enumerate() {
        for k in 0..3 {
            let prog = vector_rotate_program(kind, Some(k));
            assert_bounds_hold(
                &format!("{name} component {k}"),
                &prog,
                4.0,
                false,
                &mut uniform,
            );
        }
    }
}

/// The Mix node's kinds (as `KINDS` in tests/fixtures/blender_mix_values.py): Float and
/// Vector, Color with each blend type compiled (with the factor unclamped and the
/// result clamped for Mix), the legacy MixRGB, and Clamp.
fn mix_kinds() -> Vec<String> {
    let mut kinds: Vec<String> = ["FLOAT", "FLOAT_UNCLAMPED", "VECTOR", "VECTOR_NON_UNIFORM"]
        .map(String::from)
        .to_vec();
    kinds.extend(BLEND_TYPES.iter().map(|b| b.to_string()));
    kinds.extend(["MIX_UNCLAMPED", "MIX_CLAMPED", "SCREEN_UNCLAMPED"].map(String::from));
    kinds.extend(["LEGACY_MIX", "LEGACY_OVERLAY_CLAMPED", "LEGACY_DIVIDE"].map(String::from));
    kinds.extend(["CLAMP_MINMAX", "CLAMP_RANGE"].map(String::from));
    for mode in ["HSV", "HSL"] {
        kinds.extend([format!("SEPARATE_{mode}"), format!("COMBINE_{mode}")]);
    }
    kinds
}

/// The kinds whose colours go through HSV (blenlib, which Geometry Nodes runs, and
/// Cycles convert by different algorithms that agree on [0, 1]³ but not outside it:
/// e.g. a hue beyond 1 wraps in one and not the other); their rows are compared where
/// the colour inputs are in [0, 1]³.
fn through_hsv(kind: &str) -> bool {
    ["HUE", "SATURATION", "VALUE", "COLOR"].contains(&kind) || kind.ends_with("_HSV")
}

/// The program of the Mix `kind` with A the position, B its (z, x, y) and the factor
/// the attribute (as the fixture wires them); with `component`, that component alone
/// (the range analysis bounds floats).
fn mix_program(kind: &str, component: Option<u16>) -> Program {
    let mut bl = Builder::default();
    let p = bl.position();
    let f = bl.attribute();
    let [x, y, z] = [0, 1, 2].map(|k| bl.component(p, k).unwrap());
    let zxy = bl.combine3(z, x, y).unwrap();
    let v = if let Some(mode) = kind.strip_prefix("SEPARATE_") {
        match mode {
            "HSV" => blender_color::rgb_to_hsv(&mut bl, p).unwrap(),
            _ => blender_color::rgb_to_hsl(&mut bl, p).unwrap(),
        }
    } else if let Some(mode) = kind.strip_prefix("COMBINE_") {
        match mode {
            "HSV" => blender_color::hsv_to_rgb(&mut bl, p).unwrap(),
            _ => blender_color::hsl_to_rgb(&mut bl, p).unwrap(),
        }
    } else if let Some(range) = kind.strip_prefix("CLAMP_") {
        blender_color::clamp(&mut bl, range == "RANGE", f, x, y).unwrap()
    } else if let Some(rest) = kind.strip_prefix("LEGACY_") {
        let (blend, clamped) = match rest.strip_suffix("_CLAMPED") {
            Some(b) => (b, true),
            None => (rest, false),
        };
        let t = blender_color::saturate(&mut bl, f).unwrap();
        let v = blender_color::mix_color(&mut bl, blend, t, p, zxy)
            .unwrap()
            .expect("compiled");
        match clamped {
            true => blender_color::saturate(&mut bl, v).unwrap(),
            false => v,
        }
    } else {
        let unclamped = kind.ends_with("_UNCLAMPED");
        let base = kind
            .trim_end_matches("_UNCLAMPED")
            .trim_end_matches("_CLAMPED");
        let t = match base {
            "VECTOR_NON_UNIFORM" => bl.combine3(f, z, x).unwrap(),
            _ => f,
        };
        let t = match unclamped {
            true => t,
            false => blender_color::saturate(&mut bl, t).unwrap(),
        };
        match base {
            "FLOAT" => blender_color::mix_linear(&mut bl, t, x, y).unwrap(),
            "VECTOR" | "VECTOR_NON_UNIFORM" => {
                blender_color::mix_linear(&mut bl, t, p, zxy).unwrap()
            }
            blend => {
                let v = blender_color::mix_color(&mut bl, blend, t, p, zxy)
                    .unwrap()
                    .expect("compiled");
                match kind.ends_with("_CLAMPED") {
                    true => blender_color::saturate(&mut bl, v).unwrap(),
                    false => v,
                }
            }
        }
    };
    let v = match component {
        Some(k) if v.width() == 3 => bl.component(v, k).unwrap(),
        _ => v,
    };
    match v.width() {
        1 => bl.finish(v).unwrap(),
        _ => bl.finish_rgb(v).unwrap(),
    }
}

/// Every compiled kind of Blender's Mix, MixRGB and Clamp against Geometry Nodes at
/// 20,000 points (tests/fixtures/blender_mix_values.py: inputs uniform in
/// [-0.25, 1.25), one in ten snapped to 0, 0.5 or 1, the edges of the branches), and
/// each kind's range analysis bounds it.
///
/// Nimbus computes Cycles' `svm_mix_*` operations in Cycles' order. Geometry Nodes
/// computes blenlib's `ramp_blend`, which orders some differently (Mix: a(1 − t) + bt
/// against Cycles' a + t(b − a)): each is a handful of roundings of values below 4 in
/// magnitude, so the two differ by a few ulps of the operands. The allowed error,
/// |ours − Blender's| / max(1, |Blender's|), is `MIX_ROUNDING` = 8 ulps of 1; a
/// division (Divide, Dodge, Burn) scales its operands' errors by the quotient, which the
/// relative measure covers above 1.
const MIX_ROUNDING: f64 = 8.0 * f32::EPSILON as f64;

/// The allowed error of the kinds through HSV ([`through_hsv`]): blenlib converts by
/// other formulas than Cycles (its hue from a sorted pair and a 1e-20 guard, its RGB
/// from clamped triangle waves), so each side rounds about 12 times at magnitudes
/// below 1.25 (to HSV, the blend, back): up to 12 half-ulps each, 12 ulps of 1 in
/// all; allowed 16.
const HSV_ROUNDING: f64 = 16.0 * f32::EPSILON as f64;

#[test]
fn mix_nodes_match_blender() {
    let Some(python) = common::data::bpy_python("bpy, numpy") else {
        return;
    };
    let kinds = mix_kinds();
    let names: Vec<&str> = kinds.iter().map(String::as_str).collect();
    let dir = run_fixture(python, "blender_mix_values.py", &names);
    let mut failed = Vec::new();
    for kind in &kinds {
        let prog = mix_program(kind, None);
        let (mut equal, mut worst, mut outside) = (0, 0f64, 0);
        for r in read_rows::<7>(dir.path(), kind) {
            let (p, f) = ([r[0], r[1], r[2]], r[3]);
            if through_hsv(kind) && !p.iter().all(|c| (0.0..=1.0).contains(c)) {
                outside += 1;
                continue;
            }
            let ours = match prog.outputs_rgb() {
                true => prog.eval_rgb(p, f),
                false => [prog.eval(p, f), 0.0, 0.0],
            };
            let reference = [r[4], r[5], r[6]];
            if (0..3)
                .all(|k| ours[k].to_bits() == reference[k].to_bits() || ours[k] == reference[k])
            {
                equal += 1;
                continue;
            }
            for k in 0..3 {
                let e = (ours[k] as f64 - reference[k] as f64).abs()
                    / (reference[k].abs() as f64).max(1.0);
                worst = worst.max(if e.is_nan() { f64::INFINITY } else { e });
            }
        }
        let allowed = match through_hsv(kind) {
            true => HSV_ROUNDING,
            false => MIX_ROUNDING,
        };
        println!("{kind:<22} {equal}/{} equal to the bit; worst error {worst:.2e} (allowed {allowed:.1e})", N - outside);
        if worst > allowed {
            failed.push(kind.clone());
        }
    }
    assert!(failed.is_empty(), "{failed:?}");

    // The range analysis, every component inside its bounds.
    let mut uniform = xorshift(0x9e37_79b9_7f4a_7c15);
    for kind in &kinds {
        let width = if mix_program(kind, None).outputs_rgb() {
            3
        } else {
            1
        };
        for k in 0..width {
            let prog = mix_program(kind, Some(k));
            assert_bounds_hold_with_factor(&format!("{kind} component {k}"), &prog, &mut uniform);
        }
    }
}

/// Asserts that `prog`'s range analysis bounds it, its attribute a factor: 500 boxes of
/// the position in [-0.25, 1.25)^3 and of the attribute, wide and narrow, 40 uniform
/// points in each inside the box's bounds.
fn assert_bounds_hold_with_factor(
    name: &str,
    prog: &Program,
    uniform: &mut impl FnMut(f32, f32) -> f32,
) {
    for b in 0..500 {
        let w = if b % 2 == 0 { 1.0 } else { 0.05 };
        let mut lo = [0f32; 4];
        let mut hi = [0f32; 4];
        for d in 0..4 {
            let (x, y) = (uniform(-0.25, 1.25), uniform(-0.25, 1.25));
            lo[d] = x.min(x + w * (y - x));
            hi[d] = x.max(x + w * (y - x));
        }
        let bound = prog.bounds(
            [lo[0], lo[1], lo[2]],
            [hi[0], hi[1], hi[2]],
            Interval {
                lo: lo[3],
                hi: hi[3],
            },
        );
        for _ in 0..40 {
            let q: [f32; 4] = std::array::from_fn(|d| uniform(lo[d], hi[d]).clamp(lo[d], hi[d]));
            let v = prog.eval([q[0], q[1], q[2]], q[3]);
            assert!(
                v >= bound.lo && v <= bound.hi,
                "{name}: {v} at {q:?} outside [{}, {}]",
                bound.lo,
                bound.hi
            );
        }
    }
}

/// The Float Curves of tests/fixtures/blender_float_curve_values.py: (name, its points
/// when its segments are straight, for the extrapolation's error bound below).
const FLOAT_CURVES: [(&str, &[(f64, f64)]); 4] = [
    (
        "POLYLINE",
        &[(0.0, 0.0), (0.25, 0.75), (0.5, 0.25), (1.0, 1.0)],
    ),
    ("SMOOTH", &[]),
    ("SMOOTH_HORIZONTAL", &[]),
    ("NARROW", &[(0.2, 0.1), (0.7, 0.9)]),
];

/// The straight-segment curve through `points` at `x` (its end segments continued).
fn polyline(points: &[(f64, f64)], x: f64) -> f64 {
    let k = points
        .windows(2)
        .position(|w| x <= w[1].0)
        .unwrap_or(points.len() - 2);
    let ((x0, y0), (x1, y1)) = (points[k], points[k + 1]);
    y0 + (x - x0) * (y1 - y0) / (x1 - x0)
}

/// Blender's Float Curve against Geometry Nodes at 20,000 points (Value and Factor
/// uniform in [-0.25, 1.25): the curve is read inside its points' x range, clamped or
/// extrapolated beyond it, and the factor is not clamped), with the table the add-on
/// writes (`float_curve`: Cycles' `svm_node_curve`).
///
/// Inside the points' range Cycles reads its table of the curve at i/256 of the range,
/// and Geometry Nodes Blender's own table of the same curve at the same x when the
/// range is [0, 1]: equal up to `MIX_ROUNDING`. Beyond it Cycles continues the table's
/// last chord, Blender the end point's handle: the same line for straight end
/// segments (POLYLINE, NARROW), up to the table entries' own error ε (their largest
/// difference from the exact polyline) amplified by the extrapolation, ε + 2ε·d·256
/// at a distance d beyond the range in range units, plus rounding; for a smooth curve
/// a different line by design (Nimbus follows Cycles), so SMOOTH's extrapolated rows
/// are counted, not compared. With a horizontal extension both clamp. Each curve's
/// range analysis bounds it (20,000 points in 500 boxes of Value and Factor).
#[test]
fn float_curves_match_blender() {
    let Some(python) = common::data::bpy_python("bpy, numpy") else {
        return;
    };
    let names: Vec<&str> = FLOAT_CURVES.iter().map(|(n, _)| *n).collect();
    let dir = run_fixture(python, "blender_float_curve_values.py", &names);
    let mut uniform = xorshift(0x2545_f491_4f6c_dd1d);
    let mut failed = Vec::new();
    for (name, points) in FLOAT_CURVES {
        let (min, max, extrapolate, table) = read_curve_table(dir.path(), name);
        assert_eq!(table.len(), 257, "{name}: table entries");
        let eps = table_error(&table, (min, max), points);
        let mut bl = Builder::default();
        let p = bl.position();
        let value = bl.component(p, 0).unwrap();
        let fac = bl.attribute();
        let v = float_curve(&mut bl, table, (min, max), extrapolate, fac, value).unwrap();
        let prog = bl.finish(v).unwrap();
        let (mut equal, mut worst, mut beyond, mut skipped) = (0, 0f64, 0, 0);
        for r in read_rows::<5>(dir.path(), name) {
            let ours = prog.eval([r[0], r[1], r[2]], r[3]);
            if r[0] < min || r[0] > max {
                beyond += 1;
                if extrapolate && points.is_empty() {
                    skipped += 1;
                    continue;
                }
            }
            if ours.to_bits() == r[4].to_bits() || ours == r[4] {
                equal += 1;
                continue;
            }
            let e = curve_error((ours, r[4]), (r[0], r[3]), (min, max), extrapolate, eps);
            worst = worst.max(e);
        }
        assert_bounds_hold_with_factor(name, &prog, &mut uniform);
        println!(
            "{name:<18} {equal}/{N} equal to the bit; {beyond} beyond the points ({skipped} not compared); table error {eps:.1e}; worst error / allowed {worst:.3}"
        );
        if worst > 1.0 {
            failed.push(name);
        }
    }
    assert!(failed.is_empty(), "{failed:?}");
}

/// The RGB and Vector Curves of tests/fixtures/blender_curves_values.py: (name, each
/// channel's curve as its table holds it — the channel's own curve, or for RGB Curves
/// the combined one where the channel's is the identity — as straight segments).
type Polyline = &'static [(f64, f64)];
const CURVES: [(&str, [Polyline; 3]); 4] = [
    (
        "RGB_CHANNELS",
        [
            &[(0.0, 0.0), (0.25, 0.75), (0.5, 0.25), (1.0, 1.0)],
            &[(0.0, 0.2), (0.6, 0.9), (1.0, 0.4)],
            &[(0.0, 1.0), (1.0, 0.0)],
        ],
    ),
    ("RGB_COMBINED", [&[(0.0, 0.1), (0.3, 0.8), (1.0, 0.6)]; 3]),
    (
        "RGB_HORIZONTAL",
        [
            &[(0.0, 0.0), (0.25, 0.75), (0.5, 0.25), (1.0, 1.0)],
            &[(0.0, 0.0), (1.0, 1.0)],
            &[(0.0, 1.0), (1.0, 0.0)],
        ],
    ),
    (
        "VECTOR_CHANNELS",
        [
            &[(-1.0, -1.0), (0.0, 0.5), (1.0, 1.0)],
            &[(-1.0, 1.0), (0.5, -0.5), (1.0, 0.0)],
            &[(-1.0, -1.0), (1.0, 1.0)],
        ],
    ),
];

/// Blender's RGB Curves and Vector Curves against Geometry Nodes at 20,000 points
/// (tests/fixtures/blender_curves_values.py: the colour or vector uniform in
/// [-0.25, 1.25)^3, Fac alike, one value in ten snapped to 0, 1/3 or 1), with the
/// tables the add-on writes (`curves`: Cycles' `svm_node_curves`, each channel as
/// [`float_curve`] reads one value). The same error model as
/// `float_curves_match_blender`: inside the curves' x range equal up to
/// `MIX_ROUNDING` (Cycles' table and Blender's own curve table interpolate the same
/// samples); beyond it, extrapolated, the table's error ε against the exact polyline
/// amplified by the distance d (in range units), ε + 2ε·d·256, times |Fac|; clamped
/// (Horizontal), `MIX_ROUNDING`. RGB Curves' combined curve is tested alone
/// (RGB_COMBINED): where both it and a channel's curve bend, Cycles bakes their
/// composition into one table and Blender evaluates the two tables in turn, different
/// by design. Each channel's range analysis bounds it.
#[test]
fn rgb_and_vector_curves_match_blender() {
    let Some(python) = common::data::bpy_python("bpy, numpy") else {
        return;
    };
    let names: Vec<&str> = CURVES.iter().map(|(n, _)| *n).collect();
    let dir = run_fixture(python, "blender_curves_values.py", &names);
    let mut uniform = xorshift(0x2545_f491_4f6c_dd1d);
    let mut failed = Vec::new();
    for (name, polylines) in CURVES {
        let (min, max, extrapolate, entries) = read_curve_table(dir.path(), name);
        assert_eq!(entries.len(), 3 * 257, "{name}: table entries");
        let tables: [Vec<f32>; 3] =
            std::array::from_fn(|k| entries[257 * k..257 * (k + 1)].to_vec());
        let eps: [f64; 3] =
            std::array::from_fn(|k| table_error(&tables[k], (min, max), polylines[k]));
        let program = |component: Option<u16>| {
            let mut bl = Builder::default();
            let p = bl.position();
            let fac = bl.attribute();
            let v = curves(&mut bl, tables.clone(), (min, max), extrapolate, fac, p).unwrap();
            finish_component(bl, v, component)
        };
        let prog = program(None);
        let (mut equal, mut worst) = (0, 0f64);
        for r in read_rows::<7>(dir.path(), name) {
            let ours = prog.eval_rgb([r[0], r[1], r[2]], r[3]);
            if (0..3).all(|k| ours[k].to_bits() == r[4 + k].to_bits() || ours[k] == r[4 + k]) {
                equal += 1;
                continue;
            }
            for k in 0..3 {
                let rows = ((ours[k], r[4 + k]), (r[k], r[3]));
                worst = worst.max(curve_error(rows.0, rows.1, (min, max), extrapolate, eps[k]));
            }
        }
        for k in 0..3 {
            assert_bounds_hold_with_factor(
                &format!("{name} channel {k}"),
                &program(Some(k)),
                &mut uniform,
            );
        }
        println!(
            "{name:<16} {equal}/{N} equal to the bit; table errors {:.1e} {:.1e} {:.1e}; worst error / allowed {worst:.3}",
            eps[0], eps[1], eps[2]
        );
        if worst > 1.0 {
            failed.push(name);
        }
    }
    assert!(failed.is_empty(), "{failed:?}");
}

/// Blender's Gamma node against Geometry Nodes at 20,000 points (the colour the
/// position, Gamma 3·f − 1 computed by a Math Multiply Add in both: one in ten of the
/// inputs snapped to 0, 1/3 or 1, so channels at 0 and Gamma 0 occur). Cycles'
/// `svm_math_gamma_color` and blenlib raise each channel above 0 by powf: within
/// `LIBM` of Geometry Nodes (relative to max(1, |value|)). At Gamma 0 Cycles gives
/// white where Geometry Nodes keeps the channels at or below 0: those rows are checked
/// to be white. The range analysis bounds each channel.
#[test]
fn gamma_matches_blender() {
    let Some(python) = common::data::bpy_python("bpy, numpy") else {
        return;
    };
    let dir = run_fixture(python, "blender_curves_values.py", &["GAMMA"]);
    let program = |component: Option<u16>| {
        let mut bl = Builder::default();
        let p = bl.position();
        let f = bl.attribute();
        let three = bl.constant(3.0).unwrap();
        let minus_one = bl.constant(-1.0).unwrap();
        let g = bl
            .binary(nimbus::shader::graph::Binary::Mul, f, three)
            .unwrap();
        let g = bl
            .binary(nimbus::shader::graph::Binary::Add, g, minus_one)
            .unwrap();
        let v = blender_color::gamma(&mut bl, p, g).unwrap();
        finish_component(bl, v, component)
    };
    let prog = program(None);
    let (mut equal, mut worst, mut white) = (0, 0f64, 0);
    for r in read_rows::<7>(dir.path(), "GAMMA") {
        let ours = prog.eval_rgb([r[0], r[1], r[2]], r[3]);
        if r[3] * 3.0 - 1.0 == 0.0 {
            // Cycles gives white at Gamma 0; Geometry Nodes keeps the channels at or
            // below 0 there (blenlib has no such case). Nimbus renders as Cycles.
            assert_eq!(ours, [1.0; 3], "Gamma 0 at {r:?}");
            white += 1;
            continue;
        }
        if (0..3).all(|k| ours[k].to_bits() == r[4 + k].to_bits() || ours[k] == r[4 + k]) {
            equal += 1;
            continue;
        }
        for k in 0..3 {
            let e = (ours[k] as f64 - r[4 + k] as f64).abs() / (r[4 + k].abs() as f64).max(1.0);
            worst = worst.max(if e.is_nan() { f64::INFINITY } else { e });
        }
    }
    println!("GAMMA {equal}/{} equal to the bit; worst error {worst:.2e} (allowed {LIBM:.1e}); {white} at Gamma 0 white, as Cycles", N - white);
    assert!(white > 0, "no row at Gamma 0");
    let mut uniform = xorshift(0x9e37_79b9_7f4a_7c15);
    for k in 0..3 {
        assert_bounds_hold_with_factor(
            &format!("GAMMA channel {k}"),
            &program(Some(k)),
            &mut uniform,
        );
    }
    assert!(worst <= LIBM, "Gamma: worst error {worst:.3e}");
}

/// Blender's White Noise Texture (1D to 4D) and Blackbody node against Geometry Nodes at
/// 20,000 points (tests/fixtures/blender_curves_values.py: the Vector the position, W
/// f; the temperature 10,000·f + 500 K, so below 800 K, every piece of the fit and
/// past 12,000 K occur). Both are the functions Cycles evaluates (White Noise in every
/// kernel; Blackbody as Cycles' SSE4.2 kernel and its constant folding, each product
/// rounded, where its AVX2 kernel fuses some and differs in the last bits): equal to
/// the bit. The White Noise Value is its Color's red. The range analysis bounds each.
#[test]
fn white_noise_and_blackbody_match_blender() {
    let Some(python) = common::data::bpy_python("bpy, numpy") else {
        return;
    };
    let kinds = ["WHITE_1D", "WHITE_2D", "WHITE_3D", "WHITE_4D", "BLACKBODY"];
    let dir = run_fixture(python, "blender_curves_values.py", &kinds);
    let program = |kind: &str, output: Option<u16>| {
        let mut bl = Builder::default();
        let p = bl.position();
        let f = bl.attribute();
        let v = match kind.strip_prefix("WHITE_") {
            Some(d) => {
                let dims = d[..1].parse().unwrap();
                bl.white_noise(p, f, dims, output != Some(3)).unwrap()
            }
            None => {
                let (k, c) = (bl.constant(10000.0).unwrap(), bl.constant(500.0).unwrap());
                let t = bl.binary(nimbus::shader::graph::Binary::Mul, f, k).unwrap();
                let t = bl.binary(nimbus::shader::graph::Binary::Add, t, c).unwrap();
                bl.blackbody(t).unwrap()
            }
        };
        match output {
            Some(3) => bl.finish(v).unwrap(),
            k => finish_component(bl, v, k),
        }
    };
    let mut uniform = xorshift(0x9e37_79b9_7f4a_7c15);
    let mut failed = Vec::new();
    for kind in kinds {
        let colour = program(kind, None);
        let value = kind.starts_with("WHITE_").then(|| program(kind, Some(3)));
        let mut equal = 0;
        for r in read_rows::<7>(dir.path(), kind) {
            let (p, f) = ([r[0], r[1], r[2]], r[3]);
            let ours = colour.eval_rgb(p, f);
            let value_ok = value
                .as_ref()
                .is_none_or(|v| v.eval(p, f).to_bits() == r[4].to_bits());
            if value_ok && (0..3).all(|k| ours[k].to_bits() == r[4 + k].to_bits()) {
                equal += 1;
            }
        }
        println!("{kind:<10} {equal}/{N} equal to the bit");
        if equal != N {
            failed.push(kind);
        }
        for k in 0..3 {
            assert_bounds_hold_with_factor(
                &format!("{kind} channel {k}"),
                &program(kind, Some(k)),
                &mut uniform,
            );
        }
    }
    assert!(failed.is_empty(), "{failed:?}");
}

/// Wave Textures of tests/fixtures/blender_curves_values.py: every type and direction,
/// every profile among them.
const WAVES: [&str; 8] = [
    "WAVE_BANDS_X_SIN",
    "WAVE_BANDS_Y_SAW",
    "WAVE_BANDS_Z_TRI",
    "WAVE_BANDS_DIAGONAL_SIN",
    "WAVE_RINGS_X_TRI",
    "WAVE_RINGS_Y_SIN",
    "WAVE_RINGS_Z_SAW",
    "WAVE_RINGS_SPHERICAL_SIN",
];

/// Blender's Wave Texture against Geometry Nodes at 20,000 points (the fixture's Vector
/// the position, Scale 1.7, Distortion 4·f, Detail 2.5, Detail Scale 1.3, Detail
/// Roughness 0.6, Phase 0.3). Nimbus computes Cycles' `svm_wave` in float, as Cycles'
/// SSE4.2 kernel; Geometry Nodes computes the profile's π/2 and 1/(2π) and its Perlin
/// noise's fade and interpolation in double, so the two agree to rounding, not to the
/// bit: the phase n (|n| < 90 here) differs by its last rounding, an ulp of 128
/// (7.6e-6), and the distortion's fBM by a few ulps of 1 (4 × 6e-8, × 4·f ≤ 5); the
/// profiles' slopes are at most 1/2 (sine), 1/(2π) (saw) and 1/π (triangle): 3.8e-6
/// + 0.6e-6, allowed 1e-5 (measured: 1.9e-6). With Cycles' guard on unit coordinates
/// undone in part (its 1e-6 subtracted again after the × 0.999999; a one-off run), six
/// of the eight kinds exceeded it (worst 2.7e-5). Where the saw wraps (either
/// value within 1e-4 of 0 or 1) the two may fall on either side: counted, not compared.
/// The range analysis bounds each.
#[test]
fn wave_textures_match_blender() {
    let Some(python) = common::data::bpy_python("bpy, numpy") else {
        return;
    };
    let dir = run_fixture(python, "blender_curves_values.py", &WAVES);
    let mut uniform = xorshift(0x9e37_79b9_7f4a_7c15);
    let mut failed = Vec::new();
    for kind in WAVES {
        let parts: Vec<&str> = kind.split('_').collect();
        let mut bl = Builder::default();
        let p = bl.position();
        let f = bl.attribute();
        let (scale, phase, four) = (
            bl.constant(1.7).unwrap(),
            bl.constant(0.3).unwrap(),
            bl.constant(4.0).unwrap(),
        );
        let d = bl
            .binary(nimbus::shader::graph::Binary::Mul, f, four)
            .unwrap();
        let detail = nimbus::shader::noise::NoiseTexture {
            scale: 1.3,
            detail: 2.5,
            roughness: 0.6,
            lacunarity: 2.0,
            normalize: true,
            ..Default::default()
        };
        let v = wave(
            &mut bl,
            p,
            scale,
            (parts[1], parts[2], parts[3]),
            Some(d),
            detail,
            phase,
        )
        .unwrap()
        .expect("compiled");
        let prog = bl.finish(v).unwrap();
        let (mut equal, mut worst, mut wraps) = (0, 0f64, 0);
        for r in read_rows::<7>(dir.path(), kind) {
            let ours = prog.eval([r[0], r[1], r[2]], r[3]);
            if ours.to_bits() == r[4].to_bits() {
                equal += 1;
                continue;
            }
            let near_wrap = |x: f32| x < 1e-4 || x > 1.0 - 1e-4;
            if parts[3] == "SAW" && (near_wrap(ours) || near_wrap(r[4])) {
                wraps += 1;
                continue;
            }
            let e = (ours as f64 - r[4] as f64).abs();
            worst = worst.max(if e.is_nan() { f64::INFINITY } else { e });
        }
        println!("{kind:<26} {equal}/{N} equal to the bit; worst error {worst:.2e} (allowed 1e-5); {wraps} at the saw's wrap");
        if worst > 1e-5 {
            failed.push(kind);
        }
        assert_bounds_hold_with_factor(kind, &prog, &mut uniform);
    }
    assert!(failed.is_empty(), "{failed:?}");
}

/// Blender's Magic Texture against Geometry Nodes at 20,000 points (the fixture's
/// Vector the position, Scale 1.3, Distortion d = 2·f − 0.5 in [−1, 2), 0 at some
/// points), at turbulence depths 0, 2, 5 and 10. Nimbus computes Cycles' `svm_magic`
/// (its SSE4.2 kernel: the position modulo 2π, then ((x + y) + z)·5·scale, and 0.5/d
/// for the final division); Geometry Nodes scales the position first, has no modulo
/// and divides by 2d: the first waves' arguments (|arg| < 25) differ by an ulp of 32
/// (3.8e-6), and each round of turbulence multiplies a difference by at most |d| ≤ 2
/// (the sines' slopes are at most 1) and the final division by 1/(2|d|): allowed per
/// row 8 × 3.8e-6 × max(1, |d|)^depth / max(2|d|, 1/2) (at depth 0, where the waves
/// are not multiplied by d first, 8 × 3.8e-6 / (2|d|)), plus the division's own
/// rounding (0.5/d then a product, against one quotient: 2 ulps of the value). Rows
/// with |d| < 1e-3 at depth 0 (values past 250, where the quotient's rounding is all
/// there is) are counted, not compared.
#[test]
fn magic_textures_match_blender() {
    let Some(python) = common::data::bpy_python("bpy, numpy") else {
        return;
    };
    let kinds = ["MAGIC_0", "MAGIC_2", "MAGIC_5", "MAGIC_10"];
    let dir = run_fixture(python, "blender_curves_values.py", &kinds);
    let mut uniform = xorshift(0x9e37_79b9_7f4a_7c15);
    let mut failed = Vec::new();
    for kind in kinds {
        let depth: u32 = kind[6..].parse().unwrap();
        let program = |component: Option<u16>| {
            let mut bl = Builder::default();
            let p = bl.position();
            let f = bl.attribute();
            let (scale, two, minus_half) = (
                bl.constant(1.3).unwrap(),
                bl.constant(2.0).unwrap(),
                bl.constant(-0.5).unwrap(),
            );
            let d = bl
                .binary(nimbus::shader::graph::Binary::Mul, f, two)
                .unwrap();
            let d = bl
                .binary(nimbus::shader::graph::Binary::Add, d, minus_half)
                .unwrap();
            let c = magic(&mut bl, p, scale, depth, d).unwrap();
            finish_component(bl, c, component)
        };
        let prog = program(None);
        let (mut equal, mut worst, mut skipped) = (0, 0f64, 0);
        for r in read_rows::<7>(dir.path(), kind) {
            let ours = prog.eval_rgb([r[0], r[1], r[2]], r[3]);
            if (0..3).all(|k| ours[k].to_bits() == r[4 + k].to_bits()) {
                equal += 1;
                continue;
            }
            let d = (r[3] * 2.0 - 0.5).abs() as f64;
            if depth == 0 && d < 1e-3 {
                skipped += 1;
                continue;
            }
            // At depth 0 the waves themselves are divided by 2d; deeper, each round has
            // multiplied them by d first, so the quotient is of order 1.
            let spread = 8.0
                * 3.8e-6
                * match depth {
                    0 => 1.0 / (2.0 * d),
                    _ => d.max(1.0).powi(depth as i32) / (2.0 * d).max(0.5),
                };
            for k in 0..3 {
                // Plus the final division's own rounding: 0.5/d then a product against
                // one quotient, 2 ulps of the value.
                let allowed = spread + 2.0 * f32::EPSILON as f64 * (r[4 + k].abs() as f64 + 0.5);
                let e = (ours[k] as f64 - r[4 + k] as f64).abs() / allowed;
                worst = worst.max(if e.is_nan() { f64::INFINITY } else { e });
            }
        }
        println!("{kind:<9} {equal}/{N} equal to the bit; worst error / allowed {worst:.3}; {skipped} rows with |d| < 1e-3 not compared");
        if worst > 1.0 {
            failed.push(kind);
        }
        for k in 0..3 {
            assert_bounds_hold_with_factor(
                &format!("{kind} channel {k}"),
                &program(Some(k)),
                &mut uniform,
            );
        }
    }
    assert!(failed.is_empty(), "{failed:?}");
}
