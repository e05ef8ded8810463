//! LEB128 variable-length unsigned integers, the integer encoding of every froctomap stream.
//!
//! A value is written 7 bits at a time, least significant group first; the high bit of each
//! byte says that another byte follows. Values below 128 take one byte, below 16384 two bytes.
//! Only the *shortest* encoding is accepted when reading, so every value has exactly one
//! encoding (a reader can compare encoded bytes for equality, and fuzzed input cannot smuggle
//! redundant bytes). A `u64` takes at most [`MAX_LEN_U64`] bytes.
//!
//! ```
//! use froctomap_temporal::varint;
//! let mut out = Vec::new();
//! varint::write_u64(&mut out, 300);
//! assert_eq!(out, [0xAC, 0x02]);
//! assert_eq!(varint::encoded_len(300), 2);
//! assert_eq!(varint::read_u64(&out)?, (300, 2));
//! assert!(varint::read_u64(&[0x80]).is_err()); // truncated
//! # Ok::<(), froctomap_temporal::TemporalError>(())
//! ```

use crate::TemporalError;

/// Most bytes a `u64` can take.
pub const MAX_LEN_U64: usize = 10;

/// Appends `value` to `out`.
pub fn write_u64(out: &mut Vec<u8>, mut value: u64) {
    while value >= 0x80 {
        out.push((value as u8) | 0x80);
        value >>= 7;
    }
    out.push(value as u8);
}

/// Appends a `u32` (same encoding as [`write_u64`]).
pub fn write_u32(out: &mut Vec<u8>, value: u32) {
    write_u64(out, u64::from(value));
}

/// Number of bytes [`write_u64`] produces for `value`.
pub const fn encoded_len(value: u64) -> usize {
    let bits = 64 - (value | 1).leading_zeros() as usize;
    bits.div_ceil(7)
}

/// Reads one value from the start of `bytes`: the value and the number of bytes it took.
///
/// Fails on truncation, on values beyond `u64`, and on non-shortest encodings.
pub fn read_u64(bytes: &[u8]) -> Result<(u64, usize), TemporalError> {
    let mut value = 0u64;
    for (i, &byte) in bytes.iter().enumerate().take(MAX_LEN_U64) {
        let group = u64::from(byte & 0x7F);
        let shift = 7 * i as u32;
        if i == MAX_LEN_U64 - 1 && group > 1 {
            return Err(TemporalError::Malformed("varint (exceeds 64 bits)"));
        }
        value |= group << shift;
        if byte & 0x80 == 0 {
            if byte == 0 && i > 0 {
                return Err(TemporalError::Malformed("varint (not shortest encoding)"));
            }
            return Ok((value, i + 1));
        }
    }
    if bytes.len() >= MAX_LEN_U64 {
        Err(TemporalError::Malformed("varint (exceeds 64 bits)"))
    } else {
        Err(TemporalError::Truncated("varint"))
    }
}

/// Reads one value that must fit a `u32`.
pub fn read_u32(bytes: &[u8]) -> Result<(u32, usize), TemporalError> {
    let (value, len) = read_u64(bytes)?;
    let value =
        u32::try_from(value).map_err(|_| TemporalError::Malformed("varint (exceeds 32 bits)"))?;
    Ok((value, len))
}

/// A cursor over a byte slice for sequential decoding; every read is bounds-checked.
#[derive(Debug, Clone)]
pub struct Reader<'a> {
    bytes: &'a [u8],
    pos: usize,
}

impl<'a> Reader<'a> {
    /// A reader at the start of `bytes`.
    pub fn new(bytes: &'a [u8]) -> Self {
        Self { bytes, pos: 0 }
    }

    /// Bytes consumed so far.
    pub fn position(&self) -> usize {
        self.pos
    }

    /// Bytes not yet consumed.
    pub fn remaining(&self) -> usize {
        self.bytes.len().saturating_sub(self.pos)
    }

