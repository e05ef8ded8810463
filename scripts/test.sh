#!/usr/bin/env bash
# The whole test suite: installs missing system packages, prepares the second OctoMap client
# (octomap-python in a venv), checks formatting and lints, runs every test and doc test,
# builds the fuzz targets and runs each on a short seeded smoke campaign.
set -euo pipefail
cd "$(dirname "$0")/.."

# Each step's wall time, printed when the script ends (also on failure): where CI's minutes go.
timings=()
step() {
  local start=$SECONDS what="$*"
  "$@"
  timings+=("$((SECONDS - start)) s: ${what:0:100}")
}
report_timings() {
  local status=$?
  if [ ${#timings[@]} -gt 0 ]; then
    echo "test.sh: time per step (${SECONDS} s in all)" >&2
    printf '  %s\n' "${timings[@]}" >&2
  fi
  [ -n "${corpus:-}" ] && rm -rf "$corpus"
  return $status
}
trap report_timings EXIT

step scripts/install-deps.sh
venv="$PWD/target/interop-venv"
step scripts/python-client.sh "$venv"
export FROCTOMAP_PYTHON="$venv/bin/python"

cargo fmt --all --check
step cargo clippy --workspace --all-targets --locked -- -D warnings
step cargo test --workspace --locked "$@"
# `froctomap ros2` (cargo feature `ros2`, off by default) against the Cyclone DDS peer, on
# loopback; its code linted with the feature on.
# `froctomap ros2 --foxglove` (cargo feature `foxglove`, implies `ros2`): a WebSocket client
# on loopback against the Foxglove server. Both tests run in one build with `foxglove` on
# (a second feature set costs a whole compile of the CLI); clippy still sees `ros2` alone.
step cargo clippy --locked -p froctomap-cli --features ros2 --all-targets -- -D warnings
step cargo clippy --locked -p froctomap-cli --features foxglove --all-targets -- -D warnings
step cargo test --locked -p froctomap-cli --features foxglove --test ros2 --test foxglove

# The README's Install section: `cargo install` of the CLI (debug profile, reusing this
# build's artifacts), then the installed binary runs from outside the checkout; the pure-Rust
# route (no liboctomap) must keep compiling.
step cargo install --locked --quiet --debug --force --path crates/cli --root target/install --target-dir target
installed="$PWD/target/install/bin/froctomap"
(cd / && "$installed" --version && "$installed" formats >/dev/null)
[[ $(cd / && "$installed" man) == *".TH froctomap"* ]] || { echo "installed froctomap: no manual page" >&2; exit 1; }
[[ $(cd / && "$installed" completions bash) == *"_froctomap"* ]] || { echo "installed froctomap: no completions" >&2; exit 1; }
step cargo check --locked --quiet -p froctomap-cli --no-default-features

# The library crates build and test without liboctomap: the C++ backend is an opt-in
# feature that only the CLI, the benchmark and the interop tests turn on.
libraries=(-p froctomap-core -p froctomap-octomap-codec -p froctomap-formats -p froctomap-temporal
           -p froctomap-file -p froctomap-convert -p froctomap-synth)
for library in "${libraries[@]}"; do
  [[ $library == -p ]] && continue
  if cargo tree --locked -p "$library" -e normal,dev | grep -q froctomap-octomap-ffi; then
    echo "$library depends on liboctomap without the octomap-upstream feature" >&2
    exit 1
  fi
done
# Built (all targets) without it; only the format registry differs in behaviour without the
# feature (its default backend), so only its tests run again: the workspace step ran the rest.
step cargo check --locked --all-targets "${libraries[@]}"
step cargo test --locked -p froctomap-formats

# The Python package: `pip install .` into a venv (a release build of crates/python through
# maturin), then its tests against the command line built above (tests/python: round trips
# byte for byte, octomap-python reading its maps, the Dask fleet example of docs/FLEET.md).
step scripts/python-package.sh "$PWD/target/python-venv"
# tests/python/test_living.py writes format 2.0 segments with this example.
step cargo build --locked -p froctomap-e2e-tests --example living_segment
step env FROCTOMAP_BIN="$PWD/target/debug/froctomap" target/python-venv/bin/python -m pytest -q -p no:cacheprovider tests/python

# The fuzz crate is its own workspace (cargo-fuzz layout); it must keep building, and each
# target runs briefly from the fixtures so a crash cannot hide.
step cargo build --locked --manifest-path fuzz/Cargo.toml
corpus=$(mktemp -d)
fuzz_smoke() {
  local target=$1 runs=50000 max_len=4096
  mkdir -p "$corpus/$target"
  case $target in
    read_froct | read_living) cp fixtures/froct/*.froct "$corpus/$target/" ;;
    # The recordings' readers take files (each run writes one): fewer, larger runs.
    read_mcap) cp fixtures/ros/*.mcap "$corpus/$target/"; runs=5000 max_len=16384 ;;
    read_bag) cp fixtures/ros/*.bag "$corpus/$target/"; runs=5000 max_len=16384 ;;
    *) cp fixtures/octomap/* "$corpus/$target/" ;;
  esac
  fuzz/target/debug/$target -runs=$runs -max_len=$max_len -seed=1 "$corpus/$target" 2>&1 | tail -n 1
}
for target in read_bt read_ot roundtrip read_froct read_living read_mcap read_bag; do
  step fuzz_smoke "$target"
done
