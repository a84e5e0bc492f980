//! Deep output of a render (issue 18, part 3): `--deep` and `productType = "deepRaster"`
//! write a deep EXR whose samples are the render's depth bins; flattened front to back
//! it equals the flat beauty and alpha within the rounding bound derived below.

use nimbus::output::deep::{read_deep_exr, DeepImage, DeepSample};
use std::path::Path;

mod common;

use common::cli::{assert_clean_error, channel, channels, nimbus, stderr};
use common::repo;

/// Renders `stage` at 40×30, 4 spp, to `flat` and the deep `deep` with `extra` flags.
fn render(stage: &Path, flat: &Path, deep: &Path, extra: &[&str]) {
    let mut args = vec![
        "render",
        stage.to_str().unwrap(),
        "-o",
        flat.to_str().unwrap(),
        "--deep",
        deep.to_str().unwrap(),
        "--res",
        "40x30",
        "--spp",
        "4",
        "--seed",
        "2",
    ];
    args.extend_from_slice(extra);
    let o = nimbus(&args);
    assert!(o.status.success(), "{}", stderr(&o));
}

/// One pixel's samples.
fn pixel_samples(image: &DeepImage, p: usize) -> &[DeepSample] {
    let start: usize = image.counts[..p].iter().map(|&n| n as usize).sum();
    &image.samples[start..start + image.counts[p] as usize]
}

/// Checks every pixel's front-to-back composite against the flat RGBA. The bound: the
/// flat value is an f64 mean rounded to f32 (2⁻²⁴ relative); each stored sample value
/// is rounded to f32 once, and the composite multiplies sample k's colour by
/// T_k = Π_{j<k} (1 − A_j), whose relative error is at most Σ_{j<k} 2⁻²⁴ A_j / (1 − A_j)
/// (the rounding of each A_j, amplified where a sample is nearly opaque). So
/// |flat(deep) − beauty| ≤ 2⁻²⁴ (|beauty| + Σ_k T_k |C_k| (1 + Σ_{j<k} A_j/(1 − A_j)))
/// plus the f32 rounding of the composite (2⁻²⁴ of it); we allow twice that.
fn assert_flattens_to(flat: &[(String, Vec<f32>)], image: &DeepImage, limit: u32) {
    let eps = 2f64.powi(-24);
    let mut worst: f64 = 0.0;
    for p in 0..image.counts.len() {
        assert!(
            image.counts[p] <= limit,
            "pixel {p}: {} samples",
            image.counts[p]
        );
        let samples = pixel_samples(image, p);
        for c in 0..4 {
            let (mut t, mut amp, mut acc, mut bound) = (1f64, 0f64, 0f64, 0f64);
            for s in samples {
                assert!(s.z <= s.z_back && s.rgba.iter().all(|v| v.is_finite()));
                let (v, a) = (s.rgba[c] as f64, s.rgba[3] as f64);
                acc += t * v;
                bound += t * v.abs() * (1.0 + amp);
                amp += a.abs() / (1.0 - a).abs().max(1e-300);
                t *= 1.0 - a;
            }
            let b = channel(flat, ["R", "G", "B", "A"][c])[p] as f64;
            let tol = 2.0 * eps * (2.0 * b.abs() + bound);
            worst = worst.max((acc - b).abs() / tol.max(1e-300));
            assert!(
                (acc - b).abs() <= tol,
                "pixel {p} channel {c}: deep {acc} flat {b} (bound {tol})"
            );
        }
    }
    eprintln!("worst |flat(deep) − beauty| / bound = {worst:.3}");
}

#[test]
fn the_deep_cloud_flattens_to_the_flat_render() {
    if !common::data::deep_exr_support("the test") {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let (flat, deep) = (dir.path().join("flat.exr"), dir.path().join("deep.exr"));
    let stage = repo().join("scenes/cloud/cloud.usda");
    render(&stage, &flat, &deep, &[]);
    let image = read_deep_exr(&deep).unwrap();
    assert_eq!(image.full, (40, 30));
    assert_flattens_to(&channels(&flat), &image, 32);
    // The cloud spreads its collisions over depth: some pixel holds several samples,
    // the sky pixels one (the dome behind the volume), and depths increase.
    assert!(image.counts.iter().any(|&n| n >= 3));
    assert!(image.counts.iter().all(|&n| n >= 1));
    for p in 0..image.counts.len() {
        let s = pixel_samples(&image, p);
        assert!(s.windows(2).all(|w| w[0].z_back <= w[1].z));
    }
    // A limit of one sample per pixel merges every pixel's bins into one.
    let deep1 = dir.path().join("deep1.exr");
    render(&stage, &flat, &deep1, &["--deep-samples", "1"]);
    let one = read_deep_exr(&deep1).unwrap();
    assert_flattens_to(&channels(&flat), &one, 1);
}

/// An emissive, chromatic volume (spectral tracking's weighted estimates put alpha
/// estimates outside [0, 1] in some bins) still flattens to its flat render.
#[test]
fn the_deep_fire_flattens_to_the_flat_render() {
    if !common::data::deep_exr_support("the test") {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let (flat, deep) = (dir.path().join("flat.exr"), dir.path().join("deep.exr"));
    let stage = repo().join("scenes/fire/fire.usda");
    render(&stage, &flat, &deep, &["--tracker", "spectral"]);
    assert_flattens_to(&channels(&flat), &read_deep_exr(&deep).unwrap(), 32);
}

#[test]
fn a_deep_raster_product_writes_a_deep_exr() {
    if !common::data::deep_exr_support("the test") {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(repo().join("scenes/cloud/cloud.usda")).unwrap();
    let vdb = repo().join("scenes/cloud/cloud.vdb");
    let text = text.replace("@./cloud.vdb@", &format!("@{}@", vdb.display()));
    let deep_product = r#"
    def RenderProduct "Deep"
    {
        uniform token productType = "deepRaster"
        uniform token productName = "deep.exr"
        rel orderedVars = [</Render/Vars/color>]
    }
"#;
    let text = text.replacen(
        "    def RenderProduct \"Product\"",
        &format!("{deep_product}\n    def RenderProduct \"Product\""),
        1,
    );
    let text = text.replace(
        "rel products = </Render/Product>",
        "rel products = [</Render/Product>, </Render/Deep>]",
    );
    let stage = dir.path().join("cloud.usda");
    std::fs::write(&stage, &text).unwrap();
    let flat = dir.path().join("flat.exr");
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_nimbus"))
        .current_dir(dir.path())
        .args([
            "render",
            stage.to_str().unwrap(),
            "-o",
            flat.to_str().unwrap(),
        ])
        .args(["--res", "20x15", "--spp", "2"])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    let image = read_deep_exr(&dir.path().join("deep.exr")).unwrap();
    assert_eq!(image.counts.len(), 300);
    assert_flattens_to(&channels(&flat), &image, 32);
    // A deep product holds colour and alpha only.
    let bad = text.replace(
        "rel orderedVars = [</Render/Vars/color>]\n    }\n",
        "rel orderedVars = [</Render/Vars/color>, </Render/Vars/lookups>]\n    }\n",
    );
    std::fs::write(&stage, bad).unwrap();
    let o = nimbus(&[
        "render",
        stage.to_str().unwrap(),
        "-o",
        flat.to_str().unwrap(),
    ]);
    assert_clean_error(&o, "deepRaster");
}
