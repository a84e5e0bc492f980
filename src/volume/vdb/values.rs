//! OpenVDB's value arrays: `io::readCompressedValues` and the chunks under it.
//!
//! Every node stores its values as one record: a metadata byte that says which
//! inactive values were left out and how to restore them, those inactive values (at
//! full precision, even in half-float grids), an optional selection mask, and then
//! the stored values as one chunk, raw or compressed (zlib or blosc), as 32-bit or
//! 16-bit floats. The functions here follow OpenVDB's io/Compression.h step by step,
//! because the point is to produce exactly the values OpenVDB produces.

use super::stream::{bit, count_ones, Stream};
use super::validate::{COMPRESS_ACTIVE_MASK, COMPRESS_BLOSC, COMPRESS_ZIP};

/// The per-record metadata byte (OpenVDB's `enum` in io/Compression.h).
const NO_MASK_OR_INACTIVE_VALS: u8 = 0;
const NO_MASK_AND_MINUS_BG: u8 = 1;
const NO_MASK_AND_ONE_INACTIVE_VAL: u8 = 2;
const MASK_AND_NO_INACTIVE_VALS: u8 = 3;
const MASK_AND_ONE_INACTIVE_VAL: u8 = 4;
const MASK_AND_TWO_INACTIVE_VALS: u8 = 5;
const NO_MASK_AND_ALL_VALS: u8 = 6;

/// How a grid's values are stored: what every record of its tree shares.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Storage {
    /// `COMPRESS_*` flags of the grid.
    pub compression: u32,
    /// Values are 16-bit halves (`is_saved_as_half_float`).
    pub half: bool,
}

/// Reads one record of `mask.len() * 64` values of `N` floats each into `dest`
/// (interleaved components), as `io::readCompressedValues` with `valueMask = mask`.
/// Omitted inactive values are restored from `background` as OpenVDB restores them.
pub(crate) fn read_values<const N: usize>(
    s: &mut Stream,
    storage: Storage,
    background: [f32; N],
    mask: &[u64],
    dest: &mut [f32],
) -> Result<(), String> {
    let num = mask.len() * 64;
    debug_assert_eq!(dest.len(), num * N);
    let at = s.offset();
    let metadata = s.u8("node metadata")?;
    if metadata > NO_MASK_AND_ALL_VALS {
        return Err(format!("corrupt: node metadata {metadata} at offset {at}"));
    }
    // The two inactive values a record can restore; OpenVDB's defaults first.
    let minus_bg = background.map(|v| -v);
    let mut inactive0 = match metadata {
        NO_MASK_OR_INACTIVE_VALS => background,
        NO_MASK_AND_MINUS_BG => minus_bg,
        // OpenVDB's default for the others (MASK_AND_NO_INACTIVE_VALS selects between
        // it and the background; the rest overwrite it below).
        _ => minus_bg,
    };
    let mut inactive1 = background;
    if matches!(
        metadata,
        NO_MASK_AND_ONE_INACTIVE_VAL | MASK_AND_ONE_INACTIVE_VAL | MASK_AND_TWO_INACTIVE_VALS
    ) {
        inactive0 = s.value("inactive value")?;
        if metadata == MASK_AND_TWO_INACTIVE_VALS {
            inactive1 = s.value("inactive value")?;
        }
    }
    let selection = if matches!(
        metadata,
        MASK_AND_NO_INACTIVE_VALS | MASK_AND_ONE_INACTIVE_VAL | MASK_AND_TWO_INACTIVE_VALS
    ) {
        Some(s.mask(mask.len(), "selection mask")?)
    } else {
        None
    };
    // With active-mask compression only the active values are stored.
    let stored =
        if storage.compression & COMPRESS_ACTIVE_MASK != 0 && metadata != NO_MASK_AND_ALL_VALS {
            count_ones(mask)
        } else {
            num
        };
    if stored == num {
        return read_floats(s, storage, &mut dest[..]);
    }
    let mut active = vec![0.0f32; stored * N];
    read_floats(s, storage, &mut active)?;
    let mut next = active.chunks_exact(N);
    for (i, out) in dest.chunks_exact_mut(N).enumerate() {
        let v: &[f32] = if bit(mask, i) {
            // `stored` is the mask's popcount, so there is one per active bit.
            next.next().unwrap_or(&background[..])
        } else if selection.as_deref().is_some_and(|m| bit(m, i)) {
            &inactive1[..]
        } else {
            &inactive0[..]
        };
        out.copy_from_slice(v);
    }
    Ok(())
}

