//! The whole Hydra path on the example stages: `target/release/hydra/nimbus-hydra` (the
//! command-line Hydra host, `cpp/hydra/host.cc`: its own minimal scene delegate over
//! pxr/usd, since the SDK here has no UsdImaging) renders each of `scenes/*` and the
//! shot stage of `tests/shot.rs` (holdout cubes and quads, a light in a box, light
//! groups; written by `tests/fixtures/make_shot_stage.py`, which needs Python's pxr)
//! through hdNimbus, and `nimbus render` renders the same stage with the same
//! resolution, samples and seed (measured: the shot stage bit-identical in every pixel).
//!
//! **What must hold.** The scene descriptions are the same but for Hydra's float
//! camera parameters (UsdGeomCamera's lengths × 0.1 in float, × 10 again in Rust) and
//! transforms handed over as matrices, so a few pixels' random walks may part at the
//! last bit, and a parameter handed over in float may differ from the reader's in its
//! last bit (scenes/fire: 157 of 3,072 R values off by at most 3e-6 relative, alpha
//! bit-identical: the same paths, an emission term rounded differently). So at least
//! 99 % of each channel's pixels must agree within 1e-5 relative (measured: chromatic
//! 3,072 of 3,072 bit-identical, cloud 3,067), and the image means within 1 % (the few
//! parted pixels are independent samples of the same pixel estimate, so their effect
//! on the mean is far below that).
//!
//! Needs the host, built with the plug-in (`NIMBUS_HYDRA=require cargo build --release
//! -p nimbus-hydra`, docs/hydra.md); without it the test skips, or fails under
//! `NIMBUS_REQUIRE_DATA=1`.

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;

const RES: (usize, usize) = (64, 48);
const SPP: u32 = 8;

fn host() -> Option<PathBuf> {
    let exe = match std::env::var_os("NIMBUS_HYDRA_PLUGIN") {
        Some(d) => PathBuf::from(d).join("../nimbus-hydra"),
        None => Path::new(env!("CARGO_BIN_EXE_nimbus"))
            .parent()
            .expect("target dir")
            .join("hydra/nimbus-hydra"),
    };
    if exe.is_file() {
        Some(exe)
    } else {
        common::missing(&format!(
            "no command-line Hydra host at {} (built with the plug-in: NIMBUS_HYDRA=require … cargo build --release -p nimbus-hydra)",
            exe.display()
        ))
    }
}

fn rgba(path: &Path) -> [Vec<f32>; 4] {
    let (w, h, chans) =
        nimbus::output::exr::read_channels(path).unwrap_or_else(|e| panic!("read {e}"));
    assert_eq!((w, h), RES, "{}: size", path.display());
    ["R", "G", "B", "A"].map(|name| {
        chans
            .iter()
            .find(|c| c.0 == name)
            .unwrap_or_else(|| panic!("{}: no channel {name}", path.display()))
            .1
            .clone()
    })
}

mod hydra_host {
    use super::*;

    #[test]
    fn example_stages_through_hydra_match_nimbus_render() {
        let Some(host) = host() else {
            return;
        };
        let out = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("hydra_host");
        let _ = std::fs::remove_dir_all(&out);
        std::fs::create_dir_all(&out).unwrap();
        let res = format!("{}x{}", RES.0, RES.1);
        // The shot test stage (tests/shot.rs: a slab volume, a sun, a sphere light in a
        // closed box, holdout cubes and quads, light groups), with its slab VDB.
        let Some((shot_dir, _)) = common::data::pxr_fixtures(
            "make_shot_stage.py",
            &["pxr"],
            "pip install usd-core",
            true,
        ) else {
            return;
        };
        // As tests/shot.rs writes it: a 32³ grid of density 1 over [-1, 1]³.
        let vs = 2.0 / 32.0;
        let grid = nimbus::volume::procedural::grid_from_fn(
            "density",
            [32; 3],
            glam::DVec3::splat(-1.0 + 0.5 * vs),
            vs,
            |_| 1.0,
        );
        nimbus::volume::vdb::write_float_grid(&shot_dir.path().join("slab.vdb"), &grid).unwrap();
        let stages: Vec<(String, PathBuf)> = ["chromatic", "cloud", "fire", "overlap"]
            .iter()
            .map(|n| {
                (
                    n.to_string(),
                    common::repo().join(format!("scenes/{n}/{n}.usda")),
                )
            })
            .chain([("shot".to_string(), shot_dir.path().join("shot.usda"))])
            .collect();
        for (name, stage) in stages {
            let name = name.as_str();
            let hydra_exr = out.join(format!("{name}_hydra.exr"));
            let o = Command::new(&host)
                .arg(&stage)
                .arg("-o")
                .arg(&hydra_exr)
                .args(["--res", &res, "--spp", &SPP.to_string()])
                .output()
                .expect("run nimbus-hydra");
            let e = String::from_utf8_lossy(&o.stderr);
            assert!(o.status.success(), "nimbus-hydra {name}: {e}");
            assert!(!e.contains("Runtime Error"), "nimbus-hydra {name}: {e}");
            let nimbus_exr = out.join(format!("{name}_nimbus.exr"));
            let o = common::cli::nimbus(&[
                "render",
                stage.to_str().unwrap(),
                "-o",
                nimbus_exr.to_str().unwrap(),
                "--res",
                &res,
                "--spp",
                &SPP.to_string(),
            ]);
            assert!(
                o.status.success(),
                "nimbus render {name}: {}",
                common::cli::stderr(&o)
            );
            let (a, b) = (rgba(&hydra_exr), rgba(&nimbus_exr));
            for (c, (x, y)) in a.iter().zip(&b).enumerate() {
                let same = x
                    .iter()
                    .zip(y)
                    .filter(|(p, q)| p.to_bits() == q.to_bits())
                    .count();
                let close = x
                    .iter()
                    .zip(y)
                    .filter(|(p, q)| (*p - *q).abs() <= 1e-5 * q.abs().max(1e-6))
                    .count();
                let mean = |v: &[f32]| v.iter().map(|&p| p as f64).sum::<f64>() / v.len() as f64;
                let (ma, mb) = (mean(x), mean(y));
                let channel = "RGBA".as_bytes()[c] as char;
                eprintln!(
                    "hydra_host {name} {channel}: {same} of {} pixels bit-identical, {close} within 1e-5; mean hydra {ma:.6} nimbus {mb:.6}",
                    x.len()
                );
                assert!(
                    close * 100 >= x.len() * 99,
                    "{name} {channel}: only {close} of {} pixels within 1e-5 ({same} bit-identical)",
                    x.len()
                );
                assert!(
                    (ma - mb).abs() <= 0.01 * mb.abs().max(1e-6),
                    "{name} {channel}: mean {ma} through Hydra, {mb} from nimbus render"
                );
            }
        }
    }
}
