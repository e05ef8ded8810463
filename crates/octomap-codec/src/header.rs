//! The text header of `.bt` and `.ot` files, parsed the way upstream OctoMap 1.9.7 parses it.
//!
//! Upstream reads the first line with `getline` and compares it as a *prefix*, then reads
//! whitespace-separated tokens with `operator>>` until the token `data`: keywords may come in
//! any order and on any line, `#`-tokens and unknown keywords skip to the end of their line,
//! CR is whitespace. The body starts right after the newline that ends the `data` line.
//! A `.bt` file without a text header (before OctoMap 1.4) starts with the binary triple
//! `i32 3, f64 resolution, u32 size`.

use crate::error::CodecError;
use crate::kind::FileKind;

/// Tree type this project reads and writes.
pub const OCTREE_ID: &str = "OcTree";

/// Tells the layout from a file's first line; `None` when it is neither (a legacy headerless
/// `.bt` is recognised separately by [`looks_like_legacy_binary`]).
///
/// ```
/// use froctomap_octomap_codec::{detect_kind, FileKind};
/// assert_eq!(detect_kind(b"# Octomap OcTree binary file\n"), Some(FileKind::Binary));
/// assert_eq!(detect_kind(b"# Octomap OcTree file\r\n"), Some(FileKind::Full));
/// assert_eq!(detect_kind(b"P6\n"), None);
/// ```
pub fn detect_kind(bytes: &[u8]) -> Option<FileKind> {
    [FileKind::Binary, FileKind::Full]
        .into_iter()
        .find(|kind| bytes.starts_with(kind.first_line().as_bytes()))
}

/// `true` when the bytes start like a pre-1.4 headerless `.bt` (`i32 3`, positive finite
/// `f64` resolution).
pub fn looks_like_legacy_binary(bytes: &[u8]) -> bool {
    legacy_fields(bytes).is_some_and(|(res, _)| res.is_finite() && res > 0.0)
}

fn legacy_fields(bytes: &[u8]) -> Option<(f64, u32)> {
    let tree_type = i32::from_le_bytes(bytes.get(0..4)?.try_into().ok()?);
    if tree_type != 3 {
        return None;
    }
    let res = f64::from_le_bytes(bytes.get(4..12)?.try_into().ok()?);
    let size = u32::from_le_bytes(bytes.get(12..16)?.try_into().ok()?);
    Some((res, size))
}

/// How the header was written.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum HeaderLayout {
    /// The text header of OctoMap ≥ 1.4.
    Text,
    /// The headerless binary triple of older `.bt` files.
    Legacy,
}

/// A parsed header.
#[derive(Clone, Debug, PartialEq)]
pub struct Header {
    /// `.bt` or `.ot`.
    pub kind: FileKind,
    /// Text or legacy binary header.
    pub layout: HeaderLayout,
    /// The `id` value (`OcTree` for plain occupancy trees; the deprecated `1` is mapped to it).
    pub tree_id: String,
    /// The `size` value: the number of nodes the writer claims. Upstream skips the body when
    /// it is 0 and otherwise only uses it for a consistency check.
    pub declared_size: u32,
    /// Voxel edge length in metres.
    pub resolution: f64,
    /// Offset of the first body byte.
    pub body_offset: usize,
    /// Things upstream would warn about (unknown keywords, deprecated id, legacy header).
    pub warnings: Vec<String>,
}

/// Parses the header of a file of the given layout.
///
/// ```
/// use froctomap_octomap_codec::{parse_header, FileKind};
/// let file = b"# Octomap OcTree binary file\r\n# comment\nres 0.05 id OcTree\nsize 3\ndata\n\x00\x00";
/// let header = parse_header(file, FileKind::Binary)?;
/// assert_eq!((header.resolution, header.declared_size, header.body_offset), (0.05, 3, file.len() - 2));
/// # Ok::<(), froctomap_octomap_codec::CodecError>(())
/// ```
pub fn parse_header(bytes: &[u8], kind: FileKind) -> Result<Header, CodecError> {
    let mut input = Tokens::new(bytes);
    let first_line = input.line();
    if !first_line.starts_with(kind.first_line().as_bytes()) {
        if kind == FileKind::Binary {
            return parse_legacy_header(bytes, first_line);
        }
        return Err(wrong_first_line(kind, first_line));
    }
    let mut id: Option<Vec<u8>> = None;
    let mut size: u32 = 0;
    let mut resolution: f64 = 0.0;
    let mut warnings = Vec::new();
    let mut data_seen = false;
    // Mirrors `while (s.good() && !headerRead) { s >> token; ... }`.
    while !input.at_end && !data_seen {
        let token = input.token();
        match token {
            b"data" => {
                data_seen = true;
                input.skip_line();
            }
            [b'#', ..] => input.skip_line(),
            b"id" => id = Some(input.token().to_vec()),
            b"res" => {
                resolution = input
                    .number()
                    .and_then(|text| text.parse::<f64>().ok())
                    .ok_or_else(|| bad_header(kind, "the `res` value is not a number"))?;
            }
            b"size" => size = parse_size(&mut input, kind)?,
            other => {
                if !other.is_empty() {
                    warnings.push(format!(
                        "unknown header keyword `{}` skipped",
                        String::from_utf8_lossy(other)
                    ));
                }
                input.skip_line();
            }
        }
    }
    if !data_seen {
        return Err(bad_header(kind, "the header ends without a `data` line"));
    }
    let id = match id {
        None => return Err(bad_header(kind, "the header has no `id`")),
        Some(id) if id.is_empty() => return Err(bad_header(kind, "the header has no `id`")),
        Some(id) if id == b"1" => {
            warnings.push("deprecated tree id `1` read as `OcTree`".to_string());
            OCTREE_ID.to_string()
        }
        Some(id) => String::from_utf8_lossy(&id).into_owned(),
    };
    if !(resolution.is_finite() && resolution > 0.0) {
        return Err(bad_header(
            kind,
            &format!("resolution {resolution} is not a positive number"),
        ));
    }
    Ok(Header {
        kind,
        layout: HeaderLayout::Text,
        tree_id: id,
        declared_size: size,
        resolution,
        body_offset: input.pos,
        warnings,
    })
}

