//! hdNimbus inside Blender: bpy 4.3.0's `HydraRenderEngine` renders a Blender scene —
//! the smoke VDB as a Volume object, a sun, a ground plane and cubes (meshes: holdouts)
//! — through the delegate, with both `scene.hydra.export_method` values, and the images
//! must agree with `nimbus render` of Blender's USD export of the same scene
//! (`tests/fixtures/hydra_blender_scene.py` builds, renders and exports it).
//!
//! The Python that imports bpy 4.3.0 is `NIMBUS_BPY43_PYTHON` (`.ci/run` makes a venv
//! with `pip install bpy==4.3.0 'numpy<2'`); the plug-in is
//! `target/release/hydra/hdNimbus` (`NIMBUS_HYDRA=require cargo build --release -p
//! nimbus-hydra`, see docs/hydra.md; `NIMBUS_HYDRA_PLUGIN` names another folder); the
//! smoke is `openusd_blender_smoke/smoke_000002.vdb` of the shared data. Any of them
//! missing skips, or fails under `NIMBUS_REQUIRE_DATA=1`. The files stay in
//! `target/tmp/hydra_blender/` for a look.
//!
//! **The same scene.** Blender hands Hydra the volume without a material and its USD
//! exporter writes none, so both readers use NimbusVolumeAPI's fallback coefficients;
//! the sun is 3 W/m² in Blender, `intensity = 0.75` in both Hydra's light and the
//! exported DistantLight. The two descriptions differ only in the last bits of the
//! transforms (Blender's float matrices against the exporter's translate/rotateXYZ
//! ops), so nearly every pixel's random walk is the same: at least 90 % of the pixels
//! must be bit-identical (measured 4,090 of 4,096 at 16 spp), and the rest must agree
//! in distribution.
//!
//! **Statistics.** Both paths render the same K = 4 seeds at SPP samples per pixel. For
//! each pixel the sample variance over the seeds estimates the variance of one render;
//! a block of 8 × 8 pixels has, per path, the mean over its pixels and seeds and the
//! standard error se² = Σ_pixels s²_p / (K n²). A block passes when
//! |mean_Hydra − mean_nimbus| ≤ Z · √(se_H² + se_N²) + 1e-6 for R, G, B and A (the
//! 1e-6: float noise of blocks without variance), Z = 5: 256 block-channels per method,
//! a false alarm below 1e-4 per method for normal errors (the shared pixels make the
//! difference far smaller than independent renders' would be, so the bound is loose on
//! purpose, not tight). The lookups per sample the delegate prints must be within 2 %
//! of `nimbus render`'s (plus 0.05: it prints one decimal).

mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::time::Instant;

const RES: usize = 64;
const SPP: u32 = 32;
const SEEDS: [u64; 4] = [0, 1, 2, 3];
const MAX_DEPTH: u32 = 8;
const BLOCK: usize = 8;
const Z: f64 = 5.0;
/// Spheres beside the smoke (ico spheres of 10,242 points: their sync takes long
/// enough for Blender's worker threads to join in): with the plane, the volume, the
/// sun and the camera, 52 prims for Hydra to sync.
const CUBES: usize = 48;
const CUBE_DETAIL: usize = 5;

/// The Python that imports bpy 4.3.0, or `None` (skip; fails under
/// `NIMBUS_REQUIRE_DATA=1`).
fn bpy43_python() -> Option<PathBuf> {
    let Some(python) = std::env::var_os("NIMBUS_BPY43_PYTHON") else {
        return common::missing(
            "NIMBUS_BPY43_PYTHON is not set (a CPython 3.11 with `pip install bpy==4.3.0 'numpy<2'`)",
        );
    };
    let o = Command::new(&python)
        .args([
            "-c",
            "import bpy, os, sys; print(bpy.app.version_string); sys.stdout.flush(); os._exit(0)",
        ])
        .output();
    match o {
        Ok(o) if o.status.success() => {
            let version = String::from_utf8_lossy(&o.stdout).trim().to_string();
            if version.lines().last() == Some("4.3.0") {
                Some(PathBuf::from(python))
            } else {
                common::missing(&format!(
                    "NIMBUS_BPY43_PYTHON={} has bpy {version:?}, not 4.3.0",
                    Path::new(&python).display()
                ))
            }
        }
        Ok(o) => common::missing(&format!(
            "NIMBUS_BPY43_PYTHON={} does not import bpy: {}",
            Path::new(&python).display(),
            String::from_utf8_lossy(&o.stderr).trim()
        )),
        Err(e) => common::missing(&format!(
            "NIMBUS_BPY43_PYTHON={} does not run: {e}",
            Path::new(&python).display()
        )),
    }
}

