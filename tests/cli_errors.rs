//! End-to-end tests of the `nimbus` binary on bad input: clean errors (exit code 1, no
//! panic, a message naming the problem) that leave existing output untouched.

mod common;

use common::cli::{assert_clean_error, nimbus, render_args, root, stage_with_field, stderr};
use std::path::Path;
use std::process::{Command, Output};

#[test]
fn bad_input_fails_cleanly_and_leaves_existing_output_untouched() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let out = d.join("keep.exr");
    std::fs::write(&out, b"precious").unwrap();
    let out_s = out.to_str().unwrap();
    let check_untouched = || assert_eq!(std::fs::read(&out).unwrap(), b"precious");

    // Missing stage.
    let missing = d.join("nope.usda");
    assert_clean_error(
        &nimbus(&render_args(missing.to_str().unwrap(), out_s)),
        "nope.usda",
    );
    check_untouched();

    // Malformed stage text.
    let bad = d.join("bad.usda");
    std::fs::write(&bad, "#usda 1.0\ndef Xform \"W\" {\n  float x = \n").unwrap();
    assert_clean_error(
        &nimbus(&render_args(bad.to_str().unwrap(), out_s)),
        "bad.usda",
    );
    check_untouched();

    // Missing VDB file.
    let s = stage_with_field(d, "missing.vdb", "density");
    assert_clean_error(
        &nimbus(&render_args(s.to_str().unwrap(), out_s)),
        "missing.vdb",
    );
    check_untouched();

    // Wrong grid name.
    std::fs::copy(root().join("scenes/cloud/cloud.vdb"), d.join("good.vdb")).unwrap();
    let s = stage_with_field(d, "good.vdb", "nosuchgrid");
    assert_clean_error(
        &nimbus(&render_args(s.to_str().unwrap(), out_s)),
        "nosuchgrid",
    );
    check_untouched();

    // Corrupt VDBs: zero bytes, text, truncated.
    let good = std::fs::read(root().join("scenes/cloud/cloud.vdb")).unwrap();
    for (name, bytes) in [
        ("zero.vdb", Vec::new()),
        (
            "text.vdb",
            b"this is not a vdb file at all, just some text\n".to_vec(),
        ),
        ("truncated.vdb", good[..good.len() / 2].to_vec()),
        ("header.vdb", good[..40.min(good.len())].to_vec()),
    ] {
        std::fs::write(d.join(name), bytes).unwrap();
        let s = stage_with_field(d, name, "density");
        assert_clean_error(&nimbus(&render_args(s.to_str().unwrap(), out_s)), name);
        check_untouched();
    }

    // Unwritable output path (a folder that does not exist).
    let stage = root().join("scenes/cloud/cloud.usda");
    let o = nimbus(&render_args(
        stage.to_str().unwrap(),
        d.join("no/such/dir/out.exr").to_str().unwrap(),
    ));
    assert_clean_error(&o, "no/such/dir");

    // Resolution 0 and absurd resolutions are refused before rendering.
    let mut a = render_args(stage.to_str().unwrap(), out_s);
    a[5] = "0x10";
    let o = nimbus(&a);
    assert!(!o.status.success() && !stderr(&o).contains("panicked"));
    a[5] = "4000000x4000000";
    assert_clean_error(&nimbus(&a), "memory");
    check_untouched();

    // Negative spp is rejected by the argument parser.
    let o = nimbus(&[
        "render",
        stage.to_str().unwrap(),
        "-o",
        out_s,
        "--spp",
        "-3",
    ]);
    assert!(!o.status.success() && !stderr(&o).contains("panicked"));
    check_untouched();

    // No temporary files are left behind.
    let leftovers: Vec<_> = std::fs::read_dir(d)
        .unwrap()
        .filter_map(|e| e.ok())
        .filter(|e| e.file_name().to_string_lossy().starts_with(".nimbus-"))
        .collect();
    assert!(leftovers.is_empty(), "temporary files left: {leftovers:?}");
}

