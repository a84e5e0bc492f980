//! A colour graph placed in the world: a compiled shader graph
//! ([`Program::eval_rgb`]) and the transform from world points to its position space.
//! The emission colour and the albedo multiplier read one (the Blender add-on's node
//! trees); neither takes part in a majorant, so no range analysis is needed here.

use crate::shader::graph::Program;
use glam::{DMat4, DVec3};

/// A compiled colour graph and where its positions are.
#[derive(Clone, Debug)]
pub struct ColorGraph {
    pub program: Program,
    /// World → the graph's position space (the prim's object space).
    pub world_to_shading: DMat4,
}

impl ColorGraph {
    /// The graph's colour at world point `p`, negative components made 0.
    #[inline]
    pub fn rgb(&self, p: DVec3) -> [f64; 3] {
        let q = self
            .world_to_shading
            .transform_point3(p)
            .as_vec3()
            .to_array();
        self.program.eval_rgb(q, 0.0).map(|c| f64::from(c.max(0.0)))
    }

    /// The same graph under a Volume's new transform (its positions are in the
    /// Volume's object space).
    pub fn placed(&self, volume_to_world: DMat4) -> ColorGraph {
        ColorGraph {
            program: self.program.clone(),
            world_to_shading: volume_to_world.inverse(),
        }
    }
}
