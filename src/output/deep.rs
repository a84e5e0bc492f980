//! Deep images: per pixel, a front-to-back list of depth samples, and their deep
//! scanline OpenEXR files.
//!
//! Conventions (those of OpenEXR's "Interpreting Deep Pixels"):
//! - `Z` is camera-space depth: the distance along the camera's view axis (not along
//!   the ray), so samples of neighbouring pixels at one depth line up in a compositor.
//! - Colour and alpha are premultiplied: a sample's `R, G, B` already include its `A`.
//! - Samples are volumetric: a sample is the slab `[Z, ZBack]` with `ZBack > Z`, except a
//!   sample at one depth (`ZBack = Z`). A pixel's samples are sorted front to back and do
//!   not overlap; a pixel may have no sample at all.
//! - A pixel's flat colour is the front-to-back `over` composite of its samples.
//!
//! The renderer accumulates additive [`DepthBin`]s (what each depth interval adds to the
//! pixel's flat colour); [`deep_samples`] turns them into over-composited samples with
//! the same flat result. Files are written and read by OpenEXR's C++ library through
//! the cxx bridge (`deep_bridge.rs`, `cpp/exr_deep.cc`): the pure-Rust `exr` crate cannot
//! write deep data. Without that library (`NIMBUS_OPENEXR=off`, or not installed),
//! writing and reading deep files are errors.

use super::{write_atomically, OutputError};
use crate::render::film::Region;
use std::cmp::{Ordering, Reverse};
use std::collections::BinaryHeap;
use std::path::Path;

/// One deep sample: a volumetric slab [z, z_back] of camera depth with premultiplied colour and alpha.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DeepSample {
    pub z: f32,
    pub z_back: f32,
    pub rgba: [f32; 4],
}

/// A deep image: the samples of the pixels of `region`, a data window inside the
/// `full` display window.
#[derive(Clone, Debug, PartialEq)]
pub struct DeepImage {
    /// Display window size.
    pub full: (u32, u32),
    /// Data window (x0, y0, x1, y1 exclusive), y down.
    pub region: Region,
    /// Samples per pixel, row-major over the region.
    pub counts: Vec<u32>,
    /// All pixels' samples concatenated in pixel order, each pixel's sorted front to back.
    pub samples: Vec<DeepSample>,
    /// String header attributes (read back sorted by name).
    pub attributes: Vec<(String, String)>,
}

/// An additive depth bin of one pixel: the mean radiance and alpha the pixel's samples put between z and z_back (sums over samples / sample count, as the flat film averages).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct DepthBin {
    pub z: f64,
    pub z_back: f64,
    pub rgb: [f64; 3],
    pub alpha: f64,
}

/// Below this transmittance in front of a bin, the bin joins the sample before it: the
/// front is opaque (or, with noisy alpha estimates, beyond opaque) and the sample's
/// colour, divided by the transmittance, would blow up.
const MIN_TRANSMITTANCE: f64 = 1e-6;

/// Turns a pixel's additive bins (front to back, non-overlapping) into at most `limit` (>= 1) deep samples whose front-to-back `over` composite equals the bins' sums (rgb = Σ rgb, alpha = Σ alpha) within float rounding.
///
/// The samples are appended to `out` (a pixel's count is the growth of `out`); a pixel
/// whose bins add nothing gets none. `limit` 0 is taken as 1. Bins with a non-finite
/// value are skipped, as the flat film drops non-finite samples. Adjacent bins are
/// merged while more than `limit` remain: each time the pair with the smallest summed
/// alpha (ties: smallest summed luminance, then the frontmost pair).
pub fn deep_samples(bins: &[DepthBin], limit: usize, out: &mut Vec<DeepSample>) {
    let mut kept: Vec<DepthBin> = bins.iter().copied().filter(contributes).collect();
    merge_to_limit(&mut kept, limit.max(1));
    over_samples(&kept, out);
}

