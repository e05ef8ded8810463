//! Bounds-checked little-endian reading of byte slices.

use crate::error::{corrupt, FormatViolation};
use froctomap_temporal::varint;

/// Reads values from a byte slice; every read checks the remaining length, so hostile input
/// can only produce an error, never a panic or an out-of-bounds read.
pub(crate) struct Cursor<'a> {
    bytes: &'a [u8],
    pos: usize,
    /// Which part of the file is being read, for error messages.
    part: &'static str,
}

impl<'a> Cursor<'a> {
    pub(crate) fn new(bytes: &'a [u8], part: &'static str) -> Self {
        Self {
            bytes,
            pos: 0,
            part,
        }
    }

    pub(crate) fn remaining(&self) -> usize {
        self.bytes.len() - self.pos
    }

    pub(crate) fn is_empty(&self) -> bool {
        self.remaining() == 0
    }

    pub(crate) fn take(&mut self, len: usize) -> Result<&'a [u8], FormatViolation> {
        let end = self
            .pos
            .checked_add(len)
            .filter(|&end| end <= self.bytes.len())
            .ok_or_else(|| {
                corrupt(
                    self.part,
                    format!(
                        "truncated: {len} bytes needed at offset {}, {} left",
                        self.pos,
                        self.remaining()
                    ),
                )
            })?;
        let slice = &self.bytes[self.pos..end];
        self.pos = end;
        Ok(slice)
    }

    fn array<const N: usize>(&mut self) -> Result<[u8; N], FormatViolation> {
        let slice = self.take(N)?;
        let mut out = [0u8; N];
        out.copy_from_slice(slice);
        Ok(out)
    }

    pub(crate) fn u8(&mut self) -> Result<u8, FormatViolation> {
        Ok(self.array::<1>()?[0])
    }

    pub(crate) fn u16(&mut self) -> Result<u16, FormatViolation> {
        Ok(u16::from_le_bytes(self.array()?))
    }

    pub(crate) fn i8(&mut self) -> Result<i8, FormatViolation> {
        Ok(i8::from_le_bytes(self.array()?))
    }

    pub(crate) fn u32(&mut self) -> Result<u32, FormatViolation> {
        Ok(u32::from_le_bytes(self.array()?))
    }

    pub(crate) fn u64(&mut self) -> Result<u64, FormatViolation> {
        Ok(u64::from_le_bytes(self.array()?))
    }

    pub(crate) fn i64(&mut self) -> Result<i64, FormatViolation> {
        Ok(i64::from_le_bytes(self.array()?))
    }

    pub(crate) fn f64(&mut self) -> Result<f64, FormatViolation> {
        Ok(f64::from_le_bytes(self.array()?))
    }

    #[inline(always)]
    pub(crate) fn varint(&mut self) -> Result<u64, FormatViolation> {
        // Most values in tile streams fit one byte, nearly all others two: both decoded
        // inline (the hot loops of a retrieval call this per cell and per toggle).
        match self.bytes.get(self.pos..self.pos + 2) {
            Some(&[low, _]) if low < 0x80 => {
                self.pos += 1;
                Ok(u64::from(low))
            }
            Some(&[low, high]) if high < 0x80 && high != 0 => {
                self.pos += 2;
                Ok(u64::from(low & 0x7F) | u64::from(high) << 7)
            }
            _ => self.varint_slow(),
        }
    }

    #[cold]
    #[inline(never)]
    fn varint_slow(&mut self) -> Result<u64, FormatViolation> {
        let (value, used) = varint::read_u64(&self.bytes[self.pos..])
            .map_err(|e| corrupt(self.part, format!("{e} at offset {}", self.pos)))?;
        self.pos += used;
        Ok(value)
    }

    /// Skips `count` varints without decoding them (each ends at a byte below 0x80),
    /// counting ends eight bytes at a time.
    pub(crate) fn skip_varints(&mut self, count: u64) -> Result<(), FormatViolation> {
        const HIGH_BITS: u64 = 0x8080_8080_8080_8080;
        let mut left = count;
        let rest = &self.bytes[self.pos..];
        let mut used = 0usize;
        if left > 0 {
            let mut words = rest.chunks_exact(8);
            for word in words.by_ref() {
                let ends = u64::from(
                    (!u64::from_le_bytes(word.try_into().unwrap_or([0x80; 8])) & HIGH_BITS)
                        .count_ones(),
                );
                if ends >= left {
                    break;
                }
                left -= ends;
                used += 8;
            }
            for (i, &b) in rest[used..].iter().enumerate() {
                if b < 0x80 {
                    left -= 1;
                    if left == 0 {
                        used += i + 1;
                        break;
                    }
                }
            }
        }
        if left > 0 {
            return Err(corrupt(
                self.part,
                format!("truncated: {left} varints missing at offset {}", self.pos),
            ));
        }
        self.pos += used;
        Ok(())
    }

    /// A count of items that each take at least `min_item_bytes`, checked against the bytes
    /// left (so no allocation can exceed the input) and against `limit`.
    pub(crate) fn count(
        &mut self,
        what: &'static str,
        min_item_bytes: usize,
        limit: u64,
    ) -> Result<usize, FormatViolation> {
        let value = self.varint()?;
        self.check_count(what, value, min_item_bytes, limit)
    }

    pub(crate) fn check_count(
        &self,
        what: &'static str,
        value: u64,
        min_item_bytes: usize,
        limit: u64,
    ) -> Result<usize, FormatViolation> {
        if value > limit {
            return Err(FormatViolation::Limit { what, value, limit });
        }
        let fits = (self.remaining() / min_item_bytes.max(1)) as u64;
        if value > fits {
            return Err(corrupt(
                self.part,
                format!(
                    "{what} {value} exceeds what the remaining {} bytes can hold",
                    self.remaining()
                ),
            ));
        }
        usize::try_from(value).map_err(|_| corrupt(self.part, format!("{what} {value} too large")))
    }
}