/// Reads `dest.len()` floats stored as one chunk (`io::readData`, or `HalfReader` for
/// half-float grids).
fn read_floats(s: &mut Stream, storage: Storage, dest: &mut [f32]) -> Result<(), String> {
    if storage.half {
        // HalfReader returns before reading anything for an empty array: no chunk,
        // not even a size.
        if dest.is_empty() {
            return Ok(());
        }
        let bytes = read_chunk(s, storage.compression, dest.len() * 2)?;
        for (out, h) in dest.iter_mut().zip(bytes.chunks_exact(2)) {
            *out = half_to_f32(u16::from_le_bytes([h[0], h[1]]));
        }
    } else {
        let bytes = read_chunk(s, storage.compression, dest.len() * 4)?;
        for (out, f) in dest.iter_mut().zip(bytes.chunks_exact(4)) {
            *out = f32::from_le_bytes([f[0], f[1], f[2], f[3]]);
        }
    }
    Ok(())
}

/// A 16-bit half as OpenVDB's `half` converts it. The `half` crate gives the same
/// value for every number; only a NaN's payload could differ (its hardware path
/// quiets signalling NaNs), so NaNs are converted by the bit rule OpenVDB's
/// table-driven and portable conversions use: payload shifted, nothing set.
pub(crate) fn half_to_f32(bits: u16) -> f32 {
    let h = half::f16::from_bits(bits);
    if h.is_nan() {
        let sign = (bits as u32 & 0x8000) << 16;
        return f32::from_bits(sign | 0x7f80_0000 | ((bits as u32 & 0x03ff) << 13));
    }
    h.to_f32()
}

/// Reads one chunk that decodes to exactly `nbytes` bytes. Compressed chunks start
/// with their stored size as an `i64`; zero or negative means "stored uncompressed,
/// this many bytes" (OpenVDB falls back to that when compression would not help).
fn read_chunk<'a>(
    s: &mut Stream<'a>,
    compression: u32,
    nbytes: usize,
) -> Result<std::borrow::Cow<'a, [u8]>, String> {
    if compression & (COMPRESS_BLOSC | COMPRESS_ZIP) == 0 {
        return Ok(s.take(nbytes, "values")?.into());
    }
    let at = s.offset();
    let size = s.i64("compressed size")?;
    if size <= 0 {
        if size.unsigned_abs() != nbytes as u64 {
            return Err(format!(
                "corrupt: uncompressed chunk of {} bytes at offset {at} where {nbytes} were expected",
                size.unsigned_abs()
            ));
        }
        return Ok(s.take(nbytes, "values")?.into());
    }
    let size = usize::try_from(size)
        .ok()
        .filter(|&n| n <= s.remaining())
        .ok_or_else(|| {
            format!(
                "truncated or corrupt: compressed chunk at offset {at} claims {size} bytes, \
                 {} remain",
                s.remaining()
            )
        })?;
    let packed = s.take(size, "compressed values")?;
    // OpenVDB tries blosc first when both flags are set.
    let out = if compression & COMPRESS_BLOSC != 0 {
        blosc_decompress(packed, nbytes)
    } else {
        zlib_decompress(packed, nbytes)
    };
    out.map(Into::into)
        .map_err(|e| format!("corrupt: chunk at offset {at}: {e}"))
}