/// The hdNimbus plug-in folder (with plugInfo.json), or `None`.
fn plugin() -> Option<PathBuf> {
    let dir = match std::env::var_os("NIMBUS_HYDRA_PLUGIN") {
        Some(d) => PathBuf::from(d),
        None => Path::new(env!("CARGO_BIN_EXE_nimbus"))
            .parent()
            .expect("target dir")
            .join("hydra/hdNimbus"),
    };
    if dir.join("plugInfo.json").is_file() && dir.join("hdNimbus.so").exists() {
        Some(dir)
    } else {
        common::missing(&format!(
            "no hdNimbus plug-in in {} (build it: NIMBUS_HYDRA=require NIMBUS_USD_INCLUDE=… NIMBUS_USD_LIB=… NIMBUS_TBB_INCLUDE=… cargo build --release -p nimbus-hydra)",
            dir.display()
        ))
    }
}

struct Inputs {
    python: PathBuf,
    plugin: PathBuf,
    vdb: PathBuf,
}

fn inputs() -> Option<Inputs> {
    Some(Inputs {
        python: bpy43_python()?,
        plugin: plugin()?,
        vdb: common::shared_file("openusd_blender_smoke/smoke_000002.vdb")?,
    })
}

fn out_dir(name: &str) -> PathBuf {
    let out = PathBuf::from(env!("CARGO_TARGET_TMPDIR"))
        .join("hydra_blender")
        .join(name);
    let _ = std::fs::remove_dir_all(&out);
    std::fs::create_dir_all(&out).unwrap();
    out
}