/// Writes `files` (name, text) into `dir` and renders `dir/first`: every case must fail
/// cleanly, naming `needle`, leaving `keep` untouched.
fn assert_stage_refused(dir: &Path, files: &[(&str, &[u8])], needle: &str) {
    for (name, bytes) in files {
        std::fs::write(dir.join(name), bytes).unwrap();
    }
    let out = dir.join("keep.exr");
    std::fs::write(&out, b"precious").unwrap();
    let stage = dir.join(files[0].0);
    let o = nimbus(&render_args(stage.to_str().unwrap(), out.to_str().unwrap()));
    assert_clean_error(&o, needle);
    assert_eq!(std::fs::read(&out).unwrap(), b"precious");
    let o = nimbus(&["info", stage.to_str().unwrap()]);
    assert_clean_error(&o, needle);
}

/// Cyclic sublayers and references (between two files, and a prim referencing itself)
/// are composition errors naming the stage and the cycle, not a stack overflow or hang.
#[test]
fn cyclic_sublayers_and_references_are_clear_errors() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    assert_stage_refused(
        d,
        &[
            ("a.usda", b"#usda 1.0\n(\n    subLayers = [@./b.usda@]\n)\n"),
            ("b.usda", b"#usda 1.0\n(\n    subLayers = [@./a.usda@]\n)\n"),
        ],
        "cycle",
    );
    assert_stage_refused(
        d,
        &[
            (
                "r.usda",
                b"#usda 1.0\ndef Xform \"W\" (\n    references = @./r2.usda@</W>\n)\n{\n}\n",
            ),
            (
                "r2.usda",
                b"#usda 1.0\ndef Xform \"W\" (\n    references = @./r.usda@</W>\n)\n{\n}\n",
            ),
        ],
        "cycle",
    );
    assert_stage_refused(
        d,
        &[(
            "self.usda",
            b"#usda 1.0\ndef Xform \"W\" (\n    references = </W>\n)\n{\n}\n",
        )],
        "self.usda",
    );
    assert_stage_refused(
        d,
        &[(
            "payload.usda",
            b"#usda 1.0\ndef Xform \"W\" (\n    payload = @./payload.usda@</W>\n)\n{\n}\n",
        )],
        "cycle",
    );
}

/// Malformed .usdz packages: not a zip, empty, truncated, no layer inside, a
/// compressed (unsupported) member, a layer that does not parse.
#[test]
fn malformed_usdz_is_a_clear_error() {
    use std::io::Write;
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // Python's zipfile writes the packages (USDZ members are stored, not deflated).
    if !common::python_imports(&["zipfile"], "the zip-built cases need python3") {
        return;
    }
    let good = d.join("good.usdz");
    let script = "import sys, zipfile\nd = sys.argv[1]\nsrc = sys.argv[2]\n\
z = zipfile.ZipFile(d + '/good.usdz', 'w'); z.write(src + '/cloud.usda', 'cloud.usda'); z.write(src + '/cloud.vdb', 'cloud.vdb'); z.close()\n\
z = zipfile.ZipFile(d + '/nolayer.usdz', 'w'); z.writestr('readme.txt', 'hi'); z.close()\n\
z = zipfile.ZipFile(d + '/deflated.usdz', 'w', compression=zipfile.ZIP_DEFLATED); z.writestr('a.usda', '#usda 1.0\\n'); z.close()\n\
z = zipfile.ZipFile(d + '/badlayer.usdz', 'w'); z.writestr('a.usda', '#usda 1.0\\ndef X \"A\" {\\n float x = \\n'); z.close()\n";
    let o = Command::new("python3")
        .args([
            "-c",
            script,
            d.to_str().unwrap(),
            root().join("scenes/cloud").to_str().unwrap(),
        ])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    let bytes = std::fs::read(&good).unwrap();
    let mut garbage = std::fs::File::create(d.join("garbage.usdz")).unwrap();
    garbage.write_all(b"PK\x03\x04 not really a zip").unwrap();
    std::fs::write(d.join("empty.usdz"), b"").unwrap();
    std::fs::write(d.join("truncated.usdz"), &bytes[..bytes.len() / 2]).unwrap();
    let out = d.join("keep.exr");
    std::fs::write(&out, b"precious").unwrap();
    for name in [
        "garbage.usdz",
        "empty.usdz",
        "truncated.usdz",
        "nolayer.usdz",
        "deflated.usdz",
        "badlayer.usdz",
    ] {
        let stage = d.join(name);
        let o = nimbus(&render_args(stage.to_str().unwrap(), out.to_str().unwrap()));
        assert_clean_error(&o, name);
        assert_eq!(std::fs::read(&out).unwrap(), b"precious", "{name}");
    }
    // The well-formed package renders (the cases above fail for their own reasons).
    let o = nimbus(&render_args(good.to_str().unwrap(), out.to_str().unwrap()));
    assert!(o.status.success(), "{}", stderr(&o));
}

