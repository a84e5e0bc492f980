//! Tiles and `nimbus merge`: a frame rendered as tiles and merged equals the one-machine
//! render bit for bit (every channel), tile stats merge to the one-machine counts, and
//! merge refuses missing, duplicated, partial and mismatched tiles, naming the ones to
//! re-run and writing nothing.

mod common;

use common::cli::{channels, nimbus, stderr};
use std::path::{Path, PathBuf};

fn cloud() -> String {
    common::repo()
        .join("scenes/cloud/cloud.usda")
        .display()
        .to_string()
}

/// Renders the cloud at 37x23, 3 spp (seed from the stage) with `extra` flags.
fn render(out: &Path, extra: &[&str]) -> std::process::Output {
    let stage = cloud();
    let out = out.display().to_string();
    let mut args = vec![
        "render",
        &stage,
        "-o",
        &out,
        "--res",
        "37x23",
        "--spp",
        "3",
        "--threads",
        "2",
    ];
    args.extend_from_slice(extra);
    nimbus(&args)
}

fn tiles(dir: &Path, n: u32, extra: &[&str]) -> Vec<PathBuf> {
    let out = dir.join("out.exr");
    (0..n)
        .map(|i| {
            let t = format!("{i}/{n}");
            let mut a = vec!["--tile", &t];
            a.extend_from_slice(extra);
            let r = render(&out, &a);
            assert!(r.status.success(), "{}", stderr(&r));
            let width = (n - 1).max(1).to_string().len();
            dir.join(format!("out.tile{i:0width$}.exr"))
        })
        .collect()
}

fn merge(out: &Path, inputs: &[PathBuf]) -> std::process::Output {
    let mut args = vec!["merge".to_string(), out.display().to_string()];
    args.extend(inputs.iter().map(|p| p.display().to_string()));
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    nimbus(&args)
}

#[test]
fn merged_tiles_equal_the_one_machine_render() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let full = d.join("full.exr");
    let r = render(&full, &["--stats", d.join("full.json").to_str().unwrap()]);
    assert!(r.status.success(), "{}", stderr(&r));
    for n in [1, 4, 6] {
        let stats = d.join("s.json");
        let parts = tiles(d, n, &["--stats", stats.to_str().unwrap()]);
        let merged = d.join(format!("merged{n}.exr"));
        let m = merge(&merged, &parts);
        assert!(m.status.success(), "{}", stderr(&m));
        let (a, b) = (channels(&full), channels(&merged));
        assert_eq!(
            a.iter().map(|c| &c.0).collect::<Vec<_>>(),
            b.iter().map(|c| &c.0).collect::<Vec<_>>()
        );
        for ((name, x), (_, y)) in a.iter().zip(&b) {
            let bits = |v: &[f32]| v.iter().map(|f| f.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(x), bits(y), "{n} tiles: channel {name}");
        }
        // The tile stats add up to the one-machine counts.
        let width = (n - 1).max(1).to_string().len();
        let tile_stats: Vec<PathBuf> = (0..n)
            .map(|i| d.join(format!("s.tile{i:0width$}.json")))
            .collect();
        let merged_stats = d.join(format!("merged{n}.json"));
        let m = merge(&merged_stats, &tile_stats);
        assert!(m.status.success(), "{}", stderr(&m));
        let read = |p: &Path| -> serde_json::Value {
            serde_json::from_str(&std::fs::read_to_string(p).unwrap()).unwrap()
        };
        let (one, many) = (read(&d.join("full.json")), read(&merged_stats));
        for k in [
            "density_lookups",
            "real_collisions",
            "null_collisions",
            "cells_visited",
            "width",
            "height",
            "samples_per_pixel",
            "settings_hash",
        ] {
            assert_eq!(one[k], many[k], "{n} tiles: stats {k}");
        }
    }
}

#[test]
fn merge_refuses_incomplete_or_mismatched_tiles() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let parts = tiles(d, 4, &[]);
    let out = d.join("frame.exr");
    let refused = |inputs: &[PathBuf], needles: &[&str]| {
        let m = merge(&out, inputs);
        let err = stderr(&m);
        assert!(!m.status.success(), "merged: {err}");
        for n in needles {
            assert!(err.contains(n), "{n:?} not in: {err}");
        }
        assert!(!out.exists(), "{} was written", out.display());
    };
    // Missing tile 2.
    refused(
        &[parts[0].clone(), parts[1].clone(), parts[3].clone()],
        &["tile 2/4 is missing", "re-run tiles 2 (of 4)"],
    );
    // Tile 1 twice.
    refused(
        &[
            parts[0].clone(),
            parts[1].clone(),
            parts[1].clone(),
            parts[2].clone(),
            parts[3].clone(),
        ],
        &["tile 1 is given twice"],
    );
    // Tile 3 from another seed (another settings hash).
    let other = d.join("other");
    std::fs::create_dir(&other).unwrap();
    let r = render(&other.join("out.exr"), &["--tile", "3/4", "--seed", "99"]);
    assert!(r.status.success(), "{}", stderr(&r));
    refused(
        &[
            parts[0].clone(),
            parts[1].clone(),
            parts[2].clone(),
            other.join("out.tile3.exr"),
        ],
        &["other settings", "re-run tiles 3 (of 4)"],
    );
    // Tile 0 partial: what a task stopped by SIGTERM after 2 of its 3 samples per
    // pixel writes (the same settings, fewer samples than asked). Made by rewriting a
    // complete tile's nimbus:spp, which is what merge reads.
    let partial = d.join("partial");
    std::fs::create_dir(&partial).unwrap();
    with_spp(&parts[0], &partial.join("out.tile0.exr"), 2);
    refused(
        &[
            partial.join("out.tile0.exr"),
            parts[1].clone(),
            parts[2].clone(),
            parts[3].clone(),
        ],
        &["partial: 2 samples per pixel of 3", "re-run tiles 0 (of 4)"],
    );
    // A whole-frame render is not a tile.
    let whole = d.join("whole.exr");
    assert!(render(&whole, &[]).status.success());
    refused(&[whole], &["not a Nimbus tile"]);
    // With every tile, it merges.
    let m = merge(&out, &parts);
    assert!(m.status.success(), "{}", stderr(&m));
}

#[test]
fn bad_tiles_are_clear_errors() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out.exr");
    let r = render(&out, &["--tile", "4/4"]);
    assert_eq!(r.status.code(), Some(2), "{}", stderr(&r));
    assert!(stderr(&r).contains("0 <= I < N"), "{}", stderr(&r));
    // 1 x 997 bands do not fit 23 rows.
    let r = render(&out, &["--tile", "3/997"]);
    assert!(!r.status.success());
    assert!(
        stderr(&r).contains("do not fit a 37x23 frame"),
        "{}",
        stderr(&r)
    );
    let r = render(&out, &["--region", "0,0,38,5"]);
    assert!(!r.status.success());
    assert!(
        stderr(&r).contains("does not lie inside the 37x23 frame"),
        "{}",
        stderr(&r)
    );
    assert!(std::fs::read_dir(dir.path()).unwrap().next().is_none());
}

/// Copies the EXR `from` to `to` with its `nimbus:spp` attribute set to `spp`.
fn with_spp(from: &Path, to: &Path, spp: i32) {
    use exr::prelude::*;
    let mut image = read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .first_valid_layer()
        .all_attributes()
        .from_file(from)
        .unwrap();
    image
        .layer_data
        .attributes
        .other
        .insert(Text::from("nimbus:spp"), AttributeValue::I32(spp));
    image.write().to_file(to).unwrap();
}
