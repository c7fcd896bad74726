#!/usr/bin/env bash
# The wide-angle camera in `rankslam run` on a real kernel: OpenNI2's DummyDevice as the RGB-D
# camera and the kernel's vivid driver as the wide-angle camera over V4L2, both stamped on
# CLOCK_MONOTONIC, pose frames on vcan0. The run is stopped with SIGTERM after a few seconds; on
# the host then: it exits 130, its status lines count the wide-angle images, and report.json
# says the camera opened, delivered without faults, lost at most 5 % of its frames in the
# device, and had images paired with colour frames by stamp (which needs one clock for both).
#
#   test/vm/wide_camera_test.sh RANKSLAM WORK_DIR
#
# The VM reads WORK_DIR (the host's root, read-only there) and writes only into its own TMPDIR.
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
rankslam="$1"
work="$2"
readonly run_s=10

rm -rf "$work"
mkdir -p "$work"
# The DummyDevice's 320x240 streams, and a 640x480 wide-angle camera (vivid's size here).
cat > "$work/calibration.yaml" <<YAML
depth_scale: 1000
cameras:
  rgb: {model: pinhole, width: 320, height: 240, intrinsics: [260, 260, 159.5, 119.5]}
  fisheye: {model: fisheye, width: 640, height: 480, intrinsics: [230, 230, 319.5, 239.5],
            distortion: [0, 0, 0, 0]}
YAML
cat > "$work/in-vm.sh" <<SH
set -u
out="\$RANKSLAM_VM_OUT"
dir="\$TMPDIR/wide"
mkdir -p "\$dir"
device=""
for name in /sys/class/video4linux/video*/name; do
  case "\$(cat "\$name")" in *vid-cap*) device="/dev/\$(basename "\$(dirname "\$name")")"; break ;; esac
done
echo "\$device" > "\$out/device"
cat > "\$dir/robot.yaml" <<YAML
camera:
  source: 'openni2:Dummy'
  calibration: $work/calibration.yaml
  mounting: identity
  width: 320
  height: 240
wide_camera:
  device: \$device
  width: 640
  height: 480
  fps: 10
can:
  interface: vcan0
output:
  status_interval_s: 1
YAML
"$rankslam" run --config "\$dir/robot.yaml" --mode baseline --out "\$dir/out" > "\$out/run.log" 2>&1 &
run=\$!
# The run's seconds count from its first status line: start-up under emulation varies by seconds.
i=0
while [ \$i -lt 90 ] && ! grep -q '^status:' "\$out/run.log"; do sleep 1; i=\$((i + 1)); done
sleep $run_s
kill -TERM \$run
wait \$run
echo "exit \$?" > "\$out/run.exit"
cp -L "\$dir/out/report.json" "\$out/" 2>/dev/null
SH
set +e
RANKSLAM_VM_FILES_TO="$work/files" "$here/run-in-vm.sh" /bin/sh "$work/in-vm.sh"
code=$?
set -e
[ "$code" -eq 0 ] || exit "$code"

files="$work/files"
failures=0
fail() { echo "FAIL: $*"; failures=$((failures + 1)); }
[ -n "$(cat "$files/device")" ] || fail "no vivid capture node in the VM"
grep -qx "exit 130" "$files/run.exit" || fail "run after SIGTERM: $(cat "$files/run.exit"); $(tail -5 "$files/run.log")"
grep -q "wide-angle camera: v4l2:/dev/video" "$files/run.log" || fail "run did not name the wide-angle camera"
grep -q "status: .*, wide-angle images [1-9]" "$files/run.log" || fail "no status line counts wide-angle images"
python3 - "$files/report.json" <<'PY' || fail "report.json: see above"
import json, sys
report = json.load(open(sys.argv[1]))
wide = report["wide_angle"]
print("frames", report["frames"], "wide_angle", wide)
assert wide["opened"], "the camera did not open"
assert wide["faults"] == 0, "faults"
assert wide["images"] >= 20, "fewer than 20 images"
assert wide["device_dropped"] <= 0.05 * (wide["images"] + wide["device_dropped"]), "more than 5 % dropped"
assert wide["paired"] >= 5, "(almost) no image paired with a colour frame: not one clock"
PY
[ "$failures" -eq 0 ] || { echo "$failures failure(s); files in $files"; exit 1; }
echo "PASS"
