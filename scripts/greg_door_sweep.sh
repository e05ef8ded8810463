#!/usr/bin/env bash
# Sweeps the model options on the greg_door room's VALIDATION split only
# (`froctomap-bench greg-door --validate`: fit on training weeks 1-6, scored on the held-back
# training weeks 7-10; the test weeks are not read) and prints one markdown row per setting:
# mean Brier model / static mean, the largest weekly excess of the thresholded error over the
# static mean's, and the door's kept periods. How the defaults were chosen: docs/BENCHMARKS.md.
#
#   scripts/greg_door_sweep.sh [--data DIR] [--python PY] [--out DIR] [-- EXTRA-OPTION...]
#
# Each extra argument after `--` is one more `key=value` option added to every setting.
# Needs a release froctomap-bench (cargo build --release -p froctomap-bench) and numpy
# (scripts/python-client.sh target/interop-venv).
set -euo pipefail
cd "$(dirname "$0")/.."

data=../shared/data/greg_door_2016_min
python=target/interop-venv/bin/python
out=target/greg-door-sweep
extra=()
while [ $# -gt 0 ]; do
  case "$1" in
    --data) data=$2; shift 2 ;;
    --python) python=$2; shift 2 ;;
    --out) out=$2; shift 2 ;;
    --) shift; extra=("$@"); break ;;
    *) echo "greg_door_sweep.sh: unknown argument $1" >&2; exit 2 ;;
  esac
done
bench=target/release/froctomap-bench
[ -x "$bench" ] || { echo "greg_door_sweep.sh: build $bench first" >&2; exit 2; }

echo "| harmonics | max-order | shrink | min-cycles | extra | model / static Brier | worst excess (pp) | FreMEn k=4 / static | door periods (h) |"
echo "| ---: | ---: | --- | ---: | --- | ---: | ---: | ---: | --- |"
for harmonics in 24 48; do
  for max_order in 5 6 8; do
    for shrink in off auto; do
      for min_cycles in 1.5 2 3; do
        name=h$harmonics-m$max_order-s$shrink-c$min_cycles
        options=(harmonics=$harmonics max-order=$max_order shrink=$shrink min-cycles=$min_cycles "${extra[@]}")
        args=()
        for o in "${options[@]}"; do args+=(--option "$o"); done
        "$bench" greg-door --validate --size full --data "$data" --python "$python" \
          --out "$out/$name" "${args[@]}" >/dev/null 2>"$out.log" \
          || { echo "greg_door_sweep.sh: $name failed, see $out.log" >&2; exit 1; }
        jq -r --arg h "$harmonics" --arg m "$max_order" --arg s "$shrink" --arg c "$min_cycles" \
          --arg e "${extra[*]:-}" \
          '"| \($h) | \($m) | \($s) | \($c) | \($e) | \(.summary.model_vs_static * 1000 | round / 1000) | \(.summary.worst_excess_pp * 100 | round / 100) | \(.summary.reference_vs_static * 1000 | round / 1000) | \([.door_periods[] / 360 | round / 10] | join(", ")) |"' \
          "$out/$name/results.json"
      done
    done
  done
done
