//! Build script of hdNimbus: compiles the C++ half of the Hydra render delegate
//! (`cpp/hydra/*.cc`) against a host's USD and lays out the plug-in folder.
//!
//! `NIMBUS_HYDRA` selects the behaviour, as `NIMBUS_OPENVDB` does for the OpenVDB bridge:
//! - `auto` (default): build the delegate when `NIMBUS_USD_INCLUDE` (a folder holding
//!   `pxr/pxr.h` and `pxr/imaging/hd/renderDelegate.h`), `NIMBUS_USD_LIB` (a folder
//!   holding `libusd_ms.so`, a monolithic USD as Blender's, or the split `libusd_hd.so`,
//!   `libusd_sdf.so`, … of a USD install, also without the `usd_` prefix or with
//!   Houdini's `pxr_`) and `NIMBUS_TBB_INCLUDE` (a folder holding
//!   `tbb/tbb.h`, the TBB the host's USD was built with) are all found; else build only
//!   the Rust half (its unit tests run, no plug-in) with a warning;
//! - `require`: fail the build with a clear message when one is missing (CI);
//! - `off`: only the Rust half.
//!
//! When the delegate is built, the cfg `nimbus_hydra` is set, and
//! `target/<profile>/hydra/hdNimbus/` receives `plugInfo.json` and a symbolic link
//! `hdNimbus.so` to the library cargo links next (`target/<profile>/libhd_nimbus.so`):
//! `PXR_PLUGINPATH_NAME=target/release/hydra/hdNimbus` makes a host find it. Beside it
//! the command-line host `target/<profile>/hydra/nimbus-hydra` (host.cc) is linked.
//! `NIMBUS_USD_CXXFLAGS` adds compiler flags (e.g. `-D_GLIBCXX_USE_CXX11_ABI=0` for a
//! host built with the old ABI).

use std::env;
use std::path::{Path, PathBuf};

const SOURCES: [&str; 6] = [
    "rendererPlugin.cc",
    "renderDelegate.cc",
    "renderPass.cc",
    "renderBuffer.cc",
    "prims.cc",
    "convert.cc",
];
const HEADERS: [&str; 7] = [
    "rendererPlugin.h",
    "renderDelegate.h",
    "renderPass.h",
    "renderParam.h",
    "renderBuffer.h",
    "prims.h",
    "convert.h",
];

fn main() {
    println!("cargo::rustc-check-cfg=cfg(nimbus_hydra)");
    for var in [
        "NIMBUS_HYDRA",
        "NIMBUS_USD_INCLUDE",
        "NIMBUS_USD_LIB",
        "NIMBUS_TBB_INCLUDE",
        "NIMBUS_USD_CXXFLAGS",
    ] {
        println!("cargo:rerun-if-env-changed={var}");
    }
    println!("cargo:rerun-if-changed=build.rs");
    println!("cargo:rerun-if-changed=plugInfo.json");
    // The SDK's folders, as the root build.rs watches OpenVDB's: a USD or TBB installed
    // into (or removed from) a named folder after a first build reruns this search.
    // A folder that does not exist is not watched (cargo would rerun on every build).
    for var in ["NIMBUS_USD_INCLUDE", "NIMBUS_USD_LIB", "NIMBUS_TBB_INCLUDE"] {
        if let Some(dir) = env::var_os(var).map(PathBuf::from).filter(|d| d.is_dir()) {
            println!("cargo:rerun-if-changed={}", dir.display());
        }
    }

    let mode = env::var("NIMBUS_HYDRA").unwrap_or_else(|_| "auto".to_string());
    let required = match mode.trim().to_ascii_lowercase().as_str() {
        "off" | "0" | "no" | "false" => {
            println!("cargo:warning=NIMBUS_HYDRA=off: building only the Rust half of hdNimbus (no plug-in)");
            remove_plugin();
            return;
        }
        "auto" | "" => false,
        "require" | "on" | "1" | "yes" | "true" => true,
        other => panic!("NIMBUS_HYDRA must be auto, require or off (got {other:?})"),
    };
    match find_usd() {
        Ok(usd) => build_delegate(&usd),
        Err(why) if required => panic!(
            "NIMBUS_HYDRA=require but the USD SDK was not found: {why}.\n\
             Name the host's USD headers, its libraries and TBB's headers with \
             NIMBUS_USD_INCLUDE, NIMBUS_USD_LIB and NIMBUS_TBB_INCLUDE (docs/hydra.md), \
             or build with NIMBUS_HYDRA=auto|off."
        ),
        Err(why) => {
            println!(
                "cargo:warning=USD SDK not found ({why}); building only the Rust half of hdNimbus (no plug-in)"
            );
            remove_plugin();
        }
    }
}

