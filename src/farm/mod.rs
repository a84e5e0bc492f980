//! Frames and tiles as tasks on the schedulers studios already run: a job description
//! (`job.json`: the stage, the output pattern, the frames, the tile count and the render
//! flags) and the scheduler's files generated from it ([`slurm`], [`openjd`]). Every task
//! runs `nimbus farm task --job job.json …`, which renders one tile of one frame with
//! `render --tile I/N --skip-complete` (idempotent: a valid output is left alone; files
//! appear only by atomic rename), and every frame's merge runs `nimbus farm merge
//! --job job.json …`, which checks the tiles itself and assembles them.
//!
//! Paths never pass through a shell unquoted: the scheduler scripts hold only the
//! quoted paths of `nimbus` and of the job description, and the render flags travel in
//! the JSON.

pub mod openjd;
pub mod slurm;

use crate::output::products::frame_path;
use crate::render::tiles::Tile;
use anyhow::{bail, Context, Result};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// A farm job: what every task needs to know.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FarmJob {
    /// The `nimbus` executable the tasks run (absolute).
    pub nimbus: PathBuf,
    /// The stage (absolute).
    pub stage: PathBuf,
    /// The output pattern (absolute): a run of `#` becomes the frame number.
    pub output: PathBuf,
    pub first_frame: i64,
    pub last_frame: i64,
    /// Tiles per frame (1: whole frames, still merged from their one tile).
    pub tiles: u32,
    /// Further `nimbus render` flags, passed as they are.
    pub render_args: Vec<String>,
}

impl FarmJob {
    /// A job of `stage` → `output` over `first..=last` with `tiles` tiles per frame; paths
    /// made absolute against the working directory; an output name without `#` gets
    /// `.####` before its extension (every frame needs its own file).
    pub fn new(
        stage: &Path,
        output: &Path,
        (first, last): (i64, i64),
        tiles: u32,
        render_args: Vec<String>,
    ) -> Result<FarmJob> {
        if tiles == 0 {
            bail!("--tiles must be at least 1");
        }
        if first > last {
            bail!("the frame range {first}-{last} is empty");
        }
        if !stage.is_file() {
            bail!("{}: stage file not found", stage.display());
        }
        let cwd = std::env::current_dir().context("no working directory")?;
        let absolute = |p: &Path| {
            if p.is_absolute() {
                p.to_path_buf()
            } else {
                cwd.join(p)
            }
        };
        let mut output = absolute(output);
        let name = output
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        if name.is_empty() {
            bail!("{}: the output needs a file name", output.display());
        }
        if !name.contains('#') {
            output = output.with_file_name(match name.rfind('.').filter(|&i| i > 0) {
                Some(dot) => format!("{}.####{}", &name[..dot], &name[dot..]),
                None => format!("{name}.####"),
            });
        }
        for reserved in [
            "-o", "--output", "--frame", "--frames", "--tile", "--region",
        ] {
            if render_args
                .iter()
                .any(|a| a == reserved || a.starts_with(&format!("{reserved}=")))
            {
                bail!("{reserved} is set by the farm job itself; drop it from the render flags");
            }
        }
        if render_args
            .iter()
            .any(|a| a == "--checkpoint" || a.starts_with("--checkpoint="))
        {
            bail!("--checkpoint would write partial images onto a task's final path; split the frame into more tiles instead");
        }
        if render_args
            .iter()
            .any(|a| a == "--deep" || a.starts_with("--deep="))
        {
            bail!("--deep: `nimbus merge` does not assemble deep tiles yet; render deep images on one machine (nimbus render --deep)");
        }
        let nimbus = std::env::current_exe().context("cannot find the nimbus executable")?;
        Ok(FarmJob {
            nimbus,
            stage: absolute(stage),
            output,
            first_frame: first,
            last_frame: last,
            tiles,
            render_args,
        })
    }

    pub fn frames(&self) -> u32 {
        (self.last_frame - self.first_frame + 1) as u32
    }

