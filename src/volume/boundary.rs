//! Where a medium is: the part of a ray inside its boundary.
//!
//! A grid medium is where its majorant region is. A homogeneous medium made by a user
//! (a fog box: a closed mesh with a volume material; world fog) is where a surface
//! says: its walk over the majorant cells is clipped to the intervals of the ray that
//! lie inside the [`Boundary`]. The trackers see only the clipped segments, so every
//! tracker, the race of overlapping media and the AOVs work unchanged.
//!
//! A boundary reports *crossings* along a ray, nearest first, each marked entering or
//! leaving. Two rules turn them into intervals ([`InsideRule`]):
//! - **orientation** (closed, consistently outward-oriented meshes, and boxes): each
//!   crossing *sets* the state (entering → inside, leaving → outside), so a hit counted
//!   twice where a ray passes through an edge two triangles share, or a graze of a
//!   silhouette (in and out at one `t`), changes nothing;
//! - **parity** (meshes that are not closed or not consistently oriented, after a warning
//!   naming the prim): each crossing toggles the state, and the state at the ray's start
//!   is the parity of every crossing ahead of it. Still well defined (no NaN, no hang):
//!   an open mesh is the union of the stretches with an odd number of sheets ahead.
//!
//! World fog is everywhere ([`MediumRegion::Everywhere`]): its walk is one segment over the
//! whole ray.
//!
//! The crossings are fetched in batches of [`BATCH`] into a buffer on the stack, the
//! next batch from the last crossing on, so a query allocates nothing whatever the
//! mesh.

use crate::volume::majorant::{Segment, TreeWalk};
use glam::DVec3;
use std::sync::Arc;

/// Crossings fetched per boundary query.
pub const BATCH: usize = 16;

/// A surface crossing at `t` along a ray; `entering` when the ray goes from outside to
/// inside there (its direction against the outward normal).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Crossing {
    pub t: f64,
    pub entering: bool,
}

/// How crossings become inside intervals (see the module documentation).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum InsideRule {
    Orientation,
    Parity,
}

/// A closed surface rays can be clipped to.
pub trait Boundary: Send + Sync {
    /// Writes into `out` the nearest `out.len()` crossings of `origin + t·dir` with
    /// `t > tmin` (strictly), sorted by `t`, and returns how many it wrote and how many
    /// crossings there are beyond `tmin` in all (the parity rule needs the count).
    fn crossings(&self, origin: DVec3, dir: DVec3, tmin: f64, out: &mut [Crossing])
        -> (usize, u64);

    /// How the crossings are read.
    fn rule(&self) -> InsideRule;

    /// Whether every ray meets the inside in one interval at most (a convex surface
    /// read by orientation): its walk is then the cells over [`convex_span`], with no
    /// crossing buffer and no clipping per segment.
    fn is_convex(&self) -> bool {
        false
    }
}

/// The inside interval of `origin + t·dir`, `t` in `[tmin, tmax)`, of a convex
/// `boundary` ([`Boundary::is_convex`]): the one interval [`Inside`] would hand out, by
/// the same orientation rule and the same rounding to f32, from its first two crossings.
pub fn convex_span(
    boundary: &dyn Boundary,
    origin: DVec3,
    dir: DVec3,
    tmin: f32,
    tmax: f32,
) -> Option<(f32, f32)> {
    let mut buf = [Crossing::default(); 2];
    let (n, _) = boundary.crossings(origin, dir, tmin as f64, &mut buf);
    let crossings = &buf[..n];
    let end_of_ray = tmax as f64;
    // Inside before the first crossing exactly when it leaves.
    let start = match crossings.first() {
        Some(c) if !c.entering => tmin as f64,
        Some(c) if c.t < end_of_ray => c.t,
        _ => return None,
    };
    let end = crossings
        .iter()
        .find(|c| !c.entering)
        .map_or(end_of_ray, |c| c.t.min(end_of_ray));
    let (a, b) = (start as f32, (end as f32).min(tmax));
    (a < b).then_some((a, b))
}

/// Keeps the `out.len()` nearest crossings seen so far sorted in `out[..*n]`
/// (insertion; a batch is small). Returns the distance beyond which a crossing can no
/// longer be kept (infinite until the buffer is full), for a caller to cull with.
#[inline]
pub fn keep_nearest(out: &mut [Crossing], n: &mut usize, c: Crossing) -> f64 {
    let cap = out.len();
    if *n < cap || c.t < out[cap - 1].t {
        let mut i = (*n).min(cap - 1);
        while i > 0 && out[i - 1].t > c.t {
            out[i] = out[i - 1];
            i -= 1;
        }
        out[i] = c;
        *n = (*n + 1).min(cap);
    }
    if *n == cap {
        out[cap - 1].t
    } else {
        f64::INFINITY
    }
}

