//! UsdGeom gprims → [`HoldoutMesh`]es: the set geometry of a stage, read as black matte
//! occluders (world-space triangles at the scene's time).
//!
//! Read: `Mesh` (`points`, `faceVertexCounts`, `faceVertexIndices`, `holeIndices`,
//! `doubleSided`), each polygon fan-triangulated from its first vertex. A subdivision
//! mesh (any `subdivisionScheme`) is read as its control cage: for an occluder the cage
//! is a close, conservative stand-in and needs no subdivision library. The implicit
//! gprims `Sphere`, `Cube`, `Cylinder`, `Cone`, `Capsule` and `Plane` are tessellated
//! here (one ray-query path for everything, in `render::holdouts`) with their schema
//! fallbacks for anything unauthored. Materials, displacement, primvars, normals and
//! `orientation` are not read: a holdout is black, opaque and two-sided.
//!
//! Which prims are read (visibility, purpose, `nimbus:holdout`) is decided by the loader
//! (`stage.rs`); this module turns one prim plus its world transform into triangles.

use super::attrs::*;
use super::description::HoldoutMesh;
use glam::{DMat4, DVec3};
use openusd::usd::{Prim, TimeCode};
use std::f64::consts::PI;

/// Tessellation of the round implicit gprims: `SEGMENTS` vertices around every circle,
/// `RINGS` bands from pole to pole of a sphere (a capsule's two hemispheres get half each).
///
/// Max chord error (largest distance between the true surface and the inscribed
/// triangles, every vertex lying on the surface):
/// - circles (cylinder, cone, capsule sides): r·(1 − cos(π/SEGMENTS)) = 3.0e-4·r;
/// - sphere and capsule caps: each triangle of a lat-long quad of angular size
///   Δ = π/RINGS = 2π/SEGMENTS lies within a cap of angular radius ≤ √2·Δ/2 (its
///   circumcircle is at most the quad's diagonal), so the error is
///   ≤ r·(1 − cos(√2·π/128)) = 6.0e-4·r.
///
/// [`MAX_CHORD_ERROR`] (1e-3 of the radius) bounds both. A sphere is 16,128 triangles.
pub const SEGMENTS: usize = 128;
pub const RINGS: usize = 64;
/// Upper bound of the tessellation's chord error, as a fraction of the radius.
pub const MAX_CHORD_ERROR: f64 = 1e-3;

/// The gprim types read as holdouts (schema identifiers; `is_a` also matches types
/// derived from them).
pub(super) const GPRIM_TYPES: [&str; 7] = [
    "Mesh", "Sphere", "Cube", "Cylinder", "Cone", "Capsule", "Plane",
];

/// The first of [`GPRIM_TYPES`] `prim` is, if any. Other gprims (Points, curves,
/// NURBS, Cylinder_1, Capsule_1, …) are not read.
pub(super) fn holdout_type(prim: &Prim) -> Result<Option<&'static str>, SceneError> {
    for ty in GPRIM_TYPES {
        if prim.is_a(ty).map_err(|e| prim_error(prim.path(), e))? {
            return Ok(Some(ty));
        }
    }
    Ok(None)
}

