//! Ray queries against the holdout geometry ([`HoldoutMesh`]es): nearest hit and any
//! hit, over a BVH of world-space triangles. Holdouts are black, matte and opaque from
//! both sides, so a query only needs a distance.
//!
//! The tree is built by `obvhs` (PLOC with reinsertion, in parallel on rayon) over the
//! triangles' boxes, then flattened here into depth-first order with escape links (the
//! index just past each subtree). Queries visit the nearer child first and keep the
//! other on a fixed array on the call stack; a tree deeper than that array (only
//! pathological inputs) is walked without a stack instead, through the escape links in
//! fixed child order. Either way a query allocates nothing and cannot overflow.
//!
//! Precision: triangles are stored and intersected in f64 (Möller–Trumbore, both
//! sides, edges inclusive so neighbouring triangles leave no cracks). Node boxes are f32,
//! rounded outwards and padded by [`BOX_PADDING`] of the box's largest coordinate, so
//! a box can never cull a triangle the f64 test would hit: the answers are exactly
//! those of a brute-force loop over every triangle.
//!
//! Self-intersection: there is no epsilon. A hit counts when tmin < t < tmax, strictly.
//! Rays start inside the volume, not on holdout surfaces, so tmin = 0 is right; a caller
//! continuing a ray from a holdout surface (none does: holdouts end paths) would pass a
//! tmin of its own.

use crate::scene::HoldoutMesh;
use crate::volume::boundary::{keep_nearest, Boundary, Crossing, InsideRule};
use glam::DVec3;
use std::time::Instant;

/// Box padding, relative to the box's largest coordinate magnitude: far above f64
/// rounding (1e-16) so the f64 triangle test never reports a hit outside its node's box,
/// far below anything visible.
pub const BOX_PADDING: f64 = 1e-6;

/// A direction component smaller than this in magnitude is replaced by it (with its
/// sign) in the box test only, so 1/d stays finite and (box − origin)·(1/d) is never
/// 0·∞ = NaN. The boxes are padded far beyond the position change this makes
/// (t·1e-300).
const TINY_DIRECTION: f64 = 1e-300;

/// The holdout geometry of a scene, ready for ray queries. `Sync`: queries take `&self`.
pub struct Holdouts {
    /// Depth-first order; `nodes[0]` is the root. Empty when there is no geometry.
    nodes: Vec<Node>,
    /// Triangles in leaf order (a leaf's are contiguous).
    triangles: Vec<Triangle>,
    /// Whether the tree is shallow enough for the ordered traversal's fixed stack.
    ordered: bool,
    /// How crossings become inside intervals when the geometry bounds a fog medium.
    rule: InsideRule,
    stats: HoldoutStats,
}

/// Entries of the ordered traversal's stack (on the call stack: 1.5 KB). Trees deeper
/// than this (pathological inputs) use the stackless escape-link traversal instead.
const STACK: usize = 96;

/// What the holdouts hold and cost (`nimbus info`, stats).
#[derive(Clone, Copy, Debug, Default, serde::Serialize)]
pub struct HoldoutStats {
    /// Meshes (gprims) given to [`Holdouts::build`].
    pub meshes: usize,
    /// Triangles in the BVH.
    pub triangles: usize,
    /// Triangles left out: those the meshes counted, plus any [`Holdouts::build`] found
    /// degenerate, non-finite or indexing no point.
    pub degenerate_triangles: usize,
    /// Wall time of the BVH build (boxes, tree, flattening).
    pub build_seconds: f64,
    /// Heap bytes of the nodes and triangles.
    pub bytes: usize,
}

/// A BVH node. Inner: `count == 0`, its children are the next nodes in depth-first
/// order. Leaf: triangles `first..first + count`. Either way `escape` is the index of
/// the first node after its subtree (`nodes.len()` at the end).
#[derive(Clone, Copy, Debug)]
struct Node {
    min: [f32; 3],
    escape: u32,
    max: [f32; 3],
    first: u32,
    count: u32,
}

/// A triangle as Möller–Trumbore wants it: a vertex and the two edges from it.
#[derive(Clone, Copy, Debug)]
struct Triangle {
    v0: DVec3,
    e1: DVec3,
    e2: DVec3,
}

