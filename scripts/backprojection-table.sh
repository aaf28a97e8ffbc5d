#!/usr/bin/env bash
# The backprojection accuracy table: every fixture, the estimator at several settings on both
# backends, and the baselines, as RMSE against the ray-traced reference (1024 spp, rendered once
# and cached in OUT_DIR, shared with scripts/baseline-table.sh) with build and estimate ms (median
# of 3, from --stats) and whole-process ms (median of 3).
#   scripts/backprojection-table.sh [OUT_DIR]
# GPU rows need a Vulkan adapter (WGPU_BACKEND=vulkan; lavapipe on a machine without a GPU).
source "$(dirname "$0")/lib.sh"
table_setup "${1:-target/baseline-table}"
variants=(
  "backprojection|cpu|"
  "backprojection|gpu|"
  "backprojection|cpu|--param layers=1"
  "backprojection|cpu|--param gap_filling=true"
  "backprojection|cpu|--param self_shadow=bias"
  "backprojection|cpu|--param resolution=512"
  "backprojection|cpu|--param max_nspp=25"
  "pcss|cpu|"
  "multi-sample|cpu|"
  "pcf|cpu|"
)
table_header fixture algo backend settings RMSE MAE p99 'build ms' 'estimate ms' 'whole ms'
for scene in fixtures/*/*.toml; do
  with_reference "$scene"
  for v in "${variants[@]}"; do
    IFS='|' read -r algo backend args <<<"$v"
    tag=$(echo "$algo-$backend-$args" | tr -c 'a-zA-Z0-9_-' '_')
    img="$out/$name-$tag.exr"
    stats=()
    ok=1
    for _ in 1 2 3; do
      t0=$(date +%s%N)
      # shellcheck disable=SC2086
      if ! s=$($bin render "$scene" --algo "$algo" --backend "$backend" $args --out "$img" --stats 2>"$out/err.txt"); then
        ok=0; break
      fi
      t1=$(date +%s%N)
      stats+=("$(( (t1 - t0) / 1000000 ))|$(echo "$s" | tail -1)")
    done
    if [ $ok = 0 ]; then
      echo "| $name | $algo | $backend | ${args:-defaults} | rejected: $(tail -1 "$out/err.txt" | cut -c1-80) | | | | | |"
      continue
    fi
    sc=$($bin score "$img" "$ref")
    python3 - "$name" "$algo" "$backend" "${args:-defaults}" "$sc" "${stats[@]}" <<'PY'
import json, statistics, sys
name, algo, backend, args, sc = sys.argv[1:6]
runs = [r.split("|", 1) for r in sys.argv[6:]]
j = json.loads(sc)
whole = statistics.median(float(w) for w, _ in runs)
st = [json.loads(s)["stages_ms"] for _, s in runs]
b = statistics.median(s.get("build", 0.0) + s.get("upload", 0.0) for s in st)
e = statistics.median(s.get("estimate", 0.0) + s.get("readback", 0.0) for s in st)
print(f"| {name} | {algo} | {backend} | {args} | {j['rmse']:.4f} | {j['mae']:.4f} | {j['p99_abs_error']:.4f} | {b:.1f} | {e:.1f} | {whole:.0f} |")
PY
  done
done
