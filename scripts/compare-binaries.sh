#!/usr/bin/env bash
# Two builds of the CLI side by side at their defaults: RMSE against the references in REF_DIR
# (NAME-reference.exr, e.g. rendered by scripts/defaults-table.sh) and build+estimate ms, best of
# three, per fixture and estimator. Before/after tables of a change come from it.
#   scripts/compare-binaries.sh OLD_BIN NEW_BIN REF_DIR "ALGOS" SCENE.toml...
source "$(dirname "$0")/lib.sh"
old=$1 new=$2 refs=$3 algos=$4
shift 4
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
table_header fixture estimator 'before: RMSE / ms' 'after: RMSE / ms'
for scene in "$@"; do
  f=$(basename "$scene" .toml)
  for a in $algos; do
    line="| $f | $a"
    for bin in "$old" "$new"; do
      best=""
      for _ in 1 2 3; do
        ms=$("$bin" render "$scene" --algo "$a" --out "$tmp/v.exr" --stats 2>/dev/null | tail -1 |
          python3 -c "import json,sys; g=json.load(sys.stdin)['stages_ms']; g=g.items() if isinstance(g,dict) else g; print(sum(float(v) for k,v in g if any(w in k for w in ('estimate','build','upload'))))")
        best=$(python3 -c "print(min(float('$ms'), float('${best:-inf}')))")
      done
      rmse=$("$bin" score "$tmp/v.exr" "$refs/$f-reference.exr" | python3 -c 'import json,sys; print("%.4f" % json.load(sys.stdin)["rmse"])')
      line="$line | $rmse / $(printf %.0f "$best")"
    done
    echo "$line |"
  done
done
