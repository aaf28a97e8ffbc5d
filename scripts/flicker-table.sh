#!/usr/bin/env bash
# Temporal stability of the light-view fit modes: every fixture, a camera pan of FRAMES frames
# (default 8) by PAN (default 0.2,0,0) world units, hard / PCF / PCSS with fit=receivers|scene|
# stable: mean and p99 of |dV| between consecutive frames at the same world points (see
# crates/cli/src/path.rs for the matching).
#   scripts/flicker-table.sh [OUT_DIR] [FRAMES] [PAN]
source "$(dirname "$0")/lib.sh"
table_setup "${1:-target/flicker}"
frames=${2:-8}
pan=${3:-0.2,0,0}
table_header fixture algo fit 'mean abs dV' 'p99 abs dV' pairs
for scene in fixtures/*/*.toml; do
  name=$(basename "$scene" .toml)
  for algo in hard pcf pcss; do
    for fit in receivers scene stable; do
      line=$($bin render "$scene" --algo "$algo" --param fit="$fit" --frames "$frames" --pan "$pan" \
        --out "$out/$name-$algo-$fit.exr" | tail -1)
      python3 - "$name" "$algo" "$fit" "$line" <<'PY'
import json, sys
name, algo, fit, line = sys.argv[1:5]
f = json.loads(line)["flicker"]
print(f"| {name} | {algo} | {fit} | {f['mean_abs_dv']:.5f} | {f['p99_abs_dv']:.4f} | {f['pairs']} |")
PY
    done
  done
done
