"""The package against the command line: every public name, byte-for-byte round trips,
numpy shapes and dtypes, and octomap-python reading the maps' bytes."""

from __future__ import annotations

import csv
import datetime as dt
import json
from pathlib import Path

import numpy as np
import octomap
import pytest

import froctomap
from conftest import CREATED, run_cli, snapshot_files


@pytest.fixture(scope="module")
def f(cli_file: Path):
    with froctomap.open(cli_file) as opened:
        yield opened


def manifest_times(series: Path) -> list:
    with open(series / "manifest.csv", newline="") as text:
        rows = list(csv.DictReader(text))
    return [(series / row["path"], row["time"]) for row in rows]


def test_public_names_are_exported():
    verbs = ["append", "record", "compact", "export", "info", "convert", "render", "generate",
             "formats", "message_from_map", "map_from_message"]
    for name in ["open", "build", "evaluate", "parse_time", "FroctFile", "Map", "FroctError",
                 "__version__", *verbs]:
        assert hasattr(froctomap, name), name
        assert name in froctomap.__all__
        assert name == "__version__" or getattr(froctomap, name).__doc__, name
    # dir() shows the public names, not the typing helpers the module imports.
    assert sorted(dir(froctomap)) == sorted(froctomap.__all__)
    assert issubclass(froctomap.FroctError, OSError)
    assert issubclass(froctomap.FroctError, ValueError)
    for name in ["open", "build", "evaluate", "parse_time", "FroctFile", "Map", "FroctError"]:
        assert getattr(froctomap, name).__doc__, name
    package = Path(froctomap.__file__).parent
    assert (package / "py.typed").is_file()
    assert (package / "_native.pyi").is_file()


def test_every_native_name_has_a_stub_and_a_docstring():
    import ast
    from froctomap import _native

    stub = ast.parse((Path(_native.__file__).parent / "_native.pyi").read_text())
    stubbed = {node.name: node for node in stub.body
               if isinstance(node, (ast.FunctionDef, ast.ClassDef))}
    for name in dir(_native):
        if name.startswith("_"):
            continue
        assert name in stubbed, name
        value = getattr(_native, name)
        assert value.__doc__, name
        if isinstance(value, type):
            members = {n.name for n in stubbed[name].body if isinstance(n, ast.FunctionDef)}
            for member in dir(value):
                if not member.startswith("_"):
                    assert member in members, f"{name}.{member}"
                    assert getattr(value, member).__doc__, f"{name}.{member}"


def test_build_writes_the_bytes_of_the_command_line(series, cli_file, tmp_path):
    out = tmp_path / "python.froct"
    report = froctomap.build(series, out, created=CREATED, progress=False)
    assert out.read_bytes() == cli_file.read_bytes()
    assert report["file_bytes"] == out.stat().st_size
    assert report["used"] == len(snapshot_files(series))
    cli = json.loads(run_cli("-q", "build", series, "-o", tmp_path / "again.froct",
                             "--created", CREATED, "--json").stdout)
    for key in ["inputs", "used", "input_bytes", "samples", "cells", "voxels", "toggles",
                "file_bytes", "model_errors"]:
        assert report[key] == cli[key], key


def without_metadata(path: Path) -> tuple:
    """`info --json` less what names the inputs (metadata, the header holding it and the
    ratios counting that header), and the tiles' bytes."""
    info = json.loads(run_cli("info", "--json", path).stdout)
    header, tiles = info["size"]["header"], info["size"]["tiles"]
    for key in ["file", "metadata", "ratio_vs_inputs", "ratio_vs_raw_states"]:
        del info[key]
    del info["size"]["file"], info["size"]["header"]
    return info, path.read_bytes()[header:header + tiles]


