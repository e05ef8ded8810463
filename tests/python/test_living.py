"""Format 2.0 files (a base and committed segments) from Python: `open` reads them as the
command line does, every map comes back as its input, and `refresh()` sees a segment
committed after the file was opened. Whole-history queries ask for `compact` first.

The segments are written by the e2e crate's `living_segment` example (no command writes
segments yet): FROCTOMAP_LIVING_SEGMENT, else target/debug/examples/living_segment."""

from __future__ import annotations

import os
import subprocess
from pathlib import Path

import pytest

import froctomap
from conftest import CREATED, ROOT, run_cli, snapshot_files


def living_segment(*args: object) -> None:
    tool = Path(os.environ.get(
        "FROCTOMAP_LIVING_SEGMENT", ROOT / "target" / "debug" / "examples" / "living_segment"))
    if not tool.is_file():
        pytest.fail(f"{tool}: missing (cargo build -p froctomap-e2e-tests --example "
                    "living_segment, or set FROCTOMAP_LIVING_SEGMENT)")
    subprocess.run([str(tool), *map(str, args)], check=True, capture_output=True)


@pytest.fixture(scope="module")
def parts(series: Path, tmp_path_factory) -> dict:
    """1.x builds of the series' maps 0–5, 6–8 and 9–11, and the inputs."""
    maps = snapshot_files(series)
    assert len(maps) == 12
    out = tmp_path_factory.mktemp("living")
    built = {"maps": maps, "dir": out}
    for name, chosen in [("base", maps[:6]), ("seg1", maps[6:9]), ("seg2", maps[9:])]:
        built[name] = out / f"{name}.froct"
        run_cli("-q", "build", *chosen, "-o", built[name], "--created", CREATED)
    return built


def fresh_living(parts: dict, name: str) -> Path:
    """A 2.0 file of the base and the first segment."""
    path = parts["dir"] / name
    living_segment("convert", parts["base"], path)
    living_segment("append", path, parts["seg1"])
    return path


def test_every_map_comes_back_and_refresh_sees_a_new_segment(parts: dict) -> None:
    path = fresh_living(parts, "living.froct")
    maps = parts["maps"]
    f = froctomap.open(path)
    idle = froctomap.open(path)  # no map taken from it: refreshed in place
    assert (f.version, f.segments, len(f)) == ("2.0", 1, 9)
    assert f.info["living"]["segments"][0]["samples"] == 3
    for i in range(9):
        assert f.retrieve(f"index:{i}").to_bt_bytes() == maps[i].read_bytes(), i
    # Between two maps of the segment: the one at or before.
    mid = (f.times[7] + f.times[8]) / 2
    assert f.retrieve(mid).to_bt_bytes() == maps[7].read_bytes()
    last = f.retrieve("last")

    living_segment("append", path, parts["seg2"])
    assert len(f) == 9 and len(idle) == 9  # the view taken at open
    assert f.refresh() is True
    assert idle.refresh() is True
    assert f.refresh() is False
    assert (f.segments, len(f), len(idle)) == (2, 12, 12)
    for i in range(9, 12):
        assert f.retrieve(f"index:{i}").to_bt_bytes() == maps[i].read_bytes(), i
        assert idle.retrieve(f"index:{i}").to_bt_bytes() == maps[i].read_bytes(), i
    # A map taken before the refresh keeps its view.
    assert last.to_bt_bytes() == maps[8].read_bytes()

    # octomap-python reads a map of the segments as it reads the input.
    import octomap

    def leaves(data: bytes) -> int:
        tree = octomap.OcTree(0.1)
        assert tree.readBinary(data)
        return sum(1 for _ in tree.begin_leafs())

    retrieved = f.retrieve("index:10").to_bt_bytes()
    assert leaves(retrieved) == leaves(maps[10].read_bytes()) > 0

    # Predictions are the command line's, byte for byte.
    later = "2016-01-06T10:00:00Z"
    cli = parts["dir"] / "later.ot"
    run_cli("-q", "predict", path, "--time", later, "-o", cli)
    assert f.predict(later).to_ot_bytes() == cli.read_bytes()


