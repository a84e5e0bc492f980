//! The production-size cumulus of `nimbus bench cumulus`: the example cloud's field
//! ([`cumulus`]) sampled at production resolution, with a thick and a thin stage over
//! the one VDB, as the thick and thin clouds of Kutz et al. 2017's Figure 11 that the
//! supplement's Tables 1 and 2 measure ([`super::octree_tables`]).
//!
//! Why this cloud: decomposition tracking saves lookups where a majorant cell's minimum
//! (its control) is a large part of its maximum, which needs a field that is smooth at
//! the scale of the finest cells and dense inside, and a lookup is only worth saving
//! when it waits on memory, which needs a grid far larger than the caches. The cumulus
//! is a smooth signed-distance shape with a soft edge, a core that rises to density 1
//! and a low-frequency ±20 % modulation, so at 1,152 voxels across its interior varies
//! by about 1 % from voxel to voxel, and 200 M active voxels make about 900 MB of
//! bricks. (The smoke-derived grid of `bench grid make` is the counter-example: noisy
//! at voxel scale, so its cells' minima are small.)

use crate::output::write_atomically;
use crate::volume::grid::RawGrid;
use crate::volume::procedural::{cumulus, cumulus_bounds, grid_from_fn};
use crate::volume::vdb::write_float_grid_bytes;
use anyhow::{bail, Context, Result};
use glam::DVec3;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// What to generate.
#[derive(Clone, Copy, Debug)]
pub struct CumulusSpec {
    /// Voxels across the example's [-1, 1] box (the example has 128; only the cloud's
    /// bounding box is stored).
    pub resolution: u32,
    /// Mean free path in the thick cloud's core (density 1), in voxels.
    pub mean_free_path: f64,
    /// The thin cloud's density scale is the thick one's divided by this.
    pub thin_factor: f64,
}

impl Default for CumulusSpec {
    /// 1,152 voxels across (9× the example: 203 M active voxels), a two-voxel mean free
    /// path in the thick core, a thin cloud ten times less dense.
    fn default() -> Self {
        CumulusSpec {
            resolution: 1152,
            mean_free_path: 2.0,
            thin_factor: 10.0,
        }
    }
}

impl CumulusSpec {
    /// World size of a voxel.
    pub fn voxel_size(&self) -> f64 {
        2.0 / self.resolution as f64
    }

    /// The thick stage's `nimbus:densityScale`: σt = 1 per unit density (absorption
    /// 0.02 + scattering 0.98), so at density 1 a mean free path of `mean_free_path`
    /// voxels.
    pub fn thick_density_scale(&self) -> f64 {
        1.0 / (self.mean_free_path * self.voxel_size())
    }

    pub fn thin_density_scale(&self) -> f64 {
        self.thick_density_scale() / self.thin_factor
    }

    fn check(&self) -> Result<()> {
        if !(16..=4096).contains(&self.resolution) {
            bail!(
                "--resolution must lie in 16..=4096 voxels, got {}",
                self.resolution
            );
        }
        for (name, v) in [
            ("--mean-free-path", self.mean_free_path),
            ("--thin-factor", self.thin_factor),
        ] {
            if !(v.is_finite() && v > 0.0) {
                bail!("{name} must be a positive number, got {v}");
            }
        }
        Ok(())
    }
}

/// The cumulus density grid at `resolution` voxels across [-1, 1]³, over the index box
/// of the voxels whose centres lie in [`cumulus_bounds`] (voxel centres on the same
/// lattice as the example's `-1 + (i + ½)·2/resolution`).
pub fn cumulus_grid(resolution: u32) -> RawGrid {
    let n = resolution as f64;
    let v = 2.0 / n;
    let (lo, hi) = cumulus_bounds();
    // Voxel i's centre is -1 + (i + 0.5)·v.
    let first = |x: f64| (((x + 1.0) / v - 0.5).floor().max(0.0)) as i32;
    let last = |x: f64| (((x + 1.0) / v - 0.5).ceil().min(n - 1.0)) as i32;
    let i0 = [0, 1, 2].map(|a| first(lo[a]));
    let i1 = [0, 1, 2].map(|a| last(hi[a]));
    let dims = [0, 1, 2].map(|a| i1[a] - i0[a] + 1);
    let origin =
        DVec3::new(i0[0] as f64, i0[1] as f64, i0[2] as f64) * v + DVec3::splat(-1.0 + 0.5 * v);
    grid_from_fn("density", dims, origin, v, cumulus)
}

/// What [`write`] produced.
#[derive(Clone, Debug)]
pub struct CumulusFiles {
    pub vdb: PathBuf,
    pub thick: PathBuf,
    pub thin: PathBuf,
    pub active_voxels: u64,
    pub leaves: usize,
    /// Mean density of the active voxels whose density is at least 0.9 (the core).
    pub core_density: f64,
    pub vdb_bytes: u64,
    pub generate_seconds: f64,
    pub write_seconds: f64,
}

