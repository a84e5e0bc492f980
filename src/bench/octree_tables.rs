//! The supplement's Tables 1 and 2 (Kutz et al. 2017): delta and decomposition tracking
//! at several majorant octree depths on one stage, with the octree leaves visited,
//! the density lookups, and the time split into lookups, octree traversal, the rest of
//! the trackers and everything outside them.
//!
//! Each (depth, tracker) is rendered in `rounds` interleaved rounds, on one thread by
//! default (single-core seconds, as the paper reports them): each round renders every
//! depth, per depth both trackers untimed, then both timed (`--profile`'s timers), the
//! trackers' order alternating from round to round so neither always runs first; on a
//! shared machine a change of load then falls on both trackers and every depth alike. Totals are the untimed runs'
//! process CPU seconds; the split comes from the timed runs. Timing changes no random
//! decision, so every run of a row makes the same lookups and visits the same cells
//! (checked: any difference is an error), and the timed runs' extra time is the timers'
//! cost, reported per row. The octree of each (depth, tracker) is built once (pruning
//! depends on the tracker: decomposition pays for `dmax − dmin`) and swapped in for its
//! runs.

use crate::render::analysis::CodePaths;
use crate::render::progressive::process_cpu_seconds;
use crate::render::session::Session;
use crate::track::select::{TrackerKind, TrackerSettings, TransmittanceKind};
use crate::volume::counters::Counters;
use crate::volume::majorant::{MajorantSpec, MajorantTree, MAX_DEPTH};
use crate::volume::ticks::{Calibration, TrackerTimes};
use anyhow::{bail, Result};
use std::time::Instant;

/// The two trackers of the tables, in the supplement's order.
pub const TRACKERS: [TrackerKind; 2] = [TrackerKind::Delta, TrackerKind::Decomposition];

/// How the tables' shadow rays estimate transmittance.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Shadows {
    /// Each tracker's ratio-tracking estimator: ratio tracking for delta, residual ratio
    /// tracking (control = cell minimum) for decomposition, so each tracker's shadow
    /// rays save what its free paths save.
    Ratio,
    /// Each tracker's own free-path sampler (the track-length estimator,
    /// `--transmittance tracking`): both columns render the same estimator in
    /// distribution and differ only in cost.
    Tracking,
}

impl Shadows {
    pub fn name(self) -> &'static str {
        match self {
            Shadows::Ratio => "ratio",
            Shadows::Tracking => "tracking",
        }
    }
}

/// The tracker settings of a table column: delta or decomposition tracking (control =
/// cell minimum), with the shadow rays `shadows` gives that tracker.
pub fn tracker_settings(tracker: TrackerKind, shadows: Shadows) -> TrackerSettings {
    TrackerSettings {
        tracker,
        transmittance: match (shadows, tracker) {
            (Shadows::Tracking, _) => TransmittanceKind::Tracking,
            (Shadows::Ratio, TrackerKind::Decomposition) => TransmittanceKind::ResidualRatio,
            (Shadows::Ratio, _) => TransmittanceKind::Ratio,
        },
        ..TrackerSettings::default()
    }
}

/// What to measure.
#[derive(Clone, Debug)]
pub struct TablesConfig {
    /// Octree depths, each in 1..=[`MAX_DEPTH`].
    pub depths: Vec<u32>,
    /// Interleaved rounds per depth (≥ 1).
    pub rounds: u32,
    /// Also render each (depth, tracker) with the timers on; without, the split
    /// columns are absent and only the totals are measured.
    pub timed: bool,
    pub shadows: Shadows,
}

impl TablesConfig {
    fn check(&self) -> Result<()> {
        if self.depths.is_empty() {
            bail!("--depths needs at least one depth");
        }
        if let Some(d) = self.depths.iter().find(|d| !(1..=MAX_DEPTH).contains(*d)) {
            bail!("octree depths must lie in 1..={MAX_DEPTH}, got {d}");
        }
        let mut seen = Vec::new();
        for &d in &self.depths {
            if seen.contains(&d) {
                bail!("--depths lists depth {d} twice");
            }
            seen.push(d);
        }
        if self.rounds == 0 {
            bail!("--rounds must be at least 1");
        }
        Ok(())
    }
}

