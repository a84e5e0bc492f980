//! Which media a ray may meet, on stages with many volumes (a cloudscape of instances):
//! a BVH over the media's world boxes, asked before each tracker query instead of
//! testing every box. Stages with few volumes test their boxes in a loop, as before.
//!
//! The tree is obvhs' (as the holdouts'), over f32 boxes padded well beyond the f32
//! rounding of the query; each candidate is then tested exactly
//! ([`Medium::span`], f64), so the answer is the loop's. Media that are everywhere
//! (world fog) have no box and are always candidates.

use crate::volume::medium::Medium;
use glam::DVec3;
use obvhs::ray::Ray;

/// Stages with more media than this get an index; fewer are tested in a loop.
pub const INDEXED_MEDIA: usize = 16;

pub struct MediaIndex {
    bvh: obvhs::bvh2::Bvh2,
    /// Media id of each box the tree was built over.
    ids: Vec<u32>,
    /// Media without a box (everywhere).
    unbounded: Vec<u32>,
}

impl MediaIndex {
    /// The index of `media`, `None` for [`INDEXED_MEDIA`] or fewer.
    pub fn build(media: &[Medium]) -> Option<MediaIndex> {
        if media.len() <= INDEXED_MEDIA {
            return None;
        }
        let (mut boxes, mut ids, mut unbounded) = (Vec::new(), Vec::new(), Vec::new());
        for (i, m) in media.iter().enumerate() {
            match m.world_bounds() {
                Some((lo, hi)) => {
                    // Padding: relative to the box and to its distance from the origin,
                    // far beyond the f32 rounding of the box and the ray.
                    let pad = DVec3::splat(
                        1e-3 * (hi - lo).length() + 1e-5 * lo.abs().max(hi.abs()).max_element(),
                    );
                    let (lo, hi) = ((lo - pad).as_vec3(), (hi + pad).as_vec3());
                    boxes.push(obvhs::aabb::Aabb::new(
                        lo.to_array().into(),
                        hi.to_array().into(),
                    ));
                    ids.push(i as u32);
                }
                None if matches!(m.region, crate::volume::boundary::MediumRegion::Everywhere) => {
                    unbounded.push(i as u32)
                }
                None => {} // an empty grid: no ray meets it
            }
        }
        let bvh = obvhs::bvh2::builder::build_bvh2(
            &boxes,
            obvhs::BvhBuildParams::medium_build(),
            &mut std::time::Duration::default(),
        );
        Some(MediaIndex {
            bvh,
            ids,
            unbounded,
        })
    }

    /// Calls `f` with the id of every medium whose padded box the ray `origin + t·dir`,
    /// `t` in [`tmin`, `tmax`], may meet (in no particular order), and of every medium
    /// that is everywhere.
    #[inline]
    pub fn candidates(
        &self,
        origin: DVec3,
        dir: DVec3,
        tmin: f32,
        tmax: f32,
        mut f: impl FnMut(usize),
    ) {
        for &i in &self.unbounded {
            f(i as usize);
        }
        if self.ids.is_empty() {
            return;
        }
        let (o, d) = (origin.as_vec3().to_array(), dir.as_vec3().to_array());
        let ray = Ray::new(o.into(), d.into(), tmin, tmax);
        self.bvh.ray_traverse_anyhit(ray, |_, p| {
            f(self.ids[self.bvh.primitive_indices[p] as usize] as usize)
        });
    }
}