def test_build_takes_time_and_bytes_pairs_from_a_generator(series, cli_file, tmp_path):
    """Maps handed over as (time, bytes) pairs by a generator (each read only when asked
    for) build the command line's file of the directory, apart from the metadata naming the
    inputs; every snapshot retrieved is the command line's."""
    read = []

    def pairs():
        for path, time in manifest_times(series):
            read.append(path)
            yield int(time), path.read_bytes()

    out = tmp_path / "pairs.froct"
    report = froctomap.build(pairs(), out, created=CREATED, progress=False)
    assert len(read) == report["used"] == len(snapshot_files(series))
    assert without_metadata(out) == without_metadata(cli_file)
    assert out.read_bytes() != cli_file.read_bytes()  # the metadata do differ
    for i in range(report["used"]):
        ours, theirs = tmp_path / f"ours{i}.bt", tmp_path / f"theirs{i}.bt"
        run_cli("retrieve", out, "--time", f"index:{i}", "-o", ours)
        run_cli("retrieve", cli_file, "--time", f"index:{i}", "-o", theirs)
        assert ours.read_bytes() == theirs.read_bytes(), i
    # No spool is left beside the output.
    assert sorted(p.name for p in tmp_path.iterdir() if p.name.startswith(".froct")) == []


def test_time_and_bytes_pairs_are_checked(series, tmp_path):
    (path, time), (other, _) = manifest_times(series)[:2]
    with pytest.raises(froctomap.FroctError, match="paths or \\(time, bytes\\) pairs, not both"):
        froctomap.build([(int(time), path.read_bytes()), other], tmp_path / "x.froct",
                        progress=False)
    with pytest.raises(froctomap.FroctError, match="inputs\\[0\\]: expected a path or a \\(time, bytes\\) pair"):
        froctomap.build([(int(time), "not bytes")], tmp_path / "x.froct", progress=False)
    with pytest.raises(froctomap.FroctError, match="same time"):
        froctomap.build([(int(time), path.read_bytes()), (int(time), other.read_bytes())],
                        tmp_path / "x.froct", progress=False)
    with pytest.raises(froctomap.FroctError, match="carry their own times"):
        froctomap.build([(int(time), path.read_bytes())], tmp_path / "x.froct",
                        start=0, step=60, progress=False)
    assert not (tmp_path / "x.froct").exists()
    assert [p.name for p in tmp_path.iterdir()] == []


def test_lossy_and_fixed_order_builds_match_the_command_line(series, tmp_path):
    ours = tmp_path / "ours.froct"
    theirs = tmp_path / "theirs.froct"
    froctomap.build(series, ours, lossy=True,
                    order=1, created=CREATED, progress=False)
    run_cli("-q", "build", series, "-o", theirs, "--lossy", "--order", "1", "--created", CREATED)
    assert ours.read_bytes() == theirs.read_bytes()


def test_times_are_the_snapshots_times(f, series):
    expected = [froctomap.parse_time(t) for _, t in manifest_times(series)]
    assert f.times.dtype == np.float64
    assert f.times.shape == (len(f),)
    assert f.times_ns.dtype == np.int64
    assert f.observed.dtype == np.bool_
    assert list(f.times[f.observed]) == expected
    first = octomap.OcTree(0.1)
    assert first.readBinary(str(manifest_times(series)[0][0]).encode())
    assert f.resolution == first.getResolution()


def test_info_has_the_fields_of_info_json(f, cli_file):
    cli = json.loads(run_cli("info", cli_file, "--json").stdout)
    assert f.info == cli
    assert f.describe(count=True)["cells"] == cli["cells"]


@pytest.mark.parametrize(
    "when",
    [
        "index:3",
        "index:-1",
        "last",
        "2016-01-04T06:00:00Z",
        "2016-01-04 07:00:00+01:00",
        "2016-01-04T07:30:00Z",  # between snapshots: the one before
        1451890800,
        1451890800.0,
        dt.datetime(2016, 1, 4, 8, tzinfo=dt.timezone.utc),
        dt.datetime(2016, 1, 4, 8),  # naive: UTC, as on the command line
        np.datetime64("2016-01-04T10:00:00"),
    ],
)
def test_retrieved_bytes_are_the_command_lines(f, cli_file, tmp_path, when):
    m = f.retrieve(when)
    assert m.kind == "observed"
    text = when.isoformat() if isinstance(when, dt.datetime) else str(when)
    for extension, data in [("bt", m.to_bt_bytes()), ("ot", m.to_ot_bytes())]:
        out = tmp_path / f"cli.{extension}"
        run_cli("-q", "retrieve", cli_file, "--time", text, "-o", out)
        assert data == out.read_bytes(), (when, extension)


