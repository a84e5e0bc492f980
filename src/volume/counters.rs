//! What a render counts: the per-sample [`Counters`] (lookups, collisions, cells
//! visited, tracker timers) behind the [`Tally`] interface the trackers report to, and
//! [`NoCounts`], the tally of a render that counts nothing (every call compiles away).
//! At the bottom of `volume/` beside the majorant walk: the media, emission and albedo
//! grids and every tracker report here.

use crate::color::Spectrum;
use crate::volume::majorant::Segment;
use crate::volume::ticks::{self, Calibration, TrackerTimes};

/// Counters the trackers keep per sample: plain integers on the worker's stack,
/// summed per pixel and per tile, never atomics.
#[derive(Clone, Copy, Debug, Default)]
pub struct Counters {
    /// Evaluations of the density field (every trilinear reconstruction).
    pub density_lookups: u64,
    pub real_collisions: u64,
    pub null_collisions: u64,
    /// Majorant cells entered by the traversal.
    pub cells_visited: u64,
    /// Tentative collisions where the density exceeded the cell's majorant.
    pub majorant_violations: u64,
    /// Density lookups made by residual tracking (a subset of `density_lookups`).
    pub residual_lookups: u64,
    /// Collisions of the control process of decomposition tracking (no lookup).
    pub control_collisions: u64,
    /// Evaluations of emission grids (temperature and emission field, one each), made
    /// only at absorption events; not counted in `density_lookups`.
    pub emission_lookups: u64,
    /// Evaluations of the albedo grid (`nimbus:albedoField`), one per real scatter
    /// event; not counted in `density_lookups`.
    pub albedo_lookups: u64,
    /// Largest channel throughput seen along the path (per sample a maximum; summed
    /// over samples in a pixel, so the pixel's AOV is its mean).
    pub max_throughput: f64,
    /// Time the regions below (`--profile`); off, they stay 0 and cost one
    /// well-predicted branch per lookup and per cell.
    pub timing: bool,
    /// Ticks inside density lookups (one timed region per lookup).
    pub lookup_ticks: u64,
    /// Ticks inside the majorant walk's steps (one timed region per step).
    pub traversal_ticks: u64,
    pub walk_steps: u64,
    /// Ticks inside free-path and transmittance queries, lookups and steps included.
    pub tracker_ticks: u64,
    pub tracker_calls: u64,
    /// Largest channel throughput of any path (a maximum over samples and pixels too):
    /// one path whose throughput explodes shows here even when the mean hides it.
    pub peak_throughput: f64,
}

impl Counters {
    pub fn add(&mut self, o: &Counters) {
        self.density_lookups += o.density_lookups;
        self.real_collisions += o.real_collisions;
        self.null_collisions += o.null_collisions;
        self.cells_visited += o.cells_visited;
        self.majorant_violations += o.majorant_violations;
        self.residual_lookups += o.residual_lookups;
        self.control_collisions += o.control_collisions;
        self.emission_lookups += o.emission_lookups;
        self.albedo_lookups += o.albedo_lookups;
        self.max_throughput += o.max_throughput;
        self.timing |= o.timing;
        self.lookup_ticks += o.lookup_ticks;
        self.traversal_ticks += o.traversal_ticks;
        self.walk_steps += o.walk_steps;
        self.tracker_ticks += o.tracker_ticks;
        self.tracker_calls += o.tracker_calls;
        self.peak_throughput = self.peak_throughput.max(o.peak_throughput);
    }
}

/// What the trackers count as they go: [`Counters`] counts (for the cost AOVs, the
/// stats and `--profile`); [`NoCounts`] counts nothing, so a render that asked for
/// none of those compiles every increment out (the trackers and the integrator are
/// generic over it, instantiated once per render).
pub trait Tally {
    /// Whether lookups and walk steps are timed (`--profile`).
    fn timing(&self) -> bool;
    /// One evaluation of the density field, `ticks` long when timing.
    fn density_lookup(&mut self, ticks: u64);
    fn real_collision(&mut self);
    fn null_collision(&mut self);
    fn majorant_violation(&mut self);
    /// A density lookup made by residual tracking (also counted as a density lookup).
    fn residual_lookup(&mut self);
    fn control_collision(&mut self);
    /// One evaluation of an emission grid (at an absorption event).
    fn emission_lookup(&mut self);
    /// One evaluation of the albedo grid (at a scatter event).
    fn albedo_lookup(&mut self);
    /// Records a path throughput for the `max_throughput` statistic.
    fn observe_throughput(&mut self, w: Spectrum);
    /// The next segment of a majorant walk, counted as a visited cell (and timed as
    /// traversal when timing).
    fn next_segment<W: Iterator<Item = Segment>>(&mut self, walk: &mut W) -> Option<Segment>;
    /// Starts timing a tracker query (0 when not timing).
    fn tracker_start(&self) -> u64;
    /// Ends the tracker query started at `t0`.
    fn tracker_stop(&mut self, t0: u64);
}