/// `target/<profile>/hydra`, from OUT_DIR (target/<profile>/build/nimbus-hydra-HASH/out).
fn hydra_dir() -> Option<PathBuf> {
    let out = PathBuf::from(env::var("OUT_DIR").ok()?);
    Some(out.ancestors().nth(3)?.join("hydra"))
}

/// A build without the C++ half leaves no plug-in folder or host behind: the library
/// an earlier build's folder links to no longer holds the delegate.
fn remove_plugin() {
    if let Some(dir) = hydra_dir() {
        let _ = std::fs::remove_dir_all(dir.join("hdNimbus"));
        let _ = std::fs::remove_file(dir.join("nimbus-hydra"));
    }
}

struct Usd {
    include: PathBuf,
    lib_dir: PathBuf,
    /// Link names: `usd_ms` (monolithic) or the split libraries.
    libs: Vec<String>,
    tbb_include: PathBuf,
}

fn var_dir(var: &str, must_hold: &[&str]) -> Result<PathBuf, String> {
    let dir = env::var_os(var)
        .map(PathBuf::from)
        .ok_or_else(|| format!("{var} is not set"))?;
    for f in must_hold {
        if !dir.join(f).exists() {
            return Err(format!("{var}={} holds no {f}", dir.display()));
        }
    }
    Ok(dir)
}

fn find_usd() -> Result<Usd, String> {
    let include = var_dir(
        "NIMBUS_USD_INCLUDE",
        &["pxr/pxr.h", "pxr/imaging/hd/renderDelegate.h"],
    )?;
    let tbb_include = var_dir("NIMBUS_TBB_INCLUDE", &["tbb/tbb.h"])?;
    let lib_dir = var_dir("NIMBUS_USD_LIB", &[])?;
    let has = |name: &str| lib_dir.join(format!("lib{name}.so")).exists();
    // USD's libraries carry a prefix (PXR_LIB_PREFIX): `usd_` by default, none in some
    // builds, `pxr_` in Houdini's.
    let prefix = ["usd_", "pxr_", ""]
        .into_iter()
        .find(|p| has(&format!("{p}hd")) || has(&format!("{p}usd_ms")) || has(&format!("{p}ms")));
    let libs = if has("usd_ms") {
        vec!["usd_ms".to_string()]
    } else if has("pxr_usd_ms") {
        vec!["pxr_usd_ms".to_string()]
    } else {
        let Some(prefix) = prefix.filter(|p| has(&format!("{p}hd"))) else {
            return Err(format!(
                "NIMBUS_USD_LIB={} holds neither libusd_ms.so nor libusd_hd.so / libhd.so / libpxr_hd.so",
                lib_dir.display()
            ));
        };
        // A split install: what the delegate calls into.
        let names = [
            "hd",
            "hf",
            "hio",
            "cameraUtil",
            "usdVol",
            "sdf",
            "vt",
            "gf",
            "tf",
            "plug",
            "trace",
            "work",
            "arch",
            "ar",
        ];
        names
            .iter()
            .map(|n| format!("{prefix}{n}"))
            .filter(|n| has(n))
            .collect()
    };
    Ok(Usd {
        include,
        lib_dir,
        libs,
        tbb_include,
    })
}

