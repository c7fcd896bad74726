#!/usr/bin/env bash
# Acceptance test of `rankslam run` on a real kernel: a simulated corridor-loop recording runs
# through `rankslam run` with the replay camera and the SocketCAN driver on vcan0, its wheel
# frames played onto vcan0; candump captures the bus; pose_log_check then requires pose cycles
# at the configured rate that decode to the trajectory `rankslam replay` wrote for the same
# recording with its wheel frames, moved on by the wheels since each frame, within 1 mm and
# 0.1°, LOST after the watchdog once the recording ends with the heartbeat going on, and
# trajectory and map flushed after SIGTERM. candump runs under SCHED_FIFO with a large receive
# buffer and reports its own drops, so a lost frame is told apart from one never sent.
#
#   test/vm/pose_output_test.sh RANKSLAM POSE_LOG_CHECK WORK_DIR [normal|stress|faults] [NOTIFY_LISTEN]
#
# NOTIFY_LISTEN (test/vm/notify_listen.cpp): `run` goes under a NOTIFY_SOCKET with a 1 s watchdog,
# as under systemd's Type=notify, and must send READY=1 first (a WATCHDOG=1 of the set-up aside),
# WATCHDOG=1 also after the end of the recording, when no camera frame comes, and STOPPING=1
# last; its status line (every 1 s here) must be in its output.
#
# stress: from the end of the recording, three busy processes at nice -20 take the CPU for 4 s
# while the pose output goes on; its cycles must stay whole, in order and at their rate.
# faults: after the end of the recording vcan0 goes down for 1 s, and then a netem queue that
# holds every frame for 10 s fills the transmit queue for 1 s; the run must count the frames it
# could not send, flag them in a heartbeat, keep running and send at its rates again after.
#
# WORK_DIR must be outside /tmp (the VM sees the host's root read-only, with its own /tmp).
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
rankslam="$1"
checker="$2"
work="$3"
mode="${4:-normal}"
listener="${5:-}"
readonly frames=60 pose_rate_hz=50 heartbeat_rate_hz=10 watchdog_s=0.4 stress_s=4
case "$mode" in
  normal) hogs=0 ;;
  stress) hogs=3 ;;
  faults) hogs=0 ;;
  *) echo "usage: $0 RANKSLAM POSE_LOG_CHECK WORK_DIR [normal|stress|faults] [NOTIFY_LISTEN]"; exit 2 ;;
esac

rm -rf "$work"
mkdir -p "$work"
"$rankslam" simulate corridor-loop --frames "$frames" --out "$work/recording" > "$work/simulate.log"
# The test is about the CAN path, not registration: baseline tracks the corridor's first
# metres reliably, so the compared trajectory moves. `run` takes its wheel prior from the frames
# played onto vcan0 and received back; the reference is replay with wheels, its can.log frames
# reaching the same odometry through the replay CAN bus (hal::replay::ReplayCanBus).
"$rankslam" replay "$work/recording" --out "$work/replay" --quiet --mode baseline --frame camera > "$work/replay.log"
grep -q '"wheels_used": true' "$work/replay/report.json" || { echo "FAIL: the reference replay ran without wheels"; exit 1; }

cat > "$work/robot.yaml" <<YAML
camera:
  source: replay:recording
  replay_rate: 0            # lossless: the same frames as replay, however slow the emulated CPU
  exit_after_end_s: -1      # keep sending until SIGTERM
can:
  interface: vcan0
  play_wheel_frames: true
output:
  pose_rate_hz: $pose_rate_hz
  heartbeat_rate_hz: $heartbeat_rate_hz
  watchdog_timeout_s: $watchdog_s
  status_interval_s: 1
YAML