/// Reads `prim` (a [`holdout_type`]) into world-space triangles through `to_world`.
pub(super) fn read_holdout(
    prim: &Prim,
    prim_type: &'static str,
    to_world: &DMat4,
    time: Option<TimeCode>,
) -> Result<HoldoutMesh, SceneError> {
    let shape = match prim_type {
        "Mesh" => mesh_polygons(prim, time)?,
        "Sphere" => sphere(non_negative(prim, "radius", 1.0, time)?),
        "Cube" => cube(non_negative(prim, "size", 2.0, time)?),
        "Cylinder" => cylinder(
            non_negative(prim, "radius", 1.0, time)?,
            non_negative(prim, "height", 2.0, time)?,
        )
        .along(axis(prim, time)?),
        "Cone" => cone(
            non_negative(prim, "radius", 1.0, time)?,
            non_negative(prim, "height", 2.0, time)?,
        )
        .along(axis(prim, time)?),
        "Capsule" => capsule(
            non_negative(prim, "radius", 0.5, time)?,
            non_negative(prim, "height", 1.0, time)?,
        )
        .along(axis(prim, time)?),
        "Plane" => plane(
            non_negative(prim, "width", 2.0, time)?,
            non_negative(prim, "length", 2.0, time)?,
        )
        .along(axis(prim, time)?),
        other => {
            return Err(prim_error(
                prim.path(),
                format!("`{other}` is not a holdout gprim type"),
            ))
        }
    };
    // Every gprim has the `doubleSided` fallback (false; true on Plane).
    let double_sided = read_bool(prim, "doubleSided", time)?.unwrap_or(prim_type == "Plane");
    Ok(to_mesh(prim, prim_type, shape, to_world, double_sided))
}

/// Local-space polygons: points and faces as index lists (a face is `counts[i]`
/// consecutive entries of `indices`).
struct Polygons {
    points: Vec<[f64; 3]>,
    counts: Vec<usize>,
    indices: Vec<u32>,
}

impl Polygons {
    /// Rotates a shape built along +Z onto the prim's `axis`. For a Plane the built
    /// x and y are its width and length; the permutations follow UsdGeomPlane's table
    /// (X: width along z, length along y; Y: width x, length z; Z: width x, length y),
    /// and are harmless for the round shapes (occluders have no winding).
    fn along(mut self, axis: Axis) -> Polygons {
        for p in &mut self.points {
            let [a, b, c] = *p;
            *p = match axis {
                Axis::X => [c, b, a],
                Axis::Y => [a, c, b],
                Axis::Z => [a, b, c],
            };
        }
        self
    }
}

#[derive(Clone, Copy, Debug)]
enum Axis {
    X,
    Y,
    Z,
}

fn axis(prim: &Prim, time: Option<TimeCode>) -> Result<Axis, SceneError> {
    match read_string(prim, "axis", time)?.as_deref() {
        None | Some("Z") => Ok(Axis::Z),
        Some("X") => Ok(Axis::X),
        Some("Y") => Ok(Axis::Y),
        Some(other) => Err(prim_error(
            prim.path(),
            format!("axis = \"{other}\" is not X, Y or Z"),
        )),
    }
}

/// A size or radius: the authored value or the schema `fallback`; negative or
/// non-finite is an error naming the attribute.
fn non_negative(
    prim: &Prim,
    name: &str,
    fallback: f64,
    time: Option<TimeCode>,
) -> Result<f64, SceneError> {
    let v = read_f64(prim, name, time)?.unwrap_or(fallback);
    if !v.is_finite() {
        return Err(prim_error(
            prim.path(),
            format!("{name} = {v} is not finite"),
        ));
    }
    if v < 0.0 {
        return Err(prim_error(prim.path(), format!("{name} = {v} is negative")));
    }
    Ok(v)
}

// ----- meshes --------------------------------------------------------------------------

