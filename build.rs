//! Build script: compiles the C++ bridges (`cpp/`) when their libraries are available:
//! OpenVDB (reading VDB files) and OpenEXR (deep EXR files, which the pure-Rust `exr`
//! crate cannot write).
//!
//! `NIMBUS_OPENVDB` and `NIMBUS_OPENEXR` each select the behaviour for their library:
//! - `auto` (default): use the library when its header and library are found, else build
//!   without the bridge (for OpenVDB, Nimbus' own Rust reader is then the only one;
//!   for OpenEXR, writing or reading a deep EXR is an error);
//! - `require`: fail the build with a clear message when the library is missing (CI);
//! - `off`: never build the bridge.
//!
//! When a bridge is built, the cfg `nimbus_openvdb` / `nimbus_openexr` is set for the
//! Rust code. `OPENVDB_INCLUDE_DIR` / `OPENVDB_LIB_DIR` and `OPENEXR_INCLUDE_DIR` /
//! `OPENEXR_LIB_DIR` point the searches at a non-system install.

use std::env;
use std::path::{Path, PathBuf};

fn main() {
    println!("cargo::rustc-check-cfg=cfg(nimbus_openvdb)");
    println!("cargo::rustc-check-cfg=cfg(nimbus_openexr)");
    for var in [
        "NIMBUS_OPENVDB",
        "OPENVDB_INCLUDE_DIR",
        "OPENVDB_LIB_DIR",
        "NIMBUS_OPENEXR",
        "OPENEXR_INCLUDE_DIR",
        "OPENEXR_LIB_DIR",
    ] {
        println!("cargo:rerun-if-env-changed={var}");
    }
    println!("cargo:rerun-if-changed=build.rs");

    if let Some(required) = mode("NIMBUS_OPENVDB", "the OpenVDB bridge (Rust reader only)") {
        match find_openvdb() {
            Ok(found) => build_bridge(&found),
            Err(why) => missing(
                required,
                "NIMBUS_OPENVDB",
                "OpenVDB",
                &why,
                "`apt-get install libopenvdb-dev libboost-dev` or set OPENVDB_INCLUDE_DIR / OPENVDB_LIB_DIR",
                "the OpenVDB bridge (Rust reader only)",
            ),
        }
    }
    if let Some(required) = mode("NIMBUS_OPENEXR", "the OpenEXR bridge (no deep EXR)") {
        match find_openexr() {
            Ok(found) => build_exr_bridge(&found),
            Err(why) => missing(
                required,
                "NIMBUS_OPENEXR",
                "OpenEXR's C++ library",
                &why,
                "`apt-get install libopenexr-dev` or set OPENEXR_INCLUDE_DIR / OPENEXR_LIB_DIR",
                "the OpenEXR bridge (no deep EXR)",
            ),
        }
    }
}

/// The mode `var` asks for: `None` for off, `Some(required)` otherwise. `without` says
/// what an `off` build lacks.
fn mode(var: &str, without: &str) -> Option<bool> {
    let mode = env::var(var).unwrap_or_else(|_| "auto".to_string());
    let mode = mode.trim().to_ascii_lowercase();
    match mode.as_str() {
        "off" | "0" | "no" | "false" => {
            println!("cargo:warning={var}=off: building without {without}");
            None
        }
        "auto" | "" => Some(false),
        "require" | "on" | "1" | "yes" | "true" => Some(true),
        other => panic!("{var} must be auto, require or off (got {other:?})"),
    }
}

/// A library that was not found: a build failure when `required`, else a warning.
fn missing(required: bool, var: &str, library: &str, why: &str, install: &str, without: &str) {
    if required {
        panic!(
            "{var}=require but {library} was not found: {why}.\n\
             Install it ({install}), or build with {var}=auto|off."
        );
    }
    println!("cargo:warning={library} not found ({why}); building without {without}");
}

struct OpenVdb {
    include_dirs: Vec<PathBuf>,
    lib_dir: PathBuf,
}