# Inside the VM: capture the bus, run until the end of the recording, (stress: take the CPU;
# faults: break the bus), let the watchdog expire, stop with SIGTERM, then check.
cat > "$work/in-vm.sh" <<SH
set -u
out="\$RANKSLAM_VM_OUT"
chrt -f 60 candump -D -d -r 8388608 -L -n 1000000 vcan0 > "\$out/bus.log" 2> "\$out/candump.err" &
dump=\$!
sleep 0.3
notify_env=""
if [ -n "$listener" ]; then
  "$listener" \$TMPDIR/rankslam-notify.sock > "\$out/notify.log" 2> "\$out/notify.err" &
  listen=\$!
  for i in \$(seq 1 50); do grep -q listening "\$out/notify.log" && break; sleep 0.1; done
  grep -q listening "\$out/notify.log" || { echo "FAIL: notify_listen did not start: \$(cat "\$out/notify.err")"; exit 1; }
  notify_env="NOTIFY_SOCKET=\$TMPDIR/rankslam-notify.sock WATCHDOG_USEC=1000000"
fi
env \$notify_env "$rankslam" run --config "$work/robot.yaml" --mode baseline --frame camera --out "\$out/run" > "\$out/run.log" 2>&1 &
run=\$!
for i in \$(seq 1 1200); do
  grep -q "end of stream" "\$out/run.log" && break
  kill -0 \$run 2>/dev/null || break
  sleep 0.1
done
at_end=0
[ -z "$listener" ] || at_end=\$(grep -c '^WATCHDOG=1\$' "\$out/notify.log")
hog_pids=""
for i in \$(seq 1 $hogs); do
  nice -n -20 timeout $stress_s sh -c 'while :; do :; done' &
  hog_pids="\$hog_pids \$!"
done
[ -z "\$hog_pids" ] || { wait \$hog_pids; echo "$hogs busy processes at nice -20 ran for $stress_s s"; }
fault_window=""
if [ "$mode" = faults ]; then
  sleep 1
  from=\$(date +%s.%N)
  ip link set vcan0 down && sleep 1 && ip link set vcan0 up && sleep 1 &&
    tc qdisc add dev vcan0 root netem delay 10s limit 4 && sleep 1 && tc qdisc del dev vcan0 root ||
    echo "FAIL: the bus faults could not be made"
  fault_window="--faults \$from \$(date +%s.%N)"
  echo "faults: vcan0 down 1 s, up 1 s, transmit queue held full 1 s (\$fault_window)"
  sleep 2
fi
sleep 1.5
kill -TERM \$run
wait \$run
code=\$?
sleep 0.2
kill \$dump
cat "\$out/run.log"
echo "rankslam run exit code \$code (130 expected after SIGTERM)"
"$checker" --log "\$out/bus.log" --reference "$work/replay/trajectory.txt" --recording "$work/recording" \
  --run-out "\$out/run" --pose-rate $pose_rate_hz --heartbeat-rate $heartbeat_rate_hz --watchdog-s $watchdog_s \$fault_window
check=\$?
grep -c "^(.*) vcan0 101#" "\$out/bus.log" | sed 's/^/wheel frames on the bus: /'
grep -c "^(" "\$out/bus.log" | sed 's/^/frames on the bus: /'
[ \$code -eq 130 ] || { echo "FAIL: rankslam run exit code \$code"; exit 1; }
if [ -n "$listener" ]; then
  kill \$listen
  notes=\$(grep -v '^listening\$' "\$out/notify.log")
  echo "notifications: \$(echo "\$notes" | sort | uniq -c | tr '\n' ' ')"
  # WATCHDOG=1 may come during set-up, once the camera is open; READY=1 before anything else.
  [ "\$(echo "\$notes" | grep -v '^WATCHDOG=1\$' | head -1)" = READY=1 ] || { echo "FAIL: READY=1 does not come first"; check=1; }
  [ "\$(echo "\$notes" | tail -1)" = STOPPING=1 ] || { echo "FAIL: the last notification is not STOPPING=1"; check=1; }
  # The run goes on 1.5 s past the recording's end, without camera frames: three periods of 0.5 s.
  after_end=\$(( \$(echo "\$notes" | grep -c '^WATCHDOG=1\$') - at_end ))
  echo "WATCHDOG=1 after the end of the recording: \$after_end"
  [ "\$after_end" -ge 2 ] || { echo "FAIL: fewer than 2 WATCHDOG=1 after the end of the recording"; check=1; }
  grep -q "^status: last " "\$out/run.log" || { echo "FAIL: no status line in the run's output"; check=1; }
fi
exit \$check
SH
exec "$here/run-in-vm.sh" /bin/sh "$work/in-vm.sh"
