//! `nimbus info`: what Nimbus reads from a stage, a VDB file or a deep EXR.

use crate::render::analysis::Given;
use crate::scene::{load_stage, LoadOptions};
use crate::volume::grid::Grid;
use crate::volume::majorant::{MajorantSpec, MajorantTree, MAX_DEPTH};
use crate::volume::vdb;
use anyhow::Result;
use clap::Args;
use std::path::PathBuf;

#[derive(Args, Debug)]
pub struct InfoArgs {
    /// The USD stage, a .vdb file (lists its grids) or a deep .exr (its sample counts).
    pub stage: PathBuf,
    /// Time code to evaluate the stage at.
    #[arg(long)]
    pub frame: Option<f64>,
    /// Majorant octree depth to build and describe (default 8).
    #[arg(long, default_value_t = 8)]
    pub octree_depth: u32,
}

pub fn run(args: InfoArgs) -> Result<()> {
    if args
        .stage
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("vdb"))
    {
        return vdb_info(&args);
    }
    if crate::output::deep::is_deep_exr(&args.stage) {
        return deep_info(&args.stage);
    }
    let scene = load_stage(
        &args.stage,
        &LoadOptions {
            frame: args.frame,
            camera: None,
        },
    )?;
    println!(
        "stage: {} (time {})",
        scene.stage_path.display(),
        if scene.time.is_nan() {
            "default".to_string()
        } else {
            scene.time.to_string()
        }
    );
    println!("vdb reader: {}", vdb::active_reader().name());
    let c = &scene.camera;
    let lens = match c.f_stop > 0.0 && c.focus_distance > 0.0 {
        true => format!(" fStop {} focusDistance {}", c.f_stop, c.focus_distance),
        false => String::new(),
    };
    println!(
        "camera: {} {:?} focal {} aperture {}x{} clipping {:?}{lens}",
        c.prim_path,
        c.projection,
        c.focal_length,
        c.horizontal_aperture,
        c.vertical_aperture,
        c.clipping_range
    );
    for l in &scene.distant_lights {
        println!(
            "distant light: {} direction {:?} intensity {} exposure {} color {:?} normalize {} angle {}",
            l.prim_path, l.direction, l.intensity, l.exposure, l.color, l.normalize, l.angle_degrees
        );
    }
    for l in &scene.dome_lights {
        println!(
            "dome light: {} intensity {} exposure {} color {:?}{}",
            l.prim_path,
            l.intensity,
            l.exposure,
            l.color,
            l.texture_file
                .as_ref()
                .map(|t| format!(" texture {t} ({})", l.texture_format))
                .unwrap_or_default()
        );
    }
    for l in &scene.sphere_lights {
        println!(
            "sphere light: {} position {:?} radius {} intensity {} exposure {} color {:?} normalize {} treatAsPoint {}",
            l.prim_path,
            l.light_to_world.w_axis.truncate().to_array(),
            l.radius,
            l.intensity,
            l.exposure,
            l.color,
            l.normalize,
            l.treat_as_point
        );
    }
    for l in &scene.rect_lights {
        println!(
            "rect light: {} position {:?} size {}x{} intensity {} exposure {} color {:?} normalize {}",
            l.prim_path,
            l.light_to_world.w_axis.truncate().to_array(),
            l.width,
            l.height,
            l.intensity,
            l.exposure,
            l.color,
            l.normalize
        );
    }
    for l in &scene.disk_lights {
        println!(
            "disk light: {} position {:?} radius {} intensity {} exposure {} color {:?} normalize {}",
            l.prim_path,
            l.light_to_world.w_axis.truncate().to_array(),
            l.radius,
            l.intensity,
            l.exposure,
            l.color,
            l.normalize
        );
    }
    for l in &scene.cylinder_lights {
        println!(
            "cylinder light: {} position {:?} length {} radius {} intensity {} exposure {} color {:?} normalize {} treatAsLine {}",
            l.prim_path,
            l.light_to_world.w_axis.truncate().to_array(),
            l.length,
            l.radius,
            l.intensity,
            l.exposure,
            l.color,
            l.normalize,
            l.treat_as_line
        );
    }
    let s = &scene.settings;
    println!(
        "render settings: {} resolution {}x{} samples {} maxDepth {} seed {}",
        s.prim_path.as_deref().unwrap_or("(none)"),
        s.resolution.0,
        s.resolution.1,
        s.samples,
        s.max_depth,
        s.seed
    );
    for p in &s.products {
        let vars: Vec<_> = p.vars.iter().map(|v| v.source_name.as_str()).collect();
        println!(
            "  product {} {:?} vars {:?}",
            p.prim_path, p.product_name, vars
        );
    }
    print_holdouts(&scene.holdouts);
    for v in &scene.volumes {
        println!(
            "volume: {} densityField {} densityScale {} absorption {:?} scattering {:?} anisotropy {}",
            v.prim_path, v.density.prim_path, v.density_scale, v.absorption, v.scattering, v.anisotropy
        );
        let e = &v.emission;
        match &e.temperature {
            Some((name, f)) => println!(
                "  emission: blackbody from temperatureField {name} ({}) temperatureScale {} K/unit blackbodyIntensity {}: Le = {} * (T/1000 K)^4 * rgb(T)",
                f.prim_path, e.temperature_scale, e.blackbody_intensity, e.blackbody_intensity
            ),
            None => println!("  emission: no temperatureField (no blackbody emission)"),
        }
        match &e.emission {
            Some((name, f)) => println!(
                "  emission: emissionField {name} ({}) emissionColor {:?} emissionScale {}: Le = {:?} * value",
                f.prim_path,
                e.emission_color,
                e.emission_scale,
                e.emission_color.map(|c| c * e.emission_scale)
            ),
            None => println!("  emission: no emissionField"),
        }
        if e.is_emissive() {
            println!("  emission source term: absorption * density * Le (nothing emits where density is 0)");
        }
        match &v.albedo {
            Some((name, f)) => println!(
                "  albedo: albedoField {name} ({}): multiplier c(x) in [0,1]^3, scattering * c, absorption + (1 - c) * scattering (extinction unchanged)",
                f.prim_path
            ),
            None => println!("  albedo: constant (no albedoField)"),
        }
        if let Some(shader) = &v.material_shader {
            println!("  parameters from the bound material's volume shader {shader}");
        }
        for (name, f) in &v.fields {
            println!(
                "  field:{name} -> {} file {} fieldName '{}' fieldIndex {:?}",
                f.prim_path, f.file, f.field_name, f.field_index
            );
            match vdb::list_grids(&f.file) {
                Ok(grids) => {
                    for g in grids {
                        println!(
                            "    grid '{}' type {} active voxels {}",
                            g.name,
                            g.value_type,
                            g.active_voxels
                                .map(|n| n.to_string())
                                .unwrap_or_else(|| "?".into())
                        );
                    }
                }
                Err(e) => println!("    cannot list grids: {e}"),
            }
            if v.albedo.as_ref().is_some_and(|(n, _)| n == name) {
                // The albedo field: a Vec3s (or float, grey) grid, read as three channels.
                match vdb::read_color_grid(&f.file, &f.field_name, f.field_index) {
                    Ok(raw) => println!(
                        "    loaded '{}' as the albedo grid: {} active voxels, {} leaves, {} tiles, background {:?}",
                        raw[0].name,
                        raw[0].active_voxel_count(),
                        raw[0].leaves.len(),
                        raw[0].tiles.len(),
                        raw.each_ref().map(|g| g.background)
                    ),
                    Err(e) => println!("    cannot load: {e:#}"),
                }
                continue;
            }
            match vdb::read_float_grid(&f.file, &f.field_name, f.field_index)
                .map_err(anyhow::Error::from)
                .and_then(|raw| {
                    let g = Grid::from_raw(&raw)?;
                    Ok((raw, g))
                }) {
                Ok((raw, g)) => {
                    let wb = raw.world_bounds(v.volume_to_world);
                    println!(
                        "    loaded '{}': {} active voxels, {} leaves, {} tiles, background {}, {} bricks ({:.1} MiB), sanitized voxels {}",
                        raw.name,
                        raw.active_voxel_count(),
                        raw.leaves.len(),
                        raw.tiles.len(),
                        raw.background,
                        g.brick_count(),
                        g.memory_bytes() as f64 / 1048576.0,
                        g.sanitized_voxels
                    );
                    if let Some((lo, hi)) = wb {
                        println!("    world bounds (active voxel centres): {lo:?} .. {hi:?}");
                    }
                    let depth = args.octree_depth.clamp(1, MAX_DEPTH);
                    let t = MajorantTree::build(&g, MajorantSpec::Octree { depth });
                    let e = t.leaf_edge();
                    println!(
                        "    majorant octree depth {depth}: {} levels, {:?} leaves of {}x{}x{} voxels, max density {}, built in {:.3} s, {:.2} MiB",
                        t.levels(),
                        t.dims(),
                        e[0],
                        e[1],
                        e[2],
                        t.max_density(),
                        t.build_seconds(),
                        t.memory_bytes() as f64 / 1048576.0
                    );
                }
                Err(e) => println!("    cannot load: {e:#}"),
            }
        }
    }
    print_analysis(&args, &scene, args.octree_depth.clamp(1, MAX_DEPTH));
    Ok(())
}