/// Whether a bin is kept: finite, and adding some colour or alpha.
fn contributes(b: &DepthBin) -> bool {
    let finite = [b.z, b.z_back, b.alpha]
        .iter()
        .chain(&b.rgb)
        .all(|v| v.is_finite());
    finite && (b.alpha != 0.0 || b.rgb.iter().any(|&c| c != 0.0))
}

/// Bin `b` added to `a` (which lies in front of it): sums, spanning both.
fn merged(a: &DepthBin, b: &DepthBin) -> DepthBin {
    DepthBin {
        z: a.z,
        z_back: b.z_back,
        rgb: std::array::from_fn(|c| a.rgb[c] + b.rgb[c]),
        alpha: a.alpha + b.alpha,
    }
}

/// A candidate merge of the adjacent bins `left` and `right` (indices into the bins),
/// valid while both still have the `versions` they had when it was made.
struct Pair {
    alpha: f64,
    luminance: f64,
    left: usize,
    right: usize,
    versions: (u32, u32),
}

impl Pair {
    fn new(bins: &[DepthBin], versions: &[u32], left: usize, right: usize) -> Pair {
        let m = merged(&bins[left], &bins[right]);
        Pair {
            alpha: m.alpha,
            luminance: crate::color::luminance(m.rgb),
            left,
            right,
            versions: (versions[left], versions[right]),
        }
    }

    /// The merge order: smallest alpha, then luminance, then the frontmost (bins keep
    /// their order, so the left index orders pairs front to back).
    fn key_cmp(&self, other: &Pair) -> Ordering {
        self.alpha
            .total_cmp(&other.alpha)
            .then(self.luminance.total_cmp(&other.luminance))
            .then(self.left.cmp(&other.left))
    }
}

impl PartialEq for Pair {
    fn eq(&self, other: &Pair) -> bool {
        self.key_cmp(other) == Ordering::Equal
    }
}
impl Eq for Pair {}
impl PartialOrd for Pair {
    fn partial_cmp(&self, other: &Pair) -> Option<Ordering> {
        Some(self.key_cmp(other))
    }
}
impl Ord for Pair {
    fn cmp(&self, other: &Pair) -> Ordering {
        self.key_cmp(other)
    }
}

/// Merges adjacent bins, the smallest pair first (see [`Pair::key_cmp`]), until at most
/// `limit` remain. A heap of candidate pairs keeps this O(n log n) for pixels with many
/// bins; a pair whose bins changed since it was pushed is stale and skipped, so the
/// result is that of re-scanning all current pairs at every step.
fn merge_to_limit(bins: &mut Vec<DepthBin>, limit: usize) {
    let n = bins.len();
    if n <= limit {
        return;
    }
    let mut next: Vec<usize> = (1..=n).collect(); // n: none
    let mut prev: Vec<Option<usize>> = (0..n).map(|i| i.checked_sub(1)).collect();
    let mut versions = vec![0u32; n];
    let mut alive = vec![true; n];
    let mut heap: BinaryHeap<Reverse<Pair>> = (0..n - 1)
        .map(|i| Reverse(Pair::new(bins, &versions, i, i + 1)))
        .collect();
    let mut count = n;
    while count > limit {
        let Some(Reverse(p)) = heap.pop() else { break };
        let (l, r) = (p.left, p.right);
        if !alive[l] || !alive[r] || (versions[l], versions[r]) != p.versions {
            continue;
        }
        bins[l] = merged(&bins[l], &bins[r]);
        alive[r] = false;
        versions[l] += 1;
        next[l] = next[r];
        if next[l] < n {
            prev[next[l]] = Some(l);
            heap.push(Reverse(Pair::new(bins, &versions, l, next[l])));
        }
        if let Some(before) = prev[l] {
            heap.push(Reverse(Pair::new(bins, &versions, before, l)));
        }
        count -= 1;
    }
    let mut i = 0;
    bins.retain(|_| {
        i += 1;
        alive[i - 1]
    });
}

