//! What motion blur costs (issue 45): blurred against unblurred render time on the same
//! stage, one run, rounds interleaved, medians. Run with
//! `cargo bench --bench motion_blur --ignore-rust-version` (needs ../shared/data for the
//! smoke; its velocity grid is written here: the file has none).
//!
//! Stages (each in a still and a blurred version, shutter ±0.5 frames):
//! - `cloud`: the cloud example, its volume sliding 0.4 units and turning 20° over the
//!   shutter (transform motion), and separately its camera moving; and with a spot
//!   light above it, still and sliding 1.2 units and tilting 15° (a moving light);
//! - `smoke`: ../shared/data's smoke.vdb under a sun, advected by a swirl velocity grid
//!   (up to ~2.5 voxels per frame at the box's side, plus an updraft).
//!
//! Printed per stage and version: the median wall time of the render (stage loading
//! excluded), lookups per sample (a velocity read counts as one), and the ratio to the
//! still version's time.

use nimbus::render::analysis::CodePaths;
use nimbus::render::session::{Overrides, Session};
use std::path::{Path, PathBuf};
use std::time::Instant;

const ROUNDS: usize = 5;

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn cloud_stage(dir: &Path, name: &str, volume_ops: &str, camera_ops: &str, open: bool) -> PathBuf {
    let text = std::fs::read_to_string(repo().join("scenes/cloud/cloud.usda")).unwrap();
    let vdb = repo().join("scenes/cloud/cloud.vdb");
    let text = text
        .replace("@./cloud.vdb@", &format!("@{}@", vdb.display()))
        .replace(
            "        double3 xformOp:translate = (0, 0, 0)\n        float3 xformOp:rotateXYZ = (0, 20, 0)\n",
            volume_ops,
        )
        .replace(
            "        double3 xformOp:translate = (0, -0.5, 4.2)\n",
            &format!(
                "{camera_ops}        double shutter:open = {}\n        double shutter:close = {}\n",
                if open { -0.5 } else { 0.0 },
                if open { 0.5 } else { 0.0 }
            ),
        );
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path
}

/// `stage` with a spot above the cloud (a sphere light of radius 0.1 with a 35° cone),
/// still or sliding 1.2 units along x and tilting 15° over the shutter (as
/// tests/motion_blur.rs's moving spot).
fn with_spot(dir: &Path, name: &str, stage: &Path, moving: bool) -> PathBuf {
    let (translate, rotate) = match moving {
        true => (
            "double3 xformOp:translate.timeSamples = { 0: (-1.2, 1.3, 0.2), 2: (1.2, 1.3, 0.2) }",
            "float3 xformOp:rotateXYZ.timeSamples = { 0: (-90, 0, -15), 2: (-90, 0, 15) }",
        ),
        false => (
            "double3 xformOp:translate = (0, 1.3, 0.2)",
            "float3 xformOp:rotateXYZ = (-90, 0, 0)",
        ),
    };
    let spot = format!(
        r#"
def SphereLight "Spot" (
    prepend apiSchemas = ["ShapingAPI"]
)
{{
    float inputs:intensity = 60
    float inputs:radius = 0.1
    float inputs:shaping:cone:angle = 35
    float inputs:shaping:cone:softness = 0.2
    {translate}
    {rotate}
    uniform token[] xformOpOrder = ["xformOp:translate", "xformOp:rotateXYZ"]
}}
"#
    );
    let path = dir.join(name);
    std::fs::write(&path, std::fs::read_to_string(stage).unwrap() + &spot).unwrap();
    path
}

/// A swirl about the smoke's vertical axis plus an updraft, over its box.
fn smoke_velocity(dir: &Path, smoke: &Path) -> PathBuf {
    use nimbus::volume::procedural::vec3_grid_from_fn;
    use nimbus::volume::vdb::{read_float_grid, write_grids, WriteGrid};
    let loc = nimbus::volume::asset::AssetLocation::File(smoke.to_path_buf());
    let d = read_float_grid(&loc, "density", None).unwrap();
    let (lo, hi) = d.world_bounds(glam::DMat4::IDENTITY).unwrap();
    let centre = 0.5 * (lo + hi);
    let voxel = (hi - lo).max_element() / 48.0;
    let dims = ((hi - lo) / voxel).ceil().as_ivec3() + 3;
    let origin = lo - voxel;
    let side = 0.5 * (hi - lo).x.max((hi - lo).z);
    // 2.5 of the smoke's voxels (0.476 units) per frame at the side, 24 frames a second.
    let omega = 2.5 * 0.476 * 24.0 / side;
    let vel = vec3_grid_from_fn("vel", dims.to_array(), origin, voxel, |p| {
        let r = p - centre;
        [-omega * r.z, 10.0, omega * r.x]
    });
    let path = dir.join("smoke_vel.vdb");
    write_grids(&path, &[WriteGrid::Vec3s(&vel)]).unwrap();
    path
}