/// The holdout geometry (black matte occluders) and what its BVH costs, when the stage
/// has any; a stage without geometry prints nothing.
fn print_holdouts(meshes: &[crate::scene::HoldoutMesh]) {
    if meshes.is_empty() {
        return;
    }
    let s = crate::render::holdouts::Holdouts::build(meshes).stats();
    println!(
        "holdouts: {} meshes, {} triangles, {} degenerate skipped, BVH built in {:.3} s, {:.2} MiB",
        s.meshes,
        s.triangles,
        s.degenerate_triangles,
        s.build_seconds,
        s.bytes as f64 / (1024.0 * 1024.0)
    );
    const LISTED: usize = 20;
    for m in meshes.iter().take(LISTED) {
        println!(
            "  holdout {} ({}): {} triangles, {} degenerate skipped",
            m.prim_path,
            m.prim_type,
            m.triangles.len(),
            m.degenerate_triangles
        );
    }
    if meshes.len() > LISTED {
        println!("  … and {} more", meshes.len() - LISTED);
    }
}

/// The scene analysis and what `--tracker auto` would pick (at the stage's resolution).
fn print_analysis(args: &InfoArgs, scene: &crate::scene::Scene, depth: u32) {
    use crate::render::session::{Overrides, Session};
    use crate::track::select::TrackerSettings;
    // The session loads the grids and analyses as `render` does (a stage without a
    // camera or lights gets the defaults `render` would give it).
    let overrides = Overrides {
        frame: args.frame,
        octree_depth: Some(depth),
        ..Overrides::default()
    };
    match Session::open(&args.stage, &overrides) {
        Ok(session) => {
            for w in &session.warnings {
                println!("note: render would warn: {w}");
            }
            let a = &session.analysis;
            println!(
                "analysis: volumes {}, grey {}, emissive {}, constant albedo {}{}, homogeneous {}, empty leaves {:.1}% (depth {depth}), isotropic {}, max albedo {:.3}, lights emitting {} of {}, volume visible {}",
                a.volumes,
                a.grey,
                a.emissive,
                a.constant_albedo,
                a.albedo_field
                    .as_ref()
                    .map(|f| format!(" (albedo field {f})"))
                    .unwrap_or_default(),
                a.homogeneous,
                100.0 * a.empty_cell_fraction,
                a.isotropic,
                a.max_albedo,
                a.lights_emitting,
                a.lights_total,
                a.volume_visible
            );
            // What `render` would do without flags: the stage may name the structure.
            let given = Given {
                majorants: scene.settings.octree_depth.is_some(),
                ..Given::default()
            };
            let (t, reason) = a.choose(TrackerSettings::default(), given);
            println!(
                "tracker auto: {} scheme {} transmittance {}{}: {reason}",
                t.tracker.name(),
                t.scheme.name(),
                t.transmittance.name(),
                if t.options.no_absorption_events {
                    ", no absorption events"
                } else {
                    ""
                }
            );
            if let Some(MajorantSpec::Uniform { cell_voxels: 0 }) = a.majorants(given) {
                println!("majorants auto: one global majorant per volume");
            }
        }
        Err(e) => println!("analysis: unavailable ({e:#})"),
    }
}