/// One render of the bench.
#[derive(Clone, Debug)]
pub struct Run {
    pub round: u32,
    pub depth: u32,
    pub tracker: TrackerKind,
    /// With the tracker timers on.
    pub timed: bool,
    /// Process CPU seconds of the render (all worker threads).
    pub cpu_seconds: f64,
    pub wall_seconds: f64,
    /// The 1-minute load average when the render started (other programs on the
    /// machine; `NaN` where unknown).
    pub load_average: f64,
    pub counts: Counters,
    /// The timers' split (timed runs only), in CPU seconds: the timers read a wall
    /// clock, so their seconds are scaled by the run's CPU ÷ wall seconds (on a shared
    /// machine the thread is sometimes descheduled inside a timed region; the scaling
    /// spreads that evenly).
    pub times: Option<TrackerTimes>,
    /// CPU seconds outside the tracker queries' timed regions (timed runs only): camera
    /// rays, lights, phase sampling, the integrator. With `times`, adds up to
    /// `cpu_seconds`.
    pub outside_seconds: Option<f64>,
    /// A digest of the image's bits (RGBA sums of every pixel): equal digests, equal
    /// images.
    pub image_digest: u64,
}

/// The median, smallest and largest of some runs' values.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Spread {
    pub median: f64,
    pub min: f64,
    pub max: f64,
}

impl Spread {
    pub fn of(values: &[f64]) -> Spread {
        let mut v: Vec<f64> = values.iter().copied().filter(|x| !x.is_nan()).collect();
        v.sort_by(f64::total_cmp);
        let n = v.len();
        if n == 0 {
            return Spread {
                median: f64::NAN,
                min: f64::NAN,
                max: f64::NAN,
            };
        }
        let median = if n % 2 == 1 {
            v[n / 2]
        } else {
            0.5 * (v[n / 2 - 1] + v[n / 2])
        };
        Spread {
            median,
            min: v[0],
            max: v[n - 1],
        }
    }
}

/// One (depth, tracker) of the tables: exact counts and the medians of its runs.
#[derive(Clone, Debug)]
pub struct Row {
    pub depth: u32,
    pub tracker: TrackerKind,
    /// Levels of the octree and leaf edge in voxels (deep requests are capped at one
    /// voxel and at the leaf budget).
    pub levels: usize,
    pub leaf_edge: [f32; 3],
    pub build_seconds: f64,
    pub memory_bytes: usize,
    /// Counts of every run (identical across runs).
    pub counts: Counters,
    /// Untimed CPU seconds (the total).
    pub total: Spread,
    /// Timed CPU seconds.
    pub timed_total: Spread,
    /// Medians over the timed runs ([`Run::times`]).
    pub lookup_seconds: f64,
    pub traversal_seconds: f64,
    pub other_tracker_seconds: f64,
    /// Median over the timed runs of the CPU seconds outside the trackers' timed
    /// regions ([`Run::outside_seconds`]).
    pub outside_seconds: f64,
    /// Median load average over the row's runs.
    pub load_average: f64,
}

impl Row {
    /// Timed ÷ untimed total: what the timers add (1 when they distort nothing).
    pub fn timer_overhead(&self) -> f64 {
        self.timed_total.median / self.total.median
    }

    /// The numeric columns of [`Tables::CSV_HEADER`] from `leaves_visited` to
    /// `load_average`.
    fn csv_values(&self) -> [f64; 16] {
        let c = &self.counts;
        [
            c.cells_visited as f64,
            c.density_lookups as f64,
            c.residual_lookups as f64,
            c.control_collisions as f64,
            c.real_collisions as f64,
            c.null_collisions as f64,
            self.lookup_seconds,
            self.traversal_seconds,
            self.other_tracker_seconds,
            self.outside_seconds,
            self.total.median,
            self.total.min,
            self.total.max,
            self.timed_total.median,
            self.timer_overhead(),
            self.load_average,
        ]
    }
}

