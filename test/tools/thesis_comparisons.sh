#!/usr/bin/env bash
# The thesis' comparisons in one run: MSSE against fixed-threshold RANSAC (5/10/20 mm), fused
# registration against each single cue, inlier-ratio weights against equal weights, the adaptive
# loop-closure threshold against fixed ones (50/100/150 inliers, the thesis' Table 5.6).
#
#   test/tools/thesis_comparisons.sh --bin RANKSLAM --out DIR [--data DIR] [--scenes real|all]
#                                    [--jobs N] [--seeds "1 2 3"] [--corridor-seeds "1 2 3 4 5"] [--check]
#
# Real recordings: DATA/tum/fr1_rpy_head and fr1_desk_9 (DATA defaults to ../shared/data beside
# the checkout). --scenes all also simulates office, zigzag-plain, poster-wall and dark-office
# (--seeds) and the corridor loop (--corridor-seeds, replayed without wheels) into DIR/recordings
# and replays them; recordings already there are reused. Writes DIR/runs.tsv (one line per
# replay, with its median frame time) and DIR/table.md (per variant and scene: mean ATE with its
# range over the seeds, loop closures and false ones). --check exits 1 unless every replay
# finished with an ATE, no variant with the adaptive threshold made a false closure, fused beat
# geometric alone on fr1_rpy_head, and only the equal-weights variant weighted both kinds alike
# there. Exit 77 when there is no recording to replay, 2 on bad arguments.
set -euo pipefail

bin='' out='' scenes=real jobs=2 seeds="1 2 3" corridor_seeds="1 2 3 4 5" check=0
data=$(cd "$(dirname "$0")/../.." && pwd)/../shared/data
usage() { sed -n '2,17p' "$0" | sed 's/^# \{0,1\}//' >&2; exit 2; }
while [[ $# -gt 0 ]]; do
  case $1 in
    --bin) bin=$2; shift 2 ;;
    --out) out=$2; shift 2 ;;
    --data) data=$2; shift 2 ;;
    --scenes) scenes=$2; shift 2 ;;
    --jobs) jobs=$2; shift 2 ;;
    --seeds) seeds=$2; shift 2 ;;
    --corridor-seeds) corridor_seeds=$2; shift 2 ;;
    --check) check=1; shift ;;
    *) echo "thesis_comparisons: unknown argument '$1'" >&2; usage ;;
  esac
done
[[ -n $bin && -n $out ]] || usage
[[ -x $bin ]] || { echo "thesis_comparisons: --bin '$bin' is not an executable" >&2; exit 2; }
[[ $scenes == real || $scenes == all ]] || { echo "thesis_comparisons: --scenes must be real or all" >&2; exit 2; }
[[ $jobs =~ ^[1-9][0-9]*$ ]] || { echo "thesis_comparisons: --jobs must be a positive integer" >&2; exit 2; }

mkdir -p "$out/recordings" "$out/configs" "$out/runs"

# Variants: name, mode, configuration. One thread per replay: the estimates do not depend on it,
# and --jobs replays share the cores.
variants=(
  "fused|fused|"
  "photometric|photometric|"
  "geometric|geometric|"
  "ransac-5mm|baseline|ransac_threshold_m: 0.005"
  "ransac-10mm|baseline|ransac_threshold_m: 0.01"
  "ransac-20mm|baseline|ransac_threshold_m: 0.02"
  "fused-equal-weights|fused|fused_inlier_ratio_weights: 0"
  "fused-fixed-threshold-50|fused|loop_adaptive_threshold: 0, loop_initial_threshold: 50"
  "fused-fixed-threshold-100|fused|loop_adaptive_threshold: 0, loop_initial_threshold: 100"
  "fused-fixed-threshold-150|fused|loop_adaptive_threshold: 0, loop_initial_threshold: 150"
)
for variant in "${variants[@]}"; do
  IFS='|' read -r name mode settings <<< "$variant"
  printf 'slam: {threads: 1%s}\n' "${settings:+, $settings}" > "$out/configs/$name.yaml"