/// `nimbus info FILE.vdb`: the file's grids (name, type, active voxels) and, for float
/// and Vec3s grids, what loading them gives: voxel counts, value range, world bounds.
fn vdb_info(args: &InfoArgs) -> Result<()> {
    use crate::volume::asset::AssetLocation;
    let loc = AssetLocation::File(args.stage.clone());
    let grids = vdb::list_grids(&loc)?;
    println!("vdb: {} ({} grids)", args.stage.display(), grids.len());
    println!("vdb reader: {}", vdb::active_reader().name());
    for g in grids {
        println!(
            "grid '{}' type {} active voxels {}",
            g.name,
            g.value_type,
            g.active_voxels
                .map(|n| n.to_string())
                .unwrap_or_else(|| "?".into())
        );
        let loaded = if g.value_type.contains("float") {
            vdb::read_float_grid(&loc, &g.name, None).map(|r| vec![r])
        } else if g.value_type.contains("vec3s") {
            vdb::read_vec3s_grid(&loc, &g.name, None).map(Vec::from)
        } else {
            continue;
        };
        match loaded {
            Ok(channels) => {
                let vector = channels.len() == 3;
                for (c, raw) in channels.iter().enumerate() {
                    let (lo, hi) = active_value_range(raw);
                    println!(
                        "  '{}'{}: {} active voxels, {} leaves, {} tiles, background {}, active values {lo} .. {hi}, world bounds {:?}",
                        raw.name,
                        if vector { [".x", ".y", ".z"][c] } else { "" },
                        raw.active_voxel_count(),
                        raw.leaves.len(),
                        raw.tiles.len(),
                        raw.background,
                        raw.world_bounds(glam::DMat4::IDENTITY)
                    );
                }
            }
            Err(e) => println!("  cannot load: {e}"),
        }
    }
    Ok(())
}