/// A Vec3 grid where the density field expects a float grid: a clear error naming the
/// file, the grid and both types.
#[test]
fn vec3_grid_for_a_float_field_is_a_clear_error() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let mut bytes = std::fs::read(root().join("scenes/cloud/cloud.vdb")).unwrap();
    let from = b"Tree_float_5_4_3";
    let at = bytes
        .windows(from.len())
        .position(|w| w == from)
        .expect("grid type in the header");
    bytes[at..at + from.len()].copy_from_slice(b"Tree_vec3s_5_4_3");
    std::fs::write(d.join("vel.vdb"), &bytes).unwrap();
    let stage = stage_with_field(d, "vel.vdb", "density");
    let out = d.join("out.exr");
    let o = nimbus(&render_args(stage.to_str().unwrap(), out.to_str().unwrap()));
    assert_clean_error(&o, "vel.vdb");
    let e = stderr(&o);
    assert!(
        e.contains("\"density\"") && e.contains("Vec3s") && e.contains("float"),
        "{e}"
    );
    assert!(!out.exists());
}

/// Unreadable stage and VDB files (permission denied) are clear errors naming the file.
/// As root, permissions do not stop reads, so the binary runs as `nobody` there.
#[test]
fn unreadable_stage_and_vdb_are_clear_errors() {
    use std::os::unix::fs::PermissionsExt;
    use std::os::unix::process::CommandExt;
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::set_permissions(d, std::fs::Permissions::from_mode(0o777)).unwrap();
    let is_root = unsafe { libc::geteuid() } == 0;
    let run = |args: &[&str]| -> Output {
        let mut c = Command::new(env!("CARGO_BIN_EXE_nimbus"));
        c.args(args);
        if is_root {
            c.uid(65534).gid(65534);
        }
        c.output().expect("run nimbus")
    };
    if is_root {
        // The binary must be reachable by `nobody` (it is, under a world-readable tree).
        let probe = run(&["--version"]);
        if !probe.status.success() {
            eprintln!("cannot run nimbus as nobody: skipping ({})", stderr(&probe));
            return;
        }
    }
    std::fs::copy(root().join("scenes/cloud/cloud.vdb"), d.join("locked.vdb")).unwrap();
    let stage = stage_with_field(d, "locked.vdb", "density");
    let locked = d.join("locked.usda");
    std::fs::copy(&stage, &locked).unwrap();
    for p in [&stage, &locked] {
        std::fs::set_permissions(p, std::fs::Permissions::from_mode(0o644)).unwrap();
    }
    std::fs::set_permissions(d.join("locked.vdb"), std::fs::Permissions::from_mode(0o000)).unwrap();
    std::fs::set_permissions(&locked, std::fs::Permissions::from_mode(0o000)).unwrap();
    let out = d.join("out.exr");
    let out_s = out.to_str().unwrap();
    assert_clean_error(
        &run(&render_args(locked.to_str().unwrap(), out_s)),
        "locked.usda",
    );
    assert_clean_error(
        &run(&render_args(stage.to_str().unwrap(), out_s)),
        "locked.vdb",
    );
    assert!(!out.exists());
}

/// A volume whose transform has scale 0 is refused naming the prim.
#[test]
fn zero_scale_volume_is_a_clear_error() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::copy(root().join("scenes/cloud/cloud.vdb"), d.join("cloud.vdb")).unwrap();
    let text = std::fs::read_to_string(root().join("scenes/cloud/cloud.usda"))
        .unwrap()
        .replacen(
            "uniform token[] xformOpOrder = [\"xformOp:translate\", \"xformOp:rotateXYZ\"]",
            "float3 xformOp:scale = (0, 0, 0)\n        uniform token[] xformOpOrder = [\"xformOp:translate\", \"xformOp:rotateXYZ\", \"xformOp:scale\"]",
            1,
        );
    let stage = d.join("flat.usda");
    std::fs::write(&stage, text).unwrap();
    let out = d.join("out.exr");
    let o = nimbus(&render_args(stage.to_str().unwrap(), out.to_str().unwrap()));
    assert_clean_error(&o, "singular");
    assert!(!out.exists());
}
