//! The render session (`render::session::Session`), the library entry point every
//! command calls: a region renders the same pixels as the whole frame bit for bit; a
//! benchmark's `retrack` gives the octree a render with that tracker builds; stages
//! without a camera or lights, and bare VDB files, render with defaults and say so;
//! the preview PNG.

use nimbus::render::analysis::CodePaths;
use nimbus::render::film::{Aov, Film, Region};
use nimbus::render::job::RenderJob;
use nimbus::render::session::{Overrides, Session};
use nimbus::track::select::{TrackerKind, TrackerSettings, TransmittanceKind};
use std::path::{Path, PathBuf};
use std::process::Command;

mod common;

use common::cli::nimbus;
use common::repo as root;

fn render(session: &Session, region: Option<Region>, count: bool) -> Film {
    let job = session.job_with(CodePaths {
        count,
        specialise: true,
    });
    common::render_job(session, &job, region)
}

fn small(stage: &str) -> (PathBuf, Overrides) {
    (
        root().join(stage),
        Overrides {
            spp: Some(3),
            res: Some((37, 23)),
            ..Overrides::default()
        },
    )
}

/// Every channel of every pixel of a region equals the same pixel of the whole frame,
/// bit for bit (pixel streams are seeded from the global pixel index), for the grey
/// single-channel path and the chromatic general path.
#[test]
fn a_region_renders_the_pixels_of_the_whole_frame() {
    for stage in ["scenes/cloud/cloud.usda", "scenes/chromatic/chromatic.usda"] {
        let (path, o) = small(stage);
        let session = Session::open(&path, &o).unwrap();
        let full = render(&session, None, true);
        let region = Region {
            x0: 5,
            y0: 7,
            x1: 30,
            y1: 19,
        };
        let part = render(&session, Some(region), true);
        assert_eq!((part.width, part.height), (25, 12));
        assert_eq!(part.region, region);
        assert_eq!(part.full, (37, 23));
        for &aov in Aov::ALL.iter() {
            let (f, p) = (full.channel(aov), part.channel(aov));
            for y in region.y0..region.y1 {
                for x in region.x0..region.x1 {
                    let a = f[(y * 37 + x) as usize];
                    let b = p[((y - region.y0) * 25 + (x - region.x0)) as usize];
                    assert_eq!(
                        a.to_bits(),
                        b.to_bits(),
                        "{stage} {} at ({x}, {y}): {a} vs {b}",
                        aov.channel_name()
                    );
                }
            }
        }
    }
}

/// A benchmark that switches tracker with `retrack` renders with the octree (same
/// pruning) and so the counts of a session opened with that tracker, as `nimbus render
/// --octree-depth D --tracker T` would: the divergence issue 15 found in `bench error`.
#[test]
fn retrack_prunes_as_a_render_with_that_tracker() {
    // The stage and depth of the issue: thick smoke (../shared/data), depth 16.
    // The smoke VDB the stage reads; absent, the test is skipped, or fails under
    // NIMBUS_REQUIRE_DATA=1 (as in CI).
    if common::shared_file("openvdb_samples/smoke.vdb").is_none() {
        return;
    }
    let path = root().join("benches/smoke_chromatic/smoke_chromatic.usda");
    let mut o = Overrides {
        spp: Some(2),
        res: Some((24, 18)),
        octree_depth: Some(16),
        ..Overrides::default()
    };
    o.tracker = Some("delta".into());
    let mut bench = Session::open(&path, &o).unwrap();
    let decomposition = TrackerSettings {
        tracker: TrackerKind::Decomposition,
        transmittance: TransmittanceKind::ResidualRatio,
        ..TrackerSettings::default()
    };
    bench.retrack(decomposition);
    o.tracker = Some("decomposition".into());
    o.transmittance = Some(TransmittanceKind::ResidualRatio);
    let direct = Session::open(&path, &o).unwrap();
    let (a, b) = (render(&bench, None, true), render(&direct, None, true));
    let (ca, cb) = (a.totals().0, b.totals().0);
    assert_eq!(
        (ca.density_lookups, ca.cells_visited, ca.real_collisions),
        (cb.density_lookups, cb.cells_visited, cb.real_collisions)
    );
    assert_eq!(a.channel(Aov::R), b.channel(Aov::R));
    // The power of the check: decomposition tracking on the octree pruned for delta
    // (what `bench error` ran before) visits other cells.
    o.tracker = Some("delta".into());
    o.transmittance = None;
    let pruned_for_delta = Session::open(&path, &o).unwrap();
    let job = RenderJob {
        tracking: decomposition,
        ..pruned_for_delta.job_with(CodePaths {
            count: true,
            specialise: true,
        })
    };
    let c = common::render_job(&pruned_for_delta, &job, None);
    assert_ne!(
        c.totals().0.cells_visited,
        cb.cells_visited,
        "pruning did not depend on the tracker"
    );
}

