#!/usr/bin/env bash
# Creates a Python venv with the froctomap package built from this checkout (`pip install .`,
# a release build through maturin) and what its tests use: pytest, numpy, dask[distributed],
# tqdm, octomap-python (an independent OctoMap reader of the package's .bt bytes), and rosbags,
# mcap and mcap-ros2-support (independent readers of ROS messages and MCAP files).
# Usage: scripts/python-package.sh VENV_DIR
# The tools are installed once; the package is rebuilt on every run (cargo reuses its cache).
set -euo pipefail
cd "$(dirname "$0")/.."
venv=${1:?usage: python-package.sh VENV_DIR}
tools=(maturin==1.16.0 numpy==2.4.6 pytest==9.2.0 "dask[distributed]==2026.8.0" tqdm==4.70.1
       octomap-python==1.10.0.0 rosbags==0.11.9 mcap==1.6.0 mcap-ros2-support==0.6.0)
check="import maturin, numpy, pytest, dask.distributed, tqdm, octomap, rosbags, mcap, mcap_ros2"
python=$(command -v python3 || true)
if [ -z "$python" ]; then
  echo "python-package.sh: python3 is missing (install python3 and python3-venv)" >&2
  exit 1
fi
if ! "$venv/bin/python" -c "$check" 2>/dev/null; then
  # Build in a sibling directory and rename, so a half-made venv is never used.
  tmp="$venv.tmp.$$"
  rm -rf "$tmp"
  "$python" -m venv "$tmp"
  "$tmp/bin/python" -m pip install --quiet --disable-pip-version-check "${tools[@]}"
  rm -rf "$venv"
  mv "$tmp" "$venv"
  "$python" -m venv --upgrade "$venv" >/dev/null
fi
# `pip install .` as a user runs it, with the pinned maturin instead of a fresh download
# (whose Python hook runs the `maturin` program of the venv, hence PATH).
PATH="$venv/bin:$PATH" "$venv/bin/python" -m pip install --quiet --disable-pip-version-check --no-build-isolation \
  --force-reinstall --no-deps .
"$venv/bin/python" -c "import froctomap; print('froctomap', froctomap.__version__)"