/// A sample being built: bins joined front to back, with the transmittance a compositor
/// will have in front of it.
struct Slab {
    z: f64,
    z_back: f64,
    /// Σ rgb of its bins.
    rgb: [f64; 3],
    /// 1 − Σ alpha of all bins up to and including its last: the transmittance the
    /// composite should have behind it.
    remaining_behind: f64,
    /// The transmittance in front of it as [`flatten`] computes it from the stored (f32)
    /// alphas of the samples before.
    front: f64,
}

impl Slab {
    /// Its alpha, chosen so that the transmittance behind it is `remaining_behind`
    /// given the actual (rounded) transmittance in front: each sample corrects the
    /// rounding of those before it instead of compounding it.
    fn alpha(&self) -> f32 {
        to_f32((self.front - self.remaining_behind) / self.front)
    }

    /// The transmittance behind it, as [`flatten`] computes it (same operations).
    fn behind(&self) -> f64 {
        self.front * (1.0 - f64::from(self.alpha()))
    }

    fn sample(&self) -> DeepSample {
        let [r, g, b] = self.rgb.map(|c| to_f32(c / self.front));
        DeepSample {
            z: self.z as f32,
            z_back: self.z_back as f32,
            rgba: [r, g, b, self.alpha()],
        }
    }
}

/// Converts additive bins to `over` samples: with T the transmittance in front of a
/// bin (1 − Σ alpha of the bins before), the sample is (rgb / T, alpha / T), which
/// the composite multiplies by T again. Where T ≤ [`MIN_TRANSMITTANCE`] the bin joins
/// the previous sample instead (the first bin always has T = 1).
fn over_samples(bins: &[DepthBin], out: &mut Vec<DeepSample>) {
    let mut remaining = 1.0;
    let mut open: Option<Slab> = None;
    for b in bins {
        remaining -= b.alpha;
        let mut front = 1.0;
        if let Some(s) = &mut open {
            if s.behind() <= MIN_TRANSMITTANCE {
                s.z_back = b.z_back;
                s.rgb = std::array::from_fn(|c| s.rgb[c] + b.rgb[c]);
                s.remaining_behind = remaining;
                continue;
            }
            front = s.behind();
            out.push(s.sample());
        }
        open = Some(Slab {
            z: b.z,
            z_back: b.z_back,
            rgb: b.rgb,
            remaining_behind: remaining,
            front,
        });
    }
    out.extend(open.map(|s| s.sample()));
}

/// `v` as a finite f32: values beyond f32's range (only from absurd inputs) saturate.
fn to_f32(v: f64) -> f32 {
    if v.is_nan() {
        0.0
    } else {
        (v as f32).clamp(-f32::MAX, f32::MAX)
    }
}

/// The samples of each pixel in turn; a malformed image (counts beyond the samples)
/// gives the pixels past the end no samples rather than panicking.
fn pixels(image: &DeepImage) -> impl Iterator<Item = &[DeepSample]> {
    let mut start = 0usize;
    image.counts.iter().map(move |&n| {
        let end = start.saturating_add(n as usize).min(image.samples.len());
        let pixel = &image.samples[start.min(end)..end];
        start = end;
        pixel
    })
}

/// The front-to-back over composite of one pixel's samples (premultiplied RGBA), in
/// f64 from the stored f32 values, as [`deep_samples`] assumes.
fn composite(samples: &[DeepSample]) -> [f64; 4] {
    let mut rgb = [0.0f64; 3];
    let mut transmittance = 1.0f64;
    for s in samples {
        for (c, v) in rgb.iter_mut().enumerate() {
            *v += transmittance * f64::from(s.rgba[c]);
        }
        transmittance *= 1.0 - f64::from(s.rgba[3]);
    }
    [rgb[0], rgb[1], rgb[2], 1.0 - transmittance]
}

/// Per pixel (row-major over the region): the front-to-back `over` composite of its samples.
pub fn flatten(image: &DeepImage) -> Vec<[f32; 4]> {
    pixels(image)
        .map(|p| composite(p).map(|v| v as f32))
        .collect()
}

