//! Preamble, header sections and the time axis ([FORMAT.md §2–4](../../../docs/FORMAT.md)).

use crate::cursor::Cursor;
use crate::error::{corrupt, FormatViolation, HeaderError};
use crate::layout::{Codec, TileLayout};
use crate::limits::ReadLimits;
use crate::toggle_lists::ToggleLayout;
use froctomap_core::{validate_resolution, Timestamp, TREE_DEPTH};
use froctomap_temporal::{varint, AxisKind, ModelId, TimeAxis};
use serde_json::{Map, Value};

/// First eight bytes of every file.
pub const MAGIC: [u8; 8] = *b"\x89FROCT\r\n";
/// Last eight bytes of every file.
pub const END_MAGIC: [u8; 8] = *b"FROCTEND";
/// Major version written and understood.
pub const MAJOR_VERSION: u16 = 1;
/// Minor version written by default (range-coded toggle blocks).
pub const MINOR_VERSION: u16 = 2;
/// Bytes before the header sections.
pub const PREAMBLE_LEN: usize = 16;

pub(crate) const TAG_MAP: u16 = 1;
pub(crate) const TAG_TIME_AXIS: u16 = 2;
pub(crate) const TAG_MODEL: u16 = 3;
pub(crate) const TAG_CODEC: u16 = 4;
pub(crate) const TAG_METADATA: u16 = 5;
pub(crate) const TAG_TOGGLE_BLOCKS: u16 = 6;
pub(crate) const TAG_TOGGLE_CODE: u16 = 7;
/// The `TOGGLE_CODE` value of FORMAT.md §5.5's range coding.
const TOGGLE_CODE_RANGE: u8 = 1;
const FLAG_CRITICAL: u16 = 1;

/// Everything a reader needs before touching a tile.
#[derive(Clone, Debug, PartialEq)]
pub struct Header {
    /// Voxel edge length in metres.
    pub resolution: f64,
    /// Depth of the octree nodes that group cells into tiles (1..=16).
    pub tile_depth: u8,
    /// The sample instants of the series.
    pub axis: TimeAxis,
    /// The temporal model of every modelled cell.
    pub model_id: ModelId,
    /// The model's global parameters (`PreparedModel::encode_parameters`).
    pub model_parameters: Vec<u8>,
    /// How tiles are stored.
    pub codec: Codec,
    /// Free-form JSON metadata (creator, sources, tags).
    pub metadata: Map<String, Value>,
    /// How tiles store toggle lists: [`ToggleLayout::Blocked`] needs version 1.1,
    /// [`ToggleLayout::Coded`] 1.2.
    pub toggles: ToggleLayout,
    /// (major, minor) version of the file this header was read from; a writer writes the
    /// lowest version that expresses the file ([`Header::required_version`]).
    pub version: (u16, u16),
}

impl Header {
    /// A header for a new file, with the current version and empty metadata.
    pub fn new(
        resolution: f64,
        tile_depth: u8,
        axis: TimeAxis,
        model_id: ModelId,
        model_parameters: Vec<u8>,
        codec: Codec,
    ) -> Self {
        Self {
            resolution,
            tile_depth,
            axis,
            model_id,
            model_parameters,
            codec,
            metadata: Map::new(),
            toggles: ToggleLayout::DEFAULT,
            version: (MAJOR_VERSION, MINOR_VERSION),
        }
    }

    /// The version a writer puts in the preamble: 1.2 for range-coded toggle blocks, 1.1
    /// for blocked toggle lists, else 1.0.
    pub fn required_version(&self) -> (u16, u16) {
        match self.toggles {
            ToggleLayout::Whole => (MAJOR_VERSION, 0),
            ToggleLayout::Blocked(_) => (MAJOR_VERSION, 1),
            ToggleLayout::Coded(_) => (MAJOR_VERSION, 2),
        }
    }

    /// What a tile encoder and decoder need of the header.
    pub fn tile_layout(&self) -> TileLayout {
        TileLayout {
            tile_depth: self.tile_depth,
            codec: self.codec,
            toggles: self.toggles,
        }
    }