/// Inflates a zlib stream that must decode to exactly `nbytes` bytes (as zlib's
/// `uncompress`, which OpenVDB calls).
fn zlib_decompress(packed: &[u8], nbytes: usize) -> Result<Vec<u8>, String> {
    let mut out = vec![0u8; nbytes];
    let mut z = flate2::Decompress::new(true);
    let status = z
        .decompress(packed, &mut out, flate2::FlushDecompress::Finish)
        .map_err(|e| format!("zlib: {e}"))?;
    if status != flate2::Status::StreamEnd || z.total_out() != nbytes as u64 {
        return Err(format!(
            "zlib data does not decode to the expected {nbytes} bytes"
        ));
    }
    Ok(out)
}

/// Decompresses a blosc chunk (c-blosc 1, as OpenVDB uses it) that must decode to
/// exactly `nbytes` bytes.
fn blosc_decompress(packed: &[u8], nbytes: usize) -> Result<Vec<u8>, String> {
    // c-blosc trusts the sizes in the chunk's 16-byte header, so they must describe
    // exactly this chunk before it is called.
    if packed.len() < 16 {
        return Err(format!(
            "blosc chunk of {} bytes is shorter than its header",
            packed.len()
        ));
    }
    let field =
        |i: usize| u32::from_le_bytes([packed[i], packed[i + 1], packed[i + 2], packed[i + 3]]);
    let (declared, cbytes) = (field(4) as usize, field(12) as usize);
    if declared != nbytes || cbytes != packed.len() {
        return Err(format!(
            "blosc header declares {declared} bytes ({cbytes} compressed); expected {nbytes} \
             ({} compressed)",
            packed.len()
        ));
    }
    let mut checked = 0usize;
    // SAFETY: `packed` is a live slice of `packed.len()` bytes and `checked` a valid
    // out-pointer; blosc_cbuffer_validate reads only the header within that length.
    let valid = unsafe {
        blosc_src::blosc_cbuffer_validate(packed.as_ptr().cast(), packed.len(), &mut checked)
    };
    if valid != 0 || checked != nbytes {
        return Err("invalid blosc header".into());
    }
    if nbytes == 0 {
        return Ok(Vec::new());
    }
    let mut out = vec![0u8; nbytes];
    // SAFETY: the header's sizes were checked against both buffers above; `out` has
    // room for `nbytes` bytes and blosc writes at most `destsize` of them.
    let got = unsafe {
        blosc_src::blosc_decompress_ctx(
            packed.as_ptr().cast(),
            out.as_mut_ptr().cast(),
            out.len(),
            1,
        )
    };
    if got < 0 || got as usize != nbytes {
        let codec = match packed[2] >> 5 {
            0 => "blosclz",
            1 => "lz4",
            2 => "snappy",
            3 => "zlib",
            4 => "zstd",
            _ => "unknown",
        };
        return Err(format!(
            "blosc ({codec}) decompression failed (code {got}; this build's blosc has blosclz and lz4)"
        ));
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn half_conversion_matches_openvdb_bit_rules() {
        assert_eq!(half_to_f32(0x3c00), 1.0);
        assert_eq!(half_to_f32(0xc000), -2.0);
        assert_eq!(half_to_f32(0x0001), 2f32.powi(-24)); // smallest subnormal
        assert_eq!(half_to_f32(0x7bff), 65504.0);
        assert_eq!(half_to_f32(0x8000).to_bits(), 0x8000_0000);
        assert_eq!(half_to_f32(0x7c00), f32::INFINITY);
        // A signalling NaN keeps its payload and stays signalling.
        assert_eq!(half_to_f32(0x7c01).to_bits(), 0x7f80_2000);
        assert_eq!(half_to_f32(0xfe00).to_bits(), 0xffc0_0000);
    }

    fn record(metadata: u8, extra: &[u8], values: &[f32]) -> Vec<u8> {
        let mut b = vec![metadata];
        b.extend_from_slice(extra);
        for v in values {
            b.extend_from_slice(&v.to_le_bytes());
        }
        b
    }

    #[test]
    fn inactive_values_are_restored_as_openvdb_does() {
        let storage = Storage {
            compression: COMPRESS_ACTIVE_MASK,
            half: false,
        };
        // Voxels 0 and 65 active; everything else inactive.
        let mask = [1u64, 2, 0, 0, 0, 0, 0, 0];
        let mut selection = vec![0u8; 64];
        selection[0] = 0b10; // voxel 1 takes the second inactive value
        let bg = [0.5f32];
        let read = |bytes: &[u8]| {
            let mut out = vec![f32::NAN; 512];
            let mut s = Stream::new(bytes, 0);
            read_values::<1>(&mut s, storage, bg, &mask, &mut out).unwrap();
            assert_eq!(s.remaining(), 0);
            out
        };
        let out = read(&record(NO_MASK_OR_INACTIVE_VALS, &[], &[7.0, 8.0]));
        assert_eq!((out[0], out[65], out[1], out[511]), (7.0, 8.0, 0.5, 0.5));
        let out = read(&record(NO_MASK_AND_MINUS_BG, &[], &[7.0, 8.0]));
        assert_eq!((out[0], out[65], out[1]), (7.0, 8.0, -0.5));
        let out = read(&record(
            NO_MASK_AND_ONE_INACTIVE_VAL,
            &3f32.to_le_bytes(),
            &[7.0, 8.0],
        ));
        assert_eq!((out[1], out[64]), (3.0, 3.0));
        let out = read(&record(MASK_AND_NO_INACTIVE_VALS, &selection, &[7.0, 8.0]));
        assert_eq!((out[1], out[2]), (0.5, -0.5));
        let mut extra = 3f32.to_le_bytes().to_vec();
        extra.extend_from_slice(&selection);
        let out = read(&record(MASK_AND_ONE_INACTIVE_VAL, &extra, &[7.0, 8.0]));
        assert_eq!((out[1], out[2]), (0.5, 3.0));
        let mut extra = 3f32.to_le_bytes().to_vec();
        extra.extend_from_slice(&4f32.to_le_bytes());
        extra.extend_from_slice(&selection);
        let out = read(&record(MASK_AND_TWO_INACTIVE_VALS, &extra, &[7.0, 8.0]));
        assert_eq!((out[0], out[1], out[2], out[65]), (7.0, 4.0, 3.0, 8.0));
        let all: Vec<f32> = (0..512).map(|i| i as f32).collect();
        let out = read(&record(NO_MASK_AND_ALL_VALS, &[], &all));
        assert_eq!(out, all);
    }

    #[test]
    fn chunks_raw_negative_zlib_and_errors() {
        let data: Vec<u8> = (0..64u8).collect();
        // Stored uncompressed behind a negative size.
        let mut b = (-64i64).to_le_bytes().to_vec();
        b.extend_from_slice(&data);
        let mut s = Stream::new(&b, 0);
        assert_eq!(
            read_chunk(&mut s, COMPRESS_ZIP, 64).unwrap().as_ref(),
            &data[..]
        );
        // zlib.
        use std::io::Write;
        let mut z = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::default());
        z.write_all(&data).unwrap();
        let packed = z.finish().unwrap();
        let mut b = (packed.len() as i64).to_le_bytes().to_vec();
        b.extend_from_slice(&packed);
        let mut s = Stream::new(&b, 0);
        assert_eq!(
            read_chunk(&mut s, COMPRESS_ZIP, 64).unwrap().as_ref(),
            &data[..]
        );
        // Wrong sizes are errors, never panics.
        let mut s = Stream::new(&b, 0);
        assert!(read_chunk(&mut s, COMPRESS_ZIP, 65).is_err());
        let mut s = Stream::new(&b, 0);
        assert!(read_chunk(&mut s, COMPRESS_BLOSC, 64).is_err());
        let huge = i64::MAX.to_le_bytes();
        let mut s = Stream::new(&huge, 0);
        assert!(read_chunk(&mut s, COMPRESS_ZIP, 64).is_err());
    }
}
