#!/usr/bin/env bash
# The paper's 8-week experiment streamed (issue 26): the generated FR-079 office every 5 s
# for 8 weeks (967,680 maps), `froctomap generate --stream | froctomap record`, no map on
# disk. It takes many hours, more than a machine session, so it runs a week at a time and
# resumes: run it again (after a reboot, a kill, the end of a session) and it continues
# from the file's last sample.
#
#   scripts/eight-weeks.sh [FILE]          # default eight-weeks.froct, log FILE.log
#
# Each week is one `generate --stream --from LAST | record FILE -` pipe under
# /usr/bin/time -v: `generate --from` makes only the frames at or after the file's last
# sample (the same maps a run from the start makes; the frame at LAST itself is skipped by
# `record` as not later), so a resumed week costs what is left of it. A pipe killed
# mid-week leaves the file with every committed segment (a commit every COMMIT maps);
# the next run continues after the last of them. The log gets, per week run, the maps
# recorded, wall and CPU seconds, the peak memory of `record` and of `generate`, and the
# file's size; `record`'s own lines (one per commit) go to FILE.commits.log.
#
# After the last week, the report's steps, each skipped when its output exists (so they
# resume too): `compact FILE` in place (the lossless size), `compact FILE -o
# FILE.lossy.froct --lossy` (the lossy size), and the prediction error on the HELD_OUT
# days after the 8 weeks: `generate --stream --from END | eval FILE --against - --stride
# EVAL_STRIDE --json` into FILE.eval.json (the dynamic voxels' error, against the static mean
# and last seen), each timed with its peak memory in the log.
#
# Settings (environment): G (the froctomap binary, default target/release/froctomap,
# built with `cargo build --release -p froctomap-cli`), SEED (5), STEP_SECS (seconds between
# maps, 5), WEEKS (8),
# COMMIT (maps per commit, default 720: an hour of maps, 1,344 segments in 8 weeks, within
# the format's 65,536), COMPACT (1: `froctomap compact FILE` after each full week, timed
# and logged; default 0), NICE (10), HELD_OUT (days predicted after the weeks, 2),
# EVAL_STRIDE (every how many held-out maps one is compared, 60: every 5 minutes; each map
# compared is checked against every cell of the file).
set -euo pipefail

FILE=${1:-eight-weeks.froct}
LOG=${LOG:-$FILE.log}
G=${G:-target/release/froctomap}
SEED=${SEED:-5}
STEP_SECS=${STEP_SECS:-5}
WEEKS=${WEEKS:-8}
COMMIT=${COMMIT:-720}
COMPACT=${COMPACT:-0}
NICE=${NICE:-10}
HELD_OUT=${HELD_OUT:-2}
EVAL_STRIDE=${EVAL_STRIDE:-60}
# generate's default start: Monday 2016-01-04 00:00 UTC.
START_UNIX=1451865600
WEEK_SECS=$((7 * 86400))

[ -x "$G" ] || { echo "eight-weeks.sh: no $G; build it: cargo build --release -p froctomap-cli" >&2; exit 1; }
log() { echo "$(date -u +%FT%TZ) $*" | tee -a "$LOG" >&2; }

# The file's last sample as Unix seconds (nothing yet: before the start).
last_unix() {
  if [ -e "$FILE" ]; then
    date -u -d "$("$G" info --json "$FILE" | jq -r .time.end)" +%s
  else
    echo $((START_UNIX - 1))
  fi
}

# The peak RSS (KiB) and the CPU seconds /usr/bin/time -v wrote into $1.
peak_kib() { sed -n 's/.*Maximum resident set size (kbytes): //p' "$1"; }
cpu_secs() {
  awk -F': ' '/User time/ {u=$2} /System time/ {s=$2} END {printf "%.1f", u + s}' "$1"
}

