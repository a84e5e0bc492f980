//! `nimbus compare A.exr B.exr`: per-channel error of image A against reference B.
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
use clap::Args;
use serde::Serialize;
use std::path::{Path, PathBuf};

/// Largest finite half float; values are clamped to ±this before comparing.
pub const CLAMP: f32 = 65504.0;
/// Added to b² in the relative MSE denominator.
pub const REL_EPSILON: f64 = 0.01;

#[derive(Args, Debug)]
pub struct CompareArgs {
    /// The image to evaluate.
    pub a: PathBuf,
    /// The reference image (the denominator of the relative MSE).
    pub b: PathBuf,
    /// Print JSON instead of a table.
    #[arg(long)]
    pub json: bool,
}

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

#[derive(Serialize, Debug, Clone)]
pub struct Comparison {
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

/// Finds channel `name` among an image's channels: the exact name, else a unique
/// `<layer>.name` (EXR layers, e.g. `rgba.R` or `beauty.R`).
pub(crate) fn find<'a>(
    path: &Path,
    chans: &'a [(String, Vec<f32>)],
    name: &str,
) -> Result<&'a [f32]> {
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
                path.display(),
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
                path.display(),
                names.join(", ")
            )
        }
    }
}

/// Compares image `a` against reference `b`.
pub fn compare_files(a: &Path, b: &Path) -> Result<Comparison> {
    let (wa, ha, ca) = read_all_channels(a).map_err(anyhow::Error::msg)?;
    let (wb, hb, cb) = read_all_channels(b).map_err(anyhow::Error::msg)?;
    if (wa, ha) != (wb, hb) {
        bail!(
            "the images differ in size: {} is {wa}x{ha}, {} is {wb}x{hb}",
            a.display(),
            b.display()
        );
    }
    let mut channels = Vec::new();
    for name in ["R", "G", "B"] {
        let (x, y) = (find(a, &ca, name)?, find(b, &cb, name)?);
        channels.push(channel_error(name, x, y));
    }
    if let (Ok(x), Ok(y)) = (find(a, &ca, "A"), find(b, &cb, "A")) {
        channels.push(channel_error("A", x, y));
    }
    let rgb = &channels[..3];
    let avg = |f: fn(&ChannelError) -> f64| rgb.iter().map(f).sum::<f64>() / 3.0;
    let rgb = ChannelError {
        channel: "RGB".into(),
        mse: avg(|c| c.mse),
        relmse: avg(|c| c.relmse),
        rmse: avg(|c| c.rmse),
        mean_a: avg(|c| c.mean_a),
        mean_b: avg(|c| c.mean_b),
        nonfinite_a: rgb.iter().map(|c| c.nonfinite_a).sum(),
        nonfinite_b: rgb.iter().map(|c| c.nonfinite_b).sum(),
    };
    Ok(Comparison {
        a: a.display().to_string(),
        b: b.display().to_string(),
        width: wa,
        height: ha,
        clamp: CLAMP,
        relmse_epsilon: REL_EPSILON,
        channels,
        rgb,
    })
}

pub fn run(args: CompareArgs) -> Result<()> {
    let c = compare_files(&args.a, &args.b)?;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&c)?);
        return Ok(());
    }
    println!(
        "{} vs reference {} ({}x{}, values clamped to ±{}, relMSE = mean (a-b)^2/(b^2+{}))",
        c.a, c.b, c.width, c.height, c.clamp, c.relmse_epsilon
    );
    println!(
        "{:<8} {:>13} {:>13} {:>13} {:>13} {:>13}",
        "channel", "MSE", "relMSE", "RMSE", "mean A", "mean B"
    );
    for ch in c.channels.iter().chain(std::iter::once(&c.rgb)) {
        println!(
            "{:<8} {:>13.6e} {:>13.6e} {:>13.6e} {:>13.6e} {:>13.6e}",
            ch.channel, ch.mse, ch.relmse, ch.rmse, ch.mean_a, ch.mean_b
        );
    }
    let nonfinite = c.rgb.nonfinite_a + c.rgb.nonfinite_b;
    if nonfinite > 0 {
        eprintln!(
            "nimbus: warning: {} NaN/infinite values in {}, {} in {} (counted as ±{})",
            c.rgb.nonfinite_a, c.a, c.rgb.nonfinite_b, c.b, c.clamp
        );
    }
    Ok(())
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
}