done

# Recordings: scene name (the table's column), recording name, directory, replay flags.
recordings=()
for real in fr1_rpy_head fr1_desk_9; do
  if [[ -d $data/tum/$real ]]; then
    recordings+=("$real|$real|$data/tum/$real|")
  else
    echo "thesis_comparisons: skipped $real: $data/tum/$real absent" >&2
  fi
done
simulated() {  # scene seed [frames]
  local dir=$out/recordings/$1-$2
  if [[ ! -f $dir/groundtruth.txt ]]; then
    # Written beside, then renamed: an interrupted simulation never passes for a recording.
    local partial
    partial=$(mktemp -d "$dir.partial.XXXXXX")
    "$bin" simulate "$1" --seed "$2" --out "$partial" ${3:+--frames "$3"} > /dev/null
    mv -T "$partial" "$dir"
  fi
  echo "$dir"
}
if [[ $scenes == all ]]; then
  for scene in office zigzag-plain poster-wall dark-office; do
    for seed in $seeds; do recordings+=("$scene|$scene-$seed|$(simulated "$scene" "$seed")|"); done
  done
  for seed in $corridor_seeds; do
    recordings+=("corridor-loop vision only|corridor-loop-$seed|$(simulated corridor-loop "$seed")|--no-wheels")
  done
