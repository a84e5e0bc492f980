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

/// Job files quote paths: a stage and output folder named with spaces, quotes, `$` and
/// a command substitution render through the generated Slurm script (run by bash, as
/// Slurm would, for task 0) and nothing the names spell is run.
#[test]
fn farm_scripts_quote_paths_and_tasks_render() {
    let dir = tempfile::tempdir().unwrap();
    let odd = dir.path().join("a b 'c' $(touch pwned) `touch pwned2`");
    std::fs::create_dir(&odd).unwrap();
    let repo = common::repo();
    std::fs::copy(repo.join("scenes/cloud/cloud.usda"), odd.join("cloud.usda")).unwrap();
    std::fs::copy(repo.join("scenes/cloud/cloud.vdb"), odd.join("cloud.vdb")).unwrap();
    let stage = odd.join("cloud.usda").display().to_string();
    let out = odd.join("shot.####.exr").display().to_string();
    let job = odd.join("job").display().to_string();
    let r = nimbus(&[
        "farm", "slurm", &stage, "-o", &out, "--frames", "3-4", "--tiles", "2", "--dir", &job,
        "--", "--res", "24x18", "--spp", "2",
    ]);
    assert!(r.status.success(), "{}", stderr(&r));
    let script = odd.join("job/render.sbatch");
    let text = std::fs::read_to_string(&script).unwrap();
    assert!(
        text.contains("#SBATCH --array=0-3") && text.contains("#SBATCH --requeue"),
        "{text}"
    );
    let merge = std::fs::read_to_string(odd.join("job/merge.sbatch")).unwrap();
    assert!(merge.contains("#SBATCH --array=0-1"), "{merge}");
    for task in ["0", "1"] {
        let run = std::process::Command::new("bash")
            .arg(&script)
            .current_dir(odd.join("job"))
            .env("SLURM_ARRAY_TASK_ID", task)
            .output()
            .unwrap();
        assert!(run.status.success(), "task {task}: {}", stderr(&run));
    }
    // Idempotent: task 0 again finds its valid output and does not render.
    let again = std::process::Command::new("bash")
        .arg(&script)
        .env("SLURM_ARRAY_TASK_ID", "0")
        .output()
        .unwrap();
    assert!(again.status.success());
    assert!(
        stderr(&again).contains("not rendered"),
        "{}",
        stderr(&again)
    );
    let run = std::process::Command::new("bash")
        .arg(odd.join("job/merge.sbatch"))
        .env("SLURM_ARRAY_TASK_ID", "0")
        .output()
        .unwrap();
    assert!(run.status.success(), "merge: {}", stderr(&run));
    assert!(odd.join("shot.0003.exr").is_file());
    // Frame 4's tiles were never rendered: its merge fails and names them.
    let run = std::process::Command::new("bash")
        .arg(odd.join("job/merge.sbatch"))
        .env("SLURM_ARRAY_TASK_ID", "1")
        .output()
        .unwrap();
    assert!(!run.status.success());
    assert!(
        stderr(&run).contains("re-run tiles 0, 1 (of 2)") || stderr(&run).contains("cannot read"),
        "{}",
        stderr(&run)
    );
    for p in [dir.path(), &odd, &odd.join("job"), &repo] {
        assert!(
            !p.join("pwned").exists() && !p.join("pwned2").exists(),
            "a path was run as a command"
        );
    }
}

/// Farm errors a user meets: sbatch missing with --submit, a reserved render flag, a
/// task index out of range.
#[test]
fn farm_errors_are_clear() {
    let dir = tempfile::tempdir().unwrap();
    let stage = cloud();
    let out = dir.path().join("s.####.exr").display().to_string();
    let job = dir.path().join("job").display().to_string();
    let r = std::process::Command::new(env!("CARGO_BIN_EXE_nimbus"))
        .args([
            "farm", "slurm", &stage, "-o", &out, "--frames", "1-2", "--dir", &job, "--submit",
        ])
        .env("PATH", dir.path())
        .output()
        .unwrap();
    assert!(!r.status.success());
    assert!(stderr(&r).contains("cannot run sbatch"), "{}", stderr(&r));
    let r = nimbus(&[
        "farm", "openjd", &stage, "-o", &out, "--frames", "1-2", "--dir", &job, "--", "--tile",
        "1/2",
    ]);
    assert!(!r.status.success());
    assert!(
        stderr(&r).contains("--tile is set by the farm job"),
        "{}",
        stderr(&r)
    );
    let r = nimbus(&[
        "farm",
        "openjd",
        &stage,
        "-o",
        &out,
        "--frames",
        "1-2",
        "--dir",
        &job,
        "--",
        "--checkpoint",
        "5",
    ]);
    assert!(!r.status.success());
    assert!(
        stderr(&r).contains("--checkpoint would write partial images"),
        "{}",
        stderr(&r)
    );
    let r = nimbus(&[
        "farm", "openjd", &stage, "-o", &out, "--frames", "1-2", "--dir", &job, "--", "--deep",
        "d.exr",
    ]);
    assert!(!r.status.success());
    assert!(
        stderr(&r).contains("does not assemble deep tiles"),
        "{}",
        stderr(&r)
    );
    let r = nimbus(&[
        "farm", "openjd", &stage, "-o", &out, "--frames", "1-2", "--dir", &job, "--", "--sp", "3",
    ]);
    assert!(!r.status.success());
    assert!(
        stderr(&r).contains("render flags do not parse"),
        "{}",
        stderr(&r)
    );
    let r = nimbus(&[
        "farm", "openjd", &stage, "-o", &out, "--frames", "1-2", "--dir", &job,
    ]);
    assert!(r.status.success(), "{}", stderr(&r));
    let job_file = dir.path().join("job/job.json").display().to_string();
    let r = nimbus(&["farm", "task", "--job", &job_file, "--index", "2"]);
    assert!(!r.status.success());
    assert!(
        stderr(&r).contains("task 2 is out of range"),
        "{}",
        stderr(&r)
    );
}
