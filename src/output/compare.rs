//! Per-channel error of an image A against a reference B: what `nimbus compare` prints,
//! `nimbus.compare` returns and `nimbus bench error` measures — one implementation.
//!
//! Metrics, computed in f64 over all pixels after clamping each value to ±65504 (the
//! largest half float; the supplement of Kutz et al. 2017 clamps this way so a few
//! fireflies or infinities cannot dominate the mean):
//!
//! - `mse`    = mean (a − b)²
//! - `rmse`   = √mse
//! - `relmse` = mean (a − b)² / (b² + 0.01), **B is the reference** (the 0.01 keeps black
//!   reference pixels from dividing by zero; swapping A and B changes this number)
//! - `mean_a`, `mean_b` = channel means
//!
//! NaN counts as +65504 (Rust's `f32::min` returns the non-NaN side), so a NaN pixel shows
//! up as a large error instead of poisoning the mean; `nonfinite_a/b` report how many.

use crate::output::exr::read_all_channels;
use anyhow::{bail, Result};
use serde::Serialize;
use std::path::Path;

/// Largest finite half float; values are clamped to ±this before comparing.
pub const CLAMP: f32 = 65504.0;
/// Added to b² in the relative MSE denominator.
pub const REL_EPSILON: f64 = 0.01;

#[derive(Serialize, Debug, Clone, PartialEq)]
pub struct ChannelError {
    pub channel: String,
    pub mse: f64,
    pub relmse: f64,
    pub rmse: f64,
    pub mean_a: f64,
    pub mean_b: f64,
    pub nonfinite_a: u64,
    pub nonfinite_b: u64,
}

#[derive(Serialize, Debug, Clone, PartialEq)]
pub struct Comparison {
    /// The images' names: their paths, or what the caller calls them.
    pub a: String,
    pub b: String,
    pub width: usize,
    pub height: usize,
    pub clamp: f32,
    pub relmse_epsilon: f64,
    /// R, G, B, then A when both images have it.
    pub channels: Vec<ChannelError>,
    /// Mean over R, G, B of each metric (the single number `bench error` plots).
    pub rgb: ChannelError,
}

/// An image to compare: named channels of `width` × `height` values, row-major, as read
/// from an EXR or handed over by a caller (a Python array).
#[derive(Debug, Clone)]
pub struct Image {
    /// What error messages call it (the file's path).
    pub name: String,
    pub width: usize,
    pub height: usize,
    pub channels: Vec<(String, Vec<f32>)>,
}

impl Image {
    /// Every channel of an EXR (layers as `layer.channel`).
    pub fn read(path: &Path) -> Result<Image> {
        let (width, height, channels) = read_all_channels(path).map_err(anyhow::Error::msg)?;
        Ok(Image {
            name: path.display().to_string(),
            width,
            height,
            channels,
        })
    }

    /// Channel `name`: the exact name, else a unique `<layer>.name` (EXR layers, e.g.
    /// `rgba.R` or `beauty.R`).
    pub fn channel(&self, name: &str) -> Result<&[f32]> {
        let chans = &self.channels;
        if let Some(c) = chans.iter().find(|c| c.0 == name) {
            return Ok(&c.1);
        }
        let suffix = format!(".{name}");
        let hits: Vec<_> = chans.iter().filter(|c| c.0.ends_with(&suffix)).collect();
        match hits.as_slice() {
            [one] => Ok(&one.1),
            [] => {
                let names: Vec<_> = chans.iter().map(|c| c.0.as_str()).collect();
                bail!(
                    "{}: no channel {name} (channels: {})",
                    self.name,
                    if names.is_empty() {
                        "none".to_string()
                    } else {
                        names.join(", ")
                    }
                )
            }
            many => {
                let names: Vec<_> = many.iter().map(|c| c.0.as_str()).collect();
                bail!(
                    "{}: channel {name} is ambiguous: {}",
                    self.name,
                    names.join(", ")
                )
            }
        }
    }
}

/// Error metrics of one channel, `a` against reference `b` (same length).
pub fn channel_error(name: &str, a: &[f32], b: &[f32]) -> ChannelError {
    debug_assert_eq!(a.len(), b.len());
    let clamp = |v: f32| v.min(CLAMP).max(-CLAMP) as f64;
    let (mut se, mut rel, mut sa, mut sb) = (0f64, 0f64, 0f64, 0f64);
    let (mut na, mut nb) = (0u64, 0u64);
    for (&x, &y) in a.iter().zip(b) {
        na += !x.is_finite() as u64;
        nb += !y.is_finite() as u64;
        let (x, y) = (clamp(x), clamp(y));
        let d2 = (x - y) * (x - y);
        se += d2;
        rel += d2 / (y * y + REL_EPSILON);
        sa += x;
        sb += y;
    }
    let n = a.len().max(1) as f64;
    ChannelError {
        channel: name.to_string(),
        mse: se / n,
        relmse: rel / n,
        rmse: (se / n).sqrt(),
        mean_a: sa / n,
        mean_b: sb / n,
        nonfinite_a: na,
        nonfinite_b: nb,
    }
}

