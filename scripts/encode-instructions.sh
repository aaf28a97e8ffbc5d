#!/usr/bin/env bash
# Instructions executed inside each engine path's `encode` (the host-cost goal), counted
# by callgrind, for the small and the large (64x the triangles) scene of examples/frame_loop.rs:
# counts repeat from run to run where this 2-core machine's seconds do not, and a device that
# runs on the same cores (lavapipe) cannot inflate them. Prints one line per estimator:
#   algo  instructions/encode small  large  large/small
# Usage: scripts/encode-instructions.sh [ALGO ...]   (default: every engine path)
# Needs valgrind and a Vulkan adapter (lavapipe); about a minute per estimator.
source "$(dirname "$0")/lib.sh"
export WGPU_BACKEND="${WGPU_BACKEND:-vulkan}" XDG_RUNTIME_DIR="${XDG_RUNTIME_DIR:-/tmp}"
cargo build --release -q --example frame_loop
algos=("$@")
if [ ${#algos[@]} -eq 0 ]; then
  algos=(hard pcf pcss multi-sample backprojection accumulation deep-shadow packet-hsm)
fi
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
# frame_loop::run runs once per scene (small, then large); every run makes the same number of
# encodes (frames + timed + warm + idle + 1), so the totals compare as per-encode counts.
frames=3
encodes=$((frames + 10 + 2000 + 31 + 1))
printf '%-15s %14s %14s %8s\n' algo small large ratio
for a in "${algos[@]}"; do
  valgrind --tool=callgrind --callgrind-out-file="$tmp/$a.%p" \
    --toggle-collect='*FrameEstimator*encode*' --dump-after='frame_loop::run' \
    target/release/examples/frame_loop --json --frames "$frames" --size 32x24 --resolution 64 \
    --algo "$a" fixtures/bunny/bunny.toml >"$tmp/$a.out" 2>"$tmp/$a.err" ||
    { echo "$a: frame_loop under callgrind failed:"; tail -5 "$tmp/$a.err"; exit 1; }
  mapfile -t tot < <(for f in $(ls "$tmp/$a".*.[0-9]* | sort -t. -k3 -n); do
    sed -n 's/^totals: //p' "$f"; done)
  [ ${#tot[@]} -eq 2 ] || { echo "$a: expected 2 dumps, got ${#tot[@]}"; exit 1; }
  python3 -c "import sys; s,l=int(sys.argv[2]),int(sys.argv[3]); n=int(sys.argv[4]); print('%-15s %14.0f %14.0f %8.3f' % (sys.argv[1], s/n, l/n, l/s))" \
    "$a" "${tot[0]}" "${tot[1]}" "$encodes"
done
