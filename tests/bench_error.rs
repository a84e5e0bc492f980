//! End-to-end tests of `nimbus bench error` on the chromatic example at 16×12: the CSV's
//! exact header and rows, the plot files, the cached reference (rendered once, reused,
//! and identical when passed with `--reference`), and clean failures on bad input. No
//! timing is asserted: budgets only bound how long the test takes.

mod common;

use common::cli::{nimbus, stderr};
use std::path::{Path, PathBuf};
use std::process::Output;

fn stage() -> String {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("scenes/chromatic/chromatic.usda")
        .display()
        .to_string()
}

fn assert_ok(o: &Output) {
    assert!(o.status.success(), "nimbus failed: {}", stderr(o));
}

/// Asserts a clean failure: non-zero exit, no panic, a message containing `needle`.
fn assert_clean_error(o: &Output, needle: &str) {
    let e = stderr(o);
    assert!(!o.status.success(), "expected failure; stderr: {e}");
    assert!(!e.contains("panicked"), "panic: {e}");
    assert!(e.contains(needle), "error does not mention '{needle}': {e}");
}

struct Row {
    tracker: String,
    budget: f64,
    seed: u64,
    spp: u32,
    lookups: u64,
    relmse: f64,
    mse: f64,
}

fn read_csv(path: &Path) -> (String, Vec<Row>) {
    let text = std::fs::read_to_string(path).expect("read csv");
    let mut lines = text.lines();
    let header = lines.next().expect("header").to_string();
    let rows = lines
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            assert_eq!(f.len(), 7, "row {l}");
            Row {
                tracker: f[0].into(),
                budget: f[1].parse().unwrap(),
                seed: f[2].parse().unwrap(),
                spp: f[3].parse().unwrap(),
                lookups: f[4].parse().unwrap(),
                relmse: f[5].parse().unwrap(),
                mse: f[6].parse().unwrap(),
            }
        })
        .collect();
    (header, rows)
}

fn cached_references(dir: &Path) -> Vec<PathBuf> {
    std::fs::read_dir(dir)
        .map(|d| {
            d.filter_map(|e| e.ok())
                .map(|e| e.path())
                .filter(|p| p.extension().is_some_and(|x| x == "exr"))
                .collect()
        })
        .unwrap_or_default()
}

#[test]
fn bench_error_writes_csv_and_plot_and_reuses_the_cached_reference() {
    let tmp = tempfile::tempdir().unwrap();
    let cache = tmp.path().join("cache");
    let csv = tmp.path().join("error.csv");
    let plot = tmp.path().join("error");
    let stage = stage();
    let common = [
        "bench",
        "error",
        stage.as_str(),
        "--res",
        "16x12",
        "--reference-spp",
        "64",
        "--seed",
        "7",
        "--cache-dir",
        cache.to_str().unwrap(),
        "--csv",
        csv.to_str().unwrap(),
    ];

    // First run: time budgets, two trackers, two seeds; renders and caches the reference.
    let mut args = common.to_vec();
    args.extend([
        "--trackers",
        "naive-delta,spectral-decomposition:hist-avg",
        "--budgets",
        "0.2,0.4",
        "--seeds",
        "2",
        "--plot",
        plot.to_str().unwrap(),
    ]);
    let o = nimbus(&args);
    assert_ok(&o);
    assert!(
        stderr(&o).contains("rendering the reference"),
        "{}",
        stderr(&o)
    );
    let refs = cached_references(&cache);
    assert_eq!(refs.len(), 1, "{refs:?}");
    let (header, rows) = read_csv(&csv);
    assert_eq!(
        header,
        "tracker,budget_seconds,seed,spp,density_lookups,relmse,mse"
    );
    assert_eq!(rows.len(), 2 * 2 * 2);
    for tracker in ["naive-delta", "spectral-decomposition:hist-avg"] {
        for budget in [0.2, 0.4] {
            for seed in [7, 8] {
                let n = rows
                    .iter()
                    .filter(|r| r.tracker == tracker && r.budget == budget && r.seed == seed)
                    .count();
                assert_eq!(n, 1, "{tracker} {budget} {seed}");
            }
        }
    }
    for r in &rows {
        assert!(r.spp > 0 && r.lookups > 0, "{} {}", r.spp, r.lookups);
        assert!(r.relmse.is_finite() && r.relmse > 0.0, "{}", r.relmse);
        assert!(r.mse.is_finite() && r.mse > 0.0, "{}", r.mse);
    }
    let png = std::fs::read(tmp.path().join("error.png")).expect("png written");
    assert_eq!(&png[..8], b"\x89PNG\r\n\x1a\n");
    let svg = std::fs::read_to_string(tmp.path().join("error.svg")).expect("svg written");
    assert!(svg.trim_start().starts_with("<svg"), "{}", &svg[..80]);
    assert!(svg.trim_end().ends_with("</svg>"));

    // Second run: same stage and reference settings, so the cached reference is reused.
    // A sample cap far inside the budget makes the images exact: 2 spp per render.
    let mut args = common.to_vec();
    args.extend([
        "--trackers",
        "delta",
        "--budgets",
        "60",
        "--seeds",
        "1",
        "--spp",
        "2",
    ]);
    let o = nimbus(&args);
    assert_ok(&o);
    assert!(
        stderr(&o).contains("reusing the cached reference"),
        "{}",
        stderr(&o)
    );
    assert!(!stderr(&o).contains("rendering the reference"));
    assert_eq!(cached_references(&cache), refs);
    let (_, cached_rows) = read_csv(&csv);
    assert_eq!(cached_rows.len(), 1);
    assert_eq!(cached_rows[0].spp, 2);

    // The cached file passed as --reference gives the same errors, bit for bit.
    let mut args = common.to_vec();
    args.extend([
        "--trackers",
        "delta",
        "--budgets",
        "60",
        "--seeds",
        "1",
        "--spp",
        "2",
        "--reference",
        refs[0].to_str().unwrap(),
    ]);
    let o = nimbus(&args);
    assert_ok(&o);
    let (_, given_rows) = read_csv(&csv);
    assert_eq!(given_rows[0].relmse, cached_rows[0].relmse);
    assert_eq!(given_rows[0].mse, cached_rows[0].mse);

    // A different resolution is a different reference: a new cache entry.
    let o = nimbus(&[
        "bench",
        "error",
        stage.as_str(),
        "--res",
        "8x6",
        "--reference-spp",
        "16",
        "--cache-dir",
        cache.to_str().unwrap(),
        "--trackers",
        "delta",
        "--budgets",
        "60",
        "--seeds",
        "1",
        "--spp",
        "1",
    ]);
    assert_ok(&o);
    assert!(stderr(&o).contains("rendering the reference"));
    assert_eq!(cached_references(&cache).len(), 2);
}

