"""The command line's other verbs from Python (append, record, compact, export, info,
convert), each against the command line's own output for the same call: the same bytes
where it writes files, the same fields where it prints JSON."""

from __future__ import annotations

import csv
import json
import shutil
from pathlib import Path

import octomap
import pytest

import froctomap
from conftest import CREATED, ROOT, run_cli, snapshot_files

APPENDED = "2016-01-11T00:00:00Z"


def manifest(series: Path) -> list:
    with open(series / "manifest.csv", newline="") as text:
        return [(series / row["path"], row["time"]) for row in csv.DictReader(text)]


def write_manifest(path: Path, rows: list) -> Path:
    path.write_text("path,time\n" + "".join(f"{p},{t}\n" for p, t in rows))
    return path


@pytest.fixture(scope="module")
def halves(series: Path, tmp_path_factory) -> dict:
    """The series split in two manifests, and the command line's build of the first."""
    rows = manifest(series)
    dir = tmp_path_factory.mktemp("halves")
    first = write_manifest(dir / "first.csv", rows[:8])
    second = write_manifest(dir / "second.csv", rows[8:])
    base = dir / "base.froct"
    run_cli("-q", "build", first, "-o", base, "--created", CREATED)
    return {"first": first, "second": second, "base": base, "rows": rows}


def copy(path: Path, to: Path) -> Path:
    shutil.copyfile(path, to)
    return to


def test_append_rewrites_a_file_as_the_command_line(halves, tmp_path):
    ours = copy(halves["base"], tmp_path / "ours.froct")
    theirs = copy(halves["base"], tmp_path / "theirs.froct")
    report = froctomap.append(ours, halves["second"], appended=APPENDED, progress=False)
    cli = json.loads(run_cli("-q", "append", theirs, halves["second"], "--appended", APPENDED,
                             "--json").stdout)
    assert ours.read_bytes() == theirs.read_bytes()
    assert report["added"] == cli["added"] == 4
    for key in ["samples", "samples_before", "file_bytes", "toggles", "segments"]:
        assert report[key] == cli[key], key


def test_append_as_a_segment_and_compact_match_the_command_line(halves, tmp_path):
    ours = copy(halves["base"], tmp_path / "ours.froct")
    theirs = copy(halves["base"], tmp_path / "theirs.froct")
    # From (time, bytes) pairs: a segment holds the maps, whatever named them.
    pairs = [(int(t), p.read_bytes()) for p, t in halves["rows"][8:]]
    report = froctomap.append(ours, pairs, format_version="2.0", progress=False)
    run_cli("-q", "append", theirs, halves["second"], "--format-version", "2.0")
    assert report["segments"] == 1
    assert ours.read_bytes() == theirs.read_bytes()
    for version in ["2.0", "1.2"]:
        out_ours, out_theirs = tmp_path / f"c{version}.ours", tmp_path / f"c{version}.theirs"
        report = froctomap.compact(ours, out_ours, format_version=version, created=CREATED,
                                   progress=False)
        cli = json.loads(run_cli("-q", "compact", theirs, "-o", out_theirs, "--format-version",
                                 version, "--created", CREATED, "--json").stdout)
        assert out_ours.read_bytes() == out_theirs.read_bytes(), version
        assert (report["version"], report["maps"], report["bytes"]) == (
            cli["version"], cli["maps"], cli["bytes"]) == (version, 12, out_ours.stat().st_size)
    with pytest.raises(froctomap.FroctError, match="format_version \"3.0\""):
        froctomap.compact(ours, tmp_path / "x.froct", format_version="3.0", progress=False)


