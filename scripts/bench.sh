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
set -euo pipefail
cd "$(dirname "$0")/.."

scripts/install-deps.sh
# The CLI is built too, so that the benchmark can time `froctomap retrieve`/`predict` as
# processes (it looks for `froctomap` beside its own binary).
cargo build --release --locked -q -p froctomap-cli -p froctomap-bench
exec cargo run --release --locked -q -p froctomap-bench -- run "$@"
