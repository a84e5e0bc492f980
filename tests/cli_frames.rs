//! End-to-end tests of `nimbus render` over frames: a real VDB time sequence (loose and
//! packaged in a .usdz), and a failing frame that keeps the good ones.

mod common;

use common::cli::{
    assert_clean_error, channel, channels, cloud_stage_with, nimbus, python, render_args, root,
    stderr,
};
use std::path::{Path, PathBuf};
use std::process::Command;

/// The cloud stage with its density replaced by a VDB sequence of the EmberGen fire
/// (`(frame, path)` time samples on `filePath`, `temperature` as density), scaled into
/// the camera's view.
fn fire_stage(d: &Path, samples: &[(i32, String)]) -> PathBuf {
    let samples: Vec<String> = samples.iter().map(|(n, p)| format!("{n}: @{p}@")).collect();
    let stage = cloud_stage_with(
        d,
        &format!("asset filePath.timeSamples = {{ {} }}", samples.join(", ")),
        "temperature",
        // Fits the fire (world bounds about (-28..26, -29..22, -128..-86)) into the
        // camera's view of the unit cube.
        "float3 xformOp:scale = (0.0333, 0.0333, 0.0333)",
    );
    let text = std::fs::read_to_string(&stage)
        .unwrap()
        .replace(
            "double3 xformOp:translate = (0, 0, 0)",
            "double3 xformOp:translate = (0, 0.1, 3.57)",
        )
        // The volume's op order is the first in the file.
        .replacen(
            "[\"xformOp:translate\", \"xformOp:rotateXYZ\"]",
            "[\"xformOp:translate\", \"xformOp:scale\"]",
            1,
        );
    std::fs::write(&stage, text).unwrap();
    stage
}

/// A real VDB sequence (EmberGen, half floats, blosc) packaged with its stage by pxr's
/// UsdUtils.CreateNewUsdzPackage: the .usdz renders every frame bit-identically to the
/// loose files (VDB bytes read through openusd's package resolver, handed to OpenVDB as
/// a temporary file that is removed afterwards), and `info` lists the packaged grids.
#[test]
fn usdz_packaged_vdb_sequence_renders_like_loose_files() {
    let Some(data) = common::shared_data() else {
        return;
    };
    if !common::pxr_python() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::create_dir(d.join("fire")).unwrap();
    let mut samples = Vec::new();
    for n in [10, 20] {
        let name = format!("fire/fire_{n}.vdb");
        std::fs::copy(
            data.join(format!("embergen_fire_a/embergen_fire_a_{n}.vdb")),
            d.join(&name),
        )
        .unwrap();
        samples.push((n, format!("./{name}")));
    }
    let stage = fire_stage(d, &samples);
    let usdz = d.join("fire.usdz");
    python(
        "import sys\nfrom pxr import UsdUtils\nassert UsdUtils.CreateNewUsdzPackage(sys.argv[1], sys.argv[2])\n",
        &[stage.to_str().unwrap(), usdz.to_str().unwrap()],
    );
    // OpenVDB's temporary copies go here, so their removal can be checked.
    let tmp = d.join("tmp");
    std::fs::create_dir(&tmp).unwrap();
    let render = |stage: &Path, out: &Path| {
        let mut args = render_args(stage.to_str().unwrap(), out.to_str().unwrap());
        args.extend(["--frames", "15-20"]);
        let o = Command::new(env!("CARGO_BIN_EXE_nimbus"))
            .args(&args)
            .env("TMPDIR", &tmp)
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", stderr(&o));
    };
    render(&stage, &d.join("loose.exr"));
    render(&usdz, &d.join("packed.exr"));
    for f in 15..=20 {
        let loose = channels(&d.join(format!("loose.00{f}.exr")));
        let packed = channels(&d.join(format!("packed.00{f}.exr")));
        assert_eq!(loose, packed, "frame {f}");
        assert!(
            channel(&packed, "A").iter().any(|&a| a > 0.05),
            "frame {f}: fire in view"
        );
    }
    let left: Vec<_> = std::fs::read_dir(&tmp).unwrap().collect();
    assert!(left.is_empty(), "temporary VDB copies left: {left:?}");
    let o = nimbus(&["info", usdz.to_str().unwrap(), "--frame", "20"]);
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        out.contains("fire.usdz[fire/fire_20.vdb]") && out.contains("grid 'flames'"),
        "{out}"
    );
}