/// Smallest and largest active value (voxels and tiles) as stored; NaNs are skipped
/// (`f32::min`/`max`); (inf, -inf) for a grid with no active value.
fn active_value_range(raw: &crate::volume::grid::RawGrid) -> (f32, f32) {
    let mut r = (f32::INFINITY, f32::NEG_INFINITY);
    let mut add = |v: f32| r = (r.0.min(v), r.1.max(v));
    for l in &raw.leaves {
        for (i, &v) in l.values.iter().enumerate() {
            if l.active[i / 64] >> (i % 64) & 1 == 1 {
                add(v);
            }
        }
    }
    for t in raw.tiles.iter().filter(|t| t.active) {
        add(t.value);
    }
    r
}

/// `nimbus info FILE.exr` on a deep EXR: windows, channels and how the samples are
/// spread over the pixels.
fn deep_info(path: &std::path::Path) -> Result<()> {
    use crate::output::deep::read_deep_exr;
    let meta = ::exr::meta::MetaData::read_from_file(path, false)?;
    let channels: Vec<String> = meta
        .headers
        .first()
        .map(|h| {
            h.channels
                .list
                .iter()
                .map(|c| format!("{} ({:?})", c.name, c.sample_type))
                .collect()
        })
        .unwrap_or_default();
    let image = read_deep_exr(path)?;
    let (w, h) = image.full;
    let r = image.region;
    println!("deep exr: {} (deep scanline)", path.display());
    println!(
        "data window: x {}..{} y {}..{} ({}x{} pixels), display window {w}x{h}",
        r.x0,
        r.x1,
        r.y0,
        r.y1,
        r.width(),
        r.height()
    );
    println!("channels: {}", channels.join(", "));
    let counts = &image.counts;
    let min = counts.iter().min().copied().unwrap_or(0);
    let max = counts.iter().max().copied().unwrap_or(0);
    let mean = image.samples.len() as f64 / counts.len().max(1) as f64;
    let empty = counts.iter().filter(|&&n| n == 0).count();
    println!(
        "samples: {} total, per pixel min {min} / mean {mean:.3} / max {max}, pixels with 0 samples {empty} of {}",
        image.samples.len(),
        counts.len()
    );
    Ok(())
}
