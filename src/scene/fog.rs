//! Fog boxes' surfaces: a gprim's triangles checked for a closed, orientable surface and
//! wound outwards, so that a ray's crossings say where it is inside
//! ([`crate::volume::boundary`]).

use super::description::{FogMesh, HoldoutMesh};
use glam::DVec3;

/// A fog box's surface from a gprim's world-space triangles (the USD reader's and the
/// Hydra delegate's one way in): checks that it is closed (points welded by
/// exact position, so faces that repeat a corner's point still share the edge: every
/// edge shared by exactly two triangles), orients every triangle like its neighbours
/// and winds the whole outwards (positive enclosed volume). `mirrored` (USD
/// `orientation = "leftHanded"`, or a transform with a negative determinant) says the
/// authored winding already runs the other way; `None` for an implicit gprim, whose
/// winding is the tessellation's, not authored. Returns the mesh and, for a stage
/// warning, what is wrong with it: open or non-manifold edges, or a surface that
/// cannot be oriented (inside is then decided by parity); faces flipped to agree with
/// their neighbours, or authored inside out.
pub fn fog_mesh(mut mesh: HoldoutMesh, mirrored: Option<bool>) -> (FogMesh, Option<String>) {
    use std::collections::HashMap;
    let mut weld: HashMap<[u64; 3], u32> = HashMap::new();
    let ids: Vec<u32> = mesh
        .points
        .iter()
        .map(|p| {
            let next = weld.len() as u32;
            *weld.entry(p.map(|x| (x + 0.0).to_bits())).or_insert(next)
        })
        .collect();
    let welded = |t: &[u32; 3]| t.map(|i| ids[i as usize]);
    // Undirected edge → the triangles along it.
    let mut edges: HashMap<(u32, u32), Vec<u32>> = HashMap::new();
    for (i, t) in mesh.triangles.iter().enumerate() {
        let w = welded(t);
        for k in 0..3 {
            let (a, b) = (w[k], w[(k + 1) % 3]);
            edges
                .entry((a.min(b), a.max(b)))
                .or_default()
                .push(i as u32);
        }
    }
    let open = edges.values().filter(|v| v.len() == 1).count();
    let non_manifold = edges.values().filter(|v| v.len() > 2).count();
    // Orient by propagation: a neighbour across a shared edge must run along it the
    // other way.
    let runs = |w: [u32; 3], flip: bool, a: u32, b: u32| {
        let w = if flip { [w[0], w[2], w[1]] } else { w };
        (0..3).any(|k| w[k] == a && w[(k + 1) % 3] == b)
    };
    let n = mesh.triangles.len();
    let mut flip: Vec<Option<bool>> = vec![None; n];
    let mut orientable = true;
    for seed in 0..n {
        if flip[seed].is_some() {
            continue;
        }
        flip[seed] = Some(false);
        let mut stack = vec![seed];
        while let Some(i) = stack.pop() {
            let (w, f) = (welded(&mesh.triangles[i]), flip[i] == Some(true));
            let w = if f { [w[0], w[2], w[1]] } else { w };
            for k in 0..3 {
                let (a, b) = (w[k], w[(k + 1) % 3]);
                let shared = &edges[&(a.min(b), a.max(b))];
                if shared.len() != 2 {
                    continue;
                }
                let j = if shared[0] as usize == i {
                    shared[1]
                } else {
                    shared[0]
                } as usize;
                let wj = welded(&mesh.triangles[j]);
                // j must run b → a: unflipped if it already does.
                let need = !runs(wj, false, b, a);
                match flip[j] {
                    None => {
                        flip[j] = Some(need);
                        stack.push(j);
                    }
                    Some(have) if have != need => orientable = false,
                    _ => {}
                }
            }
        }
    }
    let flipped = flip.iter().filter(|f| **f == Some(true)).count();
    for (t, f) in mesh.triangles.iter_mut().zip(&flip) {
        if *f == Some(true) {
            t.swap(1, 2);
        }
    }
    let closed = open == 0 && non_manifold == 0 && orientable && n > 0;
    let point = |i: u32| DVec3::from_array(mesh.points[i as usize]);
    let volume: f64 = mesh
        .triangles
        .iter()
        .map(|&[a, b, c]| point(a).dot(point(b).cross(point(c))) / 6.0)
        .sum();
    // Wound outwards: e1 × e2 of every triangle points out of the enclosed volume.
    // Which way the authored faces pointed: most of them, after the flips.
    let authored_inwards = (volume < 0.0) != (2 * flipped > n);
    if volume < 0.0 {
        for t in &mut mesh.triangles {
            t.swap(1, 2);
        }
    }
    let crossing = self_intersections(&mesh.points, &mesh.triangles, &ids);
    let problem = if !closed {
        Some(format!(
            "the fog surface is not a closed, orientable surface ({open} open edges, {non_manifold} edges shared by more than two faces{}, of {n} triangles): inside is decided by the parity of surface crossings along each ray",
            if orientable { "" } else { ", not orientable" }
        ))
    } else if crossing > 0 {
        Some(format!(
            "the fog surface intersects itself ({crossing}{} pairs of its {n} faces cross): inside follows the facing of each crossing along a ray, which a self-intersecting surface leaves ambiguous where it overlaps itself",
            if crossing >= MAX_CROSSING_PAIRS { " or more" } else { "" }
        ))
    } else if mirrored.is_some() && flipped > 0 && 2 * flipped != n {
        Some(format!(
            "{} of its {n} faces point the other way from their neighbours; read with every face pointing outwards",
            flipped.min(n - flipped)
        ))
    } else if mirrored.is_some_and(|m| authored_inwards != m) {
        Some("the surface's faces point inwards (for its orientation and transform); read as pointing outwards".to_string())
    } else {
        None
    };
    (FogMesh { mesh, closed }, problem)
}