fn parse_legacy_header(bytes: &[u8], first_line: &[u8]) -> Result<Header, CodecError> {
    match legacy_fields(bytes) {
        Some((resolution, declared_size)) if resolution.is_finite() && resolution > 0.0 => {
            Ok(Header {
                kind: FileKind::Binary,
                layout: HeaderLayout::Legacy,
                tree_id: OCTREE_ID.to_string(),
                declared_size,
                resolution,
                body_offset: 16,
                warnings: vec!["outdated headerless .bt format (before OctoMap 1.4)".to_string()],
            })
        }
        Some((resolution, _)) => Err(CodecError::BadHeader {
            kind: FileKind::Binary,
            reason: format!("legacy header has resolution {resolution}, which is not positive"),
        }),
        None => Err(wrong_first_line(FileKind::Binary, first_line)),
    }
}

fn wrong_first_line(kind: FileKind, first_line: &[u8]) -> CodecError {
    let other = match kind {
        FileKind::Binary => FileKind::Full,
        FileKind::Full => FileKind::Binary,
    };
    let hint = if first_line.starts_with(other.first_line().as_bytes()) {
        format!(" (this is a .{} file)", other.extension())
    } else {
        String::new()
    };
    let shown: String = String::from_utf8_lossy(first_line)
        .chars()
        .take(60)
        .map(|c| if c.is_control() { '?' } else { c })
        .collect();
    CodecError::WrongFirstLine {
        kind,
        found: shown,
        hint,
    }
}

fn bad_header(kind: FileKind, reason: &str) -> CodecError {
    CodecError::BadHeader {
        kind,
        reason: reason.to_string(),
    }
}

/// `operator>>` into an `unsigned`: optional sign, decimal digits; values beyond `u32` fail.
fn parse_size(input: &mut Tokens<'_>, kind: FileKind) -> Result<u32, CodecError> {
    let text = input
        .integer()
        .ok_or_else(|| bad_header(kind, "the `size` value is not a number"))?;
    let (negative, digits) = match text.strip_prefix('-') {
        Some(rest) => (true, rest),
        None => (false, text.strip_prefix('+').unwrap_or(text)),
    };
    let value: u32 = digits
        .parse()
        .map_err(|_| bad_header(kind, &format!("the `size` value {text} is out of range")))?;
    // Like strtoul, a negative value wraps around.
    Ok(if negative {
        value.wrapping_neg()
    } else {
        value
    })
}

/// A byte cursor with the tokenising behaviour of a C++ `istream`.
struct Tokens<'a> {
    bytes: &'a [u8],
    pos: usize,
    /// Set once a read reached the end of input (`eofbit`).
    at_end: bool,
}

fn is_space(b: u8) -> bool {
    matches!(b, b' ' | b'\t' | b'\n' | b'\r' | 0x0B | 0x0C)
}

impl<'a> Tokens<'a> {
    fn new(bytes: &'a [u8]) -> Self {
        Self {
            bytes,
            pos: 0,
            at_end: false,
        }
    }

    fn peek(&self) -> Option<u8> {
        self.bytes.get(self.pos).copied()
    }

