//! Inputs from outside the repository: the real data in `../shared/data` and Python
//! with Pixar's USD (`pxr`). A test that needs one asks here; when it is absent the test
//! is skipped with a message, unless `NIMBUS_REQUIRE_DATA=1` is set (as in `.ci/run`),
//! in which case the test fails naming what is missing: no test passes by skipping
//! where its inputs should exist.

use std::path::{Path, PathBuf};
use std::process::Command;

/// The repository root (`CARGO_MANIFEST_DIR`).
pub fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// Whether `NIMBUS_REQUIRE_DATA=1`: a missing input fails the test instead of skipping it.
pub fn data_required() -> bool {
    std::env::var("NIMBUS_REQUIRE_DATA").is_ok_and(|v| v == "1")
}

/// Reports a missing input `what`: panics under `NIMBUS_REQUIRE_DATA=1`, otherwise prints
/// one `SKIPPED: …` line and returns `None` so the caller returns early.
///
/// The line goes to the process' standard error itself, not through `eprintln!`, which
/// the test harness captures and throws away for a test that passes: a user running
/// `cargo t` sees every skip, with what to install (`bash .ci/setup` for what it
/// installs).
pub fn missing<T>(what: &str) -> Option<T> {
    if data_required() {
        panic!("NIMBUS_REQUIRE_DATA=1 but {what}");
    }
    use std::io::Write;
    let test = std::thread::current()
        .name()
        .unwrap_or("a test")
        .to_string();
    // One write of the whole line: the harness prints its `test … ok` lines meanwhile.
    let line = format!("SKIPPED {test}: {what}\n");
    let _ = std::io::stderr().lock().write_all(line.as_bytes());
    None
}

/// Where the shared data is looked for: `NIMBUS_SHARED_DATA` if set, otherwise
/// `../shared/data` beside the repository.
pub fn shared_data_location() -> PathBuf {
    match std::env::var_os("NIMBUS_SHARED_DATA") {
        Some(p) => PathBuf::from(p),
        None => repo().join("../shared/data"),
    }
}

/// The shared data directory, or `None` (skip) when it is absent; fails the test under
/// `NIMBUS_REQUIRE_DATA=1`.
pub fn shared_data() -> Option<PathBuf> {
    let dir = shared_data_location();
    if dir.is_dir() {
        Some(dir)
    } else {
        missing(&format!(
            "{} is absent (the shared data; NIMBUS_SHARED_DATA overrides the location)",
            dir.display()
        ))
    }
}

/// The file `rel` under the shared data, or `None` (skip) when it or the directory is
/// absent; fails the test under `NIMBUS_REQUIRE_DATA=1`.
pub fn shared_file(rel: impl AsRef<Path>) -> Option<PathBuf> {
    let path = shared_data()?.join(rel);
    if path.is_file() {
        Some(path)
    } else {
        missing(&format!(
            "{} is absent from the shared data",
            path.display()
        ))
    }
}

/// Whether `python3` imports every module of `modules`. When one does not import, the
/// test is skipped with a message naming the modules (`install` says what to install),
/// or fails under `NIMBUS_REQUIRE_DATA=1`.
pub fn python_imports(modules: &[&str], install: &str) -> bool {
    let script = [
        "import importlib, sys",
        "missing = []",
        "for m in sys.argv[1:]:",
        "    try:",
        "        importlib.import_module(m)",
        "    except Exception as e:",
        "        missing.append('%s (%s)' % (m, e))",
        "print(', '.join(missing))",
    ]
    .join("\n");
    let missing_modules = match Command::new("python3")
        .arg("-c")
        .arg(script)
        .args(modules)
        .output()
    {
        Ok(o) if o.status.success() => String::from_utf8_lossy(&o.stdout).trim().to_string(),
        Ok(o) => format!(
            "python3 failed: {}",
            String::from_utf8_lossy(&o.stderr).trim()
        ),
        Err(e) => format!("python3 does not run ({e})"),
    };
    if missing_modules.is_empty() {
        return true;
    }
    missing::<()>(&format!(
        "`python3 -c 'import {}'` failed: {missing_modules}; {install}",
        modules.join(", ")
    ));
    false
}

/// What installs the Python modules the fixture scripts import.
pub const SETUP_PYTHON: &str =
    "`bash .ci/setup` installs them (or `python3 -m pip install usd-core OpenEXR numpy`)";

/// Whether `python3` imports Pixar's USD (`pxr`); see [`python_imports`].
pub fn pxr_python() -> bool {
    python_imports(&["pxr"], SETUP_PYTHON)
}

