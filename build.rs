//! Build script: compiles the C++ bridges (`cpp/`) when their libraries are available:
//! OpenVDB (reading VDB files) and OpenEXR (deep EXR files, which the pure-Rust `exr`
//! crate cannot write); and finds Open Image Denoise (denoising, `--denoise`).
//!
//! `NIMBUS_OIDN` (same modes) looks for `libOpenImageDenoise.so.2` in `OIDN_DIR/lib`
//! (the `oidn` crate's variable), in the `pyoidn` package of `python3` (PyPI's wheel
//! ships the library, no headers: none are needed), then in the system library
//! folders. Found, the cfg `nimbus_oidn` is set and the file's path is compiled in
//! (`NIMBUS_OIDN_LIBRARY`): src/output/denoise.rs loads it at run time, so nothing
//! links against it and a binary whose library went away still runs (denoising then
//! fails in one line).
//!
//! `NIMBUS_OPENVDB` and `NIMBUS_OPENEXR` each select the behaviour for their library:
//! - `auto` (default): use the library when its header and library are found, else build
//!   without the bridge (for OpenVDB the pure-Rust reader is then the only one; for
//!   OpenEXR, writing or reading a deep EXR is an error);
//! - `require`: fail the build with a clear message when the library is missing (CI);
//! - `off`: never build the bridge.
//!
//! When a bridge is built, the cfg `nimbus_openvdb` / `nimbus_openexr` is set for the
//! Rust code. `OPENVDB_INCLUDE_DIR` / `OPENVDB_LIB_DIR` and `OPENEXR_INCLUDE_DIR` /
//! `OPENEXR_LIB_DIR` point the searches at a non-system install; `NIMBUS_SYSROOT`
//! (default `/`) is prefixed to the system folders searched (a cross-compilation sysroot,
//! and how tests/build_detection.rs gives the script a system of its own).
//!
//! The search is redone whenever a searched folder changes: the header folders, the
//! multiarch library folder and the folders the environment names, where they exist, are
//! handed to cargo with `rerun-if-changed` (cargo compares the newest modification time
//! in and below each), so installing or removing `libopenvdb-dev` after a first build
//! makes the next `cargo build` / `cargo t` run this script again and build with (or
//! without) the bridge, with no `touch build.rs` ([`watch_searched_folders`] says which
//! folders and why). Folders that do not exist are not watched (cargo would rerun the
//! script, and rebuild the library, on every build). The script says which VDB reader and
//! which deep-EXR support the build got, in one `warning:` line each.

use std::env;
use std::path::{Path, PathBuf};

