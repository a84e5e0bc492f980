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
    let problem = if !closed {
        Some(format!(
            "the fog surface is not a closed, orientable surface ({open} open edges, {non_manifold} edges shared by more than two faces{}, of {n} triangles): inside is decided by the parity of surface crossings along each ray",
            if orientable { "" } else { ", not orientable" }
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
