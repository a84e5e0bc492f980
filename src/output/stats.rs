//! The stats JSON written by `--stats`.

use serde::Serialize;

#[derive(Serialize, Debug, Clone)]
pub struct RenderStats {
    pub stage: String,
    /// Samples actually taken per pixel (every pixel has the same count).
    pub samples_per_pixel: u32,
    /// Progressive passes the samples were taken in.
    pub passes: u32,
    pub max_pass_seconds: f64,
    /// The `--spp` cap (absent when only a time limit bounds the render).
    pub spp_cap: Option<u32>,
    pub time_limit_seconds: Option<f64>,
    /// Stopped by Ctrl-C / SIGTERM before the cap or budget was reached.
    pub interrupted: bool,
    pub width: u32,
    pub height: u32,
    pub wall_seconds: f64,
    pub load_seconds: f64,
    pub render_seconds: f64,
    pub threads: usize,
    pub seed: u64,
    pub tracker: String,
    pub scheme: String,
    pub transmittance: String,
    pub residual_lookups: u64,
    pub control_collisions: u64,
    /// Mean over samples of the largest channel throughput along the path.
    pub max_throughput_mean: f64,
    /// Largest channel throughput of any path (colour explosion shows here).
    pub max_throughput_peak: f64,
    pub density_lookups: u64,
    /// Emission grid lookups (at absorption events of an emissive medium).
    pub emission_lookups: u64,
    /// Albedo grid lookups (one per scatter event when `nimbus:albedoField` is set).
    pub albedo_lookups: u64,
    /// Albedo grid component values clamped into [0,1] (0 without an albedo grid).
    pub clamped_albedo_values: u64,
    pub real_collisions: u64,
    pub null_collisions: u64,
    pub cells_visited: u64,
    pub majorant_violations: u64,
    pub nonfinite_samples: u64,
    pub sanitized_voxels: u64,
    /// Leaf cells of the majorant structure.
    pub majorant_cells: usize,
    /// `--octree-depth` as requested (null for the flat `--majorant-cell` grid).
    pub octree_depth: Option<u32>,
    /// Levels actually built (depth capped at voxel resolution; 1 for a flat grid).
    pub octree_levels: usize,
    pub octree_build_seconds: f64,
    pub octree_memory_bytes: usize,
    pub vdb_reader: String,
    /// `--profile` only (else null): thread-seconds inside density lookups, inside the
    /// majorant walk, and in the rest of the trackers, each with the clock's empty-region
    /// bias removed per timed event (`timer_empty_region_ns`).
    pub lookup_seconds: Option<f64>,
    pub traversal_seconds: Option<f64>,
    pub other_tracker_seconds: Option<f64>,
    pub timer_empty_region_ns: Option<f64>,
    /// Scheme options in effect.
    pub no_absorption_events: bool,
    pub reduced_termination: bool,
    /// Why `--tracker auto` chose the tracker (null when one was named).
    pub tracker_auto_reason: Option<String>,
    /// The scene analysis the render was planned from.
    pub analysis: crate::render::analysis::Analysis,
    /// The specialised code paths the render ran (`single_channel`: grey media tracked
    /// with one channel).
    pub code_paths: CodePathsUsed,
}

/// The code paths of a render, as the stats report them.
#[derive(Clone, Debug, Serialize)]
pub struct CodePathsUsed {
    /// Lookups and collisions were counted (always, when stats are written).
    pub counting: bool,
    /// Grey medium tracked single-channel (`track::grey`).
    pub single_channel: bool,
}
