//! `nimbus merge`: the tiles of a frame (`render --tile I/N`) assembled into the frame,
//! and their stats JSONs into one. Nothing is written unless every tile is there once,
//! complete (all the samples asked for) and from the same stage and settings (the
//! settings hash); otherwise the error lists the tile indices to re-run.

use super::denoise::denoise_channels;
use super::exr::{write_channels, Denoise, ExrMetadata, FarmMetadata, MAX_READ_BYTES};
use super::products::write_json;
use crate::render::film::Region;
use crate::render::tiles::Tile;
use ::exr::prelude::*;
use anyhow::{anyhow, bail, Context, Result};
use serde_json::{Map, Value};
use std::path::{Path, PathBuf};

/// What is wrong with a set of tiles, and which to re-run: collected over every tile so
/// one error lists everything, then turned into that error (or nothing).
struct Verdict {
    count: u32,
    problems: Vec<String>,
    rerun: Vec<u32>,
}

impl Verdict {
    fn new(count: u32) -> Verdict {
        Verdict {
            count,
            problems: Vec::new(),
            rerun: Vec::new(),
        }
    }

    /// A problem; `rerun` names the tile that fixes it by being rendered again.
    fn problem(&mut self, message: String, rerun: Option<u32>) {
        self.problems.push(message);
        self.rerun.extend(rerun);
    }

    /// Ok when there was no problem and every tile `present` says was seen is there;
    /// else the error naming `out`, every problem and the tiles to re-run.
    fn finish(mut self, out: &Path, present: impl Fn(usize) -> bool) -> Result<()> {
        for i in 0..self.count {
            if !present(i as usize) && !self.rerun.contains(&i) {
                self.problem(format!("tile {i}/{} is missing", self.count), Some(i));
            }
        }
        if self.problems.is_empty() {
            return Ok(());
        }
        self.rerun.sort_unstable();
        self.rerun.dedup();
        let list: Vec<String> = self.rerun.iter().map(|i| i.to_string()).collect();
        bail!(
            "{} was not written: {}{}",
            out.display(),
            self.problems.join("; "),
            if list.is_empty() {
                String::new()
            } else {
                format!("; re-run tiles {} (of {})", list.join(", "), self.count)
            }
        );
    }
}

/// Most tiles `merge` assembles into a frame (64 × 64-pixel tiles of a 16k × 16k
/// frame): a tile's header names the count, and the list of tiles is allocated from it.
const MAX_TILES: u32 = 1 << 16;

/// One tile read back: its header facts and its channels.
struct TileImage {
    path: PathBuf,
    tile: Tile,
    full: (u32, u32),
    window: Region,
    hash: String,
    spp: i32,
    spp_cap: Option<i32>,
    channels: Vec<(String, Vec<f32>)>,
    meta: ExrMetadata,
}

/// What `merge` did.
pub struct Merged {
    pub tiles: u32,
    pub width: u32,
    pub height: u32,
    /// Seconds the merged frame's denoising took (`None`: not asked for).
    pub denoise_seconds: Option<f64>,
}

/// Merges tile EXRs (or, when the output is a `.json`, tile stats) into `out`.
pub fn merge(out: &Path, inputs: &[PathBuf]) -> Result<Merged> {
    if inputs.is_empty() {
        bail!("no tiles to merge");
    }
    if inputs.iter().any(|p| p == out) {
        bail!("{} is both the output and a tile", out.display());
    }
    super::check_writable(out)?;
    let is_json = out
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("json"));
    if is_json {
        merge_stats(out, inputs, None)
    } else {
        merge_images(out, inputs)
    }
}

/// Merges a frame's tile stats into `out` as [`merge`] does (the same checks), and
/// records the merged frame's denoising: `denoise_seconds` is the time the merge of
/// the frame's EXR tiles took to denoise it ([`Merged::denoise_seconds`]), written as
/// the merged stats' `denoise_seconds` when the tiles' `denoise` says their merge
/// denoises (`farm merge` merges a frame's stats after its image).
pub fn merge_frame_stats(
    out: &Path,
    inputs: &[PathBuf],
    denoise_seconds: Option<f64>,
) -> Result<Merged> {
    if inputs.is_empty() {
        bail!("no tile stats to merge");
    }
    if inputs.iter().any(|p| p == out) {
        bail!("{} is both the output and a tile's stats", out.display());
    }
    super::check_writable(out)?;
    merge_stats(out, inputs, denoise_seconds)
}