fn smoke_stage(dir: &Path, name: &str, smoke: &Path, vel: &Path, open: bool) -> PathBuf {
    let text = format!(
        r#"#usda 1.0
(
    timeCodesPerSecond = 24
)
def Camera "Cam" {{
    double3 xformOp:translate = (27, 53, 230)
    uniform token[] xformOpOrder = ["xformOp:translate"]
    float focalLength = 50
    float horizontalAperture = 36
    float verticalAperture = 27
    double shutter:open = {open}
    double shutter:close = {close}
}}
def DistantLight "Sun" {{
    float inputs:intensity = 3
    bool inputs:normalize = 1
    float3 xformOp:rotateXYZ = (-30, 40, 0)
    uniform token[] xformOpOrder = ["xformOp:rotateXYZ"]
}}
def Volume "Smoke" (apiSchemas = ["NimbusVolumeAPI"]) {{
    color3f nimbus:absorption = (0.2, 0.3, 0.6)
    color3f nimbus:scattering = (1.1, 1.2, 1.0)
    float nimbus:anisotropy = 0.3
    rel field:density = </Smoke/density>
    rel field:vel = </Smoke/vel>
    def OpenVDBAsset "density" {{ asset filePath = @{smoke}@
        token fieldName = "density" }}
    def OpenVDBAsset "vel" {{ asset filePath = @{vel}@
        token fieldName = "vel" }}
}}
"#,
        smoke = smoke.display(),
        vel = vel.display(),
        open = if open { -0.5 } else { 0.0 },
        close = if open { 0.5 } else { 0.0 },
    );
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path
}

/// One render's wall time (s) and lookups per sample.
fn time(stage: &Path, counted: bool) -> (f64, f64) {
    let o = Overrides {
        frame: Some(1.0),
        spp: Some(64),
        res: Some((96, 72)),
        seed: Some(1),
        threads: Some(2),
        ..Overrides::default()
    };
    let s = Session::open(stage, &o).unwrap();
    let job = s.job_with(CodePaths {
        count: counted,
        specialise: true,
    });
    let pool = s.pool(2).unwrap();
    let never = std::sync::atomic::AtomicBool::new(false);
    let t0 = Instant::now();
    let (film, _) = s
        .render(
            &job,
            None,
            &pool,
            nimbus::render::progressive::Clock::Wall,
            None,
            &never,
            &|_| {},
            |_, _| Ok::<(), ()>(()),
        )
        .unwrap();
    let seconds = t0.elapsed().as_secs_f64();
    let (c, samples, _) = film.totals();
    (seconds, c.density_lookups as f64 / samples.max(1) as f64)
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn main() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let still_volume = "        double3 xformOp:translate = (0, 0, 0)\n        float3 xformOp:rotateXYZ = (0, 20, 0)\n";
    let moving_volume = "        double3 xformOp:translate.timeSamples = { 0: (-0.4, 0, 0), 2: (0.4, 0, 0) }\n        float3 xformOp:rotateXYZ.timeSamples = { 0: (0, 0, 0), 2: (0, 40, 0) }\n";
    let still_camera = "        double3 xformOp:translate = (0, -0.5, 4.2)\n";
    let moving_camera =
        "        double3 xformOp:translate.timeSamples = { 0: (-0.3, -0.7, 4.2), 2: (0.3, -0.3, 4.2) }\n";
    let mut cases: Vec<(&str, PathBuf)> = vec![
        (
            "cloud still",
            cloud_stage(d, "a.usda", still_volume, still_camera, false),
        ),
        (
            "cloud volume moving",
            cloud_stage(d, "b.usda", moving_volume, still_camera, true),
        ),
        (
            "cloud camera moving",
            cloud_stage(d, "c.usda", still_volume, moving_camera, true),
        ),
    ];
    // The spot's cases: the still stage with the shutter open (nothing else moves).
    let open_still = cloud_stage(d, "f.usda", still_volume, still_camera, true);
    cases.push((
        "cloud + spot still",
        with_spot(d, "g.usda", &open_still, false),
    ));
    cases.push((
        "cloud + spot moving",
        with_spot(d, "h.usda", &open_still, true),
    ));
    let smoke = repo().join("../shared/data/openvdb_samples/smoke.vdb");
    if smoke.is_file() {
        let vel = smoke_velocity(d, &smoke);
        cases.push(("smoke still", smoke_stage(d, "d.usda", &smoke, &vel, false)));
        cases.push((
            "smoke velocity",
            smoke_stage(d, "e.usda", &smoke, &vel, true),
        ));
    } else {
        println!("(no ../shared/data: the smoke cases are left out)");
    }
    let lookups: Vec<f64> = cases.iter().map(|(_, p)| time(p, true).1).collect();
    let mut times = vec![Vec::new(); cases.len()];
    for round in 0..ROUNDS {
        // Rotate the order each round so no case always runs first.
        for k in 0..cases.len() {
            let i = (k + round) % cases.len();
            times[i].push(time(&cases[i].1, false).0);
        }
    }
    println!("| stage | median render s ({ROUNDS} rounds) | × still | lookups per sample |");
    println!("|---|---|---|---|");
    let mut still = 0.0;
    for (i, (name, _)) in cases.iter().enumerate() {
        let m = median(times[i].clone());
        if name.ends_with("still") {
            still = m;
        }
        println!("| {name} | {m:.3} | {:.3} | {:.1} |", m / still, lookups[i]);
    }
}
