//! `nimbus bench grid`: production-size grids (issue 17 part 3); the measurements are
//! [`crate::bench::grid`]'s, this parses and prints.
//!
//! `make` builds a benchmark grid from a real VDB (upsampled with trilinear
//! interpolation, procedural detail and a halo that grows the active region; see
//! [`crate::volume::upsample`]) and writes it with a stage to render it. `measure`
//! reports, for a VDB grid: load time (VDB → bricks, serial and parallel brick build),
//! memory per active voxel against OpenVDB's own in-memory size, and nanoseconds per
//! `Grid::sample_trilinear` lookup against the size of the region the lookups fall in,
//! from cache-resident to the whole grid. Render times at several octree depths come
//! from `nimbus bench octree` on the stage `make` writes.

use crate::bench::grid::{huge_pages_mb, lookup_boxes, measure_load, measure_lookups};
use crate::volume::asset::AssetLocation;
use crate::volume::grid::BRICK_VOXELS;
use crate::volume::upsample::{upsample, UpsampleParams};
use crate::volume::vdb;
use anyhow::{bail, Context, Result};
use clap::{Args, Subcommand};
use std::path::{Path, PathBuf};
use std::time::Instant;

#[derive(Subcommand, Debug)]
pub enum GridCommand {
    /// Upsample a VDB grid (trilinear, plus procedural detail and a grown halo) and
    /// write it as OUT/NAME.vdb with a stage OUT/NAME.usda that renders it.
    Make(MakeArgs),
    /// Load time, memory per active voxel and ns per lookup of a VDB grid.
    Measure(MeasureArgs),
}

#[derive(Args, Debug)]
pub struct MakeArgs {
    /// The source VDB file.
    pub input: PathBuf,
    /// Output directory (created if missing).
    #[arg(long)]
    pub out: PathBuf,
    /// Base name of the written files.
    #[arg(long, default_value = "big")]
    pub name: String,
    /// The float grid to read.
    #[arg(long, default_value = "density")]
    pub grid: String,
    /// Fine voxels per source voxel along each axis.
    #[arg(long, default_value_t = 4)]
    pub factor: i32,
    /// Width of the grown region around the active voxels, in source voxels.
    #[arg(long, default_value_t = 20)]
    pub halo: i32,
    /// Noise amplitude on the halo's edge, in source voxels.
    #[arg(long, default_value_t = 1.5)]
    pub edge_noise: f32,
    /// Relative amplitude of the multiplicative detail on the upsampled density.
    #[arg(long, default_value_t = 0.5)]
    pub detail: f32,
    /// Density added inside the active region, fading out across the halo.
    #[arg(long, default_value_t = 0.05)]
    pub halo_density: f32,
    #[arg(long, default_value_t = 17)]
    pub seed: u64,
    /// `nimbus:densityScale` of the stage (σt per unit density).
    #[arg(long, default_value_t = 4.0)]
    pub density_scale: f32,
}

#[derive(Args, Debug)]
pub struct MeasureArgs {
    /// The VDB file.
    pub vdb: PathBuf,
    /// The float grid to read.
    #[arg(long, default_value = "density")]
    pub grid: String,
    /// Rounds (loads, and lookup passes over every region size), interleaved.
    #[arg(long, default_value_t = 3)]
    pub rounds: u32,
    /// Lookups per region size, per round and mode.
    #[arg(long, default_value_t = 1 << 22)]
    pub lookups: u64,
    /// Edge lengths (voxels) of the cubes the lookups fall in; 0 = the whole active
    /// bounds.
    #[arg(long, value_delimiter = ',', default_value = "8,16,32,64,128,256,0")]
    pub sizes: Vec<i32>,
    /// Skip the OpenVDB memory measurement (it reads the grid once more).
    #[arg(long)]
    pub no_openvdb_memory: bool,
}

pub fn run(cmd: GridCommand) -> Result<()> {
    match cmd {
        GridCommand::Make(a) => make(a),
        GridCommand::Measure(a) => measure(a),
    }
}

