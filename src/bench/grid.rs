//! `nimbus bench grid measure`'s measurements of a VDB grid (issue 17 part 3): load
//! time (VDB → bricks, serial and parallel brick build) and nanoseconds per
//! `Grid::sample_trilinear` lookup against the size of the region the lookups fall in,
//! from cache-resident to the whole grid. The CLI parses the arguments and prints.

use super::stats::median;
use crate::volume::asset::AssetLocation;
use crate::volume::grid::{Grid, BRICK};
use crate::volume::vdb;
use anyhow::{Context, Result};
use std::time::Instant;

/// xorshift64*: the lookups' positions.
#[inline(always)]
fn next(s: &mut u64) -> u64 {
    *s ^= *s >> 12;
    *s ^= *s << 25;
    *s ^= *s >> 27;
    s.wrapping_mul(0x2545_F491_4F6C_DD1D)
}

#[inline(always)]
fn unit(x: u64) -> f32 {
    (x >> 40) as f32 * (1.0 / (1u64 << 24) as f32)
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Mode {
    /// The random position generator alone (its cost is in the other modes too).
    Rng,
    /// Independent lookups: the CPU overlaps their misses (throughput).
    Independent,
    /// Each position depends on the previous lookup's value (latency, as along a
    /// tracked ray).
    Dependent,
}

/// Seconds for `n` lookups at uniform random points of the box `[lo, lo + size)`;
/// returns the sum of the values too (so nothing is optimised away).
pub fn lookup_pass(grid: &Grid, lo: [f32; 3], size: [f32; 3], n: u64, mode: Mode) -> (f64, f64) {
    let mut s = 0x9E37_79B9_7F4A_7C15u64;
    let mut sum = 0f64;
    let start = thread_cpu_seconds();
    for _ in 0..n {
        let p = [
            lo[0] + size[0] * unit(next(&mut s)),
            lo[1] + size[1] * unit(next(&mut s)),
            lo[2] + size[2] * unit(next(&mut s)),
        ];
        match mode {
            Mode::Rng => sum += (p[0] + p[1] + p[2]) as f64,
            Mode::Independent => sum += grid.sample_trilinear(p) as f64,
            Mode::Dependent => {
                let v = grid.sample_trilinear(p);
                s ^= v.to_bits() as u64;
                sum += v as f64;
            }
        }
    }
    (thread_cpu_seconds() - start, std::hint::black_box(sum))
}

/// This thread's CPU time: other programs on a shared machine do not inflate it.
pub fn thread_cpu_seconds() -> f64 {
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: `ts` is a valid, writable timespec.
    let r = unsafe { libc::clock_gettime(libc::CLOCK_THREAD_CPUTIME_ID, &mut ts) };
    if r != 0 {
        return f64::NAN;
    }
    ts.tv_sec as f64 + ts.tv_nsec as f64 * 1e-9
}

/// The process' anonymous memory in transparent huge pages, from
/// /proc/self/smaps_rollup (Linux), in MB.
pub fn huge_pages_mb() -> Option<f64> {
    let text = std::fs::read_to_string("/proc/self/smaps_rollup").ok()?;
    let line = text.lines().find(|l| l.starts_with("AnonHugePages:"))?;
    let kb: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb / 1e3)
}

/// Medians over the rounds of each step of loading a grid, in seconds.
#[derive(Clone, Copy, Debug)]
pub struct LoadTimes {
    /// Validation alone (the Rust header and tree check).
    pub validate: f64,
    /// The whole read: validation + reader → RawGrid.
    pub read: f64,
    /// `Grid::from_raw_serial`.
    pub bricks_serial: f64,
    /// `Grid::from_raw` (rayon).
    pub bricks_parallel: f64,
}

