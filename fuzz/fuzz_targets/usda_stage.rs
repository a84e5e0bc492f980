//! Scene loading from arbitrary .usda text: parsing, composition (references,
//! sublayers, payloads to files that mostly do not exist) and Nimbus' prim reading
//! must answer with a scene or an error, never a panic, a stack overflow or a hang.
#![no_main]

use libfuzzer_sys::fuzz_target;
use std::path::PathBuf;
use std::sync::OnceLock;

/// One scratch stage file per fuzzing process (the loader opens stages by path, so
/// relative asset paths resolve next to it).
fn scratch() -> &'static PathBuf {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    DIR.get_or_init(|| {
        let dir = std::env::temp_dir().join(format!("nimbus-fuzz-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("scratch dir");
        dir.join("stage.usda")
    })
}

fuzz_target!(|data: &[u8]| {
    let path = scratch();
    if std::fs::write(path, data).is_err() {
        return;
    }
    let _ = nimbus::scene::load_stage(path, &nimbus::scene::LoadOptions::default());
});
