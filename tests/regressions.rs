//! Replays every input kept from fuzzing (and hand-made hostile inputs) through the
//! code the fuzz targets exercise (fuzz/fuzz_targets): each must end in a result or an
//! error, never a panic, an abort, a stack overflow or a hang.
//!
//! tests/regressions/vdb/*: bytes for VDB header validation and Nimbus' own Rust reader, as
//! a .usdz member in memory and as a file. tests/regressions/usda/*: stage text, loaded
//! as `stage.usda` in a scratch folder (as the fuzz target does, so a file that names
//! `./stage.usda` refers to itself).

use nimbus::scene::{load_stage, LoadOptions};

use nimbus::volume::asset::AssetLocation;
use nimbus::volume::vdb::{list_grids, read_float_grid_with, read_vec3s_grid_with, Reader};
use std::path::PathBuf;
use std::sync::Arc;

fn inputs(kind: &str) -> Vec<PathBuf> {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("tests/regressions")
        .join(kind);
    let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .map(|e| e.unwrap().path())
        .collect();
    files.sort();
    assert!(!files.is_empty(), "no inputs in {}", dir.display());
    files
}

#[test]
fn vdb_regressions_fail_cleanly() {
    let scratch = tempfile::tempdir().unwrap();
    for path in inputs("vdb") {
        let bytes = std::fs::read(&path).unwrap();
        let file = scratch.path().join("input.vdb");
        std::fs::write(&file, &bytes).unwrap();
        for loc in [
            AssetLocation::Packaged {
                package: "fuzz.usdz".into(),
                member: "fuzz.vdb".into(),
                bytes: Arc::new(bytes.clone()),
            },
            AssetLocation::File(file.clone()),
        ] {
            match list_grids(&loc) {
                Ok(grids) => {
                    for g in grids.iter().take(2) {
                        if g.value_type == "Tree_vec3s_5_4_3" {
                            let _ = read_vec3s_grid_with(Reader::Rust, &loc, &g.name, None);
                        } else {
                            let _ = read_float_grid_with(Reader::Rust, &loc, &g.name, None);
                        }
                    }
                }
                Err(e) => {
                    // The message names the file it is about.
                    let msg = e.to_string();
                    assert!(
                        msg.contains("fuzz.vdb") || msg.contains("input.vdb"),
                        "{}: {msg}",
                        path.display()
                    );
                }
            }
        }
    }
}

#[test]
fn usda_regressions_fail_cleanly() {
    let scratch = tempfile::tempdir().unwrap();
    let stage = scratch.path().join("stage.usda");
    for path in inputs("usda") {
        std::fs::copy(&path, &stage).unwrap();
        if let Err(e) = load_stage(&stage, &LoadOptions::default()) {
            let msg = e.to_string();
            assert!(!msg.is_empty(), "{}", path.display());
        }
    }
}
