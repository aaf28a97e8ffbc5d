#!/usr/bin/env bash
# Renders every fixture with each baseline on both backends through the CLI (`--backend gpu` also
# rasterises the camera G-buffer and the shadow maps on the GPU) and scores GPU against CPU.
#   scripts/gpu-vs-cpu.sh [OUT_DIR]
source "$(dirname "$0")/lib.sh"
export WGPU_BACKEND=vulkan XDG_RUNTIME_DIR=${XDG_RUNTIME_DIR:-/tmp}
table_setup "${1:-target/gpu-vs-cpu}"
table_header fixture algo 'RMSE gpu vs cpu' p99 'fraction > 0.1' matched
for scene in fixtures/*/*.toml; do
  name=$(basename "$scene" .toml)
  for algo in hard pcf pcss multi-sample; do
    for be in cpu gpu; do $bin render "$scene" --algo "$algo" --backend "$be" --out "$out/$name-$algo-$be.exr"; done
    $bin score "$out/$name-$algo-gpu.exr" "$out/$name-$algo-cpu.exr" | python3 -c '
import json, sys
j = json.load(sys.stdin)
print("| %s | %s | %.2e | %.2e | %.1e | %d (%.5f) |" % (sys.argv[1], sys.argv[2], j["rmse"], j["p99_abs_error"], j["frac_abs_error_gt_0_1"], j["matched"], j["matched_fraction"]))' "$name" "$algo"
  done
done
