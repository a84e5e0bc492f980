//! MaterialX's `noise3d`, `fractal3d` and `cellnoise3d` against the MaterialX standard library's
//! published formulas: `tests/fixtures/materialx_noise_values.py` transcribes
//! `mx_noise.glsl` (Perlin noise, lookup3 hash, gradients, fade, trilinear interpolation,
//! the fractal sum, `mx_cell_noise_float(vec3)` with `mx_bits_to_01`) and the nodes'
//! GLSL into numpy, one float32 operation per GLSL
//! operation in the GLSL's order, and evaluates them at 10,000 random points per
//! parameter set. `nimbus::shader::materialx_noise` must give the same floats, bit for
//! bit: both sides round every operation once, in the same order, with no fused
//! multiply-add. (A GPU running the GLSL may fuse; MaterialX's OSL implementation calls
//! OSL's noise, which rounds differently: those agree with this to float precision, not
//! to the bit.)
//!
//! The reference is computed here, not shipped: python3 with numpy (`bash .ci/setup`
//! installs it); without it the test prints one `SKIPPED` line, or fails under
//! `NIMBUS_REQUIRE_DATA=1`.

mod common;

use std::path::Path;

use nimbus::shader::materialx_noise::{cell_noise_3d, Fractal3d, Noise3d};

const N: usize = 10_000;

enum Node {
    Noise(Noise3d),
    Fractal(Fractal3d),
    Cell,
}

struct Case {
    name: &'static str,
    points: &'static str,
    seed: u64,
    node: Node,
}

fn cases() -> Vec<Case> {
    let noise = |amplitude, pivot| Node::Noise(Noise3d { amplitude, pivot });
    let fractal = |octaves, lacunarity, diminish, amplitude| {
        Node::Fractal(Fractal3d {
            amplitude,
            octaves,
            lacunarity,
            diminish,
        })
    };
    let case = |name, points, seed, node| Case {
        name,
        points,
        seed,
        node,
    };
    vec![
        case("noise3d_defaults", "box", 1, noise(1.0, 0.0)),
        case("noise3d_amp_pivot", "box", 2, noise(0.5, 0.5)),
        case("noise3d_negative", "negative", 3, noise(1.0, 0.0)),
        case("noise3d_wide", "wide", 4, noise(2.0, -0.25)),
        case("fractal3d_defaults", "box", 5, fractal(3, 2.0, 0.5, 1.0)),
        case("fractal3d_8_octaves", "box", 6, fractal(8, 2.3, 0.6, 0.7)),
        case(
            "fractal3d_negative",
            "negative",
            7,
            fractal(4, 1.7, 0.45, 1.0),
        ),
        case("fractal3d_wide", "wide", 8, fractal(3, 2.0, 0.5, 1.0)),
        case("cellnoise3d_box", "box", 9, Node::Cell),
        case("cellnoise3d_negative", "negative", 10, Node::Cell),
        case("cellnoise3d_wide", "wide", 11, Node::Cell),
    ]
}

fn cases_json(cases: &[Case]) -> String {
    let items: Vec<String> = cases
        .iter()
        .map(|c| {
            let (node, amplitude, pivot, octaves, lacunarity, diminish) = match &c.node {
                Node::Noise(n) => ("noise3d", n.amplitude, n.pivot, 0, 0.0, 0.0),
                Node::Fractal(f) => (
                    "fractal3d",
                    f.amplitude,
                    0.0,
                    f.octaves,
                    f.lacunarity,
                    f.diminish,
                ),
                Node::Cell => ("cellnoise3d", 0.0, 0.0, 0, 0.0, 0.0),
            };
            format!(
                "{{\"name\": \"{}\", \"node\": \"{node}\", \"points\": \"{}\", \"seed\": {}, \
                 \"n\": {N}, \"amplitude\": {amplitude:?}, \"pivot\": {pivot:?}, \
                 \"octaves\": {octaves}, \"lacunarity\": {lacunarity:?}, \
                 \"diminish\": {diminish:?}}}",
                c.name, c.points, c.seed
            )
        })
        .collect();
    format!("[\n{}\n]\n", items.join(",\n"))
}

fn read_rows(path: &Path) -> Vec<[f32; 4]> {
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
fn noise3d_fractal3d_and_cellnoise3d_match_the_published_formulas() {
    if !common::python_imports(&["numpy"], common::data::SETUP_PYTHON) {
        return;
    }
    let cases = cases();
    let dir = tempfile::tempdir().expect("temp dir");
    let spec = dir.path().join("cases.json");
    std::fs::write(&spec, cases_json(&cases)).unwrap();
    common::data::run_fixture(
        "python3",
        "materialx_noise_values.py",
        [spec.as_os_str(), dir.path().as_os_str()],
    );
    let mut failed = Vec::new();
    for case in &cases {
        let rows = read_rows(&dir.path().join(format!("{}.f32", case.name)));
        let (mut equal, mut max_abs, mut first) = (0, 0.0f32, None);
        for r in &rows {
            let p = [r[0], r[1], r[2]];
            let ours = match &case.node {
                Node::Noise(n) => n.eval(p),
                Node::Fractal(f) => f.eval(p),
                Node::Cell => cell_noise_3d(p),
            };
            let diff = (ours - r[3]).abs();
            max_abs = max_abs.max(diff);
            if ours.to_bits() == r[3].to_bits() {
                equal += 1;
            } else {
                first.get_or_insert(format!("at {p:?}: nimbus {ours:e}, formula {:e}", r[3]));
            }
        }
        println!(
            "{:<22} {equal}/{N} equal to the bit, max abs difference {max_abs:.2e}",
            case.name
        );
        if let Some(first) = first {
            failed.push(format!(
                "{}: {} differ, first {first}",
                case.name,
                N - equal
            ));
        }
    }
    assert!(failed.is_empty(), "{}", failed.join("\n"));
}
