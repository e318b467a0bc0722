#!/usr/bin/env bash
# The 12-run start-offset set for the odometry's fragile starts (README "Odometry benchmark"): the
# room at 20 / 50 / 100 W and the tunnel at 100 W, each run from its first frame and from frames
# 15 and 30 (the same sequence with its first frames left out), two runs at a time. Prints each
# run's ATE after Sim(3) alignment over the ground-truth path, and the mean. One `bench` run cannot
# judge a change to the start (a small change moves a sequence by a factor of 2-5 either way).
#
# usage: tests/tools/start_offsets.sh SEQUENCES OUT [nirslam run options...]
#   SEQUENCES  the sequences/ folder of a `nirslam bench --out DIR` (DIR/sequences); when the four
#              sequences are not there, `nirslam bench` simulates them into it first (about 2 min)
#   OUT        a folder for the runs and results.txt
#   options    passed to every `nirslam run` (default: --mode odometry)
# NIRSLAM=path/to/nirslam picks the binary (default: build/nirslam); NIRSLAM_CONFIG=file.yaml is
# passed as `nirslam --config file.yaml run ...`. NIRSLAM_OFFSET_SEQUENCES="Room_20 Parking_50 .."
# and NIRSLAM_OFFSET_FIRSTS="0 15" choose other sequences and first frames (README's Table 2 from
# frame 15: all twelve, `NIRSLAM_OFFSET_SEQUENCES=all NIRSLAM_OFFSET_FIRSTS=15`). The cut
# sequences keep frames.csv (the lamp's power per frame).
set -euo pipefail
[ $# -ge 2 ] || { sed -n '2,15p' "$0"; exit 2; }
sequences=$(realpath -m "$1"); out=$(realpath -m "$2"); shift 2
nirslam=$(realpath "${NIRSLAM:-build/nirslam}")
config=${NIRSLAM_CONFIG:+$(realpath "$NIRSLAM_CONFIG")}
run_options=("$@"); [ ${#run_options[@]} -gt 0 ] || run_options=(--mode odometry)
names=(Room_20 Room_50 Room_100 Tunnel_100)
if [ "${NIRSLAM_OFFSET_SEQUENCES:-}" = all ]; then
  names=()
  for scene in Room Outside Parking Tunnel; do for power in 20 50 100; do names+=("${scene}_$power"); done; done
elif [ -n "${NIRSLAM_OFFSET_SEQUENCES:-}" ]; then
  read -r -a names <<< "$NIRSLAM_OFFSET_SEQUENCES"
fi
read -r -a firsts <<< "${NIRSLAM_OFFSET_FIRSTS:-0 15 30}"

missing=0
for n in "${names[@]}"; do [ -d "$sequences/${n}_300f_640x480" ] || missing=1; done
if [ $missing = 1 ]; then
  bench_dir=$(dirname "$sequences")
  [ "$(basename "$sequences")" = sequences ] || { echo "$sequences: expected a bench's sequences/ folder" >&2; exit 2; }
  scenes=(--scenes room,tunnel)
  [ -z "${NIRSLAM_OFFSET_SEQUENCES:-}" ] || scenes=()  # other sequences: all four scenes
  "$nirslam" bench "${scenes[@]}" --powers 20,50,100 --modes odometry --out "$bench_dir" > "$out.bench.log" 2>&1 ||
    { echo "nirslam bench failed: see $out.bench.log" >&2; exit 1; }
fi

# A TUM monoVO folder with the frames from FIRST on: images linked, times.txt cut.
subset() {
  local src=$1 dst=$2 first=$3
  rm -rf "$dst"; mkdir -p "$dst/images"
  cp "$src/camera.txt" "$src/groundtruth.txt" "$dst/"
  [ ! -f "$src/frames.csv" ] || cp "$src/frames.csv" "$dst/"
  awk -v f="$first" 'NR > f' "$src/times.txt" > "$dst/times.txt"
  awk '{print $1}' "$dst/times.txt" | while read -r id; do ln -s "$src/images/$id.png" "$dst/images/$id.png"; done
}

mkdir -p "$out/sequences"
runs=()
for n in "${names[@]}"; do
  for first in "${firsts[@]}"; do
    src="$sequences/${n}_300f_640x480"
    if [ "$first" = 0 ]; then runs+=("$n@0|$src"); continue; fi
    dst="$out/sequences/${n}_from_$first"
    [ -f "$dst/times.txt" ] || subset "$src" "$dst" "$first"
    runs+=("$n@$first|$dst")
  done
done

one() {  # one "NAME@FIRST|FOLDER": runs it and prints "NAME@FIRST ATE PATH PERCENT"
  local label=${1%%|*} folder=${1#*|} dir
  dir="$out/runs/${label/@/_from_}"; mkdir -p "$dir"
  "$nirslam" ${config:+--config "$config"} run "$folder" --out "$dir" "${run_options[@]}" > "$dir/run.log" 2>&1 || { echo "$label FAILED (see $dir/run.log)"; return; }
  "$nirslam" eval "$dir/trajectory.txt" "$folder/groundtruth.txt" --align sim3 > "$dir/eval.txt" 2>&1 || { echo "$label EVAL FAILED"; return; }
  local ate path
  ate=$(awk '$1 == "ATE" {print $3}' "$dir/eval.txt")
  path=$(awk '/ground-truth path length/ {print $(NF-1)}' "$dir/eval.txt")
  awk -v l="$label" -v a="$ate" -v p="$path" 'BEGIN {printf "%-14s ATE %.4f m  path %.2f m  %.2f %%\n", l, a, p, 100 * a / p}'
}
export -f one
export out nirslam config
export RUN_OPTIONS="${run_options[*]}"
# Word-split the options again inside the child shells (they contain no spaces of their own).
printf '%s\n' "${runs[@]}" | xargs -P2 -I{} bash -c 'run_options=($RUN_OPTIONS); one "$1"' _ {} | sort > "$out/results.txt"
cat "$out/results.txt"
awk '/ %$/ {v = $(NF-1); s += v; n++; if (v < 1) ok++; g += log($3)} END {printf "MEAN %.2f %% over %d runs, %d under 1 %%; geometric mean ATE %.4f m\n", s / n, n, ok, exp(g / n)}' "$out/results.txt" | tee -a "$out/results.txt"