/// A Mesh's polygons, validated: finite points, every count ≥ 3, counts summing to the
/// number of indices, every index a point. Faces in `holeIndices` are left out.
fn mesh_polygons(prim: &Prim, time: Option<TimeCode>) -> Result<Polygons, SceneError> {
    let err = |message: String| prim_error(prim.path(), message);
    let points = read_vec3_array(prim, "points", time)?.unwrap_or_default();
    let counts = read_int_array(prim, "faceVertexCounts", time)?.unwrap_or_default();
    let indices = read_int_array(prim, "faceVertexIndices", time)?.unwrap_or_default();
    let holes = read_int_array(prim, "holeIndices", time)?.unwrap_or_default();

    if let Some((i, p)) = points
        .iter()
        .enumerate()
        .find(|(_, p)| !p.iter().all(|c| c.is_finite()))
    {
        return Err(err(format!(
            "points[{i}] = ({}, {}, {}) is not finite",
            p[0], p[1], p[2]
        )));
    }
    let mut sum: i64 = 0;
    for (i, &c) in counts.iter().enumerate() {
        if c < 3 {
            return Err(err(format!(
                "faceVertexCounts[{i}] = {c}: a face needs at least 3 vertices"
            )));
        }
        sum = sum.saturating_add(c);
    }
    if sum != indices.len() as i64 {
        return Err(err(format!(
            "faceVertexCounts sum to {sum} but faceVertexIndices has {} entries",
            indices.len()
        )));
    }
    // u32 indices are what the triangles store; a mesh past 4 billion points is not
    // a holdout anyone authors, so say so rather than truncate.
    let point_count = u32::try_from(points.len())
        .map_err(|_| err(format!("{} points is more than Nimbus reads", points.len())))?;
    let mut checked = Vec::with_capacity(indices.len());
    for (j, &v) in indices.iter().enumerate() {
        match u32::try_from(v) {
            Ok(v) if v < point_count => checked.push(v),
            _ => {
                return Err(err(format!(
                    "faceVertexIndices[{j}] = {v} is out of range (the mesh has {} points)",
                    points.len()
                )))
            }
        }
    }
    // holeIndices out of range name no face: nothing to leave out (as pxr's renderers do).
    let mut hole = vec![false; counts.len()];
    for h in holes {
        if let Some(slot) = usize::try_from(h).ok().and_then(|h| hole.get_mut(h)) {
            *slot = true;
        }
    }
    let mut out = Polygons {
        points,
        counts: Vec::with_capacity(counts.len()),
        indices: Vec::with_capacity(checked.len()),
    };
    let mut start = 0;
    for (face, &c) in counts.iter().enumerate() {
        // Counts are ≥ 3 and sum to indices.len(), so this fits in usize.
        let c = c as usize;
        if !hole[face] {
            out.counts.push(c);
            out.indices.extend_from_slice(&checked[start..start + c]);
        }
        start += c;
    }
    Ok(out)
}

/// Fan-triangulates `shape`'s polygons and moves its points to world space. A triangle
/// that repeats a vertex or has zero area in world space is left out and counted.
fn to_mesh(
    prim: &Prim,
    prim_type: &str,
    shape: Polygons,
    to_world: &DMat4,
    double_sided: bool,
) -> HoldoutMesh {
    let points: Vec<[f64; 3]> = shape
        .points
        .iter()
        .map(|&p| to_world.transform_point3(DVec3::from_array(p)).to_array())
        .collect();
    let mut triangles = Vec::new();
    let mut degenerate = 0;
    let mut start = 0;
    for &c in &shape.counts {
        let face = &shape.indices[start..start + c];
        start += c;
        for k in 1..c - 1 {
            let tri = [face[0], face[k], face[k + 1]];
            if is_degenerate(&points, tri) {
                degenerate += 1;
            } else {
                triangles.push(tri);
            }
        }
    }
    HoldoutMesh {
        prim_path: prim.path().to_string(),
        prim_type: prim_type.to_string(),
        points,
        triangles,
        faces: shape.counts.len(),
        degenerate_triangles: degenerate,
        double_sided,
    }
}

/// A repeated vertex, or edges at an angle whose sine is below [`DEGENERATE_SINE`] (or
/// not finite, as a singular or overflowing transform can make it). A relative test,
/// not an exact zero: collinear points moved to world space by a rotation are collinear
/// only to rounding, and such a sliver has no area a ray could hit in practice.
pub(super) fn is_degenerate(points: &[[f64; 3]], [a, b, c]: [u32; 3]) -> bool {
    if a == b || b == c || a == c {
        return true;
    }
    let p = |i: u32| DVec3::from_array(points[i as usize]);
    let (e1, e2) = (p(b) - p(a), p(c) - p(a));
    let area2 = e1.cross(e2).length_squared();
    let scale2 = e1.length_squared() * e2.length_squared();
    !(area2 > DEGENERATE_SINE * DEGENERATE_SINE * scale2 && area2.is_finite())
}

