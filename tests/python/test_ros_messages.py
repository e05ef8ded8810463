"""Maps as `octomap_msgs/Octomap` messages (`message_from_map`, `map_from_message`) against
messages serialised and read back by the PyPI `rosbags` package and trees read by
octomap-python; and the notebook example of docs/PYTHON.md (`record` from a `rosbags`
reader, then `probability` at many times), run as written there."""

from __future__ import annotations

import csv
import re
from pathlib import Path

import numpy as np
import octomap
import pytest

import froctomap
from conftest import ROOT, run_cli, snapshot_files

rosbags = pytest.importorskip("rosbags")
from rosbags.rosbag2 import Writer  # noqa: E402
from rosbags.typesys import Stores, get_types_from_msg, get_typestore  # noqa: E402

OCTOMAP_MSG = """
std_msgs/Header header
bool binary
string id
float64 resolution
int8[] data
"""
OCTOMAP = "octomap_msgs/msg/Octomap"


def typestore():
    store = get_typestore(Stores.ROS2_HUMBLE)
    store.register(get_types_from_msg(OCTOMAP_MSG, OCTOMAP))
    return store


def message(store, data: bytes, nanoseconds: int):
    Header = store.types["std_msgs/msg/Header"]
    Time = store.types["builtin_interfaces/msg/Time"]
    stamp = Time(sec=nanoseconds // 10**9, nanosec=nanoseconds % 10**9)
    return store.types[OCTOMAP](header=Header(stamp=stamp, frame_id="map"),
                                **froctomap.message_from_map(data))


def test_bt_and_ot_files_round_trip_through_rosbags_messages(series, tmp_path):
    store = typestore()
    bt = snapshot_files(series)[2]
    ot = tmp_path / "map.ot"
    froctomap.convert(bt, ot)
    for path, binary in [(bt, True), (ot, False)]:
        data = path.read_bytes()
        fields = froctomap.message_from_map(data)
        assert (fields["binary"], fields["id"]) == (binary, "OcTree")
        assert fields["data"].dtype == np.int8
        # The body is the file behind its header: the header's last line is "data".
        body = fields["data"].tobytes()
        assert data.endswith(b"data\n" + body)
        sent = message(store, data, 1_451_865_600_250_000_000)
        received = store.deserialize_cdr(store.serialize_cdr(sent, OCTOMAP), OCTOMAP)
        assert (received.binary, received.id, received.resolution) == (
            binary, "OcTree", fields["resolution"])
        rebuilt = froctomap.map_from_message(received)
        # octomap-python reads the rebuilt file as the original, node for node.
        if binary:
            ours, theirs = octomap.OcTree(0.1), octomap.OcTree(0.1)
            assert ours.readBinary(rebuilt) and theirs.readBinary(data)
            assert ours.writeBinary() == theirs.writeBinary()
        else:
            ours, theirs = octomap.OcTree.read(rebuilt), octomap.OcTree.read(data)
            assert ours.write() == theirs.write()
        assert ours.size() > 0
        # A dict of the fields reads the same, and the header holds the node count.
        assert froctomap.map_from_message(
            {"binary": binary, "id": "OcTree", "resolution": fields["resolution"],
             "data": list(fields["data"])}) == rebuilt
        assert f"size {ours.size()}\n".encode() in rebuilt


def test_a_message_that_is_not_a_map_is_refused():
    with pytest.raises(froctomap.FroctError):
        froctomap.map_from_message({"binary": True, "id": "OcTree", "resolution": 0.1,
                                    "data": b"\x07\x07"})
    with pytest.raises(froctomap.FroctError, match="resolution"):
        froctomap.map_from_message({"binary": True, "id": "OcTree", "resolution": 0.0,
                                    "data": b""})
    with pytest.raises(froctomap.FroctError, match="not an OctoMap file"):
        froctomap.message_from_map(b"P6\n")


def python_example() -> str:
    """The notebook example of docs/PYTHON.md, as written there."""
    text = (ROOT / "docs" / "PYTHON.md").read_text()
    found = re.search(r"<!-- tested: rosbag example -->\s*```python\n(.*?)```", text, re.S)
    assert found, "docs/PYTHON.md lost its rosbag example"
    return found.group(1)


def test_the_rosbag_example_of_the_docs_runs(series, tmp_path, monkeypatch):
    """A ROS 2 bag written by `rosbags` with the series' maps as messages; the example
    records it and queries p at many times. Every map comes back as the command line's
    build of the same files retrieves it."""
    store = typestore()
    with open(series / "manifest.csv", newline="") as text:
        rows = [(series / row["path"], int(row["time"])) for row in csv.DictReader(text)]
    paths, times = [p for p, _ in rows], [t for _, t in rows]
    with Writer(tmp_path / "office_bag", version=8) as writer:
        connection = writer.add_connection("/octomap_binary", OCTOMAP, typestore=store)
        for path, seconds in zip(paths, times):
            ns = seconds * 10**9
            writer.write(connection, ns,
                         store.serialize_cdr(message(store, path.read_bytes(), ns), OCTOMAP))
    monkeypatch.chdir(tmp_path)
    names: dict = {}
    exec(python_example(), names)  # noqa: S102
    summary, p, hours, points = names["summary"], names["p"], names["hours"], names["points"]
    assert (summary["committed_maps"], summary["opened"]) == (len(paths), "missing")
    assert p.shape == (len(hours), len(points)) and len(points) > 0
    f = froctomap.open(tmp_path / "office.froct")
    np.testing.assert_array_equal(p[5], f.probability(hours[5], points))
    whole = tmp_path / "cli.froct"
    run_cli("-q", "build", series, "-o", whole)
    for i in range(len(paths)):
        theirs = tmp_path / "theirs.bt"
        run_cli("retrieve", whole, "--time", f"index:{i}", "-o", theirs)
        assert f.retrieve(f"index:{i}").to_bt_bytes() == theirs.read_bytes(), i