fn find_openvdb() -> Result<OpenVdb, String> {
    let includes = candidates(
        "OPENVDB_INCLUDE_DIR",
        &["/usr/include", "/usr/local/include"],
    );
    let include = includes
        .iter()
        .find(|d| d.join("openvdb/openvdb.h").is_file())
        .cloned()
        .ok_or_else(|| format!("no openvdb/openvdb.h in {}", join_paths(&includes)))?;
    let libs = lib_candidates("OPENVDB_LIB_DIR");
    let lib_dir = libs
        .iter()
        .find(|d| find_lib(d, "openvdb").as_deref() == Some("openvdb"))
        .cloned()
        .ok_or_else(|| format!("no libopenvdb in {}", join_paths(&libs)))?;

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

/// The directory named by the environment variable `var` (if set), then `defaults`.
fn candidates(var: &str, defaults: &[&str]) -> Vec<PathBuf> {
    let mut dirs: Vec<PathBuf> = env::var(var).ok().map(PathBuf::from).into_iter().collect();
    dirs.extend(defaults.iter().map(PathBuf::from));
    dirs
}

/// Library folders to search: `var`'s, the multiarch folder, then the usual ones.
fn lib_candidates(var: &str) -> Vec<PathBuf> {
    let arch = env::var("CARGO_CFG_TARGET_ARCH").unwrap_or_default();
    let os = env::var("CARGO_CFG_TARGET_OS").unwrap_or_default();
    let mut dirs = candidates(var, &[]);
    dirs.push(format!("/usr/lib/{arch}-{os}-gnu").into());
    dirs.extend(
        [
            "/usr/lib",
            "/usr/lib64",
            "/usr/local/lib",
            "/usr/local/lib64",
        ]
        .map(PathBuf::from),
    );
    dirs
}

/// The link name of library `name` in `dir`: `name` itself when `libNAME.so` (or `.a`,
/// `.dylib`) is there, else a versioned `NAME-X_Y` (OpenEXR and Imath 3 install
/// `libOpenEXR-3_1.so`, with the unversioned link only in some packages).
fn find_lib(dir: &Path, name: &str) -> Option<String> {
    let has = |stem: &str| {
        ["so", "a", "dylib"]
            .iter()
            .any(|ext| dir.join(format!("lib{stem}.{ext}")).exists())
    };
    if has(name) {
        return Some(name.to_string());
    }
    let prefix = format!("lib{name}-");
    let mut versioned: Vec<String> = std::fs::read_dir(dir)
        .ok()?
        .filter_map(|e| e.ok()?.file_name().into_string().ok())
        .filter_map(|f| {
            let stem = f.strip_prefix("lib")?.split('.').next()?.to_string();
            (f.starts_with(&prefix) && has(&stem)).then_some(stem)
        })
        .collect();
    // The newest version: `-3_10` sorts after `-3_9` by its numbers, not as text.
    versioned.sort_by_key(|s| version_key(&s[name.len()..]));
    versioned.pop()
}

fn version_key(suffix: &str) -> Vec<u32> {
    suffix
        .trim_start_matches('-')
        .split('_')
        .map(|p| p.parse().unwrap_or(0))
        .collect()
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
    println!("cargo:rerun-if-changed=cpp/guarded.h");
    println!("cargo:rustc-link-search=native={}", found.lib_dir.display());
    for lib in ["openvdb", "tbb", "Imath-3_1"] {
        println!("cargo:rustc-link-lib={lib}");
    }
    println!("cargo:rustc-cfg=nimbus_openvdb");
}

/// OpenEXR's C++ library (3.x): its header folders and the link names of its libraries.
struct OpenExr {
    /// `.../OpenEXR` and `.../Imath`: OpenEXR's headers include both without a prefix.
    include_dirs: Vec<PathBuf>,
    /// Each library's folder and link name.
    libs: Vec<(PathBuf, String)>,
}

fn find_openexr() -> Result<OpenExr, String> {
    let includes = candidates(
        "OPENEXR_INCLUDE_DIR",
        &["/usr/include", "/usr/local/include"],
    );
    let include = includes
        .iter()
        .find(|d| d.join("OpenEXR/ImfDeepScanLineOutputFile.h").is_file())
        .cloned()
        .ok_or_else(|| {
            format!(
                "no OpenEXR/ImfDeepScanLineOutputFile.h in {}",
                join_paths(&includes)
            )
        })?;
    let lib_dirs = lib_candidates("OPENEXR_LIB_DIR");
    // Imath may sit in another prefix than OpenEXR (its own package); look in both.
    let imath_include = [include.clone()]
        .into_iter()
        .chain(includes.iter().cloned())
        .map(|d| d.join("Imath"))
        .find(|d| d.join("ImathBox.h").is_file())
        .ok_or("no Imath/ImathBox.h beside OpenEXR's headers")?;
    let libs = ["OpenEXR", "Iex", "IlmThread", "Imath"]
        .iter()
        .map(|name| {
            lib_dirs
                .iter()
                .find_map(|d| Some((d.clone(), find_lib(d, name)?)))
                .ok_or_else(|| format!("no lib{name} in {}", join_paths(&lib_dirs)))
        })
        .collect::<Result<Vec<_>, _>>()?;
    Ok(OpenExr {
        include_dirs: vec![include.join("OpenEXR"), imath_include],
        libs,
    })
}

fn build_exr_bridge(found: &OpenExr) {
    let mut build = cxx_build::bridge("src/output/deep_bridge.rs");
    build
        .file("cpp/exr_deep.cc")
        .std("c++17")
        .flag_if_supported("-Wno-deprecated-declarations");
    for dir in &found.include_dirs {
        build.include(dir);
    }
    build.compile("nimbus_exr_bridge");

    println!("cargo:rerun-if-changed=src/output/deep_bridge.rs");
    println!("cargo:rerun-if-changed=cpp/exr_deep.h");
    println!("cargo:rerun-if-changed=cpp/exr_deep.cc");
    println!("cargo:rerun-if-changed=cpp/guarded.h");
    let mut searched: Vec<&PathBuf> = Vec::new();
    for (dir, lib) in &found.libs {
        if !searched.contains(&dir) {
            println!("cargo:rustc-link-search=native={}", dir.display());
            searched.push(dir);
        }
        println!("cargo:rustc-link-lib={lib}");
    }
    println!("cargo:rustc-cfg=nimbus_openexr");
}