fn volume_only_stage(dir: &Path) -> PathBuf {
    let stage = dir.join("volume_only.usda");
    let vdb = root().join("scenes/cloud/cloud.vdb");
    std::fs::write(
        &stage,
        format!(
            "#usda 1.0\ndef Volume \"Cloud\"\n{{\n    rel field:density = </Cloud/density>\n    def OpenVDBAsset \"density\"\n    {{\n        asset filePath = @{}@\n        token fieldName = \"density\"\n    }}\n}}\n",
            vdb.display()
        ),
    )
    .unwrap();
    stage
}

/// A stage holding only a Volume renders (default camera framing it, default sun and
/// sky, each with a warning) and `info` describes it; before, both failed with "no
/// Camera prim".
#[test]
fn a_stage_with_only_a_volume_renders_with_defaults() {
    let dir = tempfile::tempdir().unwrap();
    let stage = volume_only_stage(dir.path());
    let out = dir.path().join("out.exr");
    let r = nimbus(&[
        "render",
        stage.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--res",
        "32x24",
        "--spp",
        "2",
    ]);
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(r.status.success(), "{err}");
    assert!(err.contains("default camera"), "{err}");
    assert!(err.contains("default sun and sky"), "{err}");
    // The default camera looks at the volume: some pixels have alpha.
    let session = Session::open(
        &stage,
        &Overrides {
            res: Some((32, 24)),
            spp: Some(2),
            ..Overrides::default()
        },
    )
    .unwrap();
    assert!(session.analysis.volume_visible);
    assert_eq!(session.analysis.lights_total, 2);
    let a = render(&session, None, false).channel(Aov::A);
    let covered = a.iter().filter(|&&v| v > 0.0).count();
    assert!(covered > 0);
    let i = nimbus(&["info", stage.to_str().unwrap()]);
    let text = String::from_utf8_lossy(&i.stdout);
    assert!(i.status.success(), "{}", String::from_utf8_lossy(&i.stderr));
    assert!(text.contains("analysis: volumes 1"), "{text}");
}

/// `nimbus render FILE.vdb` renders the first float grid; `--grid` names another, and
/// an unknown name is an error listing the grids, with nothing written.
#[test]
fn a_vdb_file_renders_directly() {
    let dir = tempfile::tempdir().unwrap();
    let vdb = root().join("scenes/fire/fire.vdb");
    let out = dir.path().join("fire.exr");
    let args = |grid: &str| {
        vec![
            "render".to_string(),
            vdb.display().to_string(),
            "-o".into(),
            out.display().to_string(),
            "--res".into(),
            "24x24".into(),
            "--spp".into(),
            "1".into(),
            "--grid".into(),
            grid.into(),
        ]
    };
    let run = |a: Vec<String>| {
        Command::new(env!("CARGO_BIN_EXE_nimbus"))
            .args(a)
            .output()
            .unwrap()
    };
    let r = run(args("nonexistent"));
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(!r.status.success());
    assert!(
        err.contains("no grid named 'nonexistent'") && err.contains("density"),
        "{err}"
    );
    assert!(!out.exists());
    let r = run(args("temperature"));
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    assert!(out.exists());
    let first = nimbus(&[
        "render",
        vdb.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--res",
        "24x24",
        "--spp",
        "1",
    ]);
    let err = String::from_utf8_lossy(&first.stderr);
    assert!(first.status.success(), "{err}");
    assert!(err.contains("a VDB file, not a stage"), "{err}");
}