impl Triangle {
    /// Distance t of the hit of origin + t·dir, tmin < t < tmax, if any. Both sides;
    /// barycentric bounds inclusive. A ray in the triangle's plane (det = 0) misses it.
    #[inline(always)]
    fn hit(&self, origin: DVec3, dir: DVec3, tmin: f64, tmax: f64) -> Option<f64> {
        let p = dir.cross(self.e2);
        let det = self.e1.dot(p);
        if det == 0.0 || !det.is_finite() {
            return None;
        }
        let inv = 1.0 / det;
        let s = origin - self.v0;
        let u = s.dot(p) * inv;
        if !(0.0..=1.0).contains(&u) {
            return None;
        }
        let q = s.cross(self.e1);
        let v = dir.dot(q) * inv;
        if v < 0.0 || u + v > 1.0 {
            return None;
        }
        let t = self.e2.dot(q) * inv;
        (t > tmin && t < tmax).then_some(t)
    }
}

/// A ray prepared for box tests.
struct BoxRay {
    origin: DVec3,
    inv_dir: DVec3,
}

impl BoxRay {
    fn new(origin: DVec3, dir: DVec3) -> BoxRay {
        let safe = |d: f64| {
            if d.abs() < TINY_DIRECTION {
                TINY_DIRECTION.copysign(d)
            } else {
                d
            }
        };
        BoxRay {
            origin,
            inv_dir: DVec3::new(1.0 / safe(dir.x), 1.0 / safe(dir.y), 1.0 / safe(dir.z)),
        }
    }

    /// Where the ray enters the node's box, if it meets it for some t in [tmin, tmax]
    /// (slab test).
    #[inline(always)]
    fn entry(&self, node: &Node, tmin: f64, tmax: f64) -> Option<f64> {
        let mut near = tmin;
        let mut far = tmax;
        for a in 0..3 {
            let t0 = (f64::from(node.min[a]) - self.origin[a]) * self.inv_dir[a];
            let t1 = (f64::from(node.max[a]) - self.origin[a]) * self.inv_dir[a];
            let (lo, hi) = if t0 < t1 { (t0, t1) } else { (t1, t0) };
            near = near.max(lo);
            far = far.min(hi);
        }
        (near <= far).then_some(near)
    }
}

impl Holdouts {
    /// No geometry: every query returns at once.
    pub fn empty() -> Holdouts {
        Holdouts {
            nodes: Vec::new(),
            triangles: Vec::new(),
            ordered: false,
            rule: InsideRule::Orientation,
            stats: HoldoutStats::default(),
        }
    }

    /// The BVH over every triangle of `meshes` (built in parallel). Triangles that are
    /// degenerate, non-finite or index no point are left out and counted; never panics.
    pub fn build(meshes: &[HoldoutMesh]) -> Holdouts {
        let start = Instant::now();
        let mut triangles = Vec::new();
        let mut degenerate = 0;
        for mesh in meshes {
            degenerate += mesh.degenerate_triangles;
            for &[a, b, c] in &mesh.triangles {
                let point = |i: u32| mesh.points.get(i as usize).map(|p| DVec3::from_array(*p));
                let (Some(a), Some(b), Some(c)) = (point(a), point(b), point(c)) else {
                    degenerate += 1;
                    continue;
                };
                let (e1, e2) = (b - a, c - a);
                let area2 = e1.cross(e2).length_squared();
                if !(a.is_finite() && b.is_finite() && c.is_finite() && area2 > 0.0)
                    || !area2.is_finite()
                {
                    degenerate += 1;
                    continue;
                }
                triangles.push(Triangle { v0: a, e1, e2 });
            }
        }
        let mut holdouts = Holdouts::empty();
        if !triangles.is_empty() {
            let (nodes, ordered, depth) = build_tree(&triangles);
            holdouts.nodes = nodes;
            holdouts.triangles = ordered;
            holdouts.ordered = depth < STACK;
        }
        holdouts.stats = HoldoutStats {
            meshes: meshes.len(),
            triangles: holdouts.triangles.len(),
            degenerate_triangles: degenerate,
            build_seconds: start.elapsed().as_secs_f64(),
            bytes: holdouts.nodes.capacity() * std::mem::size_of::<Node>()
                + holdouts.triangles.capacity() * std::mem::size_of::<Triangle>(),
        };
        holdouts
    }

    /// The geometry as a fog medium's boundary read with `rule`.
    pub fn with_rule(mut self, rule: InsideRule) -> Holdouts {
        self.rule = rule;
        self
    }

    pub fn is_empty(&self) -> bool {
        self.nodes.is_empty()
    }

    pub fn stats(&self) -> HoldoutStats {
        self.stats
    }

