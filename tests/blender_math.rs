//! Blender's Math node against Blender 5.0.1: `tests/fixtures/blender_math_values.py`
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

use std::process::Command;

use nimbus::scene::blender_graph::math;
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

fn read_rows(path: &std::path::Path) -> Vec<[f32; 4]> {
    let bytes = std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    assert_eq!(bytes.len(), N * 16, "{}: size", path.display());
    bytes
        .chunks_exact(16)
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
    let dir = tempfile::tempdir().expect("temp dir");
    let ops: Vec<&str> = OPERATIONS.iter().map(|(o, _)| *o).collect();
    let out = Command::new(python)
        .arg(common::repo().join("tests/fixtures/blender_math_values.py"))
        .arg(ops.join(","))
        .arg(dir.path())
        .output()
        .expect("run the fixture");
    assert!(
        out.status.success(),
        "blender_math_values.py failed:\n{}\n{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    let mut failed = Vec::new();
    for (op, allowed) in OPERATIONS {
        let prog = program(op);
        let rows = read_rows(&dir.path().join(format!("{op}.f32")));
        let (mut equal, mut worst) = (0, 0f64);
        for r in &rows {
            let ours = prog.eval([r[0], r[1], r[2]], 0.0);
            if ours.to_bits() == r[3].to_bits() || (ours == 0.0 && r[3] == 0.0) {
                equal += 1;
                continue;
            }
            let e = (ours as f64 - r[3] as f64).abs() / (r[3].abs() as f64).max(1e-30);
            worst = worst.max(if e.is_nan() { f64::INFINITY } else { e });
        }
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
    let mut state = 0x2545_f491_4f6c_dd1du64;
    let mut uniform = |lo: f32, hi: f32| {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        lo + (hi - lo) * ((state >> 40) as f32 / (1u64 << 24) as f32)
    };
    for (op, _) in OPERATIONS {
        let prog = program(op);
        let mut checked = 0;
        for k in 0..2_000 {
            let mut lo = [0f32; 3];
            let mut hi = [0f32; 3];
            for d in 0..3 {
                let (x, y) = (uniform(-4.0, 4.0), uniform(-4.0, 4.0));
                // Narrow boxes as well as wide ones.
                let w = if k % 2 == 0 { 1.0 } else { 0.05 };
                lo[d] = x.min(x + w * (y - x));
                hi[d] = x.max(x + w * (y - x));
            }
            if k % 4 == 0 {
                let n = uniform(-3.0, 4.0).floor();
                (lo[1], hi[1]) = (n, n);
            }
            let b = prog.bounds(lo, hi, Interval::point(0.0));
            for _ in 0..50 {
                let p: [f32; 3] =
                    std::array::from_fn(|d| uniform(lo[d], hi[d]).clamp(lo[d], hi[d]));
                let v = prog.eval(p, 0.0);
                assert!(
                    v >= b.lo && v <= b.hi,
                    "{op}: {v} at {p:?} outside [{}, {}] of the box {lo:?} .. {hi:?}",
                    b.lo,
                    b.hi
                );
                checked += 1;
            }
        }
        println!("{op:<15} {checked} points inside their boxes' bounds");
    }
}