def test_record_commits_as_the_command_line(halves, tmp_path):
    """`record` from paths, from (time, bytes) pairs and from messages: the same bytes as
    `froctomap record --commit-every 2 --no-compact` of the same maps (Python's `record`
    compacts only with `auto_compact=True`; the command line by default)."""
    theirs = copy(halves["base"], tmp_path / "theirs.froct")
    run_cli("-q", "record", theirs, halves["second"], "--commit-every", "2", "--no-compact")
    rows = halves["rows"][8:]
    sources = {
        "paths": halves["second"],
        "pairs": ((int(t), p.read_bytes()) for p, t in rows),
        "messages": ((int(t), froctomap.message_from_map(p.read_bytes())) for p, t in rows),
    }
    for name, source in sources.items():
        ours = copy(halves["base"], tmp_path / f"{name}.froct")
        summary = froctomap.record(ours, source, commit_every=2)
        assert ours.read_bytes() == theirs.read_bytes(), name
        assert (summary["committed_maps"], summary["commits"], summary["older"]) == (4, 2, 0)
        assert summary["opened"] == "converted"
        assert [e["segment"] for e in summary["events"]] == [1, 2]
    # Maps not later than the file's last one are skipped and counted.
    again = froctomap.record(tmp_path / "paths.froct", halves["second"], commit_every=2)
    assert (again["committed_maps"], again["older"], again["opened"]) == (0, 4, "living")
    assert (tmp_path / "paths.froct").read_bytes() == theirs.read_bytes()


def test_record_into_a_missing_file_builds_its_base(halves, tmp_path):
    out = tmp_path / "new.froct"
    summary = froctomap.record(out, [halves["first"], halves["second"]], commit_every=8)
    assert (summary["opened"], summary["committed_maps"], summary["commits"]) == ("missing", 12, 2)
    assert summary["events"][0]["segment"] is None
    for i, (path, _) in enumerate(halves["rows"]):
        retrieved = tmp_path / "r.bt"
        run_cli("retrieve", out, "--time", f"index:{i}", "-o", retrieved)
        tree = octomap.OcTree(0.1)
        assert tree.readBinary(retrieved.read_bytes())
        assert retrieved.read_bytes() == run_retrieve_of(halves, i, tmp_path)
    small = tmp_path / "small-tiles.froct"
    froctomap.record(small, [halves["first"], halves["second"]], commit_every=8, tile_depth=12)
    assert froctomap.open(small).info["tile_depth"] == 12
    for i in range(len(halves["rows"])):
        retrieved = tmp_path / "s.bt"
        run_cli("retrieve", small, "--time", f"index:{i}", "-o", retrieved)
        assert retrieved.read_bytes() == run_retrieve_of(halves, i, tmp_path)
    with pytest.raises(froctomap.FroctError, match="tile_depth"):
        froctomap.record(tmp_path / "bad.froct", [halves["first"]], tile_depth=17)


def test_record_compacts_in_the_background(halves, tmp_path):
    """`auto_compact="background"`: commits go on while the file is compacted on a thread
    of its own; the maps committed meanwhile are added to the result, which replaces the
    file; every map then retrieves as from a build of the whole series (and reads in
    octomap-python)."""
    out = tmp_path / "background.froct"
    pairs = [(int(t), p.read_bytes()) for p, t in halves["rows"]]
    summary = froctomap.record(out, pairs, commit_every=1, auto_compact="background")
    assert (summary["committed_maps"], summary["commits"]) == (12, 12)
    compactions = [e for e in summary["events"] if e["event"] == "compaction"]
    assert summary["compactions"] == len(compactions) > 0
    # The first compaction is due before the last commit: its result took that commit.
    assert any(e["maps_added_meanwhile"] > 0 for e in compactions), compactions
    assert not [p.name for p in tmp_path.iterdir() if p.name.startswith(".froct-")]
    for i in range(len(halves["rows"])):
        retrieved = tmp_path / "r.bt"
        run_cli("retrieve", out, "--time", f"index:{i}", "-o", retrieved)
        assert octomap.OcTree(0.1).readBinary(retrieved.read_bytes())
        assert retrieved.read_bytes() == run_retrieve_of(halves, i, tmp_path), i
    with pytest.raises(froctomap.FroctError, match="auto_compact"):
        froctomap.record(tmp_path / "x.froct", pairs, auto_compact="later")


