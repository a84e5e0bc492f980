//! A medium's density through a shader graph (issue 47): d(x) = max(0, graph(x, grid(x))),
//! the graph reading the position in its own space and the medium's grid value as its
//! attribute. A fog box's grid is all ones (the graph alone is the density); a volume's
//! is its density field (the graph shapes it).
//!
//! The majorants come from the graph's range analysis: each cell's bound is the
//! program's interval over the cell's box, with the grid's range over the cell as the
//! attribute ([`DensityShader::cell_bounds`]), so the trackers stay exact.

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
        if !v.is_bounded() {
            return (0.0, f32::INFINITY);
        }
        (v.lo.max(0.0), v.hi.max(0.0))
    }
}
