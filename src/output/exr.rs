//! EXR output: one f32 channel per AOV, plus metadata naming the renderer and settings.

use super::{write_atomically, OutputError};
use crate::render::film::{Aov, Film};
use exr::prelude::*;
use std::path::Path;

/// Metadata recorded in the EXR header.
#[derive(Clone, Debug)]
pub struct ExrMetadata {
    pub stage: String,
    pub tracker: String,
    pub scheme: String,
    pub transmittance: String,
    pub spp: u32,
    pub render_seconds: f64,
    /// The time code rendered (NaN: USD's default time).
    pub time: f64,
    /// The RenderProduct prim this image is, if any.
    pub product: Option<String>,
    /// Whether the image is denoised, or is a tile whose merge denoises
    /// (`nimbus:denoise`).
    pub denoise: Denoise,
    /// What a farm's `merge` checks: the seed, the samples per pixel asked for (`None`:
    /// a time limit alone), the session's settings hash, and the tile this image is.
    pub farm: Option<FarmMetadata>,
}

/// Denoising as an EXR header records it: the text attribute `nimbus:denoise`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Denoise {
    /// Not asked for (no attribute).
    #[default]
    Off,
    /// A tile of a frame to denoise: `merge` denoises the merged frame (`merge`).
    ByMerge,
    /// The beauty and split layers are denoised, the noisy beauty is the layer
    /// `noisy` (`denoised`).
    Done,
}

impl Denoise {
    pub fn attribute(self) -> Option<&'static str> {
        match self {
            Denoise::Off => None,
            Denoise::ByMerge => Some("merge"),
            Denoise::Done => Some("denoised"),
        }
    }

    pub fn from_attribute(text: Option<&str>) -> Denoise {
        match text {
            Some("merge") => Denoise::ByMerge,
            Some("denoised") => Denoise::Done,
            _ => Denoise::Off,
        }
    }
}

/// The header attributes of a tile (or of a frame a farm renders).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FarmMetadata {
    pub seed: u64,
    pub spp_cap: Option<u32>,
    pub settings_hash: u64,
    pub tile: Option<crate::render::tiles::Tile>,
}

pub fn write_exr(
    path: &Path,
    film: &Film,
    aovs: &[Aov],
    meta: &ExrMetadata,
) -> std::result::Result<(), OutputError> {
    let channels = aovs
        .iter()
        .map(|&a| (a.channel_name().to_string(), film.channel(a)))
        .collect();
    write_channels(path, film.full, film.region, channels, meta)
}

