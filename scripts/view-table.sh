#!/usr/bin/env bash
# Light-view options against the ray-traced reference (common techniques): for every fixture,
# PCSS and hard shadows (and backprojection on rect lights) with each fit mode and each near/far
# mode: RMSE, the planes n and far, far/n, and the window scale (final side over the tightest
# side; the texel density given up is its square). References cached in OUT_DIR (shared with
# scripts/baseline-table.sh).
#   scripts/view-table.sh [OUT_DIR]
source "$(dirname "$0")/lib.sh"
table_setup "${1:-target/baseline-table}"
table_header fixture algo fit nearfar RMSE n far 'far/n' 'window scale'
for scene in fixtures/*/*.toml; do
  with_reference "$scene"
  algos=(hard pcss)
  grep -q 'shape = "rect"' "$scene" && algos+=(backprojection)
  for algo in "${algos[@]}"; do
    for mode in "receivers clipped" "scene clipped" "stable clipped" "receivers aabb" "receivers frustum"; do
      read -r fit nf <<<"$mode"
      img="$out/$name-view-$algo-$fit-$nf.exr"
      s=$($bin render "$scene" --algo "$algo" --param fit="$fit" --param nearfar="$nf" --out "$img" --stats | tail -1)
      sc=$($bin score "$img" "$ref")
      python3 - "$name" "$algo" "$fit" "$nf" "$s" "$sc" <<'PY'
import json, sys
name, algo, fit, nf, s, sc = sys.argv[1:7]
st = json.loads(s)["notes"]; j = json.loads(sc)
n, far = float(st["near"]), float(st["far"])
print(f"| {name} | {algo} | {fit} | {nf} | {j['rmse']:.4f} | {n:.4g} | {far:.4g} | {far/n:.3g} | {float(st.get('window_scale', 'nan')):.3f} |")
PY
    done
  done
done
