//! Volume emission: a blackbody source from a temperature field and an emission field
//! with a colour and a scale (issue 8). Emitted radiance at a world point x is
//!
//! Le(x) = I_bb · (T/1000 K)⁴ · rgb(T) + s_e · c_e · e(x),   T = s_T · temperature(x),
//!
//! with rgb(T) UsdLux's colour-temperature colour ([`usd_blackbody_rgb`], pxr's table,
//! luminance 1) and T ≤ 0 emitting nothing. The (T/1000 K)⁴ factor keeps the shape of
//! Stefan–Boltzmann's law (radiated power ∝ T⁴) with values of order 1 for flames
//! (1000–2000 K give 1–16), so `blackbodyIntensity` is the luminance at 1000 K.
//!
//! The source term of the radiative transfer equation is μa(x)·Le(x) (pbrt-v4's
//! convention): nothing emits where the density (absorption) is 0. The integrator
//! collects Le at absorption events, where the trackers have applied the absorption
//! collision weight μa(λ)/(μ̄·Pa), so throughput × Le is an unbiased estimate of the
//! emission integral. Each grid is looked up with its own world → index transform
//! (grids of one file may have different transforms), and only at absorption events:
//! the free-path loops never touch emission.

use crate::color::usd_blackbody_rgb;
use crate::volume::color_graph::ColorGraph;
use crate::volume::counters::Tally;
use crate::volume::grid::Grid;
use crate::volume::grid::{world_to_index, MediumError};
use glam::{DMat4, DVec3};
use std::sync::Arc;

/// An emission grid with its world → index transform.
/// The grid is shared by the instances of a volume (each places it with its own
/// transform: [`EmissionGrid::placed`]).
pub struct EmissionGrid {
    pub grid: Arc<Grid>,
    world_to_index: DMat4,
}

impl EmissionGrid {
    /// `volume_to_world` is the volume prim's transform; the grid's own index → world
    /// transform is applied under it. `what` names the grid in the error (e.g.
    /// "nimbus:emissionField `flames`").
    pub fn new(
        prim: &str,
        what: &str,
        grid: impl Into<Arc<Grid>>,
        volume_to_world: DMat4,
    ) -> Result<EmissionGrid, MediumError> {
        let grid = grid.into();
        let world_to_index = world_to_index(prim, &format!("{what}: "), volume_to_world, &grid)?;
        Ok(EmissionGrid {
            grid,
            world_to_index,
        })
    }

    /// The same grid (shared, not copied) under another volume transform.
    pub fn placed(&self, prim: &str, volume_to_world: DMat4) -> Result<EmissionGrid, MediumError> {
        EmissionGrid::new(prim, "emission grid", self.grid.clone(), volume_to_world)
    }

    /// The trilinearly reconstructed value at world point `p` (one emission lookup).
    #[inline]
    pub fn sample<C: Tally>(&self, p: DVec3, c: &mut C) -> f64 {
        c.emission_lookup();
        let i = self.world_to_index.transform_point3(p).as_vec3();
        self.grid.sample_trilinear(i.to_array()) as f64
    }
}

/// What the emission model's value E(x) means (`nimbus:emissionKind`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum EmissionKind {
    /// `"radiance"`: E is emitted radiance Le; the source term is μa(x)·Le(x)
    /// (pbrt-v4), so nothing emits where the density is 0.
    #[default]
    Radiance,
    /// `"source"`: E is the source term S(x) itself, radiance per unit length, as
    /// Cycles' Principled Volume means its Emission Strength·Color and blackbody
    /// (independent of density). Collected at absorption events as S/μa(λ, x), which is
    /// unbiased for ∫T·S where μa > 0; nothing is collected where μa = 0 (Cycles emits
    /// only inside its volume mesh, the active voxels above 0.001, so the two differ
    /// where the density is ~0). An empty `nimbus:emissionField` is the constant field
    /// 1 (Cycles' plain Emission Strength input).
    Source,
}

impl EmissionKind {
    /// The schema token's value.
    pub fn token(self) -> &'static str {
        match self {
            EmissionKind::Radiance => "radiance",
            EmissionKind::Source => "source",
        }
    }

    /// Parses the schema token; `None` for anything else.
    pub fn from_token(s: &str) -> Option<EmissionKind> {
        match s {
            "radiance" => Some(EmissionKind::Radiance),
            "source" => Some(EmissionKind::Source),
            _ => None,
        }
    }
}

/// The parameters of [`Emission`] (the schema's `nimbus:*` emission attributes).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EmissionParams {
    /// Kelvin per unit of the temperature grid.
    pub temperature_scale: f64,
    /// Luminance of the blackbody radiance at 1000 K.
    pub blackbody_intensity: f64,
    pub emission_color: [f64; 3],
    pub emission_scale: f64,
    /// What the model's value means: radiance (the default) or a source term.
    pub kind: EmissionKind,
}

