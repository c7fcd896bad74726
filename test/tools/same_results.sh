#!/usr/bin/env bash
# Replays the recordings a structural change must not alter and writes each trajectory to OUT.
#   test/tools/same_results.sh BIN OUT [RECORDINGS]
# RECORDINGS holds the simulated scenes (made there when absent); compare two OUTs with
#   test/tools/compare_trajectories.py OUT_BEFORE OUT_AFTER
set -euo pipefail
bin=$1 out=$2 recordings=${3:-$out/recordings}
shared=$(cd "$(dirname "$0")/../../.." && pwd)/shared/data/tum
mkdir -p "$out" "$recordings"
simulated() {  # scene seed
  local dir=$recordings/$1-$2
  [[ -d $dir ]] || "$bin" simulate "$1" --seed "$2" --out "$dir" > /dev/null
  echo "$dir"
}
replay() {  # name recording args...
  local name=$1 recording=$2
  shift 2
  # The camera frame, that of the baselines written before outputs followed the mounting.
  "$bin" replay "$recording" --out "$out/$name" --quiet --frame camera "$@" > "$out/$name.log" 2>&1 || {
    echo "$name: replay failed, see $out/$name.log" >&2
    return 1
  }
}
if [[ -d $shared/fr1_rpy_head ]]; then
  for mode in baseline photometric geometric fused; do replay "fr1_rpy_head-$mode" "$shared/fr1_rpy_head" --mode "$mode"; done
else
  echo "skipped fr1_rpy_head: $shared/fr1_rpy_head absent" >&2
fi
for scene in office zigzag-plain poster-wall dark-office; do replay "$scene-fused" "$(simulated "$scene" 1)"; done
corridor=$(simulated corridor-loop 1)
replay corridor-loop-wheels "$corridor"
replay corridor-loop-no-wheels "$corridor" --no-wheels
