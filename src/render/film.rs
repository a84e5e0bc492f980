//! The film: per-pixel accumulators (f64 sums, integer counters) and the AOVs derived
//! from them.

use crate::render::sampler::{pixel_sampler, Sampler};
use crate::volume::counters::Counters;

/// Everything accumulated for one pixel over its samples.
#[derive(Clone, Copy, Debug, Default)]
pub struct Pixel {
    pub rgb: [f64; 3],
    pub alpha: f64,
    /// Σ luminance and Σ luminance², for the per-pixel sample variance.
    pub lum: f64,
    pub lum_sq: f64,
    pub samples: u32,
    /// Samples whose estimate was NaN or infinite: dropped from the sums and counted.
    pub nonfinite: u32,
    pub counters: Counters,
}

/// Rec. 709 luminance.
pub fn luminance(c: [f64; 3]) -> f64 {
    0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]
}

impl Pixel {
    pub fn add_sample(&mut self, rgb: [f64; 3], alpha: f64) {
        self.samples += 1;
        if !(rgb.iter().all(|v| v.is_finite()) && alpha.is_finite()) {
            self.nonfinite += 1;
            return;
        }
        for c in 0..3 {
            self.rgb[c] += rgb[c];
        }
        self.alpha += alpha;
        let l = luminance(rgb);
        self.lum += l;
        self.lum_sq += l * l;
    }

    /// Unbiased sample variance of the per-sample luminance (0 with fewer than 2 samples).
    pub fn luminance_variance(&self) -> f64 {
        let n = (self.samples - self.nonfinite) as f64;
        if n < 2.0 {
            return 0.0;
        }
        ((self.lum_sq - self.lum * self.lum / n) / (n - 1.0)).max(0.0)
    }

    fn per_sample(&self, v: f64) -> f32 {
        if self.samples == 0 {
            0.0
        } else {
            (v / self.samples as f64) as f32
        }
    }
}

/// An AOV: one EXR channel computed from the film.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Aov {
    R,
    G,
    B,
    A,
    /// Mean density lookups per sample.
    Lookups,
    /// Mean lookups made by residual tracking per sample.
    ResidualLookups,
    RealCollisions,
    NullCollisions,
    ControlCollisions,
    /// Mean over samples of the largest channel throughput seen along the path.
    MaxThroughput,
    /// Sample variance of the luminance estimate in this pixel.
    Variance,
}

impl Aov {
    /// Whether this channel reads the per-pixel counters (a render writing none of
    /// them compiles the counting out).
    pub fn uses_counters(self) -> bool {
        !matches!(self, Aov::R | Aov::G | Aov::B | Aov::A | Aov::Variance)
    }

    pub const ALL: [Aov; 11] = [
        Aov::R,
        Aov::G,
        Aov::B,
        Aov::A,
        Aov::Lookups,
        Aov::ResidualLookups,
        Aov::RealCollisions,
        Aov::NullCollisions,
        Aov::ControlCollisions,
        Aov::MaxThroughput,
        Aov::Variance,
    ];
    /// What a render writes unless asked otherwise.
    pub const DEFAULT: [Aov; 5] = [Aov::R, Aov::G, Aov::B, Aov::A, Aov::Lookups];