    /// Checks the values a writer must not put in a file.
    pub fn validate(&self) -> Result<(), HeaderError> {
        validate_resolution(self.resolution).map_err(HeaderError::Resolution)?;
        if !(1..=TREE_DEPTH).contains(&self.tile_depth) {
            return Err(HeaderError::TileDepth(self.tile_depth));
        }
        if self.toggles.block_len() == Some(0) {
            return Err(HeaderError::EmptyToggleBlocks);
        }
        Ok(())
    }

    /// Preamble, sections and header crc: the bytes a file starts with.
    pub fn encode(&self) -> Vec<u8> {
        self.encode_as(self.required_version())
    }

    /// [`encode`](Self::encode) with another version in the preamble (format 2.0 keeps the
    /// sections of 1.x).
    pub(crate) fn encode_as(&self, (major, minor): (u16, u16)) -> Vec<u8> {
        let mut sections = Vec::new();
        let mut map = Vec::new();
        map.extend(self.resolution.to_le_bytes());
        map.push(TREE_DEPTH);
        map.push(self.tile_depth);
        push_section(&mut sections, TAG_MAP, true, &map);
        push_section(&mut sections, TAG_TIME_AXIS, true, &encode_axis(&self.axis));
        let mut model = self.model_id.0.to_le_bytes().to_vec();
        varint::write_u64(&mut model, self.model_parameters.len() as u64);
        model.extend(&self.model_parameters);
        push_section(&mut sections, TAG_MODEL, true, &model);
        let codec = match self.codec {
            Codec::Raw => [0, 0],
            Codec::Zstd { level } => [1, level.to_le_bytes()[0]],
        };
        push_section(&mut sections, TAG_CODEC, true, &codec);
        if let Some(len) = self.toggles.block_len() {
            push_section(&mut sections, TAG_TOGGLE_BLOCKS, true, &len.to_le_bytes());
        }
        if let ToggleLayout::Coded(_) = self.toggles {
            push_section(&mut sections, TAG_TOGGLE_CODE, true, &[TOGGLE_CODE_RANGE]);
        }
        if !self.metadata.is_empty() {
            let json = Value::Object(self.metadata.clone()).to_string();
            push_section(&mut sections, TAG_METADATA, false, json.as_bytes());
        }
        let mut out = Vec::with_capacity(PREAMBLE_LEN + sections.len() + 4);
        out.extend(MAGIC);
        out.extend(major.to_le_bytes());
        out.extend(minor.to_le_bytes());
        out.extend((sections.len() as u32).to_le_bytes());
        out.extend(sections);
        let crc = crc32c::crc32c(&out);
        out.extend(crc.to_le_bytes());
        out
    }

    /// Reads the preamble: checks magic and that the major version is `major`, and returns
    /// the version and the header section length.
    pub(crate) fn decode_preamble(
        preamble: &[u8; PREAMBLE_LEN],
        limits: &ReadLimits,
        supported: u16,
    ) -> Result<((u16, u16), usize), FormatViolation> {
        if preamble[..8] != MAGIC {
            return Err(corrupt(
                "preamble",
                "not a FROctomap file (the first bytes are not the FROctomap magic)",
            ));
        }
        let mut cursor = Cursor::new(&preamble[8..], "preamble");
        let major = cursor.u16()?;
        let minor = cursor.u16()?;
        if major != supported {
            return Err(FormatViolation::UnsupportedVersion {
                major,
                minor,
                supported,
            });
        }
        let len = u64::from(cursor.u32()?);
        if len > limits.max_header_bytes {
            return Err(FormatViolation::Limit {
                what: "header length",
                value: len,
                limit: limits.max_header_bytes,
            });
        }
        Ok(((major, minor), len as usize))
    }