def run_retrieve_of(halves, i: int, tmp_path: Path) -> bytes:
    """The command line's own retrieval of sample `i` from a build of the whole series."""
    whole = tmp_path / "whole.froct"
    if not whole.exists():
        run_cli("-q", "build", halves["first"], halves["second"], "-o", whole)
    out = tmp_path / "w.bt"
    run_cli("retrieve", whole, "--time", f"index:{i}", "-o", out)
    return out.read_bytes()


def test_record_refuses_bad_items_after_committing_the_maps_before(halves, tmp_path):
    out = copy(halves["base"], tmp_path / "x.froct")
    (path, time), = halves["rows"][8:9]
    with pytest.raises(froctomap.FroctError, match=r"sources\[1\]: expected a path or a \(time, bytes\) pair"):
        froctomap.record(out, [(int(time), path.read_bytes()), 42], commit_every=5)
    assert froctomap.open(out).segments == 1


@pytest.mark.parametrize("fmt", ["bt", "ot"])
def test_export_writes_the_command_lines_files(cli_file, tmp_path, fmt):
    ours, theirs = tmp_path / "ours", tmp_path / "theirs"
    span = dict(start="2016-01-04T01:00:00Z", end="2016-01-05T06:00:00Z", every="5h")
    report = froctomap.export(cli_file, ours, mode="auto", format=fmt, progress=False, **span)
    run_cli("-q", "export", cli_file, "--from", span["start"], "--to", span["end"], "--every",
            span["every"], "--mode", "auto", "--format", fmt, "-o", theirs)
    names = sorted(p.name for p in theirs.iterdir())
    assert names == sorted(p.name for p in ours.iterdir())
    assert len(report["files"]) == 6 and report["manifest"] == str(ours / "manifest.csv")
    for name in names:
        assert (ours / name).read_bytes() == (theirs / name).read_bytes(), name


def test_export_to_mcap_is_the_command_lines_and_holds_octomap_messages(cli_file, tmp_path):
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    ours, theirs = tmp_path / "ours.mcap", tmp_path / "theirs.mcap"
    span = dict(start="2016-01-04T00:00:00Z", end="2016-01-04T06:00:00Z", every="2h")
    # The recording options, as keyword arguments and as flags: the same bytes.
    froctomap.export(cli_file, tmp_path / "opts.mcap", mode="auto", profile="foxglove",
                     frame_id="odom", topic_prefix="/r1", threshold=0.3, progress=False, **span)
    run_cli("-q", "export", cli_file, "--from", span["start"], "--to", span["end"], "--every",
            span["every"], "--mode", "auto", "--profile", "foxglove", "--frame-id", "odom",
            "--topic-prefix", "/r1", "--threshold", "0.3", "-o", tmp_path / "opts-cli.mcap")
    assert (tmp_path / "opts.mcap").read_bytes() == (tmp_path / "opts-cli.mcap").read_bytes()
    with pytest.raises(froctomap.FroctError, match="topic prefix"):
        froctomap.export(cli_file, tmp_path / "bad.mcap", topic_prefix="r1/", progress=False,
                         **span)
    assert not (tmp_path / "bad.mcap").exists()
    froctomap.export(cli_file, ours, mode="retrieve", progress=False, **span)
    run_cli("-q", "export", cli_file, "--from", span["start"], "--to", span["end"], "--every",
            span["every"], "--mode", "retrieve", "-o", theirs)
    assert ours.read_bytes() == theirs.read_bytes()
    # mcap-ros2-support decodes the whole file (CDR only by default); each Octomap message
    # holds the retrieved .bt's body.
    with open(ours, "rb") as stream:
        reader = make_reader(stream, decoder_factories=[DecoderFactory()])
        decoded = [(channel.topic, m.log_time, message) for _, channel, m, message
                   in reader.iter_decoded_messages()]
    maps = [(t, message) for topic, t, message in decoded if topic == "/octomap_binary"]
    assert len(decoded) == 3 * len(maps)
    assert len(maps) == 4
    for i, (_, message) in enumerate(maps):
        retrieved = tmp_path / f"{i}.bt"
        run_cli("retrieve", cli_file, "--time", f"index:{i}", "-o", retrieved)
        fields = froctomap.message_from_map(retrieved.read_bytes())
        resolution = froctomap.open(cli_file).resolution
        assert (message.binary, message.id, message.resolution) == (True, "OcTree", resolution)
        assert (fields["binary"], fields["id"], fields["resolution"]) == (True, "OcTree", resolution)
        assert bytes(b & 0xFF for b in message.data) == fields["data"].tobytes(), i
        # The file made of the message reads in octomap-python as the retrieved one.
        made, read = octomap.OcTree(0.1), octomap.OcTree(0.1)
        assert made.readBinary(froctomap.map_from_message(message))
        assert read.readBinary(retrieved.read_bytes())
        assert (made.size(), made.getNumLeafNodes()) == (read.size(), read.getNumLeafNodes())
        assert made.size() > 0