    /// The EXR channel name, also the RenderVar `sourceName`.
    pub fn channel_name(self) -> &'static str {
        match self {
            Aov::R => "R",
            Aov::G => "G",
            Aov::B => "B",
            Aov::A => "A",
            Aov::Lookups => "lookups",
            Aov::ResidualLookups => "residual_lookups",
            Aov::RealCollisions => "real_collisions",
            Aov::NullCollisions => "null_collisions",
            Aov::ControlCollisions => "control_collisions",
            Aov::MaxThroughput => "max_throughput",
            Aov::Variance => "variance",
        }
    }

    pub fn from_name(name: &str) -> Option<Aov> {
        Aov::ALL.into_iter().find(|a| a.channel_name() == name)
    }

    fn value(self, p: &Pixel) -> f32 {
        match self {
            Aov::R => p.per_sample(p.rgb[0]),
            Aov::G => p.per_sample(p.rgb[1]),
            Aov::B => p.per_sample(p.rgb[2]),
            Aov::A => p.per_sample(p.alpha),
            Aov::Lookups => p.per_sample(p.counters.density_lookups as f64),
            Aov::ResidualLookups => p.per_sample(p.counters.residual_lookups as f64),
            Aov::RealCollisions => p.per_sample(p.counters.real_collisions as f64),
            Aov::NullCollisions => p.per_sample(p.counters.null_collisions as f64),
            Aov::ControlCollisions => p.per_sample(p.counters.control_collisions as f64),
            Aov::MaxThroughput => p.per_sample(p.counters.max_throughput),
            Aov::Variance => p.luminance_variance() as f32,
        }
    }
}

/// A rectangle of pixels of the full image, `x0..x1` × `y0..y1` (y down): the data
/// window of a tile.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Region {
    pub x0: u32,
    pub y0: u32,
    pub x1: u32,
    pub y1: u32,
}

impl Region {
    /// The whole of a `width` × `height` image.
    pub fn full(width: u32, height: u32) -> Region {
        Region {
            x0: 0,
            y0: 0,
            x1: width,
            y1: height,
        }
    }

    pub fn width(&self) -> u32 {
        self.x1 - self.x0
    }

    pub fn height(&self) -> u32 {
        self.y1 - self.y0
    }

    /// Whether the region is non-empty and lies inside a `width` × `height` image.
    pub fn fits(&self, width: u32, height: u32) -> bool {
        self.x0 < self.x1 && self.y0 < self.y1 && self.x1 <= width && self.y1 <= height
    }
}

/// The accumulated pixels of a render: the whole image or a region of it.
pub struct Film {
    /// Width and height of the pixels held (the region's).
    pub width: u32,
    pub height: u32,
    /// Where these pixels lie in the full image (the full image for a whole frame).
    pub region: Region,
    /// The full image's width and height.
    pub full: (u32, u32),
    /// Row-major, y down.
    pub pixels: Vec<Pixel>,
    /// Each pixel's random stream, carried from one pass to the next so a render of N
    /// samples in any number of passes draws exactly the numbers a single pass would
    /// (and so gives the same image bit for bit).
    pub samplers: Vec<Sampler>,
}

impl Film {
    /// An empty film whose pixel streams start where a render with `seed` starts.
    pub fn new(width: u32, height: u32, seed: u64) -> Film {
        Film::of_region(width, height, Region::full(width, height), seed)
    }

    /// An empty film of `region` of a `width` × `height` image. Each pixel's stream is
    /// seeded from its index in the full image, so a region renders exactly the pixels
    /// a whole-frame render gives it, bit for bit.
    pub fn of_region(width: u32, height: u32, region: Region, seed: u64) -> Film {
        let n = region.width() as usize * region.height() as usize;
        let samplers = (region.y0..region.y1)
            .flat_map(|y| (region.x0..region.x1).map(move |x| y as u64 * width as u64 + x as u64))
            .map(|i| pixel_sampler(seed, i))
            .collect();
        Film {
            width: region.width(),
            height: region.height(),
            region,
            full: (width, height),
            pixels: vec![Pixel::default(); n],
            samplers,
        }
    }

    /// Bytes of film memory per pixel (accumulators and random stream).
    pub const BYTES_PER_PIXEL: usize =
        std::mem::size_of::<Pixel>() + std::mem::size_of::<Sampler>();

    pub fn channel(&self, aov: Aov) -> Vec<f32> {
        self.pixels.iter().map(|p| aov.value(p)).collect()
    }

    pub fn totals(&self) -> (Counters, u64, u64) {
        let mut c = Counters::default();
        let (mut samples, mut nonfinite) = (0u64, 0u64);
        for p in &self.pixels {
            c.add(&p.counters);
            samples += p.samples as u64;
            nonfinite += p.nonfinite as u64;
        }
        (c, samples, nonfinite)
    }
}