/// Writes f32 `channels` of the pixels `region` of a `full` frame: the data window is
/// the region, the display window the full frame (a whole frame has them equal).
pub fn write_channels(
    path: &Path,
    full: (u32, u32),
    region: crate::render::film::Region,
    channels: Vec<(String, Vec<f32>)>,
    meta: &ExrMetadata,
) -> std::result::Result<(), OutputError> {
    let size = (region.width() as usize, region.height() as usize);
    let channels: Vec<AnyChannel<FlatSamples>> = channels
        .into_iter()
        .map(|(name, v)| AnyChannel::new(name.as_str(), FlatSamples::F32(finite(v))))
        .collect();
    let mut attrs = LayerAttributes::default();
    attrs.layer_position = Vec2(region.x0 as i32, region.y0 as i32);
    attrs.software_name = Some(Text::from(
        format!("nimbus {}", env!("CARGO_PKG_VERSION")).as_str(),
    ));
    let mut put = |k: &str, v: AttributeValue| {
        attrs.other.insert(Text::from(k), v);
    };
    put(
        "nimbus:stage",
        AttributeValue::Text(Text::from(meta.stage.as_str())),
    );
    let text = |v: &str| AttributeValue::Text(Text::from(v));
    put("nimbus:version", text(env!("CARGO_PKG_VERSION")));
    put("nimbus:tracker", text(&meta.tracker));
    put("nimbus:scheme", text(&meta.scheme));
    put("nimbus:transmittance", text(&meta.transmittance));
    if meta.time.is_finite() {
        put("nimbus:time", AttributeValue::F64(meta.time));
    }
    if let Some(product) = &meta.product {
        put("nimbus:renderProduct", text(product));
    }
    if let Some(d) = meta.denoise.attribute() {
        put("nimbus:denoise", text(d));
    }
    put(
        "nimbus:spp",
        AttributeValue::I32(meta.spp.min(i32::MAX as u32) as i32),
    );
    put(
        "nimbus:renderSeconds",
        AttributeValue::F32(meta.render_seconds as f32),
    );
    if let Some(f) = &meta.farm {
        put("nimbus:seed", text(&f.seed.to_string()));
        put(
            "nimbus:settingsHash",
            text(&format!("{:016x}", f.settings_hash)),
        );
        if let Some(cap) = f.spp_cap {
            put(
                "nimbus:sppCap",
                AttributeValue::I32(cap.min(i32::MAX as u32) as i32),
            );
        }
        if let Some(t) = f.tile {
            put("nimbus:tile", text(&format!("{}/{}", t.index, t.count)));
        }
        put(
            "nimbus:fullResolution",
            AttributeValue::IntVec2(Vec2(full.0 as i32, full.1 as i32)),
        );
    }
    let layer = Layer::new(
        size,
        attrs,
        Encoding::FAST_LOSSLESS,
        AnyChannels::sort(channels.into()),
    );
    let mut image = Image::from_layer(layer);
    image.attributes.display_window =
        IntegerBounds::new((0, 0), (full.0 as usize, full.1 as usize));
    write_atomically(path, |file| {
        image
            .write()
            .to_buffered(std::io::BufWriter::new(file))
            .map_err(|e| format!("EXR encoding failed: {e}"))
    })
}

/// `values` with nothing non-finite: a mean that is finite in f64 can still exceed the
/// f32 range (a light 2^1000 bright), and is stored as ±`f32::MAX` (`render` warns,
/// [`Film::out_of_range`]); NaN, which the film never produces (it drops non-finite
/// samples), would be stored as 0. No written image holds an infinity or a NaN.
fn finite(mut values: Vec<f32>) -> Vec<f32> {
    for v in values.iter_mut().filter(|v| !v.is_finite()) {
        *v = if v.is_nan() {
            0.0
        } else {
            f32::MAX.copysign(*v)
        };
    }
    values
}

/// Bytes of pixels in memory the EXR readers accept (`compare`, `merge`, `info` on a
/// deep file): a header can claim any size, and the allocation of what it claims
/// must be refused with a message, not abort the process.
pub const MAX_READ_BYTES: u64 = 8 << 30;

/// Checks, from its headers alone and before any pixel is allocated, that the EXR at
/// `path` can be read: every part's chunks (each at least an 8-byte offset-table
/// entry and an 8-byte chunk header) fit in the file, and its pixels fit
/// [`MAX_READ_BYTES`] and the memory available. In memory a flat channel sample takes
/// its own size and its f32 copy; a deep pixel its count and a pointer per channel
/// (the samples themselves are checked by the deep reader once the counts are read).
pub fn check_exr_size(path: &Path) -> std::result::Result<(), String> {
    let err = |m: String| format!("{}: {m}", path.display());
    let meta = ::exr::meta::MetaData::read_from_file(path, false)
        .map_err(|e| err(format!("cannot read as EXR: {e}")))?;
    let file_bytes = std::fs::metadata(path)
        .map_err(|e| err(e.to_string()))?
        .len();
    let mut bytes = 0u64;
    for h in meta.headers.iter() {
        let (w, ht) = (h.layer_size.width() as u64, h.layer_size.height() as u64);
        if (h.chunk_count as u64).saturating_mul(16) > file_bytes {
            return Err(err(format!(
                "its header claims {w}x{ht} pixels in {} chunks, more than the {file_bytes}-byte file can hold (truncated or corrupt)",
                h.chunk_count
            )));
        }
        let per_pixel: u64 = h
            .channels
            .list
            .iter()
            .map(|c| match h.deep {
                true => 8,
                false => c.sample_type.bytes_per_sample() as u64 + 4,
            })
            .sum::<u64>()
            + if h.deep { 8 } else { 0 };
        bytes = bytes.saturating_add(w.saturating_mul(ht).saturating_mul(per_pixel));
    }
    let gib = |b: u64| b as f64 / (1u64 << 30) as f64;
    if bytes > MAX_READ_BYTES {
        return Err(err(format!(
            "its headers claim pixels that need {:.1} GiB to read, more than the {} GiB limit",
            gib(bytes),
            MAX_READ_BYTES >> 30
        )));
    }
    if let Some(available) = crate::render::session::available_memory_bytes() {
        if bytes > available {
            return Err(err(format!(
                "its pixels need {:.2} GiB to read, more than the {:.2} GiB this machine has available",
                gib(bytes),
                gib(available)
            )));
        }
    }
    Ok(())
}