/// Each metric's mean over the channels given (R, G, B), the non-finite counts summed.
pub fn rgb_mean(rgb: &[ChannelError]) -> ChannelError {
    let n = rgb.len() as f64;
    let avg = |f: fn(&ChannelError) -> f64| rgb.iter().map(f).sum::<f64>() / n;
    ChannelError {
        channel: "RGB".into(),
        mse: avg(|c| c.mse),
        relmse: avg(|c| c.relmse),
        rmse: avg(|c| c.rmse),
        mean_a: avg(|c| c.mean_a),
        mean_b: avg(|c| c.mean_b),
        nonfinite_a: rgb.iter().map(|c| c.nonfinite_a).sum(),
        nonfinite_b: rgb.iter().map(|c| c.nonfinite_b).sum(),
    }
}

/// Compares image `a` against reference `b`: R, G and B (each image must have them),
/// and A when both have it.
pub fn compare(a: &Image, b: &Image) -> Result<Comparison> {
    if (a.width, a.height) != (b.width, b.height) {
        bail!(
            "the images differ in size: {} is {}x{}, {} is {}x{}",
            a.name,
            a.width,
            a.height,
            b.name,
            b.width,
            b.height
        );
    }
    let mut channels = Vec::new();
    for name in ["R", "G", "B"] {
        let (x, y) = (a.channel(name)?, b.channel(name)?);
        channels.push(channel_error(name, x, y));
    }
    if let (Ok(x), Ok(y)) = (a.channel("A"), b.channel("A")) {
        channels.push(channel_error("A", x, y));
    }
    let rgb = rgb_mean(&channels[..3]);
    Ok(Comparison {
        a: a.name.clone(),
        b: b.name.clone(),
        width: a.width,
        height: a.height,
        clamp: CLAMP,
        relmse_epsilon: REL_EPSILON,
        channels,
        rgb,
    })
}

/// Compares the EXR `a` against the reference EXR `b`.
pub fn compare_files(a: &Path, b: &Path) -> Result<Comparison> {
    compare(&Image::read(a)?, &Image::read(b)?)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn known_errors() {
        let b = [0.0f32, 1.0, 2.0, 3.0];
        let a = [0.1f32, 1.0, 2.0, 2.0];
        let e = channel_error("R", &a, &b);
        let d0 = (0.1f32 as f64).powi(2);
        assert!((e.mse - (d0 + 1.0) / 4.0).abs() < 1e-12);
        assert!((e.relmse - (d0 / 0.01 + 1.0 / 9.01) / 4.0).abs() < 1e-9);
        assert!((e.rmse - e.mse.sqrt()).abs() < 1e-15);
        assert!((e.mean_b - 1.5).abs() < 1e-12);
    }

    #[test]
    fn clamps_and_counts_nonfinite() {
        let e = channel_error("R", &[f32::NAN, f32::INFINITY, 1e9], &[0.0, 0.0, 0.0]);
        assert_eq!(e.nonfinite_a, 2);
        assert!((e.mse - 65504f64 * 65504.0).abs() < 1e-3);
    }

    fn image(name: &str, chans: &[(&str, f32)]) -> Image {
        Image {
            name: name.into(),
            width: 2,
            height: 1,
            channels: chans
                .iter()
                .map(|&(n, v)| (n.to_string(), vec![v; 2]))
                .collect(),
        }
    }

    #[test]
    fn channels_are_found_in_layers_and_alpha_only_when_both_have_it() {
        let a = image("a", &[("rgba.R", 2.0), ("rgba.G", 1.0), ("rgba.B", 1.0)]);
        let b = image("b", &[("R", 1.0), ("G", 1.0), ("B", 1.0), ("A", 1.0)]);
        let c = compare(&a, &b).unwrap();
        let names: Vec<_> = c.channels.iter().map(|e| e.channel.as_str()).collect();
        assert_eq!(names, ["R", "G", "B"]);
        assert_eq!(c.rgb.mse, 1.0 / 3.0);
        let ambiguous = image("x", &[("a.R", 0.0), ("b.R", 0.0)]);
        let e = compare(&ambiguous, &b).unwrap_err().to_string();
        assert!(e.contains("x: channel R is ambiguous: a.R, b.R"), "{e}");
        let e = compare(&b, &image("y", &[("R", 1.0)]))
            .unwrap_err()
            .to_string();
        assert!(e.contains("y: no channel G (channels: R)"), "{e}");
    }
}
