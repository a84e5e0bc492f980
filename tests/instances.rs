//! Instanced volumes: a UsdGeomPointInstancer of VDB volumes renders as the same
//! volumes written out one by one, and every instance shares its prototype's grid and
//! majorant structure.

mod common;

use common::cli::{channel, channels, nimbus, stderr};
use common::shared_file;
use glam::{DMat4, DQuat, DVec3};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

const PROTOTYPES: [&str; 2] = [
    "openvdb_samples/smoke.vdb",
    "openvdb_samples/smoke1_2013.vdb",
];

/// One instance: prototype, position, orientation (as written: half precision), scale.
struct Instance {
    proto: usize,
    position: [f32; 3],
    orientation: [half::f16; 4],
    scale: [f32; 3],
}

impl Instance {
    /// The transform UsdGeomPointInstancer gives it: scale, then orient, then translate,
    /// computed from the values as the stage stores them.
    fn matrix(&self) -> DMat4 {
        let [w, x, y, z] = self.orientation.map(|h| f64::from(h.to_f32()));
        let q = DQuat::from_xyzw(x, y, z, w).normalize();
        DMat4::from_scale_rotation_translation(
            DVec3::from_array(self.scale.map(f64::from)),
            q,
            DVec3::from_array(self.position.map(f64::from)),
        )
    }
}

/// `n` instances scattered over a 2,000 × 2,000 field (seen from above, a ray meets a
/// few: far below the 64 volumes one ray segment races), both prototypes, seeded.
fn instances(n: usize) -> Vec<Instance> {
    use rand::{Rng, SeedableRng};
    let mut rng = rand_pcg::Pcg32::seed_from_u64(43);
    (0..n)
        .map(|i| {
            let axis = DVec3::new(rng.gen(), rng.gen(), rng.gen::<f64>() + 0.1).normalize();
            let q = DQuat::from_axis_angle(axis, rng.gen::<f64>() * 6.28);
            let s = 0.5 + rng.gen::<f32>();
            Instance {
                proto: i % 2,
                position: [
                    rng.gen::<f32>() * 2000.0 - 1000.0,
                    rng.gen::<f32>() * 2000.0 - 1000.0,
                    rng.gen::<f32>() * 40.0,
                ],
                orientation: [q.w, q.x, q.y, q.z].map(|v| half::f16::from_f32(v as f32)),
                scale: [s, s, s * 0.8],
            }
        })
        .collect()
}

const COMMON: &str = r#"def Camera "cam"
{
    float focalLength = 20
    double3 xformOp:translate = (0, 0, 1500)
    uniform token[] xformOpOrder = ["xformOp:translate"]
}
def DistantLight "sun"
{
    float inputs:intensity = 2
    float xformOp:rotateX = 40
    uniform token[] xformOpOrder = ["xformOp:rotateX"]
}
def RenderSettings "settings"
{
    int2 resolution = (48, 32)
    rel camera = </cam>
    int nimbus:samples = 4
    int nimbus:maxDepth = 2
}
"#;

fn volume_body(file: &Path) -> String {
    format!(
        "    float nimbus:densityScale = 2\n    rel field:density = </fields/{}>\n",
        file.file_stem().unwrap().to_string_lossy()
    )
}

/// The field prims both stages share (one per prototype file).
fn fields(files: &[PathBuf]) -> String {
    let mut s = String::from("def Scope \"fields\"\n{\n");
    for f in files {
        let _ = writeln!(
            s,
            "    def OpenVDBAsset \"{}\"\n    {{\n        asset filePath = @{}@\n        token fieldName = \"density\"\n    }}",
            f.file_stem().unwrap().to_string_lossy(),
            f.display()
        );
    }
    s + "}\n"
}

fn instancer_stage(files: &[PathBuf], inst: &[Instance]) -> String {
    let list = |f: &dyn Fn(&Instance) -> String| inst.iter().map(f).collect::<Vec<_>>().join(", ");
    let mut s = String::from("#usda 1.0\n(\n    upAxis = \"Z\"\n)\n");
    s += &fields(files);
    s += "def PointInstancer \"clouds\"\n{\n    rel prototypes = [</clouds/Prototypes/a>, </clouds/Prototypes/b>]\n";
    let _ = writeln!(
        s,
        "    int[] protoIndices = [{}]",
        list(&|i| i.proto.to_string())
    );
    let _ = writeln!(
        s,
        "    point3f[] positions = [{}]",
        list(&|i| format!(
            "({:?}, {:?}, {:?})",
            i.position[0], i.position[1], i.position[2]
        ))
    );
    let _ = writeln!(
        s,
        "    quath[] orientations = [{}]",
        list(&|i| {
            let o = i.orientation.map(|h| h.to_f32());
            format!("({:?}, {:?}, {:?}, {:?})", o[0], o[1], o[2], o[3])
        })
    );
    let _ = writeln!(
        s,
        "    float3[] scales = [{}]",
        list(&|i| format!("({:?}, {:?}, {:?})", i.scale[0], i.scale[1], i.scale[2]))
    );
    s += "    def Scope \"Prototypes\"\n    {\n";
    for (name, f) in ["a", "b"].iter().zip(files) {
        let _ = write!(
            s,
            "        def Volume \"{name}\"\n        {{\n{}        }}\n",
            volume_body(f).replace("    ", "            ")
        );
    }
    s += "    }\n}\n";
    s + COMMON
}

