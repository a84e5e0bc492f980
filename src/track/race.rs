//! Several media along one ray: where volumes overlap their coefficients add.
//!
//! Each medium keeps its own grid, transform and majorant structure. The sum medium's
//! null-collision process is the union of the media's independent processes (a
//! superposition of Poisson processes is a Poisson process with the summed rate), so
//! tracking the sum needs no combined majorant structure: every medium walks its own
//! cells, and the tentative collisions are taken in `t` order, each decided by the
//! medium that produced it with that medium's own coefficients, majorant and weights.
//!
//! This is decomposition tracking's argument (two processes, supplement §1.1) with
//! k media: at a tentative collision of medium i, chosen with probability μ̄ᵢ/μ̄, the
//! collision weight of the sum medium, μ★ᵢ(λ)/(μ̄·(μ̄ᵢ/μ̄)·P★), is medium i's own weight
//! μ★ᵢ(λ)/(μ̄ᵢ·P★). So every tracker stays exact, analog or weighted, and a real
//! collision belongs to the medium that produced it (its phase function, its
//! emission). Transmittance is the product of the media's transmittances, so a product
//! of independent unbiased estimates is unbiased.
//!
//! The lanes live on the stack (at most [`MAX_MEDIA`]): the hot path allocates nothing.

use crate::track::free_path::{majorant, OpticalDepth, Query};
use crate::volume::boundary::MediumWalk;
use crate::volume::counters::Tally;
use crate::volume::majorant::Segment;
use rand::Rng;
use std::ops::ControlFlow;

/// The most volumes a render tracks together (a stage with more is a clear error).
pub const MAX_MEDIA: usize = 64;

/// One medium's process (or pair of processes, for decomposition tracking's control
/// and residual) along the ray.
struct Lane<'a> {
    walk: MediumWalk<'a>,
    seg: Segment,
    rate: [f32; 2],
    /// Optical depth left to each process' next collision, at the start of `seg`.
    tau: [OpticalDepth; 2],
    /// Each process' pending collision distance (infinite at rate 0).
    next: [f32; 2],
    done: bool,
}

/// A tentative collision handed to the tracker: medium `lane`, process `process` (0,
/// or 1 for decomposition's residual), in majorant segment `seg` at rate `rate`.
pub struct Tentative<'s> {
    pub lane: usize,
    pub process: usize,
    pub seg: &'s Segment,
    pub t: f32,
    pub rate: f32,
}

/// Walks the tentative collisions of the media in `qs` merged in `t` order. `rates(i,
/// seg)` gives medium i's process rates in a majorant segment (0 = none: the cell is
/// crossed without a lookup); `at` decides each collision, and breaking returns its
/// value with the medium that produced it. Running off the end of every medium
/// returns `None`.
#[inline]
pub fn race<R: Rng, C: Tally, T>(
    qs: &[Query],
    rng: &mut R,
    c: &mut C,
    mut rates: impl FnMut(usize, &Segment) -> [f32; 2],
    mut at: impl FnMut(&Tentative, &mut R, &mut C) -> ControlFlow<T>,
) -> Option<(T, usize)> {
    debug_assert!(qs.len() <= MAX_MEDIA);
    let k = qs.len().min(MAX_MEDIA);
    // Only the k lanes in use are written (a `None` costs one word): the lanes are
    // built in place, not moved.
    let mut lanes: [Option<Lane>; MAX_MEDIA] = [const { None }; MAX_MEDIA];
    for (lane, q) in lanes.iter_mut().zip(&qs[..k]) {
        *lane = Some(Lane {
            walk: q.medium.walk(q.ray, q.tmin, q.tmax),
            seg: Segment {
                t0: q.tmin,
                t1: q.tmin,
                dmin: 0.0,
                dmax: 0.0,
            },
            rate: [0.0; 2],
            tau: [OpticalDepth::sample(rng), OpticalDepth::sample(rng)],
            next: [f32::INFINITY; 2],
            done: false,
        });
    }
    let mut pending = [f32::INFINITY; MAX_MEDIA];
    for i in 0..k {
        if let Some(lane) = lanes[i].as_mut() {
            pending[i] = settle(lane, i, c, &mut rates);
        }
    }
    loop {
        let (mut i, mut t) = (0, f32::INFINITY);
        for (j, &tj) in pending[..k].iter().enumerate() {
            if tj < t {
                (i, t) = (j, tj);
            }
        }
        if t == f32::INFINITY {
            return None;
        }
        let lane = lanes[i].as_mut().expect("lane of a pending collision");
        let p = (lane.next[1] < lane.next[0]) as usize;
        let event = Tentative {
            lane: i,
            process: p,
            seg: &lane.seg,
            t,
            rate: lane.rate[p],
        };
        if let ControlFlow::Break(v) = at(&event, rng, c) {
            return Some((v, i));
        }
        // Memoryless: only the process that fired draws its next collision.
        lane.next[p] = OpticalDepth::sample(rng).time(t, lane.rate[p]);
        pending[i] = settle(lane, i, c, &mut rates);
    }
}

/// Moves `lane` on to the segment holding its next collision and returns that
/// collision's distance (infinite once the medium's walk is over), spending each
/// process' optical depth across the segments it crosses.
#[inline]
fn settle<C: Tally>(
    lane: &mut Lane,
    i: usize,
    c: &mut C,
    rates: &mut impl FnMut(usize, &Segment) -> [f32; 2],
) -> f32 {
    loop {
        if lane.done {
            return f32::INFINITY;
        }
        let m = lane.next[0].min(lane.next[1]);
        if m < lane.seg.t1 {
            return m;
        }
        for p in 0..2 {
            lane.tau[p] = lane.tau[p].left(lane.next[p], lane.seg.t1, lane.rate[p]);
        }
        let Some(seg) = c.next_segment(&mut lane.walk) else {
            lane.done = true;
            return f32::INFINITY;
        };
        lane.seg = seg;
        lane.rate = rates(i, &seg);
        for p in 0..2 {
            lane.next[p] = lane.tau[p].time(seg.t0, lane.rate[p]);
        }
    }
}

/// [`race`] for trackers with one process per medium at the achromatic majorant
/// (delta, spectral): `at(query, t, μ̄, rng, counters)` decides each collision of the
/// medium `query` describes, as in [`walk_collisions`](super::walk_collisions).
#[inline]
pub fn race_collisions<R: Rng, C: Tally, T>(
    qs: &[Query],
    rng: &mut R,
    c: &mut C,
    mut at: impl FnMut(&Query, f32, f32, &mut R, &mut C) -> ControlFlow<T>,
) -> Option<(T, usize)> {
    race(
        qs,
        rng,
        c,
        |i, seg| [majorant(&qs[i], seg), 0.0],
        |e, rng, c| at(&qs[e.lane], e.t, e.rate, rng, c),
    )
}
