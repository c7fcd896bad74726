#!/usr/bin/env bash
# run-fuzzer.sh FUZZER WORK_CORPUS SECONDS SEED_CORPUS...: one bounded libFuzzer run. Exits
# non-zero on any crash, leak, timeout (10 s per input) or sanitizer report; prints libFuzzer's
# final statistics (executions, corpus size). Findings are written to WORK_CORPUS/../findings.
set -euo pipefail
fuzzer=$1 work=$2 seconds=$3
shift 3
findings="$(dirname "$work")/findings-$(basename "$work")"
mkdir -p "$work" "$findings"
exec "$fuzzer" "$work" "$@" -max_total_time="$seconds" -timeout=10 -rss_limit_mb=2048 -malloc_limit_mb=2048 \
  -print_final_stats=1 -artifact_prefix="$findings/" -close_fd_mask=1
