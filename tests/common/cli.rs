//! Running the `nimbus` binary and what its end-to-end tests share: its output and
//! clean errors, EXR channels and statistics files, Python with Nimbus' schemas, and
//! the stages the tests write.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

pub use super::data::repo as root;

pub fn nimbus(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_nimbus"))
        .args(args)
        .output()
        .expect("run nimbus")
}

pub fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// Asserts a clean failure: non-zero exit, no panic, an error message containing `needle`.
pub fn assert_clean_error(o: &Output, needle: &str) {
    let e = stderr(o);
    assert!(
        !o.status.success(),
        "expected failure, got success; stderr: {e}"
    );
    assert_eq!(o.status.code(), Some(1), "exit code; stderr: {e}");
    assert!(!e.contains("panicked"), "panic: {e}");
    assert!(e.contains("nimbus: error:"), "no error line: {e}");
    assert!(e.contains(needle), "error does not mention '{needle}': {e}");
}

pub fn channels(path: &Path) -> Vec<(String, Vec<f32>)> {
    nimbus::output::exr::read_channels(path)
        .expect("read exr")
        .2
}

pub fn channel<'a>(chans: &'a [(String, Vec<f32>)], name: &str) -> &'a [f32] {
    &chans
        .iter()
        .find(|c| c.0 == name)
        .unwrap_or_else(|| panic!("no channel {name}"))
        .1
}

/// R, G, B and A of the EXR at `path`, asserting its size is `(width, height)`.
pub fn rgba(path: &Path, size: (usize, usize)) -> [Vec<f32>; 4] {
    let (w, h, chans) =
        nimbus::output::exr::read_channels(path).unwrap_or_else(|e| panic!("read {e}"));
    assert_eq!((w, h), size, "{}: size", path.display());
    ["R", "G", "B", "A"].map(|name| {
        chans
            .iter()
            .find(|c| c.0 == name)
            .unwrap_or_else(|| panic!("{}: no channel {name}", path.display()))
            .1
            .clone()
    })
}

/// Runs `python3 -c script args...` and asserts success.
pub fn python(script: &str, args: &[&str]) {
    let o = Command::new("python3")
        .arg("-c")
        .arg(script)
        .args(args)
        .env("PXR_PLUGINPATH_NAME", root().join("schemas"))
        .output()
        .unwrap();
    assert!(
        o.status.success(),
        "python failed: {}",
        String::from_utf8_lossy(&o.stderr)
    );
}

/// Writes a stage whose density field points at `file` with grid name `grid`.
pub fn stage_with_field(dir: &Path, file: &str, grid: &str) -> PathBuf {
    let text = std::fs::read_to_string(root().join("scenes/cloud/cloud.usda"))
        .unwrap()
        .replace("@./cloud.vdb@", &format!("@./{file}@"))
        .replace(
            "token fieldName = \"density\"",
            &format!("token fieldName = \"{grid}\""),
        );
    let path = dir.join("stage.usda");
    std::fs::write(&path, text).unwrap();
    path
}

pub fn render_args<'a>(stage: &'a str, out: &'a str) -> Vec<&'a str> {
    vec!["render", stage, "-o", out, "--res", "8x6", "--spp", "1"]
}

pub fn stats_json(path: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

/// The example cloud stage with its density `filePath` replaced by `file_path` (an
/// `asset filePath...` line: a default value or time samples) and `extra` authored on
/// the volume.
pub fn cloud_stage_with(dir: &Path, file_path: &str, grid: &str, extra: &str) -> PathBuf {
    let text = std::fs::read_to_string(root().join("scenes/cloud/cloud.usda"))
        .unwrap()
        .replace("asset filePath = @./cloud.vdb@", file_path)
        .replace(
            "token fieldName = \"density\"",
            &format!("token fieldName = \"{grid}\""),
        )
        .replace(
            "float nimbus:anisotropy = 0.5",
            &format!("float nimbus:anisotropy = 0.5\n        {extra}"),
        );
    let path = dir.join("stage.usda");
    std::fs::write(&path, text).unwrap();
    path
}