/// See [`is_degenerate`]: far above f64 rounding (1e-16), far below any real triangle.
const DEGENERATE_SINE: f64 = 1e-12;

// ----- implicit gprims -------------------------------------------------------------------
//
// Each is built around +Z (its spine) and rotated onto `axis` by `Polygons::along`.
// Circles start at angle 0 and SEGMENTS is a multiple of 4, so the extreme points
// along ±x and ±y are vertices: the tessellation's bounds equal the shape's extent.

fn circle(k: usize) -> (f64, f64) {
    let a = 2.0 * PI * (k % SEGMENTS) as f64 / SEGMENTS as f64;
    (a.cos(), a.sin())
}

/// Appends a ring of SEGMENTS points of radius `r` at height `z`; returns its first index.
fn ring(points: &mut Vec<[f64; 3]>, r: f64, z: f64) -> u32 {
    let first = points.len() as u32;
    for k in 0..SEGMENTS {
        let (c, s) = circle(k);
        points.push([r * c, r * s, z]);
    }
    first
}

/// Quads between two rings (as 4-vertex polygons), or triangles to a single apex.
fn band(out: &mut Polygons, lower: u32, upper: u32) {
    for k in 0..SEGMENTS as u32 {
        let k1 = (k + 1) % SEGMENTS as u32;
        out.counts.push(4);
        out.indices
            .extend_from_slice(&[lower + k, lower + k1, upper + k1, upper + k]);
    }
}

fn fan(out: &mut Polygons, ring_first: u32, apex: u32) {
    for k in 0..SEGMENTS as u32 {
        let k1 = (k + 1) % SEGMENTS as u32;
        out.counts.push(3);
        out.indices
            .extend_from_slice(&[ring_first + k, ring_first + k1, apex]);
    }
}

fn point(out: &mut Polygons, p: [f64; 3]) -> u32 {
    out.points.push(p);
    (out.points.len() - 1) as u32
}

fn empty() -> Polygons {
    Polygons {
        points: Vec::new(),
        counts: Vec::new(),
        indices: Vec::new(),
    }
}

/// Latitude rings of a sphere of radius `r` centred at height `z0`, polar angles
/// θ = i·π/RINGS for i in `rings` (poles excluded), chained into bands.
fn sphere_rings(
    out: &mut Polygons,
    r: f64,
    z0: f64,
    rings: std::ops::RangeInclusive<usize>,
) -> (u32, u32) {
    let mut first = None;
    let mut previous: Option<u32> = None;
    for i in rings {
        let theta = PI * i as f64 / RINGS as f64;
        let this = ring(&mut out.points, r * theta.sin(), z0 + r * theta.cos());
        if let Some(prev) = previous {
            band(out, prev, this);
        }
        first.get_or_insert(this);
        previous = Some(this);
    }
    // Callers pass non-empty ranges.
    (first.unwrap_or(0), previous.unwrap_or(0))
}

fn sphere(r: f64) -> Polygons {
    let mut out = empty();
    let (top, bottom) = sphere_rings(&mut out, r, 0.0, 1..=RINGS - 1);
    let north = point(&mut out, [0.0, 0.0, r]);
    let south = point(&mut out, [0.0, 0.0, -r]);
    fan(&mut out, top, north);
    fan(&mut out, bottom, south);
    out
}

