//! The albedo multiplier c(x): a colour grid (issue 8: Houdini's `Cd`, a Vec3s grid,
//! or a float grid as a grey albedo) named by `nimbus:albedoField`, or a colour graph
//! connected to `nimbus:albedo` (issue 47: Principled Volume's Color driven by a node
//! tree, through the Blender add-on).
//!
//! Model. With the multiplier c(x) ∈ [0,1]³ (per channel λ),
//!
//! μs'(x,λ) = c(x,λ)·μs(x,λ),   μa'(x,λ) = μa(x,λ) + (1 − c(x,λ))·μs(x,λ),
//!
//! so the extinction μt' = μa' + μs' = μt is unchanged: majorants, free-path sampling and
//! transmittance are exactly those of the medium without the grid. Emission keeps its
//! source term μa·Le (the base absorption, not μa'): the colour grid recolours the
//! scattered light only.
//!
//! Estimator. The trackers run with c = 1 and the integrator multiplies the throughput by
//! c(x) at each real scatter event at x (one lookup per scatter event, none at null
//! collisions or in shadow rays). Unbiased: a scatter event of the c = 1 tracker
//! estimates the in-scattering integral ∫ T·μs·Ls, so weighting it by c(x) estimates
//! ∫ T·(c·μs)·Ls = ∫ T·μs'·Ls; the discarded (1 − c) fraction is exactly the extra
//! absorption (1 − c)·μs of μa', which contributes no radiance (emission is μa·Le), and
//! T is unchanged because μt is.
//!
//! Values outside [0,1] and non-finite values are clamped into [0,1] (NaN → 0): a
//! grid's when it is built ([`Albedo::clamped_values`] counts them, one count per
//! component), a graph's at each lookup.

use crate::volume::color_graph::ColorGraph;
use crate::volume::counters::Tally;
use crate::volume::grid::{world_to_index, MediumError};
use crate::volume::grid::{Grid, RawGrid};
use glam::{DMat4, DVec3};
use std::sync::Arc;

/// An albedo multiplier: a grid or a colour graph.
pub struct Albedo {
    /// The field the grid comes from (the `field:<name>` relationship, or a label), or
    /// the graph's shader ("prim path (info:id)").
    pub field: String,
    source: Source,
    /// Grid component values (voxels, tiles and backgrounds) that were outside [0,1] or
    /// not finite and were clamped (0 for a graph, clamped at each lookup).
    pub clamped_values: u64,
}

/// Where the multiplier's values come from.
enum Source {
    /// One float grid per channel (r, g, b) with one world → index transform; the
    /// grids are shared by the instances of a volume ([`Albedo::placed`]).
    Grid {
        channels: Arc<[Grid; 3]>,
        world_to_index: DMat4,
    },
    Graph(ColorGraph),
}

/// `v` clamped into [0,1] (NaN → 0), counting the values changed.
fn clamp01(v: f32, count: &mut u64) -> f32 {
    if (0.0..=1.0).contains(&v) {
        v
    } else {
        *count += 1;
        if v > 1.0 {
            1.0
        } else {
            0.0
        }
    }
}

/// Clamps every stored value of `raw` (background, tiles, all leaf values: inactive
/// leaf values take part in trilinear reconstruction too) into [0,1].
fn clamp_grid(raw: &mut RawGrid, count: &mut u64) {
    raw.background = clamp01(raw.background, count);
    for t in &mut raw.tiles {
        t.value = clamp01(t.value, count);
    }
    for l in &mut raw.leaves {
        for v in &mut l.values {
            *v = clamp01(*v, count);
        }
    }
}

impl Albedo {
    /// Builds the grid from three float grids (r, g, b; a grey albedo passes the same grid
    /// three times) sharing the first one's transform. `volume_to_world` is the volume
    /// prim's transform; `what` names the grid in errors (e.g. "nimbus:albedoField `Cd`").
    pub fn new(
        prim: &str,
        what: &str,
        field: &str,
        raw: [RawGrid; 3],
        volume_to_world: DMat4,
    ) -> Result<Albedo, MediumError> {
        let mut clamped = 0u64;
        let mut raw = raw;
        for r in &mut raw {
            clamp_grid(r, &mut clamped);
        }
        let mut grids = Vec::with_capacity(3);
        for r in &raw {
            grids.push(Grid::from_raw(r).map_err(|e| MediumError::Invalid {
                prim: prim.to_string(),
                message: format!("{what}: {e}"),
            })?);
        }
        let channels: [Grid; 3] = match grids.try_into() {
            Ok(c) => c,
            Err(_) => unreachable!("three grids"),
        };
        let world_to_index =
            world_to_index(prim, &format!("{what}: "), volume_to_world, &channels[0])?;
        Ok(Albedo {
            field: field.to_string(),
            source: Source::Grid {
                channels: Arc::new(channels),
                world_to_index,
            },
            clamped_values: clamped,
        })
    }

    /// The multiplier a colour graph gives; `source` names its shader.
    pub fn graph(source: &str, graph: ColorGraph) -> Albedo {
        Albedo {
            field: source.to_string(),
            source: Source::Graph(graph),
            clamped_values: 0,
        }
    }

    /// The same grids (shared, not copied) or graph under another volume transform.
    pub fn placed(&self, prim: &str, volume_to_world: DMat4) -> Result<Albedo, MediumError> {
        let source = match &self.source {
            Source::Grid { channels, .. } => Source::Grid {
                channels: channels.clone(),
                world_to_index: world_to_index(
                    prim,
                    "albedo grid: ",
                    volume_to_world,
                    &channels[0],
                )?,
            },
            Source::Graph(g) => Source::Graph(g.placed(volume_to_world)),
        };
        Ok(Albedo {
            field: self.field.clone(),
            source,
            clamped_values: self.clamped_values,
        })
    }

    /// The constant albedo grid `c` over all space (a grid with no voxels whose
    /// background is `c`), clamped like any grid.
    pub fn constant(field: &str, c: [f32; 3]) -> Albedo {
        let raw = c.map(|v| RawGrid {
            name: field.to_string(),
            class: "unknown".into(),
            background: v,
            leaves: Vec::new(),
            tiles: Vec::new(),
            index_to_world: DMat4::IDENTITY,
        });
        Albedo::new("", field, field, raw, DMat4::IDENTITY).expect("identity transform")
    }

    /// The multiplier c at world point `p`, per channel (one albedo lookup: at scatter
    /// events only, so the match is not per collision).
    #[inline]
    pub fn sample<C: Tally>(&self, p: DVec3, c: &mut C) -> [f32; 3] {
        c.albedo_lookup();
        match &self.source {
            Source::Grid {
                channels,
                world_to_index,
            } => {
                let i = world_to_index.transform_point3(p).as_vec3().to_array();
                channels.each_ref().map(|g| g.sample_trilinear(i))
            }
            // A colour graph may leave [0,1] (a ramp past white, a negative noise):
            // the multiplier is a fraction of the scattering, clamped like a grid's.
            Source::Graph(g) => g.rgb(p).map(|v| (v as f32).min(1.0)),
        }
    }
}