    /// Distance t in (tmin, tmax) of the nearest hit of the world ray origin + t·dir
    /// (dir unit length), or None.
    pub fn hit(&self, origin: DVec3, dir: DVec3, tmin: f64, tmax: f64) -> Option<f64> {
        let mut nearest = None;
        let mut tmax = tmax;
        self.traverse(origin, dir, tmin, &mut tmax, |t, _, tmax| {
            nearest = Some(t);
            *tmax = t;
            false
        });
        nearest
    }

    /// Whether anything blocks origin + t·dir for t in (tmin, tmax) (any-hit, stops at
    /// the first).
    pub fn occluded(&self, origin: DVec3, dir: DVec3, tmin: f64, tmax: f64) -> bool {
        let mut blocked = false;
        let mut tmax = tmax;
        self.traverse(origin, dir, tmin, &mut tmax, |_, _, _| {
            blocked = true;
            true
        });
        blocked
    }

    /// Walks the nodes the ray meets within (tmin, *tmax); on each triangle hit calls
    /// `on_hit(t, triangle, tmax)`, which may shrink *tmax (nodes beyond it are then
    /// skipped), stopping when it returns true.
    #[inline(always)]
    fn traverse(
        &self,
        origin: DVec3,
        dir: DVec3,
        tmin: f64,
        tmax: &mut f64,
        mut on_hit: impl FnMut(f64, &Triangle, &mut f64) -> bool,
    ) {
        // NaN bounds or rays would compare false everywhere below; refuse them up front.
        if self.nodes.is_empty() || !(tmin < *tmax) || !origin.is_finite() || !dir.is_finite() {
            return;
        }
        let ray = BoxRay::new(origin, dir);
        // Tests a leaf's triangles; true = stop.
        let mut leaf = |node: &Node, tmax: &mut f64| {
            let first = node.first as usize;
            for tri in &self.triangles[first..first + node.count as usize] {
                if let Some(t) = tri.hit(origin, dir, tmin, *tmax) {
                    if on_hit(t, tri, tmax) {
                        return true;
                    }
                }
            }
            false
        };
        if !self.ordered {
            // Escape links: no stack, any depth.
            let mut i = 0;
            while let Some(node) = self.nodes.get(i) {
                if ray.entry(node, tmin, *tmax).is_none() {
                    i = node.escape as usize;
                    continue;
                }
                if leaf(node, tmax) {
                    return;
                }
                i += 1;
            }
            return;
        }
        // Nearer child first, the other on a fixed stack with its entry distance (skipped
        // on pop once a hit is nearer). At most one entry per level: `ordered` says the
        // tree is shallower than the stack.
        let mut stack = [(0u32, 0f64); STACK];
        let mut depth = 0;
        let mut i = 0;
        if ray.entry(&self.nodes[0], tmin, *tmax).is_none() {
            return;
        }
        loop {
            let node = &self.nodes[i];
            let mut next = None;
            if node.count > 0 {
                if leaf(node, tmax) {
                    return;
                }
            } else {
                // Depth-first order: the first child follows its parent, the second
                // follows the first child's subtree.
                let a = i + 1;
                let b = self.nodes[a].escape as usize;
                let ta = ray.entry(&self.nodes[a], tmin, *tmax);
                let tb = ray.entry(&self.nodes[b], tmin, *tmax);
                next = match (ta, tb) {
                    (Some(ta), Some(tb)) => {
                        let (near, far, t_far) = if ta <= tb { (a, b, tb) } else { (b, a, ta) };
                        stack[depth] = (far as u32, t_far);
                        depth += 1;
                        Some(near)
                    }
                    (Some(_), None) => Some(a),
                    (None, Some(_)) => Some(b),
                    (None, None) => None,
                };
            }
            i = match next {
                Some(n) => n,
                None => loop {
                    if depth == 0 {
                        return;
                    }
                    depth -= 1;
                    let (n, t_entry) = stack[depth];
                    if t_entry <= *tmax {
                        break n as usize;
                    }
                },
            };
        }
    }
}

