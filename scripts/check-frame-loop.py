#!/usr/bin/env python3
"""Checks `frame_loop --json` output (stdin): one line per estimator on the frame path, no
readback during the frames (counted by the library), on both scenes the last frame's V within
2e-3 RMSE of the CPU twin and at most 2% of its active receivers left NaN, the large
scene at least 50 times the small one's triangles, and the GPU ms per stage (timestamps, where
the adapter has them) finite and non-negative. Host times are printed, not asserted (timings
on shared CI machines are noise; the ratio goal lives in the closing notes, and
scripts/encode-instructions.sh counts encode's instructions, which repeat).

    cargo run --release --example frame_loop -- --json --frames 3 | python3 scripts/check-frame-loop.py
"""
import sys

sys.dont_write_bytecode = True  # no __pycache__ of checklib left in scripts/
from checklib import finish, json_rows, missing_methods  # noqa: E402

rows = json_rows()
bad = missing_methods(rows, "estimators")
for r in rows:
    a = r["algo"]
    # Counted by the library (GpuContext::readbacks): every buffer mapped back during the frames.
    if r["readbacks_during_frames"] != 0:
        bad.append("%s: %d readbacks during frames" % (a, r["readbacks_during_frames"]))
    for size in ("small", "large"):
        n = r["active_" + size]
        if n <= 0:
            bad.append("%s: no active receivers on the %s scene" % (a, size))
        # Receivers a frame leaves NaN (cut short by the device's loop budget, counted in its
        # status) are the caller's to redo; at most 2% of the active receivers.
        if r["left_nan_" + size] > 0.02 * n:
            bad.append("%s: %d of %d receivers left NaN on the %s scene" % (a, r["left_nan_" + size], n, size))
        if not r["rmse_vs_cpu_" + size] <= 2e-3:
            bad.append("%s: rmse_vs_cpu %g > 2e-3 on the %s scene" % (a, r["rmse_vs_cpu_" + size], size))
    if r["triangles_large"] < 50 * r["triangles_small"]:
        bad.append("%s: large scene has only %d triangles" % (a, r["triangles_large"]))
    print("%-14s frames %d, host CPU ms/frame in encode %.4f (%d tris) / %.4f (%d tris), "
          "rmse_vs_cpu %.2e / %.2e, cold idle encode ms %.4f / %.4f, warm encode ms %.4f / %.4f, "
          "frame ms %.2f / %.2f vs CPU twin %.2f / %.2f, left NaN %d / %d" % (
        a, r["frames"], r["host_ms_per_frame_small"], r["triangles_small"],
        r["host_ms_per_frame_large"], r["triangles_large"], r["rmse_vs_cpu_small"], r["rmse_vs_cpu_large"],
        r.get("host_ms_idle_small", float("nan")), r.get("host_ms_idle_large", float("nan")),
        r.get("host_ms_warm_small", float("nan")), r.get("host_ms_warm_large", float("nan")),
        r.get("gpu_ms_per_frame_small", float("nan")), r.get("gpu_ms_per_frame_large", float("nan")),
        r.get("cpu_twin_ms_small", float("nan")), r.get("cpu_twin_ms_large", float("nan")),
        r["left_nan_small"], r["left_nan_large"]))
    # GPU ms per stage from the frame's timestamps (where the adapter has them).
    for size in ("small", "large"):
        st = r.get("gpu_stage_ms_" + size, {})
        if any(not (ms >= 0.0) for ms in st.values()):
            bad.append("%s: a negative or NaN stage time in %s" % (a, st))
        if st:
            print("%-14s   GPU ms per stage, %s: %s" % ("", size, ", ".join(
                "%s %.3f" % (k, v) for k, v in st.items())))
finish("frame_loop check", bad, "%d estimators" % len(rows))
