#!/usr/bin/env python3
"""Checks `softshadow score` output (stdin, one JSON line) against a stored expectation (a JSON
file with the same keys): fails when the matched fraction drops by more than 0.001, when RMSE
rises by more than max(0.002, 10%), or when any V is non-finite. What CI runs on the README's
render command.

    softshadow score OUT.exr REF.exr | scripts/check-score.py EXPECTED.json
    softshadow score OUT.exr REF.exr | scripts/check-score.py --write EXPECTED.json
"""
import json
import sys

sys.dont_write_bytecode = True  # no __pycache__ of checklib left in scripts/
from checklib import json_rows  # noqa: E402

args = sys.argv[1:]
write = args and args[0] == "--write"
path = args[-1] if args else None
if not path:
    print(__doc__)
    sys.exit(2)
rows = json_rows()
if not rows:
    print("score check FAILED: no JSON line from softshadow score")
    sys.exit(1)
got = rows[-1]
if write:
    keep = {k: got[k] for k in ("matched_fraction", "rmse", "mae", "nonfinite_v") if k in got}
    json.dump(keep, open(path, "w"), indent=1)
    open(path, "a").write("\n")
    print(f"wrote {path}: {keep}")
    sys.exit(0)
want = json.load(open(path))
bad = []
if got.get("nonfinite_v", 1) != 0:
    bad.append(f"{got.get('nonfinite_v')} non-finite V")
if not got["matched_fraction"] >= want["matched_fraction"] - 1e-3:
    bad.append(f"matched fraction {got['matched_fraction']}, expected {want['matched_fraction']}")
allowed = max(0.002, 0.10 * want["rmse"])
if not got["rmse"] <= want["rmse"] + allowed:
    bad.append(f"RMSE {got['rmse']:.5f}, expected {want['rmse']:.5f} (allowed +{allowed:.5f})")
if bad:
    print("score check FAILED: " + "; ".join(bad))
    sys.exit(1)
print(f"score check: RMSE {got['rmse']:.5f} (expected {want['rmse']:.5f}), matched fraction {got['matched_fraction']}: ok")