fn merge_images(out: &Path, inputs: &[PathBuf]) -> Result<Merged> {
    let tiles = inputs
        .iter()
        .map(|p| read_tile(p))
        .collect::<Result<Vec<_>>>()?;
    let first = &tiles[0];
    let count = first.tile.count;
    let (w, h) = first.full;
    // The tile list and the frame are allocated from what tile 0's header claims:
    // refuse sizes no real tile set has before allocating them.
    if count > MAX_TILES {
        bail!(
            "{}: nimbus:tile says {}/{count}: more tiles than merge assembles (at most {MAX_TILES})",
            first.path.display(),
            first.tile.index
        );
    }
    let frame_bytes = w as u64 * h as u64 * first.channels.len().max(1) as u64 * 4;
    if frame_bytes > MAX_READ_BYTES
        || crate::render::session::available_memory_bytes().is_some_and(|a| frame_bytes > a)
    {
        bail!(
            "{}: nimbus:fullResolution {w}x{h} with {} channels needs {:.1} GiB for the frame, more than merge may allocate",
            first.path.display(),
            first.channels.len(),
            frame_bytes as f64 / (1u64 << 30) as f64
        );
    }
    let mut verdict = Verdict::new(count);
    let mut seen: Vec<Option<&TileImage>> = vec![None; count as usize];
    for t in &tiles {
        let name = t.path.display();
        if t.tile.count != count || t.full != first.full {
            verdict.problem(
                format!(
                    "{name} is tile {}/{} of a {}x{} frame, {} is {}/{count} of {w}x{h}",
                    t.tile.index,
                    t.tile.count,
                    t.full.0,
                    t.full.1,
                    first.path.display(),
                    first.tile.index
                ),
                None,
            );
            continue;
        }
        if t.hash != first.hash {
            verdict.problem(format!(
                "{name} comes from other settings or another stage (settings hash {} against {} of {})",
                t.hash,
                first.hash,
                first.path.display()
            ), Some(t.tile.index));
            continue;
        }
        let expected = t.tile.region(w, h).map_err(|e| anyhow!("{name}: {e}"))?;
        if t.window != expected {
            verdict.problem(
                format!(
                    "{name}: data window {:?} is not tile {}/{count}'s {:?}",
                    t.window, t.tile.index, expected
                ),
                Some(t.tile.index),
            );
            continue;
        }
        if t.spp_cap.is_none_or(|cap| t.spp < cap) {
            verdict.problem(
                format!(
                    "{name} is partial: {} samples per pixel of {}",
                    t.spp,
                    t.spp_cap
                        .map_or("a time limit".to_string(), |c| c.to_string())
                ),
                Some(t.tile.index),
            );
            continue;
        }
        if t.channels
            .iter()
            .map(|c| &c.0)
            .ne(first.channels.iter().map(|c| &c.0))
        {
            verdict.problem(
                format!("{name} has other channels than {}", first.path.display()),
                Some(t.tile.index),
            );
            continue;
        }
        match &mut seen[t.tile.index as usize] {
            Some(other) => verdict.problem(
                format!(
                    "tile {} is given twice: {} and {name}",
                    t.tile.index,
                    other.path.display()
                ),
                None,
            ),
            slot => *slot = Some(t),
        }
    }
    verdict.finish(out, |i| seen[i].is_some())?;
    let mut channels: Vec<(String, Vec<f32>)> = first
        .channels
        .iter()
        .map(|(n, _)| (n.clone(), vec![0.0; w as usize * h as usize]))
        .collect();
    let mut seconds = 0.0;
    for t in seen.iter().flatten() {
        let r = t.window;
        for ((_, full), (_, part)) in channels.iter_mut().zip(&t.channels) {
            for y in r.y0..r.y1 {
                let src = ((y - r.y0) * r.width()) as usize;
                let dst = (y * w + r.x0) as usize;
                full[dst..dst + r.width() as usize]
                    .copy_from_slice(&part[src..src + r.width() as usize]);
            }
        }
        seconds += t.meta.render_seconds;
    }
    let mut meta = ExrMetadata {
        render_seconds: seconds,
        farm: first.meta.farm.map(|f| FarmMetadata { tile: None, ..f }),
        ..first.meta.clone()
    };
    // The frame is denoised whole, never tile by tile (the denoiser looks across
    // tile borders): as `render` denoises it on one machine, from the same channels.
    let mut denoise_seconds = None;
    if first.meta.denoise == Denoise::ByMerge {
        let d = denoise_channels(w as usize, h as usize, &mut channels)
            .map_err(|e| anyhow!("{} was not written: {e}", out.display()))?;
        denoise_seconds = Some(d.seconds);
        meta.denoise = Denoise::Done;
    }
    write_channels(out, (w, h), Region::full(w, h), channels, &meta)?;
    Ok(Merged {
        tiles: count,
        width: w,
        height: h,
        denoise_seconds,
    })
}

