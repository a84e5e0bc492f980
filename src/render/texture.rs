//! Dome texture files → linear RGB texels: OpenEXR (the `exr` crate), Radiance HDR,
//! PNG and JPEG (the `image` crate). 8- and 16-bit images are sRGB-encoded (as PNG and
//! JPEG are by default) and are decoded to linear; float images are linear already.
//!
//! A file's header is read and its size checked against [`MAX_TEXELS`] before any
//! pixel is allocated: a header claiming a million × a million pixels is refused in
//! microseconds instead of aborting on a 24 TB allocation. An OpenEXR data window
//! whose max is below its min is refused as OpenEXR refuses it (the `exr` crate would
//! swap the corners and read it).

use crate::color::srgb_to_linear;
use std::fs::File;
use std::io::{BufReader, Read};
use std::path::Path;

/// The most texels a dome texture may have: 2²⁷, a 16,384 × 8,192 lat-long image
/// (3 GiB as the f64 RGB the map keeps, 5 GiB with its sampling distribution).
pub const MAX_TEXELS: u64 = 1 << 27;

/// A texture's texels: width, height and linear RGB rows from the top.
pub type Texels = (usize, usize, Vec<[f64; 3]>);

/// Reads `path`: OpenEXR by its extension or magic number, else Radiance HDR, PNG or
/// JPEG by their signature.
pub fn read_texture(path: &Path) -> Result<Texels, String> {
    if !path.is_file() {
        return Err("file not found".into());
    }
    let ext = path
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase());
    let exr = match ext.as_deref() {
        Some("exr") => true,
        Some("hdr" | "pic" | "png" | "jpg" | "jpeg") => false,
        _ => has_exr_magic(path),
    };
    if exr {
        for window in exr_data_windows(path)? {
            check_data_window(window)?;
        }
        read_rgb_exr(path)
    } else {
        read_image(path)
    }
}

/// Refuses an empty image or one of more than [`MAX_TEXELS`] texels.
fn check_size(width: u64, height: u64) -> Result<(), String> {
    if width == 0 || height == 0 {
        return Err(format!("the image is empty ({width}×{height})"));
    }
    let texels = width.saturating_mul(height);
    if texels > MAX_TEXELS {
        return Err(format!(
            "the header claims {width}×{height} pixels ({texels} texels), more than the {MAX_TEXELS} a dome texture may have: refused before reading"
        ));
    }
    Ok(())
}

/// OpenEXR's magic number, the first four bytes of every OpenEXR file.
const EXR_MAGIC: [u8; 4] = [0x76, 0x2f, 0x31, 0x01];

fn has_exr_magic(path: &Path) -> bool {
    let mut magic = [0u8; 4];
    File::open(path).is_ok_and(|mut f| f.read_exact(&mut magic).is_ok() && magic == EXR_MAGIC)
}

/// Checks an OpenEXR data window `[xmin, ymin, xmax, ymax]` (inclusive corners).
fn check_data_window([x0, y0, x1, y1]: [i32; 4]) -> Result<(), String> {
    if x1 < x0 || y1 < y0 {
        return Err(format!(
            "its dataWindow ({x0}, {y0}) – ({x1}, {y1}) has a max below its min: not a valid OpenEXR image"
        ));
    }
    check_size(
        (x1 as i64 - x0 as i64 + 1) as u64,
        (y1 as i64 - y0 as i64 + 1) as u64,
    )
}

/// The `dataWindow` of every header of an OpenEXR file (one, or one per part of a
/// multi-part file), read from the header bytes alone: attributes are skipped without
/// being stored, so a hostile size field allocates nothing.
fn exr_data_windows(path: &Path) -> Result<Vec<[i32; 4]>, String> {
    let file = File::open(path).map_err(|e| e.to_string())?;
    let mut r = BufReader::new(file);
    let truncated = |_| "not an OpenEXR image (its header ends early)".to_string();
    let mut word = [0u8; 4];
    r.read_exact(&mut word).map_err(truncated)?;
    if word != EXR_MAGIC {
        return Err("not an OpenEXR image (no OpenEXR magic number)".into());
    }
    r.read_exact(&mut word).map_err(truncated)?;
    // Version field bit 12: a multi-part file, whose headers end with an empty one.
    let multipart = u32::from_le_bytes(word) & 0x1000 != 0;
    let mut windows = Vec::new();
    loop {
        let mut window = None;
        let mut attributes = 0;
        loop {
            let name = read_name(&mut r)?;
            if name.is_empty() {
                break;
            }
            attributes += 1;
            let kind = read_name(&mut r)?;
            r.read_exact(&mut word).map_err(truncated)?;
            let size = i32::from_le_bytes(word);
            if size < 0 {
                return Err(format!(
                    "not an OpenEXR image (attribute {name} has a negative size)"
                ));
            }
            if name == "dataWindow" {
                if kind != "box2i" || size != 16 {
                    return Err(format!(
                        "its dataWindow is a {kind} of {size} bytes, not a box2i"
                    ));
                }
                let mut b = [0i32; 4];
                for v in &mut b {
                    r.read_exact(&mut word).map_err(truncated)?;
                    *v = i32::from_le_bytes(word);
                }
                window = Some(b);
            } else {
                let skipped = std::io::copy(&mut (&mut r).take(size as u64), &mut std::io::sink())
                    .map_err(|e| e.to_string())?;
                if skipped != size as u64 {
                    return Err("not an OpenEXR image (its header ends early)".into());
                }
            }
        }
        if attributes == 0 && !windows.is_empty() {
            break;
        }
        windows.push(window.ok_or("not an OpenEXR image (a header has no dataWindow)")?);
        if !multipart {
            break;
        }
    }
    Ok(windows)
}

