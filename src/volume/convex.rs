//! A convex fog box's boundary: the intersection of its faces' half-spaces.
//!
//! Most fog boxes are convex: Blender's default cube, a UsdGeomCube, a low-poly
//! sphere. A ray meets such a surface at most twice, where it enters the last of the
//! face planes it enters and where it leaves the first it leaves (Cyrus–Beck clipping),
//! so the crossings take one dot product per distinct face plane instead of a BVH
//! traversal over every triangle (a cube: 6 planes against 12 triangles behind a
//! tree). The answers are those of the triangles in exact arithmetic; in f64 the two
//! differ in the last bits of `t`, far below the f32 intervals the walks use.
//!
//! Only a closed, consistently outward-oriented mesh (the orientation rule) with every
//! vertex inside every face plane qualifies, and only with few planes, where it beats
//! the tree; [`ConvexHull::from_triangles`] says `None` otherwise and the caller keeps
//! the BVH.

use crate::volume::boundary::{Boundary, Crossing, InsideRule};
use glam::DVec3;

/// Face planes beyond which the BVH is used instead (the clip costs one dot product per
/// plane; the tree about log₂ of the triangles in box tests).
pub const MAX_PLANES: usize = 32;

/// Two face normals this close (in their components, unit vectors) with offsets this
/// close (relative to the mesh's size) are one plane.
const SAME_PLANE: f64 = 1e-9;

/// A vertex may lie this far outside a face plane (relative to the mesh's size) and
/// the mesh still count as convex: rounding of the input's coordinates, not a dent.
const CONVEX_SLACK: f64 = 1e-9;

/// The half-space n·x ≤ d, n a unit outward normal.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Plane {
    n: DVec3,
    d: f64,
}

/// A convex polyhedron as its face planes.
#[derive(Clone, Debug)]
pub struct ConvexHull {
    planes: Vec<Plane>,
}

impl ConvexHull {
    /// The hull of a closed, consistently outward-oriented triangle mesh, if the mesh is
    /// convex and has at most [`MAX_PLANES`] distinct face planes; `None` otherwise
    /// (and for a mesh with no triangle of positive area).
    pub fn from_triangles(points: &[[f64; 3]], triangles: &[[u32; 3]]) -> Option<ConvexHull> {
        let point = |i: u32| points.get(i as usize).map(|p| DVec3::from_array(*p));
        let size = points
            .iter()
            .map(|p| DVec3::from_array(*p).abs().max_element())
            .fold(0.0, f64::max);
        if !(size.is_finite() && size > 0.0) {
            return None;
        }
        let mut planes: Vec<Plane> = Vec::new();
        for &[a, b, c] in triangles {
            let (a, b, c) = (point(a)?, point(b)?, point(c)?);
            let normal = (b - a).cross(c - a);
            if !(normal.length_squared() > 0.0) {
                continue;
            }
            let n = normal.normalize();
            let d = n.dot(a);
            let same = |p: &Plane| {
                (p.n - n).abs().max_element() < SAME_PLANE && (p.d - d).abs() < SAME_PLANE * size
            };
            if !planes.iter().any(same) {
                if planes.len() == MAX_PLANES {
                    return None;
                }
                planes.push(Plane { n, d });
            }
        }
        if planes.len() < 4 {
            // No closed solid has fewer than four face planes.
            return None;
        }
        let convex = points.iter().all(|p| {
            let p = DVec3::from_array(*p);
            planes
                .iter()
                .all(|pl| pl.n.dot(p) - pl.d <= CONVEX_SLACK * size)
        });
        convex.then_some(ConvexHull { planes })
    }

    /// Face planes kept.
    pub fn planes(&self) -> usize {
        self.planes.len()
    }

    /// Where `origin + t·dir` enters and leaves the hull, `None` when it misses it
    /// (or only grazes it: in and out at one `t`).
    #[inline]
    fn clip(&self, origin: DVec3, dir: DVec3) -> Option<(f64, f64)> {
        let (mut enter, mut leave) = (f64::NEG_INFINITY, f64::INFINITY);
        for p in &self.planes {
            let along = p.n.dot(dir);
            let inside_by = p.d - p.n.dot(origin);
            if along == 0.0 {
                // Parallel to the plane: wholly outside it, or no bound from it.
                if inside_by < 0.0 {
                    return None;
                }
                continue;
            }
            let t = inside_by / along;
            if along < 0.0 {
                enter = enter.max(t);
            } else {
                leave = leave.min(t);
            }
        }
        (enter < leave).then_some((enter, leave))
    }
}

impl Boundary for ConvexHull {
    fn crossings(
        &self,
        origin: DVec3,
        dir: DVec3,
        tmin: f64,
        out: &mut [Crossing],
    ) -> (usize, u64) {
        let Some((enter, leave)) = self.clip(origin, dir) else {
            return (0, 0);
        };
        let mut n = 0;
        for c in [
            Crossing {
                t: enter,
                entering: true,
            },
            Crossing {
                t: leave,
                entering: false,
            },
        ] {
            if c.t > tmin && c.t.is_finite() && n < out.len() {
                out[n] = c;
                n += 1;
            }
        }
        (n, n as u64)
    }

    fn rule(&self) -> InsideRule {
        InsideRule::Orientation
    }

    fn is_convex(&self) -> bool {
        true
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// The cube [-1, 1]³ as 12 outward triangles.
    pub(crate) fn cube() -> (Vec<[f64; 3]>, Vec<[u32; 3]>) {
        let points: Vec<[f64; 3]> = (0..8)
            .map(|i| [(i & 1) as f64, ((i >> 1) & 1) as f64, ((i >> 2) & 1) as f64])
            .map(|p| p.map(|c| 2.0 * c - 1.0))
            .collect();
        // Faces as quads (outward by the right-hand rule), two triangles each.
        let quads = [
            [0, 2, 3, 1],
            [4, 5, 7, 6],
            [0, 1, 5, 4],
            [2, 6, 7, 3],
            [0, 4, 6, 2],
            [1, 3, 7, 5],
        ];
        let triangles = quads
            .iter()
            .flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]])
            .collect();
        (points, triangles)
    }

    #[test]
    fn a_cube_is_six_planes_and_clips_rays() {
        let (points, triangles) = cube();
        let hull = ConvexHull::from_triangles(&points, &triangles).expect("convex");
        assert_eq!(hull.planes(), 6);
        let mut out = [Crossing::default(); 4];
        // From outside along x through the middle: in at 1, out at 3.
        let (n, total) = hull.crossings(DVec3::new(-2.0, 0.0, 0.0), DVec3::X, 0.0, &mut out);
        assert_eq!((n, total), (2, 2));
        assert_eq!((out[0].t, out[0].entering), (1.0, true));
        assert_eq!((out[1].t, out[1].entering), (3.0, false));
        // From inside: only the way out.
        let (n, _) = hull.crossings(DVec3::ZERO, DVec3::Y, 0.0, &mut out);
        assert_eq!(n, 1);
        assert_eq!((out[0].t, out[0].entering), (1.0, false));
        // Parallel to a face, outside it: a miss.
        let (n, _) = hull.crossings(DVec3::new(0.0, 1.5, 0.0), DVec3::X, -10.0, &mut out);
        assert_eq!(n, 0);
    }

    #[test]
    fn a_dented_mesh_is_not_convex() {
        let (mut points, triangles) = cube();
        // Push the vertex (1, 1, 1) inwards: the faces around it fold in.
        points[7] = [0.5, 0.5, 0.5];
        assert!(ConvexHull::from_triangles(&points, &triangles).is_none());
    }
}
