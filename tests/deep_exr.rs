//! Deep EXR files (issue 18): write → read round trips bit for bit, what a failed write
//! or a corrupt file does, telling deep from flat files, and `nimbus info` on a deep
//! file. They need the OpenEXR bridge; without it (not built with it, and
//! `NIMBUS_OPENEXR` not `require`) they are skipped with a message, or fail under
//! `NIMBUS_REQUIRE_DATA=1`.

mod common;

use common::cli::{nimbus, stderr};
use nimbus::output::deep::{
    flatten, is_deep_exr, read_deep_exr, write_deep_exr, DeepImage, DeepSample,
};
use nimbus::render::film::Region;

fn sample(z: f32, depth: f32, rgba: [f32; 4]) -> DeepSample {
    DeepSample {
        z,
        z_back: z + depth,
        rgba,
    }
}

/// A 7x5 image whose data window is x 1..6, y 1..4: 15 pixels with 0 to 4 samples
/// (several empty), values including -0, subnormals, negatives and large ones.
fn test_image() -> DeepImage {
    let region = Region {
        x0: 1,
        y0: 1,
        x1: 6,
        y1: 4,
    };
    let mut counts = Vec::new();
    let mut samples = Vec::new();
    for p in 0..15u32 {
        let n = if p % 3 == 0 { 0 } else { p % 5 };
        counts.push(n);
        let mut z = 1.5 + p as f32;
        for i in 0..n {
            let depth = if i == 1 { 0.0 } else { 0.25 * i as f32 + 0.1 };
            let v = (p * 7 + i) as f32;
            samples.push(sample(
                z,
                depth,
                [
                    0.01 * v,
                    -0.0,
                    f32::MIN_POSITIVE / 8.0,
                    0.1 + 0.05 * i as f32,
                ],
            ));
            z += depth + 1e-3 * v;
        }
    }
    samples[3].rgba[1] = -2.5e7;
    DeepImage {
        full: (7, 5),
        region,
        counts,
        samples,
        attributes: vec![
            ("nimbus:version".into(), env!("CARGO_PKG_VERSION").into()),
            ("nimbus:stage".into(), "scenes/cloud/cloud.usda".into()),
            ("comment".into(), "ünïcode, and\nnew lines".into()),
        ],
    }
}

fn bits(s: &DeepSample) -> [u32; 6] {
    [
        s.z.to_bits(),
        s.z_back.to_bits(),
        s.rgba[0].to_bits(),
        s.rgba[1].to_bits(),
        s.rgba[2].to_bits(),
        s.rgba[3].to_bits(),
    ]
}

fn assert_same(read: &DeepImage, written: &DeepImage) {
    assert_eq!(read.full, written.full);
    assert_eq!(read.region, written.region);
    assert_eq!(read.counts, written.counts);
    assert_eq!(read.samples.len(), written.samples.len());
    for (i, (a, b)) in read.samples.iter().zip(&written.samples).enumerate() {
        assert_eq!(bits(a), bits(b), "sample {i}: {a:?} vs {b:?}");
    }
    let mut want = written.attributes.clone();
    want.sort();
    assert_eq!(read.attributes, want, "read back sorted by name");
}

#[test]
fn a_deep_image_round_trips_bit_for_bit() {
    let dir = tempfile::tempdir().unwrap();
    if !common::data::deep_exr_support("the test") {
        return;
    }
    let image = test_image();
    assert!(image.counts.contains(&0) && image.region != Region::full(7, 5));
    let path = dir.path().join("deep.exr");
    write_deep_exr(&path, &image).unwrap();
    let read = read_deep_exr(&path).unwrap();
    assert_same(&read, &image);
    assert!(is_deep_exr(&path));
    let (a, b) = (flatten(&read), flatten(&image));
    assert_eq!(a.len(), 15);
    for (x, y) in a.iter().zip(&b) {
        assert_eq!(x.map(f32::to_bits), y.map(f32::to_bits));
    }

    // A whole frame without a single sample is a valid deep file too.
    let empty = DeepImage {
        full: (3, 2),
        region: Region::full(3, 2),
        counts: vec![0; 6],
        samples: vec![],
        attributes: vec![],
    };
    write_deep_exr(&path, &empty).unwrap();
    assert_same(&read_deep_exr(&path).unwrap(), &empty);
}

#[test]
fn a_flat_exr_is_not_deep() {
    let dir = tempfile::tempdir().unwrap();
    let flat = dir.path().join("flat.exr");
    let meta = nimbus::output::exr::ExrMetadata {
        stage: "s".into(),
        tracker: "t".into(),
        scheme: "h".into(),
        transmittance: "r".into(),
        spp: 1,
        render_seconds: 0.0,
        time: f64::NAN,
        product: None,
        denoise: Default::default(),
        farm: None,
    };
    nimbus::output::exr::write_channels(
        &flat,
        (2, 2),
        Region::full(2, 2),
        vec![("R".into(), vec![0.5; 4])],
        &meta,
    )
    .unwrap();
    assert!(!is_deep_exr(&flat));
    assert!(!is_deep_exr(&dir.path().join("missing.exr")));
    std::fs::write(dir.path().join("text.exr"), "not an exr").unwrap();
    assert!(!is_deep_exr(&dir.path().join("text.exr")));
    if common::data::deep_exr_support("reading a flat file as deep") {
        let e = read_deep_exr(&flat).unwrap_err().to_string();
        assert!(e.contains("flat.exr"), "{e}");
    }
}

