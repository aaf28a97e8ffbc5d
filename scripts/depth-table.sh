#!/usr/bin/env bash
# Depth precision (common techniques: tight planes make 16-bit depth enough): for every fixture,
# each single-map baseline (hard, PCF, PCSS, multi-sample) with depth=f32 and depth=unorm16 under
# each near/far mode, on the CPU and (with --gpu) on the GPU backend: RMSE against the ray-traced
# reference, the change unorm16 makes against f32 (RMSE and fraction of receivers with
# |dV| > 0.1, acne or peter-panning), the code step s = 2^ceil(log2((far - n) / 65534)), the
# light-space bytes and the estimate time. References are cached in OUT_DIR (shared with
# scripts/baseline-table.sh).
#   scripts/depth-table.sh [OUT_DIR] [--gpu]
source "$(dirname "$0")/lib.sh"
table_setup "${1:-target/baseline-table}"
backends=(cpu)
[ "${2:-}" = "--gpu" ] && backends+=(gpu)
table_header fixture algo backend nearfar 'RMSE f32' 'RMSE unorm16' 'RMSE(u16 - f32)' \
  'frac \|dV\|>0.1' 'step s' '(far-n)/s' 'bytes f32 -> u16' 'estimate ms f32 / u16'
for scene in fixtures/*/*.toml; do
  with_reference "$scene"
  for backend in "${backends[@]}"; do
    for algo in hard pcf pcss multi-sample; do
      for nf in clipped aabb frustum; do
        declare -A st=() sc=()
        for depth in f32 unorm16; do
          img="$out/$name-depth-$algo-$backend-$nf-$depth.exr"
          st[$depth]=$($bin render "$scene" --algo "$algo" --backend "$backend" --param nearfar="$nf" \
            --param depth="$depth" --out "$img" --stats | tail -1)
          sc[$depth]=$($bin score "$img" "$ref")
        done
        d=$($bin score "$out/$name-depth-$algo-$backend-$nf-unorm16.exr" "$out/$name-depth-$algo-$backend-$nf-f32.exr")
        python3 - "$name" "$algo" "$backend" "$nf" "${st[f32]}" "${st[unorm16]}" "${sc[f32]}" "${sc[unorm16]}" "$d" <<'PY'
import json, sys
name, algo, backend, nf, s32, s16, c32, c16, d = sys.argv[1:10]
s32, s16 = json.loads(s32), json.loads(s16)
c32, c16, d = json.loads(c32), json.loads(c16), json.loads(d)
def est(s):
    return sum(ms for k, ms in s["stages_ms"].items() if k.startswith("estimate"))
n16 = s16["notes"]
step = float(n16.get("depth_step", "nan"))
near = float(n16.get("near", "nan")); far = float(n16.get("far", "nan"))
print(f"| {name} | {algo} | {backend} | {nf} | {c32['rmse']:.4f} | {c16['rmse']:.4f} | {d['rmse']:.2e} | "
      f"{d['frac_abs_error_gt_0_1']:.2e} | {step:.3g} | {(far - near) / step:.0f} | "
      f"{s32['light_space_bytes']} -> {s16['light_space_bytes']} | {est(s32):.1f} / {est(s16):.1f} |")
PY
        unset st sc
      done
    done
  done
done
