//! A cycle clock for the tracker cost split (`--profile`, `nimbus bench octree`):
//! time spent in density lookups, in the majorant traversal and in the rest of the
//! trackers. A timed region costs two reads of the clock, so timing is off unless asked
//! for; when it is on, [`empty_region_ticks`] measures what an empty region reads, and
//! that bias is subtracted once per timed event.

use std::time::Instant;

/// The current tick count: the time-stamp counter on x86-64 (a constant-rate clock on
/// every x86-64 CPU of the last decade, ~20 cycles to read), nanoseconds elsewhere.
#[inline(always)]
pub fn now() -> u64 {
    #[cfg(target_arch = "x86_64")]
    {
        // SAFETY: `rdtsc` has no preconditions; it only reads the time-stamp counter.
        unsafe { core::arch::x86_64::_rdtsc() }
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        use std::sync::OnceLock;
        static START: OnceLock<Instant> = OnceLock::new();
        START.get_or_init(Instant::now).elapsed().as_nanos() as u64
    }
}

/// Ticks per second, measured against the monotonic clock over `window`.
pub fn ticks_per_second(window: std::time::Duration) -> f64 {
    let (t0, c0) = (Instant::now(), now());
    while t0.elapsed() < window {
        std::hint::spin_loop();
    }
    let (dt, dc) = (t0.elapsed().as_secs_f64(), now() - c0);
    dc as f64 / dt
}

/// What an empty timed region reads, in ticks: the median over batches of the mean of
/// `now() - now()` pairs (the median resists preemption on a shared machine).
pub fn empty_region_ticks() -> f64 {
    const PAIRS: u64 = 20_000;
    let mut batches: Vec<f64> = (0..9)
        .map(|_| {
            let mut sum = 0u64;
            for _ in 0..PAIRS {
                let t0 = now();
                sum += std::hint::black_box(now()) - t0;
            }
            sum as f64 / PAIRS as f64
        })
        .collect();
    batches.sort_by(f64::total_cmp);
    batches[batches.len() / 2]
}

/// A clock calibration: converts tick totals into seconds, removing the empty-region
/// bias of each timed event.
#[derive(Clone, Copy, Debug)]
pub struct Calibration {
    pub ticks_per_second: f64,
    pub empty_region_ticks: f64,
}

impl Calibration {
    pub fn measure() -> Calibration {
        Calibration {
            ticks_per_second: ticks_per_second(std::time::Duration::from_millis(50)),
            empty_region_ticks: empty_region_ticks(),
        }
    }

    /// Seconds in `ticks` accumulated over `events` timed regions, bias removed.
    pub fn seconds(&self, ticks: u64, events: u64) -> f64 {
        ((ticks as f64 - self.empty_region_ticks * events as f64) / self.ticks_per_second).max(0.0)
    }
}

/// Thread-seconds of tracker work by kind (summed over worker threads).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct TrackerTimes {
    pub lookup_seconds: f64,
    pub traversal_seconds: f64,
    /// Tracker queries minus their lookups and traversal: sampling, weights, events.
    pub other_tracker_seconds: f64,
}