#[test]
fn a_failed_write_names_the_path_and_keeps_the_old_file() {
    let dir = tempfile::tempdir().unwrap();
    if !common::data::deep_exr_support("the test") {
        return;
    }
    // Tests run as root, so an unwritable folder is not one: a parent that is a file is.
    let file = dir.path().join("a-file");
    std::fs::write(&file, "x").unwrap();
    let inside = file.join("deep.exr");
    let e = write_deep_exr(&inside, &test_image())
        .unwrap_err()
        .to_string();
    assert!(e.contains(&inside.display().to_string()), "{e}");

    let path = dir.path().join("deep.exr");
    write_deep_exr(&path, &test_image()).unwrap();
    let before = std::fs::read(&path).unwrap();
    let mut bad = test_image();
    bad.counts[1] += 1; // more samples counted than given
    let e = write_deep_exr(&path, &bad).unwrap_err().to_string();
    assert!(
        e.contains(&path.display().to_string()) && e.contains("add up to"),
        "{e}"
    );
    let mut bad = test_image();
    bad.attributes.push(("dataWindow".into(), "x".into()));
    let e = write_deep_exr(&path, &bad).unwrap_err().to_string();
    assert!(e.contains("dataWindow"), "{e}");
    assert_eq!(
        std::fs::read(&path).unwrap(),
        before,
        "the old file changed"
    );
    let left: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.starts_with(".nimbus-"))
        .collect();
    assert!(left.is_empty(), "temporary files left: {left:?}");
}

#[test]
fn a_corrupt_deep_file_is_an_error_naming_it() {
    let dir = tempfile::tempdir().unwrap();
    if !common::data::deep_exr_support("the test") {
        return;
    }
    let good = dir.path().join("good.exr");
    write_deep_exr(&good, &test_image()).unwrap();
    let bytes = std::fs::read(&good).unwrap();
    let cases: Vec<(&str, Vec<u8>)> = vec![
        ("truncated.exr", bytes[..bytes.len() / 2].to_vec()),
        ("header-only.exr", bytes[..40].to_vec()),
        ("flipped.exr", {
            // Damage the pixel data after the header and offset table.
            let mut b = bytes.clone();
            let n = b.len();
            for v in &mut b[n - 60..n - 20] {
                *v ^= 0x5a;
            }
            b
        }),
        (
            "garbage.exr",
            vec![0x76, 0x2f, 0x31, 0x01, 2, 8, 0, 0, 1, 2, 3],
        ),
    ];
    for (name, b) in cases {
        let path = dir.path().join(name);
        std::fs::write(&path, b).unwrap();
        match read_deep_exr(&path) {
            Err(e) => assert!(e.to_string().contains(name), "{e}"),
            // Damaged compressed data can still decompress; it must then be well formed.
            Ok(image) => assert_eq!(
                image.counts.iter().map(|&n| n as usize).sum::<usize>(),
                image.samples.len(),
                "{name}"
            ),
        }
    }
    let e = read_deep_exr(&dir.path().join("missing.exr"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("missing.exr"), "{e}");
}

#[test]
fn info_shows_the_sample_counts_of_a_deep_file() {
    let dir = tempfile::tempdir().unwrap();
    if !common::data::deep_exr_support("the test") {
        return;
    }
    let path = dir.path().join("deep.exr");
    let image = test_image();
    write_deep_exr(&path, &image).unwrap();
    let o = nimbus(&["info", path.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let s = String::from_utf8_lossy(&o.stdout);
    let total = image.samples.len();
    let max = image.counts.iter().max().unwrap();
    let empty = image.counts.iter().filter(|&&n| n == 0).count();
    for needle in [
        "deep scanline".to_string(),
        "x 1..6 y 1..4 (5x3 pixels), display window 7x5".to_string(),
        "A (F32), B (F32), G (F32), R (F32), Z (F32), ZBack (F32)".to_string(),
        format!(
            "samples: {total} total, per pixel min 0 / mean {:.3} / max {max}, pixels with 0 samples {empty} of 15",
            total as f64 / 15.0
        ),
    ] {
        assert!(s.contains(&needle), "info lacks {needle:?}: {s}");
    }
    // The same description as JSON.
    let o = nimbus(&["info", "--json", path.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(j["kind"], "deep_exr");
    assert_eq!(j["data_window"], serde_json::json!([1, 6, 1, 4]));
    assert_eq!(j["display_window"], serde_json::json!([7, 5]));
    assert_eq!(j["samples"], total);
    assert_eq!(j["samples_per_pixel_max"], *max);
    assert_eq!(j["empty_pixels"], empty);
    assert_eq!(j["channels"][0], serde_json::json!(["A", "F32"]));
}