/// Generates the cumulus and writes `out/cumulus.vdb` with the stages `out/thick.usda`
/// and `out/thin.usda` that render it (each file written atomically; `out` is created).
pub fn write(out: &Path, spec: &CumulusSpec) -> Result<CumulusFiles> {
    spec.check()?;
    std::fs::create_dir_all(out).with_context(|| format!("cannot create {}", out.display()))?;
    let start = Instant::now();
    let grid = cumulus_grid(spec.resolution);
    let generate_seconds = start.elapsed().as_secs_f64();
    let (mut core_sum, mut core_n) = (0f64, 0u64);
    for leaf in &grid.leaves {
        for &x in leaf.values.iter().filter(|&&x| x >= 0.9) {
            core_sum += x as f64;
            core_n += 1;
        }
    }
    let start = Instant::now();
    let vdb = out.join("cumulus.vdb");
    let bytes = write_float_grid_bytes(&grid)?;
    write_atomically(&vdb, |f| {
        use std::io::Write;
        f.write_all(&bytes).map_err(|e| e.to_string())
    })?;
    let write_seconds = start.elapsed().as_secs_f64();
    let files = CumulusFiles {
        thick: out.join("thick.usda"),
        thin: out.join("thin.usda"),
        active_voxels: grid.active_voxel_count(),
        leaves: grid.leaves.len(),
        core_density: core_sum / core_n.max(1) as f64,
        vdb_bytes: bytes.len() as u64,
        generate_seconds,
        write_seconds,
        vdb,
    };
    for (path, scale, name) in [
        (&files.thick, spec.thick_density_scale(), "thick"),
        (&files.thin, spec.thin_density_scale(), "thin"),
    ] {
        let text = stage_text(spec, scale, name);
        write_atomically(path, |f| {
            use std::io::Write;
            f.write_all(text.as_bytes()).map_err(|e| e.to_string())
        })?;
    }
    Ok(files)
}

/// A stage rendering `cumulus.vdb` beside it as the example cloud is rendered
/// (`scenes/cloud`: its material, camera, sun and sky), with `density_scale`.
fn stage_text(spec: &CumulusSpec, density_scale: f64, name: &str) -> String {
    format!(
        r#"#usda 1.0
(
    defaultPrim = "World"
    metersPerUnit = 1
    upAxis = "Y"
    renderSettingsPrimPath = "/Render/Settings"
    doc = """The {name} production-size cumulus, written by `nimbus bench cumulus`: the example
cloud's field at {res} voxels across [-1, 1] (voxel {voxel:.6}), density scale {density_scale:.4}
(mean free path {mfp:.3} voxels at density 1). Material, camera and lights as scenes/cloud."""
)

def Xform "World"
{{
    def Volume "Cloud" (
        prepend apiSchemas = ["NimbusVolumeAPI"]
    )
    {{
        rel field:density = </World/Cloud/density>
        token nimbus:densityField = "density"
        float nimbus:densityScale = {density_scale}
        color3f nimbus:absorption = (0.02, 0.02, 0.02)
        color3f nimbus:scattering = (0.98, 0.98, 0.98)
        float nimbus:anisotropy = 0.5
        double3 xformOp:translate = (0, 0, 0)
        float3 xformOp:rotateXYZ = (0, 20, 0)
        uniform token[] xformOpOrder = ["xformOp:translate", "xformOp:rotateXYZ"]

        def OpenVDBAsset "density"
        {{
            asset filePath = @./cumulus.vdb@
            token fieldName = "density"
        }}
    }}

    def Camera "Camera"
    {{
        float focalLength = 50
        float horizontalAperture = 36
        float verticalAperture = 27
        float2 clippingRange = (0.1, 1000)
        double3 xformOp:translate = (0, -0.5, 4.2)
        float3 xformOp:rotateXYZ = (5, 0, 0)
        uniform token[] xformOpOrder = ["xformOp:translate", "xformOp:rotateXYZ"]
    }}

    def DistantLight "Sun"
    {{
        float inputs:intensity = 6
        color3f inputs:color = (1, 0.95, 0.88)
        float inputs:angle = 0.53
        bool inputs:normalize = 1
        float3 xformOp:rotateXYZ = (-30, 80, 0)
        uniform token[] xformOpOrder = ["xformOp:rotateXYZ"]
    }}

    def DomeLight "Sky"
    {{
        float inputs:intensity = 0.35
        color3f inputs:color = (0.35, 0.55, 1)
    }}
}}

def Scope "Render"
{{
    def RenderSettings "Settings" (
        prepend apiSchemas = ["NimbusRenderSettingsAPI"]
    )
    {{
        rel camera = </World/Camera>
        uniform int2 resolution = (128, 96)
        int nimbus:samples = 32
        int nimbus:maxDepth = 64
        int nimbus:seed = 1
    }}
}}
"#,
        res = spec.resolution,
        voxel = spec.voxel_size(),
        mfp = 1.0 / (density_scale * spec.voxel_size()),
    )
}
