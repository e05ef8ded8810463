"""Point queries (`probability`, `history`) against the predicted maps and the input
snapshots, both read by octomap-python."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import octomap
import pytest

import froctomap
from conftest import run_cli, snapshot_files

# OctoMap's clamping bounds of stored probabilities (log-odds -2 and 3.5).
CLAMP = (0.1192, 0.971)


@pytest.fixture(scope="module")
def f(cli_file: Path):
    return froctomap.open(cli_file)


def tree_of_ot(data: bytes) -> "octomap.OcTree":
    """An .ot file's bytes read by octomap-python (log-odds kept)."""
    tree = octomap.OcTree.read(data)
    assert tree is not None and tree.size() > 0
    return tree


def read_tree(path: Path) -> "octomap.OcTree":
    tree = octomap.OcTree(0.1)
    assert tree.readBinary(str(path).encode())
    return tree


def node_of(tree, point):
    """The node holding `point`, or None (octomap-python raises on a missing node)."""
    node = tree.search(np.asarray(point, dtype=float))
    try:
        node.getOccupancy()
    except Exception:
        return None
    return node


def points_in_and_around(f, count: int, seed: int) -> np.ndarray:
    occupied, free = f.retrieve("index:0").point_cloud()
    rng = np.random.default_rng(seed)
    cloud = np.vstack([occupied, free])
    low, high = cloud.min(axis=0) - 1.0, cloud.max(axis=0) + 1.0
    inside = cloud[rng.choice(len(cloud), count // 2)]
    anywhere = rng.uniform(low, high, size=(count - count // 2, 3))
    return np.vstack([inside, anywhere, [[1e6, 0.0, 0.0]]])


def test_probability_is_the_predicted_maps_p(f):
    t = "2016-01-06T09:00:00Z"
    points = points_in_and_around(f, 400, seed=7)
    p = f.probability(t, points)
    assert p.dtype == np.float64 and p.shape == (len(points),)
    assert np.isnan(p[-1])
    tree = tree_of_ot(f.predict(t).to_ot_bytes())
    for point, ours in zip(points, p):
        node = node_of(tree, point)
        if node is None:
            assert np.isnan(ours), point
        else:
            assert not np.isnan(ours), point
            expected = node.getOccupancy()
            assert np.clip(ours, *CLAMP) == pytest.approx(expected, abs=1e-5), point
    assert (~np.isnan(p)).sum() > 200


def test_probability_takes_lists_and_sample_queries(f):
    point = f.retrieve("index:0").point_cloud()[0][:1]
    by_list = f.probability("index:2", point.tolist())
    by_time = f.probability(float(f.times[2]), point)
    assert by_list.shape == (1,) and by_list[0] == by_time[0]
    with pytest.raises(ValueError, match="shape"):
        f.probability("index:0", [1.0, 2.0])
    with pytest.raises(froctomap.FroctError):
        f.probability("index:99", point)


def dynamic_points(f, wanted: int):
    """Voxels whose occupancy changes: occupied in some snapshot, free in another."""
    first = {tuple(p) for p in f.retrieve("index:0").point_cloud()[0]}
    found = []
    for sample in range(1, len(f)):
        occupied = f.retrieve(f"index:{sample}").point_cloud()[0]
        for point in occupied:
            if tuple(point) not in first:
                found.append(point)
                if len(found) == wanted:
                    return found
    return found


def test_history_gives_the_states_of_the_input_snapshots(f, series):
    with open(series / "manifest.csv", newline="") as text:
        paths = [series / row["path"] for row in csv.DictReader(text)]
    trees = [read_tree(path) for path in paths]
    points = dynamic_points(f, 5)
    assert points, "the series should have changing voxels"
    for point in points:
        story = f.history(point)
        assert story["class"] in ("dynamic", "noisy")
        assert story["times"].dtype == np.float64
        assert story["states"].shape == story["p"].shape == story["samples"].shape
        assert list(story["times"]) == list(f.times)
        cell_min, cell_max = np.array(story["cell"]["min"]), np.array(story["cell"]["max"])
        assert np.all(cell_min <= point) and np.all(point < cell_max)
        for sample, state in zip(story["samples"], story["states"]):
            node = node_of(trees[sample], point)
            if node is None:
                assert np.isnan(state), (point, sample)
            else:
                assert state == float(trees[sample].isNodeOccupied(node)), (point, sample)
        if story["class"] == "dynamic":
            assert story["model"] is not None and 0.0 <= story["model"]["mean"] <= 1.0
        # The outliers are the samples where the observation and the model disagree.
        observed = ~np.isnan(story["states"])
        disagree = observed & (story["states"] != (story["p"] > 0.5))
        if story["class"] == "dynamic":
            assert list(story["outlier_samples"]) == list(story["samples"][disagree])


def test_history_is_the_command_lines(f, cli_file):
    states = {"free": 0.0, "occupied": 1.0}
    for point in dynamic_points(f, 3):
        story = f.history(point)
        at = ",".join(repr(float(c)) for c in point)
        cli = json.loads(run_cli("history", cli_file, f"--at={at}", "--json").stdout)
        assert (story["class"], story["sometimes_unknown"]) == (cli["class"], cli["sometimes_unknown"])
        for key in ["depth", "size", "center", "min", "max"]:
            assert story["cell"][key] == pytest.approx(cli["cell"][key], rel=1e-12), key
        if cli["model"] is None:
            assert story["model"] is None
        else:
            assert story["model"]["mean"] == pytest.approx(cli["model"]["mean"], rel=1e-12)
            assert len(story["model"]["periodic"]) == len(cli["model"]["periodic"])
        rows = cli["samples"]
        assert list(story["samples"]) == [row["sample"] for row in rows]
        assert list(story["times"]) == [froctomap.parse_time(row["time"]) for row in rows]
        assert list(story["p"]) == pytest.approx([row["p"] for row in rows], rel=1e-12, abs=1e-15)
        expected = [states.get(row["state"], float("nan")) for row in rows]
        assert np.array_equal(story["states"], np.array(expected), equal_nan=True)
        assert list(story["outlier_samples"]) == [row["sample"] for row in rows if row["outlier"]]
        assert len(cli["outliers"]) == len(story["outlier_samples"])


def test_history_ranges_and_refusals(f):
    point = dynamic_points(f, 1)[0]
    part = f.history(point, start="2016-01-04T04:00:00Z", end="2016-01-04T10:00:00Z")
    assert list(part["times"]) == [t for t in f.times
                                   if froctomap.parse_time("2016-01-04T04:00:00Z") <= t
                                   <= froctomap.parse_time("2016-01-04T10:00:00Z")]
    with pytest.raises(froctomap.FroctError):
        f.history((1e6, 0.0, 0.0))
    with pytest.raises(froctomap.FroctError):
        f.history(point, start="2017-01-01T00:00:00Z")
    with pytest.raises(ValueError):
        f.history((1.0, 2.0))


def test_anomalies_are_the_command_lines_and_find_an_injected_box(f, cli_file, held_out, tmp_path):
    snapshot = snapshot_files(held_out)[1]
    clean = f.anomalies(snapshot)
    cli_clean = json.loads(run_cli("anomalies", cli_file, snapshot, "--json").stdout)
    assert clean["regions"] == cli_clean["regions"]
    assert clean["time"] == cli_clean["time"] and clean["unix_time"] == cli_clean["unix_time"]
    assert clean["scored_voxels"] == cli_clean["scored_voxels"] > 0

    # A box of 6 x 6 x 6 voxels put by octomap-python into space the file predicts free.
    tree = read_tree(snapshot)
    resolution = tree.getResolution()
    free = f.predict(clean["unix_time"]).point_cloud()[1]
    corner = free[np.argmin(np.abs(free[:, 2] - 1.0) + np.abs(free[:, 0] - np.median(free[:, 0])))]
    offsets = np.stack(np.meshgrid(*[np.arange(6)] * 3, indexing="ij"), -1).reshape(-1, 3)
    for offset in offsets:
        for _ in range(4):  # a hit adds log-odds 0.85: from free (-2) to occupied
            tree.updateNode(corner + resolution * offset, True)
    tree.updateInnerOccupancy()
    boxed = tmp_path / snapshot.name  # the same name: the time comes from it
    assert tree.writeBinary(str(boxed).encode())

    found = f.anomalies(boxed)
    cli_found = json.loads(run_cli("anomalies", cli_file, boxed, "--json").stdout)
    assert found["regions"] == cli_found["regions"]
    centre = corner + resolution * 2.5
    holding = [r for r in found["regions"]
               if np.all(np.array(r["min"]) <= centre) and np.all(centre <= np.array(r["max"]))]
    assert holding and holding[0]["kind"] == "appeared", (corner, found["regions"][:3])
    assert not any(r["min"] == holding[0]["min"] for r in clean["regions"])
    assert holding[0]["voxels"] >= len(offsets) // 2

    by_time = f.anomalies(boxed, t=clean["time"], expect="static-mean")
    cli_mean = json.loads(run_cli("anomalies", cli_file, boxed, "--json", "--expect", "static-mean").stdout)
    assert by_time["regions"] == cli_mean["regions"]
    with pytest.raises(ValueError, match="expect"):
        f.anomalies(boxed, expect="yesterday")
    with pytest.raises(froctomap.FroctError, match="nothing-here.bt"):
        f.anomalies(tmp_path / "frame_20160105T030000Z_nothing-here.bt")
    unnamed = tmp_path / "snapshot.bt"
    unnamed.write_bytes(boxed.read_bytes())
    with pytest.raises(froctomap.FroctError, match="no time in the file name"):
        f.anomalies(unnamed)


def test_probability_at_many_times_is_each_times_row(f):
    """`probability(times, points)`: a (T, N) array whose rows are the one-time calls, the
    times given as a list, a numpy array of Unix seconds or sample queries."""
    points = points_in_and_around(f, 120, seed=3)
    times = ["2016-01-04T01:00:00Z", 1451901600.5, "index:-1", "2016-02-01T00:00:00Z"]
    p = f.probability(times, points)
    assert p.dtype == np.float64 and p.shape == (len(times), len(points))
    for row, t in zip(p, times):
        np.testing.assert_array_equal(row, f.probability(t, points))
    seconds = np.array([1451869200.0, 1451955600.0])
    np.testing.assert_array_equal(f.probability(seconds, points),
                                  np.vstack([f.probability(s, points) for s in seconds]))
    assert f.probability([], points).shape == (0, len(points))


@pytest.mark.parametrize("kind", ["retrieve", "predict"])
def test_search_is_octomap_pythons_search(f, kind):
    """`Map.search(points)` against octomap-python's `search`/`isNodeOccupied`/
    `getOccupancy` on the map's .ot; `leaves(with_p=True)` holds the same p."""
    m = getattr(f, kind)("2016-01-04T09:00:00Z")
    points = points_in_and_around(f, 300, seed=11)
    state, p = m.search(points)
    assert state.dtype == np.int8 and p.dtype == np.float64 and state.shape == p.shape == (len(points),)
    tree = tree_of_ot(m.to_ot_bytes())
    for point, s, q in zip(points, state, p):
        node = node_of(tree, point)
        if node is None:
            assert (s, np.isnan(q)) == (-1, True), point
        else:
            assert s == int(tree.isNodeOccupied(node)), point
            assert q == pytest.approx(node.getOccupancy(), abs=1e-6), point
    assert (state == 1).any() and (state == 0).any() and (state == -1).any()
    centres, sizes, occupied, leaf_p = m.leaves(with_p=True)
    assert leaf_p.shape == occupied.shape and ((leaf_p > 0.5) == occupied).all()
    assert len(m.leaves()) == 3
    inside = m.search(centres)
    np.testing.assert_array_equal(inside[1], leaf_p)
    if kind == "predict":
        # A prediction's leaves hold p(t), not only states.
        assert len(np.unique(leaf_p)) > 2