    /// Decodes the header of a file of major version `supported` from the preamble, the
    /// sections and the header crc.
    pub(crate) fn decode(
        preamble: &[u8; PREAMBLE_LEN],
        sections_and_crc: &[u8],
        limits: &ReadLimits,
        supported: u16,
    ) -> Result<Header, FormatViolation> {
        let (version, len) = Self::decode_preamble(preamble, limits, supported)?;
        let sections = checked_sections(preamble, sections_and_crc, len)?;
        HeaderSections::read(sections, limits)?.into_header(version, limits)
    }
}

/// The header's sections (after the preamble) once the header crc, which covers the
/// preamble too, matched; `len` is the sections' length the preamble announced.
fn checked_sections<'a>(
    preamble: &[u8; PREAMBLE_LEN],
    sections_and_crc: &'a [u8],
    len: usize,
) -> Result<&'a [u8], FormatViolation> {
    if sections_and_crc.len() != len + 4 {
        return Err(corrupt("header", "truncated"));
    }
    let (sections, crc) = sections_and_crc.split_at(len);
    let mut hasher_input = preamble.to_vec();
    hasher_input.extend_from_slice(sections);
    let expected = u32::from_le_bytes([crc[0], crc[1], crc[2], crc[3]]);
    if crc32c::crc32c(&hasher_input) != expected {
        return Err(FormatViolation::Checksum("header"));
    }
    Ok(sections)
}

/// The header sections met so far, each at most once; required ones are checked at the end.
#[derive(Default)]
struct HeaderSections {
    map: Option<(f64, u8)>,
    axis: Option<TimeAxis>,
    model: Option<(ModelId, Vec<u8>)>,
    codec: Option<Codec>,
    toggle_blocks: Option<u32>,
    toggle_code: Option<u8>,
    metadata: Map<String, Value>,
}

impl HeaderSections {
    /// Reads every section of `sections`, checking each payload is used up exactly.
    fn read(sections: &[u8], limits: &ReadLimits) -> Result<Self, FormatViolation> {
        let mut found = Self::default();
        for section in Sections::new(sections, "header") {
            let section = section?;
            let mut c = Cursor::new(section.payload, "header section");
            match section.tag {
                TAG_MAP => set_once(&mut found.map, decode_map(&mut c)?, "MAP")?,
                TAG_TIME_AXIS => {
                    set_once(&mut found.axis, decode_axis(&mut c, limits)?, "TIME_AXIS")?;
                }
                TAG_MODEL => set_once(&mut found.model, decode_model(&mut c, limits)?, "MODEL")?,
                TAG_CODEC => set_once(&mut found.codec, decode_codec(&mut c)?, "CODEC")?,
                TAG_TOGGLE_BLOCKS => set_once(
                    &mut found.toggle_blocks,
                    decode_toggle_blocks(&mut c)?,
                    "TOGGLE_BLOCKS",
                )?,
                TAG_TOGGLE_CODE => set_once(
                    &mut found.toggle_code,
                    decode_toggle_code(&mut c)?,
                    "TOGGLE_CODE",
                )?,
                TAG_METADATA => {
                    found.metadata = match serde_json::from_slice(section.payload) {
                        Ok(Value::Object(object)) => object,
                        _ => return Err(corrupt("METADATA section", "not a JSON object")),
                    };
                    continue;
                }
                _ => continue, // unknown non-critical sections are skipped by Sections
            }
            if !c.is_empty() {
                return Err(corrupt(
                    "header",
                    format!("section {} has {} extra bytes", section.tag, c.remaining()),
                ));
            }
        }
        Ok(found)
    }

