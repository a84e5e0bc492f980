//! `nimbus compare A.exr B.exr`: per-channel error of image A against reference B
//! ([`crate::output::compare`] computes it; this prints it as a table or JSON).

use crate::output::compare::compare_files;
use anyhow::Result;
use clap::Args;
use std::path::PathBuf;

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