/// A NUL-terminated attribute name or type (at most 255 bytes, OpenEXR's long names).
fn read_name(r: &mut impl Read) -> Result<String, String> {
    let mut name = Vec::new();
    let mut byte = [0u8; 1];
    loop {
        r.read_exact(&mut byte)
            .map_err(|_| "not an OpenEXR image (its header ends early)".to_string())?;
        if byte[0] == 0 {
            return Ok(String::from_utf8_lossy(&name).into_owned());
        }
        if name.len() == 255 {
            return Err("not an OpenEXR image (an attribute name is over 255 bytes)".into());
        }
        name.push(byte[0]);
    }
}

/// Reads an EXR's R, G, B (first valid layer, largest level) as row-major rows from the
/// top of the data window.
fn read_rgb_exr(path: &Path) -> Result<Texels, String> {
    use exr::prelude::*;
    let image = read_first_rgba_layer_from_file(
        path,
        |res: Vec2<usize>, _: &RgbaChannels| (res.0, vec![[0f64; 3]; res.0 * res.1]),
        |px: &mut (usize, Vec<[f64; 3]>), pos: Vec2<usize>, (r, g, b, _a): (f32, f32, f32, f32)| {
            let w = px.0;
            px.1[pos.1 * w + pos.0] = [r as f64, g as f64, b as f64];
        },
    )
    .map_err(|e| format!("cannot read as an RGB(A) OpenEXR image: {e}"))?;
    let size = image.layer_data.size;
    let (w, h) = (size.0, size.1);
    if w == 0 || h == 0 {
        return Err("empty image".into());
    }
    let texels = image.layer_data.channel_data.pixels.1;
    if texels.iter().flatten().any(|v| !v.is_finite()) {
        return Err("contains NaN or infinite values".into());
    }
    Ok((w, h, texels))
}

/// Reads a Radiance HDR, PNG or JPEG image through the `image` crate.
fn read_image(path: &Path) -> Result<Texels, String> {
    use image::{DynamicImage, ImageReader};
    let unknown = "not an OpenEXR, Radiance HDR, PNG or JPEG image";
    let open = || {
        ImageReader::open(path)
            .and_then(|r| r.with_guessed_format())
            .map_err(|e| e.to_string())
    };
    let reader = open()?;
    if reader.format().is_none() {
        return Err(unknown.into());
    }
    let (w, h) = reader
        .into_dimensions()
        .map_err(|e| format!("cannot read its header ({unknown}?): {e}"))?;
    check_size(w as u64, h as u64)?;
    let mut reader = open()?;
    let mut limits = image::Limits::default();
    // Room for the largest allowed image as 32-bit float RGBA.
    limits.max_alloc = Some(MAX_TEXELS * 16);
    reader.limits(limits);
    let image = reader
        .decode()
        .map_err(|e| format!("cannot decode it: {e}"))?;
    let (w, h) = (image.width() as usize, image.height() as usize);
    let texels: Vec<[f64; 3]> = match image {
        DynamicImage::ImageRgb32F(_) | DynamicImage::ImageRgba32F(_) => image
            .into_rgb32f()
            .pixels()
            .map(|p| p.0.map(f64::from))
            .collect(),
        DynamicImage::ImageLuma16(_)
        | DynamicImage::ImageLumaA16(_)
        | DynamicImage::ImageRgb16(_)
        | DynamicImage::ImageRgba16(_) => image
            .into_rgb16()
            .pixels()
            .map(|p| p.0.map(|v| srgb_to_linear(v as f64 / 65535.0)))
            .collect(),
        _ => {
            let table: Vec<f64> = (0..256).map(|v| srgb_to_linear(v as f64 / 255.0)).collect();
            image
                .into_rgb8()
                .pixels()
                .map(|p| p.0.map(|v| table[v as usize]))
                .collect()
        }
    };
    if texels.iter().flatten().any(|v| !v.is_finite()) {
        return Err("contains NaN or infinite values".into());
    }
    Ok((w, h, texels))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn srgb_decoding_hits_its_ends_and_knee() {
        assert_eq!(srgb_to_linear(0.0), 0.0);
        assert!((srgb_to_linear(1.0) - 1.0).abs() < 1e-15);
        // 50 % sRGB grey is 21.4 % linear.
        assert!((srgb_to_linear(0.5) - 0.214_041).abs() < 1e-6);
    }

    #[test]
    fn sizes_are_checked_before_reading() {
        assert!(check_size(16384, 8192).is_ok());
        assert!(check_size(16385, 8192)
            .unwrap_err()
            .contains("refused before reading"));
        assert!(check_size(0, 4).unwrap_err().contains("empty"));
        assert!(check_data_window([0, 0, 999_999, 999_999]).is_err());
        assert!(check_data_window([5, 0, 4, 3])
            .unwrap_err()
            .contains("max below its min"));
        assert!(check_data_window([-2, -3, 1, 0]).is_ok());
    }
}
