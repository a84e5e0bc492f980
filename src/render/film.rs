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
    /// Σ RGB² (per channel): adaptive sampling's error estimate takes each channel's
    /// sample variance ([`crate::render::adaptive`]).
    pub rgb_sq: [f64; 3],
    /// Σ over samples of the single-scattering albedo at the first real scattering
    /// event of the camera path (0 for a sample with none): the denoiser's auxiliary
    /// image ([`Aov::AlbedoR`]).
    pub albedo: [f64; 3],
}

/// Rec. 709 luminance.
pub fn luminance(c: [f64; 3]) -> f64 {
    0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]
}

impl Pixel {
    /// Adds one sample; `false` when it was NaN or infinite (counted, not added).
    pub fn add_sample(&mut self, rgb: [f64; 3], alpha: f64) -> bool {
        self.samples += 1;
        if !(rgb.iter().all(|v| v.is_finite()) && alpha.is_finite()) {
            self.nonfinite += 1;
            return false;
        }
        for c in 0..3 {
            self.rgb[c] += rgb[c];
            self.rgb_sq[c] += rgb[c] * rgb[c];
        }
        self.alpha += alpha;
        let l = luminance(rgb);
        self.lum += l;
        self.lum_sq += l * l;
        true
    }

    /// Unbiased sample variance of the per-sample luminance (0 with fewer than 2 samples).
    pub fn luminance_variance(&self) -> f64 {
        let n = (self.samples - self.nonfinite) as f64;
        if n < 2.0 {
            return 0.0;
        }
        ((self.lum_sq - self.lum * self.lum / n) / (n - 1.0)).max(0.0)
    }

    /// The estimated variance of the pixel's mean in channel `c`: the sample variance
    /// of the finite samples over their count; with fewer than two unknown, said by
    /// the largest float (finite: every AOV is, and the EXR writer would write an
    /// infinity as it).
    pub fn mean_variance(&self, c: usize) -> f32 {
        let n = (self.samples - self.nonfinite) as f64;
        if n < 2.0 {
            return f32::MAX;
        }
        let variance = (self.rgb_sq[c] - self.rgb[c] * self.rgb[c] / n) / (n - 1.0);
        (variance.max(0.0) / n) as f32
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
    /// Samples taken in this pixel (adaptive sampling stops pixels early).
    Samples,
    /// The estimated variance of the pixel's value in each channel: the channel's
    /// sample variance over the sample count (the largest float, meaning unknown, with
    /// fewer than two samples). Denoising reads it ([`crate::output::denoise_mix`]).
    BeautyVarianceR,
    BeautyVarianceG,
    BeautyVarianceB,
    /// Mean over samples of the single-scattering albedo σs/σt (times the albedo
    /// field) at the camera path's first scattering event, 0 where it had none: the
    /// auxiliary image of denoising (docs/sampling.md, "Denoising").
    AlbedoR,
    AlbedoG,
    AlbedoB,
}

impl Aov {
    /// Whether this channel reads the per-pixel counters (a render writing none of
    /// them compiles the counting out).
    pub fn uses_counters(self) -> bool {
        !matches!(
            self,
            Aov::R
                | Aov::G
                | Aov::B
                | Aov::A
                | Aov::Variance
                | Aov::Samples
                | Aov::BeautyVarianceR
                | Aov::BeautyVarianceG
                | Aov::BeautyVarianceB
                | Aov::AlbedoR
                | Aov::AlbedoG
                | Aov::AlbedoB
        )
    }

    pub const ALL: [Aov; 18] = [
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
        Aov::Samples,
        Aov::BeautyVarianceR,
        Aov::BeautyVarianceG,
        Aov::BeautyVarianceB,
        Aov::AlbedoR,
        Aov::AlbedoG,
        Aov::AlbedoB,
    ];
    /// The albedo AOV's channels (`albedo.R`, `.G`, `.B`).
    pub const ALBEDO: [Aov; 3] = [Aov::AlbedoR, Aov::AlbedoG, Aov::AlbedoB];
    /// The beauty variance's channels (`beauty_variance.R`, `.G`, `.B`).
    pub const BEAUTY_VARIANCE: [Aov; 3] = [
        Aov::BeautyVarianceR,
        Aov::BeautyVarianceG,
        Aov::BeautyVarianceB,
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
            Aov::Samples => "samples",
            Aov::BeautyVarianceR => "beauty_variance.R",
            Aov::BeautyVarianceG => "beauty_variance.G",
            Aov::BeautyVarianceB => "beauty_variance.B",
            Aov::AlbedoR => "albedo.R",
            Aov::AlbedoG => "albedo.G",
            Aov::AlbedoB => "albedo.B",
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
            Aov::Samples => p.samples as f32,
            Aov::BeautyVarianceR => p.mean_variance(0),
            Aov::BeautyVarianceG => p.mean_variance(1),
            Aov::BeautyVarianceB => p.mean_variance(2),
            Aov::AlbedoR => p.per_sample(p.albedo[0]),
            Aov::AlbedoG => p.per_sample(p.albedo[1]),
            Aov::AlbedoB => p.per_sample(p.albedo[2]),
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

/// Camera-depth bins of the deep output: `bins` equal slabs of [`z0`, `z1`] (the
/// depth range of the volumes' bounds in front of the camera), then one more for light
/// that reached the camera without a real collision on the camera ray (the environment
/// seen through the volume), placed at `z1`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DepthBins {
    pub z0: f64,
    pub z1: f64,
    pub bins: usize,
}

impl DepthBins {
    /// Accumulators per pixel: the slabs and the no-collision bin.
    pub fn stride(&self) -> usize {
        self.bins + 1
    }

