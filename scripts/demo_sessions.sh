#!/usr/bin/env bash
# The path from a day of trials to a model for the next day, on the simulator (make demo-sessions):
# collect a labelled session, train on it, score on a second session (another day: the rod held
# 1 cm further in, more sensor noise), calibrate with a few trials of that day, score again.
# The operator's answers come from a script (every contact kept); run the collect lines without
# --answers to answer yourself. Everything is written under $OUT (default build/demo_sessions).
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
EXT="$ROOT/.venv/bin/ext-sense"
OUT=${OUT:-$ROOT/build/demo_sessions}
rm -rf "$OUT" && mkdir -p "$OUT" && cd "$OUT"
for _ in $(seq 100); do echo keep; done > keep.txt
DAY2=scene:=tap_rod30_nuskin_day2
collect() {  # the operator's screen goes to NAME.log, its last line here
  "$EXT" collect tap_localization "$1" --answers keep.txt --name "$1" "${@:2}" >"$1.log" 2>&1 \
    || { tail -5 "$1.log"; exit 1; }
  tail -1 "$1.log"
}
collect day1 --trials 30
collect day2_calib --trials 8 "$DAY2" seed:=9
collect day2 --trials 20 "$DAY2" seed:=5
"$EXT" train --data day1 --anytime-ms none --out day1_model
echo "== the day-1 model on day 2"
"$EXT" score day1_model --data day2
"$EXT" calibrate day1_model --data day2_calib --out day2_model
echo "== calibrated with 8 taps of day 2, on the other 20"
"$EXT" score day2_model --data day2