fn explicit_stage(files: &[PathBuf], inst: &[Instance]) -> String {
    let mut s = String::from("#usda 1.0\n(\n    upAxis = \"Z\"\n)\n");
    s += &fields(files);
    for (k, i) in inst.iter().enumerate() {
        // USD matrices are row-vector (the transpose of glam's): its rows are glam's columns.
        let m = i.matrix().to_cols_array_2d();
        let rows: Vec<String> = m
            .iter()
            .map(|r| format!("({:?}, {:?}, {:?}, {:?})", r[0], r[1], r[2], r[3]))
            .collect();
        let _ = write!(
            s,
            "def Volume \"v{k}\"\n{{\n{}    matrix4d xformOp:transform = ({})\n    uniform token[] xformOpOrder = [\"xformOp:transform\"]\n}}\n",
            volume_body(&files[i.proto]),
            rows.join(", ")
        );
    }
    s + COMMON
}

/// The instancer stage and the same 1,000 volumes written one by one render the same
/// image, bit for bit: the reader places instance i at the transform
/// UsdGeomPointInstancer defines (scale, orient, translate), the explicit prims carry
/// that matrix, and media are raced in the same order. Both stages load each VDB once
/// (their grids and majorant structures are shared: benches/instances measures the
/// memory), and the media index finds the few volumes each ray meets.
#[test]
fn a_point_instancer_renders_as_its_instances_written_out() {
    let Some(files) = PROTOTYPES
        .iter()
        .map(shared_file)
        .collect::<Option<Vec<PathBuf>>>()
    else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let inst = instances(1000);
    let a = dir.path().join("instancer.usda");
    let b = dir.path().join("explicit.usda");
    std::fs::write(&a, instancer_stage(&files, &inst)).unwrap();
    std::fs::write(&b, explicit_stage(&files, &inst)).unwrap();
    let mut images = Vec::new();
    for stage in [&a, &b] {
        let exr = stage.with_extension("exr");
        let out = nimbus(&[
            "render",
            stage.to_str().unwrap(),
            "-o",
            exr.to_str().unwrap(),
        ]);
        assert!(
            out.status.success(),
            "{}: {}",
            stage.display(),
            stderr(&out)
        );
        assert!(
            !stderr(&out).contains("more than 64 volumes"),
            "{}",
            stderr(&out)
        );
        images.push(channels(&exr));
    }
    let alpha = channel(&images[0], "A");
    assert!(alpha.iter().any(|&a| a > 0.05), "the clouds are in view");
    for name in ["R", "G", "B", "A"] {
        assert_eq!(
            channel(&images[0], name),
            channel(&images[1], name),
            "channel {name}: the instancer's image and the explicit volumes' differ"
        );
    }
}

/// Instancer input errors name the prim and attribute: an index past the prototypes,
/// arrays of the wrong length.
#[test]
fn bad_instancer_arrays_are_errors_naming_the_attribute() {
    let dir = tempfile::tempdir().unwrap();
    for (name, body, needle) in [
        (
            "index",
            "int[] protoIndices = [0, 3]\n    point3f[] positions = [(0,0,0), (1,0,0)]",
            "protoIndices[1] = 3 is not one of its 1 prototypes",
        ),
        (
            "length",
            "int[] protoIndices = [0, 0]\n    point3f[] positions = [(0,0,0)]",
            "`positions` has 1 entries, `protoIndices` 2",
        ),
    ] {
        let stage = dir.path().join(format!("{name}.usda"));
        std::fs::write(
            &stage,
            format!(
                "#usda 1.0\ndef PointInstancer \"i\"\n{{\n    rel prototypes = </i/P/v>\n    {body}\n    def Scope \"P\"\n    {{\n        def Volume \"v\"\n        {{\n        }}\n    }}\n}}\n"
            ),
        )
        .unwrap();
        let out = nimbus(&["info", stage.to_str().unwrap()]);
        common::cli::assert_clean_error(&out, needle);
        assert!(stderr(&out).contains("/i"), "{}", stderr(&out));
    }
}