fn main() {
    println!("cargo::rustc-check-cfg=cfg(nimbus_openvdb)");
    println!("cargo::rustc-check-cfg=cfg(nimbus_openexr)");
    println!("cargo::rustc-check-cfg=cfg(nimbus_oidn)");
    for var in [
        "NIMBUS_OIDN",
        "OIDN_DIR",
        "OIDN_LIB_DIR",
        "NIMBUS_OPENVDB",
        "OPENVDB_INCLUDE_DIR",
        "OPENVDB_LIB_DIR",
        "NIMBUS_OPENEXR",
        "OPENEXR_INCLUDE_DIR",
        "OPENEXR_LIB_DIR",
        "NIMBUS_SYSROOT",
    ] {
        println!("cargo:rerun-if-env-changed={var}");
    }
    println!("cargo:rerun-if-changed=build.rs");
    watch_searched_folders();

    let vdb = match mode("NIMBUS_OPENVDB") {
        None => "the pure-Rust reader (NIMBUS_OPENVDB=off)".to_string(),
        Some(required) => match find_openvdb() {
            Ok(found) => {
                build_bridge(&found);
                format!(
                    "OpenVDB through the C++ bridge ({}, {})",
                    found.include_dirs[0].display(),
                    found.lib_dir.display()
                )
            }
            Err(why) => missing(
                required,
                "NIMBUS_OPENVDB",
                "OpenVDB",
                &why,
                "`bash .ci/setup`, or `apt-get install libopenvdb-dev libboost-dev`, or set OPENVDB_INCLUDE_DIR / OPENVDB_LIB_DIR",
                "the pure-Rust reader",
            ),
        },
    };
    println!("cargo:warning=VDB files are read by {vdb}");

    let exr = match mode("NIMBUS_OPENEXR") {
        None => "deep EXR: not built in (NIMBUS_OPENEXR=off)".to_string(),
        Some(required) => match find_openexr() {
            Ok(found) => {
                build_exr_bridge(&found);
                "deep EXR: OpenEXR's C++ library through the C++ bridge".to_string()
            }
            Err(why) => format!(
                "deep EXR: {}",
                missing(
                    required,
                    "NIMBUS_OPENEXR",
                    "OpenEXR's C++ library",
                    &why,
                    "`bash .ci/setup`, or `apt-get install libopenexr-dev`, or set OPENEXR_INCLUDE_DIR / OPENEXR_LIB_DIR",
                    "not built in",
                )
            ),
        },
    };
    println!("cargo:warning={exr}");

    let oidn = match mode("NIMBUS_OIDN") {
        None => "denoising: not built in (NIMBUS_OIDN=off)".to_string(),
        Some(required) => match find_oidn() {
            Ok(lib) => {
                println!("cargo:rerun-if-changed={}", lib.display());
                println!("cargo:rustc-env=NIMBUS_OIDN_LIBRARY={}", lib.display());
                println!("cargo:rustc-cfg=nimbus_oidn");
                format!(
                    "denoising: Open Image Denoise, loaded at run time from {}",
                    lib.display()
                )
            }
            Err(why) => format!(
                "denoising: {}",
                missing(
                    required,
                    "NIMBUS_OIDN",
                    "Open Image Denoise 2.x",
                    &why,
                    "`bash .ci/setup`, or `python3 -m pip install pyoidn`, or set OIDN_DIR",
                    "not built in",
                )
            ),
        },
    };
    println!("cargo:warning={oidn}");
}

/// OIDN's library file: `OIDN_DIR/lib` (or `lib64`), the `pyoidn` wheel's
/// `oidn/lib` of `python3`, then the system library folders.
fn find_oidn() -> Result<PathBuf, String> {
    const FILE: &str = "libOpenImageDenoise.so.2";
    let mut dirs: Vec<PathBuf> = Vec::new();
    if let Some(d) = env::var_os("OIDN_DIR").filter(|d| !d.is_empty()) {
        let d = PathBuf::from(d);
        dirs.extend([d.join("lib"), d.join("lib64"), d]);
    }
    dirs.extend(pyoidn_lib_dir());
    dirs.extend(lib_candidates("OIDN_LIB_DIR"));
    dirs.iter()
        .map(|d| d.join(FILE))
        .find(|f| f.is_file())
        .ok_or_else(|| format!("no {FILE} in {}", join_paths(&dirs)))
}

/// Where the `pyoidn` package of `python3` keeps its library, if it is installed:
/// asked without importing it (`find_spec` reads no module), so this costs one
/// interpreter start. The folder is watched (pip replacing the wheel reruns this).
fn pyoidn_lib_dir() -> Option<PathBuf> {
    let out = std::process::Command::new("python3")
        .args([
            "-c",
            "import importlib.util as u; s = u.find_spec('pyoidn'); \
             print(s.submodule_search_locations[0] if s else '')",
        ])
        .output()
        .ok()?;
    let text = String::from_utf8_lossy(&out.stdout).trim().to_string();
    let dir = PathBuf::from(&text).join("oidn/lib");
    if !out.status.success() || text.is_empty() || !dir.is_dir() {
        return None;
    }
    println!("cargo:rerun-if-changed={}", dir.display());
    Some(dir)
}

/// The system header folders searched (under `NIMBUS_SYSROOT`).
const INCLUDE_DIRS: [&str; 2] = ["/usr/include", "/usr/local/include"];

/// Debian's multiarch library folder, e.g. `/usr/lib/x86_64-linux-gnu`.
fn multiarch_dir() -> PathBuf {
    let arch = env::var("CARGO_CFG_TARGET_ARCH").unwrap_or_default();
    let os = env::var("CARGO_CFG_TARGET_OS").unwrap_or_default();
    system_dir(&format!("/usr/lib/{arch}-{os}-gnu"))
}

