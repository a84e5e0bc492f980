//! A medium's density through a shader graph (issue 47): d(x) = max(0, graph(x, grid(x))),
//! the graph reading the position in its own space and the medium's grid value as its
//! attribute. A fog box's grid is all ones (the graph alone is the density); a volume's
//! is its density field (the graph shapes it).
//!
//! The majorants come from the graph's range analysis: each cell's bound is the
//! program's interval over the cell's box, with the grid's range over the cell as the
//! attribute ([`DensityShader::cell_bounds`]), so the trackers stay exact. Where the
//! analysis finds no usable bound (a division by a range holding 0, a negative power
//! of a range reaching 0, an Exponent past f32's range), the cell's majorant is an
//! estimate from lookups instead ([`DensityShader::cell_estimate`]) and `auto` tracks
//! with signed weights, which stay unbiased under a majorant that does not bound.

use crate::shader::graph::Program;
use crate::shader::interval::Interval;
use glam::{Affine3A, DMat4, DVec3, Vec3};

/// A compiled density graph placed in a medium's index space.
#[derive(Clone, Debug)]
pub struct DensityShader {
    pub program: Program,
    /// Index space → the graph's position space (object space).
    index_to_shading: Affine3A,
    index_to_shading_f64: DMat4,
    /// The shader (node or material) it was read from, for messages and `nimbus info`.
    pub source: String,
}

impl DensityShader {
    pub fn new(program: Program, index_to_shading: DMat4, source: &str) -> DensityShader {
        DensityShader {
            program,
            index_to_shading: Affine3A::from_mat4(index_to_shading.as_mat4()),
            index_to_shading_f64: index_to_shading,
            source: source.to_string(),
        }
    }

    /// The density at the index-space point `p` where the grid reads `grid`. Negative
    /// values are 0, as in Cycles' volume shaders.
    #[inline(always)]
    pub fn density(&self, p: Vec3, grid: f32) -> f32 {
        let q = self.index_to_shading.transform_point3(p);
        self.program.eval(q.to_array(), grid).max(0.0)
    }

    /// Bounds of the density over the closed index box `[lo, hi]` where the grid lies
    /// in `grid` (its min and max there): `(min, max)`, `max` infinite where the graph
    /// cannot be bounded.
    pub fn cell_bounds(&self, lo: DVec3, hi: DVec3, grid: (f32, f32)) -> (f32, f32) {
        let mut b = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
        for c in crate::volume::grid::box_corners(lo, hi) {
            let q = self.index_to_shading_f64.transform_point3(c);
            b = (b.0.min(q), b.1.max(q));
        }
        // Rounding the box to f32 (and the f32 transform a lookup uses) moves points by
        // a few ulps of the coordinates: the box is widened by far more.
        let pad = DVec3::splat(1e-5 * b.0.abs().max(b.1.abs()).max_element().max(1.0));
        let b = (b.0 - pad, b.1 + pad);
        let attribute = Interval::new(grid.0, grid.1);
        let v = self.program.bounds(
            b.0.as_vec3().to_array(),
            b.1.as_vec3().to_array(),
            attribute,
        );
        // Only the top matters for a majorant: a graph capped by a Minimum is bounded
        // even where what it caps is not, and below 0 the density is 0.
        if !v.hi.is_finite() {
            return (0.0, f32::INFINITY);
        }
        let lo = if v.lo.is_finite() { v.lo.max(0.0) } else { 0.0 };
        (lo, v.hi.max(0.0))
    }

    /// A majorant for the index box `[lo, hi]` where [`cell_bounds`](Self::cell_bounds)
    /// gives none that can be used: [`ESTIMATE_MARGIN`] times the largest density at
    /// the box's 8 corners and the centres of its [`ESTIMATE_POINTS`]³ sub-boxes, the
    /// grid read by `grid` at each. Not a bound: near a singularity the density
    /// exceeds it, and only weighted trackers stay unbiased there.
    pub fn cell_estimate(&self, lo: Vec3, hi: Vec3, grid: &dyn Fn(Vec3) -> f32) -> f32 {
        let n = ESTIMATE_POINTS;
        let mut largest = 0f32;
        let mut look = |p: Vec3| {
            let d = self.density(p, grid(p));
            // A NaN (0·∞ inside the graph) says nothing; an ∞ makes the estimate ∞,
            // which the medium refuses.
            if !d.is_nan() {
                largest = largest.max(d);
            }
        };
        for c in crate::volume::grid::box_corners(lo.as_dvec3(), hi.as_dvec3()) {
            look(c.as_vec3());
        }
        for i in 0..n * n * n {
            let f = Vec3::new((i % n) as f32, (i / n % n) as f32, (i / (n * n)) as f32);
            look(lo + (hi - lo) * (f + 0.5) / n as f32);
        }
        ESTIMATE_MARGIN * largest
    }
}

/// The majorant cell's (min, max) from the range analysis' `bounds`, or where they are
/// no use (not finite, or finite but beyond [`TRUSTED_BOUND`] and [`LOOSE_BOUND`] times
/// the estimate) from `estimate` (called only then); and whether it is an estimate.
pub fn usable_bounds(bounds: (f32, f32), estimate: impl FnOnce() -> f32) -> ((f32, f32), bool) {
    let (min, max) = bounds;
    if max <= TRUSTED_BOUND {
        return (bounds, false);
    }
    let guess = estimate();
    if max.is_finite() && max <= LOOSE_BOUND * guess {
        return (bounds, false);
    }
    ((min.min(guess), guess), true)
}

/// Sub-boxes per axis where [`DensityShader::cell_estimate`] looks the density up.
pub const ESTIMATE_POINTS: usize = 5;

/// The estimate's multiple of the largest density seen: room for peaks between the
/// points, so that in smooth parts of the cell the estimate still bounds.
pub const ESTIMATE_MARGIN: f32 = 2.0;

/// A finite bound above this many times the cell's estimate is not used: tracking
/// under it would cost that many lookups per unit of the density's own optical depth
/// (the cells beside a singularity, where the bound is finite but huge).
pub const LOOSE_BOUND: f32 = 1000.0;

/// Bounds at or below this density are used without looking at an estimate (which
/// costs lookups at load): every scene whose graph is not singular.
pub const TRUSTED_BOUND: f32 = 1.0e6;

#[cfg(test)]
mod tests {
    use super::*;

    /// Bounds are kept up to the trusted size without an estimate, and beyond it while
    /// within [`LOOSE_BOUND`] of the estimate; an infinite or a far looser bound gives
    /// way to the estimate, with a minimum no higher than it.
    #[test]
    fn an_unusable_bound_gives_way_to_the_estimate() {
        let never = || -> f32 { panic!("no estimate needed") };
        assert_eq!(usable_bounds((0.5, 3.0), never), ((0.5, 3.0), false));
        assert_eq!(
            usable_bounds((0.0, TRUSTED_BOUND), never),
            ((0.0, TRUSTED_BOUND), false)
        );
        assert_eq!(usable_bounds((1.0, 2.0e6), || 1.0e4), ((1.0, 2.0e6), false));
        assert_eq!(usable_bounds((1.0, 2.0e9), || 1.0e4), ((1.0, 1.0e4), true));
        assert_eq!(
            usable_bounds((0.0, f32::INFINITY), || 7.0),
            ((0.0, 7.0), true)
        );
        assert_eq!(
            usable_bounds((9.0, f32::INFINITY), || 7.0),
            ((7.0, 7.0), true)
        );
    }
}