/// `--preview` writes an 8-bit RGB PNG of the render's size beside the EXR; the sky
/// behind the cloud is blue (B > R in the corner), the sunlit cloud brighter than the
/// sky. An unwritable preview path fails before rendering and writes no EXR.
#[test]
fn preview_png_is_written_and_checked_first() {
    let dir = tempfile::tempdir().unwrap();
    let exr = dir.path().join("cloud.exr");
    let png_path = dir.path().join("cloud.png");
    let stage = root().join("scenes/cloud/cloud.usda");
    let r = nimbus(&[
        "render",
        stage.to_str().unwrap(),
        "-o",
        exr.to_str().unwrap(),
        "--res",
        "40x30",
        "--spp",
        "4",
        "--preview",
        png_path.to_str().unwrap(),
    ]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let decoder = png::Decoder::new(std::fs::File::open(&png_path).unwrap());
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size()];
    let info = reader.next_frame(&mut buf).unwrap();
    assert_eq!((info.width, info.height), (40, 30));
    assert_eq!(info.color_type, png::ColorType::Rgb);
    let corner = &buf[0..3];
    assert!(corner[2] > corner[0], "sky corner {corner:?} is not blue");
    let centre = &buf[((15 * 40 + 20) * 3) as usize..][..3];
    let sum = |p: &[u8]| p.iter().map(|&v| v as u32).sum::<u32>();
    assert!(
        sum(centre) > sum(corner),
        "cloud {centre:?} vs sky {corner:?}"
    );

    let exr2 = dir.path().join("second.exr");
    let bad = dir.path().join("no/such/folder/p.png");
    let r = nimbus(&[
        "render",
        stage.to_str().unwrap(),
        "-o",
        exr2.to_str().unwrap(),
        "--res",
        "8x6",
        "--spp",
        "1",
        "--preview",
        bad.to_str().unwrap(),
    ]);
    assert!(!r.status.success());
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(err.contains("p.png"), "{err}");
    assert!(!exr2.exists());
}

/// A RenderProduct's `nimbus:previewName` (NimbusRenderProductAPI) writes a preview PNG
/// of that product beside its EXR, relative to the working directory like
/// `productName`.
#[test]
fn render_product_preview_name_writes_a_png() {
    let dir = tempfile::tempdir().unwrap();
    let vdb = root().join("scenes/cloud/cloud.vdb");
    let stage = dir.path().join("p.usda");
    std::fs::write(
        &stage,
        format!(
            r#"#usda 1.0
(
    renderSettingsPrimPath = "/Render/Settings"
)
def Volume "Cloud"
{{
    rel field:density = </Cloud/density>
    def OpenVDBAsset "density"
    {{
        asset filePath = @{}@
        token fieldName = "density"
    }}
}}
def Scope "Render"
{{
    def RenderSettings "Settings"
    {{
        uniform int2 resolution = (20, 16)
        rel products = </Render/Product>
    }}
    def RenderProduct "Product" (
        prepend apiSchemas = ["NimbusRenderProductAPI"]
    )
    {{
        uniform token productName = "out.exr"
        string nimbus:previewName = "out_preview.png"
    }}
}}
"#,
            vdb.display()
        ),
    )
    .unwrap();
    let r = Command::new(env!("CARGO_BIN_EXE_nimbus"))
        .args(["render", stage.to_str().unwrap(), "--spp", "1"])
        .current_dir(dir.path())
        .output()
        .unwrap();
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    assert!(dir.path().join("out.exr").is_file());
    let png_path = dir.path().join("out_preview.png");
    let decoder = png::Decoder::new(std::fs::File::open(&png_path).unwrap());
    let info = decoder.read_info().unwrap().info().clone();
    assert_eq!((info.width, info.height), (20, 16));
}