    /// The header of file version `version`, once the required sections are there and
    /// the toggle layout is consistent and within `limits`.
    fn into_header(
        self,
        version: (u16, u16),
        limits: &ReadLimits,
    ) -> Result<Header, FormatViolation> {
        let missing = |name: &str| corrupt("header", format!("required section {name} is missing"));
        let (resolution, tile_depth) = self.map.ok_or_else(|| missing("MAP"))?;
        let (model_id, model_parameters) = self.model.ok_or_else(|| missing("MODEL"))?;
        let axis = self.axis.ok_or_else(|| missing("TIME_AXIS"))?;
        let toggles = match (self.toggle_blocks, self.toggle_code) {
            (None, None) => ToggleLayout::Whole,
            (Some(len), None) => ToggleLayout::Blocked(len),
            (Some(len), Some(_)) => ToggleLayout::Coded(len),
            (None, Some(_)) => {
                return Err(corrupt(
                    "header",
                    "TOGGLE_CODE section without TOGGLE_BLOCKS",
                ))
            }
        };
        // Tiles keep a few values per toggle block: bound them before any tile is read.
        let blocks = u64::from(toggles.blocks(axis.len()));
        if blocks > limits.max_toggle_blocks {
            return Err(FormatViolation::Limit {
                what: "toggle blocks",
                value: blocks,
                limit: limits.max_toggle_blocks,
            });
        }
        Ok(Header {
            resolution,
            tile_depth,
            axis,
            model_id,
            model_parameters,
            codec: self.codec.ok_or_else(|| missing("CODEC"))?,
            metadata: self.metadata,
            toggles,
            version,
        })
    }
}

/// The MAP section: resolution and tile depth (the tree depth is OctoMap's 16).
fn decode_map(c: &mut Cursor<'_>) -> Result<(f64, u8), FormatViolation> {
    let resolution = c.f64()?;
    validate_resolution(resolution).map_err(|e| corrupt("MAP section", e.to_string()))?;
    let tree_depth = c.u8()?;
    if tree_depth != TREE_DEPTH {
        return Err(FormatViolation::UnsupportedFeature(format!(
            "tree depth {tree_depth} (only 16 exists in OctoMap)"
        )));
    }
    let tile_depth = c.u8()?;
    if !(1..=TREE_DEPTH).contains(&tile_depth) {
        return Err(corrupt("MAP section", format!("tile depth {tile_depth}")));
    }
    Ok((resolution, tile_depth))
}

/// The MODEL section: the model's id and its parameters, within `limits`.
fn decode_model(
    c: &mut Cursor<'_>,
    limits: &ReadLimits,
) -> Result<(ModelId, Vec<u8>), FormatViolation> {
    let id = ModelId(c.u16()?);
    let n = c.count(
        "model parameter length",
        limits.max_model_parameter_bytes,
        1,
    )?;
    Ok((id, c.take(n)?.to_vec()))
}

/// The CODEC section.
fn decode_codec(c: &mut Cursor<'_>) -> Result<Codec, FormatViolation> {
    // Both codecs carry the (informative) level byte.
    match (c.u8()?, c.i8()?) {
        (0, _) => Ok(Codec::Raw),
        (1, level) => Ok(Codec::Zstd { level }),
        (other, _) => Err(FormatViolation::UnsupportedFeature(format!(
            "tile codec {other}"
        ))),
    }
}

/// The TOGGLE_BLOCKS section: samples per toggle block.
fn decode_toggle_blocks(c: &mut Cursor<'_>) -> Result<u32, FormatViolation> {
    let len = c.u32()?;
    if len == 0 {
        return Err(corrupt("TOGGLE_BLOCKS section", "blocks of 0 samples"));
    }
    Ok(len)
}

/// The TOGGLE_CODE section: the code of the toggle blocks (only range coding exists).
fn decode_toggle_code(c: &mut Cursor<'_>) -> Result<u8, FormatViolation> {
    let code = c.u8()?;
    if code != TOGGLE_CODE_RANGE {
        return Err(FormatViolation::UnsupportedFeature(format!(
            "toggle code {code}"
        )));
    }
    Ok(code)
}

fn set_once<T>(slot: &mut Option<T>, value: T, name: &str) -> Result<(), FormatViolation> {
    if slot.replace(value).is_some() {
        return Err(corrupt("header", format!("section {name} appears twice")));
    }
    Ok(())
}