    /// Render tasks: frames × tiles.
    pub fn task_count(&self) -> u32 {
        self.frames() * self.tiles
    }

    /// The frame and tile of render task `index` (frame-major).
    pub fn task(&self, index: u32) -> Result<(i64, Tile)> {
        if index >= self.task_count() {
            bail!(
                "task {index} is out of range: the job has {} tasks (0..{})",
                self.task_count(),
                self.task_count() - 1
            );
        }
        Ok((
            self.first_frame + (index / self.tiles) as i64,
            Tile {
                index: index % self.tiles,
                count: self.tiles,
            },
        ))
    }

    /// Frame `index` of the merge step (0 = the first frame).
    pub fn frame(&self, index: u32) -> Result<i64> {
        if index >= self.frames() {
            bail!(
                "frame index {index} is out of range: the job has {} frames",
                self.frames()
            );
        }
        Ok(self.first_frame + index as i64)
    }

    /// The `nimbus render` arguments of `frame`'s `tile`.
    pub fn render_command(&self, frame: i64, tile: Tile) -> Vec<String> {
        let mut args = vec![
            "render".to_string(),
            self.stage.display().to_string(),
            "-o".into(),
            self.output.display().to_string(),
            "--frame".into(),
            frame.to_string(),
            "--tile".into(),
            format!("{}/{}", tile.index, tile.count),
            "--skip-complete".into(),
        ];
        args.extend(self.render_args.iter().cloned());
        args
    }

    /// The frame's file, and its tiles' files.
    pub fn frame_files(&self, frame: i64) -> (PathBuf, Vec<PathBuf>) {
        let out = frame_path(&self.output, frame);
        let name = out
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        let tiles = (0..self.tiles)
            .map(|index| {
                out.with_file_name(
                    Tile {
                        index,
                        count: self.tiles,
                    }
                    .file_name(&name),
                )
            })
            .collect();
        (out, tiles)
    }

    /// Writes the job description `dir/job.json` (atomically) and returns its path.
    pub fn write(&self, dir: &Path) -> Result<PathBuf> {
        std::fs::create_dir_all(dir.join("logs"))
            .with_context(|| format!("cannot create the job folder {}", dir.display()))?;
        let path = dir.join("job.json");
        crate::output::products::write_json(&path, self)?;
        Ok(path)
    }

    /// Reads a job description.
    pub fn read(path: &Path) -> Result<FarmJob> {
        let text = std::fs::read_to_string(path)
            .with_context(|| format!("{}: cannot read the job description", path.display()))?;
        serde_json::from_str(&text)
            .with_context(|| format!("{}: not a Nimbus farm job description", path.display()))
    }
}

/// `s` as one POSIX shell word: single-quoted, with every `'` written `'\''`, so
/// spaces, quotes, `$`, backquotes and globs are taken literally.
pub fn shell_quote(s: &str) -> String {
    format!("'{}'", s.replace('\'', r"'\''"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shell_quoting_is_literal() {
        assert_eq!(shell_quote("a b"), "'a b'");
        assert_eq!(shell_quote("it's $HOME `x`"), r"'it'\''s $HOME `x`'");
    }

    #[test]
    fn tasks_are_frame_major() {
        let job = FarmJob {
            nimbus: "/n".into(),
            stage: "/s.usda".into(),
            output: "/o.####.exr".into(),
            first_frame: 10,
            last_frame: 11,
            tiles: 4,
            render_args: vec![],
        };
        assert_eq!(job.task_count(), 8);
        assert_eq!(job.task(5).unwrap(), (11, Tile { index: 1, count: 4 }));
        assert!(job.task(8).is_err());
        let (out, tiles) = job.frame_files(11);
        assert_eq!(out, PathBuf::from("/o.0011.exr"));
        assert_eq!(tiles[3], PathBuf::from("/o.0011.tile3.exr"));
    }
}
