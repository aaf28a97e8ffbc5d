#!/usr/bin/env python3
"""Checks the Bevy plugin's headless example (`--json`, stdin): every method of the frame API
listed, none refused on the fixture, each method's V within RMSE 0.01 of its CPU twin on the
receivers Bevy's prepass gave, shadows present, at most 10% of receivers left
NaN by the device's loop budget, and those counted by the view's status (read back without
waiting). Times are printed, not asserted.

    cd crates/bevy-softshadow && cargo run --example headless -- --json --frames 3 | python3 ../../scripts/check-bevy-headless.py
"""
import sys

sys.dont_write_bytecode = True  # no __pycache__ of checklib left in scripts/
from checklib import finish, json_rows, missing_methods  # noqa: E402

rows = json_rows()
bad = missing_methods(rows, "methods")
for r in rows:
    a = r["algo"]
    if "error" in r:
        bad.append("%s: %s" % (a, r["error"]))
        continue
    if not r["rmse_vs_cpu"] <= 0.01:
        bad.append("%s: rmse_vs_cpu %g > 0.01" % (a, r["rmse_vs_cpu"]))
    if not (r["frac_below_half"] > 0.01 and r["mean_v"] < 0.99):
        bad.append("%s: no shadow (mean V %g)" % (a, r["mean_v"]))
    if r["nan"] > 0.1 * r["receivers"]:
        bad.append("%s: %d of %d receivers NaN" % (a, r["nan"], r["receivers"]))
    counted = r.get("status_left_nan") if r.get("keeps_status") else 0
    if counted != r["nan"]:
        bad.append("%s: %d receivers NaN, the frame status says %s" % (a, r["nan"], r.get("status_left_nan")))
    g = r["prepass_vs_raytraced"]
    print("%-14s %d frames %dx%d, %.1f ms/frame, rmse_vs_cpu %.2e (max %.2e, NaN %d), "
          "vs render --backend cpu %.4f; prepass vs ray-traced: %d pixels covered by one, "
          "%d apart > 1e-3" % (
        a, r["frames"], r["width"], r["height"], r["ms_per_frame"], r["rmse_vs_cpu"],
        r["max_abs_vs_cpu"], r["nan"], r["rmse_vs_cpu_render"], g["pixels_covered_by_one"],
        g["pixels_apart_1e-3"]))
finish("bevy headless check", bad, "%d methods" % len(rows))
