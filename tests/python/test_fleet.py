"""docs/FLEET.md's example, run as written: three small series, built and evaluated on a
Dask LocalCluster of two worker processes, every result checked against the command line."""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

from conftest import CREATED, ROOT, generate, run_cli


def fleet_script() -> str:
    text = (ROOT / "docs" / "FLEET.md").read_text()
    blocks = re.findall(r"```python\n(.*?)```", text, flags=re.S)
    assert len(blocks) == 1, "FLEET.md should hold one Python block, the example"
    return blocks[0]


def test_the_fleet_example_matches_the_command_line(tmp_path):
    robots = []
    for seed in (1, 2, 3):
        robot = tmp_path / "robots" / f"r{seed}"
        generate(robot / "snapshots", "2016-01-04T00:00:00Z", "0.5", "2h", seed=seed)
        generate(robot / "held-out", "2016-01-04T12:00:00Z", "0.25", "3h", seed=seed)
        robots.append(robot)
    script = tmp_path / "fleet.py"
    script.write_text(fleet_script())
    out = tmp_path / "archives"
    results_path = tmp_path / "results.json"
    run = subprocess.run(
        [sys.executable, str(script), *map(str, robots), "--out", str(out), "--workers", "2",
         "--created", CREATED, "--json", str(results_path)],
        capture_output=True, text=True, cwd=tmp_path, timeout=600,
    )
    assert run.returncode == 0, run.stderr
    table = [line for line in run.stdout.splitlines() if line.startswith("| r")]
    assert len(table) == 3, run.stdout
    results = json.loads(results_path.read_text())
    assert [Path(r["robot"]) for r in results] == robots
    for robot, result in zip(robots, results):
        archive = Path(result["archive"])
        reference = tmp_path / f"{robot.name}-cli.froct"
        run_cli("-q", "build", robot / "snapshots", "-o", reference, "--created", CREATED)
        assert archive.read_bytes() == reference.read_bytes(), robot
        assert result["build"]["file_bytes"] == reference.stat().st_size
        evaluation = json.loads(run_cli("-q", "eval", reference, "--against",
                                        robot / "held-out", "--json").stdout)
        assert result["eval"] == evaluation, robot
        assert evaluation["outside"] > 0
