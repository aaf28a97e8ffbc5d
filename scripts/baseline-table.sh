#!/usr/bin/env bash
# Renders the ray-traced reference of every fixture once, then each baseline five times, and prints
# a markdown table: RMSE against the reference (softshadow score) and whole-process wall time
# (median of 5 runs, includes loading, BVH, G-buffer, light-space build, estimate and EXR write).
#   scripts/baseline-table.sh [OUT_DIR] [ALGO...]
source "$(dirname "$0")/lib.sh"
table_setup "${1:-target/baseline-table}"
shift || true
algos=("${@:-pcss multi-sample hard pcf}")
read -r -a algos <<<"${algos[*]}"
median() { python3 -c 'import sys,statistics; print("%.0f" % statistics.median(float(x) for x in sys.argv[1:]))' "$@"; }
table_header fixture algo RMSE MAE p99 'whole process ms (median of 5)'
for scene in fixtures/*/*.toml; do
  name=$(basename "$scene" .toml)
  ref="$out/$name-reference.exr"
  if [ ! -f "$ref" ]; then
    t0=$(date +%s%N); $bin render "$scene" --algo reference --out "$ref"; t1=$(date +%s%N)
    echo "| $name | reference (1024 spp) | 0 | 0 | 0 | $(( (t1 - t0) / 1000000 )) (one run) |"
  fi
  for algo in "${algos[@]}"; do
    times=()
    for _ in 1 2 3 4 5; do
      t0=$(date +%s%N)
      $bin render "$scene" --algo "$algo" --out "$out/$name-$algo.exr"
      t1=$(date +%s%N)
      times+=($(( (t1 - t0) / 1000000 )))
    done
    s=$($bin score "$out/$name-$algo.exr" "$ref")
    read -r rmse mae p99 < <(python3 -c 'import json,sys; j=json.loads(sys.argv[1]); print("%.4f %.4f %.4f" % (j["rmse"], j["mae"], j["p99_abs_error"]))' "$s")
    echo "| $name | $algo | $rmse | $mae | $p99 | $(median "${times[@]}") |"
  done
done