/// Loads grid `name` of `loc` `rounds` (≥ 1) times: validation alone, then the whole
/// read, then the brick build serial and parallel (alternating which goes first).
/// Returns the medians and the grid of the last build.
pub fn measure_load(loc: &AssetLocation, name: &str, rounds: u32) -> Result<(LoadTimes, Grid)> {
    let (mut val, mut read, mut serial, mut parallel) = (vec![], vec![], vec![], vec![]);
    let mut grid = None;
    for r in 0..rounds.max(1) {
        let t = Instant::now();
        vdb::list_grids(loc)?;
        val.push(t.elapsed().as_secs_f64());
        let t = Instant::now();
        let raw = vdb::read_float_grid(loc, name, None)?;
        read.push(t.elapsed().as_secs_f64());
        grid = None;
        for first_serial in [r % 2 == 0, r % 2 != 0] {
            let t = Instant::now();
            let g = if first_serial {
                Grid::from_raw_serial(&raw)
            } else {
                Grid::from_raw(&raw)
            }
            .with_context(|| loc.to_string())?;
            let s = t.elapsed().as_secs_f64();
            if first_serial {
                serial.push(s);
            } else {
                parallel.push(s);
            }
            grid = Some(g);
        }
    }
    let grid = grid.expect("at least one round");
    Ok((
        LoadTimes {
            validate: median(&mut val),
            read: median(&mut read),
            bricks_serial: median(&mut serial),
            bricks_parallel: median(&mut parallel),
        },
        grid,
    ))
}

/// A box of voxels the lookups fall in: its lower corner and size.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LookupBox {
    pub lo: [i32; 3],
    pub size: [i32; 3],
}

impl LookupBox {
    /// Bricks the box touches, and how many of them the grid stores.
    pub fn bricks(&self, grid: &Grid) -> (u64, u64) {
        let (mut total, mut stored) = (0u64, 0u64);
        let (blo, size) = (self.lo, self.size);
        let bhi = [0, 1, 2].map(|i| (blo[i] + size[i] - 1).div_euclid(BRICK));
        let blo_b = blo.map(|c| c.div_euclid(BRICK));
        for z in blo_b[2]..=bhi[2] {
            for y in blo_b[1]..=bhi[1] {
                for x in blo_b[0]..=bhi[0] {
                    total += 1;
                    stored += grid.has_brick([x, y, z]) as u64;
                }
            }
        }
        (total, stored)
    }
}

/// The boxes of edge `sizes` (voxels; 0 = the whole active bounds) around the centre
/// of the grid's active bounds, aligned to bricks; `None` for an empty grid.
pub fn lookup_boxes(grid: &Grid, sizes: &[i32]) -> Option<Vec<LookupBox>> {
    let (lo, hi) = grid.index_bounds?;
    let centre = [0, 1, 2].map(|i| (lo[i] + hi[i]) / 2);
    Some(
        sizes
            .iter()
            .map(|&e| {
                if e == 0 {
                    LookupBox {
                        lo,
                        size: [0, 1, 2].map(|i| hi[i] - lo[i] + 1),
                    }
                } else {
                    // A cube of edge e around the centre, aligned to bricks.
                    let b = [0, 1, 2].map(|i| (centre[i] - e / 2).div_euclid(BRICK) * BRICK);
                    LookupBox {
                        lo: b,
                        size: [e; 3],
                    }
                }
            })
            .collect(),
    )
}

/// The modes of [`measure_lookups`], in the order of its results.
pub const MODES: [Mode; 3] = [Mode::Rng, Mode::Independent, Mode::Dependent];

/// Thread-CPU nanoseconds per lookup in each box, for each of [`MODES`]: the median
/// over `rounds` passes of `lookups` lookups (rounds outermost, then boxes, then modes,
/// so a change of machine load spreads over all of them).
pub fn measure_lookups(
    grid: &Grid,
    boxes: &[LookupBox],
    rounds: u32,
    lookups: u64,
) -> Vec<[f64; 3]> {
    let mut times = vec![vec![Vec::new(); MODES.len()]; boxes.len()];
    for _ in 0..rounds {
        for (bi, b) in boxes.iter().enumerate() {
            let lo = b.lo.map(|c| c as f32);
            // The upper edge stays inside the box: voxel centres lo ..= lo + size - 1.
            let sz = b.size.map(|s| (s - 1).max(0) as f32);
            for (mi, &m) in MODES.iter().enumerate() {
                let (s, _) = lookup_pass(grid, lo, sz, lookups, m);
                times[bi][mi].push(s / lookups as f64 * 1e9);
            }
        }
    }
    times
        .iter_mut()
        .map(|t| [0, 1, 2].map(|mi| median(&mut t[mi])))
        .collect()
}