pub(crate) fn push_section(out: &mut Vec<u8>, tag: u16, critical: bool, payload: &[u8]) {
    out.extend(tag.to_le_bytes());
    out.extend((if critical { FLAG_CRITICAL } else { 0 }).to_le_bytes());
    out.extend((payload.len() as u32).to_le_bytes());
    out.extend(payload);
}

/// One section of a header or index tail.
pub(crate) struct Section<'a> {
    pub(crate) tag: u16,
    pub(crate) payload: &'a [u8],
}

/// Iterates sections, rejecting malformed framing and unknown *critical* sections (a known
/// tag set is passed by the caller through `known`).
pub(crate) struct Sections<'a> {
    cursor: Cursor<'a>,
    failed: bool,
    known: &'static [u16],
}

impl<'a> Sections<'a> {
    pub(crate) fn new(bytes: &'a [u8], part: &'static str) -> Self {
        Self::with_known(
            bytes,
            part,
            &[
                TAG_MAP,
                TAG_TIME_AXIS,
                TAG_MODEL,
                TAG_CODEC,
                TAG_METADATA,
                TAG_TOGGLE_BLOCKS,
                TAG_TOGGLE_CODE,
            ],
        )
    }

    pub(crate) fn with_known(bytes: &'a [u8], part: &'static str, known: &'static [u16]) -> Self {
        Self {
            cursor: Cursor::new(bytes, part),
            failed: false,
            known,
        }
    }

    fn next_section(&mut self) -> Result<Option<Section<'a>>, FormatViolation> {
        loop {
            if self.cursor.is_empty() {
                return Ok(None);
            }
            let tag = self.cursor.u16()?;
            let flags = self.cursor.u16()?;
            let len = self.cursor.u32()? as usize;
            let payload = self.cursor.take(len)?;
            if flags & !FLAG_CRITICAL != 0 {
                return Err(corrupt(
                    "section",
                    format!("section {tag} has reserved flags {flags:#x}"),
                ));
            }
            if self.known.contains(&tag) {
                return Ok(Some(Section { tag, payload }));
            }
            if flags & FLAG_CRITICAL != 0 {
                return Err(FormatViolation::UnsupportedFeature(format!(
                    "critical section {tag}"
                )));
            }
        }
    }
}

impl<'a> Iterator for Sections<'a> {
    type Item = Result<Section<'a>, FormatViolation>;

    fn next(&mut self) -> Option<Self::Item> {
        if self.failed {
            return None;
        }
        let item = self.next_section().transpose();
        if matches!(item, Some(Err(_))) {
            self.failed = true;
        }
        item
    }
}

/// Encodes a time axis (FORMAT.md §4).
pub fn encode_axis(axis: &TimeAxis) -> Vec<u8> {
    let mut out = Vec::new();
    match axis.kind() {
        AxisKind::Regular => {
            out.push(0);
            out.extend(axis.start().0.to_le_bytes());
            out.extend(axis.step_ns().unwrap_or(1).to_le_bytes());
            out.extend(axis.len().to_le_bytes());
            write_positions(&mut out, axis.missing());
        }
        AxisKind::Explicit => {
            out.push(1);
            out.extend(axis.len().to_le_bytes());
            let times = axis.times().unwrap_or_default();
            let mut previous = None;
            for t in times {
                match previous {
                    None => out.extend(t.0.to_le_bytes()),
                    // Strictly increasing, so the difference is positive.
                    Some(p) => {
                        varint::write_u64(&mut out, (i128::from(t.0) - i128::from(p)) as u64)
                    }
                }
                previous = Some(t.0);
            }
        }
    }
    out
}

/// Writes sorted, distinct positions as a count plus gaps (`next − previous − 1`).
pub(crate) fn write_positions(out: &mut Vec<u8>, positions: &[u32]) {
    varint::write_u64(out, positions.len() as u64);
    let mut next = 0u32;
    for &p in positions {
        varint::write_u32(out, p - next);
        next = p.saturating_add(1);
    }
}