/// The measured tables.
#[derive(Clone, Debug)]
pub struct Tables {
    pub width: u32,
    pub height: u32,
    pub spp: u32,
    pub seed: u64,
    pub threads: usize,
    pub rounds: u32,
    pub prune: f32,
    pub shadows: Shadows,
    pub calibration: Calibration,
    pub rows: Vec<Row>,
    pub runs: Vec<Run>,
}

impl Tables {
    pub fn row(&self, depth: u32, tracker: TrackerKind) -> Option<&Row> {
        self.rows
            .iter()
            .find(|r| r.depth == depth && r.tracker == tracker)
    }

    /// Decomposition ÷ delta of `value` at `depth`.
    pub fn ratio(&self, depth: u32, value: impl Fn(&Row) -> f64) -> f64 {
        match (
            self.row(depth, TrackerKind::Delta),
            self.row(depth, TrackerKind::Decomposition),
        ) {
            (Some(d), Some(x)) => value(x) / value(d),
            _ => f64::NAN,
        }
    }

    /// The row of `tracker` with the smallest median total.
    pub fn best(&self, tracker: TrackerKind) -> Option<&Row> {
        self.rows
            .iter()
            .filter(|r| r.tracker == tracker)
            .min_by(|a, b| a.total.median.total_cmp(&b.total.median))
    }

    pub const CSV_HEADER: &'static str = "depth,tracker,levels,leaf_edge_voxels,leaves_visited,density_lookups,residual_lookups,control_collisions,real_collisions,null_collisions,lookup_seconds,traversal_seconds,other_tracker_seconds,outside_seconds,total_seconds,total_min,total_max,timed_seconds,timer_overhead,load_average,rounds";

    /// One line per row, then one `decomposition/delta` line per depth with the
    /// ratio of every numeric column.
    pub fn csv(&self) -> String {
        let mut text = String::from(Self::CSV_HEADER);
        text.push('\n');
        let join = |v: &[f64]| {
            v.iter()
                .map(|x| x.to_string())
                .collect::<Vec<_>>()
                .join(",")
        };
        for r in &self.rows {
            text.push_str(&format!(
                "{},{},{},{},{},{}\n",
                r.depth,
                r.tracker.name(),
                r.levels,
                r.leaf_edge[0],
                join(&r.csv_values()),
                self.rounds
            ));
        }
        let mut depths: Vec<u32> = self.rows.iter().map(|r| r.depth).collect();
        depths.dedup();
        for d in depths {
            let (Some(a), Some(b)) = (
                self.row(d, TrackerKind::Delta),
                self.row(d, TrackerKind::Decomposition),
            ) else {
                continue;
            };
            let ratios: Vec<f64> = a
                .csv_values()
                .iter()
                .zip(b.csv_values())
                .map(|(x, y)| y / x)
                .collect();
            text.push_str(&format!(
                "{d},decomposition/delta,,,{},{}\n",
                join(&ratios),
                self.rounds
            ));
        }
        text
    }

    pub const RUNS_CSV_HEADER: &'static str = "round,depth,tracker,timed,cpu_seconds,wall_seconds,load_average,leaves_visited,density_lookups,lookup_seconds,traversal_seconds,other_tracker_seconds,outside_seconds,image_digest";

    /// Every run, in the order they ran.
    pub fn runs_csv(&self) -> String {
        let mut text = String::from(Self::RUNS_CSV_HEADER);
        text.push('\n');
        for r in &self.runs {
            let t = r.times.unwrap_or(TrackerTimes {
                lookup_seconds: f64::NAN,
                traversal_seconds: f64::NAN,
                other_tracker_seconds: f64::NAN,
            });
            text.push_str(&format!(
                "{},{},{},{},{},{},{},{},{},{},{},{},{},{:016x}\n",
                r.round,
                r.depth,
                r.tracker.name(),
                r.timed,
                r.cpu_seconds,
                r.wall_seconds,
                r.load_average,
                r.counts.cells_visited,
                r.counts.density_lookups,
                t.lookup_seconds,
                t.traversal_seconds,
                t.other_tracker_seconds,
                r.outside_seconds.unwrap_or(f64::NAN),
                r.image_digest
            ));
        }
        text
    }
}

