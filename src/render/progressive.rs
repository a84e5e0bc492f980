//! Progressive rendering: passes of samples until a sample cap or a time budget is
//! reached or a stop is requested, with checkpoints in between. Each pixel's random
//! stream lives in the film, so the pass structure does not change the image.

use crate::render::adaptive::Convergence;
use crate::render::film::{Film, Region};
use crate::render::job::RenderJob;
use crate::track::select::Choice;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

/// When to stop and when to checkpoint.
#[derive(Clone, Copy, Debug)]
pub struct Budget {
    /// Samples per pixel at most (`u32::MAX`: no cap).
    pub spp_cap: u32,
    /// Seconds of rendering, kept to within one pass.
    pub time_limit: Option<f64>,
    /// Seconds between checkpoints.
    pub checkpoint: Option<f64>,
    /// What a second is: wall time, or the process' CPU time.
    pub clock: Clock,
}

/// The clock budgets and progress are measured on.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Clock {
    /// Wall-clock time (what a user waits).
    #[default]
    Wall,
    /// CPU time of this process, all threads summed: on a shared machine other
    /// programs do not inflate it, so equal-time comparisons stay fair under load.
    Cpu,
}

impl Choice for Clock {
    const ALL: &'static [Self] = &[Clock::Wall, Clock::Cpu];

    fn name(self) -> &'static str {
        Clock::name(self)
    }

    fn help(self) -> &'static str {
        match self {
            Clock::Wall => "Wall-clock time (what a user waits)",
            Clock::Cpu => "CPU time of this process, all threads summed (fair under load)",
        }
    }
}

impl Clock {
    /// The option's name (a CLI value, a schema token, a stats string).
    pub fn name(self) -> &'static str {
        match self {
            Clock::Wall => "wall",
            Clock::Cpu => "cpu",
        }
    }
}

/// A running stopwatch on a [`Clock`].
#[derive(Clone, Copy, Debug)]
pub struct Stopwatch {
    clock: Clock,
    wall: Instant,
    cpu: f64,
}

impl Stopwatch {
    pub fn start(clock: Clock) -> Stopwatch {
        Stopwatch {
            clock,
            wall: Instant::now(),
            cpu: process_cpu_seconds(),
        }
    }

    /// Seconds since the start, on the stopwatch's clock.
    pub fn elapsed(&self) -> f64 {
        match self.clock {
            Clock::Wall => self.wall.elapsed().as_secs_f64(),
            Clock::Cpu => process_cpu_seconds() - self.cpu,
        }
    }
}

/// CPU seconds this process has used (user + system, all threads).
pub fn process_cpu_seconds() -> f64 {
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: `ts` is a valid, writable timespec; CLOCK_PROCESS_CPUTIME_ID is supported
    // on every Linux and macOS kernel Nimbus targets.
    let r = unsafe { libc::clock_gettime(libc::CLOCK_PROCESS_CPUTIME_ID, &mut ts) };
    if r != 0 {
        return 0.0;
    }
    ts.tv_sec as f64 + ts.tv_nsec as f64 * 1e-9
}

/// Renders `job` (the whole frame, or `region` of it) in passes on `pool` until `budget` is spent or `stop` is set (checked
/// between passes: a pass always finishes). `on_samples(n)` is called per finished row
/// with the pass size; `after_pass` after every pass, with `checkpoint_due` set when a
/// checkpoint should be written; its error ends the render.
pub fn render_progressive<E>(
    job: &RenderJob,
    region: Option<Region>,
    pool: &rayon::ThreadPool,
    budget: &Budget,
    stop: &AtomicBool,
    on_samples: &(dyn Fn(u32) + Sync),
    mut after_pass: impl FnMut(&Film, &Progress) -> Result<(), E>,
) -> Result<(Film, Progress), E> {
    let start = Stopwatch::start(budget.clock);
    let mut film = job.new_film(region);
    let mut p = Progress::default();
    let mut schedule = PassSchedule::new(budget.spp_cap, budget.time_limit, budget.checkpoint);
    let mut last_checkpoint = 0.0;
    while let Some(n) = schedule.next(start.elapsed(), last_checkpoint) {
        if stop.load(Ordering::SeqCst) {
            break;
        }
        let pass_start = Stopwatch::start(budget.clock);
        pool.install(|| job.render_pass(&mut film, n, &|| on_samples(n)));
        let dt = pass_start.elapsed();
        schedule.finished(n, dt);
        p.spp += n;
        p.passes += 1;
        p.convergence = Convergence::of(&film.pixels, job.extras.adaptive);
        p.max_pass_seconds = p.max_pass_seconds.max(dt);
        p.seconds = start.elapsed();
        p.checkpoint_due = budget
            .checkpoint
            .is_some_and(|c| p.seconds - last_checkpoint >= c)
            && p.spp < budget.spp_cap
            && !stop.load(Ordering::SeqCst);
        after_pass(&film, &p)?;
        if p.checkpoint_due {
            last_checkpoint = start.elapsed();
        }
        // Adaptive sampling has stopped every pixel: later passes would take nothing
        // (and a render bounded by a time limit alone would never end). The film is
        // then exactly the film of the whole cap, so it counts as the cap's: a farm
        // tile that converged early is complete, not partial.
        if p.convergence.done() {
            if budget.spp_cap != u32::MAX {
                p.spp = budget.spp_cap;
            }
            break;
        }
    }
    p.checkpoint_due = false;
    p.interrupted = stop.load(Ordering::SeqCst);
    p.seconds = start.elapsed();
    Ok((film, p))
}

