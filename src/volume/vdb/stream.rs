//! A bounds-checked little-endian cursor over one grid's bytes, held in memory.
//!
//! The tree reader takes a grid's whole byte range at once (OpenVDB reads every node
//! anyway) and parses it from a slice: every read is checked against the slice, so a
//! length or count that lies can only produce an error, never a panic or a read past
//! the end. Offsets in messages are file offsets, so they can be checked with a hex
//! dump.

pub(crate) struct Stream<'a> {
    data: &'a [u8],
    pos: usize,
    /// File offset of `data[0]`.
    base: u64,
}

impl<'a> Stream<'a> {
    pub fn new(data: &'a [u8], base: u64) -> Self {
        Stream { data, pos: 0, base }
    }

    /// The file offset of the next byte.
    pub fn offset(&self) -> u64 {
        self.base + self.pos as u64
    }

    pub fn remaining(&self) -> usize {
        self.data.len() - self.pos
    }

    /// The next `n` bytes.
    pub fn take(&mut self, n: usize, what: &str) -> Result<&'a [u8], String> {
        if n > self.remaining() {
            return Err(format!(
                "truncated or corrupt: {what} needs {n} bytes at offset {} but the grid's data \
                 ends at offset {}",
                self.offset(),
                self.base + self.data.len() as u64
            ));
        }
        let bytes = &self.data[self.pos..self.pos + n];
        self.pos += n;
        Ok(bytes)
    }

    pub fn array<const N: usize>(&mut self, what: &str) -> Result<[u8; N], String> {
        let mut out = [0u8; N];
        out.copy_from_slice(self.take(N, what)?);
        Ok(out)
    }

    pub fn u8(&mut self, what: &str) -> Result<u8, String> {
        Ok(self.array::<1>(what)?[0])
    }
    pub fn i32(&mut self, what: &str) -> Result<i32, String> {
        Ok(i32::from_le_bytes(self.array(what)?))
    }
    pub fn u32(&mut self, what: &str) -> Result<u32, String> {
        Ok(u32::from_le_bytes(self.array(what)?))
    }
    pub fn i64(&mut self, what: &str) -> Result<i64, String> {
        Ok(i64::from_le_bytes(self.array(what)?))
    }
    pub fn f32(&mut self, what: &str) -> Result<f32, String> {
        Ok(f32::from_le_bytes(self.array(what)?))
    }

    /// `N` consecutive floats: one value of a float (N = 1) or Vec3s (N = 3) grid.
    pub fn value<const N: usize>(&mut self, what: &str) -> Result<[f32; N], String> {
        let mut v = [0.0f32; N];
        for c in v.iter_mut() {
            *c = self.f32(what)?;
        }
        Ok(v)
    }

    pub fn coord(&mut self, what: &str) -> Result<[i32; 3], String> {
        Ok([self.i32(what)?, self.i32(what)?, self.i32(what)?])
    }

    /// A node mask of `words` 64-bit words (OpenVDB's `NodeMask::load`: the words as
    /// stored, little-endian; bit `i` of the node is bit `i % 64` of word `i / 64`).
    pub fn mask(&mut self, words: usize, what: &str) -> Result<Vec<u64>, String> {
        let bytes = self.take(words * 8, what)?;
        Ok(bytes
            .chunks_exact(8)
            .map(|w| u64::from_le_bytes(w.try_into().expect("8-byte chunk")))
            .collect())
    }
}

/// Whether bit `i` of `mask` is set.
pub(crate) fn bit(mask: &[u64], i: usize) -> bool {
    mask[i / 64] >> (i % 64) & 1 != 0
}

pub(crate) fn count_ones(mask: &[u64]) -> usize {
    mask.iter().map(|w| w.count_ones() as usize).sum()
}