/// A fog box's surface: its BVH answers the crossings of a ray (every hit, with the
/// side it is crossed from: the triangles' winding gives the outward normal
/// (e1 × e2), which the reader made consistent and outward, or the parity rule for a
/// mesh it could not).
impl Boundary for Holdouts {
    fn crossings(
        &self,
        origin: DVec3,
        dir: DVec3,
        tmin: f64,
        out: &mut [Crossing],
    ) -> (usize, u64) {
        let (mut n, mut total) = (0, 0u64);
        let mut tmax = f64::INFINITY;
        // The parity rule counts every crossing ahead, so only the orientation rule may
        // cull beyond the batch's farthest kept crossing.
        let cull = self.rule == InsideRule::Orientation;
        self.traverse(origin, dir, tmin, &mut tmax, |t, tri, tmax| {
            total += 1;
            let entering = dir.dot(tri.e1.cross(tri.e2)) < 0.0;
            let reach = keep_nearest(out, &mut n, Crossing { t, entering });
            if cull {
                // Strictly beyond the farthest kept one: a crossing at the same t is
                // one of a shared edge's duplicates, which changes no state.
                *tmax = reach.next_up();
            }
            false
        });
        (n, total)
    }

    fn rule(&self) -> InsideRule {
        self.rule
    }
}

/// The box of `tri`, outward-rounded to f32 and padded (see [`BOX_PADDING`]).
fn padded_box(tri: &Triangle) -> ([f32; 3], [f32; 3]) {
    let (a, b, c) = (tri.v0, tri.v0 + tri.e1, tri.v0 + tri.e2);
    padded(a.min(b).min(c), a.max(b).max(c))
}

fn padded(lo: DVec3, hi: DVec3) -> ([f32; 3], [f32; 3]) {
    let pad = BOX_PADDING * lo.abs().max(hi.abs()).max_element();
    let (lo, hi) = (lo - DVec3::splat(pad), hi + DVec3::splat(pad));
    (lo.to_array().map(round_down), hi.to_array().map(round_up))
}

fn round_down(x: f64) -> f32 {
    let f = x as f32;
    if f64::from(f) > x {
        f.next_down()
    } else {
        f
    }
}

fn round_up(x: f64) -> f32 {
    let f = x as f32;
    if f64::from(f) < x {
        f.next_up()
    } else {
        f
    }
}

