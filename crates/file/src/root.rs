//! The root of a format 2.0 file ([FORMAT.md §10.2](../../../docs/FORMAT.md)): two
//! checksummed slots after the preamble, one of them current, the other overwritten by the
//! next commit.

use crate::cursor::Cursor;
use crate::error::{corrupt, FormatViolation};
use crate::header::PREAMBLE_LEN;

/// Major version of files with segments (format 2.0).
pub const LIVING_MAJOR_VERSION: u16 = 2;
/// Minor version of format 2 written.
pub const LIVING_MINOR_VERSION: u16 = 0;
/// Bytes of one root slot.
pub const ROOT_SLOT_LEN: usize = 64;
/// Offset of root slot A (slot B follows it).
pub const ROOT_SLOTS_AT: u64 = PREAMBLE_LEN as u64;
/// Offset of a 2.0 file's header sections: after the preamble and both slots.
pub(crate) const LIVING_HEADER_AT: u64 = ROOT_SLOTS_AT + 2 * ROOT_SLOT_LEN as u64;
/// Bytes of a slot before its crc: fields, then reserved zeros.
const SLOT_CRC_AT: usize = ROOT_SLOT_LEN - 4;
const SLOT_FIELDS_LEN: usize = 40;

/// What a commit made durable: the state a reader sees.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Root {
    /// Commit number: the valid slot with the higher one is current.
    pub sequence: u64,
    /// Bytes of the file that are committed; later bytes are ignored (and cut by the next
    /// writer).
    pub committed_len: u64,
    /// End of the base (its footer's last byte + 1); segments follow it.
    pub base_len: u64,
    /// Offset of the newest segment's record, 0 when there is none.
    pub last_segment: u64,
    /// Segments committed.
    pub segment_count: u32,
    /// Samples of the whole series: the base axis and every segment's.
    pub sample_count: u32,
}

impl Root {
    /// The slot's 64 bytes.
    pub(crate) fn encode(&self) -> [u8; ROOT_SLOT_LEN] {
        let mut out = [0u8; ROOT_SLOT_LEN];
        out[0..8].copy_from_slice(&self.sequence.to_le_bytes());
        out[8..16].copy_from_slice(&self.committed_len.to_le_bytes());
        out[16..24].copy_from_slice(&self.base_len.to_le_bytes());
        out[24..32].copy_from_slice(&self.last_segment.to_le_bytes());
        out[32..36].copy_from_slice(&self.segment_count.to_le_bytes());
        out[36..40].copy_from_slice(&self.sample_count.to_le_bytes());
        let crc = crc32c::crc32c(&out[..SLOT_CRC_AT]);
        out[SLOT_CRC_AT..].copy_from_slice(&crc.to_le_bytes());
        out
    }

    /// A slot's root, or `None` when the slot is not valid (never written, torn, damaged).
    fn decode_slot(bytes: &[u8; ROOT_SLOT_LEN]) -> Option<Root> {
        let crc = u32::from_le_bytes(bytes[SLOT_CRC_AT..].try_into().ok()?);
        if crc32c::crc32c(&bytes[..SLOT_CRC_AT]) != crc
            || bytes[SLOT_FIELDS_LEN..SLOT_CRC_AT].iter().any(|&b| b != 0)
        {
            return None;
        }
        let mut c = Cursor::new(&bytes[..SLOT_FIELDS_LEN], "root slot");
        let root = Root {
            sequence: c.u64().ok()?,
            committed_len: c.u64().ok()?,
            base_len: c.u64().ok()?,
            last_segment: c.u64().ok()?,
            segment_count: c.u32().ok()?,
            sample_count: c.u32().ok()?,
        };
        (root.sequence > 0).then_some(root)
    }

    /// The current root of both slots (their 128 bytes): the valid one with the higher
    /// sequence, and which slot it is (0 = A, 1 = B).
    pub(crate) fn current(
        slots: &[u8; 2 * ROOT_SLOT_LEN],
    ) -> Result<(Root, usize), FormatViolation> {
        let mut best: Option<(Root, usize)> = None;
        for (slot, bytes) in slots.chunks_exact(ROOT_SLOT_LEN).enumerate() {
            let Ok(bytes) = <&[u8; ROOT_SLOT_LEN]>::try_from(bytes) else {
                continue;
            };
            if let Some(root) = Self::decode_slot(bytes) {
                if best.is_none_or(|(b, _)| root.sequence > b.sequence) {
                    best = Some((root, slot));
                }
            }
        }
        let (root, slot) =
            best.ok_or(FormatViolation::Checksum("root slots (neither is valid)"))?;
        if root.base_len < LIVING_HEADER_AT || root.committed_len < root.base_len {
            return Err(corrupt(
                "root",
                "committed length before the end of the base",
            ));
        }
        if (root.segment_count == 0) != (root.last_segment == 0) {
            return Err(corrupt("root", "segment count and last segment disagree"));
        }
        if root.segment_count > 0 && root.last_segment < root.base_len {
            return Err(corrupt("root", "last segment inside the base"));
        }
        Ok((root, slot))
    }

    /// Offset of slot `slot` (0 = A, 1 = B).
    pub(crate) fn slot_offset(slot: usize) -> u64 {
        ROOT_SLOTS_AT + (slot.min(1) * ROOT_SLOT_LEN) as u64
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn root(sequence: u64) -> Root {
        Root {
            sequence,
            committed_len: 1000 + sequence,
            base_len: 900,
            last_segment: 950,
            segment_count: 1,
            sample_count: 7,
        }
    }

    fn slots(a: [u8; ROOT_SLOT_LEN], b: [u8; ROOT_SLOT_LEN]) -> [u8; 2 * ROOT_SLOT_LEN] {
        let mut out = [0u8; 2 * ROOT_SLOT_LEN];
        out[..ROOT_SLOT_LEN].copy_from_slice(&a);
        out[ROOT_SLOT_LEN..].copy_from_slice(&b);
        out
    }

    #[test]
    fn the_valid_slot_with_the_higher_sequence_is_current() {
        let (a, b) = (root(3).encode(), root(4).encode());
        assert_eq!(Root::current(&slots(a, b)).unwrap(), (root(4), 1));
        assert_eq!(Root::current(&slots(b, a)).unwrap(), (root(4), 0));
        // A never written (zero) slot is not valid.
        assert_eq!(
            Root::current(&slots(a, [0; ROOT_SLOT_LEN])).unwrap(),
            (root(3), 0)
        );
        // Any damage to the newer slot (a torn write) leaves the older one current.
        for byte in 0..ROOT_SLOT_LEN {
            for bit in 0..8 {
                let mut torn = b;
                torn[byte] ^= 1 << bit;
                assert_eq!(Root::current(&slots(a, torn)).unwrap(), (root(3), 0));
            }
        }
        assert!(matches!(
            Root::current(&slots([0; ROOT_SLOT_LEN], [0xFF; ROOT_SLOT_LEN])),
            Err(FormatViolation::Checksum(_))
        ));
    }
}
