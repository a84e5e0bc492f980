//! `build.rs` redoes its library search when a library is installed or removed after a
//! first build (issue 42: a user who installs OpenVDB after a first `cargo t` gets the
//! bridge with no `touch build.rs`).
//!
//! The real `build.rs`, verbatim but for its inner doc comment, is the build script of
//! a probe crate in a temp folder, with `cxx_build` replaced by a stub that compiles
//! nothing (the probe only shows what the script decides). `NIMBUS_SYSROOT` gives the
//! script a system of its own, where the test installs and removes a fake OpenVDB the
//! way `dpkg` does: files with old modification times in existing folders. Cargo runs
//! the probe's build script again exactly when the test changed that system, and the
//! script's cfg follows what is installed.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, SystemTime};

/// `cxx_build` as far as `build.rs` calls it, compiling nothing. A local module shadows
/// the crate of the same name in paths.
const CXX_BUILD_STUB: &str = r#"
mod cxx_build {
    pub struct Build;
    pub fn bridge(_: &str) -> Build {
        Build
    }
    impl Build {
        pub fn file(&mut self, _: &str) -> &mut Self {
            self
        }
        pub fn std(&mut self, _: &str) -> &mut Self {
            self
        }
        pub fn flag_if_supported(&mut self, _: &str) -> &mut Self {
            self
        }
        pub fn include<P: AsRef<std::path::Path>>(&mut self, _: P) -> &mut Self {
            self
        }
        pub fn compile(&mut self, _: &str) {}
    }
}
"#;

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// The probe crate in `dir`: the real build script, and the files it watches by relative
/// path (the bridges' sources), so that only the system folders can make it rerun.
fn write_probe(dir: &Path) {
    let script = std::fs::read_to_string(repo().join("build.rs")).expect("read build.rs");
    let body: String = script
        .lines()
        .filter(|l| !l.trim_start().starts_with("//!"))
        .map(|l| format!("{l}\n"))
        .collect();
    std::fs::create_dir_all(dir.join("src")).unwrap();
    std::fs::write(dir.join("build.rs"), format!("{CXX_BUILD_STUB}\n{body}")).unwrap();
    std::fs::write(dir.join("src/lib.rs"), "").unwrap();
    std::fs::write(
        dir.join("Cargo.toml"),
        "[package]\nname = \"probe\"\nversion = \"0.1.0\"\nedition = \"2021\"\nbuild = \"build.rs\"\n\n[workspace]\n",
    )
    .unwrap();
    // Every literal relative path the script watches (`cargo:rerun-if-changed=cpp/…`).
    for piece in script.split("cargo:rerun-if-changed=").skip(1) {
        let path = piece.split('"').next().unwrap_or_default();
        if !path.is_empty() && !path.contains('{') && path != "build.rs" {
            let file = dir.join(path);
            std::fs::create_dir_all(file.parent().unwrap()).unwrap();
            std::fs::write(file, "").unwrap();
        }
    }
}

/// What one `cargo build` of the probe did: whether the build script ran, and its output.
struct Build {
    script_ran: bool,
    output: String,
}

impl Build {
    fn has_bridge(&self) -> bool {
        self.output.contains("cargo:rustc-cfg=nimbus_openvdb")
    }
}

fn build(probe: &Path, sysroot: &Path, target: &Path) -> Build {
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let out = Command::new(cargo)
        .args(["build", "-vv", "--offline"])
        .current_dir(probe)
        .env("NIMBUS_SYSROOT", sysroot)
        .env("NIMBUS_OPENVDB", "auto")
        .env("NIMBUS_OPENEXR", "auto")
        // Open Image Denoise is looked for outside the sysroot too (python3's pyoidn):
        // found or not, it must not fail the probe (CI requires it for the real build).
        .env("NIMBUS_OIDN", "auto")
        .env("CARGO_TARGET_DIR", target)
        .env_remove("OPENVDB_INCLUDE_DIR")
        .env_remove("OPENVDB_LIB_DIR")
        .env_remove("OPENEXR_INCLUDE_DIR")
        .env_remove("OPENEXR_LIB_DIR")
        .env_remove("OIDN_DIR")
        .env_remove("OIDN_LIB_DIR")
        .env_remove("RUSTFLAGS")
        .output()
        .expect("run cargo");
    let output = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(out.status.success(), "probe build failed:\n{output}");
    Build {
        // cargo -vv prints the script's output lines, prefixed `[probe 0.1.0]`, when it runs it.
        script_ran: output.contains("[probe 0.1.0] cargo:"),
        output,
    }
}

/// A file as `dpkg` leaves it: its modification time is the package's, years old.
fn install(path: &Path) {
    std::fs::create_dir_all(path.parent().unwrap()).unwrap();
    let f = std::fs::File::create(path).unwrap();
    f.set_modified(SystemTime::now() - Duration::from_secs(3 * 365 * 24 * 3600))
        .unwrap();
}

#[test]
fn build_script_reruns_when_openvdb_is_installed_and_removed() {
    let tmp = tempfile::tempdir().unwrap();
    let (probe, sysroot, target) = (
        tmp.path().join("probe"),
        tmp.path().join("sys"),
        tmp.path().join("target"),
    );
    let multiarch = format!(
        "usr/lib/{}-{}-gnu",
        std::env::consts::ARCH,
        std::env::consts::OS
    );
    for dir in [
        "usr/include",
        "usr/local/include",
        "usr/local/lib",
        &multiarch,
    ] {
        std::fs::create_dir_all(sysroot.join(dir)).unwrap();
    }
    write_probe(&probe);
    let header = sysroot.join("usr/include/openvdb/openvdb.h");
    let library = sysroot.join(&multiarch).join("libopenvdb.so");

    let first = build(&probe, &sysroot, &target);
    assert!(first.script_ran && !first.has_bridge(), "{}", first.output);
    assert!(
        first
            .output
            .contains("VDB files are read by the pure-Rust reader: OpenVDB was not found"),
        "the build says which reader it uses:\n{}",
        first.output
    );
    let again = build(&probe, &sysroot, &target);
    assert!(
        !again.script_ran,
        "nothing changed, yet the script ran again (every build would rebuild the library):\n{}",
        again.output
    );

    install(&header);
    install(&library);
    let installed = build(&probe, &sysroot, &target);
    assert!(
        installed.script_ran && installed.has_bridge(),
        "after installing OpenVDB the build must use the bridge:\n{}",
        installed.output
    );
    assert!(
        installed
            .output
            .contains("VDB files are read by OpenVDB through the C++ bridge"),
        "{}",
        installed.output
    );
    assert!(!build(&probe, &sysroot, &target).script_ran);

    std::fs::remove_file(&library).unwrap();
    std::fs::remove_dir_all(header.parent().unwrap()).unwrap();
    let removed = build(&probe, &sysroot, &target);
    assert!(
        removed.script_ran && !removed.has_bridge(),
        "after removing OpenVDB the build must go without the bridge:\n{}",
        removed.output
    );
}
