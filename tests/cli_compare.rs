//! End-to-end tests of `nimbus compare`: the JSON report and its known errors.

mod common;

use common::cli::{assert_clean_error, nimbus, stderr};
use std::path::Path;

/// Writes an EXR with f32 channels `(name, values)`, optionally inside a named layer.
fn write_test_exr(
    path: &Path,
    w: usize,
    h: usize,
    layer: Option<&str>,
    chans: &[(&str, Vec<f32>)],
) {
    use exr::prelude::*;
    let channels: Vec<AnyChannel<FlatSamples>> = chans
        .iter()
        .map(|(n, v)| AnyChannel::new(*n, FlatSamples::F32(v.clone())))
        .collect();
    let mut attrs = LayerAttributes::default();
    attrs.layer_name = layer.map(Text::from);
    let layer = Layer::new(
        (w, h),
        attrs,
        Encoding::FAST_LOSSLESS,
        AnyChannels::sort(channels.into()),
    );
    Image::from_layer(layer).write().to_file(path).unwrap();
}

fn compare_json(a: &Path, b: &Path) -> serde_json::Value {
    let o = nimbus(&[
        "compare",
        a.to_str().unwrap(),
        b.to_str().unwrap(),
        "--json",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    serde_json::from_slice(&o.stdout).unwrap()
}

#[test]
fn compare_reports_known_errors() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (w, h) = (4, 2);
    // Reference: R = 1, G = 0, B = 2. Test: R off by 0.5 everywhere, G off by 0.1 in
    // half the pixels, B exact except one pixel at 1e6 (clamped to 65504).
    let refc = vec![
        ("R", vec![1.0; 8]),
        ("G", vec![0.0; 8]),
        ("B", vec![2.0; 8]),
    ];
    let mut b_test = vec![2.0f32; 8];
    b_test[3] = 1e6;
    let test = vec![
        ("R", vec![1.5; 8]),
        (
            "G",
            (0..8).map(|i| if i % 2 == 0 { 0.1 } else { 0.0 }).collect(),
        ),
        ("B", b_test),
    ];
    let (a, b) = (d.join("a.exr"), d.join("b.exr"));
    write_test_exr(&a, w, h, None, &test);
    write_test_exr(&b, w, h, None, &refc);
    let j = compare_json(&a, &b);
    let ch = |i: usize, k: &str| j["channels"][i][k].as_f64().unwrap();
    let close = |x: f64, y: f64| (x - y).abs() <= 1e-6 * y.abs().max(1e-6);
    assert_eq!(j["channels"][0]["channel"], "R");
    assert!(close(ch(0, "mse"), 0.25));
    assert!(close(ch(0, "rmse"), 0.5));
    assert!(close(ch(0, "relmse"), 0.25 / 1.01));
    assert!(close(ch(0, "mean_a"), 1.5));
    assert!(close(ch(0, "mean_b"), 1.0));
    let g_d2 = (0.1f32 as f64).powi(2);
    assert!(close(ch(1, "mse"), g_d2 / 2.0));
    assert!(close(ch(1, "relmse"), g_d2 / 0.01 / 2.0));
    let b_d2 = (65504.0f64 - 2.0).powi(2);
    assert!(close(ch(2, "mse"), b_d2 / 8.0));
    assert!(close(ch(2, "relmse"), b_d2 / 4.01 / 8.0));
    // An image against itself: zero error.
    let z = compare_json(&b, &b);
    assert_eq!(z["rgb"]["mse"].as_f64().unwrap(), 0.0);

    // RGBA inside a named layer (`rgba.R` on read-back) is found.
    let layered = d.join("layered.exr");
    write_test_exr(&layered, w, h, Some("rgba"), &test);
    let jl = compare_json(&layered, &b);
    assert_eq!(jl["channels"][0]["mse"], j["channels"][0]["mse"]);
    // So are channels named `beauty.R` etc. without a layer attribute.
    let dotted = d.join("dotted.exr");
    let dotted_chans: Vec<(&str, Vec<f32>)> = vec![
        ("beauty.R", test[0].1.clone()),
        ("beauty.G", test[1].1.clone()),
        ("beauty.B", test[2].1.clone()),
    ];
    write_test_exr(&dotted, w, h, None, &dotted_chans);
    assert_eq!(compare_json(&dotted, &b)["rgb"], j["rgb"]);

    // Text output has the table.
    let o = nimbus(&["compare", a.to_str().unwrap(), b.to_str().unwrap()]);
    assert!(o.status.success());
    assert!(String::from_utf8_lossy(&o.stdout).contains("relMSE"));

    // Different sizes, a missing channel, a file that is not an EXR: clean errors.
    let small = d.join("small.exr");
    write_test_exr(
        &small,
        2,
        2,
        None,
        &[
            ("R", vec![0.0; 4]),
            ("G", vec![0.0; 4]),
            ("B", vec![0.0; 4]),
        ],
    );
    let o = nimbus(&["compare", small.to_str().unwrap(), b.to_str().unwrap()]);
    assert_clean_error(&o, "differ in size");
    let nog = d.join("nog.exr");
    write_test_exr(
        &nog,
        w,
        h,
        None,
        &[("R", vec![0.0; 8]), ("B", vec![0.0; 8])],
    );
    let o = nimbus(&["compare", nog.to_str().unwrap(), b.to_str().unwrap()]);
    assert_clean_error(&o, "no channel G");
    let junk = d.join("junk.exr");
    std::fs::write(&junk, b"not an exr").unwrap();
    let o = nimbus(&["compare", a.to_str().unwrap(), junk.to_str().unwrap()]);
    assert_clean_error(&o, "junk.exr");
}