def test_whole_history_queries_ask_for_compact_first(parts: dict) -> None:
    path = fresh_living(parts, "to-compact.froct")
    f = froctomap.open(path)
    with pytest.raises(froctomap.FroctError, match="froctomap compact"):
        f.history((0.0, 0.0, 0.0))
    with pytest.raises(froctomap.FroctError, match="1 segment"):
        f.probability("2016-01-05T00:00:00Z", [[0.0, 0.0, 0.0]])
    run_cli("-q", "compact", path, "--created", CREATED)
    f.close()
    g = froctomap.open(path)
    assert (g.version, g.segments, len(g)) == ("2.0", 0, 9)
    assert g.probability("2016-01-05T00:00:00Z", [[0.0, 0.0, 0.0]]).shape == (1,)
    for i in range(9):
        assert g.retrieve(f"index:{i}").to_bt_bytes() == parts["maps"][i].read_bytes(), i


def test_a_lossy_compaction_is_the_command_lines_and_never_in_place(parts: dict) -> None:
    path = fresh_living(parts, "to-lossy.froct")
    before = path.read_bytes()
    with pytest.raises(froctomap.FroctError, match="lossy compaction in place"):
        froctomap.compact(path, lossy=True, progress=False)
    assert path.read_bytes() == before
    ours = parts["dir"] / "lossy-python.froct"
    cli = parts["dir"] / "lossy-cli.froct"
    report = froctomap.compact(path, ours, lossy=True, created=CREATED, progress=False)
    run_cli("-q", "compact", path, "-o", cli, "--lossy", "--created", CREATED)
    assert ours.read_bytes() == cli.read_bytes()
    assert froctomap.open(ours).info["outliers"] == "lossy"
    assert report["bytes"] == ours.stat().st_size


def test_a_tile_budget_deepens_the_tiles_as_the_command_line_does(parts: dict) -> None:
    path = fresh_living(parts, "to-budget.froct")
    depth = froctomap.open(path).info["tile_depth"]
    kept = parts["dir"] / "budget-none.froct"
    report = froctomap.compact(path, kept, tile_budget=None, progress=False)
    assert (report["tile_depth_before"], report["tile_depth"]) == (depth, depth)
    # A budget of one byte: one level deeper, as the command line's --tile-budget 1.
    ours = parts["dir"] / "budget-python.froct"
    cli = parts["dir"] / "budget-cli.froct"
    report = froctomap.compact(path, ours, tile_budget=1, created=CREATED, progress=False)
    run_cli("-q", "compact", path, "-o", cli, "--tile-budget", "1", "--created", CREATED)
    assert ours.read_bytes() == cli.read_bytes()
    assert report["tile_depth"] == froctomap.open(ours).info["tile_depth"] == depth + 1
    g = froctomap.open(ours)
    for i in range(len(g)):
        assert g.retrieve(f"index:{i}").to_bt_bytes() == parts["maps"][i].read_bytes(), i
    assert froctomap.DEFAULT_TILE_BUDGET == 32 << 20
    with pytest.raises(froctomap.FroctError, match="tile_budget"):
        froctomap.compact(path, parts["dir"] / "zero.froct", tile_budget=0, progress=False)


def test_a_compaction_into_smaller_tiles_is_the_command_lines(parts: dict) -> None:
    path = fresh_living(parts, "to-small-tiles.froct")
    ours = parts["dir"] / "small-tiles-python.froct"
    cli = parts["dir"] / "small-tiles-cli.froct"
    froctomap.compact(path, ours, tile_depth=13, created=CREATED, progress=False)
    run_cli("-q", "compact", path, "-o", cli, "--tile-depth", "13", "--created", CREATED)
    assert ours.read_bytes() == cli.read_bytes()
    g = froctomap.open(ours)
    assert g.info["tile_depth"] == 13
    for i in range(len(g)):
        assert g.retrieve(f"index:{i}").to_bt_bytes() == parts["maps"][i].read_bytes(), i
    with pytest.raises(froctomap.FroctError, match="tile depth 9"):
        froctomap.compact(path, parts["dir"] / "coarser.froct", tile_depth=9, progress=False)