    /// `getline`: everything up to the next newline, which is consumed.
    fn line(&mut self) -> &'a [u8] {
        let rest = self.bytes.get(self.pos..).unwrap_or_default();
        match rest.iter().position(|&b| b == b'\n') {
            Some(n) => {
                self.pos += n + 1;
                &rest[..n]
            }
            None => {
                self.pos = self.bytes.len();
                self.at_end = true;
                rest
            }
        }
    }

    /// Consumes up to and including the next newline.
    fn skip_line(&mut self) {
        self.line();
    }

    fn skip_space(&mut self) {
        while let Some(b) = self.peek() {
            if !is_space(b) {
                return;
            }
            self.pos += 1;
        }
        self.at_end = true;
    }

    /// `s >> std::string`: skips whitespace, then takes non-whitespace bytes.
    fn token(&mut self) -> &'a [u8] {
        self.skip_space();
        self.take_while(|b, _| !is_space(b))
    }

    /// Takes bytes while `accept(byte, taken_so_far)` holds.
    fn take_while(&mut self, mut accept: impl FnMut(u8, &[u8]) -> bool) -> &'a [u8] {
        let start = self.pos;
        while let Some(b) = self.peek() {
            if !accept(b, &self.bytes[start..self.pos]) {
                return &self.bytes[start..self.pos];
            }
            self.pos += 1;
        }
        self.at_end = true;
        &self.bytes[start..self.pos]
    }

    /// The longest prefix that looks like a decimal floating-point number.
    fn number(&mut self) -> Option<&'a str> {
        self.skip_space();
        let text = self.take_while(|b, taken| match b {
            b'0'..=b'9' | b'.' => true,
            b'+' | b'-' => taken.is_empty() || matches!(taken.last(), Some(b'e' | b'E')),
            b'e' | b'E' => !taken.is_empty() && !taken.contains(&b'e') && !taken.contains(&b'E'),
            _ => false,
        });
        std::str::from_utf8(text).ok().filter(|t| !t.is_empty())
    }

    /// The longest prefix that looks like a decimal integer.
    fn integer(&mut self) -> Option<&'a str> {
        self.skip_space();
        let text = self.take_while(|b, taken| match b {
            b'0'..=b'9' => true,
            b'+' | b'-' => taken.is_empty(),
            _ => false,
        });
        std::str::from_utf8(text).ok().filter(|t| !t.is_empty())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keywords_in_any_order_with_crlf_and_comments() {
        let text = b"# Octomap OcTree file with extra words\r\n#c\r\nsize 12\r\nfoo bar\r\nid 1\r\nres 1e-1\r\ndata\r\nBODY";
        let header = parse_header(text, FileKind::Full).unwrap();
        assert_eq!(header.tree_id, "OcTree");
        assert_eq!(header.declared_size, 12);
        assert_eq!(header.resolution, 0.1);
        assert_eq!(&text[header.body_offset..], b"BODY");
        assert_eq!(header.warnings.len(), 2, "{:?}", header.warnings);
    }

    #[test]
    fn missing_parts_are_errors() {
        let cases: [(&[u8], &str); 5] = [
            (b"# Octomap OcTree file\nid OcTree\nres 0.1\n", "data"),
            (b"# Octomap OcTree file\nres 0.1\ndata\n", "id"),
            (
                b"# Octomap OcTree file\nid OcTree\nres -2\ndata\n",
                "resolution",
            ),
            (b"# Octomap OcTree file\nid OcTree\nres x\ndata\n", "res"),
            (
                b"# Octomap OcTree file\nid OcTree\nsize 99999999999\ndata\n",
                "size",
            ),
        ];
        for (text, needle) in cases {
            let err = parse_header(text, FileKind::Full).unwrap_err().to_string();
            assert!(err.contains(needle), "{err}");
        }
    }

    #[test]
    fn wrong_kind_is_named() {
        let err = parse_header(b"# Octomap OcTree binary file\nid OcTree\n", FileKind::Full)
            .unwrap_err()
            .to_string();
        assert!(err.contains("this is a .bt file"), "{err}");
        let err = parse_header(b"# Octomap OcTree file\nid OcTree\n", FileKind::Binary)
            .unwrap_err()
            .to_string();
        assert!(err.contains("this is a .ot file"), "{err}");
    }

    #[test]
    fn legacy_binary_header() {
        let mut bytes = 3i32.to_le_bytes().to_vec();
        bytes.extend(0.2f64.to_le_bytes());
        bytes.extend(5u32.to_le_bytes());
        assert!(looks_like_legacy_binary(&bytes));
        let header = parse_header(&bytes, FileKind::Binary).unwrap();
        assert_eq!(header.layout, HeaderLayout::Legacy);
        assert_eq!(
            (header.resolution, header.declared_size, header.body_offset),
            (0.2, 5, 16)
        );
    }

    #[test]
    fn negative_size_wraps_like_strtoul() {
        let header = parse_header(
            b"# Octomap OcTree file\nid OcTree res 1 size -1 data\n",
            FileKind::Full,
        )
        .unwrap();
        assert_eq!(header.declared_size, u32::MAX);
    }
}