/// Why `image` cannot be written, if anything: shapes that disagree, a region outside
/// the display window, or an attribute name a deep EXR header cannot take.
fn check_image(image: &DeepImage) -> Result<(), String> {
    let (w, h) = image.full;
    let r = image.region;
    if !r.fits(w, h) || w > i32::MAX as u32 || h > i32::MAX as u32 {
        return Err(format!(
            "the data window {}..{} x {}..{} is empty or outside the {w}x{h} image",
            r.x0, r.x1, r.y0, r.y1
        ));
    }
    let pixels = r.width() as u64 * r.height() as u64;
    if image.counts.len() as u64 != pixels {
        return Err(format!(
            "{} sample counts for {pixels} pixels",
            image.counts.len()
        ));
    }
    let total: u64 = image.counts.iter().map(|&n| u64::from(n)).sum();
    if total != image.samples.len() as u64 {
        return Err(format!(
            "the counts add up to {total} samples but there are {}",
            image.samples.len()
        ));
    }
    let mut names: Vec<&str> = image.attributes.iter().map(|(k, _)| k.as_str()).collect();
    names.sort_unstable();
    if let Some(pair) = names.windows(2).find(|p| p[0] == p[1]) {
        return Err(format!("attribute {} is given twice", pair[0]));
    }
    match names.iter().find(|n| !valid_attribute_name(n)) {
        Some(bad) => Err(format!(
            "attribute name {bad:?} is empty, too long, contains NUL or is one of OpenEXR's own"
        )),
        None => Ok(()),
    }
}

/// Attribute names OpenEXR sets itself in a deep scanline header.
const RESERVED: &[&str] = &[
    "channels",
    "chunkCount",
    "compression",
    "dataWindow",
    "displayWindow",
    "lineOrder",
    "maxSamplesPerPixel",
    "name",
    "pixelAspectRatio",
    "screenWindowCenter",
    "screenWindowWidth",
    "tiles",
    "type",
    "version",
];

fn valid_attribute_name(name: &str) -> bool {
    // OpenEXR names are NUL-terminated and at most 255 bytes (long-name files).
    !name.is_empty() && name.len() <= 255 && !name.contains('\0') && !RESERVED.contains(&name)
}

/// Writes `image` as a deep scanline OpenEXR (channels Z, ZBack, R, G, B, A, all f32;
/// ZIPS compression; data window = the region, display window = the full image; the
/// string attributes). Written to a temporary file beside `path` and renamed into
/// place: on failure nothing is left behind and an existing file is untouched.
pub fn write_deep_exr(path: &Path, image: &DeepImage) -> Result<(), OutputError> {
    let err = |message: String| OutputError::Write {
        path: path.display().to_string(),
        message,
    };
    check_image(image).map_err(err)?;
    let bytes = encode(path, image).map_err(err)?;
    write_atomically(path, |file| {
        std::io::Write::write_all(file, &bytes).map_err(|e| e.to_string())
    })
}

/// Reads a deep scanline OpenEXR. Its display window must start at (0, 0) and hold the
/// data window (as files from [`write_deep_exr`] do); a file without `ZBack` reads
/// with ZBack = Z (point samples), missing colour or alpha channels as 0.
pub fn read_deep_exr(path: &Path) -> Result<DeepImage, OutputError> {
    let err = |message: String| OutputError::Read {
        path: path.display().to_string(),
        message,
    };
    // The header's size is checked before OpenEXR allocates a count and six sample
    // pointers per pixel it claims.
    super::exr::check_exr_size(path).map_err(|message| OutputError::Read {
        path: path.display().to_string(),
        message: message
            .strip_prefix(&format!("{}: ", path.display()))
            .unwrap_or(&message)
            .to_string(),
    })?;
    let bytes = std::fs::read(path).map_err(|e| err(e.to_string()))?;
    decode(path, &bytes).map_err(err)
}

/// Whether `path` is a deep scanline OpenEXR (its first header's `type` is
/// `deepscanline`), from the header only; false for anything unreadable.
pub fn is_deep_exr(path: &Path) -> bool {
    use ::exr::meta::{header::Header, BlockDescription, MetaData};
    MetaData::read_from_file(path, false).is_ok_and(|m| {
        m.headers
            .first()
            .is_some_and(|h: &Header| h.deep && h.blocks == BlockDescription::ScanLines)
    })
}

