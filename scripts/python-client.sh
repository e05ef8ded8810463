#!/usr/bin/env bash
# Creates a Python venv with the PyPI package octomap-python (upstream OctoMap 1.10, linked
# statically): a second, separately built OctoMap client for interoperability tests.
# Usage: scripts/python-client.sh VENV_DIR   (idempotent)
set -euo pipefail
venv=${1:?usage: python-client.sh VENV_DIR}
version=1.10.0.0
if "$venv/bin/python" -c "import octomap" 2>/dev/null; then
  exit 0
fi
python=$(command -v python3 || true)
if [ -z "$python" ]; then
  echo "python-client.sh: python3 is missing (install python3 and python3-venv)" >&2
  exit 1
fi
# Build in a sibling directory and rename, so concurrent test processes never see half a venv.
tmp="$venv.tmp.$$"
rm -rf "$tmp"
"$python" -m venv "$tmp"
"$tmp/bin/python" -m pip install --quiet --disable-pip-version-check "octomap-python==$version"
rm -rf "$venv"
mv "$tmp" "$venv"
# Paths inside a venv are absolute; re-create the launcher links for the final location.
"$python" -m venv --upgrade "$venv" >/dev/null
"$venv/bin/python" -c "import octomap" || { echo "python-client.sh: octomap-python did not import" >&2; exit 1; }