    fn rest(&self) -> &'a [u8] {
        self.bytes.get(self.pos..).unwrap_or(&[])
    }

    /// Reads a varint.
    pub fn u64(&mut self) -> Result<u64, TemporalError> {
        let (value, len) = read_u64(self.rest())?;
        self.pos += len;
        Ok(value)
    }

    /// Reads a varint that must fit a `u32`.
    pub fn u32(&mut self) -> Result<u32, TemporalError> {
        let (value, len) = read_u32(self.rest())?;
        self.pos += len;
        Ok(value)
    }

    /// Reads a varint count and checks it against `limit` and against the bytes left, given
    /// that each counted item takes at least `min_item_bytes` bytes. This bounds allocations by
    /// the input size, so a hostile count cannot make the decoder reserve huge buffers.
    pub fn count(
        &mut self,
        what: &'static str,
        limit: u64,
        min_item_bytes: usize,
    ) -> Result<usize, TemporalError> {
        let value = self.u64()?;
        if value > limit {
            return Err(TemporalError::LimitExceeded { what, value, limit });
        }
        let needed = u128::from(value) * min_item_bytes as u128;
        if needed > self.remaining() as u128 {
            return Err(TemporalError::Truncated(what));
        }
        usize::try_from(value).map_err(|_| TemporalError::LimitExceeded {
            what,
            value,
            limit: usize::MAX as u64,
        })
    }

    /// Reads `N` raw bytes.
    pub fn array<const N: usize>(&mut self, what: &'static str) -> Result<[u8; N], TemporalError> {
        let end = self
            .pos
            .checked_add(N)
            .ok_or(TemporalError::Truncated(what))?;
        let slice = self
            .bytes
            .get(self.pos..end)
            .ok_or(TemporalError::Truncated(what))?;
        let mut out = [0u8; N];
        out.copy_from_slice(slice);
        self.pos = end;
        Ok(out)
    }

    /// Reads a little-endian `u16`.
    pub fn u16_le(&mut self, what: &'static str) -> Result<u16, TemporalError> {
        self.array::<2>(what).map(u16::from_le_bytes)
    }

    /// Reads one byte.
    pub fn u8(&mut self, what: &'static str) -> Result<u8, TemporalError> {
        self.array::<1>(what).map(|[b]| b)
    }

    /// Reads a little-endian IEEE `f64`.
    pub fn f64_le(&mut self, what: &'static str) -> Result<f64, TemporalError> {
        self.array::<8>(what).map(f64::from_le_bytes)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        #[test]
        fn round_trip(value: u64) {
            let mut out = Vec::new();
            write_u64(&mut out, value);
            prop_assert_eq!(out.len(), encoded_len(value));
            prop_assert_eq!(read_u64(&out)?, (value, out.len()));
            // Every strict prefix is truncated, never a different value.
            for cut in 0..out.len() {
                prop_assert_eq!(read_u64(&out[..cut]), Err(TemporalError::Truncated("varint")));
            }
        }

        #[test]
        fn arbitrary_bytes_never_panic(bytes: Vec<u8>) {
            if let Ok((value, len)) = read_u64(&bytes) {
                let mut out = Vec::new();
                write_u64(&mut out, value);
                prop_assert_eq!(&out[..], &bytes[..len]);
            }
        }
    }

    #[test]
    fn rejects_overlong_and_oversized() {
        assert!(read_u64(&[0x80, 0x00]).is_err());
        let mut max = Vec::new();
        write_u64(&mut max, u64::MAX);
        assert_eq!(max.len(), MAX_LEN_U64);
        assert_eq!(read_u64(&max), Ok((u64::MAX, 10)));
        let mut too_big = max.clone();
        too_big[9] = 0x02;
        assert!(read_u64(&too_big).is_err());
        assert!(read_u64(&[0xFF; 11]).is_err());
        assert!(read_u32(&[0x80, 0x80, 0x80, 0x80, 0x10]).is_err());
        assert_eq!(read_u32(&[0xFF, 0xFF, 0xFF, 0xFF, 0x0F]), Ok((u32::MAX, 5)));
    }

    #[test]
    fn reader_count_is_bounded_by_input() {
        let mut bytes = Vec::new();
        write_u64(&mut bytes, 1_000_000);
        bytes.extend([0u8; 10]);
        let mut r = Reader::new(&bytes);
        assert_eq!(
            r.count("items", u64::MAX, 1),
            Err(TemporalError::Truncated("items"))
        );
        let mut r = Reader::new(&bytes);
        assert!(matches!(
            r.count("items", 10, 1),
            Err(TemporalError::LimitExceeded { .. })
        ));
    }
}