def test_export_to_a_bag_is_the_command_lines_and_rosbags_reads_it(cli_file, tmp_path):
    from rosbags.rosbag1 import Reader
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    ours, theirs = tmp_path / "ours.bag", tmp_path / "theirs.bag"
    span = dict(start="2016-01-04T00:00:00Z", end="2016-01-04T06:00:00Z", every="2h")
    froctomap.export(cli_file, ours, mode="retrieve", frame_id="odom", progress=False, **span)
    run_cli("-q", "export", cli_file, "--from", span["start"], "--to", span["end"], "--every",
            span["every"], "--mode", "retrieve", "--frame-id", "odom", "-o", theirs)
    assert ours.read_bytes() == theirs.read_bytes()
    with pytest.raises(froctomap.FroctError, match="profile"):
        froctomap.export(cli_file, tmp_path / "bad.bag", profile="foxglove", progress=False,
                         **span)
    assert not (tmp_path / "bad.bag").exists()
    # rosbags reads the bag through its index; each Octomap message holds the retrieved .bt's
    # body, in the frame asked.
    store = get_typestore(Stores.ROS1_NOETIC)
    with Reader(ours) as reader:
        (connection,) = reader.connections
        store.register(get_types_from_msg(connection.msgdef.data, connection.msgtype))
        messages = [store.deserialize_ros1(raw, connection.msgtype)
                    for _, _, raw in reader.messages()]
    assert connection.topic == "/octomap_binary"
    assert len(messages) == 4
    for i, message in enumerate(messages):
        retrieved = tmp_path / f"{i}.bt"
        run_cli("retrieve", cli_file, "--time", f"index:{i}", "-o", retrieved)
        fields = froctomap.message_from_map(retrieved.read_bytes())
        assert (message.header.frame_id, message.binary, message.id) == ("odom", True, "OcTree")
        assert message.data.tobytes() == fields["data"].tobytes(), i


def test_export_to_a_ros2_bag_is_the_command_lines_and_rosbags_reads_it(cli_file, tmp_path):
    from rosbags.rosbag2 import Reader
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    (tmp_path / "ours").mkdir()
    (tmp_path / "theirs").mkdir()
    ours, theirs = tmp_path / "ours" / "maps_bag", tmp_path / "theirs" / "maps_bag"
    span = dict(start="2016-01-04T00:00:00Z", end="2016-01-04T06:00:00Z", every="2h")
    # format="ros2bag" asks for the bag directory as --format ros2bag does.
    report = froctomap.export(cli_file, ours, mode="retrieve", format="ros2bag",
                              frame_id="odom", progress=False, **span)
    run_cli("-q", "export", cli_file, "--from", span["start"], "--to", span["end"], "--every",
            span["every"], "--mode", "retrieve", "--format", "ros2bag", "--frame-id", "odom",
            "-o", theirs)
    assert report["format"] == "ros2bag" and report["manifest"] is None
    assert sorted(p.name for p in ours.iterdir()) == ["maps_bag_0.mcap", "metadata.yaml"]
    for name in ["maps_bag_0.mcap", "metadata.yaml"]:
        assert (ours / name).read_bytes() == (theirs / name).read_bytes(), name
    # An existing directory is refused, as on the command line; a profile a bag cannot hold
    # too; nothing is left.
    with pytest.raises(froctomap.FroctError, match="already exists"):
        froctomap.export(cli_file, ours, format="ros2bag", progress=False, **span)
    with pytest.raises(froctomap.FroctError, match="profile"):
        froctomap.export(cli_file, tmp_path / "bad_bag", format="ros2bag", profile="foxglove",
                         progress=False, **span)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["ours", "theirs"]
    # rosbags opens the directory; each Octomap message holds the retrieved .bt's body.
    store = get_typestore(Stores.EMPTY)
    with Reader(ours) as reader:
        for connection in reader.connections:
            types = get_types_from_msg(connection.msgdef.data, connection.msgtype)
            store.register({k: v for k, v in types.items() if k not in store.types})
        assert reader.message_count == 12
        messages = [store.deserialize_cdr(raw, connection.msgtype)
                    for connection, _, raw in reader.messages()
                    if connection.topic == "/octomap_binary"]
    assert len(messages) == 4
    for i, message in enumerate(messages):
        retrieved = tmp_path / f"{i}.bt"
        run_cli("retrieve", cli_file, "--time", f"index:{i}", "-o", retrieved)
        fields = froctomap.message_from_map(retrieved.read_bytes())
        retrieved.unlink()
        assert (message.header.frame_id, message.binary, message.id) == ("odom", True, "OcTree")
        assert message.data.tobytes() == fields["data"].tobytes(), i


