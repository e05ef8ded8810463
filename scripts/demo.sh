#!/usr/bin/env bash
# The main job on built-in sample data, end to end:
#   1. generate three days of OctoMap snapshots (every 30 min) of the real FR-079 corridor
#      (geb079.bt from liboctomap-dev) with doors, people, objects, machines, sensor noise
#      and partial views — doors driven by a real office door's recordings when ../shared has
#      them;
#   2. build one FROctomap file from the first two days;
#   3. print its info; retrieve a past time (checked byte for byte against the input, read
#      by upstream OctoMap); predict the held-out third day (read by upstream OctoMap);
#   4. evaluate reconstruction and prediction against the inputs and the held-out day.
set -euo pipefail
cd "$(dirname "$0")/.."

scripts/install-deps.sh
cargo build --release --locked -q -p froctomap-cli
froctomap=target/release/froctomap
out=target/demo
rm -rf "$out"
mkdir -p "$out"

doors=()
if [ -f ../shared/data/greg_door_2016_min/training_data.txt ]; then
  doors=(--real-doors ../shared/data/greg_door_2016_min/training_data.txt)
fi

echo "== froctomap generate: 3 days every 30 minutes from geb079.bt"
"$froctomap" generate --days 3 --step 30min --seed 7 "${doors[@]}" -o "$out/series"

echo
echo "== froctomap build: the first two days -> one file"
"$froctomap" build "$out/series/frame_2016010[45]T*.bt" -o "$out/office.froct"

echo
echo "== froctomap info"
"$froctomap" info "$out/office.froct"

echo
echo "== froctomap retrieve: the map as observed on 2016-01-05 at 10:00"
"$froctomap" retrieve "$out/office.froct" --time 2016-01-05T10:00:00Z -o "$out/past.bt"
cmp "$out/past.bt" "$out/series/frame_20160105T100000Z.bt"
echo "ok: byte-identical to the input snapshot"
convert_octree "$out/past.bt" "$out/past_upstream.ot" >/dev/null 2>&1
echo "ok: upstream convert_octree reads it"

echo
echo "== froctomap predict: the held-out third day, 10:00"
"$froctomap" predict "$out/office.froct" --time 2016-01-06T10:00:00Z -o "$out/future.ot"
convert_octree "$out/future.ot" "$out/future_upstream.bt" >/dev/null 2>&1
echo "ok: upstream convert_octree reads it"

echo
echo "== froctomap eval: reconstruction of the two days, prediction of the third"
"$froctomap" eval --quiet "$out/office.froct" --against "$out/series/frame_2016010[45]T*.bt" "$out/series/frame_20160106T*.bt"
