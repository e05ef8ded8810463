"""Fixtures of the Python package's tests: small generated series, the command line's own
outputs for them (the reference every result is compared with), and helpers to run it."""

from __future__ import annotations

import os
import subprocess
from pathlib import Path
from typing import List

import pytest

ROOT = Path(__file__).resolve().parents[2]
#: Creation time stored in every file built here, so builds are byte-reproducible.
CREATED = "2016-01-10T00:00:00Z"


def cli_path() -> Path:
    """The froctomap binary: FROCTOMAP_BIN, else the workspace's debug build."""
    path = Path(os.environ.get("FROCTOMAP_BIN", ROOT / "target" / "debug" / "froctomap"))
    if not path.is_file():
        pytest.fail(f"{path}: no froctomap binary (cargo build -p froctomap-cli, or set FROCTOMAP_BIN)")
    return path


def run_cli(*args: object, check: bool = True) -> subprocess.CompletedProcess:
    """Runs the command line; `check=False` returns failures too."""
    result = subprocess.run(
        [str(cli_path()), *map(str, args)], capture_output=True, text=True
    )
    if check and result.returncode != 0:
        raise AssertionError(f"froctomap {args} failed: {result.stderr}")
    return result


def cli_error(*args: object) -> str:
    """The message of the command line's `error: …` line for a failing command."""
    result = run_cli(*args, check=False)
    assert result.returncode == 1, result
    lines = [l for l in result.stderr.splitlines() if l.startswith("error: ")]
    assert lines, result.stderr
    return lines[0][len("error: "):]


def generate(out: Path, start: str, days: str, step: str, seed: int = 1) -> Path:
    run_cli("-q", "generate", "--start", start, "--days", days, "--step", step,
            "--seed", seed, "-o", out)
    return out


@pytest.fixture(scope="session")
def series(tmp_path_factory) -> Path:
    """One day of snapshots every 2 h (12 maps of the FR-079 corridor with doors, people)."""
    return generate(tmp_path_factory.mktemp("series") / "maps", "2016-01-04T00:00:00Z", "1", "2h")


@pytest.fixture(scope="session")
def held_out(tmp_path_factory) -> Path:
    """The half day after `series`, every 3 h: ground truth for prediction."""
    return generate(tmp_path_factory.mktemp("held_out") / "maps", "2016-01-05T00:00:00Z", "0.5", "3h")


@pytest.fixture(scope="session")
def cli_file(series: Path, tmp_path_factory) -> Path:
    """The command line's build of `series`."""
    out = tmp_path_factory.mktemp("cli") / "office.froct"
    run_cli("-q", "build", series, "-o", out, "--created", CREATED)
    return out


def snapshot_files(series: Path) -> List[Path]:
    return sorted(p for p in series.iterdir() if p.suffix == ".bt")
