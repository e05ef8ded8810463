//! The lengths inside an MCAP record checked against its bytes before the `mcap` crate
//! parses it: the crate reserves a string's declared length (a `u32`) before reading it, so
//! a resealed record declaring 0xFFFFFFFF bytes aborted the process on a 4 GiB allocation.
//! Field layouts as the MCAP specification gives them (<https://mcap.dev/spec>).

use mcap::records::op;

/// Walks a record's fields, checking each declared length against the bytes left.
struct Fields<'a> {
    rest: &'a [u8],
}

impl Fields<'_> {
    fn skip(&mut self, n: u64, what: &'static str) -> Result<(), &'static str> {
        let n = usize::try_from(n).map_err(|_| what)?;
        self.rest = self.rest.get(n..).ok_or(what)?;
        Ok(())
    }

    fn u32(&mut self) -> Result<u32, &'static str> {
        let (head, rest) = self
            .rest
            .split_first_chunk::<4>()
            .ok_or("a field is cut off")?;
        self.rest = rest;
        Ok(u32::from_le_bytes(*head))
    }

    fn u64(&mut self) -> Result<u64, &'static str> {
        let (head, rest) = self
            .rest
            .split_first_chunk::<8>()
            .ok_or("a field is cut off")?;
        self.rest = rest;
        Ok(u64::from_le_bytes(*head))
    }

    /// A `u32`-prefixed string.
    fn string(&mut self) -> Result<(), &'static str> {
        let len = self.u32()?;
        self.skip(u64::from(len), "a string runs past its record")
    }

    /// A `u32`-prefixed byte length of pairs of strings.
    fn string_map(&mut self) -> Result<(), &'static str> {
        let len = u64::from(self.u32()?);
        if len > self.rest.len() as u64 {
            return Err("a map runs past its record");
        }
        let end = self.rest.len() as u64 - len;
        while self.rest.len() as u64 > end {
            self.string()?;
            self.string()?;
        }
        Ok(())
    }

    /// A `u32`-prefixed byte length of fixed-size entries.
    fn array(&mut self) -> Result<(), &'static str> {
        let len = self.u32()?;
        self.skip(u64::from(len), "an array runs past its record")
    }
}

/// Checks every length `body`, the body of a record of kind `opcode`, declares: `Err` names
/// the first one that does not fit. Other problems are left to the `mcap` crate's parser.
pub(crate) fn check(opcode: u8, body: &[u8]) -> Result<(), &'static str> {
    let mut f = Fields { rest: body };
    match opcode {
        op::HEADER => {
            f.string()?;
            f.string()
        }
        op::SCHEMA => {
            f.skip(2, "a field is cut off")?;
            f.string()?;
            f.string()?;
            f.array()
        }
        op::CHANNEL => {
            f.skip(4, "a field is cut off")?;
            f.string()?;
            f.string()?;
            f.string_map()
        }
        op::CHUNK => {
            f.skip(28, "a field is cut off")?;
            f.string()?;
            let len = f.u64()?;
            f.skip(len, "the chunk's records run past it")
        }
        op::MESSAGE_INDEX => {
            f.skip(2, "a field is cut off")?;
            f.array()
        }
        op::CHUNK_INDEX => {
            f.skip(32, "a field is cut off")?;
            f.array()?;
            f.skip(8, "a field is cut off")?;
            f.string()
        }
        op::ATTACHMENT => {
            f.skip(16, "a field is cut off")?;
            f.string()?;
            f.string()?;
            let len = f.u64()?;
            f.skip(len, "the attachment's data runs past it")
        }
        op::ATTACHMENT_INDEX => {
            f.skip(40, "a field is cut off")?;
            f.string()?;
            f.string()
        }
        op::STATISTICS => {
            f.skip(8 + 2 + 16 + 16, "a field is cut off")?;
            f.array()
        }
        op::METADATA => {
            f.string()?;
            f.string_map()
        }
        op::METADATA_INDEX => {
            f.skip(16, "a field is cut off")?;
            f.string()
        }
        _ => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn string(s: &[u8]) -> Vec<u8> {
        let mut out = (s.len() as u32).to_le_bytes().to_vec();
        out.extend_from_slice(s);
        out
    }

    #[test]
    fn declared_lengths_past_the_record_are_refused_before_parsing() {
        // A schema: id, name, encoding, data.
        let mut schema = 1u16.to_le_bytes().to_vec();
        schema.extend(string(b"octomap_msgs/msg/Octomap"));
        schema.extend(string(b"ros2msg"));
        schema.extend(string(b"uint8[] data"));
        assert_eq!(check(op::SCHEMA, &schema), Ok(()));
        assert!(mcap::parse_record(op::SCHEMA, &schema).is_ok());
        // The name's length made 0xFFFFFFFF: refused here, where the crate would reserve it.
        let mut hostile = schema.clone();
        hostile[2..6].copy_from_slice(&u32::MAX.to_le_bytes());
        assert_eq!(
            check(op::SCHEMA, &hostile),
            Err("a string runs past its record")
        );
        // A channel whose metadata map overruns.
        let mut channel = 1u16.to_le_bytes().to_vec();
        channel.extend(1u16.to_le_bytes());
        channel.extend(string(b"/octomap"));
        channel.extend(string(b"cdr"));
        channel.extend(u32::MAX.to_le_bytes());
        assert_eq!(
            check(op::CHANNEL, &channel),
            Err("a map runs past its record")
        );
    }
}
