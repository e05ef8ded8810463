#!/usr/bin/env bash
# The whole test suite: installs missing system packages, prepares the second OctoMap client
# (octomap-python in a venv), checks formatting and lints, then runs every test and doc test.
set -euo pipefail
cd "$(dirname "$0")/.."

scripts/install-deps.sh
venv="$PWD/target/interop-venv"
scripts/python-client.sh "$venv"
export FROCTOMAP_PYTHON="$venv/bin/python"

cargo fmt --all --check
cargo clippy --workspace --all-targets --locked -- -D warnings
cargo test --workspace --locked "$@"
