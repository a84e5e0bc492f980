//! `nimbus info`: what Nimbus reads from a stage, a VDB file or a deep EXR
//! ([`crate::output::describe`] reads it; this prints it as text or JSON).

use crate::output::describe::{
    describe, DeepExrDescription, DescribeOptions, Description, HoldoutsDescription,
    LightDescription, LightParams, LoadedField, StageDescription, VdbDescription,
};
use anyhow::Result;
use clap::Args;
use glam::DVec3;
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
    /// Print the description as JSON (what `nimbus.info` returns in Python).
    #[arg(long)]
    pub json: bool,
}

pub fn run(args: InfoArgs) -> Result<()> {
    let d = describe(
        &args.stage,
        &DescribeOptions {
            frame: args.frame,
            octree_depth: args.octree_depth,
        },
    )?;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&d)?);
        return Ok(());
    }
    match &d {
        Description::Stage(s) => print_stage(s),
        Description::Vdb(v) => print_vdb(v),
        Description::DeepExr(e) => print_deep_exr(e),
    }
    Ok(())
}

/// glam's Debug form of a point, as `info` has always printed bounds.
fn point(p: [f64; 3]) -> DVec3 {
    DVec3::from_array(p)
}

fn print_stage(d: &StageDescription) {
    println!(
        "stage: {} (time {})",
        d.stage,
        d.time
            .map_or_else(|| "default".to_string(), |t| t.to_string())
    );
    println!("vdb reader: {}", d.vdb_reader);
    let c = &d.camera;
    let lens = match c.f_stop > 0.0 && c.focus_distance > 0.0 {
        true => format!(" fStop {} focusDistance {}", c.f_stop, c.focus_distance),
        false => String::new(),
    };
    println!(
        "camera: {} {} focal {} aperture {}x{} clipping {:?}{lens}",
        c.prim_path,
        c.projection,
        c.focal_length,
        c.horizontal_aperture,
        c.vertical_aperture,
        c.clipping_range
    );
    if let Some((open, close)) = c.shutter {
        match c.motion_keys {
            0 => println!("  shutter {open} to {close} (time codes from the frame); the camera does not move"),
            n => println!("  shutter {open} to {close} (time codes from the frame); the camera moves: {n} transform keys"),
        }
    }
    for l in &d.lights {
        print_light(l);
    }
    let s = &d.render_settings;
    println!(
        "render settings: {} resolution {}x{} samples {} maxDepth {} seed {}",
        s.prim_path.as_deref().unwrap_or("(none)"),
        s.resolution[0],
        s.resolution[1],
        s.samples,
        s.max_depth,
        s.seed
    );
    let adaptive = match (s.noise_threshold > 0.0, s.min_samples) {
        (false, _) => "off".to_string(),
        (true, 0) => format!(
            "noise threshold {} (default minimum)",
            s.noise_threshold as f32
        ),
        (true, m) => format!(
            "noise threshold {} min samples {m}",
            s.noise_threshold as f32
        ),
    };
    println!(
        "  adaptive sampling {adaptive}; denoise {}",
        if s.denoise { "on" } else { "off" }
    );
    for p in &s.products {
        println!(
            "  product {} {:?} vars {:?}",
            p.prim_path, p.product_name, p.vars
        );
    }
    if let Some(h) = &d.holdouts {
        print_holdouts(h);
    }
    for v in &d.volumes {
        println!(
            "volume: {} densityField {} densityScale {} absorption {:?} scattering {:?} anisotropy {}",
            v.prim_path, v.density_field, v.density_scale, v.absorption, v.scattering, v.anisotropy
        );
        let prim = |name: &str| v.field(name).map_or("", |f| f.prim_path.as_str());
        match &v.temperature_field {
            Some(name) => println!(
                "  emission: blackbody from temperatureField {name} ({}) temperatureScale {} K/unit blackbodyIntensity {}: Le = {} * (T/1000 K)^4 * rgb(T)",
                prim(name), v.temperature_scale, v.blackbody_intensity, v.blackbody_intensity
            ),
            None => println!("  emission: no temperatureField (no blackbody emission)"),
        }
        match &v.emission_field {
            Some(name) => println!(
                "  emission: emissionField {name} ({}) emissionColor {:?} emissionScale {}: Le = {:?} * value",
                prim(name),
                v.emission_color,
                v.emission_scale,
                v.emission_color.map(|c| c * v.emission_scale)
            ),
            None => println!("  emission: no emissionField"),
        }
        if let Some(source) = &v.emission_graph {
            println!(
                "  emission: colour graph from {source} in place of emissionColor: colour(x) * emissionScale {} * field",
                v.emission_scale
            );
        }
        if v.emission_kind == "source" {
            match (&v.emission_field, &v.emission_graph) {
                (Some(_), _) => {}
                (None, Some(_)) => println!(
                    "  emission: constant field 1 (emissionKind source): S(x) = {} * colour(x)",
                    v.emission_scale
                ),
                (None, None) => println!(
                    "  emission: constant field 1 (emissionKind source): S = {:?}",
                    v.emission_color.map(|c| c * v.emission_scale)
                ),
            }
            println!("  emission source term (emissionKind source): S itself, per unit length, independent of density (nothing where absorption * density is 0)");
        } else if v.temperature_field.is_some() || v.emission_field.is_some() {
            println!("  emission source term: absorption * density * Le (nothing emits where density is 0)");
        }
        match (&v.albedo_field, &v.albedo_graph) {
            (_, Some(source)) => println!(
                "  albedo: colour graph from {source}, evaluated at scatter events: multiplier c(x) clamped into [0,1]^3, scattering * c, absorption + (1 - c) * scattering (extinction unchanged)"
            ),
            (Some(name), None) => println!(
                "  albedo: albedoField {name} ({}): multiplier c(x) in [0,1]^3, scattering * c, absorption + (1 - c) * scattering (extinction unchanged)",
                prim(name)
            ),
            (None, None) => println!("  albedo: constant (no albedoField, nimbus:albedo not connected)"),
        }
        if v.motion_keys > 0 {
            println!(
                "  motion blur: the volume moves over the shutter ({} transform keys)",
                v.motion_keys
            );
        }
        if let Some(name) = &v.velocity_field {
            println!(
                "  motion blur: fields advected by the velocity field {name} ({}), {} s of flow per time code",
                prim(name),
                v.velocity_seconds_per_time_code
            );
        }
        if let Some(shader) = &v.material_shader {
            println!("  parameters from the bound material's volume shader {shader}");
        }
        if let Some(g) = &v.density_graph {
            println!(
                "  density: shader graph from {} ({} instructions per lookup, {}); majorants from its range analysis",
                g.source,
                g.instructions,
                match g.reads_field {
                    true => "times the density field",
                    false => "over the volume's region",
                }
            );
        }
        for (name, f) in &v.fields {
            println!(
                "  field:{name} -> {} file {} fieldName '{}' fieldIndex {:?}",
                f.prim_path, f.file, f.field_name, f.field_index
            );
            match (&f.grids, &f.grids_error) {
                (Some(grids), _) => {
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
                (None, e) => println!("    cannot list grids: {}", e.as_deref().unwrap_or("")),
            }
            match &f.loaded {
                Some(LoadedField::Albedo {
                    grid,
                    active_voxels,
                    leaves,
                    tiles,
                    background,
                }) => println!(
                    "    loaded '{grid}' as the albedo grid: {active_voxels} active voxels, {leaves} leaves, {tiles} tiles, background {background:?}"
                ),
                Some(LoadedField::Float {
                    grid,
                    active_voxels,
                    leaves,
                    tiles,
                    background,
                    bricks,
                    memory_bytes,
                    sanitized_voxels,
                    world_bounds,
                    octree: t,
                }) => {
                    println!(
                        "    loaded '{grid}': {active_voxels} active voxels, {leaves} leaves, {tiles} tiles, background {background}, {bricks} bricks ({:.1} MiB), sanitized voxels {sanitized_voxels}",
                        *memory_bytes as f64 / 1048576.0
                    );
                    if let Some([lo, hi]) = world_bounds {
                        println!(
                            "    world bounds (active voxel centres): {:?} .. {:?}",
                            point(*lo),
                            point(*hi)
                        );
                    }
                    let e = t.leaf_edge;
                    println!(
                        "    majorant octree depth {}: {} levels, {:?} leaves of {}x{}x{} voxels, max density {}, built in {:.3} s, {:.2} MiB",
                        t.depth,
                        t.levels,
                        t.dims,
                        e[0],
                        e[1],
                        e[2],
                        t.max_density,
                        t.build_seconds,
                        t.memory_bytes as f64 / 1048576.0
                    );
                }
                None => println!(
                    "    cannot load: {}",
                    f.load_error.as_deref().unwrap_or("")
                ),
            }
        }
    }
    print_analysis(d);
}

/// One line per light: its type, prim path and parameters.
fn print_light(l: &LightDescription) {
    let p = &l.prim_path;
    match &l.params {
        LightParams::Distant {
            direction,
            intensity,
            exposure,
            color,
            normalize,
            angle,
        } => println!(
            "distant light: {p} direction {direction:?} intensity {intensity} exposure {exposure} color {color:?} normalize {normalize} angle {angle}"
        ),
        LightParams::Dome {
            intensity,
            exposure,
            color,
            texture_file,
            texture_format,
        } => println!(
            "dome light: {p} intensity {intensity} exposure {exposure} color {color:?}{}",
            texture_file
                .as_ref()
                .map(|t| format!(" texture {t} ({texture_format})"))
                .unwrap_or_default()
        ),
        LightParams::Sphere {
            position,
            radius,
            intensity,
            exposure,
            color,
            normalize,
            treat_as_point,
            lights_interior,
        } => println!(
            "sphere light: {p} position {position:?} radius {radius} intensity {intensity} exposure {exposure} color {color:?} normalize {normalize} treatAsPoint {treat_as_point}{}",
            if *lights_interior { " lightsInterior" } else { "" }
        ),
        LightParams::Rect {
            position,
            width,
            height,
            intensity,
            exposure,
            color,
            normalize,
        } => println!(
            "rect light: {p} position {position:?} size {width}x{height} intensity {intensity} exposure {exposure} color {color:?} normalize {normalize}"
        ),
        LightParams::Disk {
            position,
            radius,
            intensity,
            exposure,
            color,
            normalize,
        } => println!(
            "disk light: {p} position {position:?} radius {radius} intensity {intensity} exposure {exposure} color {color:?} normalize {normalize}"
        ),
        LightParams::Cylinder {
            position,
            length,
            radius,
            intensity,
            exposure,
            color,
            normalize,
            treat_as_line,
        } => println!(
            "cylinder light: {p} position {position:?} length {length} radius {radius} intensity {intensity} exposure {exposure} color {color:?} normalize {normalize} treatAsLine {treat_as_line}"
        ),
        LightParams::Other => println!("light: {p}"),
    }
    if l.motion_keys > 0 {
        println!(
            "  motion blur: the light moves over the shutter ({} transform keys)",
            l.motion_keys
        );
    }
}

/// The holdout geometry (black matte occluders) and what its BVH costs.
fn print_holdouts(h: &HoldoutsDescription) {
    let s = &h.stats;
    println!(
        "holdouts: {} meshes, {} triangles, {} degenerate skipped, BVH built in {:.3} s, {:.2} MiB",
        s.meshes,
        s.triangles,
        s.degenerate_triangles,
        s.build_seconds,
        s.bytes as f64 / (1024.0 * 1024.0)
    );
    const LISTED: usize = 20;
    for m in h.meshes.iter().take(LISTED) {
        println!(
            "  holdout {} ({}): {} triangles, {} degenerate skipped",
            m.prim_path, m.prim_type, m.triangles, m.degenerate_triangles
        );
    }
    if h.meshes.len() > LISTED {
        println!("  … and {} more", h.meshes.len() - LISTED);
    }
}

/// The scene analysis and what `--tracker auto` would pick (at the stage's resolution).
fn print_analysis(d: &StageDescription) {
    let (Some(a), Some(t)) = (&d.analysis, &d.auto) else {
        println!(
            "analysis: unavailable ({})",
            d.analysis_error.as_deref().unwrap_or("")
        );
        return;
    };
    for w in &d.warnings {
        println!("note: render would warn: {w}");
    }
    println!(
        "analysis: volumes {}, grey {}, emissive {}, constant albedo {}{}, homogeneous {}, empty leaves {:.1}% (depth {}), isotropic {}, max albedo {:.3}, lights emitting {} of {}, volume visible {}",
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
        d.octree_depth,
        a.isotropic,
        a.max_albedo,
        a.lights_emitting,
        a.lights_total,
        a.volume_visible
    );
    println!(
        "tracker auto: {} scheme {} transmittance {}{}: {}",
        t.tracker,
        t.scheme,
        t.transmittance,
        if t.no_absorption_events {
            ", no absorption events"
        } else {
            ""
        },
        t.reason
    );
    if t.one_global_majorant {
        println!("majorants auto: one global majorant per volume");
    }
    println!("light sampling {}", t.light_sampling);
}

/// `nimbus info FILE.vdb`: the file's grids (name, type, active voxels) and, for float
/// and Vec3s grids, what loading them gives: voxel counts, value range, world bounds.
fn print_vdb(d: &VdbDescription) {
    println!("vdb: {} ({} grids)", d.vdb, d.grids.len());
    println!("vdb reader: {}", d.vdb_reader);
    for g in &d.grids {
        println!(
            "grid '{}' type {} active voxels {}",
            g.grid.name,
            g.grid.value_type,
            g.grid
                .active_voxels
                .map(|n| n.to_string())
                .unwrap_or_else(|| "?".into())
        );
        if let Some(e) = &g.load_error {
            println!("  cannot load: {e}");
        }
        for c in &g.channels {
            let [lo, hi] = c.value_range;
            println!(
                "  '{}'{}: {} active voxels, {} leaves, {} tiles, background {}, active values {lo} .. {hi}, world bounds {:?}",
                c.name,
                c.component.map_or(String::new(), |x| format!(".{x}")),
                c.active_voxels,
                c.leaves,
                c.tiles,
                c.background,
                c.world_bounds.map(|[lo, hi]| (point(lo), point(hi)))
            );
        }
    }
}

/// `nimbus info FILE.exr` on a deep EXR: windows, channels and how the samples are
/// spread over the pixels.
fn print_deep_exr(d: &DeepExrDescription) {
    let [x0, x1, y0, y1] = d.data_window;
    let [w, h] = d.display_window;
    println!("deep exr: {} (deep scanline)", d.deep_exr);
    println!(
        "data window: x {x0}..{x1} y {y0}..{y1} ({}x{} pixels), display window {w}x{h}",
        x1 - x0,
        y1 - y0
    );
    let channels: Vec<String> = d
        .channels
        .iter()
        .map(|(name, ty)| format!("{name} ({ty})"))
        .collect();
    println!("channels: {}", channels.join(", "));
    println!(
        "samples: {} total, per pixel min {} / mean {:.3} / max {}, pixels with 0 samples {} of {}",
        d.samples,
        d.samples_per_pixel_min,
        d.samples_per_pixel_mean,
        d.samples_per_pixel_max,
        d.empty_pixels,
        d.pixels
    );
}