/// The inside intervals of one ray, produced lazily in `t` order.
pub struct Inside<'a> {
    boundary: &'a dyn Boundary,
    origin: DVec3,
    dir: DVec3,
    tmax: f32,
    rule: InsideRule,
    buf: [Crossing; BATCH],
    n: usize,
    next: usize,
    /// Whether crossings may lie beyond `buf[n - 1]` (the batch was full).
    more: bool,
    inside: bool,
    /// Start of the open interval while `inside`.
    start: f64,
    /// The current interval `[a, b)`, or `None` once there are no more.
    current: Option<(f32, f32)>,
    /// Whether every interval has been handed out.
    done: bool,
}

impl<'a> Inside<'a> {
    /// The intervals of `origin + t·dir`, `t` in `[tmin, tmax)`, inside `boundary`.
    pub fn new(
        boundary: &'a dyn Boundary,
        origin: DVec3,
        dir: DVec3,
        tmin: f32,
        tmax: f32,
    ) -> Self {
        let mut inside = Inside {
            boundary,
            origin,
            dir,
            tmax,
            rule: boundary.rule(),
            buf: [Crossing::default(); BATCH],
            n: 0,
            next: 0,
            more: false,
            inside: false,
            start: tmin as f64,
            current: None,
            done: false,
        };
        let total = inside.fetch(tmin as f64);
        inside.inside = match inside.rule {
            InsideRule::Parity => total % 2 == 1,
            // Before the first crossing the ray is inside exactly when that crossing
            // leaves; no crossing ahead: outside.
            InsideRule::Orientation => inside.n > 0 && !inside.buf[0].entering,
        };
        inside.advance();
        inside
    }

    /// Fetches the batch of crossings after `t`; returns their total count.
    fn fetch(&mut self, t: f64) -> u64 {
        let (n, total) = self
            .boundary
            .crossings(self.origin, self.dir, t, &mut self.buf);
        self.n = n;
        self.next = 0;
        self.more = total > n as u64;
        total
    }

    /// The current interval, `None` when the ray has no more inside.
    #[inline(always)]
    pub fn current(&self) -> Option<(f32, f32)> {
        self.current
    }

    /// Moves on to the next interval.
    pub fn advance(&mut self) {
        self.current = None;
        while !self.done {
            if self.next == self.n && self.more {
                let last = self.buf[self.n - 1].t;
                self.fetch(last);
                continue;
            }
            // No crossing left, or the next one past the end of the ray: an interval
            // still open runs to the end (without a crossing ahead, only a mesh that
            // is not closed leaves one open).
            let c = (self.next < self.n).then(|| self.buf[self.next]);
            let Some(c) = c.filter(|c| c.t < self.tmax as f64) else {
                self.done = true;
                if self.inside {
                    self.emit(self.tmax as f64);
                }
                return;
            };
            self.next += 1;
            let now_inside = match self.rule {
                InsideRule::Orientation => c.entering,
                InsideRule::Parity => !self.inside,
            };
            match (self.inside, now_inside) {
                (false, true) => {
                    self.inside = true;
                    self.start = c.t;
                }
                (true, false) => {
                    self.inside = false;
                    if self.emit(c.t) {
                        return;
                    }
                }
                _ => {}
            }
        }
    }

    /// Makes `[start, end)` the current interval unless it is empty in f32.
    fn emit(&mut self, end: f64) -> bool {
        let (a, b) = (self.start as f32, (end as f32).min(self.tmax));
        if a < b {
            self.current = Some((a, b));
        }
        a < b
    }
}

/// Where a medium is.
#[derive(Clone)]
pub enum MediumRegion {
    /// Where its grid's majorant region is (a VDB volume).
    Grid,
    /// Inside a closed surface (a fog box).
    Inside(Arc<dyn Boundary>),
    /// Everywhere, without end (world fog, as Cycles' world volume: a ray that leaves
    /// every surface runs on through it, so nothing reaches it from infinity).
    Everywhere,
}

/// A medium's walk along a ray: its majorant segments, clipped to the inside of its
/// boundary when it has one, or one segment over the whole ray for a medium that is
/// everywhere. Segments keep their cell's bounds; only `t0`, `t1` move.
pub enum MediumWalk<'a> {
    Cells(TreeWalk<'a>),
    /// The cells of a medium of constant density, already clipped to its convex
    /// boundary's one interval: each segment carries the cell's top as both bounds.
    Constant(TreeWalk<'a>),
    Clipped {
        cells: TreeWalk<'a>,
        inside: Inside<'a>,
        /// The rest of the cell segment being clipped.
        pending: Option<Segment>,
        /// The density is constant inside the boundary (a fog box's): the clipped
        /// segments carry it as both bounds, so estimators may use closed forms.
        constant: bool,
    },
    /// The one segment left, if any.
    Everywhere(Option<Segment>),
}

impl Iterator for MediumWalk<'_> {
    type Item = Segment;

    #[inline(always)]
    fn next(&mut self) -> Option<Segment> {
        match self {
            MediumWalk::Cells(cells) => cells.next(),
            MediumWalk::Constant(cells) => cells.next().map(constant_segment),
            MediumWalk::Everywhere(seg) => seg.take(),
            MediumWalk::Clipped {
                cells,
                inside,
                pending,
                constant,
            } => {
                let seg = clipped_next(cells, inside, pending)?;
                Some(match constant {
                    true => constant_segment(seg),
                    false => seg,
                })
            }
        }
    }
}