/// `auto` stands for the stage's `--tracker auto` choice, labelled with it; the budgets
/// can run on the wall clock too.
#[test]
fn bench_error_resolves_auto_per_stage() {
    let tmp = tempfile::tempdir().unwrap();
    let csv = tmp.path().join("auto.csv");
    let stage = stage();
    let o = nimbus(&[
        "bench",
        "error",
        stage.as_str(),
        "--res",
        "8x6",
        "--reference-spp",
        "16",
        "--cache-dir",
        tmp.path().join("cache").to_str().unwrap(),
        "--trackers",
        "delta,auto",
        "--budgets",
        "60",
        "--seeds",
        "1",
        "--spp",
        "1",
        "--clock",
        "wall",
        "--csv",
        csv.to_str().unwrap(),
    ]);
    assert_ok(&o);
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(out.contains("auto: chromatic, non-emissive"), "{out}");
    assert!(out.contains("wall clock"), "{out}");
    let (_, rows) = read_csv(&csv);
    let labels: Vec<&str> = rows.iter().map(|r| r.tracker.as_str()).collect();
    assert_eq!(labels, ["delta", "auto=ratio-select:no-absorption-events"]);
}

#[test]
fn bench_error_bad_input_fails_cleanly() {
    let tmp = tempfile::tempdir().unwrap();
    let cache = tmp.path().join("cache");
    let csv = tmp.path().join("out.csv");
    let stage = stage();
    let run = |extra: &[&str]| {
        let mut args = vec![
            "bench",
            "error",
            stage.as_str(),
            "--res",
            "8x6",
            "--reference-spp",
            "4",
            "--spp",
            "1",
            "--cache-dir",
            cache.to_str().unwrap(),
            "--csv",
            csv.to_str().unwrap(),
        ];
        args.extend_from_slice(extra);
        nimbus(&args)
    };
    let o = run(&["--trackers", "delta,warp-drive", "--budgets", "1"]);
    assert_clean_error(&o, "unknown tracker 'warp-drive'");
    assert!(
        stderr(&o).contains("spectral-decomposition"),
        "lists known trackers"
    );
    assert_clean_error(
        &run(&["--trackers", "delta:hist-avg", "--budgets", "1"]),
        "takes no scheme",
    );
    assert_clean_error(
        &run(&["--trackers", "delta,", "--budgets", "1"]),
        "empty tracker",
    );
    assert_clean_error(&run(&["--trackers", "delta"]), "--budgets");
    assert_clean_error(
        &run(&["--trackers", "delta", "--budgets", "1,0"]),
        "positive",
    );
    assert_clean_error(
        &run(&["--trackers", "delta", "--budgets", "1", "--seeds", "0"]),
        "--seeds",
    );

    // A reference of another size.
    let small = tmp.path().join("small.exr");
    let o = nimbus(&[
        "render",
        stage.as_str(),
        "-o",
        small.to_str().unwrap(),
        "--res",
        "4x3",
        "--spp",
        "1",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_clean_error(
        &run(&[
            "--trackers",
            "delta",
            "--budgets",
            "1",
            "--reference",
            small.to_str().unwrap(),
        ]),
        "is 4x3 but the bench renders at 8x6",
    );
    let missing = tmp.path().join("missing.exr");
    assert_clean_error(
        &run(&[
            "--trackers",
            "delta",
            "--budgets",
            "1",
            "--reference",
            missing.to_str().unwrap(),
        ]),
        "missing.exr",
    );
    assert!(!csv.exists(), "no CSV after failures");

    // An unwritable CSV is refused before anything is rendered.
    let o = nimbus(&[
        "bench",
        "error",
        stage.as_str(),
        "--trackers",
        "delta",
        "--budgets",
        "1",
        "--csv",
        tmp.path().join("no/such/dir/out.csv").to_str().unwrap(),
        "--cache-dir",
        cache.to_str().unwrap(),
    ]);
    assert_clean_error(&o, "out.csv");
    assert!(!stderr(&o).contains("rendering the reference"));
    assert!(cached_references(&cache).is_empty());
}
