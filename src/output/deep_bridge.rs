//! cxx bindings to `cpp/exr_deep.cc` (compiled only with `cfg(nimbus_openexr)`).
//!
//! The C++ side only moves samples between these buffers and OpenEXR, in memory;
//! `output::deep` does the file I/O, checks the buffers' shapes and builds the images.

#[cxx::bridge(namespace = "nimbus_exr")]
pub(crate) mod ffi {
    /// A string header attribute.
    struct DeepAttribute {
        name: String,
        value: String,
    }

    /// A deep scanline image as flat buffers.
    struct DeepBuffers {
        /// OpenEXR's inclusive boxes: min x, min y, max x, max y.
        display_window: [i32; 4],
        data_window: [i32; 4],
        /// Samples per pixel, row-major over the data window.
        counts: Vec<u32>,
        /// Six floats per sample (Z, ZBack, R, G, B, A); all pixels' samples in pixel order.
        samples: Vec<f32>,
        /// On reading: whether the file has a ZBack channel (without it, ZBack = Z).
        has_z_back: bool,
        attributes: Vec<DeepAttribute>,
    }

    unsafe extern "C++" {
        include!("nimbus/cpp/exr_deep.h");

        /// The bytes of a deep scanline EXR of `image`; `name` labels errors.
        fn encode_deep_scanline(name: &str, image: &DeepBuffers) -> Result<Vec<u8>>;
        /// The image in the bytes of a deep scanline EXR; `name` labels errors.
        fn decode_deep_scanline(name: &str, bytes: &[u8]) -> Result<DeepBuffers>;
    }
}