log "eight weeks into $FILE: seed $SEED, a map every $STEP_SECS s, $COMMIT maps per commit, $("$G" --version)"
# The last sample is read once here and again only after a week is recorded (`info` used
# to walk every tile of a compacted file: a minute on the 8 weeks').
last=$(last_unix)
for week in $(seq 1 "$WEEKS"); do
  week_end=$((START_UNIX + week * WEEK_SECS))
  if [ "$last" -ge $((week_end - STEP_SECS)) ]; then
    continue # this week is recorded (its last map is within a step of its end)
  fi
  from=$(date -u -d "@$last" +%FT%TZ)
  gen_time=$(mktemp) rec_time=$(mktemp)
  log "week $week: from $from"
  started=$(date +%s.%N)
  # `--days` is counted from the start: the series' first $week weeks, made from $from on.
  nice -n "$NICE" /usr/bin/time -v -o "$gen_time" \
    "$G" -q generate --stream --days $((week * 7)) --step "${STEP_SECS}s" --seed "$SEED" --from "$from" \
    2>>"$FILE.generate.log" |
    nice -n "$NICE" /usr/bin/time -v -o "$rec_time" \
      "$G" record "$FILE" - --commit-every "$COMMIT" --no-compact >>"$FILE.commits.log" 2>&1
  wall=$(echo "$(date +%s.%N) - $started" | bc)
  last=$(last_unix)
  maps=$(grep -o 'recorded [0-9,]* maps' "$FILE.commits.log" | tail -1 | tr -dc 0-9)
  log "week $week: recorded ${maps:-?} maps in ${wall%.*} s wall," \
    "record $(cpu_secs "$rec_time") s CPU, peak $(($(peak_kib "$rec_time") / 1024)) MiB;" \
    "generate $(cpu_secs "$gen_time") s CPU, peak $(($(peak_kib "$gen_time") / 1024)) MiB;" \
    "file $(stat -c %s "$FILE") B, last sample $(date -u -d "@$last" +%FT%TZ)"
  if [ "$COMPACT" = 1 ]; then
    nice -n "$NICE" /usr/bin/time -v -o "$rec_time" "$G" compact "$FILE" >>"$FILE.commits.log" 2>&1
    log "week $week: compacted in $(cpu_secs "$rec_time") s CPU," \
      "peak $(($(peak_kib "$rec_time") / 1024)) MiB, file $(stat -c %s "$FILE") B"
  fi
  rm -f "$gen_time" "$rec_time"
done
log "recorded: $("$G" info "$FILE" | grep -E '^(time|size|file)' | tr '\n' ' ')"

# The report's steps. `timed NAME CMD…` runs CMD under /usr/bin/time -v and logs its wall
# and CPU seconds and peak memory.
timed() {
  local name=$1 out
  shift
  out=$(mktemp)
  local started
  started=$(date +%s.%N)
  nice -n "$NICE" /usr/bin/time -v -o "$out" "$@"
  log "$name: $(echo "$(date +%s.%N) - $started" | bc | cut -d. -f1) s wall," \
    "$(cpu_secs "$out") s CPU, peak $(($(peak_kib "$out") / 1024)) MiB"
  rm -f "$out"
}
if [ "$("$G" info --json "$FILE" | jq '.living.segments // [] | length')" != 0 ]; then
  timed "compact (lossless)" "$G" -q compact "$FILE"
fi
log "lossless: $(stat -c %s "$FILE") B"
if [ ! -e "$FILE.lossy.froct" ]; then
  timed "compact --lossy" "$G" -q compact "$FILE" -o "$FILE.lossy.froct" --lossy
fi
log "lossy: $(stat -c %s "$FILE.lossy.froct") B"
if [ ! -e "$FILE.eval.json" ]; then
  end=$(date -u -d "@$((START_UNIX + WEEKS * WEEK_SECS))" +%FT%TZ)
  # `eval` reads the held-out maps from the pipe; its JSON is written atomically.
  timed "eval of $HELD_OUT held-out days, every ${EVAL_STRIDE}th map" bash -c "
    '$G' -q generate --stream --days $((WEEKS * 7 + HELD_OUT)) --step ${STEP_SECS}s --seed $SEED --from $end 2>>'$FILE.generate.log' |
      '$G' -q eval '$FILE' --against - --stride $EVAL_STRIDE --json > '$FILE.eval.json.tmp' && mv '$FILE.eval.json.tmp' '$FILE.eval.json'"
fi
log "prediction, dynamic voxels: $(jq -c '[.prediction[] | {(.[0]): .[1].dynamic}] | add' "$FILE.eval.json")"