/// Counting stops at this many crossing face pairs (the warning says "or more").
const MAX_CROSSING_PAIRS: usize = 1000;

/// Bounding-box pairs examined at most: the sweep is O(n log n + pairs), and a surface
/// whose faces' boxes overlap in far more pairs than that (a pathological mesh) is not
/// searched further.
const MAX_BOX_PAIRS: usize = 20_000_000;

/// How many pairs of faces that share no (welded) corner cross each other, up to
/// [`MAX_CROSSING_PAIRS`]: the faces' boxes are swept along the axis where their
/// centres spread most, and each pair of overlapping boxes is tested edge against
/// triangle both ways. Faces that only touch (at a corner or an edge) or overlap in one
/// plane are not counted: the test asks for an edge passing strictly through a face's
/// interior.
fn self_intersections(points: &[[f64; 3]], triangles: &[[u32; 3]], ids: &[u32]) -> usize {
    let corner = |t: &[u32; 3], k: usize| DVec3::from_array(points[t[k] as usize]);
    let boxes: Vec<(DVec3, DVec3)> = triangles
        .iter()
        .map(|t| {
            let (a, b, c) = (corner(t, 0), corner(t, 1), corner(t, 2));
            (a.min(b).min(c), a.max(b).max(c))
        })
        .collect();
    let (lo, hi) = boxes.iter().fold(
        (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
        |(lo, hi), (a, b)| (lo.min((*a + *b) / 2.0), hi.max((*a + *b) / 2.0)),
    );
    let spread = hi - lo;
    let axis = if spread.x >= spread.y && spread.x >= spread.z {
        0
    } else if spread.y >= spread.z {
        1
    } else {
        2
    };
    let mut order: Vec<usize> = (0..triangles.len()).collect();
    order.sort_unstable_by(|&i, &j| boxes[i].0[axis].total_cmp(&boxes[j].0[axis]));
    let welded = |t: &[u32; 3]| t.map(|i| ids[i as usize]);
    let (mut found, mut examined) = (0, 0);
    for (k, &i) in order.iter().enumerate() {
        let (lo_i, hi_i) = boxes[i];
        let wi = welded(&triangles[i]);
        for &j in &order[k + 1..] {
            let (lo_j, hi_j) = boxes[j];
            if lo_j[axis] > hi_i[axis] {
                break;
            }
            examined += 1;
            if examined > MAX_BOX_PAIRS {
                return found;
            }
            if (0..3).any(|a| lo_j[a] > hi_i[a] || lo_i[a] > hi_j[a]) {
                continue;
            }
            let wj = welded(&triangles[j]);
            if wi.iter().any(|v| wj.contains(v)) {
                continue;
            }
            let ti = [0, 1, 2].map(|k| corner(&triangles[i], k));
            let tj = [0, 1, 2].map(|k| corner(&triangles[j], k));
            if faces_cross(&ti, &tj) {
                found += 1;
                if found >= MAX_CROSSING_PAIRS {
                    return found;
                }
            }
        }
    }
    found
}

/// Whether an edge of either triangle passes strictly through the other's interior.
fn faces_cross(a: &[DVec3; 3], b: &[DVec3; 3]) -> bool {
    let edge_through = |t: &[DVec3; 3], p: DVec3, q: DVec3| {
        // Möller–Trumbore with the segment p → q; strict margins relative to the
        // segment keep edges that merely touch the face out.
        const MARGIN: f64 = 1e-9;
        let (e1, e2, d) = (t[1] - t[0], t[2] - t[0], q - p);
        let h = d.cross(e2);
        let det = e1.dot(h);
        if det.abs() <= 1e-14 * e1.length() * e2.length() * d.length() {
            return false; // parallel (or a degenerate face)
        }
        let inv = 1.0 / det;
        let s = p - t[0];
        let u = s.dot(h) * inv;
        let qv = s.cross(e1);
        let v = d.dot(qv) * inv;
        let w = e2.dot(qv) * inv;
        u > MARGIN && v > MARGIN && u + v < 1.0 - MARGIN && w > MARGIN && w < 1.0 - MARGIN
    };
    (0..3).any(|k| edge_through(b, a[k], a[(k + 1) % 3]))
        || (0..3).any(|k| edge_through(a, b[k], b[(k + 1) % 3]))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An octahedron's triangles, centred at `c` with radius `r`, wound outwards.
    fn octahedron(c: [f64; 3], r: f64, first: u32) -> (Vec<[f64; 3]>, Vec<[u32; 3]>) {
        let p = |d: [f64; 3]| [c[0] + r * d[0], c[1] + r * d[1], c[2] + r * d[2]];
        let points = vec![
            p([1.0, 0.0, 0.0]),
            p([-1.0, 0.0, 0.0]),
            p([0.0, 1.0, 0.0]),
            p([0.0, -1.0, 0.0]),
            p([0.0, 0.0, 1.0]),
            p([0.0, 0.0, -1.0]),
        ];
        let f = |a: u32, b: u32, c: u32| [first + a, first + b, first + c];
        let triangles = vec![
            f(0, 2, 4),
            f(2, 1, 4),
            f(1, 3, 4),
            f(3, 0, 4),
            f(2, 0, 5),
            f(1, 2, 5),
            f(3, 1, 5),
            f(0, 3, 5),
        ];
        (points, triangles)
    }

    fn mesh(parts: &[([f64; 3], f64)]) -> HoldoutMesh {
        let (mut points, mut triangles) = (Vec::new(), Vec::new());
        for &(c, r) in parts {
            let (p, t) = octahedron(c, r, points.len() as u32);
            points.extend(p);
            triangles.extend(t);
        }
        HoldoutMesh {
            prim_path: "/fog".into(),
            prim_type: "Mesh".into(),
            faces: triangles.len(),
            points,
            triangles,
            degenerate_triangles: 0,
            double_sided: false,
        }
    }

    /// Two closed octahedra that interpenetrate make one closed, orientable mesh that
    /// crosses itself: a warning; apart (or one alone), none.
    #[test]
    fn a_self_intersecting_surface_is_a_warning() {
        let (one, problem) = fog_mesh(mesh(&[([0.0; 3], 1.0)]), Some(false));
        assert!(one.closed && problem.is_none(), "{problem:?}");
        let (apart, problem) = fog_mesh(
            mesh(&[([0.0; 3], 1.0), ([3.0, 0.2, 0.1], 1.0)]),
            Some(false),
        );
        assert!(apart.closed && problem.is_none(), "{problem:?}");
        let (crossing, problem) = fog_mesh(
            mesh(&[([0.0; 3], 1.0), ([0.7, 0.2, 0.1], 1.0)]),
            Some(false),
        );
        assert!(crossing.closed);
        let problem = problem.expect("no warning for a self-intersecting surface");
        assert!(problem.contains("intersects itself"), "{problem}");
    }
}
