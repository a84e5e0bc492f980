//! `nimbus merge OUT TILES...`: assembles the tiles of a frame (`render --tile I/N`)
//! into the frame, or their stats JSONs into one (when OUT is a `.json`).

use crate::output::merge::merge;
use anyhow::Result;
use clap::Args;
use std::path::PathBuf;

#[derive(Args, Debug)]
pub struct MergeArgs {
    /// The frame to write (an EXR), or the merged stats (a .json).
    pub output: PathBuf,
    /// The tiles: every tile of the frame once (`out.tile*.exr`, or their stats).
    #[arg(required = true)]
    pub tiles: Vec<PathBuf>,
}

pub fn run(args: MergeArgs) -> Result<()> {
    let m = merge(&args.output, &args.tiles)?;
    eprintln!(
        "nimbus: wrote {} ({}x{}, {} tiles{})",
        args.output.display(),
        m.width,
        m.height,
        m.tiles,
        m.denoise_seconds
            .map_or(String::new(), |s| format!(", denoised in {s:.2} s"))
    );
    Ok(())
}
