//! Dome textures as other tools write them: any size, `automatic` read as lat-long,
//! the other UsdLuxDomeLight layouts, Radiance HDR, PNG and JPEG beside OpenEXR, a
//! one-colour image rendered exactly as the constant dome it is, and hostile headers
//! refused before anything is allocated. (Each layout's sampling is proven exact in
//! `render::dome`'s unit tests.)

mod common;

use common::cli::{channels, nimbus, root, stderr};
use nimbus::color::srgb_to_linear;
use nimbus::render::dome::Layout;
use nimbus::render::lights::Lights;
use nimbus::scene::{load_stage, LoadOptions};
use std::path::{Path, PathBuf};

const CAMERA: &str = "def Camera \"Cam\" { double3 xformOp:translate = (0, 0, 5)\n uniform token[] xformOpOrder = [\"xformOp:translate\"] }\n";

/// The lights of a stage holding a camera and a dome light with `body`.
fn dome_lights(dir: &Path, body: &str) -> Result<Lights, String> {
    let path = dir.join("dome.usda");
    std::fs::write(
        &path,
        format!("#usda 1.0\n{CAMERA}def DomeLight \"Sky\" {{\n{body}\n}}\n"),
    )
    .unwrap();
    let scene = load_stage(&path, &LoadOptions::default()).expect("stage loads");
    Lights::from_scene(&scene).map_err(|e| e.to_string())
}

fn write_exr(path: &Path, w: usize, h: usize, f: impl Fn(usize, usize) -> [f32; 3] + Sync) {
    use exr::prelude::*;
    write_rgb_file(path, w, h, |x, y| {
        let c = f(x, y);
        (c[0], c[1], c[2])
    })
    .expect("write test exr");
}

/// The example cloud lit only by `dome` (USD text inside /World).
fn cloud_lit_by(dir: &Path, name: &str, dome: &str) -> PathBuf {
    let text = std::fs::read_to_string(root().join("scenes/cloud/cloud.usda")).unwrap();
    let start = text.find("    def DistantLight \"Sun\"").unwrap();
    let end = text.find("def Scope \"Render\"").unwrap();
    let text = format!("{}{dome}\n}}\n\n{}", &text[..start], &text[end..]).replace(
        "@./cloud.vdb@",
        &format!("@{}@", root().join("scenes/cloud/cloud.vdb").display()),
    );
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path
}

/// A 1 × 1 texture with format `automatic` (what Blender writes for a world colour)
/// renders, and bit for bit as the constant-colour dome of its texel: every channel
/// of a 24 × 18, 4 spp render (seed 1) is equal. Colours are powers of two, so
/// intensity × colour × texel is exact either way.
#[test]
fn one_by_one_dome_renders_as_the_constant_dome() {
    let dir = tempfile::tempdir().unwrap();
    write_exr(&dir.path().join("world.exr"), 1, 1, |_, _| [0.25, 0.5, 2.0]);
    let textured = cloud_lit_by(
        dir.path(),
        "textured.usda",
        "    def DomeLight \"World\" {\n float inputs:intensity = 3\n asset inputs:texture:file = @./world.exr@\n token inputs:texture:format = \"automatic\"\n }",
    );
    let constant = cloud_lit_by(
        dir.path(),
        "constant.usda",
        "    def DomeLight \"World\" {\n float inputs:intensity = 3\n color3f inputs:color = (0.25, 0.5, 2)\n }",
    );
    let mut images = Vec::new();
    for stage in [&textured, &constant] {
        let out = stage.with_extension("exr");
        let o = nimbus(&[
            "render",
            stage.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
            "--res",
            "24x18",
            "--spp",
            "4",
            "--seed",
            "1",
        ]);
        assert!(o.status.success(), "{}", stderr(&o));
        images.push(channels(&out));
    }
    assert_eq!(images[0].len(), images[1].len());
    for ((name, a), (_, b)) in images[0].iter().zip(&images[1]) {
        let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(a), bits(b), "channel {name} differs");
    }
    let r: f32 = images[0]
        .iter()
        .find(|c| c.0 == "R")
        .unwrap()
        .1
        .iter()
        .sum();
    assert!(r > 0.0, "the dome lights the image");
}