def test_formats_are_the_command_lines_less_the_upstream_backend():
    cli = json.loads(run_cli("formats", "--json").stdout)
    # The wheel reads and writes maps with the native codec only.
    assert froctomap.formats() == [row for row in cli if row["backend"] != "octomap"]
    assert any(row["backend"] == "octomap" for row in cli)
    kinds = {row["name"]: row["kind"] for row in froctomap.formats()}
    assert (kinds["bt"], kinds["froct"], kinds["mcap"]) == ("map", "series", "recording")


def test_info_of_map_files_and_froct_files_is_the_command_lines(series, cli_file):
    snapshot = snapshot_files(series)[0]
    cli = json.loads(run_cli("info", "--json", snapshot).stdout)
    ours = froctomap.info(snapshot)
    assert ours == cli and ours["format"] == "bt" and ours["leaves"] > 0
    cli = json.loads(run_cli("info", "--json", "--count", cli_file).stdout)
    assert froctomap.info(cli_file, count=True) == cli
    with pytest.raises(froctomap.FroctError, match="nope.bt"):
        froctomap.info(series / "nope.bt")


def test_convert_writes_the_command_lines_bytes(series, tmp_path):
    snapshot = snapshot_files(series)[3]
    ours, theirs = tmp_path / "ours.ot", tmp_path / "theirs.ot"
    report = froctomap.convert(snapshot, ours)
    run_cli("-q", "convert", snapshot, theirs)
    assert ours.read_bytes() == theirs.read_bytes()
    assert (report["input_format"], report["output_format"]) == ("bt", "ot")
    tree = octomap.OcTree(0.1)
    back = tmp_path / "back.bt"
    froctomap.convert(ours, back)
    assert back.read_bytes() == snapshot.read_bytes()
    assert tree.readBinary(back.read_bytes())
    with pytest.raises(froctomap.FroctError, match="input"):
        froctomap.convert(snapshot, snapshot)


@pytest.mark.parametrize("how", [["--time", "index:3"], ["--time", "2016-02-01T00:00:00Z", "--slice", "z=0.5"], ["--dynamics"]])
def test_render_draws_the_command_lines_picture(cli_file, tmp_path, how):
    ours, theirs = tmp_path / "ours.png", tmp_path / "theirs.png"
    options = {"dynamics": "--dynamics" in how}
    if "--time" in how:
        options["t"] = how[how.index("--time") + 1]
    if "--slice" in how:
        options["slice"] = how[how.index("--slice") + 1]
    report = froctomap.render(cli_file, ours, width=400, **options)
    run_cli("-q", "render", cli_file, *how, "--width", "400", "-o", theirs)
    assert ours.read_bytes() == theirs.read_bytes()
    assert ours.read_bytes().startswith(b"\x89PNG") and report["width"] == 400
    assert report["kind"] == {"index:3": "retrieved"}.get(options.get("t"), report["kind"])
    # The wheel ships its font, a TrueType file.
    font = Path(froctomap.__file__).parent / "fonts" / "DejaVuSans.ttf"
    assert font.read_bytes()[:4] == b"\x00\x01\x00\x00"