impl Tally for Counters {
    #[inline(always)]
    fn timing(&self) -> bool {
        self.timing
    }

    #[inline(always)]
    fn density_lookup(&mut self, ticks: u64) {
        self.density_lookups += 1;
        self.lookup_ticks += ticks;
    }

    #[inline(always)]
    fn real_collision(&mut self) {
        self.real_collisions += 1;
    }

    #[inline(always)]
    fn null_collision(&mut self) {
        self.null_collisions += 1;
    }

    #[inline(always)]
    fn majorant_violation(&mut self) {
        self.majorant_violations += 1;
    }

    #[inline(always)]
    fn residual_lookup(&mut self) {
        self.residual_lookups += 1;
    }

    #[inline(always)]
    fn control_collision(&mut self) {
        self.control_collisions += 1;
    }

    #[inline(always)]
    fn emission_lookup(&mut self) {
        self.emission_lookups += 1;
    }

    #[inline(always)]
    fn albedo_lookup(&mut self) {
        self.albedo_lookups += 1;
    }

    #[inline(always)]
    fn observe_throughput(&mut self, w: Spectrum) {
        let m = w[0].abs().max(w[1].abs()).max(w[2].abs()) as f64;
        if m > self.max_throughput {
            self.max_throughput = m;
            self.peak_throughput = self.peak_throughput.max(m);
        }
    }

    #[inline(always)]
    fn next_segment<W: Iterator<Item = Segment>>(&mut self, walk: &mut W) -> Option<Segment> {
        let seg = if self.timing {
            let t0 = ticks::now();
            let seg = walk.next();
            self.traversal_ticks += ticks::now() - t0;
            self.walk_steps += 1;
            seg
        } else {
            walk.next()
        };
        self.cells_visited += seg.is_some() as u64;
        seg
    }

    #[inline(always)]
    fn tracker_start(&self) -> u64 {
        if self.timing {
            ticks::now()
        } else {
            0
        }
    }

    #[inline(always)]
    fn tracker_stop(&mut self, t0: u64) {
        if self.timing {
            self.tracker_ticks += ticks::now() - t0;
            self.tracker_calls += 1;
        }
    }
}

/// The tally of a render that wants no counts: every method is empty.
#[derive(Clone, Copy, Debug, Default)]
pub struct NoCounts;

impl Tally for NoCounts {
    #[inline(always)]
    fn timing(&self) -> bool {
        false
    }
    #[inline(always)]
    fn density_lookup(&mut self, _ticks: u64) {}
    #[inline(always)]
    fn real_collision(&mut self) {}
    #[inline(always)]
    fn null_collision(&mut self) {}
    #[inline(always)]
    fn majorant_violation(&mut self) {}
    #[inline(always)]
    fn residual_lookup(&mut self) {}
    #[inline(always)]
    fn control_collision(&mut self) {}
    #[inline(always)]
    fn emission_lookup(&mut self) {}
    #[inline(always)]
    fn albedo_lookup(&mut self) {}
    #[inline(always)]
    fn observe_throughput(&mut self, _w: Spectrum) {}
    #[inline(always)]
    fn next_segment<W: Iterator<Item = Segment>>(&mut self, walk: &mut W) -> Option<Segment> {
        walk.next()
    }
    #[inline(always)]
    fn tracker_start(&self) -> u64 {
        0
    }
    #[inline(always)]
    fn tracker_stop(&mut self, _t0: u64) {}
}

impl Calibration {
    /// Splits the timed counters of a render (`c.timing` set) into seconds. The tracker
    /// regions contain the lookup and traversal regions, so those are taken out of them
    /// together with the bias of the nested clock reads. (Beside [`Counters`] rather than
    /// in `ticks`, which stays below the counters it times.)
    pub fn split(&self, c: &Counters) -> TrackerTimes {
        let lookup = self.seconds(c.lookup_ticks, c.density_lookups);
        let traversal = self.seconds(c.traversal_ticks, c.walk_steps);
        let nested = c.density_lookups + c.walk_steps;
        let tracker = self.seconds(c.tracker_ticks, c.tracker_calls + nested);
        TrackerTimes {
            lookup_seconds: lookup,
            traversal_seconds: traversal,
            other_tracker_seconds: (tracker - lookup - traversal).max(0.0),
        }
    }
}
