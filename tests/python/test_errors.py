"""Bad inputs raise froctomap.FroctError (an OSError and a ValueError) with the command
line's message."""

from __future__ import annotations

import errno
import shutil
import warnings

import pytest

import froctomap
from conftest import cli_error, run_cli, snapshot_files


def test_a_missing_file_is_an_os_error_with_the_cli_message(tmp_path):
    missing = tmp_path / "nowhere.froct"
    with pytest.raises(froctomap.FroctError) as caught:
        froctomap.open(missing)
    assert isinstance(caught.value, OSError) and isinstance(caught.value, ValueError)
    assert caught.value.errno == errno.ENOENT
    assert str(caught.value) == cli_error("retrieve", missing, "--time", "last", "-o",
                                          tmp_path / "x.bt")
    with pytest.raises(OSError):
        froctomap.open(missing)


@pytest.mark.parametrize("damage", ["truncated", "flipped", "empty", "text"])
def test_a_corrupt_file_is_refused_with_the_cli_message(cli_file, tmp_path, damage):
    data = cli_file.read_bytes()
    bad = tmp_path / f"{damage}.froct"
    if damage == "truncated":
        bad.write_bytes(data[: len(data) // 2])
    elif damage == "flipped":
        bad.write_bytes(data[:100] + bytes([data[100] ^ 0xFF]) + data[101:])
    elif damage == "empty":
        bad.write_bytes(b"")
    else:
        bad.write_text("not a map at all\n")
    with pytest.raises(froctomap.FroctError) as caught:
        froctomap.open(bad)
    assert str(caught.value) == cli_error("retrieve", bad, "--time", "last", "-o", tmp_path / "x.bt")


def test_a_map_file_is_not_a_series(series, tmp_path):
    snapshot = snapshot_files(series)[0]
    with pytest.raises(froctomap.FroctError) as caught:
        froctomap.open(snapshot)
    assert str(caught.value) == cli_error("retrieve", snapshot, "--time", "last", "-o", tmp_path / "x.bt")


@pytest.mark.parametrize("when", ["2016-01-03T00:00:00Z", "index:12", "index:-13", "index:x",
                                  "soon", "2300-01-01T00:00:00Z"])
def test_times_outside_the_axis_or_unreadable_raise_the_cli_message(cli_file, tmp_path, when):
    f = froctomap.open(cli_file)
    with pytest.raises(froctomap.FroctError) as caught:
        f.retrieve(when)
    assert isinstance(caught.value, ValueError)
    assert str(caught.value) == cli_error("retrieve", cli_file, "--time", when, "-o", tmp_path / "x.bt")


@pytest.mark.parametrize("when", ["index:12", "index:-13", "soon"])
def test_predict_refuses_what_the_cli_refuses(cli_file, tmp_path, when):
    f = froctomap.open(cli_file)
    with pytest.raises(froctomap.FroctError) as caught:
        f.predict(when)
    assert str(caught.value) == cli_error("predict", cli_file, "--time", when, "-o", tmp_path / "x.bt")


def test_a_time_after_the_last_snapshot_warns(cli_file):
    f = froctomap.open(cli_file)
    with pytest.warns(UserWarning, match="outside the file's span"):
        m = f.retrieve("2016-02-01T00:00:00Z")
    assert m.sample == len(f) - 1
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        f.retrieve("index:-1")


def test_wrong_types_are_type_errors(cli_file):
    f = froctomap.open(cli_file)
    for bad in [None, [1], True, object()]:
        with pytest.raises(TypeError):
            f.retrieve(bad)


def test_build_errors_carry_the_cli_message(series, tmp_path):
    missing = tmp_path / "none"
    with pytest.raises(froctomap.FroctError) as caught:
        froctomap.build(missing, tmp_path / "x.froct", progress=False)
    assert str(caught.value) == cli_error("build", missing, "-o", tmp_path / "x.froct")
    # An output that is one of the inputs is refused and the input left alone.
    inputs = tmp_path / "inputs"
    shutil.copytree(series, inputs)
    victim = snapshot_files(inputs)[0]
    before = victim.read_bytes()
    with pytest.raises(froctomap.FroctError) as caught:
        froctomap.build(inputs, victim, progress=False)
    assert str(caught.value) == cli_error("build", inputs, "-o", victim)
    assert victim.read_bytes() == before
    with pytest.raises(froctomap.FroctError, match="unknown model"):
        froctomap.build(series, tmp_path / "y.froct", model="nonsense", progress=False)
    with pytest.raises(froctomap.FroctError, match="order"):
        froctomap.build(series, tmp_path / "y.froct", model="static", order=2, progress=False)
    assert not (tmp_path / "x.froct").exists() and not (tmp_path / "y.froct").exists()


def test_writing_over_the_file_itself_is_refused(cli_file, tmp_path):
    copy = tmp_path / "copy.froct"
    shutil.copy(cli_file, copy)
    f = froctomap.open(copy)
    with pytest.raises(froctomap.FroctError):
        f.retrieve("index:0").write(copy, format="bt")
    assert copy.read_bytes() == cli_file.read_bytes()


def test_evaluate_of_a_missing_file_raises(tmp_path, series):
    with pytest.raises(froctomap.FroctError) as caught:
        froctomap.evaluate(tmp_path / "none.froct", series)
    assert str(caught.value) == cli_error("eval", tmp_path / "none.froct", "--against", series)


def test_a_resealed_huge_outlier_varint_raises_instead_of_a_wrong_map(series, tmp_path):
    # Issue 29: the query path skipped the check the full walk makes, and `retrieve`
    # returned a map with extra leaves.
    from hostile import with_huge_outlier_varint

    raw = tmp_path / "raw.froct"
    run_cli("-q", "build", series, "-o", raw, "--zstd-level", "0", "--toggle-block", "4")
    bad = tmp_path / "resealed.froct"
    bad.write_bytes(with_huge_outlier_varint(raw.read_bytes()))
    f = froctomap.open(bad)  # the header, index and checksums are intact
    m = f.retrieve("index:0")  # maps are read when used
    with pytest.raises(froctomap.FroctError) as caught:
        m.to_bt_bytes()
    assert "resealed.froct" in str(caught.value)
    assert "toggle beyond the time axis" in str(caught.value)
    assert str(caught.value) == cli_error("retrieve", bad, "--time", "index:0", "-o",
                                          tmp_path / "x.bt")
    with pytest.raises(froctomap.FroctError):
        len(f.retrieve("index:-1"))
    # A prediction reads the models only, which the damaged list cannot shift: it is the
    # intact file's, never a different map.
    assert (f.predict("2016-01-04T05:00:00Z").to_bt_bytes()
            == froctomap.open(raw).predict("2016-01-04T05:00:00Z").to_bt_bytes())


def test_a_hostile_mcap_length_raises_instead_of_aborting_the_interpreter(tmp_path):
    # Issue 29: a record length of 0xFFFFFFFF inside an MCAP file reached the `mcap`
    # crate's reserve and aborted the process (a notebook kernel died).
    from hostile import ROOT_FIXTURES, with_chunk_compression_length

    bad = tmp_path / "hostile.mcap"
    bad.write_bytes(with_chunk_compression_length((ROOT_FIXTURES / "ros" / "two_maps_zstd.mcap").read_bytes()))
    with pytest.raises(froctomap.FroctError) as caught:
        froctomap.build(bad, tmp_path / "x.froct", progress=False)
    assert "hostile.mcap" in str(caught.value)
    assert "a string runs past its record" in str(caught.value)
    assert str(caught.value) == cli_error("build", bad, "-o", tmp_path / "x.froct")
    assert not (tmp_path / "x.froct").exists()


def test_errno_is_set_whatever_call_met_the_missing_file(tmp_path):
    """`errno` comes from the operating-system error behind a failure in every call, not
    only in `open` (a build of a missing directory had none)."""
    missing = tmp_path / "nodir"
    calls = [
        lambda: froctomap.open(missing),
        lambda: froctomap.build(f"{missing}/", tmp_path / "x.froct", progress=False),
        lambda: froctomap.build([missing / "a.bt"], tmp_path / "x.froct", progress=False),
        lambda: froctomap.info(missing),
        lambda: froctomap.convert(missing, tmp_path / "x.ot"),
        lambda: froctomap.compact(missing, tmp_path / "x.froct", progress=False),
        lambda: froctomap.evaluate(missing, [tmp_path], progress=False),
    ]
    for i, call in enumerate(calls):
        with pytest.raises(froctomap.FroctError) as caught:
            call()
        assert caught.value.errno == errno.ENOENT, (i, str(caught.value))
    # A failure without an operating-system cause has none.
    with pytest.raises(froctomap.FroctError) as caught:
        froctomap.message_from_map(b"P6\n")
    assert caught.value.errno is None