/// Any size and every layout loads through the stage; `automatic` reads a non-2:1
/// image as lat-long; a vertical cross must be 3N × 4N and an unknown format is an
/// error naming the light, the file and the token.
#[test]
fn layouts_and_sizes_load_through_the_stage() {
    let dir = tempfile::tempdir().unwrap();
    write_exr(&dir.path().join("sky.exr"), 6, 8, |x, y| {
        [x as f32, y as f32, 1.0]
    });
    for (format, layout) in [
        ("automatic", Layout::LatLong),
        ("latlong", Layout::LatLong),
        ("mirroredBall", Layout::MirroredBall),
        ("angular", Layout::Angular),
        ("cubeMapVerticalCross", Layout::CubeMapVerticalCross),
    ] {
        let lights = dome_lights(
            dir.path(),
            &format!("asset inputs:texture:file = @./sky.exr@\ntoken inputs:texture:format = \"{format}\""),
        )
        .unwrap_or_else(|e| panic!("{format}: {e}"));
        let map = &lights.env_maps[0];
        assert_eq!(
            (map.width, map.height, map.layout),
            (6, 8, layout),
            "{format}"
        );
        assert_eq!(
            map.texels[6 * 2 + 5],
            [5.0, 2.0, 1.0],
            "{format}: texel (5, 2)"
        );
    }
    write_exr(&dir.path().join("wide.exr"), 8, 8, |x, _| [x as f32; 3]);
    let e = dome_lights(
        dir.path(),
        "asset inputs:texture:file = @./wide.exr@\ntoken inputs:texture:format = \"cubeMapVerticalCross\"",
    )
    .err()
    .expect("an 8×8 cross is refused");
    assert!(
        e.contains("/Sky") && e.contains("wide.exr") && e.contains("8×8") && e.contains("3N×4N"),
        "{e}"
    );
    let e = dome_lights(
        dir.path(),
        "asset inputs:texture:file = @./wide.exr@\ntoken inputs:texture:format = \"octahedral\"",
    )
    .err()
    .expect("an unknown format is refused");
    assert!(
        e.contains("/Sky") && e.contains("wide.exr") && e.contains("octahedral"),
        "{e}"
    );
}

/// PNG (8- and 16-bit) and JPEG texels are sRGB-decoded to linear; Radiance HDR texels
/// are linear. Each image has two colours (so it stays a map, not a constant). JPEG is
/// lossy: a flat 16 × 8 block decodes within 2/255 of its value before decoding to
/// linear; RGBE keeps 8 bits of mantissa: 1 %.
#[test]
fn png_jpeg_and_hdr_textures_are_read() {
    use image::{DynamicImage, ImageBuffer, Rgb};
    let dir = tempfile::tempdir().unwrap();
    let read = |file: &str| {
        let lights = dome_lights(
            dir.path(),
            &format!("asset inputs:texture:file = @./{file}@\nfloat inputs:intensity = 2"),
        )
        .unwrap_or_else(|e| panic!("{file}: {e}"));
        let map = &lights.env_maps[0];
        assert_eq!((map.width, map.height), (16, 8), "{file}");
        (map.texels[0], map.texels[15])
    };

    let png8 = ImageBuffer::from_fn(16, 8, |x, _| {
        if x < 8 {
            Rgb([128u8, 64, 255])
        } else {
            Rgb([0, 0, 0])
        }
    });
    png8.save(dir.path().join("sky8.png")).unwrap();
    let (lit, dark) = read("sky8.png");
    let expect = [128.0, 64.0, 255.0].map(|v: f64| 2.0 * srgb_to_linear(v / 255.0));
    for c in 0..3 {
        assert!(
            (lit[c] - expect[c]).abs() < 1e-12,
            "8-bit PNG: {lit:?} vs {expect:?}"
        );
    }
    assert_eq!(dark, [0.0; 3]);

    let png16 = ImageBuffer::from_fn(16, 8, |x, _| {
        if x < 8 {
            Rgb([32768u16, 1000, 65535])
        } else {
            Rgb([0, 0, 0])
        }
    });
    DynamicImage::ImageRgb16(png16)
        .save(dir.path().join("sky16.png"))
        .unwrap();
    let (lit, _) = read("sky16.png");
    let expect = [32768.0, 1000.0, 65535.0].map(|v: f64| 2.0 * srgb_to_linear(v / 65535.0));
    for c in 0..3 {
        assert!(
            (lit[c] - expect[c]).abs() < 1e-12,
            "16-bit PNG: {lit:?} vs {expect:?}"
        );
    }

    let jpeg = ImageBuffer::from_fn(16, 8, |x, _| {
        if x < 8 {
            Rgb([200u8, 100, 50])
        } else {
            Rgb([20, 20, 20])
        }
    });
    jpeg.save(dir.path().join("sky.jpg")).unwrap();
    let (lit, _) = read("sky.jpg");
    for (c, v) in [200.0, 100.0, 50.0].into_iter().enumerate() {
        let (lo, hi) = (
            2.0 * srgb_to_linear((v - 2.0) / 255.0),
            2.0 * srgb_to_linear((v + 2.0) / 255.0),
        );
        assert!(
            (lo..=hi).contains(&lit[c]),
            "JPEG channel {c}: {} not in [{lo}, {hi}]",
            lit[c]
        );
    }

    let hdr = ImageBuffer::from_fn(16, 8, |x, _| {
        if x < 8 {
            Rgb([0.5f32, 2.0, 1.0])
        } else {
            Rgb([0.0, 0.0, 0.0])
        }
    });
    DynamicImage::ImageRgb32F(hdr)
        .save(dir.path().join("sky.hdr"))
        .unwrap();
    let (lit, _) = read("sky.hdr");
    for (c, v) in [1.0, 4.0, 2.0].into_iter().enumerate() {
        assert!((lit[c] - v).abs() < 0.01 * v, "HDR: {lit:?}");
    }

    std::fs::write(dir.path().join("bad.png"), b"not a png").unwrap();
    let e = dome_lights(dir.path(), "asset inputs:texture:file = @./bad.png@")
        .err()
        .expect("a bad PNG is refused");
    assert!(e.contains("/Sky") && e.contains("bad.png"), "{e}");
}