def test_retrieval_gives_back_the_input_snapshots(f, series):
    for path, time in manifest_times(series):
        m = f.retrieve(time)
        assert m.time == froctomap.parse_time(time)
        assert m.to_bt_bytes() == path.read_bytes(), path


def test_nearest_takes_the_closest_snapshot(f):
    assert f.retrieve("2016-01-04T07:30:00Z").iso_time == "2016-01-04T06:00:00Z"
    assert f.retrieve("2016-01-04T07:30:00Z", nearest=True).iso_time == "2016-01-04T08:00:00Z"


@pytest.mark.parametrize("when", ["2016-01-06T12:00:00Z", "2016-01-04T05:00:00Z", "index:2"])
def test_predicted_bytes_are_the_command_lines(f, cli_file, tmp_path, when):
    m = f.predict(when)
    assert m.kind == "predicted" and m.sample is None
    for extension, data in [("bt", m.to_bt_bytes()), ("ot", m.to_ot_bytes())]:
        out = tmp_path / f"cli.{extension}"
        run_cli("-q", "predict", cli_file, "--time", when, "-o", out)
        assert data == out.read_bytes(), (when, extension)


def test_write_gives_the_same_bytes(f, tmp_path):
    m = f.predict("2016-01-07T00:00:00Z")
    assert m.write(tmp_path / "p.bt") > 0
    assert (tmp_path / "p.bt").read_bytes() == m.to_bt_bytes()
    m.write(tmp_path / "p.map", format="ot")
    assert (tmp_path / "p.map").read_bytes() == m.to_ot_bytes()


def octomap_tree(data: bytes) -> "octomap.OcTree":
    tree = octomap.OcTree(0.1)
    assert tree.readBinary(data), "octomap-python refused the bytes"
    return tree


def keys(points: np.ndarray, resolution: float) -> set:
    return set(map(tuple, np.floor(points / resolution).astype(np.int64)))


@pytest.mark.parametrize("query", ["retrieve", "predict"])
def test_octomap_python_reads_the_bt_bytes_as_the_point_cloud(f, query):
    m = getattr(f, query)("2016-01-04T12:00:00Z")
    occupied, free = m.point_cloud()
    for cloud in (occupied, free):
        assert cloud.dtype == np.float64 and cloud.ndim == 2 and cloud.shape[1] == 3
    assert len(occupied) > 1000 and len(free) > len(occupied)
    tree = octomap_tree(m.to_bt_bytes())
    assert tree.getResolution() == pytest.approx(m.resolution)
    their_occupied, their_free = tree.extractPointCloud()
    assert len(their_occupied) == len(occupied) and len(their_free) == len(free)
    assert keys(their_occupied, m.resolution) == keys(occupied, m.resolution)
    assert keys(their_free, m.resolution) == keys(free, m.resolution)
    # The centres are voxel centres: half a voxel from the grid lines.
    offsets = occupied / m.resolution - np.floor(occupied / m.resolution)
    assert np.allclose(offsets, 0.5)


def test_leaves_are_the_compact_form_of_the_point_cloud(f):
    m = f.retrieve("index:0")
    centres, sizes, occupied = m.leaves()
    assert centres.shape == (len(m), 3) and centres.dtype == np.float64
    assert sizes.shape == (len(m),) and sizes.dtype == np.float64
    assert occupied.shape == (len(m),) and occupied.dtype == np.bool_
    voxels = np.round((sizes / m.resolution) ** 3).astype(np.int64)
    occ, free = m.point_cloud()
    assert voxels[occupied].sum() == len(occ)
    assert voxels[~occupied].sum() == len(free)
    with pytest.raises(froctomap.FroctError, match="max_points"):
        m.point_cloud(max_points=10)