/// The 1-minute load average (Linux `/proc/loadavg`), `NaN` where unavailable.
pub fn load_average() -> f64 {
    std::fs::read_to_string("/proc/loadavg")
        .ok()
        .and_then(|s| s.split_whitespace().next()?.parse().ok())
        .unwrap_or(f64::NAN)
}

/// Measures the tables on `session` (opened with the resolution, samples, seed and
/// pruning to use) on `pool`; `on_run` hears of every run as it finishes (progress).
pub fn measure(
    session: &mut Session,
    pool: &rayon::ThreadPool,
    config: &TablesConfig,
    mut on_run: impl FnMut(&Run),
) -> Result<Tables> {
    config.check()?;
    let calibration = Calibration::measure();
    // Every (depth, tracker)'s octree, built once up front (pruning depends on the
    // tracker: decomposition pays for `dmax − dmin`); `current` is the one the session
    // holds, the others wait in `trees`.
    let mut trees: Vec<[Option<Vec<std::sync::Arc<MajorantTree>>>; 2]> = Vec::new();
    for &depth in &config.depths {
        session.spec = MajorantSpec::Octree { depth };
        trees.push(TRACKERS.map(|t| {
            Some(pool.install(|| session.majorants_for(&tracker_settings(t, config.shadows))))
        }));
    }
    let mut current: Option<(usize, usize)> = None;
    let mut runs = Vec::new();
    // Rounds outermost, so a change of the machine's load falls on every row alike;
    // within a round the trackers' order alternates from round to round.
    for round in 0..config.rounds {
        let order: [usize; 2] = if round % 2 == 0 { [0, 1] } else { [1, 0] };
        let timings: &[bool] = if config.timed {
            &[false, true]
        } else {
            &[false]
        };
        for (d, &depth) in config.depths.iter().enumerate() {
            for &timed in timings {
                for &i in &order {
                    if current != Some((d, i)) {
                        let mine = trees[d][i].take().expect("each row's octree");
                        session.spec = MajorantSpec::Octree { depth };
                        let old = session
                            .switch_tracking(tracker_settings(TRACKERS[i], config.shadows), mine);
                        if let Some((cd, ci)) = current {
                            trees[cd][ci] = Some(old);
                        }
                        current = Some((d, i));
                    }
                    let run = render_once(session, pool, &calibration, round, depth, timed);
                    on_run(&run);
                    runs.push(run);
                }
            }
        }
    }
    let mut rows = Vec::new();
    for (d, &depth) in config.depths.iter().enumerate() {
        for (i, &tracker) in TRACKERS.iter().enumerate() {
            let mine: Vec<&Run> = runs
                .iter()
                .filter(|r| r.depth == depth && r.tracker == tracker)
                .collect();
            // The structure this row rendered with: in the session or stashed.
            let media_trees: Vec<&MajorantTree> = match &trees[d][i] {
                Some(t) => t.iter().map(|t| &**t).collect(),
                None => session.media().iter().map(|m| &*m.majorants).collect(),
            };
            rows.push(summarise(depth, tracker, &mine, &media_trees)?);
        }
    }
    Ok(Tables {
        width: session.width,
        height: session.height,
        spp: session.spp,
        seed: session.seed,
        threads: pool.current_num_threads(),
        rounds: config.rounds,
        prune: session.octree_prune(),
        shadows: config.shadows,
        calibration,
        rows,
        runs,
    })
}