/// What has been rendered so far.
#[derive(Default)]
pub struct Progress {
    /// Samples per pixel taken (the same in every pixel).
    pub spp: u32,
    pub passes: u32,
    /// Seconds of rendering so far.
    pub seconds: f64,
    pub max_pass_seconds: f64,
    /// Stopped by the stop flag before the cap or budget was reached.
    pub interrupted: bool,
    /// Set when the pass just finished crossed a checkpoint interval (and the render
    /// goes on): the caller should write its outputs.
    pub checkpoint_due: bool,
    /// The pixels' estimated noise after the last pass (and with adaptive sampling the
    /// share of pixels stopped).
    pub convergence: Convergence,
}

/// Longest pass Nimbus plans when nothing else bounds it: a stop request waits for the
/// current pass, so passes stay short enough to answer within about this long.
const MAX_PASS_SECONDS: f64 = 2.0;

/// Chooses the samples per pixel of each pass. The first pass takes 1 sample to measure
/// the cost of one; later passes take as many as fit the remaining time budget, the
/// time to the next checkpoint and [`MAX_PASS_SECONDS`], but at most twice the previous
/// pass (a timing from a small pass may be noisy) and never beyond the cap. Because
/// each pixel's random stream lives in the film, the split does not change the image.
pub struct PassSchedule {
    cap: u32,
    time_limit: Option<f64>,
    checkpoint: Option<f64>,
    done: u32,
    last_n: u32,
    /// Seconds per sample per pixel, from the last pass.
    per_spp: Option<f64>,
}

impl PassSchedule {
    pub fn new(cap: u32, time_limit: Option<f64>, checkpoint: Option<f64>) -> Self {
        PassSchedule {
            cap,
            time_limit,
            checkpoint,
            done: 0,
            last_n: 0,
            per_spp: None,
        }
    }

    /// The size of the next pass at `elapsed` seconds of rendering (last checkpoint
    /// written at `last_checkpoint`), or `None` when the render is complete.
    pub fn next(&self, elapsed: f64, last_checkpoint: f64) -> Option<u32> {
        let left = self.cap - self.done;
        if left == 0 {
            return None;
        }
        let Some(per_spp) = self.per_spp else {
            return Some(1);
        };
        let mut target = MAX_PASS_SECONDS;
        if let Some(limit) = self.time_limit {
            let remaining = limit - elapsed;
            // Start another pass only if at least half a sample fits: the budget is then
            // missed by at most half a pass either way.
            if remaining < 0.5 * per_spp {
                return None;
            }
            target = target.min(remaining);
        }
        if let Some(c) = self.checkpoint {
            target = target.min((last_checkpoint + c - elapsed).max(0.0));
        }
        let fit = (target / per_spp.max(1e-9))
            .floor()
            .clamp(1.0, u32::MAX as f64) as u32;
        Some(fit.min(self.last_n.saturating_mul(2)).min(left).max(1))
    }

    pub fn finished(&mut self, n: u32, seconds: f64) {
        self.done += n;
        self.last_n = n;
        self.per_spp = Some(seconds / n as f64);
    }
}

#[cfg(test)]
mod tests {
    use super::{Clock, PassSchedule, Stopwatch};

    /// The CPU clock advances with work done on this thread: a busy loop of 0.1 s of
    /// wall time spends at least 5 ms of CPU time (loose on purpose: on a loaded
    /// machine the loop may get a small share; a clock that does not advance fails).
    #[test]
    fn cpu_clock_counts_work() {
        let cpu = Stopwatch::start(Clock::Cpu);
        let wall = Stopwatch::start(Clock::Wall);
        let mut x = 0u64;
        while wall.elapsed() < 0.1 {
            x = x.wrapping_mul(6364136223846793005).wrapping_add(1);
        }
        std::hint::black_box(x);
        let (c, w) = (cpu.elapsed(), wall.elapsed());
        assert!(c > 0.005, "cpu {c} s in {w} s of wall time");
    }

    #[test]
    fn schedule_starts_with_one_sample_then_doubles_up_to_the_cap() {
        let mut s = PassSchedule::new(10, None, None);
        let mut sizes = Vec::new();
        while let Some(n) = s.next(0.0, 0.0) {
            sizes.push(n);
            s.finished(n, 0.001 * n as f64);
        }
        assert_eq!(sizes, [1, 2, 4, 3]);
    }

    #[test]
    fn schedule_fits_the_time_budget() {
        // 0.1 s per sample, 1 s budget, 0.25 s spent after the first pass.
        let mut s = PassSchedule::new(u32::MAX, Some(1.0), None);
        assert_eq!(s.next(0.0, 0.0), Some(1));
        s.finished(1, 0.1);
        assert_eq!(s.next(0.25, 0.0), Some(2)); // doubling bound
        s.finished(2, 0.2);
        assert_eq!(s.next(0.45, 0.0), Some(4)); // 0.55 s left fit 5, doubling allows 4
        s.finished(4, 0.4);
        assert_eq!(s.next(0.85, 0.0), Some(1)); // 0.15 s left: one sample
        s.finished(1, 0.1);
        assert_eq!(s.next(0.96, 0.0), None); // 0.04 s left < half a sample
    }

    #[test]
    fn schedule_shortens_passes_to_meet_checkpoints() {
        let mut s = PassSchedule::new(1000, None, Some(4.0));
        s.finished(8, 0.5); // 1/16 s per sample
                            // 3 s to the next checkpoint fit 48 samples; doubling allows 16.
        assert_eq!(s.next(1.0, 0.0), Some(16));
        // 0.5 s to it: 8.
        assert_eq!(s.next(3.5, 0.0), Some(8));
        // Past due: one sample, then the checkpoint is written.
        assert_eq!(s.next(4.5, 0.0), Some(1));
    }
}
