#!/usr/bin/env bash
# Every estimator at its defaults on every fixture (or the scenes given), one backend: RMSE and
# lit MAE (mean |V - Vr| over pixels whose reference is fully lit: false shadow) against the
# ray-traced reference (1024 spp, rendered once and kept in OUT_DIR), and the estimator's own
# stage time (--stats). Prints a markdown table; before/after tables of a change come from it.
#   scripts/defaults-table.sh [OUT_DIR] [BACKEND] [SCENE.toml...]
source "$(dirname "$0")/lib.sh"
table_setup "${1:-target/defaults-table}"
backend=${2:-cpu}
shift 2 || true
scenes=("$@")
[ ${#scenes[@]} -gt 0 ] || scenes=(fixtures/*/*.toml)
algos=(hard pcf pcss multi-sample backprojection accumulation packet-hsm deep-shadow)
table_header fixture algo backend RMSE 'lit MAE' 'lit px' 'build ms' 'estimate ms' cascades \
  'cascade jump mean / max'
for scene in "${scenes[@]}"; do
  with_reference "$scene"
  for algo in "${algos[@]}"; do
    img="$out/$name-$algo-$backend.exr"
    if ! stats=$($bin render "$scene" --algo "$algo" --backend "$backend" --out "$img" --stats 2>&1); then
      echo "| $name | $algo | $backend | error: $(echo "$stats" | tail -1) | | | | | | |"
      continue
    fi
    s=$($bin score "$img" "$ref")
    python3 - "$name" "$algo" "$backend" "$s" "$stats" <<'PY'
import json, sys
name, algo, backend, s, stats = sys.argv[1:6]
j = json.loads(s)
ms = bms = casc = jump = ""
for line in stats.splitlines():
    try:
        st = json.loads(line)
    except ValueError:
        continue
    stages = st.get("stages_ms") or {}
    items = stages.items() if isinstance(stages, dict) else stages
    items = [(k, float(v)) for k, v in items]
    ms = "%.1f" % sum(v for k, v in items if "estimate" in k)
    bms = "%.1f" % sum(v for k, v in items if "build" in k or "upload" in k)
    notes = st.get("notes") or {}
    casc = notes.get("cascades", "")
    if "cascade_jump_mean" in notes:
        jump = "%s / %s" % (notes["cascade_jump_mean"], notes.get("cascade_jump_max", ""))
print("| %s | %s | %s | %.4f | %.4f | %d | %s | %s | %s | %s |" % (name, algo, backend, j["rmse"], j["lit_mae"], j["lit_pixels"], bms, ms, casc, jump))
PY
  done
done