/// One render of the session as it stands, timed or not.
fn render_once(
    session: &Session,
    pool: &rayon::ThreadPool,
    calibration: &Calibration,
    round: u32,
    depth: u32,
    timed: bool,
) -> Run {
    let mut job = session.job_with(CodePaths::default());
    job.tracking.profile = timed;
    let load = load_average();
    let (cpu0, wall0) = (process_cpu_seconds(), Instant::now());
    let film = pool.install(|| job.render(&|| {}));
    let (cpu_seconds, wall_seconds) = (process_cpu_seconds() - cpu0, wall0.elapsed().as_secs_f64());
    let (counts, _, _) = film.totals();
    let (times, outside_seconds) = if timed {
        let scale = cpu_seconds / wall_seconds;
        let t = calibration.split(&counts);
        let times = TrackerTimes {
            lookup_seconds: t.lookup_seconds * scale,
            traversal_seconds: t.traversal_seconds * scale,
            other_tracker_seconds: t.other_tracker_seconds * scale,
        };
        let inside = times.lookup_seconds + times.traversal_seconds + times.other_tracker_seconds;
        (Some(times), Some(cpu_seconds - inside))
    } else {
        (None, None)
    };
    Run {
        round,
        depth,
        tracker: job.tracking.tracker,
        timed,
        cpu_seconds,
        wall_seconds,
        load_average: load,
        counts,
        times,
        outside_seconds,
        image_digest: digest(&film),
    }
}

/// FNV-1a over the bits of every pixel's RGBA sums.
fn digest(film: &crate::render::film::Film) -> u64 {
    let mut h = 0xcbf2_9ce4_8422_2325u64;
    for p in &film.pixels {
        for v in [p.rgb[0], p.rgb[1], p.rgb[2], p.alpha] {
            for b in v.to_bits().to_le_bytes() {
                h = (h ^ b as u64).wrapping_mul(0x0100_0000_01b3);
            }
        }
    }
    h
}

/// The counts that must agree between runs of one row.
fn key(c: &Counters) -> [u64; 7] {
    [
        c.density_lookups,
        c.cells_visited,
        c.residual_lookups,
        c.control_collisions,
        c.real_collisions,
        c.null_collisions,
        c.majorant_violations,
    ]
}

fn summarise(
    depth: u32,
    tracker: TrackerKind,
    runs: &[&Run],
    trees: &[&MajorantTree],
) -> Result<Row> {
    let first = runs.first().expect("every row has runs");
    for r in runs {
        if key(&r.counts) != key(&first.counts) || r.image_digest != first.image_digest {
            bail!(
                "internal error: depth {depth} {}: round {} ({}) made other counts or another image than round {} ({})",
                tracker.name(),
                r.round,
                if r.timed { "timed" } else { "untimed" },
                first.round,
                if first.timed { "timed" } else { "untimed" },
            );
        }
    }
    let pick = |timed: bool, f: &dyn Fn(&Run) -> f64| -> Spread {
        let v: Vec<f64> = runs
            .iter()
            .filter(|r| r.timed == timed)
            .map(|r| f(r))
            .collect();
        Spread::of(&v)
    };
    let time = |f: &dyn Fn(&TrackerTimes) -> f64| {
        pick(true, &|r| r.times.as_ref().map_or(f64::NAN, f)).median
    };
    Ok(Row {
        depth,
        tracker,
        levels: trees.iter().map(|t| t.levels()).max().unwrap_or(0),
        leaf_edge: trees.first().map_or([0.0; 3], |t| t.leaf_edge()),
        build_seconds: trees.iter().map(|t| t.build_seconds()).sum(),
        memory_bytes: trees.iter().map(|t| t.memory_bytes()).sum(),
        counts: first.counts,
        total: pick(false, &|r| r.cpu_seconds),
        timed_total: pick(true, &|r| r.cpu_seconds),
        lookup_seconds: time(&|t| t.lookup_seconds),
        traversal_seconds: time(&|t| t.traversal_seconds),
        other_tracker_seconds: time(&|t| t.other_tracker_seconds),
        outside_seconds: pick(true, &|r| r.outside_seconds.unwrap_or(f64::NAN)).median,
        load_average: Spread::of(&runs.iter().map(|r| r.load_average).collect::<Vec<_>>()).median,
    })
}