fn make(a: MakeArgs) -> Result<()> {
    let loc = AssetLocation::File(a.input.clone());
    let start = Instant::now();
    let raw = vdb::read_float_grid(&loc, &a.grid, None)?;
    let read_s = start.elapsed().as_secs_f64();
    let params = UpsampleParams {
        factor: a.factor,
        halo: a.halo,
        edge_noise: a.edge_noise,
        detail: a.detail,
        halo_density: a.halo_density,
        seed: a.seed,
    };
    let start = Instant::now();
    let big = upsample(&raw, &params).with_context(|| a.input.display().to_string())?;
    let gen_s = start.elapsed().as_secs_f64();
    eprintln!(
        "nimbus: {} '{}': {} active voxels, {} leaves -> x{} upsampled: {} active voxels, {} leaves ({:.1} s read, {:.1} s generate on {} threads)",
        a.input.display(),
        a.grid,
        raw.active_voxel_count(),
        raw.leaves.len(),
        a.factor,
        big.active_voxel_count(),
        big.leaves.len(),
        read_s,
        gen_s,
        rayon::current_num_threads()
    );
    drop(raw);
    std::fs::create_dir_all(&a.out)
        .with_context(|| format!("cannot create {}", a.out.display()))?;
    let vdb_path = a.out.join(format!("{}.vdb", a.name));
    let start = Instant::now();
    vdb::write_float_grid(&vdb_path, &big)?;
    let write_s = start.elapsed().as_secs_f64();
    let stage_path = a.out.join(format!("{}.usda", a.name));
    std::fs::write(&stage_path, stage_text(&a, &params, &vdb_path))
        .with_context(|| format!("cannot write {}", stage_path.display()))?;
    println!(
        "wrote {} ({:.1} MB, {:.1} s) and {}",
        vdb_path.display(),
        std::fs::metadata(&vdb_path).map_or(0, |m| m.len()) as f64 / 1e6,
        write_s,
        stage_path.display()
    );
    Ok(())
}

fn stage_text(a: &MakeArgs, p: &UpsampleParams, vdb_path: &Path) -> String {
    let file = vdb_path
        .file_name()
        .map_or_else(String::new, |f| f.to_string_lossy().into_owned());
    format!(
        r#"#usda 1.0
(
    defaultPrim = "World"
    metersPerUnit = 1
    upAxis = "Y"
    renderSettingsPrimPath = "/Render/Settings"
    doc = """Production-size grid (issue 17 part 3), written by `nimbus bench grid make`:
{input} '{grid}' upsampled x{factor} per axis (trilinear), detail {detail}, halo {halo} source voxels
(edge noise {edge}), halo density {hd}, seed {seed}. Camera and lights as benches/smoke_thick."""
)

def Xform "World"
{{
    def Volume "Smoke" (
        prepend apiSchemas = ["NimbusVolumeAPI"]
    )
    {{
        rel field:density = </World/Smoke/density>
        token nimbus:densityField = "density"
        float nimbus:densityScale = {scale}
        color3f nimbus:absorption = (0.1, 0.1, 0.1)
        color3f nimbus:scattering = (0.9, 0.9, 0.9)
        float nimbus:anisotropy = 0.3

        def OpenVDBAsset "density"
        {{
            asset filePath = @./{file}@
            token fieldName = "{grid}"
        }}
    }}

    def Camera "Camera"
    {{
        float focalLength = 50
        float horizontalAperture = 36
        float verticalAperture = 27
        float2 clippingRange = (0.1, 10000)
        double3 xformOp:translate = (-7.4, 40.5, 100)
        uniform token[] xformOpOrder = ["xformOp:translate"]
    }}

    def DistantLight "Sun"
    {{
        float inputs:intensity = 5
        color3f inputs:color = (1, 0.95, 0.88)
        float inputs:angle = 0.53
        bool inputs:normalize = 1
        float3 xformOp:rotateXYZ = (-40, 35, 0)
        uniform token[] xformOpOrder = ["xformOp:rotateXYZ"]
    }}

    def DomeLight "Sky"
    {{
        float inputs:intensity = 0.4
        color3f inputs:color = (0.45, 0.6, 0.9)
    }}
}}

def Scope "Render"
{{
    def RenderSettings "Settings" (
        prepend apiSchemas = ["NimbusRenderSettingsAPI"]
    )
    {{
        rel camera = </World/Camera>
        uniform int2 resolution = (64, 96)
        int nimbus:samples = 8
        int nimbus:maxDepth = 64
        int nimbus:seed = 1
    }}
}}
"#,
        input = a.input.display(),
        grid = a.grid,
        factor = p.factor,
        detail = p.detail,
        halo = p.halo,
        edge = p.edge_noise,
        hd = p.halo_density,
        seed = p.seed,
        scale = a.density_scale,
    )
}