/// `--frames` over the EmberGen fire, a VDB sequence through time samples on
/// `filePath` (its `temperature` grid standing in for density): one EXR per frame
/// named by the `#` run or before the extension, the file held between samples (same
/// image for the same seed), a new file at the next sample, and each frame identical
/// to a single `--frame` render.
#[test]
fn frames_render_a_vdb_time_sequence() {
    let Some(data) = common::shared_data() else {
        return;
    };
    let fire = data.join("embergen_fire_a");
    let samples: Vec<(i32, String)> = [10, 20, 30]
        .iter()
        .map(|n| {
            let f = fire.join(format!("embergen_fire_a_{n}.vdb"));
            (*n, f.display().to_string())
        })
        .collect();
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let stage = fire_stage(d, &samples);
    let s = stage.to_str().unwrap();
    let seq = d.join("fire.###.exr");
    let stats = d.join("fire.json");
    let mut args = render_args(s, seq.to_str().unwrap());
    args.extend(["--frames", "18-20", "--stats", stats.to_str().unwrap()]);
    let o = nimbus(&args);
    let e = stderr(&o);
    assert!(o.status.success(), "{e}");
    for (i, f) in [18, 19, 20].iter().enumerate() {
        assert!(e.contains(&format!("frame {f} ({}/3)", i + 1)), "{e}");
        assert!(d.join(format!("fire.0{f}.exr")).is_file(), "frame {f}");
        assert!(d.join(format!("fire.00{f}.json")).is_file(), "stats {f}");
    }
    let a = channels(&d.join("fire.018.exr"));
    let b = channels(&d.join("fire.019.exr"));
    let c = channels(&d.join("fire.020.exr"));
    assert_eq!(a, b, "frames 18 and 19 hold the frame-10 file");
    assert!(channel(&c, "A").iter().any(|&x| x > 0.05), "fire in view");
    assert_ne!(
        channel(&b, "A"),
        channel(&c, "A"),
        "frame 20 reads a new file"
    );
    let single = d.join("single.exr");
    let mut args = render_args(s, single.to_str().unwrap());
    args.extend(["--frame", "20"]);
    let o = nimbus(&args);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(channels(&single), c, "--frame 20 == frame 20 of --frames");
}

/// A frame that fails (its VDB is missing) is reported, the other frames are written,
/// the exit status is non-zero, and the failed frame's existing file is untouched.
#[test]
fn failing_frame_keeps_good_frames() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::copy(root().join("scenes/cloud/cloud.vdb"), d.join("cloud.vdb")).unwrap();
    let stage = cloud_stage_with(
        d,
        "asset filePath.timeSamples = { 1: @./cloud.vdb@, 3: @./missing.vdb@ }",
        "density",
        "",
    );
    let previous = b"frame 3 from an earlier run";
    std::fs::write(d.join("out.0003.exr"), previous).unwrap();
    let out = d.join("out.exr");
    let mut args = render_args(stage.to_str().unwrap(), out.to_str().unwrap());
    args.extend(["--frames", "1-3"]);
    let o = nimbus(&args);
    assert_clean_error(&o, "1 of 3 frames failed: 3");
    assert!(stderr(&o).contains("frame 3: "), "{}", stderr(&o));
    assert!(stderr(&o).contains("missing.vdb"), "{}", stderr(&o));
    for f in [1, 2] {
        assert!(!channels(&d.join(format!("out.000{f}.exr"))).is_empty());
    }
    assert_eq!(std::fs::read(d.join("out.0003.exr")).unwrap(), previous);
    let leftovers: Vec<_> = std::fs::read_dir(d)
        .unwrap()
        .filter_map(|e| e.ok())
        .filter(|e| e.file_name().to_string_lossy().starts_with(".nimbus-"))
        .collect();
    assert!(leftovers.is_empty(), "temporary files left: {leftovers:?}");

    // Malformed ranges and --frame with --frames are refused before any work.
    for bad in ["5-2", "a-b", "1-"] {
        let mut args = render_args(stage.to_str().unwrap(), out.to_str().unwrap());
        args.extend(["--frames", bad]);
        let o = nimbus(&args);
        assert!(!o.status.success(), "--frames {bad} accepted");
        assert!(stderr(&o).contains("frame range"), "{}", stderr(&o));
    }
    let mut args = render_args(stage.to_str().unwrap(), out.to_str().unwrap());
    args.extend(["--frames", "1-2", "--frame", "1"]);
    assert!(!nimbus(&args).status.success(), "--frame with --frames");
}
