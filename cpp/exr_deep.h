// Deep scanline OpenEXR ↔ plain buffers, with OpenEXR's C++ library (the pure-Rust exr
// crate cannot write deep data). The C++ only moves samples between Rust-owned buffers
// and OpenEXR's frame buffers, in memory: Rust does the file I/O (atomic writes), all
// validation of the image and all interpretation.
#pragma once

#include "rust/cxx.h"

#include <cstdint>

namespace nimbus_exr {

struct DeepBuffers;

// Encodes `image` as a deep scanline EXR (channels Z, ZBack, R, G, B, A, all FLOAT;
// ZIPS compression; its string attributes) and returns the file's bytes. `name` only
// labels error messages. Throws (→ Rust Err) on inconsistent buffers or an attribute
// name OpenEXR already uses.
rust::Vec<uint8_t> encode_deep_scanline(rust::Str name, const DeepBuffers& image);

// Decodes the bytes of a deep scanline EXR: windows, sample counts, the six channels
// above as floats (a missing channel reads as 0; `has_z_back` says whether ZBack was
// there) and the string attributes other than `type` and `name`. Throws (→ Rust Err)
// on anything OpenEXR rejects, on a file without Z, or on implausibly large sizes.
DeepBuffers decode_deep_scanline(rust::Str name, rust::Slice<const uint8_t> bytes);

} // namespace nimbus_exr