/// Reads a tile EXR: the channels of its first layer, its data window and its
/// Nimbus attributes.
fn read_tile(path: &Path) -> Result<TileImage> {
    super::exr::check_exr_size(path).map_err(anyhow::Error::msg)?;
    let image = read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .first_valid_layer()
        .all_attributes()
        .from_file(path)
        .map_err(|e| anyhow!("{}: cannot read as EXR: {e}", path.display()))?;
    let layer = &image.layer_data;
    let attrs = &layer.attributes.other;
    let text = |k: &str| match attrs.get(&Text::from(k)) {
        Some(AttributeValue::Text(t)) => Some(t.to_string()),
        _ => None,
    };
    let int = |k: &str| match attrs.get(&Text::from(k)) {
        Some(AttributeValue::I32(i)) => Some(*i),
        _ => None,
    };
    let not_tile = || {
        anyhow!(
            "{}: not a Nimbus tile (no nimbus:tile attribute; render it with --tile I/N)",
            path.display()
        )
    };
    let tile = Tile::parse(&text("nimbus:tile").ok_or_else(not_tile)?)
        .map_err(|e| anyhow!("{}: nimbus:tile: {e}", path.display()))?;
    let full = match attrs.get(&Text::from("nimbus:fullResolution")) {
        Some(AttributeValue::IntVec2(v)) if v.0 > 0 && v.1 > 0 => (v.0 as u32, v.1 as u32),
        _ => bail!("{}: no valid nimbus:fullResolution", path.display()),
    };
    let pos = layer.attributes.layer_position;
    let (lw, lh) = (layer.size.width() as u32, layer.size.height() as u32);
    if pos.0 < 0 || pos.1 < 0 {
        bail!("{}: data window starts at negative pixels", path.display());
    }
    let window = Region {
        x0: pos.0 as u32,
        y0: pos.1 as u32,
        x1: pos.0 as u32 + lw,
        y1: pos.1 as u32 + lh,
    };
    let channels = layer
        .channel_data
        .list
        .iter()
        .map(|c| (c.name.to_string(), c.sample_data.values_as_f32().collect()))
        .collect();
    let hash = text("nimbus:settingsHash")
        .ok_or_else(|| anyhow!("{}: no nimbus:settingsHash", path.display()))?;
    let seed = text("nimbus:seed")
        .and_then(|s| s.parse().ok())
        .ok_or_else(|| anyhow!("{}: no nimbus:seed", path.display()))?;
    let spp = int("nimbus:spp").ok_or_else(|| anyhow!("{}: no nimbus:spp", path.display()))?;
    let spp_cap = int("nimbus:sppCap");
    let meta = ExrMetadata {
        stage: text("nimbus:stage").unwrap_or_default(),
        tracker: text("nimbus:tracker").unwrap_or_default(),
        scheme: text("nimbus:scheme").unwrap_or_default(),
        transmittance: text("nimbus:transmittance").unwrap_or_default(),
        spp: spp.max(0) as u32,
        render_seconds: match attrs.get(&Text::from("nimbus:renderSeconds")) {
            Some(AttributeValue::F32(s)) => *s as f64,
            _ => 0.0,
        },
        time: match attrs.get(&Text::from("nimbus:time")) {
            Some(AttributeValue::F64(t)) => *t,
            _ => f64::NAN,
        },
        product: text("nimbus:renderProduct"),
        denoise: Denoise::from_attribute(text("nimbus:denoise").as_deref()),
        farm: Some(FarmMetadata {
            seed,
            spp_cap: spp_cap.map(|c| c.max(0) as u32),
            settings_hash: u64::from_str_radix(&hash, 16).unwrap_or(0),
            tile: Some(tile),
        }),
    };
    Ok(TileImage {
        path: path.to_path_buf(),
        tile,
        full,
        window,
        hash,
        spp,
        spp_cap,
        channels,
        meta,
    })
}

/// Stats keys that add up over tiles (counts, and seconds of work).
const SUMMED: &[&str] = &[
    "density_lookups",
    "emission_lookups",
    "albedo_lookups",
    "real_collisions",
    "null_collisions",
    "cells_visited",
    "majorant_violations",
    "nonfinite_samples",
    "residual_lookups",
    "control_collisions",
    "render_seconds",
    "load_seconds",
    "wall_seconds",
    "lookup_seconds",
    "traversal_seconds",
    "other_tracker_seconds",
];

/// Stats keys whose merged value is the largest tile's.
const LARGEST: &[&str] = &["max_pass_seconds", "max_throughput_peak"];

