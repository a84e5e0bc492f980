//! Build script: compiles the OpenVDB C++ bridge (`cpp/`) when OpenVDB is available.
//!
//! `NIMBUS_OPENVDB` selects the behaviour:
//! - `auto` (default): use OpenVDB when its header and library are found, else build
//!   without the bridge (the pure-Rust vdb-rs reader is then the only one);
//! - `require`: fail the build with a clear message when OpenVDB is missing (CI);
//! - `off`: never build the bridge.
//!
//! When the bridge is built, the cfg `nimbus_openvdb` is set for the Rust code.
//! `OPENVDB_INCLUDE_DIR` / `OPENVDB_LIB_DIR` point the search at a non-system install.

use std::env;
use std::path::PathBuf;

fn main() {
    println!("cargo::rustc-check-cfg=cfg(nimbus_openvdb)");
    println!("cargo:rerun-if-env-changed=NIMBUS_OPENVDB");
    println!("cargo:rerun-if-env-changed=OPENVDB_INCLUDE_DIR");
    println!("cargo:rerun-if-env-changed=OPENVDB_LIB_DIR");
    println!("cargo:rerun-if-changed=build.rs");

    let mode = env::var("NIMBUS_OPENVDB").unwrap_or_else(|_| "auto".to_string());
    let mode = mode.trim().to_ascii_lowercase();
    match mode.as_str() {
        "off" | "0" | "no" | "false" => {
            println!("cargo:warning=NIMBUS_OPENVDB=off: building without the OpenVDB bridge (vdb-rs only)");
            return;
        }
        "auto" | "" | "require" | "on" | "1" | "yes" | "true" => {}
        other => panic!("NIMBUS_OPENVDB must be auto, require or off (got {other:?})"),
    }
    let required = !matches!(mode.as_str(), "auto" | "");

    match find_openvdb() {
        Ok(found) => build_bridge(&found),
        Err(why) => {
            if required {
                panic!(
                    "NIMBUS_OPENVDB={mode} but OpenVDB was not found: {why}.\n\
                     Install it (Debian/Ubuntu: `apt-get install libopenvdb-dev libboost-dev`) \
                     or set OPENVDB_INCLUDE_DIR / OPENVDB_LIB_DIR, or build with NIMBUS_OPENVDB=auto|off."
                );
            }
            println!(
                "cargo:warning=OpenVDB not found ({why}); building without the OpenVDB bridge (vdb-rs only)"
            );
        }
    }
}

struct OpenVdb {
    include_dirs: Vec<PathBuf>,
    lib_dir: PathBuf,
}

fn find_openvdb() -> Result<OpenVdb, String> {
    let mut include_candidates: Vec<PathBuf> = Vec::new();
    if let Ok(dir) = env::var("OPENVDB_INCLUDE_DIR") {
        include_candidates.push(dir.into());
    }
    include_candidates.extend(["/usr/include", "/usr/local/include"].map(PathBuf::from));
    let include = include_candidates
        .iter()
        .find(|d| d.join("openvdb/openvdb.h").is_file())
        .cloned()
        .ok_or_else(|| {
            format!(
                "no openvdb/openvdb.h in {}",
                join_paths(&include_candidates)
            )
        })?;

    let mut lib_candidates: Vec<PathBuf> = Vec::new();
    if let Ok(dir) = env::var("OPENVDB_LIB_DIR") {
        lib_candidates.push(dir.into());
    }
    let arch = env::var("CARGO_CFG_TARGET_ARCH").unwrap_or_default();
    let os = env::var("CARGO_CFG_TARGET_OS").unwrap_or_default();
    lib_candidates.push(format!("/usr/lib/{arch}-{os}-gnu").into());
    lib_candidates.extend(
        [
            "/usr/lib",
            "/usr/lib64",
            "/usr/local/lib",
            "/usr/local/lib64",
        ]
        .map(PathBuf::from),
    );
    let lib_dir = lib_candidates
        .iter()
        .find(|d| {
            d.join("libopenvdb.so").exists()
                || d.join("libopenvdb.a").exists()
                || d.join("libopenvdb.dylib").exists()
        })
        .cloned()
        .ok_or_else(|| format!("no libopenvdb in {}", join_paths(&lib_candidates)))?;

    let mut include_dirs = vec![include.clone()];
    // Imath's headers include each other without the `Imath/` prefix.
    let imath = include.join("Imath");
    if imath.is_dir() {
        include_dirs.push(imath);
    }
    Ok(OpenVdb {
        include_dirs,
        lib_dir,
    })
}

fn join_paths(paths: &[PathBuf]) -> String {
    paths
        .iter()
        .map(|p| p.display().to_string())
        .collect::<Vec<_>>()
        .join(", ")
}

fn build_bridge(found: &OpenVdb) {
    let mut build = cxx_build::bridge("src/volume/vdb/bridge.rs");
    build
        .file("cpp/vdb_bridge.cc")
        .std("c++17")
        .flag_if_supported("-Wno-deprecated-declarations");
    for dir in &found.include_dirs {
        build.include(dir);
    }
    build.compile("nimbus_vdb_bridge");

    println!("cargo:rerun-if-changed=src/volume/vdb/bridge.rs");
    println!("cargo:rerun-if-changed=cpp/vdb_bridge.h");
    println!("cargo:rerun-if-changed=cpp/vdb_bridge.cc");
    println!("cargo:rustc-link-search=native={}", found.lib_dir.display());
    for lib in ["openvdb", "tbb", "Imath-3_1"] {
        println!("cargo:rustc-link-lib={lib}");
    }
    println!("cargo:rustc-cfg=nimbus_openvdb");
}
