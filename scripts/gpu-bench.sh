#!/usr/bin/env bash
# The GPU benchmarks on a machine with a real GPU: the GPU bench (benches/gpu.rs: the adapter's
# ceilings, the shadow-map stages, and every estimator's frame on the engine path beside its CPU
# twin, with per-frame GPU timestamps where the adapter has them) and examples/frame_loop.rs (the
# 60-frame orbit through the frame API, then one frame with timestamps between its passes: GPU ms
# per stage, `gpu_stage_ms_*`), both at 1920x1080 receivers and 2048^2 maps.
#
#   scripts/gpu-bench.sh              # a machine with the toolchain and the GPU: build, then run
#   scripts/gpu-bench.sh build        # here: release-build both into .gpu-bench/
#   scripts/gpu-bench.sh loader       # here, once: download the Vulkan loader .debs into .gl/ (docs/methods.md §12)
#   scripts/gpu-bench.sh run          # there: unpack .gl/ if present, point Vulkan at the NVIDIA ICD, run both
#
# Without a toolchain there (the H200 reached through the `device` tool): `run` with carry
# [".gpu-bench", ".gl"] and the command `bash scripts/gpu-bench.sh run` (the script travels with
# the working tree; .gpu-bench/ and .gl/ are git-ignored, so they must be carried). Results: the
# bench's markdown tables and frame_loop's lines on stdout, JSON in $OUT/gpu-bench.json and
# $OUT/frame-loop.jsonl.
#
# `run` defaults (override by setting them): SOFTSHADOW_BENCH_RES=2048,
# SOFTSHADOW_BENCH_RECEIVERS=1920x1080, SOFTSHADOW_BENCH_FIXTURE=fixtures/bunny/bunny.toml,
# FRAME_LOOP_FRAMES=60. Any other SOFTSHADOW_BENCH_* variable (benches/README.md) passes through.
source "$(dirname "$0")/lib.sh"

build() {
  # The bench binary's path comes from cargo's JSON messages (its name carries a hash).
  local exe
  exe=$(cargo bench --bench gpu --features gpu --no-run --message-format=json-render-diagnostics |
    jq -r 'select(.reason == "compiler-artifact" and .target.name == "gpu"
                  and (.target.kind | index("bench")) and .executable != null) | .executable' |
    tail -n 1)
  if [ -z "$exe" ] || [ ! -x "$exe" ]; then
    echo "gpu-bench.sh: no bench executable in cargo's output" >&2
    exit 1
  fi
  mkdir -p .gpu-bench
  cp "$exe" .gpu-bench/gpu-bench
  cargo build --release --example frame_loop
  cp target/release/examples/frame_loop .gpu-bench/frame_loop
  strip .gpu-bench/gpu-bench .gpu-bench/frame_loop 2>/dev/null || true
  echo "built $exe -> .gpu-bench/gpu-bench ($(du -h .gpu-bench/gpu-bench | cut -f1))"
  echo "built frame_loop -> .gpu-bench/frame_loop ($(du -h .gpu-bench/frame_loop | cut -f1))"
}

loader() {
  # docs/methods.md §12, "The GPU reached through the device tool": the loader and the GL
  # vendor-neutral libraries the NVIDIA ICD needs, as amd64 .debs unpacked there at run time.
  if ls .gl/*.deb >/dev/null 2>&1; then
    echo ".gl/ already holds $(ls .gl/*.deb | wc -l) packages"
    return
  fi
  mkdir -p .gl /tmp/amd64/partial
  local o=(-oAPT::Architecture=amd64 -oAPT::Architectures=amd64 -oDir::State::Lists=/tmp/amd64)
  apt-get "${o[@]}" update
  (cd .gl && apt-get "${o[@]}" download libvulkan1 libegl1 libglvnd0 libopengl0 libgl1 libglx0 libgles2)
  echo "downloaded $(ls .gl/*.deb | wc -l) packages into .gl/"
}

run() {
  for b in gpu-bench frame_loop; do
    if [ ! -x ".gpu-bench/$b" ]; then
      echo "gpu-bench.sh: .gpu-bench/$b is missing (run 'build' here and carry .gpu-bench)" >&2
      exit 1
    fi
  done
  if ls .gl/*.deb >/dev/null 2>&1; then
    for f in .gl/*.deb; do dpkg -x "$f" /; done
    ldconfig
  fi
  if [ -f /usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json ]; then
    export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
  fi
  export WGPU_BACKEND=vulkan XDG_RUNTIME_DIR=/tmp
  export SOFTSHADOW_BENCH_RES=${SOFTSHADOW_BENCH_RES:-2048}
  export SOFTSHADOW_BENCH_RECEIVERS=${SOFTSHADOW_BENCH_RECEIVERS:-1920x1080}
  export SOFTSHADOW_BENCH_FIXTURE=${SOFTSHADOW_BENCH_FIXTURE:-fixtures/bunny/bunny.toml}
  nvidia-smi --query-gpu=name,driver_version,clocks.sm,clocks.max.sm --format=csv 2>/dev/null || true
  ./.gpu-bench/gpu-bench --bench
  local size=$SOFTSHADOW_BENCH_RECEIVERS out=${OUT:-target}
  mkdir -p "$out"
  ./.gpu-bench/frame_loop --json --frames "${FRAME_LOOP_FRAMES:-60}" --size "$size" \
    --resolution "$SOFTSHADOW_BENCH_RES" "$SOFTSHADOW_BENCH_FIXTURE" | tee "$out/frame-loop.jsonl"
  python3 scripts/check-frame-loop.py < "$out/frame-loop.jsonl" || true
}

case "${1:-all}" in
  all) build && run ;;
  build) build ;;
  loader) loader ;;
  run) run ;;
  *)
    echo "usage: $0 [all|build|loader|run]" >&2
    exit 2
    ;;
esac
