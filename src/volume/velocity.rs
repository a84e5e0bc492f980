//! Velocity motion blur: a volume's fields advected by a velocity grid over the shutter
//! (issue 45). At a sample whose time is Δ seconds from the frame, every field of the
//! medium is looked up at
//!
//! x' = x − v(x)·Δ,
//!
//! v the velocity grid's trilinear value at x (Eulerian, first order: the field is
//! moved along the flow without re-simulation, as Cycles, Karma and Arnold blur a
//! `vel` grid). Δ = τ · scale, τ the frame-relative time in time codes and `scale` the
//! seconds per time code times the blur scales ([`VelocityGrid::seconds_per_time_code`]).
//!
//! Majorants stay bounds: x' lies within max|v|·max|Δ| of x along each axis, so a
//! majorant cell's bound over its voxels widened by that distance (and the region
//! widened as much) bounds the advected density at every time of the shutter
//! ([`crate::volume::majorant::MajorantTree::build_widened`]).

use crate::volume::grid::{Grid, GridError, RawGrid};
use glam::{DMat4, Mat3, Mat4, Vec3};
use std::sync::Arc;

/// A velocity grid (a Vec3s grid, in the volume's local units per second) placed in a
/// medium's density index space.
pub struct VelocityGrid {
    /// The field it comes from (the `field:<name>` relationship).
    pub field: String,
    channels: Arc<[Grid; 3]>,
    /// Density index → velocity index.
    to_velocity_index: Mat4,
    /// A local velocity → density index units (the density grid's index ← volume map's
    /// linear part).
    to_density_index: Mat3,
    /// Seconds of advection per time code from the frame: 1 / timeCodesPerSecond
    /// times the blur scales.
    pub seconds_per_time_code: f32,
    /// The largest |component| of any stored velocity, in density index units per
    /// second, per axis (the majorants' widening).
    pub max_index_speed: [f32; 3],
    /// Stored component values that were NaN or infinite (replaced by 0).
    pub sanitized: u64,
}

impl VelocityGrid {
    /// The velocity grid of `raw` (x, y, z components, sharing the first one's
    /// transform: index → volume), for the density grid whose index → volume map is
    /// `density_index_to_volume`.
    pub fn new(
        field: &str,
        raw: [RawGrid; 3],
        density_index_to_volume: DMat4,
        seconds_per_time_code: f64,
    ) -> Result<VelocityGrid, GridError> {
        let velocity_index_to_volume = raw[0].index_to_world;
        let mut sanitized = 0;
        let mut max_local = [0f32; 3];
        let mut channels = Vec::with_capacity(3);
        for (a, r) in raw.iter().enumerate() {
            let g = Grid::from_raw_signed(r)?;
            sanitized += g.sanitized_voxels;
            max_local[a] = g.max_abs();
            channels.push(g);
        }
        let Ok(channels) = <[Grid; 3]>::try_from(channels) else {
            unreachable!("three channels pushed")
        };
        let volume_to_density_index = density_index_to_volume.inverse();
        let to_density_index = Mat3::from_mat4(volume_to_density_index.as_mat4());
        // |(M v)_i| ≤ Σ_j |M_ij|·max|v_j|.
        let m = to_density_index.transpose().to_cols_array_2d();
        let max_index_speed = [0, 1, 2].map(|i| (0..3).map(|j| m[i][j].abs() * max_local[j]).sum());
        Ok(VelocityGrid {
            field: field.to_string(),
            channels: Arc::new(channels),
            to_velocity_index: (velocity_index_to_volume.inverse() * density_index_to_volume)
                .as_mat4(),
            to_density_index,
            seconds_per_time_code: seconds_per_time_code as f32,
            max_index_speed,
            sanitized,
        })
    }

    /// The same grid for another placement of the density grid (an instance: the
    /// index → volume maps do not change, so nothing does).
    pub fn shared(&self) -> VelocityGrid {
        VelocityGrid {
            field: self.field.clone(),
            channels: self.channels.clone(),
            to_velocity_index: self.to_velocity_index,
            to_density_index: self.to_density_index,
            seconds_per_time_code: self.seconds_per_time_code,
            max_index_speed: self.max_index_speed,
            sanitized: self.sanitized,
        }
    }

    /// The velocity at density index point `p`, in density index units per second
    /// (one lookup of the vector grid; the caller counts it as one density lookup).
    #[inline(always)]
    pub fn index_velocity(&self, p: Vec3) -> Vec3 {
        let q = self.to_velocity_index.transform_point3(p).to_array();
        let [x, y, z] = &*self.channels;
        let v = Vec3::new(
            x.sample_trilinear(q),
            y.sample_trilinear(q),
            z.sample_trilinear(q),
        );
        self.to_density_index * v
    }

    /// The voxels the majorants widen by for advection of up to `seconds` (either
    /// side of the frame): the largest displacement per axis, rounded up, plus one for
    /// rounding.
    pub fn widening(&self, seconds: f64) -> [i32; 3] {
        self.max_index_speed.map(|s| {
            let d = (s as f64 * seconds.abs()).ceil() + 1.0;
            d.min(1e6) as i32
        })
    }
}
