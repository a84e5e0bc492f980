//! EXR output: one f32 channel per AOV, plus metadata naming the renderer and settings.

use super::{write_atomically, OutputError};
use crate::render::film::{Aov, Film};
use exr::prelude::*;
use std::path::Path;

/// Metadata recorded in the EXR header.
pub struct ExrMetadata {
    pub stage: String,
    pub tracker: String,
    pub spp: u32,
    pub render_seconds: f64,
}

pub fn write_exr(
    path: &Path,
    film: &Film,
    aovs: &[Aov],
    meta: &ExrMetadata,
) -> std::result::Result<(), OutputError> {
    let size = (film.width as usize, film.height as usize);
    let channels: Vec<AnyChannel<FlatSamples>> = aovs
        .iter()
        .map(|&a| AnyChannel::new(a.channel_name(), FlatSamples::F32(film.channel(a))))
        .collect();
    let mut attrs = LayerAttributes::default();
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
    put(
        "nimbus:tracker",
        AttributeValue::Text(Text::from(meta.tracker.as_str())),
    );
    put(
        "nimbus:spp",
        AttributeValue::I32(meta.spp.min(i32::MAX as u32) as i32),
    );
    put(
        "nimbus:renderSeconds",
        AttributeValue::F32(meta.render_seconds as f32),
    );
    let layer = Layer::new(
        size,
        attrs,
        Encoding::FAST_LOSSLESS,
        AnyChannels::sort(channels.into()),
    );
    let image = Image::from_layer(layer);
    write_atomically(path, |file| {
        image
            .write()
            .to_buffered(std::io::BufWriter::new(file))
            .map_err(|e| format!("EXR encoding failed: {e}"))
    })
}

/// Reads the named f32/f16 channels of an EXR's first layer (tests and `compare`).
pub fn read_channels(
    path: &Path,
) -> std::result::Result<(usize, usize, Vec<(String, Vec<f32>)>), String> {
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