pub(crate) fn decode_axis(
    c: &mut Cursor<'_>,
    limits: &ReadLimits,
) -> Result<TimeAxis, FormatViolation> {
    let invalid =
        |e: froctomap_temporal::TemporalError| corrupt("TIME_AXIS section", e.to_string());
    match c.u8()? {
        0 => {
            let start = Timestamp(c.i64()?);
            let step = c.i64()?;
            let count = c.u32()?;
            if u64::from(count) > limits.max_samples {
                return Err(FormatViolation::Limit {
                    what: "sample count",
                    value: u64::from(count),
                    limit: limits.max_samples,
                });
            }
            let missing_count = c.count("missing sample count", u64::from(count), 1)?;
            let mut missing = Vec::with_capacity(missing_count);
            let mut next = 0u64;
            for _ in 0..missing_count {
                let sample = next + c.varint()?;
                if sample >= u64::from(count) {
                    return Err(corrupt(
                        "TIME_AXIS section",
                        "missing sample beyond the axis",
                    ));
                }
                missing.push(sample as u32);
                next = sample + 1;
            }
            TimeAxis::regular(start, step, count, missing).map_err(invalid)
        }
        1 => {
            let count = u64::from(c.u32()?);
            if count == 0 {
                return Err(corrupt("TIME_AXIS section", "empty axis"));
            }
            let count = c.check_count("sample count", count - 1, limits.max_samples, 1)? + 1;
            let mut times = Vec::with_capacity(count);
            let mut t = i128::from(c.i64()?);
            times.push(Timestamp(t as i64));
            for _ in 1..count {
                t += i128::from(c.varint()?);
                let value = i64::try_from(t).map_err(|_| {
                    corrupt(
                        "TIME_AXIS section",
                        "instant beyond the representable range",
                    )
                })?;
                times.push(Timestamp(value));
            }
            TimeAxis::explicit(times).map_err(invalid)
        }
        kind => Err(FormatViolation::UnsupportedFeature(format!(
            "time axis kind {kind}"
        ))),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn roundtrip(axis: TimeAxis) {
        let bytes = encode_axis(&axis);
        let mut c = Cursor::new(&bytes, "test");
        assert_eq!(decode_axis(&mut c, &ReadLimits::default()).unwrap(), axis);
        assert!(c.is_empty());
    }

    #[test]
    fn axes_round_trip() {
        roundtrip(
            TimeAxis::regular(Timestamp(-5), 600_000_000_000, 4032, vec![0, 7, 8, 4000]).unwrap(),
        );
        roundtrip(TimeAxis::regular(Timestamp(i64::MAX - 10), 1, 5, vec![]).unwrap());
        roundtrip(
            TimeAxis::explicit(vec![Timestamp(i64::MIN), Timestamp(0), Timestamp(i64::MAX)])
                .unwrap(),
        );
    }

    #[test]
    fn header_round_trips_and_detects_damage() {
        let axis = TimeAxis::regular(
            Timestamp::from_secs(1_700_000_000),
            60_000_000_000,
            10,
            vec![3],
        )
        .unwrap();
        let mut header = Header::new(0.08, 10, axis, ModelId(2), vec![1, 0, 0], Codec::default());
        header
            .metadata
            .insert("creator".into(), Value::from("test"));
        let bytes = header.encode();
        let preamble: [u8; PREAMBLE_LEN] = bytes[..PREAMBLE_LEN].try_into().unwrap();
        let decoded = Header::decode(
            &preamble,
            &bytes[PREAMBLE_LEN..],
            &ReadLimits::default(),
            MAJOR_VERSION,
        )
        .unwrap();
        assert_eq!(decoded, header);
        for i in 0..bytes.len() {
            let mut damaged = bytes.clone();
            damaged[i] ^= 0x10;
            let preamble: [u8; PREAMBLE_LEN] = damaged[..PREAMBLE_LEN].try_into().unwrap();
            assert!(
                Header::decode(
                    &preamble,
                    &damaged[PREAMBLE_LEN..],
                    &ReadLimits::default(),
                    MAJOR_VERSION
                )
                .is_err(),
                "byte {i}"
            );
        }
    }
}