fn build_delegate(usd: &Usd) {
    let mut build = cxx_build::bridge("src/ffi.rs");
    let host_build = build.clone();
    build
        .files(SOURCES)
        .std("c++17")
        // The SDK's headers as system headers: their warnings are not ours.
        .flag("-isystem")
        .flag(
            usd.include
                .to_str()
                .expect("NIMBUS_USD_INCLUDE is not UTF-8"),
        )
        .flag("-isystem")
        .flag(
            usd.tbb_include
                .to_str()
                .expect("NIMBUS_TBB_INCLUDE is not UTF-8"),
        )
        .include(".")
        .define("MFB_PACKAGE_NAME", "hdNimbus")
        .define("MFB_ALT_PACKAGE_NAME", "hdNimbus")
        .define("MFB_PACKAGE_MODULE", "hdNimbus")
        .define("TBB_SUPPRESS_DEPRECATED_MESSAGES", "1")
        .define("_GLIBCXX_USE_CXX11_ABI", "1")
        .flag("-fPIC")
        .flag_if_supported("-Wno-deprecated")
        .flag_if_supported("-Wno-deprecated-declarations")
        .flag_if_supported("-Wno-unused-parameter");
    if let Ok(extra) = env::var("NIMBUS_USD_CXXFLAGS") {
        for f in extra.split_whitespace() {
            build.flag(f);
        }
    }
    // Linked whole, and only into the plug-in (the cdylib; the Rust half's unit tests
    // need no USD): nothing in the Rust half calls the delegate, whose classes
    // register themselves with USD from static initialisers the linker would drop.
    build.cargo_metadata(false).compile("hdnimbus_cpp");
    let out = PathBuf::from(env::var("OUT_DIR").expect("OUT_DIR"));
    println!("cargo:rustc-cdylib-link-arg=-Wl,--whole-archive");
    println!(
        "cargo:rustc-cdylib-link-arg={}",
        out.join("libhdnimbus_cpp.a").display()
    );
    println!("cargo:rustc-cdylib-link-arg=-Wl,--no-whole-archive");
    for f in SOURCES.iter().chain(HEADERS.iter()) {
        println!("cargo:rerun-if-changed={f}");
    }
    println!("cargo:rerun-if-changed=src/ffi.rs");

    let lib = usd.lib_dir.display();
    println!("cargo:rustc-cdylib-link-arg=-L{lib}");
    for l in &usd.libs {
        println!("cargo:rustc-cdylib-link-arg=-l{l}");
    }
    println!("cargo:rustc-cdylib-link-arg=-lstdc++");
    println!("cargo:rustc-cdylib-link-arg=-Wl,-rpath,{lib}");
    println!("cargo:rustc-cdylib-link-arg=-Wl,--no-undefined");
    println!("cargo:rustc-cfg=nimbus_hydra");
    let dir = lay_out_plugin();
    println!("cargo:rerun-if-changed=host.cc");
    if let Some(dir) = dir {
        build_host(&host_build, usd, &dir.join("nimbus-hydra"));
    }
}

