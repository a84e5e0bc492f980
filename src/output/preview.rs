//! The preview PNG (`--preview`, a RenderProduct's `nimbus:previewName`): the beauty
//! tone-mapped for a screen, so a user can look at a render without an EXR viewer.
//! Reinhard on luminance (hue kept; no exposure to choose), then the sRGB transfer
//! curve, 8 bits. Opaque: the beauty already holds what the camera sees behind the
//! volume (the dome), which an alpha channel would hide in most viewers.

use super::{write_atomically, OutputError};
use crate::color::luminance;
use crate::render::film::{Aov, Film};
use std::path::Path;

/// Writes `film`'s beauty as an 8-bit sRGB RGB PNG, atomically.
pub fn write_preview(path: &Path, film: &Film) -> Result<(), OutputError> {
    let rgb = [Aov::R, Aov::G, Aov::B].map(|c| film.channel(c));
    write_preview_rgb(path, (film.width, film.height), [&rgb[0], &rgb[1], &rgb[2]])
}

/// Writes the `width` × `height` image `rgb` (three row-major channels, e.g. a
/// denoised beauty) as an 8-bit sRGB RGB PNG, atomically.
pub fn write_preview_rgb(
    path: &Path,
    (width, height): (u32, u32),
    rgb: [&[f32]; 3],
) -> Result<(), OutputError> {
    let rgba = tone_map_rgb(rgb);
    write_atomically(path, |f| {
        let mut encoder = png::Encoder::new(f, width, height);
        encoder.set_color(png::ColorType::Rgb);
        encoder.set_depth(png::BitDepth::Eight);
        encoder.set_source_srgb(png::SrgbRenderingIntent::Perceptual);
        let mut writer = encoder.write_header().map_err(|e| e.to_string())?;
        writer.write_image_data(&rgba).map_err(|e| e.to_string())?;
        writer.finish().map_err(|e| e.to_string())
    })
}

/// The film's pixels as 8-bit sRGB RGB, row-major, y down.
pub fn tone_map(film: &Film) -> Vec<u8> {
    let rgb = [Aov::R, Aov::G, Aov::B].map(|c| film.channel(c));
    tone_map_rgb([&rgb[0], &rgb[1], &rgb[2]])
}

/// Three row-major channels as 8-bit sRGB RGB.
fn tone_map_rgb([r, g, b]: [&[f32]; 3]) -> Vec<u8> {
    let mut out = Vec::with_capacity(r.len() * 3);
    for i in 0..r.len() {
        let c = [r[i] as f64, g[i] as f64, b[i] as f64].map(|v| {
            if v.is_finite() {
                v.max(0.0)
            } else {
                0.0
            }
        });
        let y = luminance(c);
        // Reinhard on luminance: L/(1+L) keeps the ratios between channels.
        let scale = if y > 0.0 { 1.0 / (1.0 + y) } else { 1.0 };
        for v in c {
            out.push(encode_srgb(v * scale));
        }
    }
    out
}

/// Linear [0, 1] → 8-bit sRGB.
fn encode_srgb(v: f64) -> u8 {
    let v = v.clamp(0.0, 1.0);
    let s = if v <= 0.003_130_8 {
        12.92 * v
    } else {
        1.055 * v.powf(1.0 / 2.4) - 0.055
    };
    (s * 255.0 + 0.5) as u8
}

#[cfg(test)]
mod tests {
    use super::encode_srgb;

    #[test]
    fn srgb_encoding_matches_the_standard_curve() {
        assert_eq!(encode_srgb(0.0), 0);
        assert_eq!(encode_srgb(1.0), 255);
        // 0.5 linear is 0.7354 in sRGB: 188 of 255.
        assert_eq!(encode_srgb(0.5), 188);
        // The linear toe: 0.002 → 12.92·0.002·255 = 6.6.
        assert_eq!(encode_srgb(0.002), 7);
    }
}