impl Default for EmissionParams {
    fn default() -> Self {
        EmissionParams {
            temperature_scale: 1.0,
            blackbody_intensity: 1.0,
            emission_color: [1.0; 3],
            emission_scale: 1.0,
            kind: EmissionKind::Radiance,
        }
    }
}

impl EmissionParams {
    /// Every parameter must be finite and non-negative; the error names the prim and
    /// the attribute.
    pub fn check(&self, prim: &str) -> Result<(), MediumError> {
        let check = |name: &str, v: f64| {
            if v.is_finite() && v >= 0.0 {
                Ok(())
            } else {
                Err(MediumError::Invalid {
                    prim: prim.to_string(),
                    message: format!("{name} must be finite and non-negative, got {v}"),
                })
            }
        };
        check("nimbus:temperatureScale", self.temperature_scale)?;
        check("nimbus:blackbodyIntensity", self.blackbody_intensity)?;
        check("nimbus:emissionScale", self.emission_scale)?;
        for c in self.emission_color {
            check("nimbus:emissionColor", c)?;
        }
        Ok(())
    }
}

/// The emission of a medium: at least one of the two grids, or a source-kind emission
/// whose field is the constant 1.
pub struct Emission {
    pub temperature: Option<EmissionGrid>,
    pub field: Option<EmissionGrid>,
    pub params: EmissionParams,
    /// A colour graph in place of `emissionColor` (the Blender add-on's node trees).
    pub color_graph: Option<ColorGraph>,
    /// emissionScale · emissionColor.
    field_rgb: [f64; 3],
    /// No emission grid and [`EmissionKind::Source`]: the field is the constant 1.
    constant_field: bool,
}

impl Emission {
    /// Checks the parameters ([`EmissionParams::check`]) and builds the emission;
    /// `None` when neither grid is given, unless the kind is
    /// [`EmissionKind::Source`] (whose missing field is the constant 1).
    pub fn new(
        prim: &str,
        temperature: Option<EmissionGrid>,
        field: Option<EmissionGrid>,
        params: EmissionParams,
        color_graph: Option<ColorGraph>,
    ) -> Result<Option<Emission>, MediumError> {
        params.check(prim)?;
        let source = params.kind == EmissionKind::Source;
        if temperature.is_none() && field.is_none() && !source {
            return Ok(None);
        }
        Ok(Some(Emission {
            temperature,
            constant_field: field.is_none() && source,
            field,
            params,
            color_graph,
            field_rgb: params.emission_color.map(|c| c * params.emission_scale),
        }))
    }

    /// The same emission (its grids shared) under another volume transform.
    pub fn placed(&self, prim: &str, volume_to_world: DMat4) -> Result<Emission, MediumError> {
        let place = |g: &Option<EmissionGrid>| {
            g.as_ref()
                .map(|g| g.placed(prim, volume_to_world))
                .transpose()
        };
        Ok(Emission {
            temperature: place(&self.temperature)?,
            field: place(&self.field)?,
            params: self.params,
            // A Volume's graph is in its volume space.
            color_graph: self.color_graph.as_ref().map(|g| g.placed(volume_to_world)),
            field_rgb: self.field_rgb,
            constant_field: self.constant_field,
        })
    }

    /// The emission model's value at world point `p` (one lookup per grid): emitted
    /// radiance Le, or for [`EmissionKind::Source`] the source term S.
    #[inline]
    pub fn radiance<C: Tally>(&self, p: DVec3, c: &mut C) -> [f64; 3] {
        let mut le = [0.0; 3];
        if let Some(t) = &self.temperature {
            let kelvin = self.params.temperature_scale * t.sample(p, c);
            le = blackbody_radiance(kelvin, self.params.blackbody_intensity);
        }
        let field_rgb = || match &self.color_graph {
            Some(g) => g.rgb(p).map(|x| x * self.params.emission_scale),
            None => self.field_rgb,
        };
        if let Some(f) = &self.field {
            let e = f.sample(p, c);
            if e > 0.0 {
                for (l, f) in le.iter_mut().zip(field_rgb()) {
                    *l += f * e;
                }
            }
        } else if self.constant_field {
            for (l, f) in le.iter_mut().zip(field_rgb()) {
                *l += f;
            }
        }
        le
    }
}

/// Blackbody radiance of the emission model: `intensity · (T/1000 K)⁴ · rgb(T)` with
/// rgb(T) UsdLux's colour of temperature T (luminance 1, so the luminance of the result
/// is `intensity · (T/1000 K)⁴`); 0 for T ≤ 0 (and NaN).
pub fn blackbody_radiance(kelvin: f64, intensity: f64) -> [f64; 3] {
    if kelvin.is_nan() || kelvin <= 0.0 || kelvin.is_infinite() {
        return [0.0; 3];
    }
    let s = intensity * (kelvin / 1000.0).powi(4);
    usd_blackbody_rgb(kelvin).map(|c| c * s)
}
