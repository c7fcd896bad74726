#!/usr/bin/env bash
# Checkpoints of `rankslam run` on a real kernel (map.file, map.checkpoint_s): a simulated
# corridor-loop recording replays through `run` on vcan0. The first run starts a new map and is
# killed with SIGKILL once it has published a checkpoint; the second starts in the map the first
# left and is stopped with SIGTERM at the end of the recording. On the host then: both map files
# load (`rankslam replay --load-map`), the map directory never holds anything but the map, the
# killed run's published outputs are whole, and the second run exits 130 having saved the map
# and counted its checkpoints. test/bench/cli/checkpoint_kill_test.cpp kills the same loop at 20
# random moments.
#
#   test/vm/checkpoint_test.sh RANKSLAM WORK_DIR
#
# The VM reads WORK_DIR (the host's root, read-only there) and writes only into its own TMPDIR.
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
rankslam="$1"
work="$2"

rm -rf "$work"
mkdir -p "$work"
"$rankslam" simulate corridor-loop --frames 90 --out "$work/recording" > "$work/simulate.log"
# The VM's writable place is its TMPDIR (a tmpfs); /tmp may be the host's, read-only.
cat > "$work/in-vm.sh" <<SH
set -u
out="\$RANKSLAM_VM_OUT"
dir="\$TMPDIR/checkpoint"
mkdir -p "\$dir/maps"
cat > "\$dir/robot.yaml" <<YAML
camera:
  source: replay:$work/recording
  replay_rate: 0
  exit_after_end_s: -1
can:
  interface: vcan0
  play_wheel_frames: false
output:
  status_interval_s: 0
slam:
  keyframe_capacity: 32
map:
  file: \$dir/maps/map.rsm
  checkpoint_s: 0.5
YAML
"$rankslam" run --config "\$dir/robot.yaml" --mode baseline --out "\$dir/out" > "\$out/run-kill.log" 2>&1 &
run=\$!
for i in \$(seq 1 600); do
  [ -e "\$dir/out/report.json" ] && break
  kill -0 \$run 2>/dev/null || break
  sleep 0.1
done
kill -KILL \$run
wait \$run
echo "exit \$?" > "\$out/run-kill.exit"
ls -A "\$dir/maps" > "\$out/maps-kill.ls"
cp "\$dir/maps/map.rsm" "\$out/map-kill.rsm"
cp -L "\$dir/out/trajectory.txt" "\$dir/out/report.json" "\$out/" 2>/dev/null
"$rankslam" run --config "\$dir/robot.yaml" --mode baseline --out "\$dir/out" > "\$out/run-term.log" 2>&1 &
run=\$!
for i in \$(seq 1 600); do
  grep -q "end of stream" "\$out/run-term.log" && break
  kill -0 \$run 2>/dev/null || break
  sleep 0.1
done
kill -TERM \$run
wait \$run
echo "exit \$?" > "\$out/run-term.exit"
ls -A "\$dir/maps" > "\$out/maps-term.ls"
cp "\$dir/maps/map.rsm" "\$out/map-term.rsm"
cp -L "\$dir/out/report.json" "\$out/report-term.json"
SH
set +e
RANKSLAM_VM_FILES_TO="$work/files" "$here/run-in-vm.sh" /bin/sh "$work/in-vm.sh"
code=$?
set -e
[ "$code" -eq 0 ] || exit "$code"

files="$work/files"
failures=0
fail() { echo "FAIL: $*"; failures=$((failures + 1)); }
loads() {
  "$rankslam" replay "$work/recording" --load-map "$1" --max-frames 1 --quiet --out "$work/check" > "$work/check.log" 2>&1 ||
    fail "$1 does not load: $(grep -m1 error "$work/check.log")"
}
grep -qx "exit 137" "$files/run-kill.exit" || fail "the first run was not killed by SIGKILL: $(cat "$files/run-kill.exit")"
grep -q "does not exist yet: a new map" "$files/run-kill.log" || fail "the first run did not start a new map"
[ "$(cat "$files/maps-kill.ls")" = map.rsm ] || fail "after the kill the map directory holds: $(cat "$files/maps-kill.ls")"
loads "$files/map-kill.rsm"
grep -q '"checkpoint": true' "$files/report.json" || fail "the killed run's report.json is not a checkpoint's"
python3 - "$files/trajectory.txt" <<'PY' || fail "the killed run's trajectory.txt is not whole"
import sys
text = open(sys.argv[1]).read()
assert text.endswith("\n")
for line in text.splitlines():
    if not line.startswith("#"):
        assert len([float(f) for f in line.split()]) == 8, line
PY
grep -q "map loaded from .*/maps/map.rsm" "$files/run-term.log" || fail "the second run did not start in the map"
grep -qx "exit 130" "$files/run-term.exit" || fail "the second run after SIGTERM: $(cat "$files/run-term.exit")"
grep -q "map saved to .*/maps/map.rsm" "$files/run-term.log" || fail "the second run did not save the map at exit"
[ "$(cat "$files/maps-term.ls")" = map.rsm ] || fail "after SIGTERM the map directory holds: $(cat "$files/maps-term.ls")"
loads "$files/map-term.rsm"
grep -q '"checkpoints_written": [1-9]' "$files/report-term.json" || fail "the second run's report counts no checkpoint"
grep -q '"checkpoint_failures": 0' "$files/report-term.json" || fail "the second run's report counts failed checkpoints"
[ "$failures" -eq 0 ] || { echo "$failures failure(s); files in $files"; exit 1; }
echo "PASS"
