"""Makes hostile sqlite3 storage files for ROS 2 bag directories with Python's own sqlite3
(an independent SQLite client), for the recording tests of froctomap.

Usage: python hostile_sqlite.py GOOD.db3 OUT_DIR
Writes into OUT_DIR one bag directory per case, each a copy of metadata.yaml beside GOOD.db3
and a database named like GOOD.db3:
  no_messages/   the `messages` table missing
  no_data/       `messages` without its `data` column
  view/          `messages` a view (an endless recursive query) instead of a table
  huge_blob/     a message whose record declares a blob of about 128 MiB in a 1 MiB file
  not_sqlite/    a file that is not a database
and prints {"huge_declared": bytes} as JSON.
"""
import json
import shutil
import sqlite3
import sys
from pathlib import Path


def varint(value):
    """SQLite's big-endian varint (at most 8 bytes of 7 bits here)."""
    out = [value & 0x7F]
    value >>= 7
    while value:
        out.append(0x80 | (value & 0x7F))
        value >>= 7
    return bytes(reversed(out))


def case(out, name, good):
    bag = out / name
    bag.mkdir()
    shutil.copy(good.parent / "metadata.yaml", bag / "metadata.yaml")
    return bag / good.name


def schema(path, messages):
    conn = sqlite3.connect(path)
    conn.executescript(
        "CREATE TABLE topics(id INTEGER PRIMARY KEY, name TEXT, type TEXT, serialization_format TEXT,"
        " offered_qos_profiles TEXT);"
        "INSERT INTO topics VALUES(1, '/octomap_binary', 'octomap_msgs/msg/Octomap', 'cdr', '');"
        + messages
    )
    conn.commit()
    conn.close()


def main():
    good, out = Path(sys.argv[1]), Path(sys.argv[2])
    schema(case(out, "no_messages", good), "")
    schema(case(out, "no_data", good),
           "CREATE TABLE messages(id INTEGER PRIMARY KEY, topic_id INTEGER, timestamp INTEGER);"
           "INSERT INTO messages VALUES(1, 1, 5);")
    schema(case(out, "view", good),
           "CREATE VIEW messages AS WITH RECURSIVE n(x) AS (SELECT 1 UNION ALL SELECT x + 1 FROM n)"
           " SELECT 1 AS id, 1 AS topic_id, x AS timestamp, zeroblob(10) AS data FROM n;")
    # A message of 1 MiB + 7 bytes: its record header holds the blob's serial type as a
    # 4-byte varint, rewritten to claim (2^28 - 14) / 2 bytes (the overflow chain is not changed).
    huge = case(out, "huge_blob", good)
    schema(huge,
           "CREATE TABLE messages(id INTEGER PRIMARY KEY, topic_id INTEGER, timestamp INTEGER, data BLOB);")
    conn = sqlite3.connect(huge)
    length = (1 << 20) + 7
    conn.execute("INSERT INTO messages VALUES(1, 1, 5, ?)", (b"\x00\x01\x00\x00" + bytes(length - 4),))
    conn.commit()
    conn.close()
    raw = bytearray(huge.read_bytes())
    serial = varint(2 * length + 12)
    assert len(serial) == 4 and raw.count(serial) == 1, (serial, raw.count(serial))
    claimed = varint(0x0FFFFFFE)
    assert len(claimed) == 4
    at = raw.index(serial)
    raw[at:at + 4] = claimed
    huge.write_bytes(bytes(raw))
    case(out, "not_sqlite", good).write_bytes(b"not a database, " * 512)
    print(json.dumps({"huge_declared": (0x0FFFFFFE - 12) // 2}))


main()