/// `NIMBUS_SYSROOT` (default `/`) joined with the system folder `dir`.
fn system_dir(dir: &str) -> PathBuf {
    let root = env::var_os("NIMBUS_SYSROOT")
        .filter(|r| !r.is_empty())
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from("/"));
    root.join(dir.trim_start_matches('/'))
}

/// Hands the searched folders that exist to cargo, so that this script runs again when a
/// library appears in one or leaves it: the header folders (a library is found by its
/// header first, and installs its header with it), the folders named by the environment
/// and the multiarch library folder, where Debian installs these libraries. Left out,
/// because cargo would walk them on every build and rebuild Nimbus whenever anything in
/// them changes: `/usr/lib` (some 70,000 files: Python, Perl…), `/usr/lib64` and
/// `/usr/local/lib` (pip's `dist-packages`). A library found in one of those is watched
/// as a file ([`watch_library`]), so removing it is noticed too.
fn watch_searched_folders() {
    let mut dirs: Vec<PathBuf> = Vec::new();
    for var in ["OPENVDB_INCLUDE_DIR", "OPENEXR_INCLUDE_DIR"] {
        dirs.extend(candidates(var, &INCLUDE_DIRS));
    }
    for var in ["OPENVDB_LIB_DIR", "OPENEXR_LIB_DIR"] {
        dirs.extend(candidates(var, &[]));
    }
    dirs.push(multiarch_dir());
    let mut watched: Vec<PathBuf> = Vec::new();
    for dir in dirs {
        if dir.is_dir() && !watched.contains(&dir) {
            println!("cargo:rerun-if-changed={}", dir.display());
            watched.push(dir);
        }
    }
}

/// Watches the file of library `name` found in `dir` (its removal reruns this script),
/// for the folders [`watch_searched_folders`] leaves out.
fn watch_library(dir: &Path, name: &str) {
    for ext in ["so", "a", "dylib"] {
        let file = dir.join(format!("lib{name}.{ext}"));
        if file.exists() {
            println!("cargo:rerun-if-changed={}", file.display());
        }
    }
}

/// The mode `var` asks for: `None` for off, `Some(required)` otherwise.
fn mode(var: &str) -> Option<bool> {
    let mode = env::var(var).unwrap_or_else(|_| "auto".to_string());
    let mode = mode.trim().to_ascii_lowercase();
    match mode.as_str() {
        "off" | "0" | "no" | "false" => None,
        "auto" | "" => Some(false),
        "require" | "on" | "1" | "yes" | "true" => Some(true),
        other => panic!("{var} must be auto, require or off (got {other:?})"),
    }
}

/// A library that was not found: a build failure when `required`, else what the build
/// does without it (`without`), with why and how to install it.
fn missing(
    required: bool,
    var: &str,
    library: &str,
    why: &str,
    install: &str,
    without: &str,
) -> String {
    if required {
        panic!(
            "{var}=require but {library} was not found: {why}.\n\
             Install it ({install}), or build with {var}=auto|off."
        );
    }
    format!(
        "{without}: {library} was not found ({why}); install it ({install}) and the next build uses it"
    )
}

struct OpenVdb {
    include_dirs: Vec<PathBuf>,
    lib_dir: PathBuf,
}

fn find_openvdb() -> Result<OpenVdb, String> {
    let includes = candidates("OPENVDB_INCLUDE_DIR", &INCLUDE_DIRS);
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
    dirs.extend(defaults.iter().map(|d| system_dir(d)));
    dirs
}

/// Library folders to search: `var`'s, the multiarch folder, then the usual ones.
fn lib_candidates(var: &str) -> Vec<PathBuf> {
    let mut dirs = candidates(var, &[]);
    dirs.push(multiarch_dir());
    dirs.extend(
        [
            "/usr/lib",
            "/usr/lib64",
            "/usr/local/lib",
            "/usr/local/lib64",
        ]
        .map(system_dir),
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
    watch_library(&found.lib_dir, "openvdb");
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
    let includes = candidates("OPENEXR_INCLUDE_DIR", &INCLUDE_DIRS);
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
        watch_library(dir, lib);
        println!("cargo:rustc-link-lib={lib}");
    }
    println!("cargo:rustc-cfg=nimbus_openexr");
}