/// Merges tile stats: counts and seconds summed, maxima kept, the mean throughput
/// weighted by pixels, the frame's size; the rest as in tile 0. The same checks as for
/// images (one stats file per tile, same settings hash, complete).
fn merge_stats(out: &Path, inputs: &[PathBuf], denoise_seconds: Option<f64>) -> Result<Merged> {
    let mut stats = Vec::new();
    for p in inputs {
        let text =
            std::fs::read_to_string(p).with_context(|| format!("{}: cannot read", p.display()))?;
        let v: Value =
            serde_json::from_str(&text).with_context(|| format!("{}: not JSON", p.display()))?;
        let Value::Object(map) = v else {
            bail!("{}: not a stats object", p.display());
        };
        let tile = map
            .get("tile")
            .and_then(Value::as_str)
            .ok_or_else(|| anyhow!("{}: not the stats of a tile (no \"tile\")", p.display()))
            .and_then(|t| Tile::parse(t).map_err(|e| anyhow!("{}: {e}", p.display())))?;
        stats.push((p, tile, map));
    }
    let (first_path, first_tile, first) = &stats[0];
    let count = first_tile.count;
    let hash = |m: &Map<String, Value>| m.get("settings_hash").cloned();
    let mut verdict = Verdict::new(count);
    let mut seen = vec![false; count as usize];
    for (p, t, m) in &stats {
        if t.count != count {
            verdict.problem(
                format!("{} is a tile of {}, not {count}", p.display(), t.count),
                None,
            );
        } else if hash(m) != hash(first) {
            verdict.problem(
                format!(
                    "{} comes from other settings than {}",
                    p.display(),
                    first_path.display()
                ),
                Some(t.index),
            );
        } else if m.get("samples_per_pixel") != m.get("spp_cap")
            || m.get("interrupted") == Some(&Value::Bool(true))
        {
            verdict.problem(format!("{} is partial", p.display()), Some(t.index));
        } else if std::mem::replace(&mut seen[t.index as usize], true) {
            verdict.problem(format!("tile {} is given twice", t.index), None);
        }
    }
    verdict.finish(out, |i| seen[i])?;
    let mut merged = first.clone();
    let num = |m: &Map<String, Value>, k: &str| m.get(k).and_then(Value::as_f64);
    let pixels =
        |m: &Map<String, Value>| num(m, "width").unwrap_or(0.0) * num(m, "height").unwrap_or(0.0);
    for &k in SUMMED {
        if first.get(k).is_some_and(|v| v.is_number()) {
            let all_int = stats
                .iter()
                .all(|(_, _, m)| m.get(k).is_some_and(|v| v.is_u64()));
            let sum: f64 = stats.iter().filter_map(|(_, _, m)| num(m, k)).sum();
            merged.insert(
                k.into(),
                if all_int {
                    Value::from(
                        stats
                            .iter()
                            .filter_map(|(_, _, m)| m.get(k).and_then(Value::as_u64))
                            .sum::<u64>(),
                    )
                } else {
                    Value::from(sum)
                },
            );
        }
    }
    for &k in LARGEST {
        if let Some(max) = stats
            .iter()
            .filter_map(|(_, _, m)| num(m, k))
            .reduce(f64::max)
        {
            merged.insert(k.into(), Value::from(max));
        }
    }
    let total: f64 = stats.iter().map(|(_, _, m)| pixels(m)).sum();
    if total > 0.0 {
        let mean: f64 = stats
            .iter()
            .map(|(_, _, m)| num(m, "max_throughput_mean").unwrap_or(0.0) * pixels(m))
            .sum::<f64>()
            / total;
        merged.insert("max_throughput_mean".into(), Value::from(mean));
    }
    let (w, h) = match first.get("full_resolution").and_then(Value::as_array) {
        Some(a) if a.len() == 2 => (
            a[0].as_u64().unwrap_or(0) as u32,
            a[1].as_u64().unwrap_or(0) as u32,
        ),
        _ => bail!("{}: no full_resolution", first_path.display()),
    };
    merged.insert("width".into(), Value::from(w));
    merged.insert("height".into(), Value::from(h));
    merged.insert("tile".into(), Value::Null);
    merged.insert("tiles_merged".into(), Value::from(count));
    // The tiles' `"merge"`: the merged image is denoised, by `merge` of the EXRs. Its
    // time is known when the caller merged the EXRs (`farm merge`); a merge of the
    // stats alone does not know it: null then, not the tiles' 0.
    let by_merge = Denoise::ByMerge.attribute();
    let denoised_by_merge =
        by_merge.is_some() && merged.get("denoise").and_then(Value::as_str) == by_merge;
    if denoised_by_merge {
        merged.insert("denoise".into(), Value::from(Denoise::Done.attribute()));
        merged.insert(
            "denoise_seconds".into(),
            denoise_seconds.map_or(Value::Null, Value::from),
        );
    }
    write_json(out, &Value::Object(merged))?;
    Ok(Merged {
        tiles: count,
        width: w,
        height: h,
        denoise_seconds: denoise_seconds.filter(|_| denoised_by_merge),
    })
}