/// Runs the scene script in `out` with `extra` arguments.
fn blender(i: &Inputs, out: &Path, extra: &[&str]) -> Output {
    let o = Command::new(&i.python)
        .arg(common::repo().join("tests/fixtures/hydra_blender_scene.py"))
        .arg(out)
        .arg("--plugin")
        .arg(&i.plugin)
        .arg("--vdb")
        .arg(&i.vdb)
        .args(["--res", &format!("{RES}x{RES}")])
        .args(["--spp", &SPP.to_string()])
        .args(["--max-depth", &MAX_DEPTH.to_string()])
        .args(["--cubes", &CUBES.to_string()])
        .args(["--cube-detail", &CUBE_DETAIL.to_string()])
        .args(extra)
        .output()
        .expect("run hydra_blender_scene.py");
    assert!(
        o.status.success(),
        "hydra_blender_scene.py {extra:?} failed:\n{}\n{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
    o
}

/// RGBA of an EXR: `[channel][y * RES + x]`.
fn read_rgba(path: &Path) -> [Vec<f32>; 4] {
    common::cli::rgba(path, (RES, RES))
}

/// The number before `what` in the line of `text` that starts with `prefix`.
fn number_before(text: &str, prefix: &str, what: &str) -> Option<f64> {
    let line = text.lines().rev().find(|l| l.starts_with(prefix))?;
    let head = &line[..line.find(what)?];
    head.split([' ', ','])
        .rfind(|s| !s.is_empty())?
        .parse()
        .ok()
}

/// Per pixel and channel: mean over the seeds' images and the variance of that mean.
fn seed_stats(images: &[[Vec<f32>; 4]]) -> ([Vec<f64>; 4], [Vec<f64>; 4]) {
    let k = images.len() as f64;
    let n = RES * RES;
    let mut mean: [Vec<f64>; 4] = std::array::from_fn(|_| vec![0.0; n]);
    let mut var: [Vec<f64>; 4] = std::array::from_fn(|_| vec![0.0; n]);
    for c in 0..4 {
        for p in 0..n {
            let m = images.iter().map(|im| im[c][p] as f64).sum::<f64>() / k;
            let s2 = images
                .iter()
                .map(|im| (im[c][p] as f64 - m).powi(2))
                .sum::<f64>()
                / (k - 1.0);
            mean[c][p] = m;
            var[c][p] = s2 / k;
        }
    }
    (mean, var)
}

fn block_pixels(bx: usize, by: usize) -> Vec<usize> {
    (by * BLOCK..(by + 1) * BLOCK)
        .flat_map(|y| (bx * BLOCK..(bx + 1) * BLOCK).map(move |x| y * RES + x))
        .collect()
}

fn compare(method: &str, hydra: &[[Vec<f32>; 4]], nimbus: &[[Vec<f32>; 4]]) {
    // Bit-identical pixels of seed 0 (all four channels).
    let identical = (0..RES * RES)
        .filter(|&p| (0..4).all(|c| hydra[0][c][p].to_bits() == nimbus[0][c][p].to_bits()))
        .count();
    let (hm, hv) = seed_stats(hydra);
    let (nm, nv) = seed_stats(nimbus);
    let mut failures = Vec::new();
    let mut worst: f64 = 0.0;
    for by in 0..RES / BLOCK {
        for bx in 0..RES / BLOCK {
            let px = block_pixels(bx, by);
            let n = px.len() as f64;
            for c in 0..4 {
                let mean = |m: &[f64]| px.iter().map(|&p| m[p]).sum::<f64>() / n;
                let var = |v: &[f64]| px.iter().map(|&p| v[p]).sum::<f64>() / (n * n);
                let (a, b) = (mean(&hm[c]), mean(&nm[c]));
                let se = (var(&hv[c]) + var(&nv[c])).sqrt();
                let bound = Z * se + 1e-6;
                worst = worst.max((a - b).abs() / bound);
                if (a - b).abs() > bound {
                    failures.push(format!(
                        "block ({bx},{by}) channel {}: hydra {a:.6} nimbus {b:.6} (bound {bound:.2e})",
                        "RGBA".as_bytes()[c] as char
                    ));
                }
            }
        }
    }
    let mean_r = |ims: &[[Vec<f32>; 4]]| {
        ims.iter()
            .map(|im| im[0].iter().map(|&v| v as f64).sum::<f64>())
            .sum::<f64>()
            / (ims.len() * RES * RES) as f64
    };
    eprintln!(
        "hydra_blender {method}: {identical} of {} pixels bit-identical (seed 0); mean R hydra {:.6} nimbus {:.6}; worst block |diff|/bound {worst:.3}",
        RES * RES,
        mean_r(hydra),
        mean_r(nimbus)
    );
    assert!(
        failures.is_empty(),
        "{method}: {} block-channels disagree:\n{}",
        failures.len(),
        failures.join("\n")
    );
    assert!(
        identical * 10 >= RES * RES * 9,
        "{method}: only {identical} of {} pixels bit-identical to nimbus render (expected at least 90 %: the scene descriptions differ only in the transforms' last bits)",
        RES * RES
    );
}

mod hydra_blender {
    use super::*;

    /// Both export methods against `nimbus render` of the USD export (module doc);
    /// also: the lookups in the delegate's statistics, and prims synced on several
    /// of the host's threads.
    #[test]
    fn renders_agree_with_nimbus_render() {
        let Some(i) = inputs() else {
            return;
        };
        let out = out_dir("agree");
        let start = Instant::now();
        // Blender's USD export of the scene (once: the scene does not depend on the seed).
        blender(&i, &out.join("export"), &["--usd-export", "--spp", "1"]);
        let stage = out.join("export/scene.usda");
        assert!(stage.is_file(), "no USD export at {}", stage.display());

        let mut nimbus_images = Vec::new();
        let mut nimbus_lookups = Vec::new();
        let nimbus_start = Instant::now();
        for seed in SEEDS {
            let exr = out.join(format!("nimbus_{seed}.exr"));
            let o = common::cli::nimbus(&[
                "render",
                stage.to_str().unwrap(),
                "-o",
                exr.to_str().unwrap(),
                "--camera",
                "/root/camera/camera",
                "--res",
                &format!("{RES}x{RES}"),
                "--spp",
                &SPP.to_string(),
                "--seed",
                &seed.to_string(),
                "--max-depth",
                &MAX_DEPTH.to_string(),
            ]);
            let e = common::cli::stderr(&o);
            assert!(o.status.success(), "nimbus render: {e}");
            nimbus_lookups.push(number_before(&e, "nimbus: wrote", "lookups/sample").expect(&e));
            nimbus_images.push(read_rgba(&exr));
        }
        let nimbus_seconds = nimbus_start.elapsed().as_secs_f64();
        let mut sync_threads = Vec::new();

        for method in ["HYDRA", "USD"] {
            let mut images = Vec::new();
            let method_start = Instant::now();
            for (k, seed) in SEEDS.iter().enumerate() {
                let dir = out.join(format!("{}_{seed}", method.to_lowercase()));
                let o = blender(
                    &i,
                    &dir,
                    &["--export-method", method, "--seed", &seed.to_string()],
                );
                let e = String::from_utf8_lossy(&o.stderr).into_owned();
                assert!(
                    !e.contains("Runtime Error") && !e.contains("Coding Error"),
                    "{method}: the delegate reported an error:\n{e}"
                );
                // The delegate's statistics: Nimbus' trackers ran, with lookups counted.
                let lookups = number_before(&e, "hdNimbus:", "lookups/sample")
                    .unwrap_or_else(|| panic!("{method}: no hdNimbus statistics line:\n{e}"));
                assert!(
                    e.contains(&format!("{SPP} of {SPP} spp")),
                    "{method}: not converged:\n{e}"
                );
                // nimbus render prints one decimal: 0.05 of rounding, 2 % of change.
                let off = (lookups - nimbus_lookups[k]).abs();
                assert!(
                    lookups > 0.0 && off <= 0.05 + 0.02 * nimbus_lookups[k],
                    "{method} seed {seed}: {lookups} lookups/sample, nimbus render {}",
                    nimbus_lookups[k]
                );
                let threads = number_before(&e, "hdNimbus:", "threads")
                    .unwrap_or_else(|| panic!("{method}: no sync thread count:\n{e}"));
                sync_threads.push(threads as usize);
                images.push(read_rgba(
                    &dir.join(format!("hydra_{}.exr", method.to_lowercase())),
                ));
            }
            eprintln!(
                "hydra_blender {method}: {} Blender renders in {:.1} s",
                SEEDS.len(),
                method_start.elapsed().as_secs_f64()
            );
            compare(method, &images, &nimbus_images);
        }
        eprintln!(
            "hydra_blender: nimbus render {} seeds in {nimbus_seconds:.1} s; whole test {:.1} s; prims synced on {sync_threads:?} threads",
            SEEDS.len(),
            start.elapsed().as_secs_f64()
        );
        // Prims synced on several of Blender's threads at once (its TBB has one per
        // core) in at least one of the 8 renders: the store's locking was exercised.
        // Measured on the loaded 2-core machine: with small cubes 4 of 8 renders synced
        // on one thread; with these spheres 2 threads in every one of 12 renders.
        let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
        assert!(
            sync_threads.iter().any(|&t| t >= 2) || cores < 2,
            "prims synced on {sync_threads:?} threads with {cores} cores"
        );
    }

    /// A VDB that vanishes after Blender read it: the delegate reports the missing file
    /// as a Hydra runtime error, renders nothing, and Blender finishes the render and
    /// goes on (the script writes alive.txt after `bpy.ops.render.render`).
    #[test]
    fn missing_vdb_is_an_error_and_blender_lives() {
        let Some(i) = inputs() else {
            return;
        };
        let out = out_dir("missing");
        let o = blender(&i, &out, &["--missing-vdb"]);
        let e = String::from_utf8_lossy(&o.stderr).into_owned();
        assert!(
            out.join("alive.txt").is_file(),
            "Blender did not finish:\n{e}"
        );
        assert!(
            e.contains("Runtime Error") && e.contains("vanishing.vdb"),
            "no runtime error naming the missing file:\n{e}"
        );
        assert!(!e.contains("panicked"), "a panic:\n{e}");
        let rgba = read_rgba(&out.join("hydra_hydra.exr"));
        assert!(
            rgba.iter().flatten().all(|&v| v == 0.0),
            "the image of a failed render is not empty"
        );
    }
}