def test_parse_time_reads_like_the_command_line():
    assert froctomap.parse_time("2016-01-04T00:00:00Z") == 1451865600.0
    assert froctomap.parse_time(1451865600.25) == 1451865600.25
    assert froctomap.parse_time(dt.date(2016, 1, 4)) == 1451865600.0
    assert froctomap.parse_time("index:7") == ("index", 7)
    assert froctomap.parse_time("last") == ("from_end", 1)
    with pytest.raises(froctomap.FroctError, match="cannot read"):
        froctomap.parse_time("yesterday-ish")
    with pytest.raises(TypeError):
        froctomap.parse_time([1, 2])
    with pytest.raises(TypeError):
        froctomap.parse_time(True)


def test_evaluate_returns_the_tables_of_eval_json(cli_file, held_out, series):
    ours = froctomap.evaluate(cli_file, [held_out, series])
    theirs = json.loads(run_cli("-q", "eval", cli_file, "--against", held_out, series,
                                "--json").stdout)
    assert ours == theirs
    # Issue 28: every {wrong, total} object carries the Brier score and the log loss.
    for _, rates in ours["prediction"]:
        for voxels in ["all", "non_empty", "dynamic"]:
            assert {"wrong", "total", "brier", "log_loss"} <= rates[voxels].keys()
    assert 0 < ours["log_loss_epsilon"] < 0.5
    assert ours["outside"] == len(snapshot_files(held_out))
    assert ours["inside"] == len(snapshot_files(series))
    strided = froctomap.evaluate(cli_file, [held_out, series], stride=2)
    theirs = json.loads(run_cli("-q", "eval", cli_file, "--against", held_out, series,
                                "--stride", "2", "--json").stdout)
    assert strided == theirs
    assert strided["inside"] + strided["outside"] == (
        len(snapshot_files(held_out)) + len(snapshot_files(series)) + 1) // 2
    with pytest.raises(ValueError, match="stride"):
        froctomap.evaluate(cli_file, [held_out, series], stride=0)


def test_progress_reaches_a_callback(series, tmp_path):
    calls = []
    froctomap.build(series, tmp_path / "p.froct", created=CREATED,
                    progress=lambda stage, done, total: calls.append((stage, done, total)))
    stages = {stage for stage, _, _ in calls}
    assert len(stages) >= 2, calls
    for stage in stages:
        last = [c for c in calls if c[0] == stage][-1]
        assert last[2] == 0 or last[1] == last[2], last
    # progress=True draws tqdm bars (on stderr); it must not change the file.
    froctomap.build(series, tmp_path / "bars.froct", created=CREATED, progress=True)
    assert (tmp_path / "bars.froct").read_bytes() == (tmp_path / "p.froct").read_bytes()


def test_an_exception_in_the_callback_stops_the_build_and_writes_nothing(series, tmp_path):
    calls = []

    def broken(stage, done, total):
        calls.append(stage)
        raise RuntimeError("stop drawing")

    with pytest.raises(RuntimeError, match="stop drawing"):
        froctomap.build(series, tmp_path / "x.froct", progress=broken)
    # The build stopped at its next batch: the callback was not called again, and neither
    # the file nor a temporary is left.
    assert calls == ["checking inputs"]
    assert list(tmp_path.iterdir()) == []


INTERRUPTED = """
import signal, sys, time
import froctomap

# A shell without job control starts background commands with SIGINT ignored, and Python
# then installs no handler of its own (CI runs so): take Ctrl-C as an interactive user does.
signal.signal(signal.SIGINT, signal.default_int_handler)

def slow(stage, done, total):
    print(stage, flush=True)
    time.sleep(1.0)

call = sys.argv[1]
if call == "build":
    froctomap.build(sys.argv[2], sys.argv[3], progress=slow)
elif call == "export":
    froctomap.export(sys.argv[2], sys.argv[3], start="2016-01-04T00:00:00Z",
                     end="2016-01-05T00:00:00Z", every="1h", progress=slow)
elif call == "append":
    froctomap.append(sys.argv[2], sys.argv[3], progress=slow)
elif call == "compact":
    froctomap.compact(sys.argv[2], progress=slow)
print("finished", flush=True)
"""