/// A capsule: a cylinder of `height` capped by hemispheres of radius `r` (total length
/// height + 2r).
fn capsule(r: f64, height: f64) -> Polygons {
    let mut out = empty();
    let h = height / 2.0;
    let (top, upper_equator) = sphere_rings(&mut out, r, h, 1..=RINGS / 2);
    let (lower_equator, bottom) = sphere_rings(&mut out, r, -h, RINGS / 2..=RINGS - 1);
    // With height 0 the cylinder has no area: leave it out rather than count it degenerate.
    if height > 0.0 {
        band(&mut out, upper_equator, lower_equator);
    }
    let north = point(&mut out, [0.0, 0.0, h + r]);
    let south = point(&mut out, [0.0, 0.0, -h - r]);
    fan(&mut out, top, north);
    fan(&mut out, bottom, south);
    out
}

fn cylinder(r: f64, height: f64) -> Polygons {
    let mut out = empty();
    let h = height / 2.0;
    let bottom = ring(&mut out.points, r, -h);
    let top = ring(&mut out.points, r, h);
    band(&mut out, bottom, top);
    let bottom_centre = point(&mut out, [0.0, 0.0, -h]);
    let top_centre = point(&mut out, [0.0, 0.0, h]);
    fan(&mut out, bottom, bottom_centre);
    fan(&mut out, top, top_centre);
    out
}

/// UsdGeomCone: base of radius `r` at −height/2, apex at +height/2.
fn cone(r: f64, height: f64) -> Polygons {
    let mut out = empty();
    let h = height / 2.0;
    let base = ring(&mut out.points, r, -h);
    let apex = point(&mut out, [0.0, 0.0, h]);
    let centre = point(&mut out, [0.0, 0.0, -h]);
    fan(&mut out, base, apex);
    fan(&mut out, base, centre);
    out
}

/// A cube of edge `size` centred at the origin: six quads.
fn cube(size: f64) -> Polygons {
    let s = size / 2.0;
    let mut out = empty();
    for i in 0..8 {
        let c = |bit: usize| if i & bit != 0 { s } else { -s };
        out.points.push([c(1), c(2), c(4)]);
    }
    // Faces as corner indices (bit 1 = +x, 2 = +y, 4 = +z).
    for face in [
        [0, 2, 6, 4],
        [1, 5, 7, 3],
        [0, 4, 5, 1],
        [2, 3, 7, 6],
        [0, 1, 3, 2],
        [4, 6, 7, 5],
    ] {
        out.counts.push(4);
        out.indices.extend_from_slice(&face);
    }
    out
}

/// A plane: `width` along x and `length` along y before `along`; one quad.
fn plane(width: f64, length: f64) -> Polygons {
    let (w, l) = (width / 2.0, length / 2.0);
    Polygons {
        points: vec![[-w, -l, 0.0], [w, -l, 0.0], [w, l, 0.0], [-w, l, 0.0]],
        counts: vec![4],
        indices: vec![0, 1, 2, 3],
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn max_radius_error(shape: &Polygons, r: f64) -> f64 {
        // Distance from the centre to each triangle's plane at its circumcentre is at
        // least the minimum over triangle centroids; checks the stated bound.
        let mut worst: f64 = 0.0;
        let mut start = 0;
        for &c in &shape.counts {
            let f = &shape.indices[start..start + c];
            start += c;
            for k in 1..c - 1 {
                let [a, b, d] =
                    [f[0], f[k], f[k + 1]].map(|i| DVec3::from_array(shape.points[i as usize]));
                let n = (b - a).cross(d - a);
                if n.length_squared() == 0.0 {
                    continue;
                }
                let dist = n.normalize().dot(a).abs();
                worst = worst.max((r - dist) / r);
            }
        }
        worst
    }

    #[test]
    fn sphere_chord_error_is_within_the_stated_bound() {
        let s = sphere(2.0);
        let e = max_radius_error(&s, 2.0);
        assert!(e > 0.0 && e < 6.1e-4 && e < MAX_CHORD_ERROR, "{e}");
        assert!(s
            .points
            .iter()
            .all(|p| (DVec3::from_array(*p).length() - 2.0).abs() < 1e-12));
    }
}