/// A cell segment of a medium of constant density: the cell's top is its density, so
/// both bounds.
#[inline(always)]
fn constant_segment(seg: Segment) -> Segment {
    Segment {
        dmin: seg.dmax,
        ..seg
    }
}

/// The next cell segment of `cells` clipped to `inside`'s intervals.
#[inline(always)]
fn clipped_next(
    cells: &mut TreeWalk,
    inside: &mut Inside,
    pending: &mut Option<Segment>,
) -> Option<Segment> {
    loop {
        let (a, b) = inside.current()?;
        let seg = match *pending {
            Some(s) => s,
            None => cells.next()?,
        };
        *pending = Some(seg);
        if b <= seg.t0 {
            inside.advance();
            continue;
        }
        if seg.t1 <= a {
            *pending = None;
            continue;
        }
        // They overlap: a < seg.t1 and seg.t0 < b, so the clip is not empty.
        let clipped = Segment {
            t0: seg.t0.max(a),
            t1: seg.t1.min(b),
            ..seg
        };
        if seg.t1 <= b {
            *pending = None;
        } else {
            *pending = Some(Segment { t0: b, ..seg });
            inside.advance();
        }
        return Some(clipped);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Crossings given as a list (for the interval logic alone).
    struct Listed(Vec<Crossing>, InsideRule);

    impl Boundary for Listed {
        fn crossings(&self, _o: DVec3, _d: DVec3, tmin: f64, out: &mut [Crossing]) -> (usize, u64) {
            let mut n = 0;
            let mut total = 0;
            for c in &self.0 {
                if c.t > tmin {
                    total += 1;
                    keep_nearest(out, &mut n, *c);
                }
            }
            (n, total)
        }
        fn rule(&self) -> InsideRule {
            self.1
        }
    }

    fn intervals(b: &dyn Boundary, tmin: f32, tmax: f32) -> Vec<(f32, f32)> {
        let mut i = Inside::new(b, DVec3::ZERO, DVec3::X, tmin, tmax);
        let mut out = Vec::new();
        while let Some(iv) = i.current() {
            out.push(iv);
            i.advance();
        }
        out
    }

    fn c(t: f64, entering: bool) -> Crossing {
        Crossing { t, entering }
    }

    #[test]
    fn orientation_ignores_repeated_and_grazing_crossings() {
        // An edge counted twice (two entering hits at 1), a graze at 4 (in and out).
        let b = Listed(
            vec![
                c(1.0, true),
                c(1.0, true),
                c(2.0, false),
                c(4.0, true),
                c(4.0, false),
                c(5.0, true),
                c(7.0, false),
            ],
            InsideRule::Orientation,
        );
        assert_eq!(intervals(&b, 0.0, 100.0), vec![(1.0, 2.0), (5.0, 7.0)]);
        // Starting inside: the first crossing leaves.
        assert_eq!(intervals(&b, 1.5, 6.0), vec![(1.5, 2.0), (5.0, 6.0)]);
    }

    #[test]
    fn batches_continue_past_the_buffer() {
        // 3 × BATCH entries: alternating slabs [2k, 2k+1).
        let list = (0..3 * BATCH as i32)
            .map(|k| c(k as f64 + 1.0, k % 2 == 0))
            .collect();
        let b = Listed(list, InsideRule::Orientation);
        let got = intervals(&b, 0.0, 1e9);
        assert_eq!(got.len(), 3 * BATCH / 2);
        assert!(got
            .iter()
            .enumerate()
            .all(|(k, &(a, b))| a == 2.0 * k as f32 + 1.0 && b == a + 1.0));
    }

    #[test]
    fn parity_of_an_open_mesh_is_well_defined() {
        // One sheet at 3 (an open mesh): odd count ahead of 0 → inside until 3.
        let b = Listed(vec![c(3.0, true)], InsideRule::Parity);
        assert_eq!(intervals(&b, 0.0, 10.0), vec![(0.0, 3.0)]);
        assert_eq!(intervals(&b, 4.0, 10.0), vec![]);
        // Orientation with a lone entering sheet: inside from 3 to the end of the ray.
        let b = Listed(vec![c(3.0, true)], InsideRule::Orientation);
        assert_eq!(intervals(&b, 0.0, 10.0), vec![(3.0, 10.0)]);
    }
}
