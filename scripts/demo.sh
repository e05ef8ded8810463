#!/usr/bin/env bash
# The main job on built-in sample data: inspect the real FR-079 corridor scan (geb079.bt,
# shipped with liboctomap-dev), convert it .bt -> .ot -> .bt with froctomap, and verify both
# outputs against upstream OctoMap's own tools.
set -euo pipefail
cd "$(dirname "$0")/.."

scripts/install-deps.sh
cargo build --release --locked -q -p froctomap-cli
froctomap=target/release/froctomap
sample=/usr/share/doc/liboctomap-dev/examples/data/geb079.bt
out=target/demo
mkdir -p "$out"

echo "== froctomap info $sample"
"$froctomap" info "$sample"

echo
echo "== froctomap convert: .bt -> .ot -> .bt"
"$froctomap" convert "$sample" "$out/geb079.ot"
"$froctomap" convert "$out/geb079.ot" "$out/geb079.bt"

echo
echo "== verification with upstream OctoMap tools"
convert_octree "$sample" "$out/upstream.ot" >/dev/null 2>&1
cmp "$out/geb079.ot" "$out/upstream.ot"
echo "ok: our .ot is byte-identical to convert_octree's ($(stat -c %s "$out/geb079.ot") bytes)"
cmp "$out/geb079.bt" "$sample"
echo "ok: our .bt is byte-identical to the original ($(stat -c %s "$out/geb079.bt") bytes)"
report=$(compare_octrees "$out/geb079.ot" "$out/upstream.ot" 2>&1)
if grep -q '^KLD: 0$' <<<"$report" && ! grep -q 'ERROR' <<<"$report"; then
  echo "ok: compare_octrees finds zero difference ($(grep 'Expanded num. leafs' <<<"$report" | tr -s ' '))"
else
  echo "compare_octrees reports a difference:" >&2
  echo "$report" >&2
  exit 1
fi