/// Builds obvhs' BVH2 over the triangles' boxes and flattens it into depth-first nodes
/// with escape links; returns the nodes, the triangles in leaf order and the tree's
/// depth (edges from the root to the deepest node).
fn build_tree(triangles: &[Triangle]) -> (Vec<Node>, Vec<Triangle>, usize) {
    let boxes: Vec<obvhs::aabb::Aabb> = triangles
        .iter()
        .map(|t| {
            let (min, max) = padded_box(t);
            obvhs::aabb::Aabb::new(min.into(), max.into())
        })
        .collect();
    let bvh = obvhs::bvh2::builder::build_bvh2(
        &boxes,
        obvhs::BvhBuildParams::medium_build(),
        &mut std::time::Duration::default(),
    );

    // Pre-order walk (an explicit stack: the tree's depth is unbounded).
    let mut order = Vec::with_capacity(bvh.nodes.len());
    let mut pending = vec![(0u32, 0usize)];
    let mut depth = 0;
    while let Some((n, d)) = pending.pop() {
        order.push(n);
        depth = depth.max(d);
        let node = &bvh.nodes[n as usize];
        if !node.is_leaf() {
            // Second child pushed first so the first is visited first.
            pending.push((node.first_index + 1, d + 1));
            pending.push((node.first_index, d + 1));
        }
    }
    // Subtree sizes, children before parents (reverse pre-order).
    let mut size = vec![1u32; bvh.nodes.len()];
    for &n in order.iter().rev() {
        let node = &bvh.nodes[n as usize];
        if !node.is_leaf() {
            size[n as usize] =
                1 + size[node.first_index as usize] + size[node.first_index as usize + 1];
        }
    }
    let mut nodes = Vec::with_capacity(order.len());
    let mut ordered = Vec::with_capacity(triangles.len());
    for (position, &n) in order.iter().enumerate() {
        let node = &bvh.nodes[n as usize];
        let (first, count) = if node.is_leaf() {
            let first = ordered.len() as u32;
            let range = node.first_index as usize..(node.first_index + node.prim_count) as usize;
            for &p in &bvh.primitive_indices[range] {
                ordered.push(triangles[p as usize]);
            }
            (first, node.prim_count)
        } else {
            (0, 0)
        };
        nodes.push(Node {
            min: node.aabb.min.to_array(),
            max: node.aabb.max.to_array(),
            escape: position as u32 + size[n as usize],
            first,
            count,
        });
    }
    (nodes, ordered, depth)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rounding_is_outwards() {
        for x in [0.1f64, -0.1, 1.0 / 3.0, -7.0 / 3.0, 1e-30, 3.0] {
            assert!(f64::from(round_down(x)) <= x && f64::from(round_up(x)) >= x);
        }
    }

    fn soup(points: Vec<[f64; 3]>) -> HoldoutMesh {
        let triangles = (0..points.len() as u32 / 3)
            .map(|i| [3 * i, 3 * i + 1, 3 * i + 2])
            .collect();
        HoldoutMesh {
            prim_path: "/Soup".into(),
            prim_type: "Mesh".into(),
            points,
            triangles,
            faces: 0,
            degenerate_triangles: 0,
            double_sided: true,
        }
    }

    /// A UV sphere of radius `r` about `c` with `nu` segments round and `nv` rings:
    /// planar quads (two triangles) and fans at the poles, outward.
    fn uv_sphere(r: f64, c: DVec3, nu: u32, nv: u32) -> HoldoutMesh {
        let mut points = vec![(c + DVec3::Z * r).to_array(), (c - DVec3::Z * r).to_array()];
        for j in 1..nv {
            let theta = std::f64::consts::PI * j as f64 / nv as f64;
            for i in 0..nu {
                let phi = std::f64::consts::TAU * i as f64 / nu as f64;
                let d = DVec3::new(
                    theta.sin() * phi.cos(),
                    theta.sin() * phi.sin(),
                    theta.cos(),
                );
                points.push((c + d * r).to_array());
            }
        }
        let at = |j: u32, i: u32| 2 + (j - 1) * nu + i % nu;
        let mut triangles = Vec::new();
        for i in 0..nu {
            triangles.push([0, at(1, i), at(1, i + 1)]);
            triangles.push([1, at(nv - 1, i + 1), at(nv - 1, i)]);
            for j in 1..nv - 1 {
                let (a, b) = (at(j, i), at(j, i + 1));
                let (c, d) = (at(j + 1, i), at(j + 1, i + 1));
                triangles.push([a, c, d]);
                triangles.push([a, d, b]);
            }
        }
        HoldoutMesh {
            prim_path: "/Sphere".into(),
            prim_type: "Mesh".into(),
            points,
            triangles,
            faces: 0,
            degenerate_triangles: 0,
            double_sided: false,
        }
    }

    /// The inside intervals of a ray through `boundary` from t = 0 to 100.
    fn intervals(boundary: &dyn Boundary, o: DVec3, d: DVec3) -> Vec<(f32, f32)> {
        let mut inside = crate::volume::boundary::Inside::new(boundary, o, d, 0.0, 100.0);
        let mut out = Vec::new();
        while let Some(i) = inside.current() {
            out.push(i);
            inside.advance();
        }
        out
    }

    /// A convex fog box clipped by its face planes ([`ConvexHull`]) gives the inside
    /// intervals its triangles' BVH gives: 4,000 random rays (origins inside and
    /// outside, aimed across the sphere's box) through a UV sphere of 8 × 4 (32 planes, the most
    /// kept) and one of 6 × 3 elsewhere, each endpoint within 1e-5 (f32
    /// intervals from f64 crossings that may differ in their last bits).
    #[test]
    fn convex_hulls_clip_as_the_triangles_do() {
        use crate::volume::convex::ConvexHull;
        use rand::{Rng, SeedableRng};
        let mut rng = rand_pcg::Pcg64::seed_from_u64(11);
        let meshes = [
            uv_sphere(1.5, DVec3::new(0.3, -0.2, 0.1), 8, 4),
            uv_sphere(0.8, DVec3::new(-0.5, 0.4, 0.2), 6, 3),
        ];
        let (mut rays, mut hits) = (0, 0);
        for mesh in &meshes {
            let hull = ConvexHull::from_triangles(&mesh.points, &mesh.triangles)
                .expect("a UV sphere is convex");
            let tree = Holdouts::build(std::slice::from_ref(mesh));
            for _ in 0..2000 {
                let o = DVec3::new(
                    rng.gen_range(-2.5..2.5),
                    rng.gen_range(-2.5..2.5),
                    rng.gen_range(-2.5..2.5),
                );
                // Aimed at the sphere's box, so that most rays hit it and some graze.
                let poles = DVec3::from_array(mesh.points[0]) + DVec3::from_array(mesh.points[1]);
                let target = poles / 2.0
                    + DVec3::new(
                        rng.gen_range(-1.6..1.6),
                        rng.gen_range(-1.6..1.6),
                        rng.gen_range(-1.6..1.6),
                    );
                let d = (target - o).normalize();
                let (a, b) = (intervals(&hull, o, d), intervals(&tree, o, d));
                assert_eq!(a.len(), b.len(), "ray {o} {d}: {a:?} against {b:?}");
                for (x, y) in a.iter().zip(&b) {
                    assert!(
                        (x.0 - y.0).abs() < 1e-5 && (x.1 - y.1).abs() < 1e-5,
                        "ray {o} {d}: {a:?} against {b:?}"
                    );
                }
                rays += 1;
                hits += !a.is_empty() as usize;
            }
        }
        assert!(hits > rays / 3 && hits < rays, "{hits} of {rays} rays hit");
    }

    /// The stackless traversal (trees deeper than the stack) answers as the ordered one.
    #[test]
    fn both_traversals_agree() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_pcg::Pcg64::seed_from_u64(5);
        let mut r = |s: f64| rng.gen_range(-s..s);
        let points: Vec<[f64; 3]> = (0..3000)
            .map(|i| {
                let c = if i % 3 == 0 {
                    [r(5.0), r(5.0), r(5.0)]
                } else {
                    [0.0; 3]
                };
                [c[0] + r(1.0), c[1] + r(1.0), c[2] + r(1.0)]
            })
            .collect();
        // Triangles as offsets from their first vertex.
        let points: Vec<[f64; 3]> = points
            .chunks(3)
            .flat_map(|c| {
                let a = c[0];
                [
                    a,
                    [a[0] + c[1][0], a[1] + c[1][1], a[2] + c[1][2]],
                    [a[0] + c[2][0], a[1] + c[2][1], a[2] + c[2][2]],
                ]
            })
            .collect();
        let ordered = Holdouts::build(&[soup(points)]);
        assert!(ordered.ordered);
        let mut stackless = Holdouts::build(&[]);
        stackless.nodes = ordered.nodes.clone();
        stackless.triangles = ordered.triangles.clone();
        stackless.ordered = false;
        for _ in 0..5000 {
            let o = DVec3::new(r(7.0), r(7.0), r(7.0));
            let d = DVec3::new(r(1.0), r(1.0), r(1.0)).normalize();
            let (tmin, tmax) = (r(1.0).abs(), 2.0 + r(20.0).abs());
            assert_eq!(
                ordered.hit(o, d, tmin, tmax),
                stackless.hit(o, d, tmin, tmax)
            );
            assert_eq!(
                ordered.occluded(o, d, tmin, tmax),
                stackless.occluded(o, d, tmin, tmax)
            );
        }
    }

    /// Triangles at exponentially growing distances make a chain-like tree deeper than
    /// the ordered traversal's stack: it is walked through the escape links instead.
    #[test]
    fn a_deep_tree_falls_back_to_the_stackless_traversal() {
        let mut points = Vec::new();
        for k in 0..900 {
            let x = 1.1f64.powi(k);
            points.extend([[x, -1.0, -1.0], [x, 1.0, -1.0], [x, 0.0, 1.0]]);
        }
        let h = Holdouts::build(&[soup(points)]);
        assert_eq!(h.stats().triangles, 900);
        assert!(!h.ordered, "expected a tree deeper than {STACK}");
        // Along +x from the origin the first wall is at 1; from past wall k, at 1.1^(k+1).
        assert_eq!(
            h.hit(DVec3::new(0.0, 0.0, 0.0), DVec3::X, 0.0, f64::INFINITY),
            Some(1.0)
        );
        let from = 1.1f64.powi(100) * 1.05;
        let want = 1.1f64.powi(101) - from;
        let got = h.hit(DVec3::new(from, 0.0, 0.0), DVec3::X, 0.0, f64::INFINITY);
        assert!(
            got.is_some_and(|t| (t - want).abs() <= 1e-9 * want),
            "{got:?} vs {want}"
        );
        assert!(h.occluded(DVec3::new(from, 0.0, 0.0), DVec3::NEG_X, 0.0, f64::INFINITY));
        assert!(!h.occluded(DVec3::new(from, 0.0, 0.0), DVec3::Y, 0.0, f64::INFINITY));
    }

    #[test]
    fn holdouts_are_sync() {
        fn sync<T: Sync + Send>() {}
        sync::<Holdouts>();
    }
}
