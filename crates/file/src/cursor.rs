//! Bounds-checked reading of a part of a file: [`varint::Reader`] with the container's
//! errors (naming the part and the offset) and the few reads a tile adds (slices, skipping
//! varints, a faster varint for the hot loops).

use crate::error::{corrupt, FormatViolation};
use froctomap_temporal::{varint, TemporalError};

/// Reads values from one part of a file; every read checks the remaining length, so hostile
/// input can only produce an error, never a panic or an out-of-bounds read. Argument orders
/// follow [`varint::Reader`], which does the decoding.
pub(crate) struct Cursor<'a> {
    bytes: &'a [u8],
    pos: usize,
    /// Which part of the file is being read, for error messages.
    part: &'static str,
}

impl<'a> Cursor<'a> {
    /// The part of the file being read, for errors.
    pub(crate) fn part(&self) -> &'static str {
        self.part
    }

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

    fn rest(&self) -> &'a [u8] {
        &self.bytes[self.pos..]
    }

    /// Runs one read of a [`varint::Reader`] over the rest of the part and moves past what
    /// it consumed.
    fn read<T>(
        &mut self,
        read: impl FnOnce(&mut varint::Reader<'a>) -> Result<T, TemporalError>,
    ) -> Result<T, FormatViolation> {
        let mut reader = varint::Reader::new(self.rest());
        let value = read(&mut reader).map_err(|e| self.violation(e))?;
        self.pos += reader.position();
        Ok(value)
    }

    fn violation(&self, error: TemporalError) -> FormatViolation {
        match error {
            TemporalError::LimitExceeded { what, value, limit } => {
                FormatViolation::Limit { what, value, limit }
            }
            other => corrupt(self.part, format!("{other} at offset {}", self.pos)),
        }
    }

    pub(crate) fn take(&mut self, len: usize) -> Result<&'a [u8], FormatViolation> {
        let slice = self.rest().get(..len).ok_or_else(|| {
            corrupt(
                self.part,
                format!(
                    "truncated: {len} bytes needed at offset {}, {} left",
                    self.pos,
                    self.remaining()
                ),
            )
        })?;
        self.pos += len;
        Ok(slice)
    }

    fn array<const N: usize>(&mut self) -> Result<[u8; N], FormatViolation> {
        let part = self.part;
        self.read(|r| r.array::<N>(part))
    }

    pub(crate) fn u8(&mut self) -> Result<u8, FormatViolation> {
        let part = self.part;
        self.read(|r| r.u8(part))
    }

    pub(crate) fn i8(&mut self) -> Result<i8, FormatViolation> {
        self.array().map(i8::from_le_bytes)
    }

    pub(crate) fn u16(&mut self) -> Result<u16, FormatViolation> {
        let part = self.part;
        self.read(|r| r.u16_le(part))
    }

    pub(crate) fn u32(&mut self) -> Result<u32, FormatViolation> {
        self.array().map(u32::from_le_bytes)
    }

    pub(crate) fn u64(&mut self) -> Result<u64, FormatViolation> {
        self.array().map(u64::from_le_bytes)
    }

    pub(crate) fn i64(&mut self) -> Result<i64, FormatViolation> {
        self.array().map(i64::from_le_bytes)
    }

    pub(crate) fn f64(&mut self) -> Result<f64, FormatViolation> {
        let part = self.part;
        self.read(|r| r.f64_le(part))
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
        self.read(varint::Reader::u64)
    }

    /// A varint count of items that each take at least `min_item_bytes`, checked against
    /// `limit` and the bytes left (so no allocation can exceed the input).
    pub(crate) fn count(
        &mut self,
        what: &'static str,
        limit: u64,
        min_item_bytes: usize,
    ) -> Result<usize, FormatViolation> {
        self.read(|r| r.count(what, limit, min_item_bytes))
    }

    /// The checks of [`count`](Self::count) for a count stored as a fixed-width integer.
    pub(crate) fn check_count(
        &self,
        what: &'static str,
        value: u64,
        limit: u64,
        min_item_bytes: usize,
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
