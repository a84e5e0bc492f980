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

use nimbus::scene::blender_graph::{gradient, map_range, mapping, math, vector_math};
use nimbus::shader::graph::{Builder, Program};
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
    let v = mapping(&mut bl, ty, p, l, rotation, s)
        .unwrap()
        .expect("compiled");
    match component {
        None => bl.finish_rgb(v).unwrap(),
        Some(k) => {
            let c = bl.component(v, k).unwrap();
            bl.finish(c).unwrap()
        }
    }
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