@pytest.mark.parametrize("call", ["build", "export", "append", "compact"])
def test_ctrl_c_stops_a_long_call_and_leaves_no_output(call, series, cli_file, tmp_path):
    """SIGINT while the work runs (its progress callback slowed down so that the signal
    comes first): KeyboardInterrupt once the work stopped at its next batch, and nothing
    written, no temporary left."""
    import shutil
    import signal
    import subprocess
    import sys

    script = tmp_path / "interrupted.py"
    script.write_text(INTERRUPTED)
    work = tmp_path / "work"
    work.mkdir()
    if call == "build":
        args, output = [series, work / "out.froct"], work / "out.froct"
    elif call == "export":
        args, output = [cli_file, work / "maps.mcap"], work / "maps.mcap"
    else:
        rows = manifest_times(series)
        base = work / "base.froct"
        froctomap.build([(int(t), p.read_bytes()) for p, t in rows[:6]], base, progress=False)
        later = tmp_path / "later.csv"
        later.write_text("path,time\n" + "".join(f"{p},{t}\n" for p, t in rows[6:]))
        args, output = [base, later], base
        if call == "compact":
            # A living map of a base and a segment, compacted in place.
            froctomap.append(base, later, format_version="2.0", progress=False)
            args = [base]
    before = output.read_bytes() if output.exists() else None
    child = subprocess.Popen([sys.executable, str(script), call, *map(str, args)],
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    first = child.stdout.readline()
    assert first.strip(), child.stderr.read()
    child.send_signal(signal.SIGINT)
    out, err = child.communicate(timeout=300)
    assert "finished" not in out
    assert err.rstrip().endswith("KeyboardInterrupt"), err
    if before is None:
        assert not output.exists()
    else:
        assert output.read_bytes() == before
    left = sorted(p.name for p in work.iterdir())
    assert left == ([output.name] if before is not None else []), left


def test_maps_outlive_the_closed_file(cli_file):
    file = froctomap.open(cli_file)
    m = file.retrieve("index:0")
    file.close()
    assert m.to_bt_bytes()
    with pytest.raises(froctomap.FroctError, match="closed"):
        file.retrieve("index:0")
    assert "closed" in repr(file)


def test_skipped_inputs_are_dicts_with_a_code(series, tmp_path):
    """Each input `skip_bad` leaves out is {"path", "code", "message"}, as `build --json`
    gives it: a truncated .bt, a file that is no map, an empty file, a map of another
    resolution (rewritten by octomap-python, an independent writer)."""
    import shutil
    copy = tmp_path / "maps"
    shutil.copytree(series, copy)
    files = snapshot_files(copy)
    data = files[1].read_bytes()
    files[1].write_bytes(data[:-7])
    files[3].write_text("timestamp,x,y,z\n1,2,3,4\n")
    files[5].write_bytes(b"")
    tree = octomap.OcTree(0.2)
    tree.updateNode(np.array([1.0, 2.0, 0.5]), True)
    tree.writeBinary(str(files[7]).encode())
    expected = {files[1]: "malformed", files[3]: "not-a-map", files[5]: "empty",
                files[7]: "resolution-mismatch"}
    report = froctomap.build(copy, tmp_path / "py.froct", skip_bad=True, progress=False)
    cli = json.loads(run_cli("-q", "build", copy, "-o", tmp_path / "cli.froct", "--skip-bad",
                             "--json").stdout)
    for skipped in (report["skipped"], cli["skipped"]):
        assert all(sorted(entry) == ["code", "message", "path"] for entry in skipped), skipped
        assert {Path(e["path"]): e["code"] for e in skipped} == expected, skipped
        assert all(e["message"] for e in skipped), skipped
    assert report["skipped"] == cli["skipped"]
    assert report["used"] == len(files) - 4