    /// The slab holding camera depth `z` (clamped into the range: a jittered sample's
    /// collision can lie a rounding error outside it); NaN (no collision) is the last
    /// bin.
    #[inline]
    pub fn index(&self, z: f64) -> usize {
        if z.is_nan() {
            return self.bins;
        }
        let f = (z - self.z0) / (self.z1 - self.z0) * self.bins as f64;
        (f.max(0.0) as usize).min(self.bins - 1)
    }

    /// The depth range of bin `i`.
    pub fn slab(&self, i: usize) -> (f64, f64) {
        if i >= self.bins {
            return (self.z1, self.z1);
        }
        let dz = (self.z1 - self.z0) / self.bins as f64;
        (self.z0 + dz * i as f64, self.z0 + dz * (i + 1) as f64)
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
    /// Split layers (light groups, path splits): `layer_count` RGB sums per pixel.
    pub layers: Vec<[f64; 3]>,
    pub layer_count: usize,
    /// Deep output: per pixel, RGB and alpha sums per depth bin of `depth_bins`.
    pub deep: Vec<[f64; 4]>,
    pub depth_bins: Option<DepthBins>,
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
            layers: Vec::new(),
            layer_count: 0,
            deep: Vec::new(),
            depth_bins: None,
        }
    }

    /// Adds `layers` split-layer accumulators and the deep bins `depth` to every pixel.
    pub fn with_extras(mut self, layers: usize, depth: Option<DepthBins>) -> Film {
        let n = self.pixels.len();
        self.layer_count = layers;
        self.layers = vec![[0.0; 3]; n * layers];
        self.depth_bins = depth;
        self.deep = vec![[0.0; 4]; n * depth.map_or(0, |d| d.stride())];
        self
    }

    /// Bytes of film memory per pixel for `layers` split layers and deep `depth` bins.
    pub fn extra_bytes_per_pixel(layers: usize, depth: Option<DepthBins>) -> usize {
        layers * std::mem::size_of::<[f64; 3]>()
            + depth.map_or(0, |d| d.stride() * std::mem::size_of::<[f64; 4]>())
    }

    /// Split layer `i` as three channels (R, G, B), per-sample means like the beauty.
    pub fn layer(&self, i: usize) -> [Vec<f32>; 3] {
        std::array::from_fn(|c| {
            self.pixels
                .iter()
                .enumerate()
                .map(|(p, px)| px.per_sample(self.layers[p * self.layer_count + i][c]))
                .collect()
        })
    }

    /// Pixel `p`'s deep bins as per-sample means: (slab, RGB, alpha) front to back.
    pub fn deep_bins(&self, p: usize) -> Vec<((f64, f64), [f64; 3], f64)> {
        let Some(d) = self.depth_bins else {
            return Vec::new();
        };
        let px = &self.pixels[p];
        let n = px.samples.max(1) as f64;
        self.deep[p * d.stride()..(p + 1) * d.stride()]
            .iter()
            .enumerate()
            .map(|(i, b)| (d.slab(i), [b[0] / n, b[1] / n, b[2] / n], b[3] / n))
            .collect()
    }

    /// Bytes of film memory per pixel (accumulators and random stream).
    pub const BYTES_PER_PIXEL: usize =
        std::mem::size_of::<Pixel>() + std::mem::size_of::<Sampler>();

    pub fn channel(&self, aov: Aov) -> Vec<f32> {
        self.pixels.iter().map(|p| aov.value(p)).collect()
    }

    /// Where the render went out of range, for its warnings: the full-image position
    /// of the first pixel that dropped a non-finite sample, and the number of pixels
    /// whose beauty or alpha mean is finite in f64 but beyond the f32 range (the EXR
    /// writer stores those as ±`f32::MAX`).
    pub fn out_of_range(&self) -> (Option<(u32, u32)>, usize) {
        let at = |i: usize| {
            let w = self.width as usize;
            (
                self.region.x0 + (i % w) as u32,
                self.region.y0 + (i / w) as u32,
            )
        };
        let first_dropped = self.pixels.iter().position(|p| p.nonfinite > 0).map(at);
        let overflowing = self
            .pixels
            .iter()
            .filter(|p| {
                [Aov::R, Aov::G, Aov::B, Aov::A]
                    .iter()
                    .any(|a| !a.value(p).is_finite())
            })
            .count();
        (first_dropped, overflowing)
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