/// Reads the named f32/f16 channels of an EXR's first layer (tests and `compare`).
pub fn read_channels(
    path: &Path,
) -> std::result::Result<(usize, usize, Vec<(String, Vec<f32>)>), String> {
    check_exr_size(path)?;
    let image = read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .first_valid_layer()
        .all_attributes()
        .from_file(path)
        .map_err(|e| format!("{}: {e}", path.display()))?;
    let layer = &image.layer_data;
    let (w, h) = (layer.size.width(), layer.size.height());
    let chans = layer
        .channel_data
        .list
        .iter()
        .map(|c| (c.name.to_string(), c.sample_data.values_as_f32().collect()))
        .collect();
    Ok((w, h, chans))
}

/// Reads every f32/f16/u32 channel of every layer (part) of an EXR as f32, for
/// `compare`. Channels of a named layer are returned as `layer.channel`, so an image
/// whose RGBA sits in a layer (`rgba.R`, or a part named `beauty`) is still found.
/// Layers whose size differs from the first layer's are left out (they cannot be
/// compared pixel by pixel with it).
pub fn read_all_channels(path: &Path) -> ChannelsResult {
    check_exr_size(path)?;
    let image = read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .all_layers()
        .all_attributes()
        .from_file(path)
        .map_err(|e| format!("{}: cannot read as EXR: {e}", path.display()))?;
    let Some(first) = image.layer_data.first() else {
        return Err(format!("{}: the EXR has no layers", path.display()));
    };
    let size = first.size;
    let mut chans = Vec::new();
    for layer in image.layer_data.iter().filter(|l| l.size == size) {
        let prefix = layer
            .attributes
            .layer_name
            .as_ref()
            .map(|n| format!("{n}."))
            .unwrap_or_default();
        for c in &layer.channel_data.list {
            chans.push((
                format!("{prefix}{}", c.name),
                c.sample_data.values_as_f32().collect(),
            ));
        }
    }
    Ok((size.width(), size.height(), chans))
}

type ChannelsResult = std::result::Result<(usize, usize, Vec<(String, Vec<f32>)>), String>;

/// The integer attribute `key` (e.g. `nimbus:spp`) of an EXR's first layer or header.
pub fn read_i32_attribute(path: &Path, key: &str) -> std::result::Result<Option<i32>, String> {
    Ok(match read_attribute(path, key)? {
        Some(AttributeValue::I32(i)) => Some(i),
        _ => None,
    })
}

/// The text attribute `key` (e.g. `nimbus:settingsHash`) of an EXR's first layer or
/// header.
pub fn read_text_attribute(path: &Path, key: &str) -> std::result::Result<Option<String>, String> {
    Ok(match read_attribute(path, key)? {
        Some(AttributeValue::Text(t)) => Some(t.to_string()),
        _ => None,
    })
}

/// The attribute `key` of an EXR's first layer, else of its shared header.
fn read_attribute(path: &Path, key: &str) -> std::result::Result<Option<AttributeValue>, String> {
    let meta = ::exr::meta::MetaData::read_from_file(path, false)
        .map_err(|e| format!("{}: {e}", path.display()))?;
    let Some(h) = meta.headers.first() else {
        return Ok(None);
    };
    let key = Text::from(key);
    Ok(h.own_attributes
        .other
        .get(&key)
        .or_else(|| h.shared_attributes.other.get(&key))
        .cloned())
}