/// Runs the fixture generator `tests/fixtures/SCRIPT` (a Python script authoring stages
/// with Pixar's USD and writing what pxr computes for them to `expected.json`) into a
/// fresh temp dir, with Nimbus' schemas on pxr's plugin path when `schemas`. `None` (with
/// a message; a failure under `NIMBUS_REQUIRE_DATA=1`) when Python lacks one of `modules`.
pub fn pxr_fixtures(
    script: &str,
    modules: &[&str],
    install: &str,
    schemas: bool,
) -> Option<(tempfile::TempDir, serde_json::Value)> {
    if !python_imports(modules, install) {
        return None;
    }
    let dir = tempfile::tempdir().expect("temp dir");
    let mut command = Command::new("python3");
    command
        .arg(repo().join("tests/fixtures").join(script))
        .arg(dir.path());
    if schemas {
        command.env("PXR_PLUGINPATH_NAME", repo().join("schemas"));
    }
    let output = command
        .output()
        .unwrap_or_else(|e| panic!("run {script}: {e}"));
    assert!(
        output.status.success(),
        "{script} failed:\n{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let text = std::fs::read_to_string(dir.path().join("expected.json")).expect("expected.json");
    let expected = serde_json::from_str(&text).expect("expected.json parses");
    Some((dir, expected))
}

/// Whether this build writes deep EXR files (the OpenEXR bridge): probes with a one-pixel
/// image. Without the bridge the write must fail with the documented message; the caller
/// then skips `part` ("the test", or the part of it that needs deep EXRs) with one
/// `SKIPPED` line, unless `NIMBUS_OPENEXR=require` or `NIMBUS_REQUIRE_DATA=1`, where it
/// fails.
pub fn deep_exr_support(part: &str) -> bool {
    use nimbus::output::deep::{write_deep_exr, DeepImage};
    use nimbus::render::film::Region;
    let dir = tempfile::tempdir().expect("temp dir");
    let probe = DeepImage {
        full: (1, 1),
        region: Region::full(1, 1),
        counts: vec![0],
        samples: vec![],
        attributes: vec![],
    };
    let Err(e) = write_deep_exr(&dir.path().join("probe.exr"), &probe) else {
        return true;
    };
    let e = e.to_string();
    assert!(
        e.contains(
            "deep EXR output needs OpenEXR's C++ library; this build has none (NIMBUS_OPENEXR)"
        ),
        "{e}"
    );
    if std::env::var("NIMBUS_OPENEXR").is_ok_and(|v| v == "require") {
        panic!("NIMBUS_OPENEXR=require but {e}");
    }
    missing::<()>(&format!(
        "{part}: no deep EXR support in this build ({e}); `bash .ci/setup` installs libopenexr-dev"
    ));
    false
}

/// Whether this build has the OpenVDB bridge, for tests that compare the two VDB readers:
/// without it the comparison `part` is skipped with one `SKIPPED` line (the Rust reader's
/// own checks still run), or fails under `NIMBUS_REQUIRE_DATA=1`.
pub fn openvdb_bridge(part: &str) -> bool {
    if nimbus::volume::vdb::Reader::OpenVdb.available() {
        return true;
    }
    missing::<()>(&format!(
        "{part}: built without OpenVDB; `bash .ci/setup` installs libopenvdb-dev and the next \
         build uses it"
    ));
    false
}

/// The Python that imports bpy 5.0.1 and the modules `imports` names (e.g.
/// `"bpy, numpy"`), from `NIMBUS_BPY_PYTHON`, or `None` (skip; fails under
/// `NIMBUS_REQUIRE_DATA=1`).
pub fn bpy_python(imports: &str) -> Option<std::path::PathBuf> {
    use std::path::Path;
    let Some(python) = std::env::var_os("NIMBUS_BPY_PYTHON") else {
        return missing(
            "NIMBUS_BPY_PYTHON is not set (a CPython 3.11 with `pip install bpy==5.0.1`)",
        );
    };
    let o = std::process::Command::new(&python)
        .args([
            "-c",
            &format!("import {imports}; print(bpy.app.version_string)"),
        ])
        .output();
    match o {
        Ok(o) if o.status.success() => {
            let version = String::from_utf8_lossy(&o.stdout).trim().to_string();
            if version.lines().last() == Some("5.0.1") {
                Some(std::path::PathBuf::from(python))
            } else {
                missing(&format!(
                    "NIMBUS_BPY_PYTHON={} has bpy {version:?}, not 5.0.1",
                    Path::new(&python).display()
                ))
            }
        }
        Ok(o) => missing(&format!(
            "NIMBUS_BPY_PYTHON={} does not import {imports}: {}",
            Path::new(&python).display(),
            String::from_utf8_lossy(&o.stderr).trim()
        )),
        Err(e) => missing(&format!(
            "NIMBUS_BPY_PYTHON={} does not run: {e}",
            Path::new(&python).display()
        )),
    }
}

/// Whether this build denoises (Open Image Denoise found by build.rs, and it loads):
/// without it `part` is skipped with one `SKIPPED` line, or fails under
/// `NIMBUS_REQUIRE_DATA=1` (CI, which also builds with `NIMBUS_OIDN=require`).
pub fn oidn(part: &str) -> bool {
    match nimbus::output::denoise::check_available() {
        Ok(()) => true,
        Err(e) => {
            missing::<()>(&format!("{part}: {e}"));
            false
        }
    }
}

/// Runs the fixture script `script` (under tests/fixtures) with `python` and `args`;
/// panics with its output if it fails. Returns its output.
pub fn run_fixture<I, S>(
    python: impl AsRef<std::ffi::OsStr>,
    script: &str,
    args: I,
) -> std::process::Output
where
    I: IntoIterator<Item = S>,
    S: AsRef<std::ffi::OsStr>,
{
    let out = std::process::Command::new(python)
        .arg(repo().join("tests/fixtures").join(script))
        .args(args)
        .output()
        .unwrap_or_else(|e| panic!("run {script}: {e}"));
    assert!(
        out.status.success(),
        "{script} failed:\n{}\n{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    out
}