#[cfg(not(nimbus_openexr))]
const NO_OPENEXR: &str =
    "deep EXR output needs OpenEXR's C++ library; this build has none (NIMBUS_OPENEXR)";

#[cfg(not(nimbus_openexr))]
fn encode(_path: &Path, _image: &DeepImage) -> Result<Vec<u8>, String> {
    Err(NO_OPENEXR.into())
}

#[cfg(not(nimbus_openexr))]
fn decode(_path: &Path, _bytes: &[u8]) -> Result<DeepImage, String> {
    Err(NO_OPENEXR.into())
}

#[cfg(nimbus_openexr)]
fn encode(path: &Path, image: &DeepImage) -> Result<Vec<u8>, String> {
    use super::deep_bridge::ffi;
    let r = image.region;
    let buffers = ffi::DeepBuffers {
        display_window: [0, 0, image.full.0 as i32 - 1, image.full.1 as i32 - 1],
        data_window: [r.x0 as i32, r.y0 as i32, r.x1 as i32 - 1, r.y1 as i32 - 1],
        counts: image.counts.clone(),
        samples: image
            .samples
            .iter()
            .flat_map(|s| [s.z, s.z_back, s.rgba[0], s.rgba[1], s.rgba[2], s.rgba[3]])
            .collect(),
        has_z_back: true,
        attributes: image
            .attributes
            .iter()
            .map(|(name, value)| ffi::DeepAttribute {
                name: name.clone(),
                value: value.clone(),
            })
            .collect(),
    };
    ffi::encode_deep_scanline(&path.display().to_string(), &buffers)
        .map_err(|e| format!("OpenEXR: {e}"))
}

#[cfg(nimbus_openexr)]
fn decode(path: &Path, bytes: &[u8]) -> Result<DeepImage, String> {
    use super::deep_bridge::ffi;
    let b = ffi::decode_deep_scanline(&path.display().to_string(), bytes)
        .map_err(|e| format!("OpenEXR: {e}"))?;
    let (full, region) = windows(b.display_window, b.data_window)?;
    let total: u64 = b.counts.iter().map(|&n| u64::from(n)).sum();
    if b.counts.len() as u64 != region.width() as u64 * region.height() as u64
        || b.samples.len() as u64 != total * 6
    {
        return Err("OpenEXR returned inconsistent deep buffers".into());
    }
    let samples = b
        .samples
        .chunks_exact(6)
        .map(|s| DeepSample {
            z: s[0],
            z_back: if b.has_z_back { s[1] } else { s[0] },
            rgba: [s[2], s[3], s[4], s[5]],
        })
        .collect();
    Ok(DeepImage {
        full,
        region,
        counts: b.counts,
        samples,
        attributes: b
            .attributes
            .into_iter()
            .map(|a| (a.name, a.value))
            .collect(),
    })
}