fi
if [[ ${#recordings[@]} -eq 0 ]]; then
  echo "thesis_comparisons: no recording to replay (no $data/tum)" >&2
  exit 77
fi

# One job per recording and variant; each writes its line to runs/NAME.tsv.
run_one() {  # bin out scene recording dir flags variant mode
  local bin=$1 out=$2 scene=$3 recording=$4 dir=$5 flags=$6 name=$7 mode=$8
  local run=$out/runs/$recording.$name
  # shellcheck disable=SC2086  # flags is a word list
  if ! "$bin" replay "$dir" --out "$run" --frame camera --mode "$mode" -c "$out/configs/$name.yaml" --quiet $flags \
      > "$run.log" 2>&1; then
    echo "thesis_comparisons: $recording $name: replay failed, see $run.log" >&2
    printf '%s\t%s\t%s\tfailed\t\t\t\t\t\n' "$scene" "$recording" "$name" > "$run.tsv"
    return 0
  fi
  local report=$run/report.json
  # report.json's first occurrence of a key is the top-level one (pose_sigma's "frames" comes later).
  field() { grep -o "\"$1\": *[^,}]*" "$report" | head -1 | sed 's/^[^:]*: *//'; }
  printf '%s\t%s\t%s\t%s\t%s\t%s\t%s\t%s\t%s\n' "$scene" "$recording" "$name" "$(field ate_rmse_m)" "$(field frames)" \
    "$(field failed_frames)" "$(field loop_closures)" "$(field false_loop_closures)" \
    "$(grep -o '"frame_ms": {"median": *[^,}]*' "$report" | sed 's/.*: *//')" > "$run.tsv"
}
export -f run_one
for recording in "${recordings[@]}"; do
  IFS='|' read -r scene name dir flags <<< "$recording"
  for variant in "${variants[@]}"; do
    IFS='|' read -r vname mode _ <<< "$variant"
    printf '%s\0%s\0%s\0%s\0%s\0%s\0%s\0%s\0' "$bin" "$out" "$scene" "$name" "$dir" "$flags" "$vname" "$mode"
  done
done | xargs -0 -n 8 -P "$jobs" bash -c 'run_one "$@"' run_one

{
  printf 'scene\trecording\tvariant\tate_rmse_m\tframes\tfailed_frames\tloop_closures\tfalse_loop_closures\tframe_ms_median\n'
  for recording in "${recordings[@]}"; do
    IFS='|' read -r _ name _ _ <<< "$recording"
    for variant in "${variants[@]}"; do cat "$out/runs/$name.${variant%%|*}.tsv"; done
  done
} > "$out/runs.tsv"

# The table: a row per variant, a column per scene; mean ATE (min–max over the recordings of the
# scene), and closures / false closures.
awk -F'\t' -v order="$(printf '%s\n' "${variants[@]}" | cut -d'|' -f1 | paste -sd' ')" '
  NR == 1 { next }
  {
    if (!($1 in seen)) { seen[$1] = 1; scenes[++nscenes] = $1 }
    key = $3 SUBSEP $1
    if ($4 == "failed" || $4 == "" || $4 == "null") { failed[key]++; next }
    n[key]++; sum[key] += $4
    if (!(key in lo) || $4 < lo[key]) lo[key] = $4
    if (!(key in hi) || $4 > hi[key]) hi[key] = $4
    closures[key] += $7; if ($8 != "null" && $8 != "") falses[key] += $8
  }
  END {
    printf "ATE RMSE (m): mean over the recordings of each scene (min–max); closures / false closures.\n\n| variant |"
    for (s = 1; s <= nscenes; ++s) printf " %s |", scenes[s]
    printf "\n|---|"
    for (s = 1; s <= nscenes; ++s) printf "---|"
    printf "\n"
    nv = split(order, variants, " ")
    for (v = 1; v <= nv; ++v) {
      printf "| %s |", variants[v]
      for (s = 1; s <= nscenes; ++s) {
        key = variants[v] SUBSEP scenes[s]
        if (!(key in n)) { printf " failed |"; continue }
        if (n[key] == 1) printf " %.4f", sum[key]
        else printf " %.4f (%.4f–%.4f)", sum[key] / n[key], lo[key], hi[key]
        printf "; %d / %d", closures[key], falses[key]
        if (key in failed) printf "; %d failed", failed[key]
        printf " |"
      }
      printf "\n"
    }
  }' "$out/runs.tsv" > "$out/table.md"
cat "$out/table.md"

if [[ $check -eq 1 ]]; then
  awk -F'\t' '
    NR == 1 { next }
    $4 == "failed" || $4 == "" || $4 == "null" { print "check: " $2 " " $3 ": no ATE"; bad = 1; next }
    $3 !~ /fixed-threshold/ && $8 != "" && $8 != "null" && $8 > 0 { print "check: " $2 " " $3 ": " $8 " false loop closures"; bad = 1 }
    $2 == "fr1_rpy_head" && $3 == "fused" { fused = $4 }
    $2 == "fr1_rpy_head" && $3 == "geometric" { geometric = $4 }
    END {
      if (fused != "" && geometric != "" && !(fused + 0 < geometric + 0)) {
        print "check: fr1_rpy_head: fused ATE " fused " not below geometric alone " geometric; bad = 1
      }
      exit bad
    }' "$out/runs.tsv" || { echo "thesis_comparisons: check failed (see $out/runs.tsv)" >&2; exit 1; }
  # The kind weights as frames.csv gives them: other than 0 and 1 only with the inlier ratios.
  weights() {  # recording variant: the distinct photometric_weight values
    local csv=$out/runs/$1.$2/frames.csv
    [[ -f $csv ]] || return 0
    awk -F, 'NR == 1 { for (i = 1; i <= NF; ++i) if ($i == "photometric_weight") c = i; next }
             c { print $c + 0 }' "$csv" | sort -u
  }
  if [[ -d $out/runs/fr1_rpy_head.fused ]]; then
    if weights fr1_rpy_head fused-equal-weights | grep -qvx '[01]'; then
      echo "check: fr1_rpy_head fused-equal-weights: a kind weight other than 0 or 1" >&2; exit 1
    fi
    if ! weights fr1_rpy_head fused | grep -qvx '[01]'; then
      echo "check: fr1_rpy_head fused: no frame weighted its kinds by their inlier ratios" >&2; exit 1
    fi
  fi
  echo "thesis_comparisons: check passed"
fi