/// The command-line host `target/<profile>/hydra/nimbus-hydra` (host.cc), linked
/// against the same USD. A USD built with Python support (Blender's) needs libpython
/// too: `NIMBUS_USD_HOST_LIBS` names extra link arguments, else the `python3` on PATH's
/// library is tried when the link without it fails. A host that does not link is a
/// warning (an error under NIMBUS_HYDRA=require): the plug-in does not need it.
fn build_host(build: &cc::Build, usd: &Usd, exe: &Path) {
    let required = env::var("NIMBUS_HYDRA")
        .map(|m| matches!(m.trim(), "require" | "on" | "1" | "yes" | "true"))
        .unwrap_or(false);
    let lib = &usd.lib_dir;
    let attempt = |extra: &[String]| -> Result<(), String> {
        let mut cmd = build.get_compiler().to_command();
        cmd.args(["-std=c++17", "-O2", "-fPIC", "-D_GLIBCXX_USE_CXX11_ABI=1"])
            .arg("-DTBB_SUPPRESS_DEPRECATED_MESSAGES=1")
            .arg("-isystem")
            .arg(&usd.include)
            .arg("-isystem")
            .arg(&usd.tbb_include)
            .arg("host.cc")
            .arg("-o")
            .arg(exe)
            .arg(format!("-L{}", lib.display()));
        for l in &usd.libs {
            cmd.arg(format!("-l{l}"));
        }
        if lib.join("libtbb.so.2").exists() {
            cmd.arg("-l:libtbb.so.2");
        } else if lib.join("libtbb.so").exists() {
            cmd.arg("-ltbb");
        }
        cmd.arg(format!("-Wl,-rpath,{}", lib.display()));
        cmd.args(extra);
        if let Ok(flags) = env::var("NIMBUS_USD_CXXFLAGS") {
            cmd.args(flags.split_whitespace());
        }
        let o = cmd
            .output()
            .map_err(|e| format!("cannot run the compiler: {e}"))?;
        match o.status.success() {
            true => Ok(()),
            false => Err(String::from_utf8_lossy(&o.stderr)
                .lines()
                .filter(|l| l.contains("error") || l.contains("undefined"))
                .take(5)
                .collect::<Vec<_>>()
                .join("\n")),
        }
    };
    let extra: Vec<String> = env::var("NIMBUS_USD_HOST_LIBS")
        .map(|v| v.split_whitespace().map(str::to_string).collect())
        .unwrap_or_default();
    let mut result = attempt(&extra);
    if result.is_err() && extra.is_empty() {
        if let Some(python) = python_link_args() {
            result = attempt(&python);
        }
    }
    match result {
        Ok(()) => {}
        Err(why) if required => panic!(
            "NIMBUS_HYDRA=require: the command-line host nimbus-hydra does not link: {why}\n\
             (NIMBUS_USD_HOST_LIBS names extra link arguments, e.g. the libpython a USD \
             built with Python support needs)"
        ),
        Err(why) => println!("cargo:warning=nimbus-hydra (the command-line host) not built: {why}"),
    }
}

/// `-L<dir> -lpython3.X -Wl,-rpath,<dir>` of the `python3` on PATH, if it has a shared
/// library.
fn python_link_args() -> Option<Vec<String>> {
    let o = std::process::Command::new("python3")
        .args([
            "-c",
            "import sysconfig as s; print(s.get_config_var('LIBDIR')); print(s.get_config_var('LDLIBRARY'))",
        ])
        .output()
        .ok()?;
    let text = String::from_utf8(o.stdout).ok()?;
    let mut lines = text.lines();
    let (dir, file) = (lines.next()?, lines.next()?);
    let name = file.strip_prefix("lib")?.strip_suffix(".so")?;
    Path::new(dir).join(file).exists().then(|| {
        vec![
            format!("-L{dir}"),
            format!("-l{name}"),
            format!("-Wl,-rpath,{dir}"),
        ]
    })
}

/// `target/<profile>/hydra/hdNimbus/{plugInfo.json, hdNimbus.so -> ../../libhd_nimbus.so}`;
/// returns `target/<profile>/hydra`.
fn lay_out_plugin() -> Option<PathBuf> {
    let hydra = hydra_dir()?;
    let dir = hydra.join("hdNimbus");
    std::fs::create_dir_all(&dir).expect("create the hydra/hdNimbus folder");
    std::fs::copy("plugInfo.json", dir.join("plugInfo.json")).expect("copy plugInfo.json");
    let link = dir.join("hdNimbus.so");
    let _ = std::fs::remove_file(&link);
    symlink(Path::new("../../libhd_nimbus.so"), &link);
    Some(hydra)
}

#[cfg(unix)]
fn symlink(target: &Path, link: &Path) {
    std::os::unix::fs::symlink(target, link).expect("link hdNimbus.so");
}

#[cfg(not(unix))]
fn symlink(_target: &Path, _link: &Path) {}