fn measure(a: MeasureArgs) -> Result<()> {
    if a.rounds == 0 || a.lookups == 0 {
        bail!("--rounds and --lookups must be at least 1");
    }
    if a.sizes.iter().any(|&s| s < 0) {
        bail!("--sizes must be ≥ 0 (0 = the whole active bounds)");
    }
    let loc = AssetLocation::File(a.vdb.clone());
    let file_bytes = std::fs::metadata(&a.vdb)
        .with_context(|| format!("cannot read {}", a.vdb.display()))?
        .len();
    let threads = rayon::current_num_threads();
    println!(
        "{} grid '{}': {:.1} MB file, {} rounds, reader {}, {} rayon threads",
        a.vdb.display(),
        a.grid,
        file_bytes as f64 / 1e6,
        a.rounds,
        vdb::active_reader().name(),
        threads
    );

    let (t, grid) = measure_load(&loc, &a.grid, a.rounds)?;
    let (val, read, serial, parallel) = (t.validate, t.read, t.bricks_serial, t.bricks_parallel);
    let mb = file_bytes as f64 / 1e6;
    println!("load (medians of {} rounds):", a.rounds);
    println!("  validate (Rust header + tree check)   {val:8.3} s");
    println!(
        "  read: validate + reader → RawGrid      {read:8.3} s  {:8.1} MB/s of file",
        mb / read
    );
    println!("  bricks: Grid::from_raw serial         {serial:8.3} s");
    println!(
        "  bricks: Grid::from_raw parallel       {parallel:8.3} s  ({threads} threads, {:.2}x)",
        serial / parallel
    );
    println!(
        "  total VDB → bricks (parallel)         {:8.3} s  {:8.1} MB/s of file",
        read + parallel,
        mb / (read + parallel)
    );

    // Memory.
    let active = grid.active_voxels.max(1) as f64;
    let nimbus = grid.memory_bytes();
    println!(
        "memory: {} active voxels, {} bricks",
        grid.active_voxels,
        grid.brick_count()
    );
    println!(
        "  Nimbus Grid::memory_bytes   {:10.1} MB  {:6.3} B/active voxel (bricks {:.1} MB, index {:.1} MB)",
        nimbus as f64 / 1e6,
        nimbus as f64 / active,
        (grid.brick_count() * BRICK_VOXELS * 4) as f64 / 1e6,
        (nimbus - grid.brick_count() * BRICK_VOXELS * 4) as f64 / 1e6
    );
    if let Some(mb) = huge_pages_mb() {
        println!("  process memory in transparent huge pages: {mb:.1} MB");
    }
    if !a.no_openvdb_memory {
        match vdb::openvdb_mem_usage(&loc, &a.grid, None) {
            Ok(bytes) => println!(
                "  OpenVDB grid->memUsage()    {:10.1} MB  {:6.3} B/active voxel",
                bytes as f64 / 1e6,
                bytes as f64 / active
            ),
            Err(e) => println!("  OpenVDB memUsage: unavailable ({e})"),
        }
    }

    // Lookups.
    let Some(boxes) = lookup_boxes(&grid, &a.sizes) else {
        bail!("{}: grid '{}' is empty", a.vdb.display(), a.grid);
    };
    let ns = measure_lookups(&grid, &boxes, a.rounds, a.lookups);
    println!(
        "lookups: Grid::sample_trilinear at uniform random points of a box, one thread, {} per box, mode and round; thread-CPU ns per lookup, medians (random-number cost included; 'rng' alone)",
        a.lookups
    );
    println!(
        "{:>22} {:>9} {:>11} {:>9} {:>8} {:>12} {:>11}",
        "box (voxels)", "bricks", "bricks MB", "stored %", "rng ns", "independent", "dependent"
    );
    for (b, [rng, ind, dep]) in boxes.iter().zip(ns) {
        let (total, stored) = b.bricks(&grid);
        let size = b.size;
        println!(
            "{:>22} {:>9} {:>11.2} {:>8.1}% {:>8.1} {:>12.1} {:>11.1}",
            format!("{}x{}x{}", size[0], size[1], size[2]),
            stored,
            (stored as usize * BRICK_VOXELS * 4) as f64 / 1e6,
            100.0 * stored as f64 / total.max(1) as f64,
            rng,
            ind,
            dep
        );
    }
    Ok(())
}
