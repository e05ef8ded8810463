#!/usr/bin/env bash
# The long-term benchmark in one line: generates a realistic series from geb079.bt (doors on
# the real door recording, people, chairs, objects, machines, sensor noise, partial views),
# then measures storage (raw .bt, tar | zstd -19 --long=31, tar | xz -9, froctomap lossless
# and lossy orders 0-5), time (build vs the C++ library's read-only time, retrieve/predict
# vs one C++ read, peak memory at two lengths) and accuracy (reconstruction and prediction
# vs the static-mean and last-seen baselines). Prints markdown; writes results.json,
# results.md and PNG plots into --out (default target/bench). See docs/BENCHMARKS.md.
#
#   scripts/bench.sh                        # CI size: 2 days + 1 held-out day, a few minutes
#   scripts/bench.sh --size 4weeks --out docs/benchmarks   # the documented run
#   scripts/bench.sh --help                 # every option
#
# At the CI size it also runs the real-data prediction benchmark at its CI size (the
# greg_door recording as a small room, 3 training weeks, 2 test weeks, against a plain FreMEn
# computed in numpy); the full run is `froctomap-bench greg-door` (docs/BENCHMARKS.md).
set -euo pipefail
cd "$(dirname "$0")/.."

scripts/install-deps.sh
# The CLI is built too, so that the benchmark can time `froctomap retrieve`/`predict` as
# processes (it looks for `froctomap` beside its own binary).
cargo build --release --locked -q -p froctomap-cli -p froctomap-bench
cargo run --release --locked -q -p froctomap-bench -- run "$@"

size=ci
previous=
for arg in "$@"; do
  case "$previous" in --size) size=$arg ;; esac
  case "$arg" in --size=*) size=${arg#--size=} ;; esac
  previous=$arg
done
greg_door=${GREG_DOOR_DATA:-../shared/data/greg_door_2016_min}
if [ "$size" = ci ]; then
  if [ -f "$greg_door/training_data.txt" ]; then
    scripts/python-client.sh target/interop-venv
    # --require-targets: CI fails when a run misses issue 28's targets.
    cargo run --release --locked -q -p froctomap-bench -- greg-door --size ci --require-targets \
      --data "$greg_door" --python target/interop-venv/bin/python --out target/greg-door-ci
    # Its validation mode (training weeks 4-6 fitted, week 7 scored; test weeks not read).
    cargo run --release --locked -q -p froctomap-bench -- greg-door --size ci --validate --require-targets \
      --data "$greg_door" --python target/interop-venv/bin/python --out target/greg-door-ci-validate
  else
    echo "bench.sh: $greg_door/training_data.txt is missing: the greg_door benchmark is skipped" >&2
  fi
fi
