"""Resealed hostile files for the Python tests: a raw (`--zstd-level 0`) .froct file's tiles
taken apart into their streams (docs/FORMAT.md §5), one stream changed, and every length,
offset and checksum recomputed, as crates/file/tests/common/resealed.rs does in Rust."""

from __future__ import annotations

import struct
from typing import List, Tuple

FOOTER_LEN = 32
TILE_ENTRY_LEN = 40
#: A block part's outlier columns (format 1.1 and 1.2: 10 and 11 streams).
BLOCK_OUTLIER_STARTS = 8
BLOCK_OUTLIER_LENGTHS = 9


def _crc_table() -> List[int]:
    table = []
    for n in range(256):
        c = n
        for _ in range(8):
            c = (c >> 1) ^ 0x82F63B78 if c & 1 else c >> 1
        table.append(c)
    return table


_TABLE = _crc_table()


def crc32c(data: bytes) -> int:
    crc = 0xFFFFFFFF
    for b in data:
        crc = _TABLE[(crc ^ b) & 0xFF] ^ (crc >> 8)
    return crc ^ 0xFFFFFFFF


def read_varint(data: bytes, at: int) -> Tuple[int, int]:
    value, shift = 0, 0
    while True:
        b = data[at]
        at += 1
        value |= (b & 0x7F) << shift
        shift += 7
        if b < 0x80:
            return value, at


def varint(value: int) -> bytes:
    out = bytearray()
    while value >= 0x80:
        out.append(value & 0x7F | 0x80)
        value >>= 7
    out.append(value)
    return bytes(out)


def _streams(data: bytes, at: int, count: int) -> Tuple[List[bytes], int]:
    streams = []
    for _ in range(count):
        length, at = read_varint(data, at)
        streams.append(data[at:at + length])
        at += length
    return streams, at


def parse_tile(stored: bytes, block_streams: int):
    """(cell count, cell streams, frames of block parts) of a blocked raw tile."""
    at = 0
    count, at = read_varint(stored, at)
    stored_lens = []
    for _ in range(count):
        n, at = read_varint(stored, at)
        stored_lens.append(n)
    for _ in range(count):
        _, at = read_varint(stored, at)
    block_counts = []
    for _ in range(count - 1):
        n, at = read_varint(stored, at)
        block_counts.append(n)
    frames = []
    for n in stored_lens:
        frames.append(stored[at:at + n])
        at += n
    assert at == len(stored)
    cell_count, pos = read_varint(frames[0], 0)
    cells, pos = _streams(frames[0], pos, 6)
    assert pos == len(frames[0])
    blocks = []
    for frame, held in zip(frames[1:], block_counts):
        pos, parts = 0, []
        for _ in range(held):
            part, pos = _streams(frame, pos, block_streams)
            parts.append(part)
        assert pos == len(frame)
        blocks.append(parts)
    return cell_count, cells, blocks


def encode_tile(cell_count: int, cells: List[bytes], blocks) -> Tuple[bytes, int]:
    def part(streams):
        return b"".join(varint(len(s)) + s for s in streams)

    frames = [varint(cell_count) + part(cells)]
    frames += [b"".join(part(p) for p in parts) for parts in blocks]
    out = varint(len(frames))
    out += b"".join(varint(len(f)) for f in frames) * 2
    out += b"".join(varint(len(parts)) for parts in blocks)
    return out + b"".join(frames), sum(map(len, frames))


def with_huge_outlier_varint(data: bytes, value: int = 1 << 63) -> bytes:
    """A 1.2 raw file whose first outlier-length varint (or, lacking one, start varint) in
    the first block part holding any is `value`, resealed."""
    (index,) = struct.unpack_from("<Q", data, len(data) - FOOTER_LEN)
    (index_len,) = struct.unpack_from("<Q", data, len(data) - FOOTER_LEN + 8)
    index_bytes = bytearray(data[index:index + index_len])
    (tiles,) = struct.unpack_from("<I", index_bytes, 0)
    entries = [4 + t * TILE_ENTRY_LEN for t in range(tiles)]
    first = struct.unpack_from("<Q", index_bytes, entries[0] + 8)[0]
    out = bytearray(data[:first])
    damaged = False
    for e in entries:
        offset, stored = struct.unpack_from("<QI", index_bytes, e + 8)
        cell_count, cells, blocks = parse_tile(data[offset:offset + stored], 11)
        for parts in blocks:
            for p in parts:
                for column in (BLOCK_OUTLIER_LENGTHS, BLOCK_OUTLIER_STARTS):
                    if not damaged and p[column]:
                        _, used = read_varint(p[column], 0)
                        p[column] = varint(value) + p[column][used:]
                        damaged = True
        tile, raw_len = encode_tile(cell_count, cells, blocks)
        struct.pack_into("<QIII", index_bytes, e + 8, len(out), len(tile), raw_len, crc32c(tile))
        out += tile
    assert damaged, "no outliers in the file"
    index_offset = len(out)
    out += index_bytes
    footer = bytearray(data[len(data) - FOOTER_LEN:])
    struct.pack_into("<QQI", footer, 0, index_offset, len(index_bytes), crc32c(bytes(index_bytes)))
    struct.pack_into("<I", footer, 20, crc32c(bytes(footer[:20])))
    return bytes(out + footer)


ROOT_FIXTURES = __import__("pathlib").Path(__file__).resolve().parents[2] / "fixtures"
MCAP_MAGIC = b"\x89MCAP0\r\n"


def with_chunk_compression_length(data: bytes, length: int = 0xFFFFFFFF) -> bytes:
    """An MCAP file whose first chunk declares a compression name of `length` bytes (the
    chunk lies outside the summary, whose CRC stays valid)."""
    pos = len(MCAP_MAGIC)
    while pos < len(data) - len(MCAP_MAGIC):
        opcode = data[pos]
        (record_len,) = struct.unpack_from("<Q", data, pos + 1)
        if opcode == 0x06:
            at = pos + 9 + 28  # start, end, uncompressed size, uncompressed crc
            return data[:at] + struct.pack("<I", length) + data[at + 4:]
        pos += 9 + record_len
    raise AssertionError("no chunk")