def test_render_with_the_wheels_own_font_is_the_command_lines(cli_file, tmp_path):
    """The font the wheel ships renders (a machine without DejaVu Sans gets it): a picture
    drawn with it by Python is the command line's drawn with the same file."""
    import os
    import subprocess
    import sys

    from conftest import cli_path

    font = Path(froctomap.__file__).parent / "fonts" / "DejaVuSans.ttf"
    env = {**os.environ, "FROCTOMAP_FONT": str(font)}
    ours, theirs = tmp_path / "ours.png", tmp_path / "theirs.png"
    # A process of its own: a process looks its font up once.
    draw = ("import sys, froctomap; froctomap.render(sys.argv[1], sys.argv[2], width=400, "
            "dynamics=True)")
    subprocess.run([sys.executable, "-c", draw, str(cli_file), str(ours)], env=env, check=True)
    subprocess.run([str(cli_path()), "-q", "render", str(cli_file), "--dynamics", "--width", "400", "-o",
                    str(theirs)], env=env, check=True)
    assert ours.read_bytes() == theirs.read_bytes()


def test_generate_writes_the_command_lines_series(tmp_path):
    ours, theirs = tmp_path / "ours", tmp_path / "theirs"
    options = dict(days=0.25, step="2h", seed=4, noise=0.001)
    report = froctomap.generate(ours, progress=False, **options)
    run_cli("-q", "generate", "--days", "0.25", "--step", "2h", "--seed", "4", "--noise",
            "0.001", "-o", theirs)
    names = sorted(p.name for p in theirs.iterdir())
    assert names == sorted(p.name for p in ours.iterdir()) and len(names) == 4
    for name in names:
        assert (ours / name).read_bytes() == (theirs / name).read_bytes(), name
    assert report["snapshots"] == 3 and report["start"] == "2016-01-04T00:00:00Z"
    tree = octomap.OcTree(0.1)
    assert tree.readBinary(str(ours / names[0]).encode())
    with pytest.raises(froctomap.FroctError, match="nope.bt"):
        froctomap.generate(tmp_path / "x", base=tmp_path / "nope.bt", progress=False)


def test_generate_without_the_debian_base_map_asks_for_one(tmp_path, monkeypatch):
    """What a pip user without liboctomap-dev meets: a clear error naming `base=`, and
    nothing written."""
    monkeypatch.setattr(froctomap, "_DEFAULT_BASE", str(tmp_path / "no-liboctomap-dev.bt"))
    with pytest.raises(froctomap.FroctError, match="no base map: pass base="):
        froctomap.generate(tmp_path / "out", progress=False)
    assert not (tmp_path / "out").exists()


def test_info_of_recordings_is_the_command_lines_and_counts_the_written_messages():
    """`info` on each recording fixture (ROS 1 bags, a ROS 2 bag directory, an MCAP file):
    the command line's JSON, and per map topic the messages and log times the fixtures were
    written with (fixtures/ros/spec.json, the writers' side)."""
    spec = json.loads((ROOT / "fixtures" / "ros" / "spec.json").read_text())
    for recording in spec["recordings"]:
        path = ROOT / recording["path"]
        ours = froctomap.info(path)
        assert ours == json.loads(run_cli("info", "--json", path).stdout), path
        topics = {t["topic"]: t for t in ours["topics"]}
        for name in {m["topic"] for m in recording["messages"]}:
            written = [m["log_ns"] for m in recording["messages"] if m["topic"] == name]
            topic = topics[name]
            assert topic["messages"] == len(written), (path, name)
            assert (topic["first_ns"], topic["last_ns"]) == (min(written), max(written))
            assert topic["type"].replace("/msg/", "/") == "octomap_msgs/Octomap"