/// The display size and the data window as a region, from OpenEXR's inclusive boxes;
/// `Err` when they do not fit this crate's model (display at the origin, data inside).
#[cfg_attr(not(nimbus_openexr), allow(dead_code))]
fn windows(display: [i32; 4], data: [i32; 4]) -> Result<((u32, u32), Region), String> {
    let size = |min: i32, max: i32| u32::try_from(i64::from(max) - i64::from(min) + 1).ok();
    let (Some(w), Some(h)) = (size(0, display[2]), size(0, display[3])) else {
        return Err(format!("display window {display:?} is empty"));
    };
    let region = (|| {
        Some(Region {
            x0: u32::try_from(data[0]).ok()?,
            y0: u32::try_from(data[1]).ok()?,
            x1: u32::try_from(i64::from(data[2]) + 1).ok()?,
            y1: u32::try_from(i64::from(data[3]) + 1).ok()?,
        })
    })();
    match region {
        Some(r) if display[0] == 0 && display[1] == 0 && r.fits(w, h) => Ok(((w, h), r)),
        _ => Err(format!(
            "data window {data:?} is not inside a display window {display:?} that starts at (0, 0) (min x, min y, max x, max y)"
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn bin(z: f64, rgb: [f64; 3], alpha: f64) -> DepthBin {
        DepthBin {
            z,
            z_back: z + 1.0,
            rgb,
            alpha,
        }
    }

    fn sums(bins: &[DepthBin]) -> [f64; 4] {
        bins.iter().fold([0.0; 4], |s, b| {
            [
                s[0] + b.rgb[0],
                s[1] + b.rgb[1],
                s[2] + b.rgb[2],
                s[3] + b.alpha,
            ]
        })
    }

    fn one_pixel(samples: Vec<DeepSample>) -> DeepImage {
        DeepImage {
            full: (1, 1),
            region: Region::full(1, 1),
            counts: vec![samples.len() as u32],
            samples,
            attributes: vec![],
        }
    }

    /// The reference of `merge_to_limit`: rescans every adjacent pair at each step.
    fn merge_naive(bins: &mut Vec<DepthBin>, limit: usize) {
        while bins.len() > limit {
            let versions = vec![0; bins.len()];
            let best = (0..bins.len() - 1)
                .map(|i| Pair::new(bins, &versions, i, i + 1))
                .min()
                .unwrap();
            bins[best.left] = merged(&bins[best.left], &bins[best.right]);
            bins.remove(best.right);
        }
    }

    #[test]
    fn an_opaque_front_gets_one_sample_and_what_is_behind_joins_it() {
        let bins = [
            bin(0.0, [0.5, 0.5, 0.5], 1.0),
            bin(1.0, [0.25, 0.0, 0.0], 0.5),
            bin(2.0, [0.0, 0.1, 0.0], -0.25),
        ];
        let mut out = Vec::new();
        deep_samples(&bins, 8, &mut out);
        assert_eq!(out.len(), 1, "{out:?}");
        assert_eq!((out[0].z, out[0].z_back), (0.0, 3.0));
        let flat = flatten(&one_pixel(out));
        let want = sums(&bins);
        for c in 0..4 {
            assert!((f64::from(flat[0][c]) - want[c]).abs() < 1e-6, "{flat:?}");
        }
    }

    #[test]
    fn transparent_bins_become_divided_samples() {
        // T = 1, 0.5: the second sample's colour and alpha are divided by 0.5.
        let bins = [
            bin(0.0, [0.2, 0.2, 0.2], 0.5),
            bin(1.0, [0.1, 0.0, 0.0], 0.25),
        ];
        let mut out = Vec::new();
        deep_samples(&bins, 4, &mut out);
        assert_eq!(out.len(), 2);
        assert_eq!(out[0].rgba, [0.2, 0.2, 0.2, 0.5]);
        assert_eq!(out[1].rgba, [0.2, 0.0, 0.0, 0.5]);
    }

    #[test]
    fn empty_and_zero_bins_give_no_samples() {
        let mut out = vec![];
        deep_samples(&[], 3, &mut out);
        deep_samples(&[bin(0.0, [0.0; 3], 0.0)], 3, &mut out);
        assert!(out.is_empty());
        assert_eq!(flatten(&one_pixel(out)), vec![[0.0; 4]]);
    }

    #[test]
    fn the_smallest_alpha_pair_merges_first_and_ties_go_to_the_front() {
        let mut bins = vec![
            bin(0.0, [0.0; 3], 0.4),
            bin(1.0, [0.0; 3], 0.1),
            bin(2.0, [0.0; 3], 0.1),
            bin(3.0, [0.0; 3], 0.1),
            bin(4.0, [0.0; 3], 0.1),
        ];
        merge_to_limit(&mut bins, 4);
        let z: Vec<_> = bins.iter().map(|b| (b.z, b.z_back)).collect();
        assert_eq!(z, [(0.0, 1.0), (1.0, 3.0), (3.0, 4.0), (4.0, 5.0)]);
    }

    #[test]
    fn a_malformed_image_flattens_without_panicking() {
        let mut image = one_pixel(vec![]);
        image.counts = vec![5, 3];
        assert_eq!(flatten(&image), vec![[0.0; 4]; 2]);
    }

    #[test]
    fn writing_checks_the_shapes_and_attribute_names() {
        let mut image = one_pixel(vec![]);
        image.attributes = vec![("type".into(), "x".into())];
        assert!(check_image(&image).unwrap_err().contains("\"type\""));
        image.attributes = vec![("a".into(), "x".into()), ("a".into(), "y".into())];
        assert!(check_image(&image).unwrap_err().contains("twice"));
        image.attributes.clear();
        image.counts = vec![1];
        assert!(check_image(&image).unwrap_err().contains("add up to 1"));
        image.counts = vec![];
        assert!(check_image(&image).unwrap_err().contains("0 sample counts"));
    }

    /// Random bins of one pixel: front to back, non-overlapping, some zero, some of
    /// zero depth; rgb may be negative and alpha sums may pass 1 or go below 0 (weighted
    /// trackers' estimates do).
    fn random_bins() -> impl Strategy<Value = Vec<DepthBin>> {
        let one = (
            0.0f64..2.0,
            prop_oneof![Just(0.0), 0.0f64..3.0],
            prop::array::uniform3(prop_oneof![Just(0.0), -0.5f64..4.0]),
            prop_oneof![Just(0.0), Just(1.0), -0.2f64..0.7],
        );
        prop::collection::vec(one, 0..60).prop_map(|v| {
            let mut z = 0.5;
            v.into_iter()
                .map(|(gap, depth, rgb, alpha)| {
                    let b = DepthBin {
                        z: z + gap,
                        z_back: z + gap + depth,
                        rgb,
                        alpha,
                    };
                    z = b.z_back;
                    b
                })
                .collect()
        })
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 4000, ..ProptestConfig::default() })]

        /// The samples composite to the bins' sums. Bound: the samples are stored as
        /// f32 (relative rounding 2^-24 ≈ 6e-8 per value) and the composite takes a
        /// few f64 products per sample; as each sample's alpha is chosen against the
        /// transmittance the rounded samples before it leave, rounding does not
        /// compound, so each bin's colour arrives within ~2^-23 of itself. The error is
        /// relative to the channel's Σ|rgb| (negative rgb can cancel the sum itself to 0) and, for
        /// alpha, to 1 + Σ|alpha| (the composite computes alpha as 1 − T).
        /// 1e-5 leaves a wide margin for 60 bins.
        #[test]
        fn flatten_of_deep_samples_is_the_bin_sums(bins in random_bins(), limit in 1usize..40) {
            let mut out = Vec::new();
            deep_samples(&bins, limit, &mut out);
            prop_assert!(out.len() <= limit);
            for s in &out {
                prop_assert!(s.z.is_finite() && s.z_back.is_finite() && s.rgba.iter().all(|v| v.is_finite()), "{s:?}");
                prop_assert!(s.z <= s.z_back, "{s:?}");
            }
            prop_assert!(out.windows(2).all(|w| w[0].z_back <= w[1].z), "not sorted: {out:?}");
            let flat = flatten(&one_pixel(out.clone()))[0];
            let want = sums(&bins);
            for c in 0..4 {
                let abs: f64 = bins.iter().map(|b| if c < 3 { b.rgb[c] } else { b.alpha }.abs()).sum();
                let scale = if c < 3 { abs } else { 1.0 + abs };
                let err = (f64::from(flat[c]) - want[c]).abs();
                prop_assert!(err <= 1e-5 * scale, "channel {c}: {} vs {} (scale {scale}); {out:?}", flat[c], want[c]);
            }
        }

        /// The heap's merges are those of rescanning all pairs each time.
        #[test]
        fn merge_to_limit_equals_the_naive_merge(bins in random_bins(), limit in 1usize..20) {
            let mut fast: Vec<DepthBin> = bins.iter().copied().filter(contributes).collect();
            let mut slow = fast.clone();
            merge_to_limit(&mut fast, limit);
            merge_naive(&mut slow, limit);
            prop_assert_eq!(fast, slow);
        }
    }
}