/// An OpenEXR file with its dataWindow replaced by `window` (xmin, ymin, xmax, ymax).
fn exr_with_window(path: &Path, window: [i32; 4]) {
    write_exr(path, 4, 2, |_, _| [1.0; 3]);
    let mut bytes = std::fs::read(path).unwrap();
    let key = b"dataWindow\0box2i\0";
    let at = bytes
        .windows(key.len())
        .position(|w| w == key)
        .expect("a dataWindow attribute")
        + key.len()
        + 4;
    for (i, v) in window.iter().enumerate() {
        bytes[at + 4 * i..at + 4 * i + 4].copy_from_slice(&v.to_le_bytes());
    }
    std::fs::write(path, bytes).unwrap();
}

/// Issue 34: an OpenEXR or PNG header claiming 1,000,000 × 1,000,000 pixels is refused
/// from the header (this test would abort on a 24 TB allocation otherwise), and so is
/// an OpenEXR data window whose max is below its min; the message names the light and
/// the file.
#[test]
fn hostile_image_headers_are_refused_before_reading() {
    let dir = tempfile::tempdir().unwrap();
    exr_with_window(&dir.path().join("huge.exr"), [0, 0, 999_999, 999_999]);
    let e = dome_lights(dir.path(), "asset inputs:texture:file = @./huge.exr@")
        .err()
        .expect("the huge header is refused");
    assert!(
        e.contains("/Sky") && e.contains("huge.exr") && e.contains("1000000×1000000"),
        "{e}"
    );
    exr_with_window(&dir.path().join("inverted.exr"), [3, 0, 0, 1]);
    let e = dome_lights(dir.path(), "asset inputs:texture:file = @./inverted.exr@")
        .err()
        .expect("max < min is refused");
    assert!(
        e.contains("/Sky") && e.contains("inverted.exr") && e.contains("max below its min"),
        "{e}"
    );
    // The unpatched file reads.
    write_exr(&dir.path().join("fine.exr"), 4, 2, |x, _| [x as f32; 3]);
    dome_lights(dir.path(), "asset inputs:texture:file = @./fine.exr@").expect("fine.exr reads");

    // A PNG whose IHDR claims 1,000,000 × 1,000,000 (its CRC recomputed, so the
    // header is valid): refused from the header too.
    let path = dir.path().join("huge.png");
    image::RgbImage::from_pixel(2, 2, image::Rgb([9, 9, 9]))
        .save(&path)
        .unwrap();
    let mut bytes = std::fs::read(&path).unwrap();
    assert_eq!(&bytes[12..16], b"IHDR");
    bytes[16..20].copy_from_slice(&1_000_000u32.to_be_bytes());
    bytes[20..24].copy_from_slice(&1_000_000u32.to_be_bytes());
    let crc = crc32(&bytes[12..29]);
    bytes[29..33].copy_from_slice(&crc.to_be_bytes());
    std::fs::write(&path, bytes).unwrap();
    let e = dome_lights(dir.path(), "asset inputs:texture:file = @./huge.png@")
        .err()
        .expect("the huge PNG is refused");
    assert!(
        e.contains("/Sky") && e.contains("huge.png") && e.contains("1000000×1000000"),
        "{e}"
    );
}

/// CRC-32 (ISO-HDLC, PNG's chunk checksum), bit by bit.
fn crc32(data: &[u8]) -> u32 {
    let mut crc = !0u32;
    for &b in data {
        crc ^= b as u32;
        for _ in 0..8 {
            crc = if crc & 1 != 0 {
                (crc >> 1) ^ 0xEDB8_8320
            } else {
                crc >> 1
            };
        }
    }
    !crc
}
